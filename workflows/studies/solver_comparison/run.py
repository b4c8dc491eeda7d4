"""Every registered solver at every tolerance preset on one scene at one level.

The reference (:func:`solvers.reference.reference_solve`: the exact PDAS, or in 3D
beyond a factorisation's reach the iterative reference to verified KKT residuals
<= 1e-10) gives ``u_ref``; each run records its
verified status, KKT residuals, the certified energy bound, time, peak memory,
iterations and the energy-norm error ``||u - u_ref||_A / ||u_ref||_A``. Beside them,
the linear floor per preset: geometric-multigrid PCG for the same system without
contact to the preset's energy accuracy (``solver`` = ``linear_floor``). Every
run is a child process with a hard wall-clock limit
(:func:`workflows.isolation.solve_isolated`): failures, crashes and time-outs
are rows, not gaps. A solver that cannot take the problem is a ``skipped`` row with its
reason (:meth:`solvers.base.SolverSpec.check`); one that timed out or failed at a
coarser level of the same scene (``--coarser``, that level's results) is ``skipped``
here with the reason "timed out at level k" / "failed at level k", and so is one whose
time, fitted over the two finest coarser levels, predicts more than the time limit here
(:func:`predicted_beyond_the_limit`). Called by the rule ``solver_comparison``.

Example::

    python -m workflows.studies.solver_comparison.run --problem circle_square --level 1 \\
        --out results/circle_square/solvers_L1.csv
"""
from __future__ import annotations

import argparse
import re
import time

import numpy as np
import pandas as pd

from problems.kkt import energy_error
from solvers.interface import TOLERANCES, SolveResult, solvers
from solvers.reference import reference_solve
from problems.spec import ParameterError
from workflows.io import read_csv, run_solvers, write_csv
from workflows.isolation import log_traceback, solve_isolated
from workflows.measure import amg_pcg_floor, linear_solution
from workflows.progress import study_progress
from workflows.scene_args import add_scene_arguments, check_levels, scene_from_args


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(parser)
    parser.add_argument("--level", type=int, required=True)
    parser.add_argument("--solvers", nargs="+", default=None,
                        help="default: every registered solver but the exact reference (in "
                             "a regeneration: of the solver set fixed when it started)")
    parser.add_argument("--presets", nargs="+", default=list(TOLERANCES), choices=list(TOLERANCES))
    parser.add_argument("--time-limit", type=float, default=600.0)
    parser.add_argument("--coarser", nargs="*", default=[],
                        help="results of coarser levels of the same scene: a solver that "
                             "timed out or failed there is skipped here")
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    spec, params = scene_from_args(parser, args)
    (level,) = check_levels(parser, spec, [args.level])
    registry = solvers()
    unknown = sorted(set(args.solvers or ()) - set(registry))
    if unknown:
        parser.error(f"argument --solvers: unknown {unknown}; allowed: {', '.join(registry)}")
    qp = spec.build(level, params)
    t0 = time.perf_counter()
    ref = reference_solve(qp, tol=1e-10)
    t_ref = time.perf_counter() - t0
    if ref.status != "converged":
        raise SystemExit(f"the reference failed on {qp.name}: {ref.status} {ref.message}")
    # the reference run is its own row; every solver runs at every preset (the exact PDAS
    # too where it is not the reference)
    try:
        fixed = run_solvers(registry)       # a regeneration's set, fixed when it started
    except ParameterError as err:
        parser.error(str(err))
    names = args.solvers or [n for n in fixed
                             if not (registry[n].role == "exact" and n == ref.solver)]
    base = {"scene_problem": spec.name, "level": level, "n": qp.n, "m": qp.m, "N": qp.n_nodes}
    rows = [{**base, "preset": "reference", **ref.summary(), "energy_error": 0.0,
             "wall_time": t_ref}]
    # the linear floor: geometric-multigrid PCG for the same system without contact, to the
    # preset's relative energy error, in this process (the study's yardstick for costs)
    u_lin = linear_solution(qp)
    for preset in args.presets:
        floor = amg_pcg_floor(qp, "gmg", TOLERANCES[preset], u_lin)
        rows.append({**base, "solver": "linear_floor", "preset": preset,
                     "tol": TOLERANCES[preset], "status": floor["status"],
                     "iterations": floor["n_to_target"], "setup_time": floor["t_setup"],
                     "solve_time": floor["t_to_target"] - floor["t_setup"],
                     "total_time": floor["t_to_target"], "energy_error": floor["energy_error"],
                     "message": "multigrid PCG for A u = f without contact (the floor)"})
    coarser = [read_csv(f) for f in args.coarser]
    given_up = {**predicted_beyond_the_limit(coarser, level, qp.n, args.time_limit),
                **gave_up_at_coarser_levels(coarser, level)}
    for solver, preset in study_progress([(s, p) for s in names for p in args.presets],
                                        rule="solver_comparison", out=args.out,
                                        desc=f"solvers on {qp.name}"):
        t0 = time.perf_counter()
        if (solver, preset) in given_up:
            res = skipped_result(qp, solver, preset, given_up[solver, preset])
        else:
            res = solve_isolated(qp, solver, preset, time_limit=args.time_limit)
            log_traceback(res, f"{qp.name} ({preset})")
        rows.append({**base, "preset": preset, **res.summary(),
                     "energy_error": energy_error(qp, res.u, ref.u)
                     if res.kkt is not None else np.nan,
                     "wall_time": time.perf_counter() - t0})
    write_csv(args.out, pd.DataFrame(rows))


