"""Merge the per-case/side error tables; fit rates over the finest three levels.

Writes ``errors.csv`` (the default constrained side, columns case, variant,
level, h, ndof, err_h1, err_l2), ``errors_by_side.csv`` (both sides, with the
column ``constrained``) and ``rates.csv`` (case, variant, rate_h1, rate_l2 for
the default side, plus ``constrained`` rows for the other side below them).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from report.rates import rate_table
from workflows.io import provenance, write_csv, write_json


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("inputs", nargs="+")
    ap.add_argument("--default-side", default="coarse")
    ap.add_argument("--outdir", required=True)
    args = ap.parse_args(argv)
    out = Path(args.outdir)
    both = pd.concat([pd.read_csv(p) for p in args.inputs], ignore_index=True)
    both = both.sort_values(["constrained", "case", "variant", "level"], kind="stable")
    columns = ["case", "variant", "level", "h", "ndof", "err_h1", "err_l2"]
    default = both[both["constrained"] == args.default_side]
    write_csv(out / "errors_by_side.csv", both)
    write_csv(out / "errors.csv", default[columns])
    rates = rate_table(both, ["constrained", "case", "variant"],
                       {"err_h1": "rate_h1", "err_l2": "rate_l2"})
    rates["default_side"] = rates["constrained"] == args.default_side
    rates = rates.sort_values(["default_side", "constrained", "case", "variant"],
                              ascending=[False, True, True, True], kind="stable")
    write_csv(out / "rates.csv", rates[["case", "variant", "rate_h1", "rate_l2", "constrained",
                                        "levels"]])
    write_json(out / "provenance.json", provenance())


if __name__ == "__main__":
    main()
