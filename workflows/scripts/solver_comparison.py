"""Every registered solver at every tolerance preset on one circle-square level.

The exact reference (PDAS to 1e-12) gives u_ref; each run records its verified
status, KKT residuals, time, iterations and the energy-norm error
||u - u_ref||_A / ||u_ref||_A. Failures and time-outs are rows, not gaps.
Called by the rule ``solver_comparison``.
"""
from __future__ import annotations

import argparse
import threading
import time
from contextlib import contextmanager

import numpy as np
import pandas as pd
from tqdm import tqdm

from problems.spec import problems
from solvers.interface import TOLERANCES, solve, solvers
from workflows.io import write_csv


@contextmanager
def peak_rss(interval: float = 0.005):
    """Sample the process's resident memory in a thread; yields a dict whose
    ``peak_mb`` is the peak increase over the start (MB) once the block exits.
    Sampling can miss spikes shorter than ``interval``."""
    import psutil

    proc = psutil.Process()
    base = proc.memory_info().rss
    out = {"peak_mb": 0.0}
    stop = threading.Event()

    def sample():
        peak = base
        while not stop.is_set():
            peak = max(peak, proc.memory_info().rss)
            stop.wait(interval)
        out["peak_mb"] = (max(peak, proc.memory_info().rss) - base) / 2 ** 20

    thread = threading.Thread(target=sample, daemon=True)
    thread.start()
    try:
        yield out
    finally:
        stop.set()
        thread.join()


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
    # the exact solver's run is the reference row; every other solver runs at every preset
    names = args.solvers or [n for n, s in solvers().items() if s.role in ("reference", "thesis")]
    rows = [{"level": args.level, "n": qp.n, "m": qp.m, "preset": "reference", **ref.summary(),
             "energy_error": 0.0, "wall_time": t_ref}]
    for name in tqdm([(s, p) for s in names for p in args.presets], desc=f"solvers L{args.level}"):
        solver, preset = name
        t0 = time.perf_counter()
        with peak_rss() as mem:
            res = solve(qp, solver=solver, tol=preset, time_limit=args.time_limit)
        rows.append({"level": args.level, "n": qp.n, "m": qp.m, "preset": preset, **res.summary(),
                     "energy_error": energy_error(qp, res.u, ref.u) if res.status != "failed" else np.nan,
                     "wall_time": time.perf_counter() - t0, "peak_mem_mb": mem["peak_mb"]})
    write_csv(args.out, pd.DataFrame(rows))


if __name__ == "__main__":
    main()