#: The message of a run skipped because it gave up at a coarser level (and nothing else).
GAVE_UP = re.compile(r"skipped: ((?:timed out|failed) at level \d+)")


def gave_up_at_coarser_levels(tables: list[pd.DataFrame], level: int) -> dict:
    """``{(solver, preset): reason}`` for the solvers that timed out or failed at a level
    below ``level`` (or were skipped there for that reason), from the coarser levels'
    results: the reason names the level where it happened first."""
    out = {}
    if not tables:
        return out
    t = pd.concat(tables, ignore_index=True)
    t = t[(t["level"] < level) & t["status"].isin(["time_limit", "failed", "skipped"])]
    for _, r in t.sort_values("level").iterrows():
        key = (r["solver"], r["preset"])
        if key in out:
            continue
        if r["status"] == "skipped":
            carried = GAVE_UP.fullmatch(str(r.get("message", "")))
            if carried:                                 # carried over from a coarser level
                out[key] = carried.group(1)
        else:
            verb = "timed out" if r["status"] == "time_limit" else "failed"
            out[key] = f"{verb} at level {int(r['level'])}"
    return out


def predicted_beyond_the_limit(tables: list[pd.DataFrame], level: int, n: int,
                               time_limit: float) -> dict:
    """``{(solver, preset): reason}`` for the solvers whose time, fitted as ``c n^e`` over
    the two finest coarser levels where they converged, predicts more than
    ``time_limit`` at this level's ``n`` unknowns (a time limit used as
    information: the level is not run to its limit). The reason gives the prediction, the exponent and the levels."""
    out = {}
    if not tables:
        return out
    t = pd.concat(tables, ignore_index=True)
    t = t[(t["level"] < level) & (t["status"] == "converged") & (t["total_time"] > 0)]
    for (solver, preset), g in t.groupby(["solver", "preset"]):
        g = g.sort_values("level").drop_duplicates("level", keep="last").tail(2)
        if len(g) < 2 or g["n"].iloc[1] <= g["n"].iloc[0]:
            continue
        e = float(np.log(g["total_time"].iloc[1] / g["total_time"].iloc[0])
                  / np.log(g["n"].iloc[1] / g["n"].iloc[0]))
        predicted = float(g["total_time"].iloc[1] * (n / g["n"].iloc[1]) ** e)
        if predicted > time_limit:
            out[solver, preset] = (f"predicted {predicted:.0f} s > time limit {time_limit:g} s "
                                   f"(time exponent {e:.2f} in n over levels "
                                   f"{int(g['level'].iloc[0])}-{int(g['level'].iloc[1])})")
    return out


def skipped_result(qp, solver: str, preset: str, reason: str) -> SolveResult:
    """The row of a run that is not made (status ``skipped``, the reason in its message)."""
    return SolveResult.without_answer(qp.n, qp.m, solver, TOLERANCES[preset], "skipped",
                                      f"skipped: {reason}")


if __name__ == "__main__":
    main()
