"""Every registered QP solver at every tolerance preset on one circle-square level.

The exact reference (PDAS to 1e-12) gives u_ref; each run records its verified
status, KKT residuals, time, iterations and the energy-norm error
||u - u_ref||_A / ||u_ref||_A. Failures and time-outs are rows, not gaps.
Called by the rule ``solver_comparison``.
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import pandas as pd
from tqdm import tqdm

from problems.spec import problems
from solvers.interface import TOLERANCES, solve, solvers
from workflows.io import write_csv


def energy_error(qp, u, u_ref) -> float:
    """||u - u_ref||_A / ||u_ref||_A."""
    e = u - u_ref
    return float(np.sqrt(max(e @ (qp.A @ e), 0.0) / (u_ref @ (qp.A @ u_ref))))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--problem", default="circle_square")
    ap.add_argument("--level", type=int, required=True)
    ap.add_argument("--solvers", nargs="+", default=None, help="default: every reference solver")
    ap.add_argument("--presets", nargs="+", default=list(TOLERANCES))
    ap.add_argument("--time-limit", type=float, default=600.0)
    ap.add_argument("--out", required=True)
    args = ap.parse_args(argv)
    qp = problems()[args.problem].make(args.level)
    t0 = time.perf_counter()
    ref = solve(qp, solver="pdas", tol=1e-12)
    t_ref = time.perf_counter() - t0
    if ref.status != "converged":
        raise SystemExit(f"exact reference failed at level {args.level}: {ref.status} {ref.message}")
    names = args.solvers or [n for n, s in solvers().items() if s.role in ("reference", "exact")]
    rows = [{"level": args.level, "n": qp.n, "m": qp.m, "preset": "reference", **ref.summary(),
             "energy_error": 0.0, "wall_time": t_ref}]
    for name in tqdm([(s, p) for s in names for p in args.presets], desc=f"solvers L{args.level}"):
        solver, preset = name
        t0 = time.perf_counter()
        res = solve(qp, solver=solver, tol=preset, time_limit=args.time_limit)
        rows.append({"level": args.level, "n": qp.n, "m": qp.m, "preset": preset, **res.summary(),
                     "energy_error": energy_error(qp, res.u, ref.u) if res.status != "failed" else np.nan,
                     "wall_time": time.perf_counter() - t0})
    write_csv(args.out, pd.DataFrame(rows))


if __name__ == "__main__":
    main()
