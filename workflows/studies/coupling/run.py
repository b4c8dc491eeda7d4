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
(:class:`workflows.reference_solution.Reference`, the adaptive study's comparison too):

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
  (:meth:`~workflows.reference_solution.Reference.pressure_dual_error`). A pressure
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
:func:`workflows.reference_solution.contact_measures`): ``a_moment`` / ``a_hertz``
and ``p0_moment`` / ``p0_hertz`` (the moments of the nodal forces against Hertz for the
measured force) and ``dev_hertz_rms``, the nodal pressure's root-mean-square deviation
from Hertz's over the nodes in Hertz's zone, relative to ``p0``: a discrete L2 norm of
the multiplier error.

P2 rows (``--orders 1 2``; the scenes' ``degree=2``, every row has its ``order``): every
coupling the scene takes at P2 (``nodal``, ``mortar``; ``mortar_dual`` in 2D, where the
dual basis of the P2 trace exists) at the levels below ``--p2-reference-level``, against
a P2 reference of their own: the scene at P2 at that level with the
``--p2-reference-coupling`` (default: the reference's; in 3D ``mortar_dual`` has no P2
basis, so the standard ``mortar`` or ``nodal``), solved as the P1 reference is. A P1
reference would not do: its own error is O(h_ref), where P2's is at best O(h^{3/2}).
A coupling the scene refuses at P2 (``stabilised``; ``mortar_dual`` in 3D) gets one
``skipped`` row per level with the scene's reason, no solve. Against the P2 reference:

* ``err_energy`` -- ``||I u_h - u_ref||_A / ||u_ref||_A`` with ``I`` the P2 field of
  ``u_h`` evaluated at the reference's P2 nodes (vertices and edge midpoints; its P2
  shape functions in the coarse cell holding each node, per body:
  :func:`problems.fem.accuracy.interpolation_matrix`), which is the reference space's
  P2 interpolant, exact on nested meshes (the circle's projected nodes get the
  quadratic extension of their nearest cell), and ``A`` the reference's P2 stiffness
  on all nodal DOFs (the element_order study's comparison);
* ``err_force`` and Hertz's a and p0 with the normal nodal forces the rows exert on the
  constrained nodes (:func:`problems.fem.fields.contact_forces`: the multipliers for nodal
  and dual rows, the consistent loads for standard mortar rows, whose multipliers in 3D
  are no nodal forces); ``err_pressure`` with the P2 pressure recovered from the forces
  (:meth:`problems.qp.ContactSurface.pressure`: aggregated onto the vertices, over the
  P1 lumped mass), at both sides;
* ``err_pressure_dual`` and the energy shares per region are P1 only (NaN and absent
  at P2: the forces ``B_C' (m lambda)`` are the P1 multiplier basis's, the shares
  come from the P1 energy per cell);

and Hertz's a, p0 and the recovered pressure's deviation as at P1.

Example::

    python -m workflows.studies.coupling.run --problem circle_square --levels 0 1 2 3 \\
        --reference-level 4 --orders 1 2 --p2-reference-level 3 \\
        --out results/circle_square/coupling.csv
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
from workflows.reference_solution import Reference, contact_measures

#: The couplings compared by default: the thesis's nodal and stabilised ones and both
#: mortar bases.
COMPARED = ("nodal", "stabilised", "mortar", "mortar_dual")
#: The exact reference the suite uses: PDAS at its tightest preset, verified.
SOLVER, TOL = "pdas", "high"
#: The element order without ``--orders``: P1, the thesis's elements.
THESIS_ORDER = 1


def exact(qp):
    """``qp`` solved by :data:`SOLVER` at :data:`TOL` (verified) and its solve time."""
    t0 = time.perf_counter()
    res = solve(qp, SOLVER, tol=TOL)
    return res, time.perf_counter() - t0


def order_params(order: int) -> dict:
    """The scene parameters of an element order: none at P1 (the scenes' default, so the
    P1 rows are built as without the option), ``degree=2`` at P2."""
    return {} if order == 1 else {"degree": order}


def run(spec, params: dict, coupling: str, level: int, ref: Reference, order: int = 1) -> dict:
    """One coupling at one level and element order: its row (module docstring)."""
    qp = spec.make(level, **params, **order_params(order), coupling=coupling)
    res, t_solve = exact(qp)
    row = {"coupling": coupling, "level": level, "order": order, "dim": qp.dim,
           "N": qp.n_nodes, "n": qp.n, "NC": qp.m,
           "status": res.status, "solver": res.solver, "t_solve": t_solve,
           "kkt_max": res.kkt.max if res.kkt is not None else float("nan")}
    if res.status == "converged":
        row.update(contact_measures(qp, res.u, res.p))
        row.update(ref.compare(qp, res.u, res.p))
        row["err_pressure_dual"] = ref.pressure_dual_error(qp, res.p)
    return row


def refused(spec, params: dict, couplings, level: int, order: int) -> dict:
    """``{coupling: reason}`` of the couplings the scene refuses at ``order`` (its
    :class:`~problems.spec.ParameterError`, e.g. the stabilised coupling at P2, the dual
    multipliers of the P2 trace on triangles)."""
    out = {}
    for c in couplings:
        try:
            spec.make(level, **params, **order_params(order), coupling=c)
        except ParameterError as err:
            out[c] = str(err)
    return out


def order_rows(spec, params: dict, scene: str, order: int, levels, couplings,
               ref_level: int, ref_coupling: str, out: str) -> list[dict]:
    """The rows of one element order: its reference's, then every coupling the scene takes
    at this order at every level (a refused one as ``skipped`` rows with the reason)."""
    print(f"reference: {scene} {ref_coupling} P{order} level {ref_level}", flush=True)
    ref_qp = spec.make(ref_level, **params, **order_params(order), coupling=ref_coupling)
    skipped = refused(spec, params, couplings, min(levels), order) if order > 1 else {}
    t0 = time.perf_counter()
    ref_res = reference_solve(ref_qp, tol=1e-10)
    t_ref = time.perf_counter() - t0
    rows = [{"coupling": ref_coupling, "level": ref_level, "order": order,
             "dim": ref_qp.dim, "N": ref_qp.n_nodes, "n": ref_qp.n, "NC": ref_qp.m,
             "status": ref_res.status,
             "solver": ref_res.solver, "t_solve": t_ref, "role": "reference",
             "kkt_max": ref_res.kkt.max if ref_res.kkt is not None else float("nan")}]
    for c, reason in skipped.items():
        print(f"skipped: {c} at P{order}: {reason}", flush=True)
        rows += [{"coupling": c, "level": level, "order": order, "dim": ref_qp.dim,
                  "status": "skipped", "reason": reason, "role": "compared"}
                 for level in sorted(set(levels))]
    if ref_res.status != "converged":      # nothing to measure against: the table says why
        print(f"reference not converged ({ref_res.status}): no comparison", flush=True)
        return rows
    rows[0].update(contact_measures(ref_qp, ref_res.u, ref_res.p))
    ref = Reference(ref_qp, ref_res.u, ref_res.p,
                    {"solver": ref_res.solver, "status": ref_res.status, "t_solve": t_ref})
    cases = [(c, level) for c in couplings if c not in skipped for level in sorted(set(levels))]
    for c, level in study_progress(cases, rule="coupling_study", out=out,
                                   desc=f"{scene} couplings P{order}", unit="solve"):
        rows.append({**run(spec, params, c, level, ref, order), "role": "compared"})
    return rows


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
    parser.add_argument("--orders", type=int, nargs="+",
                        help=f"element orders compared (omitted: {THESIS_ORDER}, the thesis's "
                             "P1); allowed: 1, 2 (2: the scene's degree=2)")
    parser.add_argument("--p2-reference-level", type=int,
                        help="mesh level of the P2 rows' reference (with --orders 2; the P2 "
                             "rows run at the levels below it)")
    parser.add_argument("--p2-reference-coupling",
                        help="coupling of the P2 rows' reference (default: "
                             "--reference-coupling); one the scene takes at degree=2")
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    args.orders = args.orders or [THESIS_ORDER]
    spec, _ = scene_from_args(parser, args)
    params = parse_sets(args.set)
    names = {p.name for p in spec.parameters}
    if "coupling" not in names:
        parser.error(f"argument --problem: {spec.name!r} is not allowed; allowed: a problem "
                     "with the 'coupling' parameter")
    for key in ("coupling", "degree"):
        if key in params:
            parser.error(f"argument --set: {key!r} is not allowed; the study sets it "
                         "(--couplings, --reference-coupling, --orders)")
    p2_coupling = args.p2_reference_coupling or args.reference_coupling
    for name, values in (("--couplings", args.couplings),
                         ("--reference-coupling", [args.reference_coupling]),
                         ("--p2-reference-coupling", [p2_coupling])):
        bad = [c for c in values if c not in COUPLINGS]
        if bad:
            parser.error(f"argument {name}: {', '.join(bad)} is not allowed; allowed: "
                         f"{', '.join(COUPLINGS)}")
    bad = sorted({o for o in args.orders if o not in (1, 2)})
    if bad or len(set(args.orders)) != len(args.orders):
        parser.error(f"argument --orders: {' '.join(map(str, args.orders))} is not allowed; "
                     "allowed: distinct orders among 1, 2")
    levels = check_levels(parser, spec, [*args.levels, args.reference_level])[:-1]
    if args.reference_level <= max(levels):
        parser.error(f"argument --reference-level: {args.reference_level} is not allowed; "
                     f"allowed: above every level ({max(levels)})")
    p2_levels = []
    if 2 in args.orders:
        if "degree" not in names:
            parser.error(f"argument --orders: 2 is not allowed for {spec.name!r}; allowed: 1 "
                         "(a problem without the 'degree' parameter)")
        if args.p2_reference_level is None:
            parser.error("argument --p2-reference-level: required with --orders 2")
        check_levels(parser, spec, [args.p2_reference_level])
        p2_levels = [lv for lv in levels if lv < args.p2_reference_level]
        if not p2_levels:
            parser.error(f"argument --p2-reference-level: {args.p2_reference_level} is not "
                         f"allowed; allowed: above one of the levels ({min(levels)})")
    elif args.p2_reference_level is not None:
        parser.error("argument --p2-reference-level: not allowed without --orders 2")

    scene = " ".join([spec.name, *args.set])
    try:                                       # refused combinations, before any solve
        for c in {*args.couplings, args.reference_coupling}:
            spec.make(min(levels), **params, coupling=c)
        if p2_levels:                          # the P2 reference's coupling, at a coarse level
            spec.make(min(p2_levels), **params, **order_params(2), coupling=p2_coupling)
    except ParameterError as err:
        parser.error(str(err))
    plan = {1: (levels, args.reference_level, args.reference_coupling),
            2: (p2_levels, args.p2_reference_level, p2_coupling)}
    rows = []
    for order in sorted(args.orders):
        order_levels, ref_level, ref_coupling = plan[order]
        rows += order_rows(spec, params, scene, order, order_levels, args.couplings,
                           ref_level, ref_coupling, args.out)
    out = pd.DataFrame(rows)
    out.insert(0, "scene", scene)
    write_csv(args.out, out)


if __name__ == "__main__":
    main()
