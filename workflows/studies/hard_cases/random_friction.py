"""The random frictional family's harder sample (a table of the hard-case study).

The draws ``--first .. --first + --draws - 1`` of :mod:`problems.friction.random_family`
(seeded: law, friction coefficient, tangential load and its steps, stiffness and Poisson
ratios, the contact's size and position; 2D and 3D) at mesh ``--level``, beyond the
tests' draws (seeds 0 .. 499 at level 0). Each draw's load path is solved by the exact
reference (:func:`workflows.problem_set.frictional_steps`, the test set's rounded step
definitions); every tangential step is then solved from zero by every registered solver
at ``--preset``, each verified as every run of the suite is (a solver without friction is
``skipped`` with its reason).

Per run: the draw and its options, the step, the solver, the verified and claimed status,
the worst KKT residual, the certified energy bound and its floor, the energy-norm distance
to the exact reference (relative), whether semismooth Newton's fallback ran, iterations, time and
message. One process, one solve after the other (the libraries' ``--time-limit`` each).

Example::

    python -m workflows.studies.hard_cases.random_friction --first 500 --draws 40 \\
        --level 1 --preset mid --out results/hard_cases/random_friction.csv
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import pandas as pd
from tqdm import tqdm

from problems.friction.random_family import MAX_LEVEL, draw
from problems.kkt import energy_error
from solvers.base import TOLERANCES
from solvers.interface import solve, solvers
from workflows.io import write_csv
from workflows.problem_set import frictional_steps
from workflows.progress import study_progress


def step_rows(member, step: int, fstep, names: list[str], preset: str,
              time_limit: float) -> list[dict]:
    """Every solver of ``names`` on one tangential step ``fstep`` of the draw ``member``
    (:class:`workflows.problem_set.FrictionStep`), from zero: one row each."""
    params = dict(member.params)
    base = {"seed": member.seed, "draw": member.name, "problem": member.problem,
            "dim": fstep.qp.dim, "level": member.level, "n": fstep.qp.n, "m": fstep.qp.m,
            "law": params["friction"], "mu": params["mu"], "shift": params["shift"],
            "shift_steps": params["shift_steps"], "E2": params["E2"], "step": step,
            "preset": preset}
    rows = []
    for name in names:
        t0 = time.perf_counter()
        res = solve(fstep.qp, name, preset, time_limit=time_limit)
        finite = res.u is not None and bool(np.all(np.isfinite(res.u)))
        rows.append({
            **base, "solver": name, "status": res.status,
            "claimed_status": res.claimed_status, "iterations": res.iterations,
            "kkt_max": res.kkt.max if res.kkt is not None else np.nan,
            "energy_bound": res.gap.certified_bound if res.gap is not None else np.nan,
            "energy_bound_floor": res.gap.floor if res.gap is not None else np.nan,
            "energy_error": (energy_error(fstep.qp, res.u, fstep.solution.u)
                             if finite and res.status != "skipped" else np.nan),
            "fallback": bool(res.stats.get("fallback", False)),
            "wall_time": time.perf_counter() - t0, "message": res.message[:200]})
    return rows


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--first", type=int, default=500, help="the first seed (>= 0)")
    parser.add_argument("--draws", type=int, required=True, help="number of draws (>= 1)")
    parser.add_argument("--level", type=int, default=1,
                        help=f"mesh level of every draw (0 .. {MAX_LEVEL})")
    parser.add_argument("--preset", default="mid", choices=list(TOLERANCES),
                        help="every solver's preset")
    parser.add_argument("--solvers", nargs="*", default=None,
                        help="registered solvers (default: every one)")
    parser.add_argument("--time-limit", type=float, default=20.0,
                        help="seconds per solve (> 0)")
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    registered = sorted(solvers())
    if args.first < 0:
        parser.error(f"argument --first: {args.first} is not allowed; allowed: >= 0")
    if args.draws < 1:
        parser.error(f"argument --draws: {args.draws} is not allowed; allowed: >= 1")
    if not 0 <= args.level <= MAX_LEVEL:
        parser.error(f"argument --level: {args.level} is not allowed; allowed: 0 .. {MAX_LEVEL}")
    if args.time_limit <= 0:
        parser.error(f"argument --time-limit: {args.time_limit} is not allowed; allowed: > 0")
    names = registered if args.solvers is None else args.solvers
    unknown = [n for n in names if n not in registered]
    if unknown:
        parser.error(f"argument --solvers: {unknown} not allowed; allowed: "
                     f"{', '.join(registered)}")
    rows = []
    seeds = range(args.first, args.first + args.draws)
    for seed in study_progress(seeds, rule="hard_cases_random_friction", out=args.out,
                               desc="random frictional draws", unit="draw"):
        member = draw(seed, args.level)
        steps = frictional_steps(member.problem, member.params, member.level)
        ran = [row for k, fstep in steps.items()
               for row in step_rows(member, k, fstep, names, args.preset, args.time_limit)]
        rows += ran
        done = [r for r in ran if r["status"] != "skipped"]
        tqdm.write(f"{member.name} ({member.problem}, {len(steps)} steps): "
                   f"{sum(r['status'] == 'converged' for r in done)} of {len(done)} runs "
                   f"converged")
    write_csv(args.out, pd.DataFrame(rows))


if __name__ == "__main__":
    main()
