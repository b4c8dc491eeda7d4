"""P1 against P2 on a contact problem (thesis Remark 7.11): accuracy against
unknowns and against solve time, and Alg. 8.4 on P2 (Table 9.1's columns).

For one scene (a registered problem with the ``degree`` parameter and parameter
overrides, ``--problem P --set key=value``): a reference solution, P2
(``degree=2``) at ``--reference-level``
(:func:`solvers.reference.reference_solve`: the exact PDAS or, beyond the direct
limit, the augmented projection to verified KKT <= 1e-10); then P1 at ``--levels``
and one level more (the same number of nodes as P2 at the finest level), and P2
at ``--levels``. Each is solved by the augmented projection at the ``mid`` tolerance
(its defaults; one process, one solve after the other) and compared with the
reference:

* ``err_energy`` -- ``||I u_h - u_ref||_A / ||u_ref||_A`` with ``I`` the interpolation
  of ``u_h`` (P1 or P2) at the reference's P2 nodes (exact on nested meshes; the
  curved boundary's nodes projected onto the circle/sphere get the linear extension)
  and ``A`` the reference's P2 stiffness;
* ``dev_a`` / ``dev_p0`` -- the contact zone against Hertz (moments of the nodal forces;
  scenes with a Hertz reference);
* Alg. 8.4's ``n_outer``, ``kappa(S-hat)``, ``kappa(S-hat^-1 S_in)``, setup and solve time.

Example::

    python -m workflows.studies.element_order.run --problem circle_square --levels 0 1 2 \\
        --reference-level 3 --time-limit 120 --out results/circle_square/element_order.csv
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import pandas as pd

from problems.fem.accuracy import interpolation_matrix
from problems.fem.fields import hertz_comparison
from problems.fem.quadratic import quadratic_mesh, stiffness_matrix_p2
from problems.spec import ParameterError, problems
from solvers.interface import solve
from solvers.reference import reference_solve
from workflows.io import write_csv
from workflows.progress import study_progress
from workflows.scene_args import add_scene_arguments, check_levels, parse_sets, scene_from_args


def prolongation(qp, ref) -> "np.ndarray":
    """Interpolation of ``qp``'s nodal field at ``ref``'s nodes, per body."""
    m, r = qp.mesh, ref.mesh
    return interpolation_matrix(m.points, m.cells, r.points, m.body_of_node[m.cells[:, 0]],
                                r.body_of_node)


def energy_error(qp, u, ref, u_ref_full, A_ref) -> float:
    """``||I u_h - u_ref||_A / ||u_ref||_A`` on the reference's nodes (module docstring);
    ``A_ref`` the reference's stiffness on all nodal DOFs."""
    e = (prolongation(qp, ref) @ qp.full_displacement(u)).ravel() - u_ref_full
    return float(np.sqrt(max(e @ (A_ref @ e), 0.0) / (u_ref_full @ (A_ref @ u_ref_full))))


def run(spec, params: dict, level: int, degree: int, ref, u_ref_full, A_ref,
        time_limit: float) -> dict:
    """One solve of the scene (``spec`` with ``params``) at ``level`` with elements of
    ``degree``: its row."""
    t0 = time.perf_counter()
    qp = spec.make(level, **params, degree=degree)
    t_build = time.perf_counter() - t0
    res = solve(qp, "augmented_projection", tol="mid", time_limit=time_limit)
    s = res.stats
    row = {"degree": degree, "level": level, "N": qp.n_nodes, "n": qp.n, "NC": qp.m,
           "status": res.status, "n_outer": res.iterations, "t_build": t_build,
           "t_setup": res.setup_time, "t_solve": res.solve_time,
           "kappa_S": s.get("kappa_S", np.nan), "kappa_SinvSin": s.get("kappa_SinvSin", np.nan),
           "schur_kind": s.get("schur_kind"), "ahat_degree": s.get("ahat_degree", np.nan),
           "kkt_max": res.kkt.max if res.kkt is not None else np.nan}
    if res.status == "converged":
        row["err_energy"] = energy_error(qp, res.u, ref, u_ref_full, A_ref)
    if res.status == "converged" and qp.hertz is not None:
        h = hertz_comparison(qp, res.p)
        row.update(dev_a=h["dev_a_moment"], dev_p0=h["dev_p0_moment"], a_over_h=h["a_over_h"])
    return row


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(parser)
    parser.add_argument("--levels", type=int, nargs="+", required=True,
                        help="mesh levels of the P2 runs (P1 runs one level more)")
    parser.add_argument("--reference-level", type=int, required=True,
                        help="mesh level of the P2 reference (above every level)")
    parser.add_argument("--time-limit", type=float, required=True, help="seconds per solve (> 0)")
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    spec, _ = scene_from_args(parser, args)
    params = parse_sets(args.set)
    if "degree" not in {p.name for p in spec.parameters}:
        allowed = sorted(n for n, s in problems().items() if s.kind == "contact"
                         and "degree" in {p.name for p in s.parameters})
        parser.error(f"argument --problem: {spec.name!r} is not allowed; allowed: "
                     f"{', '.join(allowed)} (problems with the 'degree' parameter)")
    if "degree" in params:
        parser.error("argument --set: 'degree' is not allowed; the study runs degree 1 and 2")
    levels = check_levels(parser, spec, [*args.levels, args.reference_level])[:-1]
    if args.reference_level <= max(levels):
        parser.error(f"argument --reference-level: {args.reference_level} is not allowed; "
                     f"allowed: above every level ({max(levels)})")
    if args.time_limit <= 0:
        parser.error(f"argument --time-limit: {args.time_limit} is not allowed; allowed: > 0")

    scene = " ".join([spec.name, *args.set])
    print(f"reference: {scene} P2 level {args.reference_level}", flush=True)
    try:
        ref = spec.make(args.reference_level, **params, degree=2)
    except ParameterError as err:            # a combination the problem refuses for P2
        parser.error(str(err))
    t0 = time.perf_counter()
    ref_res = reference_solve(ref, tol=1e-10)
    t_ref = time.perf_counter() - t0
    A_ref = _full_stiffness(ref)
    u_ref_full = ref.full_displacement(ref_res.u).ravel()
    rows = [{"degree": 2, "level": args.reference_level, "N": ref.n_nodes, "n": ref.n,
             "NC": ref.m, "status": ref_res.status, "role": "reference",
             "solver": ref_res.solver, "t_solve": t_ref}]
    cases = [(1, level) for level in sorted(set(levels) | {max(levels) + 1})]
    cases += [(2, level) for level in sorted(set(levels))]
    for degree, level in study_progress(cases, rule="element_order_study", out=args.out,
                                        desc=f"{scene} P1/P2", unit="solve"):
        row = run(spec, params, level, degree, ref, u_ref_full, A_ref, args.time_limit)
        rows.append({**row, "role": "compared", "solver": "augmented_projection"})
    out = pd.DataFrame(rows)
    out.insert(0, "scene", scene)
    write_csv(args.out, out)


def _full_stiffness(qp):
    """The P2 stiffness of ``qp``'s mesh on all nodal DOFs (free and prescribed: the error
    on the supports counts too); the same numbering, as :func:`quadratic_mesh` is
    deterministic."""
    m = qp.mesh
    d = m.dim
    verts = m.cells[:, :d + 1]
    quad = quadratic_mesh(m.points[:verts.max() + 1], verts)
    if not np.array_equal(quad.cells, m.cells):
        raise ValueError("the reference's P2 numbering is not quadratic_mesh's")
    return stiffness_matrix_p2(quad, m.E_cell, m.nu_cell)


if __name__ == "__main__":
    main()
