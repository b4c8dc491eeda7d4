"""The adaptive study of Sect. 7.4 on one scene (Tables 9.2/9.4, Figs. 7.3/7.4, 9.2/9.4/9.7).

From the scene's level ``--start-level`` mesh, one adaptive run per variant
(:data:`problems.fem.adaptive.STUDY_VARIANTS`: the estimator that marks and the
discretisation): solve, estimate, mark (Doerfler, theta = ``--theta``, at least
``--min-marked`` of the cells), bisect, until
the mesh has ``--max-nodes`` nodes. Every step is solved from the previous step's
solution (Alg. 8.5). The scene's module supplies ``scene(level, params)`` (its
:class:`problems.fem.two_body.TwoBodyScene`). A variant whose discretisation is not the
scene's own nodal one is built from it per step: ``stabilised`` is the stabilised
two-sided formulation (7.10)/(7.11) (:func:`problems.fem.stabilised.stabilise` with
``--alpha`` and ``--penalty``), marked by eta_1 as the thesis's Fig. 7.5; its pressure and
force are those on the constrained surface (:func:`problems.qp.surface_multipliers`), its
KKT residual that of the stabilised problem.

* The run of ``--table-variant`` (eta_1 + eta_2, as in the thesis's tables) is solved
  by Alg. 8.4 (``alg84``: geometric multigrid A-hat on the adaptive hierarchy with local
  smoothing, multilevel S-hat, MPRGP), and the thesis's columns are read off its history
  from ``(0, 0)``, as for the uniform Table 9.1: n_o(eps) by (8.25) at eps = 1e-2 and
  1e-3, the mean inner steps, T_solve (setup included) and T_proj at each eps,
  kappa(S-hat), the unknowns smoothed per V-cycle over N. A second run from the nested
  guess (Alg. 8.5) to the same absolute estimate gives ``n_outer_nested_1e-03`` and
  ``t_solve_nested_1e-03`` (:func:`table_solve`). The solution is then made exact
  (PDAS from the Alg. 8.4 iterate) where a factorisation is affordable
  (:data:`solvers.reference.DIRECT_REFERENCE_LIMIT`), else Alg. 8.4 continues to
  verified KKT residuals <= ``--tol``. The other variants are solved exactly.
* The constant in front of eta_T2^2 (``--eta2-weight``): ``calibrated`` = the ratio
  sum eta_T1^2 / sum eta_T2^2 on the start mesh, fixed for the run (both parts
  of the estimate equally large where the run starts), or a number, or (for
  comparison) ``bound``: at every step the thesis's bound of the penetration term,
  ``||p||_Q ||w_h||``, in the units of eta_1^2: ``c = E^(3/2) ||p||_* / (sum eta_T2^2)^(1/2)``
  with ``||p||_*^2 = p' B A^-1 B' p`` (one solve) and E the constrained body's modulus,
  so that ``c sum eta_T2^2 = E^(3/2) ||p||_* (sum eta_T2^2)^(1/2)``.
* Per step: N, N^C, the estimates, the contact force, Hertz deviations (moment
  estimates), the nodal pressure's zig-zag (:func:`problems.fem.accuracy.zigzag`)
  and its rms deviation from Hertz in the contact zone, and the nodes of both
  contact surfaces in the zone (the pile-up of Fig. 7.3).
* Accuracy (``--uniform-levels``, 2D): the uniform levels are the start mesh bisected
  2L times (the nodes of the red levels), solved exactly. The reference is the common
  refinement of the finest uniform level and of every run's last step with at most
  ``--error-max-nodes`` nodes, bisected twice more (:func:`problems.fem.accuracy.common_refinement`),
  solved exactly; every compared mesh is nested in it. Per compared mesh:
  ``||u_ref - u_h||_A / ||u_ref||_A`` (full displacement, Dirichlet values included),
  its split into the contact zone (within 2a of the contact centre), the
  neighbourhoods (radius 2a) of the boundary points where a fully prescribed facet
  meets a free one (singular points: clamped corners, ends of a held arc) and the
  rest; the pressure error in L2 on the constrained surface and the force error.
  In 3D the bodies are bisected by longest edges with ties broken by node numbers,
  so meshes of different runs are not nested: no energy errors there.

Writes ``--steps`` (one row per run and step, the uniform levels and the
reference), and per variant (in the order of ``--variants``) the last step's fields
(``--fields``, VTU) and its contact surfaces (``--surfaces``: both surfaces' nodes,
the constrained nodes' pressure and activity).

Example::

    python -m workflows.studies.adaptive.run --problem circle_square --start-level 0 \\
        --max-nodes 10000 --uniform-levels 0 1 2 --variants eta1 eta1+eta2 \\
        --steps out/adaptive_steps.csv --fields out/eta1.vtu out/eta1_eta2.vtu \\
        --surfaces out/eta1_surface.csv out/eta1_eta2_surface.csv
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np
import pandas as pd
import scipy.sparse as sp

from problems.fem import accuracy as acc
from problems.fem.adaptive import (STUDY_VARIANTS, adaptive_loop, adaptive_start,
                                   body_force_per_cell, mark_doerfler, truncated)
from problems.fem.elasticity import boundary_facets
from problems.fem.estimators import estimate
from problems.fem.fields import contact_fields
from problems.fem.mesh import project_to_circle
from problems.fem.stabilised import stabilise
from problems.fem.two_body import assemble_two_body
from problems.kkt import kkt_residuals
from problems.qp import ContactQP, surface_multipliers
from solvers import augmented_projection as ap
from solvers.interface import solve, verify
from solvers.reference import DIRECT_REFERENCE_LIMIT, reference_solve
from workflows.io import write_csv, write_vtu
from workflows.measure import dual_norm, return_freed_memory
from workflows.reference_solution import Reference, contact_measures
from workflows.progress import study_progress
from workflows.scene_args import add_scene_arguments, check_levels, scene_from_args
from workflows.settings import study_defaults

#: The tolerances of (8.25) at which the thesis's tables count outer steps and time.
TABLE_EPS = (1e-2, 1e-3)

#: The study's defaults, declared once in the config schema (workflows/settings.py).
DEFAULTS = study_defaults("adaptive")


# --------------------------------------------------------------------------- solvers
def _alg84_options():
    """Alg. 8.4 as Tables 9.2/9.4 ran it (``alg84`` with one V-cycle as A-hat, the thesis's
    (8.18)), stopped by the caller's callback.

    The automatic Chebyshev degree would take 2 on the merged graded hierarchy
    (kappa(V A) ~3.1 > ``gamma_target`` 2.5 at 115k nodes): n_o(1e-3) 7 -> 6 for twice
    the V-cycles per step and a second Lanczos pass, 20 against 10 us per node. The
    degree is for locking materials (the incompressibility study), not for nu = 0.3."""
    return ap.SOLVER.options(**ap.VARIANTS["alg84"].options, stop="estimate", eps=1e-14,
                             record_kkt=False, diagnostics=False, **{"ahat.degree": 1})


def exact_solve(qp: ContactQP, u0=None, p0=None, tol: float = 1e-8,
                time_limit: float | None = None):
    """PDAS (exact: ``A`` factorised once, the dual problem on the contact rows) where a
    factorisation is affordable (:data:`solvers.reference.DIRECT_REFERENCE_LIMIT`), else
    Alg. 8.4 as the table's run (``alg84``: multigrid A-hat, multilevel S-hat) until its
    KKT residuals are <= ``tol``, verified; warm-started either way.

    (Face-CG steps, the earlier choice, assemble S_in column by column: at 75k nodes in
    3D that ran into the 600 s limit where ``alg84`` takes about a minute.)"""
    if qp.n <= DIRECT_REFERENCE_LIMIT.get(qp.dim, 0):
        return solve(qp, "pdas", tol=1e-10, u0=u0, p0=p0)
    opts = _alg84_options()
    deadline = None if time_limit is None else time.perf_counter() + time_limit
    target = tol
    for _ in range(5):   # the certified energy bound may need a tighter KKT (stabilised rows)
        left = None if deadline is None else max(deadline - time.perf_counter(), 1.0)
        res = ap.solve(qp, 1e-12, 5000, left, u0, p0, opts,
                       callback=lambda step: kkt_residuals(qp, step.u, step.p).max <= target)
        if kkt_residuals(qp, res.u, res.p).max <= tol:
            res.claimed_status = "converged"           # our stopping rule was met
            res.message = f"KKT <= {target:g}: " + res.message
        res = verify(qp, res, tol)
        if res.status == "converged" or res.claimed_status != "converged":
            return res
        u0, p0, target = res.u, res.p, target / 10
    return res


def release_steps(run, compared_max_nodes: int | None) -> None:
    """Free what a finished run no longer needs: the problems of its steps beyond the
    accuracy comparison (``compared_max_nodes``; None: no comparison) except the last
    (its fields are written), and the shared work (factorisations, linear solvers)
    cached on every problem. A full-scale 3D run holds ~15 steps of up to 100k
    nodes; three variants kept whole would not fit the 16 GB budget of a full run."""
    last = len(run.qps) - 1
    for i, (rec, qp) in enumerate(zip(run.records, run.qps)):
        if qp is None:
            continue
        qp.cache = type(qp.cache)()
        if i != last and not (compared_max_nodes is not None
                              and (rec.N <= compared_max_nodes or i == 0)):
            run.qps[i] = None


def table_solve(qp: ContactQP, u0, p0, tol: float, time_limit: float):
    """The thesis's columns of Alg. 8.4 (``alg84``) on this step, then the step's solution.

    1. From ``(0, 0)``, as Table 9.1 and every uniform level: until (8.25) <= 1e-3, the
       columns read off its history (``n_o(eps)`` counts the relative iteration error
       ``eps``, the thesis's definition; from the nested guess the same ``eps`` would be
       relative to an error already small, and the count would measure how good the
       guess was rather than the solver).
    2. From the nested guess ``(u0, p0)`` (Alg. 8.5): until the estimate reaches the same
       absolute value as run 1 at 1e-3 (``n_outer_nested_1e-03``, ``t_solve_nested_1e-03``:
       what the nested iteration saves), then exact (PDAS) where a factorisation is
       affordable, else on to verified KKT <= ``tol``.
    """
    direct = qp.n <= DIRECT_REFERENCE_LIMIT.get(qp.dim, 0)
    eps_min = min(TABLE_EPS)
    opts = _alg84_options()
    cold = ap.solve(qp, 1e-12, 2000, time_limit, None, None, opts,
                    callback=lambda step: step.eta_rel <= eps_min)
    h, s = cold.history, cold.stats
    eta = np.asarray(h["eta_rel"])
    sizes = [P.shape[1] for P in qp.multilevel.prolongations] + [qp.n]
    row = {"solver": "alg84", "n_outer_total": cold.iterations, "t_setup": s["t_setup"],
           # the V-cycle's levels (the refinement levels merged, solvers.kernels.multigrid.
           # merge_levels) and unknowns smoothed per cycle over N (4/3 on a uniform 2D
           # hierarchy); beside them the refinement levels' sizes, what smoothing every
           # level in full would cost
           "kappa_S": s["kappa_S"], "mg_levels": s["amg_levels"],
           "mg_refinement_levels": len(sizes),
           "mg_work_ratio": s["smoothing_work"], "mg_deep_ratio": s["deep_work"],
           "mg_size_ratio": float(np.sum(sizes)) / qp.n,
           "t_vcycle": s["t_vcycle"], "n_vcycles": s["n_vcycles"], "ap_status": cold.status}
    for e in TABLE_EPS:
        hit = np.flatnonzero(eta <= e)
        k = int(hit[0]) if hit.size else -1
        ok = hit.size > 0
        row.update({f"n_outer_{e:.0e}": k + 1 if ok else -1,
                    f"n_inner_mean_{e:.0e}": float(np.mean(h["n_inner"][:k + 1])) if ok else np.nan,
                    f"t_solve_{e:.0e}": float(s["t_setup"] + h["time"][k]) if ok else np.nan,
                    f"t_proj_{e:.0e}": float(np.sum(h["t_proj"][:k + 1])) if ok else np.nan})
    reached = bool(eta.size) and eta[-1] <= eps_min
    target = eps_min ** 2 * h["eta"][0] if reached else 0.0      # eta_rel = sqrt(eta / eta_0)
    marks = {}

    def stop(step):
        hit = step.eta <= target if reached else step.eta_rel <= eps_min
        if hit and "n" not in marks:
            marks["n"] = step.k
            marks["t"] = time.perf_counter() - t0
        return hit and (direct or kkt_residuals(qp, step.u, step.p).max <= tol)

    t0 = time.perf_counter()
    res = ap.solve(qp, 1e-12, 2000, time_limit, u0, p0, opts, callback=stop)
    row.update({"n_outer_nested_1e-03": marks.get("n", -1),
                "t_solve_nested_1e-03": marks.get("t", np.nan)})
    if "n" in marks and (direct or kkt_residuals(qp, res.u, res.p).max <= tol):
        res.claimed_status = "converged"               # our stopping rule was met
        res.message = (f"(8.25) at the level of {eps_min:g} from (0, 0) and verified KKT <= "
                       f"{tol:g}: " + res.message)
    res = verify(qp, res, 1.0 if direct else tol)
    if direct:
        res = exact_solve(qp, res.u, res.p)
        row["solver"] = "alg84 + pdas"
    res.stats = {**res.stats, "table": row}
    return res


# --------------------------------------------------------------------------- the study
def circle_projection(scene) -> tuple:
    """Per body: where to put new boundary nodes. A body whose boundary nodes all lie on
    one circle (sphere) - found by a least-squares fit - gets
    :func:`problems.fem.mesh.project_to_circle` onto it; any other body (polygonal
    boundaries) gets None (midpoints stay where they are)."""
    out = []
    for body in scene.bodies:
        pts = body.meshes.points[-1]
        f = np.unique(boundary_facets(body.meshes.cells[-1]))
        x = pts[f]
        # least-squares sphere through the boundary nodes: |x|^2 = 2 c.x + (r^2 - |c|^2)
        M = np.hstack([2 * x, np.ones((len(x), 1))])
        sol, *_ = np.linalg.lstsq(M, np.sum(x ** 2, axis=1), rcond=None)
        c = sol[:-1]
        r = np.sqrt(sol[-1] + c @ c)
        on = np.abs(np.linalg.norm(x - c, axis=1) - r) <= 1e-9 * max(r, 1.0)
        out.append(project_to_circle(c, r) if on.all() else None)
    return tuple(out)


def run_study(spec, params, start_level: int, variants: list[str], max_nodes: int,
              theta: float, weight_spec: str, uniform_levels: list[int], error_max_nodes: int,
              table_variant: str, tol: float, time_limit: float, max_steps: int,
              stabilisation: tuple[float, float] = (1.0, 1.0), log=print,
              min_marked: float = 0.0):
    """Everything of one scene (module docstring). Returns ``(rows, finals)`` with
    ``finals[variant] = (qp, u, p)`` of the last step."""
    module = __import__(f"problems.{spec.name}", fromlist=["scene"])
    scene0 = module.scene(start_level, params)
    make, start = adaptive_start(scene0, start_level)
    project = circle_projection(scene0)
    rows, finals, runs = [], {}, {}
    calibrated = {}
    p_star = {}                      # ||p||_* and E per step of the run being solved

    def weight_for(variant):
        if STUDY_VARIANTS[variant][0] == "eta1":
            return 0.0
        if weight_spec == "bound":
            def bound(step, est):
                e2 = float(est["eta2_sq"].sum())
                pstar, E = p_star[step]
                return E ** 1.5 * pstar / np.sqrt(e2) if e2 > 0 else 0.0
            return bound
        if weight_spec != "calibrated":
            return float(weight_spec)

        def calibrate(step, est):
            e1, e2 = float(est["eta1_sq"].sum()), float(est["eta2_sq"].sum())
            if variant not in calibrated and e2 > 0:
                calibrated[variant] = e1 / e2
            return calibrated.get(variant, 0.0)
        return calibrate

    for variant in variants:
        estimator, discretisation = STUDY_VARIANTS[variant]
        discretise = None
        if discretisation == "stabilised":
            alpha, penalty = stabilisation
            discretise = lambda qp, a=alpha, k=penalty: stabilise(qp, a, k)
        clock = {"t": time.perf_counter()}
        timing = []

        def solver(qp, u0, p0, _v=variant):
            t0 = time.perf_counter()
            if _v == table_variant:
                res = table_solve(qp, u0, p0, tol, time_limit)
            else:
                res = exact_solve(qp, u0, p0, tol, time_limit)
            timing.append({"t_solve_total": time.perf_counter() - t0,
                           "t_other": t0 - clock["t"]})
            if weight_spec == "bound":             # ||p||_*^2 = p' B A^-1 B' p, untimed
                body = qp.mesh.body_of_node[qp.contact.nodes[0]]
                E = float(qp.mesh.E_cell[qp.mesh.body_of_node[qp.mesh.cells[:, 0]] == body][0])
                p_star[len(timing) - 1] = (dual_norm(qp, qp.B.T @ res.p), E)
            clock["t"] = time.perf_counter()
            extra = f" + {qp.m - qp.m_contact} reverse rows" if qp.stabilisation else ""
            log(f"{_v}: N = {qp.n_nodes}, N^C = {qp.m_contact}{extra}, {res.status}, "
                f"kkt {res.kkt.max:.1e}, {timing[-1]['t_solve_total']:.2f} s")
            return res

        t0 = time.perf_counter()
        run = adaptive_loop(make, start, solver, estimator=estimator,
                            marking=lambda e: mark_doerfler(e, theta, min_marked), max_nodes=max_nodes,
                            max_steps=max_steps, project=project, eta2_weight=weight_for(variant),
                            discretise=discretise, name=variant)
        log(f"{variant}: {len(run.records)} steps, {time.perf_counter() - t0:.1f} s, "
            f"stopped by {run.stop_reason}")
        runs[variant] = run
        for rec, qp, (u, p), est, res, tm in zip(run.records, run.qps, run.solutions,
                                                run.estimates, run.results, timing):
            row = {"variant": variant, "estimator": estimator, "discretisation": discretisation,
                   "step": rec.step, "level": rec.level, "N": rec.N, "NC": rec.NC,
                   "n_cells": rec.n_cells, "eta2_weight": rec.eta2_weight,
                   "sum_eta1_sq": float(est["eta1_sq"].sum()),
                   "sum_eta2_sq": float(est["eta2_sq"].sum()), "sum_eta_sq": rec.sum_eta2,
                   "max_eta": rec.max_eta,
                   "max_eta1_plus_eta2": float(np.max(np.sqrt(est["eta1_sq"])
                                                      + np.sqrt(rec.eta2_weight * est["eta2_sq"]))),
                   "n_marked": rec.n_marked, "status": res.status, "iterations": rec.iterations,
                   **tm, **res.stats.get("table", {"solver": res.solver}),
                   **contact_measures(qp, u, p)}
            rows.append(row)
        finals[variant] = (run.qps[-1], *run.solutions[-1])
        release_steps(run, error_max_nodes if uniform_levels else None)
        return_freed_memory()

    # ---------------------------------------------------------------- accuracy (2D)
    if uniform_levels:
        t0 = time.perf_counter()
        uniform = {}
        weight = (next(iter(calibrated.values()), 0.0) if weight_spec == "calibrated" else
                  float("nan") if weight_spec == "bound" else float(weight_spec))
        for L in uniform_levels:
            meshes = acc.refine_to_depth(start, start, 2 * L, project)
            qp = assemble_two_body(make(meshes), len(meshes[0].points) - 1,
                                   name=f"{spec.name} uniform {L}")
            res = exact_solve(qp)
            sc = make(meshes)
            est = estimate(qp, res.u, "eta1+eta2", body_force=body_force_per_cell(sc, qp),
                           tractions=sc.tractions, direction=sc.direction, eta2_weight=0.0)
            eta_sq = est["eta1_sq"] + weight * est["eta2_sq"]
            uniform[L] = (meshes, qp, res.u, res.p)
            rows.append({"variant": "uniform", "estimator": "", "discretisation": "nodal",
                         "step": L, "level": L, "N": qp.n_nodes, "NC": qp.m,
                         "n_cells": len(qp.mesh.cells), "eta2_weight": weight,
                         "sum_eta1_sq": float(est["eta1_sq"].sum()),
                         "sum_eta2_sq": float(est["eta2_sq"].sum()), "sum_eta_sq": float(eta_sq.sum()),
                         "max_eta": float(np.sqrt(eta_sq.max())),
                         "max_eta1_plus_eta2": float(np.max(np.sqrt(est["eta1_sq"])
                                                            + np.sqrt(weight * est["eta2_sq"]))),
                         "status": res.status, "solver": res.solver,
                         **contact_measures(qp, res.u, res.p)})
            log(f"uniform level {L} (2L bisections): N = {qp.n_nodes}, {res.status}")
        compared = {}
        for variant, run in runs.items():
            last = max(i for i, r in enumerate(run.records)
                       if r.N <= error_max_nodes or i == 0)
            compared[variant] = last
        targets = [uniform[max(uniform_levels)][0]]
        targets += [tuple(truncated(h, runs[v].records[k].level) for h in runs[v].meshes)
                    for v, k in compared.items()]
        ref_meshes = acc.common_refinement(start, targets, project, extra=2)
        qref = assemble_two_body(make(ref_meshes), len(ref_meshes[0].points) - 1,
                                 name=f"{spec.name} reference")
        log(f"reference mesh: N = {qref.n_nodes}, N^C = {qref.m} "
            f"({time.perf_counter() - t0:.1f} s so far)")
        t1 = time.perf_counter()
        r = reference_solve(qref, tol=1e-10)        # exact through the dual problem (7.3)
        u_ref, p_ref = r.u, r.p
        info = {"solver": r.solver, "status": r.status, "kkt_max": r.kkt.max,
                "t_solve": time.perf_counter() - t1}
        log(f"reference solved by {info['solver']}: {info['status']}, kkt {info['kkt_max']:.1e}, "
            f"{info['t_solve']:.1f} s")
        ref = Reference(qref, u_ref, p_ref, info)
        sc = make(ref_meshes)
        est = estimate(qref, u_ref, "eta1+eta2", body_force=body_force_per_cell(sc, qref),
                       tractions=sc.tractions, direction=sc.direction, eta2_weight=0.0)
        rows.append({**ref.row, "max_nodes_compared": error_max_nodes,
                     "sum_eta1_sq": float(est["eta1_sq"].sum()),
                     "sum_eta2_sq": float(est["eta2_sq"].sum())})
        index = {(r["variant"], r["step"]): i for i, r in enumerate(rows)}
        for L, (meshes, qp, u, p) in uniform.items():
            rows[index[("uniform", L)]].update(ref.compare(qp, u, p))
        for variant, run in runs.items():
            last = compared[variant]
            qp_last = run.qps[last]
            P_last = ref.prolongation(qp_last)
            for k in range(last + 1):
                # nested prolongation through the run's own hierarchy to its compared last step
                lk, ll = run.records[k].level, run.records[last].level
                P = sp.identity(run.qps[k].n_nodes, format="csr")
                for j in range(lk, ll):
                    P = sp.block_diag([h.prolongations[j] for h in run.meshes], format="csr") @ P
                qp, (u, p) = run.qps[k], run.solutions[k]
                rows[index[(variant, k)]].update(ref.compare(qp, u, p, P_last @ P))
        log(f"accuracy: {time.perf_counter() - t0:.1f} s")
    return rows, finals


def surface_table(qp: ContactQP, p: np.ndarray) -> pd.DataFrame:
    """Both contact surfaces' nodes: kind, coordinates, pressure and activity (constrained)."""
    opp = np.unique(qp.contact.opposing_facets)
    p = surface_multipliers(qp, p)
    x = np.vstack([qp.constrained_points(), qp.mesh.points[opp]])
    kind = ["constrained"] * len(p) + ["opposing"] * len(opp)
    pressure = np.concatenate([p / qp.contact.mass, np.full(len(opp), np.nan)])
    active = np.concatenate([p > 0, np.zeros(len(opp), dtype=bool)])
    return pd.DataFrame({"kind": kind, **{f"x{i}": x[:, i] for i in range(x.shape[1])},
                         "pressure": pressure, "active": active})


