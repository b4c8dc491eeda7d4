"""Solver comparison report for one scene: one tidy table, the preset mapping, the cost
growth (fitted exponents of time and memory against N, and the ratio to the linear
floor per level), two figures."""
from __future__ import annotations

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from report.figures import save_figure  # noqa: E402
from report.rates import fitted_slope  # noqa: E402
from solvers.interface import TOLERANCES, solvers  # noqa: E402
from workflows.io import read_csv, run_solvers, write_csv  # noqa: E402

MARKERS = {"converged": "o", "inaccurate": "x", "max_iter": "s", "time_limit": ">", "failed": "X",
           "skipped": "."}
LINES = {"low": ":", "mid": "--", "high": "-"}


FLOOR = "linear_floor"


def solver_colors(names) -> dict:
    """One distinct colour per solver (tab20: up to 20 before a colour repeats)."""
    return {name: plt.cm.tab20.colors[i % 20] for i, name in enumerate(sorted(names))}


def cost_table(table: pd.DataFrame) -> pd.DataFrame:
    """Per solver and preset: the fitted exponents of wall time and of peak memory
    against N over the levels it solved (verified or not, but not failed or cut
    short), and its time as a ratio to the linear floor at each level."""
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
        for _, r in grp.iterrows():
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



def times_figure(table: pd.DataFrame, path: str) -> None:
    """Wall time against problem size per solver and preset; markers show the verified status."""
    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    runs = table[table.preset != "reference"]
    colors = solver_colors(runs.solver.unique())
    for (solver, preset), grp in runs.groupby(["solver", "preset"]):
        grp = grp.sort_values("n")
        style = dict(color="k", lw=2, alpha=0.5) if solver == FLOOR else dict(color=colors[solver],
                                                                             lw=1)
        ax.loglog(grp["n"], grp["total_time"], LINES.get(preset, "-"), **style,
                  label=f"{solver} ({preset})")
        for _, r in grp.iterrows():
            ax.loglog(r["n"], r["total_time"], MARKERS.get(r["status"], "?"), color=colors[solver],
                      mfc="none" if r["status"] != "converged" else colors[solver], ms=6)
    n = np.array(sorted(runs["n"].unique()), dtype=float)
    t0 = runs[runs.n == n[0]]["total_time"].median()
    ax.loglog(n, t0 * n / n[0], ":", color="0.6", lw=1, label="slope 1 (O(N))")
    ax.set_xlabel("unknowns N (free DOFs)")
    ax.set_ylabel("wall time, setup + solve [s]")
    ax.set_title("Circle-square: time per solver and preset "
                 "(filled o = verified converged; x inaccurate, s max_iter, > time limit, X failed)",
                 fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6, ncol=2)
    save_figure(fig, path)


def work_precision_figure(table: pd.DataFrame, path: str) -> None:
    """Energy-norm error against time, one curve per solver and level (points = presets)."""
    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    runs = table[(table.preset != "reference") & (table.solver != FLOOR)
                 & np.isfinite(table.energy_error)]
    colors = solver_colors(runs.solver.unique())
    levels = sorted(runs.level.unique())
    styles = dict(zip(levels, ["-", "--", ":", "-.", (0, (1, 3))]))
    for (solver, level), grp in runs.groupby(["solver", "level"]):
        order = grp["preset"].map({k: i for i, k in enumerate(TOLERANCES)}).argsort()
        grp = grp.iloc[order]
        err = np.maximum(grp["energy_error"], 1e-16)
        ax.loglog(grp["total_time"], err, linestyle=styles[level], color=colors[solver], lw=1,
                  marker="o", ms=3, label=f"{solver}, level {level}")
    ax.set_xlabel("wall time, setup + solve [s]")
    ax.set_ylabel(r"energy-norm error $\|u-u_{ref}\|_A/\|u_{ref}\|_A$ (floored at 1e-16)")
    ax.set_title("Work-precision: presets low/mid/high along each curve; reference = exact PDAS",
                 fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6, ncol=2)
    save_figure(fig, path)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--inputs", nargs="+", required=True)
    ap.add_argument("--table", required=True)
    ap.add_argument("--presets", required=True)
    ap.add_argument("--times", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--costs", required=True)
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
    times_figure(table, args.times)
    work_precision_figure(table, args.work)


if __name__ == "__main__":
    main()
