"""The exact reference, two ways, side by side: PDAS through the dual problem on the
contact rows (``method=schur``: ``A`` factorised once by a sparse Cholesky, the dense
``S = B A^-1 B^T`` from partial solves) against PDAS with a sparse LU of the reduced
KKT matrix at every active-set step (``method=kkt``, the suite's reference before).

Per level and method: verified status, KKT residuals, active-set steps, factorisation
backend and fill, factorisation and total time, peak memory; per level the largest
multiplier difference ``max|p_schur - p_kkt| / max|p_kkt|`` and the relative energy
norm of the displacement difference. Everything runs in this process, one solve after
the other (timings comparable). Called by the rule ``exact_reference``.

Example::

    python -m workflows.studies.exact_reference.run --problem circle_square --levels 1 2 3 \\
        --kkt-levels 1 2 3 --out results/circle_square/exact_reference_runs.csv
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import pandas as pd

from problems.kkt import energy_error
from solvers.interface import solve
from workflows.io import write_csv
from workflows.measure import peak_rss
from workflows.progress import study_progress
from workflows.scene_args import add_scene_arguments, check_levels, scene_from_args

METHODS = ("schur", "kkt")


def run(qp, method: str, time_limit: float) -> tuple[dict, object]:
    """One exact solve of ``qp`` by PDAS with ``method``: its row and result."""
    t0 = time.perf_counter()
    with peak_rss() as mem:
        res = solve(qp, "pdas", tol=1e-10, time_limit=time_limit, method=method)
    wall = time.perf_counter() - t0
    s = res.stats
    return {"method": method, "backend": s.get("factorization") or "splu",
            "status": res.status, "kkt_max": res.kkt.max, "steps": res.iterations,
            "factor_time": s.get("factor_time", np.nan), "total_time": wall,
            "peak_mb": mem["peak_mb"], "message": res.message}, res


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(parser)
    parser.add_argument("--levels", type=int, nargs="+", required=True)
    parser.add_argument("--kkt-levels", type=int, nargs="*", default=None,
                        help="levels where the KKT-LU PDAS runs beside (default: all)")
    parser.add_argument("--time-limit", type=float, default=900.0,
                        help="seconds per solve (> 0)")
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    spec, params = scene_from_args(parser, args)
    levels = check_levels(parser, spec, args.levels)
    kkt_levels = set(levels if args.kkt_levels is None else args.kkt_levels)
    if not kkt_levels <= set(levels):
        parser.error(f"argument --kkt-levels: {sorted(kkt_levels - set(levels))} not among "
                     f"--levels {levels}")
    if args.time_limit <= 0:
        parser.error(f"argument --time-limit: {args.time_limit} is not allowed; allowed: > 0")
    rows = []
    for level in study_progress(levels, rule="exact_reference", out=args.out,
                                desc=f"exact reference on {spec.name}"):
        qp = spec.build(level, params)
        base = {"scene_problem": spec.name, "level": level, "n": qp.n, "m": qp.m,
                "N": qp.n_nodes}
        fast, res_fast = run(qp, "schur", args.time_limit)
        rows.append({**base, **fast})
        if level in kkt_levels:
            slow, res_slow = run(qp, "kkt", args.time_limit)
            scale = max(float(np.abs(res_slow.p).max()), 1e-300)
            slow["p_difference"] = float(np.abs(res_fast.p - res_slow.p).max()) / scale
            slow["u_difference"] = energy_error(qp, res_fast.u, res_slow.u)
            slow["speedup"] = slow["total_time"] / fast["total_time"]
            rows.append({**base, **slow})
    write_csv(args.out, pd.DataFrame(rows))


if __name__ == "__main__":
    main()
