"""Nodal, stabilised and mortar couplings on a contact scene (thesis Ch. 6, Sect. 7.5,
Prop. 7.6): the energy error against a common fine reference, the contact force and
Hertz's half-width and peak pressure, per coupling and level.

For one scene (a registered problem with the ``coupling`` parameter and parameter
overrides, ``--problem P --set key=value``): a reference solution at
``--reference-level`` with the ``--reference-coupling`` (default ``mortar_dual``), then
every coupling of ``--couplings`` at every level of ``--levels``. Every compared problem
is solved exactly: PDAS through :func:`solvers.interface.solve` at the ``high``
tolerance, its status verified (a solve that is not ``converged`` keeps its row, with
its status, and no errors). The reference is the suite's
(:func:`solvers.reference.reference_solve` at 1e-10: the exact PDAS where a
factorisation is affordable, else TNNMG verified to KKT residuals and certified energy
bound 1e-10, a thousandth of the smallest error measured). Against the reference
(:class:`workflows.scripts.adaptive_study.Reference`, the adaptive study's comparison):

* ``err_energy`` -- ``||P u_h - u_ref||_A / ||u_ref||_A`` with ``P`` the P1 interpolation
  at the reference's nodes per body (exact on the nested uniform levels; the circle's
  nodes projected onto the circle get the linear extension) and ``A`` the reference's
  stiffness on all nodal DOFs;
* ``err_force`` -- the total contact force against the reference's (relative);
* ``err_pressure`` -- the nodal pressure interpolated onto the reference's constrained
  surface against the reference's, a discrete L2 norm weighted by its surface mass;
* ``err_pressure_dual`` -- the multiplier (pressure) error in the dual (energy) norm of
  the reference's discretisation,
  ``||A^{-1/2} (F_h - F_ref)|| / ||A^{-1/2} F_ref||`` with ``A`` the reference's
  stiffness on its free DOFs
  (:meth:`~workflows.scripts.adaptive_study.Reference.pressure_dual_error`). A pressure
  ``lambda`` acts on both bodies as the nodal forces ``F = B_C' (m * lambda)``:
  ``B_C`` the reference's constrained rows (its multiplier basis), ``lambda`` the nodal
  pressure at its constrained nodes (the compared one interpolated as for
  ``err_pressure``), ``m`` their lumped surface mass; the reference's own forces are
  ``B' p_ref``. ``F`` is the functional ``v -> int lambda n.[v] ds`` on the
  reference's displacements, and ``||A^{-1/2} F|| = sup_v F'v / ||v||_A`` its norm
  as a load, the energy of the displacement it produces. By the trace theorem (the
  trace of ``H^1`` onto ``Gamma_C`` with its bounded extension) the dual norm of such a
  surface load is equivalent to the ``H^{-1/2}(Gamma_C)`` norm of its density, the
  norm in which the mortar analysis states the multiplier error (Wohlmuth 2000;
  Hüeber, Wohlmuth, SIAM J. Numer. Anal. 43 (2005)). Approximated: the surfaces are the
  reference's polygons (the circle's chords, the sphere's flat triangles); the compared
  pressure enters as its P1 interpolant at the reference's constrained nodes, integrated
  with the lumped mass; the sup runs over the reference's P1 space, not ``H^1`` (a
  lower bound of the continuous dual norm, reached as the reference is refined). One
  linear solve with the reference's ``A`` per compared solve (its factorisation, or
  multigrid PCG beyond the direct limit);

and against Hertz (scenes with a Hertz reference;
:func:`workflows.scripts.adaptive_study.contact_measures`): ``a_moment`` / ``a_hertz``
and ``p0_moment`` / ``p0_hertz`` (the moments of the nodal forces against Hertz for the
measured force) and ``dev_hertz_rms``, the nodal pressure's root-mean-square deviation
from Hertz's over the nodes in Hertz's zone, relative to ``p0``: a discrete L2 norm of
the multiplier error.

Example::

    python -m workflows.scripts.coupling --problem circle_square --levels 0 1 2 3 \\
        --reference-level 5 --out results/circle_square/coupling.csv
"""
from __future__ import annotations

import argparse
import time

import pandas as pd

from problems.fem.stabilised import COUPLINGS
from problems.spec import ParameterError
from solvers.interface import solve
from solvers.reference import reference_solve
from workflows.io import write_csv
from workflows.progress import study_progress
from workflows.scene_args import add_scene_arguments, check_levels, parse_sets, scene_from_args
from workflows.scripts.adaptive_study import Reference, contact_measures