def build_parser() -> argparse.ArgumentParser:
    """The study's command line: the scene, the variants, the marking, the outputs."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(parser)
    parser.add_argument("--start-level", type=int, required=True)
    parser.add_argument("--variants", nargs="+", default=list(STUDY_VARIANTS),
                        choices=list(STUDY_VARIANTS))
    parser.add_argument("--max-nodes", type=int, required=True)
    parser.add_argument("--max-steps", type=int, default=60)
    parser.add_argument("--theta", type=float, default=DEFAULTS["theta"],
                        help="Doerfler's bulk parameter")
    parser.add_argument("--min-marked", type=float, default=DEFAULTS["min_marked"],
                        help="mark at least this share of the cells, in [0, 1] (0: the bulk "
                             "set alone; problems.fem.adaptive.mark_doerfler)")
    parser.add_argument("--eta2-weight", default="calibrated",
                        help="'calibrated', 'bound' or a number >= 0 (module docstring)")
    parser.add_argument("--uniform-levels", type=int, nargs="*", default=[],
                        help="uniform levels (2L bisections) for the accuracy comparison (2D)")
    parser.add_argument("--error-max-nodes", type=int, default=None,
                        help="compare adaptive steps up to this many nodes (default: all)")
    parser.add_argument("--table-variant", default="eta1+eta2",
                        help="the variant solved by Alg. 8.4 for the thesis's table; 'none': "
                             "every variant exact")
    parser.add_argument("--tol", type=float, default=DEFAULTS["tol"],
                        help="verified KKT target where Alg. 8.4 must finish without PDAS")
    parser.add_argument("--time-limit", type=float, default=DEFAULTS["time_limit"],
                        help="seconds per solve")
    parser.add_argument("--alpha", type=float, default=DEFAULTS["stabilisation"]["alpha"],
                        help="the stabilised variant's exponent alpha of (7.10), in [0, 2]")
    parser.add_argument("--penalty", type=float,
                        default=DEFAULTS["stabilisation"]["penalty"],
                        help="the stabilised variant's penalty factor (> 0; "
                             "problems/fem/stabilised.py)")
    parser.add_argument("--steps", required=True, help="output: the per-step table (CSV)")
    parser.add_argument("--fields", nargs="+", required=True,
                        help="output: the last step's fields per variant (VTU), same order")
    parser.add_argument("--surfaces", nargs="+", required=True,
                        help="output: the last step's contact surfaces per variant (CSV)")
    return parser


def checked_scene(parser: argparse.ArgumentParser, args) -> tuple:
    """``(spec, params, start level)`` once every argument is checked; a bad value ends
    with the parser's error naming the argument."""
    if not len(args.variants) == len(args.fields) == len(args.surfaces):
        parser.error("--variants, --fields and --surfaces need one entry per variant")
    spec, params = scene_from_args(parser, args)
    (start_level,) = check_levels(parser, spec, [args.start_level])
    if args.eta2_weight not in ("calibrated", "bound"):
        try:
            if not float(args.eta2_weight) >= 0:
                raise ValueError
        except ValueError:
            parser.error(f"--eta2-weight: {args.eta2_weight!r} is not allowed; allowed: "
                         "'calibrated', 'bound' or a number >= 0")
    if args.table_variant not in args.variants + ["none"]:
        parser.error(f"--table-variant: {args.table_variant!r} is not among --variants")
    if not 0.0 <= args.min_marked <= 1.0:
        parser.error(f"--min-marked: {args.min_marked!r} is not allowed; allowed: a number in "
                     "[0, 1]")
    if not 0.0 <= args.alpha <= 2.0:
        parser.error(f"--alpha: {args.alpha!r} is not allowed; allowed: a number in [0, 2]")
    if not (np.isfinite(args.penalty) and args.penalty > 0):
        parser.error(f"--penalty: {args.penalty!r} is not allowed; allowed: a number in (0, inf)")
    if args.uniform_levels and spec.make(0).dim != 2:
        parser.error("--uniform-levels: the accuracy comparison needs nested meshes (2D only)")
    return spec, params, start_level


