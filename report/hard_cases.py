"""The hard-case table and heat map (study hard_cases): per case and solver the verified
status, the worst KKT residual, the energy error against the reference and the time.

The hard cases are families of the contact QP test set; their rows come from the
test set's runs (``workflows/scripts/problem_set_runs.py``), filtered to the configured
cases, levels and preset.

The table also checks the study's two promises on every row: a ``converged`` run
has KKT residuals and a certified energy bound within the tolerance
(``claim_ok``), and its answer is accurate against the reference
(``accurate``: energy error and S-norm multiplier error <= tolerance).
"""
from __future__ import annotations

import argparse
import textwrap

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.colors import ListedColormap  # noqa: E402

from report.claims import Claim  # noqa: E402
from report.figures import save_figure  # noqa: E402
from workflows.io import read_csv, write_csv  # noqa: E402
from workflows.problem_set import plain_rows  # noqa: E402

STATUS_ORDER = ("converged", "inaccurate", "max_iter", "time_limit", "failed", "skipped")
STATUS_COLORS = ("#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#d62728", "#c7c7c7")


def table(inputs: list[str], cases: list[str] | None = None,
          preset: str | None = None) -> pd.DataFrame:
    """The rows of ``cases`` (``family:level``) at ``preset`` (all rows if None), with the
    two promises checked per row."""
    t = plain_rows(pd.concat([read_csv(f) for f in inputs], ignore_index=True)).copy()
    if "case" not in t:
        t["case"] = t["family"]
    if "wall_time" not in t:
        t["wall_time"] = t["total_time"]
    if cases:
        wanted = {tuple(c.rsplit(":", 1)) for c in cases}
        t = t[[(c, str(lv)) in wanted for c, lv in zip(t["case"], t["level"])]]
    if preset:
        t = t[t["preset"] == preset]
    t = t.reset_index(drop=True)
    conv = t["status"] == "converged"
    bound_ok = t["energy_bound"] <= np.maximum(t["tol"], 4 * t["energy_bound_floor"])
    t["claim_ok"] = ~conv | ((t["kkt_max"] <= t["tol"]) & bound_ok)
    t["accurate"] = (t["energy_error"] <= t["tol"] * 1.001) & (
        t["multiplier_error_S"] <= t["tol"] * 1.001)
    return t


#: The verification's two promises on the hard cases (report/claims.py).
CLAIMS = {
    "no_false_converged": Claim("Ch. 8 (the solvers' stopping rules); suite bar: a verdict is never wrong",
                                "hard cases: no run reported converged without meeting its KKT "
                                "tolerance and certified bound", "given", "0"),
    "converged_accurate": Claim("Ch. 8 (the solvers' stopping rules); suite bar: a verdict is never wrong",
                                "hard cases: every verified-converged run is accurate against "
                                "the reference (energy and S-norm multiplier errors <= tol)",
                                "given", "0"),
}


def claims(t: pd.DataFrame) -> pd.DataFrame:
    """The two promises of the verification on the hard cases (claim, thesis, measured,
    bar, pass)."""
    conv = t["status"] == "converged"
    refuted = int((~t["claim_ok"].astype(bool)).sum())
    wrong = int((conv & ~t["accurate"].astype(bool)).sum())
    return pd.DataFrame([
        CLAIMS["no_false_converged"].row(f"{refuted} of {len(t)} runs", passed=refuted == 0),
        CLAIMS["converged_accurate"].row(
            f"{wrong} of {int(conv.sum())} converged runs inaccurate", passed=wrong == 0)])


def _cell_text(value: float, panel: str) -> str:
    """The short text of one heat-map cell: a status, a power of ten, a time."""
    if panel == "status":
        return STATUS_SHORT[STATUS_ORDER[int(value)]]
    if panel == "time":
        return f"{10 ** value:.2g}"
    return f"{value:.0f}"


def _ink(rgba) -> str:
    """Black on a light cell, white on a dark one (relative luminance)."""
    r, g, b = rgba[:3]
    return "k" if 0.2126 * r + 0.7152 * g + 0.0722 * b > 0.5 else "w"


#: The status panel's cell labels (short enough for one cell).
STATUS_SHORT = {"converged": "conv", "inaccurate": "inacc", "max_iter": "iter",
                "time_limit": "time", "failed": "fail", "skipped": "skip"}


