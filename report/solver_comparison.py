"""Solver comparison report for one scene: one tidy table, the preset mapping, the cost
growth (fitted exponents of time and memory against N, and the ratio to the linear
floor per level), two figures."""
from __future__ import annotations

import argparse

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from report import charts
from report.figures import (PRESET_LINES, nothing_to_draw, save_figure,
                            solver_legend, solver_style)
from report.rates import fitted_slope
from solvers.interface import TOLERANCES, solvers
from workflows.io import read_csv, run_solvers, write_csv



FLOOR = "linear_floor"


def cost_table(table: pd.DataFrame) -> pd.DataFrame:
    """Per solver and preset: the fitted exponents of wall time and of peak memory
    against N over the levels it solved (verified or not, but not failed or cut
    short), and its time as a ratio to the linear floor at each level it ran (a skip's
    time is its refusal: no ratio)."""
    floor = table[table.solver == FLOOR].set_index(["level", "preset"])["total_time"]
    runs = table[~table.solver.isin([FLOOR]) & (table.preset != "reference")]
    rows = []
    for (solver, preset), grp in runs.groupby(["solver", "preset"]):
        ok = grp[~grp.status.isin(["failed", "time_limit", "skipped"])].sort_values("N")
        row = {"solver": solver, "preset": preset, "levels": len(ok),
               "converged": int((grp.status == "converged").sum()), "runs": len(grp),
               "time_exponent": fitted_slope(ok["N"], ok["total_time"], last=len(ok)),
               "memory_exponent": fitted_slope(ok["N"], ok["peak_mem_mb"], last=len(ok))
               if "peak_mem_mb" in ok else np.nan}
        for _, r in grp[grp.status != "skipped"].iterrows():
            key = (r["level"], preset)
            if key in floor.index and floor[key] > 0:
                row[f"floor_ratio_L{int(r['level'])}"] = r["total_time"] / floor[key]
        rows.append(row)
    return pd.DataFrame(rows)


def preset_table() -> pd.DataFrame:
    """How each solver maps the presets low/mid/high onto its own options."""
    rows = []
    registry = solvers()
    for name in run_solvers(registry):
        spec = registry[name]
        for preset, tol in TOLERANCES.items():
            rows.append({"solver": name, "preset": preset, "tol": tol,
                         "options": spec.presets.get(preset, "")})
    return pd.DataFrame(rows)



def _scene(table: pd.DataFrame) -> str:
    """The scene the table's runs come from (its ``scene_problem`` column)."""
    names = sorted(table["scene_problem"].dropna().unique()) if "scene_problem" in table else []
    return ", ".join(names) or "unknown scene"


def times_frame(table: pd.DataFrame) -> pd.DataFrame:
    """The data of the times figure: every solver run (the exact reference and the skipped
    runs left out: a skip's time is the refusal, not a solve) with its size n, preset,
    wall time, status and whether it is verified converged, sorted by solver, preset
    and n."""
    runs = table[(table.preset != "reference") & (table.status != "skipped")]
    runs = runs.sort_values(["solver", "preset", "n"])
    return pd.DataFrame({"solver": runs.solver, "preset": runs.preset, "level": runs.level,
                         "n": runs.n.astype(int), "total_time": runs.total_time.astype(float),
                         "status": runs.status, "verified": runs.status == "converged"}
                        ).reset_index(drop=True)