def write_outputs(args, spec, rows: list[dict], finals: dict, t0: float) -> None:
    """The last step's fields (VTU) and contact surfaces per variant, then the per-step
    table with the study's wall time."""
    for variant, vtu, surf in zip(args.variants, args.fields, args.surfaces):
        qp, u, p = finals[variant]
        write_vtu(vtu, contact_fields(qp, u, p))
        write_csv(surf, surface_table(qp, p))
    frame = pd.DataFrame(rows)
    frame.insert(0, "scene", spec.name)
    frame["wall_time_study"] = time.perf_counter() - t0
    write_csv(args.steps, frame)


def main(argv=None) -> None:
    parser = build_parser()
    args = parser.parse_args(argv)
    spec, params, start_level = checked_scene(parser, args)
    t0 = time.perf_counter()
    # the console's progress line shows the latest step (workflows/progress.py)
    bar = study_progress(rule="adaptive_study", out=args.steps, desc=f"adaptive {spec.name}",
                         unit="step", file=sys.stderr)

    def log(line: str) -> None:
        print(line, flush=True)
        bar.set_postfix_str(line)
        bar.update()

    rows, finals = run_study(spec, params, start_level, args.variants, args.max_nodes,
                             args.theta, args.eta2_weight, args.uniform_levels,
                             args.error_max_nodes or args.max_nodes, args.table_variant,
                             args.tol, args.time_limit, args.max_steps,
                             (args.alpha, args.penalty), log=log, min_marked=args.min_marked)
    bar.close()
    write_outputs(args, spec, rows, finals, t0)
    print(f"{spec.name}: {len(rows)} rows, {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
