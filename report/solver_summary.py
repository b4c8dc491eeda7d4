"""The solver summary across every scene, level and hard case, in the style of qpbenchmark.

Per solver and preset (qpbenchmark's conventions, adapted to the suite's verification):

* ``success_rate``: share of runs verified ``converged`` (the KKT residuals and
  the certified energy bound meet the preset's tolerance);
* ``correct_rate``: share of runs whose claim agrees with the verification (a
  claimed convergence that is verified, or a non-convergence the solver
  admitted); a solver that claims success and is refuted is not "correct";
* shifted geometric means (shift 10, over all runs) of the wall time, a failed or
  unverified run counting as the time limit (qpbenchmark's penalty), and of the
  worst KKT residual and the certified energy bound in units of the preset's
  tolerance (so that the shift 10 separates "within 10x of the target" from far
  off), a run without a solution counting as 1/tol;
* failures are counted, never dropped.

Performance profiles (Dolan and Moré, Math. Program. 91, 2002): for each
problem (scene, level; a hard case) the ratio of a solver's time to the best
verified time; a run that is not verified converged has an infinite ratio; the
curve is the share of problems solved within a factor tau of the best.
"""
from __future__ import annotations

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from report.figures import save_figure  # noqa: E402
from solvers.interface import TOLERANCES  # noqa: E402
from workflows.io import read_csv, write_csv  # noqa: E402

SHIFT = 10.0
SKIP = ("reference", "linear_floor")


def runs(inputs: list[str], time_limit: float) -> pd.DataFrame:
    """Every solver run of the inputs (solver tables and hard-case tables) as rows with
    ``problem`` (scene or case and level) and the penalised time."""
    frames = []
    for path in inputs:
        t = read_csv(path)
        label = t["case"] if "case" in t else t.get("scene_problem", pd.Series(["?"] * len(t)))
        t = t.assign(problem=label.astype(str) + " L" + t["level"].astype(str))
        frames.append(t)
    t = pd.concat(frames, ignore_index=True)
    t = t[(t.preset != "reference") & ~t.solver.isin(SKIP)].copy()
    t["time"] = t.get("wall_time", t["total_time"]).fillna(t["total_time"])
    verified = t["status"] == "converged"
    t["penalised_time"] = np.where(verified, t["time"], time_limit)
    t["correct"] = (t["claimed_status"] == "converged") == verified
    return t


def sgm(values, shift: float = SHIFT) -> float:
    """Shifted geometric mean ``exp(mean(log(v + shift))) - shift``."""
    v = np.asarray(values, dtype=float)
    return float(np.exp(np.mean(np.log(v + shift))) - shift) if v.size else float("nan")


def summary(t: pd.DataFrame) -> pd.DataFrame:
    """One row per solver and preset (see the module docstring)."""
    rows = []
    for (solver, preset), g in t.groupby(["solver", "preset"]):
        tol = TOLERANCES[preset]
        kkt = g["kkt_max"].fillna(1.0).clip(upper=1.0) / tol
        bound = (g["energy_bound"].fillna(1.0).clip(upper=1.0) / tol
                 if "energy_bound" in g else kkt)
        rows.append({"solver": solver, "preset": preset, "tol": tol,
                     "runs": len(g), "converged": int((g.status == "converged").sum()),
                     "inaccurate": int((g.status == "inaccurate").sum()),
                     "max_iter": int((g.status == "max_iter").sum()),
                     "time_limit": int((g.status == "time_limit").sum()),
                     "failed": int((g.status == "failed").sum()),
                     "skipped": int((g.status == "skipped").sum()),
                     "success_rate": float((g.status == "converged").mean()),
                     "correct_rate": float(g["correct"].mean()),
                     "sgm_time": sgm(g["penalised_time"]),
                     "sgm_kkt_over_tol": sgm(kkt), "sgm_energy_bound_over_tol": sgm(bound)})
    out = pd.DataFrame(rows)
    # qpbenchmark reports the time SGM relative to the best solver of the preset
    best = out.groupby("preset")["sgm_time"].transform("min")
    out["sgm_time_relative"] = out["sgm_time"] / best
    return out.sort_values(["preset", "sgm_time"]).reset_index(drop=True)


def performance_profiles(t: pd.DataFrame, path: str) -> None:
    """One panel per preset: share of problems solved (verified) within tau x the best."""
    presets = [p for p in TOLERANCES if p in set(t.preset)]
    fig, axes = plt.subplots(1, len(presets), figsize=(5.2 * len(presets), 4.4), squeeze=False)
    for ax, preset in zip(axes[0], presets):
        g = t[t.preset == preset]
        times = g.pivot_table(index="problem", columns="solver", values="time", aggfunc="first")
        ok = g.pivot_table(index="problem", columns="solver", values="status",
                           aggfunc="first") == "converged"
        times = times.where(ok.reindex_like(times).fillna(False))
        best = times.min(axis=1)
        ratio = times.div(best, axis=0).fillna(np.inf)
        taus = np.logspace(0, 3, 300)
        for i, solver in enumerate(sorted(ratio.columns)):
            share = [(ratio[solver] <= tau).mean() for tau in taus]
            ax.semilogx(taus, share, lw=1.5, label=solver, color=plt.cm.tab20.colors[i % 20],
                        linestyle=("-", "--")[i // 10 % 2])
        ax.set_xlabel("tau: time within this factor of the best verified")
        ax.set_ylabel("share of problems")
        ax.set_title(f"preset {preset} ({len(ratio)} problems)", fontsize=9)
        ax.set_ylim(0, 1.02)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    fig.suptitle("Performance profiles (Dolan-Moré) over every scene, level and hard case; "
                 "only verified runs count", fontsize=10)
    save_figure(fig, path)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--inputs", nargs="+", required=True,
                    help="solver tables (results/<scene>/solvers.csv) and hard-case tables")
    ap.add_argument("--time-limit", type=float, required=True,
                    help="the penalty time of an unverified run (the studies' time limit)")
    ap.add_argument("--summary", required=True)
    ap.add_argument("--profiles", required=True)
    args = ap.parse_args(argv)
    t = runs(args.inputs, args.time_limit)
    write_csv(args.summary, summary(t))
    performance_profiles(t, args.profiles)


if __name__ == "__main__":
    main()