#: The couplings compared by default: the thesis's nodal and stabilised ones and both
#: mortar bases.
COMPARED = ("nodal", "stabilised", "mortar", "mortar_dual")
#: The exact reference the suite uses: PDAS at its tightest preset, verified.
SOLVER, TOL = "pdas", "high"


def exact(qp):
    """``qp`` solved by :data:`SOLVER` at :data:`TOL` (verified) and its solve time."""
    t0 = time.perf_counter()
    res = solve(qp, SOLVER, tol=TOL)
    return res, time.perf_counter() - t0


def run(spec, params: dict, coupling: str, level: int, ref: Reference) -> dict:
    """One coupling at one level: its row (module docstring)."""
    qp = spec.make(level, **params, coupling=coupling)
    res, t_solve = exact(qp)
    row = {"coupling": coupling, "level": level, "dim": qp.dim, "N": qp.n_nodes, "n": qp.n,
           "NC": qp.m,
           "status": res.status, "solver": res.solver, "t_solve": t_solve,
           "kkt_max": res.kkt.max if res.kkt is not None else float("nan")}
    if res.status == "converged":
        row.update(contact_measures(qp, res.u, res.p))
        row.update(ref.compare(qp, res.u, res.p))
        row["err_pressure_dual"] = ref.pressure_dual_error(qp, res.p)
    return row


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(parser)
    parser.add_argument("--levels", type=int, nargs="+", required=True,
                        help="mesh levels of the compared solves")
    parser.add_argument("--couplings", nargs="+", default=list(COMPARED),
                        help=f"couplings compared (default: {' '.join(COMPARED)}); allowed: "
                             f"{', '.join(COUPLINGS)}")
    parser.add_argument("--reference-level", type=int, required=True,
                        help="mesh level of the reference (above every level)")
    parser.add_argument("--reference-coupling", default="mortar_dual",
                        help=f"coupling of the reference; allowed: {', '.join(COUPLINGS)}")
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    spec, _ = scene_from_args(parser, args)
    params = parse_sets(args.set)
    if "coupling" not in {p.name for p in spec.parameters}:
        parser.error(f"argument --problem: {spec.name!r} is not allowed; allowed: a problem "
                     "with the 'coupling' parameter")
    if "coupling" in params:
        parser.error("argument --set: 'coupling' is not allowed; the study sets it "
                     "(--couplings, --reference-coupling)")
    for name, values in (("--couplings", args.couplings),
                         ("--reference-coupling", [args.reference_coupling])):
        bad = [c for c in values if c not in COUPLINGS]
        if bad:
            parser.error(f"argument {name}: {', '.join(bad)} is not allowed; allowed: "
                         f"{', '.join(COUPLINGS)}")
    levels = check_levels(parser, spec, [*args.levels, args.reference_level])[:-1]
    if args.reference_level <= max(levels):
        parser.error(f"argument --reference-level: {args.reference_level} is not allowed; "
                     f"allowed: above every level ({max(levels)})")

    scene = " ".join([spec.name, *args.set])
    print(f"reference: {scene} {args.reference_coupling} level {args.reference_level}",
          flush=True)
    try:
        ref_qp = spec.make(args.reference_level, **params, coupling=args.reference_coupling)
        for c in args.couplings:               # refused combinations, before any solve
            spec.make(min(levels), **params, coupling=c)
    except ParameterError as err:
        parser.error(str(err))
    t0 = time.perf_counter()
    ref_res = reference_solve(ref_qp, tol=1e-10)
    t_ref = time.perf_counter() - t0
    rows = [{"coupling": args.reference_coupling, "level": args.reference_level,
             "dim": ref_qp.dim, "N": ref_qp.n_nodes, "n": ref_qp.n, "NC": ref_qp.m,
             "status": ref_res.status,
             "solver": ref_res.solver, "t_solve": t_ref, "role": "reference",
             "kkt_max": ref_res.kkt.max if ref_res.kkt is not None else float("nan")}]
    if ref_res.status == "converged":
        rows[0].update(contact_measures(ref_qp, ref_res.u, ref_res.p))
        ref = Reference(ref_qp, ref_res.u, ref_res.p,
                        {"solver": ref_res.solver, "status": ref_res.status, "t_solve": t_ref})
        cases = [(c, level) for c in args.couplings for level in sorted(set(levels))]
        for c, level in study_progress(cases, rule="coupling_study", out=args.out,
                                       desc=f"{scene} couplings", unit="solve"):
            rows.append({**run(spec, params, c, level, ref), "role": "compared"})
    else:                      # nothing to measure against: the table says why
        print(f"reference not converged ({ref_res.status}): no comparison", flush=True)
    out = pd.DataFrame(rows)
    out.insert(0, "scene", scene)
    write_csv(args.out, out)


if __name__ == "__main__":
    main()
