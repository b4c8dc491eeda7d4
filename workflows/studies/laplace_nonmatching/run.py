"""Errors of every variant of the non-matching Laplace problem, one case and side.

Called by the Snakemake rule ``laplace_errors``; writes one CSV atomically.
"""
from __future__ import annotations

import argparse
import time

import pandas as pd

from problems.laplace_nonmatching import CASES, VARIANTS, solve
from workflows.io import write_csv
from workflows.progress import study_progress


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--case", choices=CASES, required=True)
    ap.add_argument("--constrained", choices=("coarse", "fine"), required=True)
    ap.add_argument("--levels", type=int, nargs="+", required=True)
    ap.add_argument("--ratio", default="2:3")
    ap.add_argument("--out", required=True)
    args = ap.parse_args(argv)
    rows = []
    jobs = [(v, L) for v in VARIANTS for L in args.levels]
    for variant, level in study_progress(jobs, rule="laplace_errors", out=args.out,
                                          desc=f"laplace {args.case}/{args.constrained}",
                                          unit="solve"):
        t0 = time.perf_counter()
        sol = solve(level, case=args.case, variant=variant, ratio=args.ratio,
                    constrained=args.constrained)
        rows.append({**sol.record(), "ratio": args.ratio, "time": time.perf_counter() - t0})
    write_csv(args.out, pd.DataFrame(rows))


if __name__ == "__main__":
    main()