def times_figure(runs: pd.DataFrame, scene: str, path: str) -> None:
    """Wall time against problem size per solver and preset (``runs``:
    :func:`times_frame`): colour and marker the solver
    (:func:`report.figures.solver_style`), line style the preset, filled markers the
    verified-converged runs; the slope-1 guide only where there are two sizes or more.
    With one size the figure is a dot chart instead (:func:`_times_one_size`)."""
    if runs.empty:
        nothing_to_draw(path, f"{scene}: time per solver", "no solver ran on this scene")
        return
    sizes = np.array(sorted(runs["n"].unique()), dtype=float)
    if len(sizes) == 1:
        _times_one_size(runs, scene, path)
        return
    fig, ax = plt.subplots(figsize=(8.5, 4.8))
    for (solver, preset), grp in runs.groupby(["solver", "preset"]):
        style = solver_style(solver)
        lw = 2 if solver == FLOOR else 1
        ax.loglog(grp["n"], grp["total_time"], PRESET_LINES.get(preset, "-"), color=style["color"],
                  lw=lw, alpha=0.8)
        _status_points(ax, grp["n"], grp["total_time"], grp["verified"], style)
    t0 = runs[runs.n == sizes[0]]["total_time"].median()
    ax.loglog(sizes, t0 * sizes / sizes[0], ":", color="0.6", lw=1)
    ax.set_xlabel("unknowns N (free DOFs)")
    ax.set_ylabel("wall time, setup + solve [s]")
    ax.set_title(f"{scene}: time per solver and preset", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    lines = [(f"preset {p}", dict(ls=PRESET_LINES[p])) for p in PRESET_LINES
             if p in set(runs.preset)]
    lines.append(("slope 1 (O(N))", dict(ls=":", color="0.6")))
    solver_legend(ax, sorted(runs.solver.unique()), lines)
    save_figure(fig, path)


def _status_points(ax, x, y, verified, style: dict, **kw) -> None:
    """The points ``(x, y)`` in the solver's ``style``: filled where ``verified``, hollow
    where not."""
    ok = np.asarray(verified, dtype=bool)
    x, y = np.asarray(x), np.asarray(y)
    ax.plot(x[ok], y[ok], marker=style["marker"], color=style["color"], ms=6, ls="none", **kw)
    ax.plot(x[~ok], y[~ok], marker=style["marker"], color=style["color"], mfc="none", ms=6,
            ls="none", **kw)


def _times_one_size(runs: pd.DataFrame, scene: str, path: str) -> None:
    """The times at a single size as a dot chart: one row per solver (and preset, where
    there are several), fastest at the top, the time on a log axis; the linear floor as a
    vertical line across the rows."""
    n = int(runs["n"].iloc[0])
    several = runs["preset"].nunique() > 1
    rows = runs[runs.solver != FLOOR].sort_values("total_time", ascending=False)
    labels = [f"{r.solver} ({r.preset})" if several else r.solver for r in rows.itertuples()]
    fig, ax = plt.subplots(figsize=(8.5, 1.6 + 0.27 * len(rows)))
    y = np.arange(len(rows))
    for solver, idx in rows.groupby("solver").indices.items():
        _status_points(ax, rows["total_time"].to_numpy()[idx], y[idx],
                       rows["verified"].to_numpy()[idx], solver_style(solver))
    floor = runs[runs.solver == FLOOR]
    lines = []
    if len(floor):
        ax.axvline(float(floor["total_time"].min()), color="k", ls=":", lw=1.2)
        lines = [("linear floor: the same system without contact", dict(ls=":", color="k"))]
    ax.set_xscale("log")
    ax.set_yticks(y, labels, fontsize=8)
    ax.set_ylim(-0.7, len(rows) - 0.3)
    ax.set_xlabel("wall time, setup + solve [s]")
    ax.set_ylabel("solver" + (" (preset)" if several else ""))
    preset = "" if several else f", preset {runs['preset'].iloc[0]}"
    ax.set_title(f"{scene}: time per solver at one size, N = {n:,}{preset}", fontsize=9)
    ax.grid(True, which="both", axis="x", alpha=0.3)
    solver_legend(ax, [], lines)
    save_figure(fig, path)


def times_chart(runs: pd.DataFrame, scene: str) -> tuple[str, dict]:
    """The times figure as an interactive chart (note, Vega-Lite spec)."""
    spec = charts.solver_chart(
        runs, ("n", "unknowns N (free DOFs)", True),
        ("total_time", "wall time, setup + solve [s]", True),
        f"{scene}: time per solver and preset", tooltip=("preset", "level", "status"),
        line_by=("preset",), dash="preset", filled="verified")
    return ("Colour and shape: the solver; line style: the preset; hollow: not verified "
            "converged.", spec)


def work_frame(table: pd.DataFrame) -> pd.DataFrame:
    """The data of the work-precision figure: every solver run with an energy error
    against the exact reference (floored at 1e-16), presets in their order."""
    runs = table[(table.preset != "reference") & (table.solver != FLOOR)
                 & np.isfinite(table.energy_error)]
    runs = runs.assign(order=runs["preset"].map({k: i for i, k in enumerate(TOLERANCES)}))
    runs = runs.sort_values(["solver", "level", "order"])
    return pd.DataFrame({"solver": runs.solver, "level": runs.level.astype(int),
                         "preset": runs.preset, "total_time": runs.total_time.astype(float),
                         "energy_error": np.maximum(runs.energy_error.astype(float), 1e-16),
                         "status": runs.status, "verified": runs.status == "converged"}
                        ).reset_index(drop=True)


def work_precision_figure(runs: pd.DataFrame, scene: str, path: str) -> None:
    """Energy-norm error against time, one curve per solver and level (points = presets;
    ``runs``: :func:`work_frame`; filled: verified converged). Where every curve is one
    point (one preset), the points stand alone, each marked with its level where there
    are several, and the title says so."""
    if runs.empty:
        nothing_to_draw(path, f"{scene}: work-precision",
                        "no run has an energy error against the exact reference")
        return
    fig, ax = plt.subplots(figsize=(8.5, 4.8))
    levels = sorted(runs.level.unique())
    styles = dict(zip(levels, ["-", "--", ":", "-.", (0, (1, 3))]))
    curves = runs.groupby(["solver", "level"])
    lines = curves.size().max() > 1
    for (solver, level), grp in curves:
        style = solver_style(solver)
        if lines:
            ax.loglog(grp["total_time"], grp["energy_error"], linestyle=styles[level],
                      color=style["color"], lw=1)
        _status_points(ax, grp["total_time"], grp["energy_error"], grp["verified"], style)
        if not lines and len(levels) > 1:
            for x, y in zip(grp["total_time"], grp["energy_error"]):
                ax.annotate(f"L{level}", (x, y), xytext=(4, 2), textcoords="offset points",
                            fontsize=7, color=style["color"])
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time, setup + solve [s]")
    ax.set_ylabel(r"energy-norm error $\|u-u_{ref}\|_A/\|u_{ref}\|_A$ (floored at 1e-16)")
    along = ("presets low/mid/high along each curve" if lines else
             f"one preset ({', '.join(sorted(runs.preset.unique()))}): one point per solver"
             + (" and level (L)" if len(levels) > 1 else ""))
    ax.set_title(f"{scene}: work-precision, {along}; reference = exact PDAS", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    solver_legend(ax, sorted(runs.solver.unique()),
                  [(f"level {lv}", dict(ls=styles[lv])) for lv in levels])
    save_figure(fig, path)


def work_chart(runs: pd.DataFrame, scene: str) -> tuple[str, dict]:
    """The work-precision figure as an interactive chart (note, Vega-Lite spec)."""
    spec = charts.solver_chart(
        runs, ("total_time", "wall time, setup + solve [s]", True),
        ("energy_error", "energy-norm error ||u - u_ref||_A / ||u_ref||_A", True),
        f"{scene}: work-precision", tooltip=("preset", "level", "status"),
        line_by=("level",), filled="verified")
    return ("One line per solver and level through the presets low, mid, high; hollow: "
            "not verified converged.", spec)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--inputs", nargs="+", required=True)
    ap.add_argument("--table", required=True)
    ap.add_argument("--presets", required=True)
    ap.add_argument("--times", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--costs", required=True)
    ap.add_argument("--charts", default=None,
                    help="HTML: the times and work-precision as interactive charts")
    args = ap.parse_args(argv)
    table = pd.concat([read_csv(f) for f in args.inputs], ignore_index=True)
    keep = ["scene_problem", "level", "N", "n", "m", "solver", "preset", "tol", "status",
            "claimed_status", "failed_check",
            "iterations", "setup_time", "solve_time", "total_time", "wall_time",
            "kkt_stationarity", "kkt_primal", "kkt_dual", "kkt_complementarity", "kkt_max",
            "energy_bound", "energy_bound_floor", "pair_gap", "energy_error", "peak_mem_mb",
            "message"]
    table = table[[c for c in keep if c in table.columns]]
    write_csv(args.table, table)
    write_csv(args.presets, preset_table())
    write_csv(args.costs, cost_table(table))
    scene = _scene(table)
    times, work = times_frame(table), work_frame(table)
    times_figure(times, scene, args.times)
    work_precision_figure(work, scene, args.work)
    if args.charts:
        charts.write_page(args.charts, [c for c, data in ((times_chart(times, scene), times),
                                                          (work_chart(work, scene), work))
                                        if len(data)],
                          f"{scene}: solver times and work-precision, interactive")


if __name__ == "__main__":
    main()