def heatmap(t: pd.DataFrame, path: str) -> None:
    """Four panels: status (with its colour key), worst KKT residual, energy error, wall
    time. A cell without a value (no solution: skipped, failed, cut short) reads "--"; the
    footnote names the runs behind each blank column and why."""
    from matplotlib.patches import Patch
    cases = list(dict.fromkeys(t["case"]))
    solvers = sorted(t["solver"].unique())

    def grid(col):
        g = t.pivot_table(index="case", columns="solver", values=col, aggfunc="first")
        return g.reindex(index=cases, columns=solvers)

    solved = grid("status").isin(["converged", "inaccurate", "max_iter"])

    status = grid("status").apply(lambda c: c.map({s: i for i, s in enumerate(STATUS_ORDER)}))
    width = max(3.2, 0.55 * len(solvers) + 1.6)
    fig, axes = plt.subplots(2, 2, figsize=(2 * width + 1.5, 2 * (0.4 * len(cases) + 2.2)),
                             squeeze=False)
    panels = [(status, "status", "verified status",
               ListedColormap(STATUS_COLORS), (0, len(STATUS_ORDER) - 1)),
              (np.log10(grid("kkt_max").astype(float).clip(lower=1e-16)), "kkt",
               "log10 worst scaled KKT residual", "viridis", (-16, 0)),
              (np.log10(grid("energy_error").astype(float).clip(lower=1e-16)), "error",
               "log10 energy error vs the reference", "viridis", (-16, 0)),
              (np.log10(grid("wall_time").astype(float).clip(lower=1e-3)).where(
                  solved | grid("status").isin(["time_limit"])), "time",
               "wall time [s] (colour: log10)", "magma_r", None)]
    for ax, (data, panel, title, cmap, lim) in zip(axes.flat, panels):
        vals = data.to_numpy(dtype=float)
        im = ax.imshow(vals, cmap=cmap, aspect="auto",
                       vmin=None if lim is None else lim[0], vmax=None if lim is None else lim[1])
        ax.set_xticks(range(len(solvers)), solvers, rotation=45, ha="right", fontsize=7)
        ax.set_yticks(range(len(cases)), cases, fontsize=7)
        ax.set_title(title, fontsize=9)
        for (i, j), v in np.ndenumerate(vals):
            ax.text(j, i, _cell_text(v, panel) if np.isfinite(v) else "--", ha="center",
                    va="center", fontsize=6,
                    color=_ink(im.cmap(im.norm(v))) if np.isfinite(v) else "k")
        if panel == "status":
            ax.legend(handles=[Patch(color=c, label=s) for s, c in
                               zip(STATUS_ORDER, STATUS_COLORS)],
                      loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7,
                      title="status", title_fontsize=7)
        else:
            fig.colorbar(im, ax=ax, fraction=0.046, pad=0.02)
    preset = t["preset"].iloc[0]
    fig.suptitle(f"Hard cases: {len(cases)} families, preset {preset} (tol "
                 f"{t['tol'].iloc[0]:g}), every solver in its own process with a hard time "
                 "limit", fontsize=10)
    blank = blank_columns(t)
    if blank:
        note = textwrap.fill("-- : no value (no solution, or a skip's time). "
                             + "; ".join(blank), width=int(14 * fig.get_figwidth()))
        fig.text(0.01, 0.0, note, fontsize=7, ha="left", va="top")
    save_figure(fig, path)


def blank_columns(t: pd.DataFrame) -> list[str]:
    """Per solver without any energy error: its statuses and first message, the reason
    its columns are blank."""
    out = []
    for solver, g in t.groupby("solver"):
        if g["energy_error"].astype(float).notna().any():
            continue
        msg = next((str(m) for m in g.get("message", pd.Series(dtype=object)).dropna()
                    if str(m).strip()), "")
        statuses = ", ".join(sorted(set(g["status"])))
        out.append(f"{solver}: {statuses}"
                   + (f" ({textwrap.shorten(msg, 200, placeholder=' ...')})" if msg else ""))
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--inputs", nargs="+", required=True, help="the test set's run tables")
    ap.add_argument("--cases", nargs="*", default=None, metavar="FAMILY:LEVEL",
                    help="the hard cases (default: every row)")
    ap.add_argument("--preset", default=None, help="the preset shown (default: every row)")
    ap.add_argument("--table", required=True)
    ap.add_argument("--heatmap", required=True)
    args = ap.parse_args(argv)
    t = table(args.inputs, args.cases, args.preset)
    if t.empty:
        raise SystemExit(f"no rows of the cases {args.cases} at preset {args.preset} in "
                         f"{args.inputs}")
    write_csv(args.table, t)
    heatmap(t, args.heatmap)


if __name__ == "__main__":
    main()
