"""P1 against P2 on a contact problem (issue 25, thesis Remark 7.11): accuracy against
unknowns and against solve time, and Alg. 8.4 on P2 (Table 9.1's columns).

For one scene: a reference solution, P2 (``degree=2``) at ``--reference-level``
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
* ``dev_a`` / ``dev_p0`` -- the contact zone against Hertz (moments of the nodal forces);
* Alg. 8.4's ``n_outer``, ``kappa(S-hat)``, ``kappa(S-hat^-1 S_in)``, setup and solve time.

Example::

    python -m workflows.scripts.element_order --scene circle_square --levels 0 1 2 \\
        --reference-level 3 --out results/circle_square/element_order.csv
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import pandas as pd
from tqdm import tqdm

from problems.fem.accuracy import interpolation_matrix
from problems.fem.fields import hertz_comparison
from problems.fem.quadratic import quadratic_mesh, stiffness_matrix_p2
from problems.spec import problems
from solvers.interface import solve
from solvers.reference import reference_solve
from workflows.io import write_csv


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


def run(spec, level: int, degree: int, ref, u_ref_full, A_ref, time_limit: float) -> dict:
    """One solve of ``spec`` at ``level`` with elements of ``degree``: its row."""
    t0 = time.perf_counter()
    qp = spec.make(level, degree=degree)
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
        h = hertz_comparison(qp, res.p)
        row.update(dev_a=h["dev_a_moment"], dev_p0=h["dev_p0_moment"], a_over_h=h["a_over_h"])
    return row


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scene", required=True, help="a registered contact problem with a "
                        "Hertz reference and the 'degree' parameter")
    parser.add_argument("--levels", type=int, nargs="+", required=True,
                        help="mesh levels of the P2 runs (P1 runs one level more)")
    parser.add_argument("--reference-level", type=int, required=True,
                        help="mesh level of the P2 reference (above every level)")
    parser.add_argument("--time-limit", type=float, default=120.0, help="seconds per solve (> 0)")
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    registry = problems()
    spec = registry.get(args.scene)
    if spec is None or spec.kind != "contact" or "degree" not in {p.name for p in spec.parameters}:
        allowed = sorted(n for n, s in registry.items() if s.kind == "contact"
                         and "degree" in {p.name for p in s.parameters})
        parser.error(f"argument --scene: {args.scene!r} is not allowed; allowed: "
                     f"{', '.join(allowed)}")
    lo, hi = spec.levels
    if args.reference_level > hi or args.reference_level <= max(args.levels) or min(args.levels) < lo:
        parser.error(f"argument --reference-level/--levels: levels {args.levels} and reference "
                     f"{args.reference_level} are not allowed; allowed: levels in [{lo}, {hi}] "
                     "below the reference level")
    if args.time_limit <= 0:
        parser.error(f"argument --time-limit: {args.time_limit} is not allowed; allowed: > 0")

    print(f"reference: {args.scene} P2 level {args.reference_level}", flush=True)
    ref = spec.make(args.reference_level, degree=2)
    t0 = time.perf_counter()
    ref_res = reference_solve(ref, tol=1e-10)
    t_ref = time.perf_counter() - t0
    A_ref = _full_stiffness(ref)
    u_ref_full = ref.full_displacement(ref_res.u).ravel()
    rows = [{"degree": 2, "level": args.reference_level, "N": ref.n_nodes, "n": ref.n,
             "NC": ref.m, "status": ref_res.status, "role": "reference",
             "solver": ref_res.solver, "t_solve": t_ref}]
    cases = [(1, level) for level in sorted(set(args.levels) | {max(args.levels) + 1})]
    cases += [(2, level) for level in sorted(args.levels)]
    for degree, level in tqdm(cases, desc=f"{args.scene} P1/P2", unit="solve"):
        row = run(spec, level, degree, ref, u_ref_full, A_ref, args.time_limit)
        rows.append({**row, "role": "compared", "solver": "augmented_projection"})
    out = pd.DataFrame(rows)
    out.insert(0, "scene", args.scene)
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
