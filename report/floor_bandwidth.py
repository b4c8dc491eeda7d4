"""The linear floor against the machine: attained memory bandwidth of its V-cycle and PCG step.

Reads the runs of ``workflows/studies/floor_bandwidth/run.py`` for one scene and writes the
table (per level: bytes, median time, attained bandwidth and its share of the STREAM
triad's; the index arrays' share of the bytes; the most float32 values or a matrix-free
operator could gain) and a figure (bandwidth against N beside the triad's; bytes per
unknown by kind).

Example::

    python -m report.floor_bandwidth --runs results/circle_square/floor_bandwidth_runs.csv \\
        --table t.csv --figure f.png
"""
from __future__ import annotations

import argparse

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from report.figures import legend_outside, save_figure
from workflows.io import read_csv, write_csv


def bandwidth_table(runs: pd.DataFrame) -> pd.DataFrame:
    """One row per level: the measured bytes, times and bandwidths (the median run's,
    ``_low`` and ``_high`` from the slowest and the fastest run), and what they imply.

    ``vcycle_of_triad`` and ``cg_step_of_triad`` are the attained bandwidths over the
    triad's; ``index_share`` the V-cycle's bytes that are index arrays;
    ``float32_gain`` the V-cycle's bytes over what they would be with float32 matrix
    values, ``matrix_free_gain`` its bytes over its vectors' alone (an upper bound: a
    matrix-free operator still reads the mesh), both at the same attained bandwidth."""
    t = runs.sort_values("N").reset_index(drop=True)
    out = t[["level", "N", "n", "mg_levels", "operator_complexity"]].copy()
    for kind in ("vcycle", "cg_step"):
        out[f"{kind}_mb"] = t[f"{kind}_mb"]
        out[f"t_{kind}_ms"] = 1e3 * t[f"t_{kind}"]
        out[f"{kind}_gbs"] = t[f"{kind}_gbs"]
        out[f"{kind}_gbs_low"] = t[f"{kind}_mb"] / 1e3 / t[f"t_{kind}_max"]
        out[f"{kind}_gbs_high"] = t[f"{kind}_mb"] / 1e3 / t[f"t_{kind}_min"]
        out[f"{kind}_of_triad"] = t[f"{kind}_gbs"] / t["stream_triad_gbs"]
    out["stream_triad_gbs"] = t["stream_triad_gbs"]
    out["index_share"] = t["vcycle_indices_mb"] / t["vcycle_mb"]
    out["float32_gain"] = t["vcycle_mb"] / (t["vcycle_mb"] - t["vcycle_values_mb"] / 2)
    out["matrix_free_gain"] = t["vcycle_mb"] / t["vcycle_vectors_mb"]
    out["timing_repeats"] = t["timing_repeats"]
    return out


def figure(runs: pd.DataFrame, path: str) -> None:
    """Attained bandwidth against N beside the triad's; V-cycle bytes per unknown by kind."""
    t = runs.sort_values("N").reset_index(drop=True)
    table = bandwidth_table(t)           # the spread as the table gives it
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    for kind, style, color, label in (("vcycle", "o-", "tab:blue", "V-cycle"),
                                      ("cg_step", "s--", "tab:orange", "PCG step")):
        gbs = table[f"{kind}_gbs"]
        spread = [gbs - table[f"{kind}_gbs_low"], table[f"{kind}_gbs_high"] - gbs]
        left.errorbar(t.N, gbs, yerr=spread, fmt=style, color=color, capsize=3,
                      label=f"{label} (median, bars: slowest and fastest run)")
    left.set_xscale("log")
    triad = float(t.stream_triad_gbs.iloc[0])
    left.axhline(triad, color="black", lw=1,
                 label=f"STREAM triad, one core ({triad:.1f} GB/s)")
    fastest = float(table[["vcycle_gbs_high", "cg_step_gbs_high"]].to_numpy().max())
    # every point and bar in the lower half, the legend above them (a cache-resident level
    # may pass the triad)
    left.set_ylim(0, 1.9 * max(triad, fastest))
    left.set_xlabel("nodes N")
    left.set_ylabel("attained bandwidth [GB/s] (one thread)")
    left.set_title(f"bytes moved / time, {int(t.timing_repeats.iloc[0])} timed runs per "
                   "level", fontsize=9)
    left.grid(True, which="both", alpha=0.3)
    left.legend(fontsize=8, loc="upper left")
    x = np.arange(len(t))
    bottom = np.zeros(len(t))
    for col, color, label in (("vcycle_values_mb", "tab:blue", "matrix values"),
                              ("vcycle_indices_mb", "tab:gray", "index arrays"),
                              ("vcycle_vectors_mb", "tab:green", "vectors")):
        per_unknown = t[col].to_numpy() * 1e6 / t.n.to_numpy()
        right.bar(x, per_unknown, bottom=bottom, color=color, label=label)
        bottom += per_unknown
    right.set_xticks(x, [f"{lv}\nN = {n:,}" for lv, n in zip(t.level, t.N)], fontsize=8)
    right.set_xlabel("refinement level")
    right.set_ylabel("bytes per unknown and V-cycle [B]")
    right.set_title("what a V-cycle reads and writes", fontsize=9)
    legend_outside(right)
    fig.suptitle(f"The linear floor against the machine: {t.scene_problem.iloc[0]}, "
                 f"{int(t.dim.iloc[0])}D, geometric-multigrid PCG", fontsize=10)
    save_figure(fig, path)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", required=True)
    ap.add_argument("--table", required=True)
    ap.add_argument("--figure", required=True)
    args = ap.parse_args(argv)
    runs = read_csv(args.runs)
    write_csv(args.table, bandwidth_table(runs))
    figure(runs, args.figure)


if __name__ == "__main__":
    main()
