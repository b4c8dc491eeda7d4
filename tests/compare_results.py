"""Compare two regenerations' result tables, apart from what measures time or memory.

Every CSV under ``A/results`` and ``B/results`` (benchmark files aside) is read and
compared column by column after dropping the timing columns (:data:`TIMING`), the claims
about time (:data:`TIMING_CLAIM`), and the row order; a table only one run has is named.
Used by the tests (the solving jobs' tables of two tiny runs of one commit agree bit for
bit) and by hand, to show that a restructuring changed no result::

    python tests/compare_results.py OLD_CHECKOUT NEW_CHECKOUT

Exit status 0 if every table agrees, 1 otherwise (the differing tables and columns are
printed).
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

import pandas as pd

#: Columns that measure time, memory or the machine, not the mathematics (the only
#: ones two runs may disagree in).
TIMING = re.compile(r"(^|_)(t|s|cpu|wall|rss|mb|peak|memory|created|gbs)($|_)|time|seconds|"
                    r"speedup|floor_ratio|ratio_to_floor|of_triad|efficiency|tnnmg_over_petsc|"
                    r"^(rank|median_ratio|spread|shift|fastest)$")
#: Claims whose measured value is a time ratio or a time's growth, or a memory ratio.
TIMING_CLAIM = re.compile(r"T_solve|time|faster|fastest|speed|memory|efficiency")


def comparable(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` without what measures time or memory: timing columns, claims about time
    (their measured value is a time ratio or slope), and the row order (tables sorted
    by a time)."""
    frame = frame[[c for c in frame.columns if not TIMING.search(str(c))]]
    if "claim" in frame.columns:
        frame = frame[~frame["claim"].astype(str).str.contains(TIMING_CLAIM)]
    keys = [c for c in frame.columns if not measured(frame[c])]
    order = keys + [c for c in frame.columns if c not in keys]
    return frame.sort_values(order, key=lambda c: c.astype(str)).reset_index(drop=True)


def measured(column: pd.Series) -> bool:
    """Whether ``column`` holds measured reals (numbers, some not integers; blanks aside):
    sorted on after the others, so that two checkouts whose results differ in the last
    digits still pair the same rows (a scene, a level, a solver, a start, a count)."""
    values = pd.to_numeric(column.replace("", None), errors="coerce")
    given = column.astype(str) != ""
    return bool(values[given].notna().all() and (values[given] % 1 != 0).any())


def tables(root: Path) -> set[Path]:
    """The result tables of a checkout (relative paths)."""
    return {p.relative_to(root) for p in (root / "results").rglob("*.csv")
            if "benchmarks" not in p.parts}


def differences(a_root: Path, b_root: Path, only: set[Path] | None = None) -> dict[str, object]:
    """``{table: what differs}``: the columns that differ, a different shape, or a table
    only one checkout has; among the tables ``only`` (relative paths) where given."""
    a_tables, b_tables = tables(a_root), tables(b_root)
    if only is not None:
        a_tables, b_tables = a_tables & only, b_tables & only
    out: dict[str, object] = {str(p): "only in the first" for p in a_tables - b_tables}
    out.update({str(p): "only in the second" for p in b_tables - a_tables})
    for rel in sorted(a_tables & b_tables):
        a, b = (pd.read_csv(root / rel, keep_default_na=False) for root in (a_root, b_root))
        if list(a.columns) != list(b.columns) or len(a) != len(b):
            out[str(rel)] = f"columns or rows differ ({a.shape} against {b.shape})"
            continue
        a, b = comparable(a), comparable(b)
        if a.empty and b.empty:     # only timing rows (their blanks may change a dtype)
            continue
        cols = [c for c in a.columns if not a[c].equals(b[c])]
        if cols:
            out[str(rel)] = cols
    return out


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    a, b = map(Path, argv)
    found = differences(a, b)
    print(f"{len(tables(a) | tables(b))} tables; {len(found)} differ")
    for rel, what in sorted(found.items()):
        print(f"  {rel}: {what}")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
