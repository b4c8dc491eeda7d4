"""The thesis's solver table regenerated and the complexity claims of Ch. 8 checked.

Reads the tidy study CSV of ``workflows/studies/augmented_projection/run.py``
for one scene and, when the scene runs with the thesis's parameters, the
thesis's table (``--thesis reference/table_9_1.csv`` for circle-square,
Table 9.3 for cube-sphere); writes our table beside the thesis's, a claims
table (each claim, the measured number, the bar, pass/miss) and the figures
(T_solve against N: Figs. 9.1/9.6; kappa(S-hat) against N: Figs. 9.3/9.8; TNNMG's
steps, time and memory against the linear floor's).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from report.claims import Claim
from report.figures import (THESIS_COLOR, legend_below, save_figure, solver_shades,
                            solver_style)
from report.rates import fitted_slope as slope
from workflows.io import read_csv, write_csv

MAIN = "alg84"
#: Rows of the study that are not configurations of Alg. 8.4 (besides the ``amg_pcg_*`` floor).
NOT_VARIANTS = ("reference", "semismooth_newton", "tnnmg", "tnnmg_nested")
#: Truncated nonsmooth Newton multigrid's rows (suite bars for "close to one linear solve":
#: time to the target over the fastest linear multigrid-PCG solve at the finest level, 2D and
#: 3D; step growth).
TNNMG_ROWS = ("tnnmg", "tnnmg_nested")
TNNMG_TIME_BAR = {2: 2.0, 3: 2.5}
#: The fewest unknowns N at which TNNMG's time bars are judged: they are set for the
#: thesis's level-3 sizes (65,926 in 2D, 135,102 in 3D), where the floor's solve is no
#: longer dominated by its setup; below, the ratio is reported.
TNNMG_TIME_MIN_N = {2: 50_000, 3: 100_000}
TNNMG_MEMORY_BAR = 1.5
#: The linear floor TNNMG's figure and memory claim compare with (geometric multigrid-PCG).
FLOOR = "amg_pcg_gmg"


def read_thesis(path: str | Path | None) -> pd.DataFrame | None:
    """A thesis table (rows = uniform levels 1, 2, ...), or None without a path."""
    if path is None:
        return None
    t = pd.read_csv(path, comment="#")
    t.insert(0, "level", np.arange(1, len(t) + 1))
    return t


def time_to_target(df: pd.DataFrame) -> pd.Series:
    """Time to the energy-error target, including the coarse levels of nested iteration."""
    extra = df["t_coarse_levels"].fillna(0.0) if "t_coarse_levels" in df else 0.0
    return df["t_to_target"] + extra


def thesis_table(study: pd.DataFrame, thesis: pd.DataFrame | None,
                 config: str = MAIN) -> pd.DataFrame:
    """Our columns of the thesis's table for ``config`` beside its values (``thesis_*``).

    Outer steps and times are given at both tolerances of the thesis's tables
    (``n_outer_1e-02`` ...: Tables 9.3/9.4 count at 1e-2, Tables 9.1/9.2 at 1e-3);
    the thesis's columns name theirs.
    """
    ours = study[study.config == config].sort_values("level").reset_index(drop=True)
    keep = ["level", "N", "NC", "n_outer_1e-02", "n_outer_1e-03", "n_inner_mean",
            "t_solve_1e-02", "t_solve_1e-03", "t_setup", "t_proj_1e-02", "t_proj_1e-03",
            "kappa_S", "kappa_SinvS", "energy_error", "kkt_max", "stop_8_25", "status"]
    out = ours[[c for c in keep if c in ours.columns]].copy()
    if thesis is None:
        return out
    th = thesis.rename(columns={c: f"thesis_{c}".replace("1e-3", "1e-03").replace("1e-2", "1e-02")
                                for c in thesis.columns if c != "level"})
    return out.merge(th, on="level", how="left")


#: Ch. 8's claims for Alg. 8.4, its cost against a linear solve (reported: no published bar),
#: and TNNMG's bars (report/claims.py).
CLAIMS = {
    "n_outer": Claim("Theorem 8.8 (n_o independent of h)", "Alg. 8.4's outer steps n_o(eps) "
                     "do not grow with refinement", "<=", 0.15,
                     details="growth of n_o, second-finest -> finest level"),
    "kappa": Claim("Lemma 8.13", "kappa(S-hat) = O(h^-1): ratio per refinement", "in",
                   (1.5, 2.6), details="2 expected"),
    "kappa_stabilised": Claim("Sect. 7.5, (7.10)/(7.11)", "kappa(S-hat) of the stabilised "
                              "coupling: ratio per refinement",
                              unjudged="Lemma 8.13 bounds kappa for the nodal rows only: no "
                              "bar for the stabilised ones",
                              details="stabilised (7.10)/(7.11)"),
    "time": Claim("Example 8.1", "T_solve = O(N): fitted exponent of the solve time in N",
                  "<=", 1.15, details="slope of log {what} vs log N, finest three levels"),
    "vs_floor": Claim("suite figure (no published bar for Alg. 8.4 against a linear solve)",
                      "Alg. 8.4's time to the energy-error target over one linear solve",
                      unjudged="a measured figure: neither the thesis nor the suite sets a bar",
                      details="{label}: {config}, over the fastest AMG-PCG linear solve at N "
                      "= {N}; coarse levels of nested iteration included"),
    "tnnmg_steps": Claim("suite bar (TNNMG: multigrid steps do not grow with N)",
                         "{config}: steps to the energy-error target do not grow with N",
                         "<=", 0.15, details="growth, second-finest -> finest level"),
    **{f"tnnmg_time_{dim}d": Claim("suite bar (TNNMG: close to one linear solve)",
                                   "{config}: time to the energy-error target over one linear "
                                   "solve", "<=", bar, details="over the fastest AMG-PCG "
                                   "linear solve at N = {N}; coarse levels included")
       for dim, bar in TNNMG_TIME_BAR.items()},
    "tnnmg_memory": Claim("suite bar (TNNMG: in about the linear solve's memory)",
                          "tnnmg: peak memory over the linear solve's", "<=",
                          TNNMG_MEMORY_BAR, details="input + traced peak of the solve, over "
                          "the multigrid-PCG linear solve's, finest level"),
}


def claims(study: pd.DataFrame, config: str = MAIN) -> pd.DataFrame:
    """The checkable claims of Ch. 8 and the suite's bars, measured."""
    ours = study[study.config == config].sort_values("N")
    stabilised = "coupling" in study and bool((study["coupling"] == "stabilised").any())
    if "stop_8_25" in ours:  # a run cut short (max_iter, time limit) measures nothing
        ours = ours[ours["stop_8_25"].astype(bool)]
    rows = []
    if len(ours) >= 2:
        n_o = ours["n_outer"].to_numpy(float)
        rows.append(CLAIMS["n_outer"].row(n_o[-1] / n_o[-2] - 1))
        k = ours["kappa_S"].to_numpy(float)
        # C_r ~ h^(2 alpha) (7.11) makes a stabilised S itself worse than O(h^-1)
        rows.append(CLAIMS["kappa_stabilised" if stabilised else "kappa"].row(k[-1] / k[-2]))
    if len(ours) >= 3:
        # the stabilised rows' (8.25) point is short of the KKT tolerance (the estimate
        # sees the penalised rows' near-null direction late): timed to the energy target
        t = ours["t_to_target"] if stabilised else ours["t_setup"] + ours["t_solve"]
        what = ("time to the energy-error target (setup incl.), stabilised (7.10)/(7.11)"
                if stabilised else "T_solve (setup incl.)")
        rows.append(CLAIMS["time"].row(slope(ours["N"], t), what=what))
    finest = study[study.level == study.level.max()].assign(t_total=time_to_target)
    floor = finest[finest.config.str.startswith("amg_pcg")]
    if len(floor) and np.isfinite(floor["t_to_target"]).any():
        t_floor = floor["t_to_target"].min()
        runs = finest[~finest.config.isin(NOT_VARIANTS) & ~finest.config.str.startswith("amg_pcg")]
        best = runs.loc[[runs["t_total"].idxmin()]] if runs["t_total"].notna().any() else runs.iloc[:0]
        # the thesis claims O(N), bounded n_o and kappa(S-hat) = O(h^-1)
        # for Alg. 8.4 (checked above); its cost as a multiple of one linear multigrid solve
        # was never published, so it is a measured figure here, not a pass/miss bar (the
        # bar for "close to one linear solve" is TNNMG's, below)
        for label, row in ((config + " (Alg. 8.4 as written)", runs[runs.config == config]),
                           ("best configuration", best)):
            if not len(row):
                continue
            rows.append(CLAIMS["vs_floor"].row(float(row["t_total"].iloc[0] / t_floor),
                                               label=label, config=row["config"].iloc[0],
                                               N=int(row["N"].iloc[0])))
    rows += tnnmg_claims(study)
    return pd.DataFrame(rows)


def tnnmg_claims(study: pd.DataFrame) -> list[dict]:
    """TNNMG's bars: steps to the target grow by at most 15% from the second-finest to the
    finest level; time to the target (coarse levels included) over the fastest linear
    multigrid-PCG solve of the same system at the finest level."""
    rows = []
    for config in TNNMG_ROWS:
        ours = study[study.config == config].sort_values("N")
        ours = ours[ours["n_to_target"] > 0] if "n_to_target" in ours else ours.iloc[:0]
        if len(ours) >= 2:
            n = ours["n_to_target"].to_numpy(float)
            rows.append(CLAIMS["tnnmg_steps"].row(n[-1] / n[-2] - 1, config=config))
        finest = study[study.level == study.level.max()]
        floor = finest[finest.config.str.startswith("amg_pcg")]["t_to_target"]
        row = finest[finest.config == config]
        if len(row) and floor.notna().any() and np.isfinite(row["t_to_target"].iloc[0]):
            dim = int(finest["dim"].iloc[0]) if "dim" in finest else 2
            N = int(row["N"].iloc[0])
            rows.append(CLAIMS[f"tnnmg_time_{dim}d"].row(
                float(time_to_target(row).iloc[0] / floor.min()), config=config, N=N,
                judged=N >= TNNMG_TIME_MIN_N[dim],
                reason=f"the bar is judged from N = {TNNMG_TIME_MIN_N[dim]:,} (the "
                       "thesis's level-3 size it is set for)"))
    ratio = memory_ratio(study)
    if np.isfinite(ratio):
        rows.append(CLAIMS["tnnmg_memory"].row(ratio))
    return rows


def _memory(study: pd.DataFrame, config: str) -> pd.DataFrame:
    """``(N, mem_mb)`` of ``config``'s rows that measured memory: the input both hold plus
    the solve's traced peak."""
    if "mem_peak_mb" not in study:
        return pd.DataFrame(columns=["N", "mem_mb", "level"])
    rows = study[(study.config == config) & study["mem_peak_mb"].notna()].sort_values("N")
    return pd.DataFrame({"N": rows["N"], "mem_mb": rows["mem_input_mb"] + rows["mem_peak_mb"],
                         "level": rows["level"]})


def memory_ratio(study: pd.DataFrame) -> float:
    """TNNMG's peak memory over the multigrid-PCG linear solve's at the finest level both
    measured (nan without memory columns)."""
    ours, floor = _memory(study, "tnnmg"), _memory(study, FLOOR)
    if not (len(ours) and len(floor)):
        return np.nan
    both = ours.merge(floor, on="level", suffixes=("", "_floor"))
    if not len(both):
        return np.nan
    last = both.sort_values("N").iloc[-1]
    return float(last["mem_mb"] / last["mem_mb_floor"])


def figure_tnnmg(study: pd.DataFrame, path: str) -> None:
    """TNNMG against the linear floor level by level: steps to the energy-error target,
    time to it (coarse levels included) and peak memory against N, with the fitted
    exponents."""
    fig, axes = plt.subplots(1, 3, figsize=(12.5, 4.6))
    tnnmg = solver_style("tnnmg")
    lines = [("tnnmg", dict(**tnnmg, ls="-"), "TNNMG from zero"),
             ("tnnmg_nested", dict(**tnnmg, ls="--", mfc="none"), "TNNMG, nested iteration"),
             (FLOOR, dict(color="k", ls=":"), "multigrid-PCG, no contact (floor)")]
    for config, style, label in lines:
        grp = study[(study.config == config) & (study["n_to_target"] > 0)].sort_values("N")
        if not len(grp):
            continue
        axes[0].semilogx(grp["N"], grp["n_to_target"], ms=5, label=label, **style)
        t = time_to_target(grp)
        axes[1].loglog(grp["N"], t, ms=5,
                       label=f"{label}, exponent {slope(grp['N'], t):.2f}", **style)
        mem = _memory(study, config)
        if len(mem):
            axes[2].loglog(mem["N"], mem["mem_mb"], ms=5, **style,
                           label=f"{label}, exponent {slope(mem['N'], mem['mem_mb']):.2f}")
    n = np.array([study["N"].min(), study["N"].max()], float)
    floor = study[(study.config == FLOOR) & (study["n_to_target"] > 0)].sort_values("N")
    if len(floor):
        t0 = float(time_to_target(floor).iloc[0])
        axes[1].loglog(n, t0 * n / n[0], color="0.6", lw=1, label="slope 1 guide")
    axes[0].set_ylabel("steps to the energy-error target")
    axes[1].set_ylabel("time to the target [s]\n(setup and coarse levels included)")
    axes[2].set_ylabel("peak memory [MB]\n(input + traced peak of the solve)")
    for ax in axes:
        ax.set_xlabel("nodes N")
        ax.grid(True, which="both", alpha=0.3)
        legend_below(ax)
    axes[0].set_ylim(bottom=0)
    fig.suptitle("Truncated nonsmooth Newton multigrid against the linear multigrid-PCG "
                 "solve of the same system (exponents: least-squares fit of log-log)",
                 fontsize=9)
    save_figure(fig, path)


def _time_series(config: str, grp: pd.DataFrame, variants: list[str]) -> tuple:
    """One configuration's curve of the time figure: (times, plot keywords, label). A
    solver's rows wear its colour and marker (:func:`report.figures.solver_style`); the
    configurations of Alg. 8.4 the shades of ``augmented_projection``'s colour
    (:func:`report.figures.solver_shades`: ``variants`` in order, :data:`MAIN` first), each
    with its own line style; the linear floors black."""
    if config.startswith("amg_pcg"):
        return (time_to_target(grp), dict(color="k", ls=":" if config.endswith("gmg") else "-."),
                f"{config} (linear solve, no contact; floor)")
    if config in TNNMG_ROWS:
        style = solver_style("tnnmg")
        nested = config != "tnnmg"
        return (time_to_target(grp), dict(**style, ls="--" if nested else "-",
                                          mfc="none" if nested else style["color"]),
                f"{config} (TNNMG, not Alg. 8.4; time to the target)")
    if config in NOT_VARIANTS:
        return (grp["t_setup"] + grp["t_solve"], dict(**solver_style(config), ls="-."),
                f"{config} (not Alg. 8.4; to its certified stop at the target)")
    coarse = grp["t_coarse_levels"].fillna(0.0) if "t_coarse_levels" in grp else 0.0
    k = variants.index(config)
    colour = solver_shades("augmented_projection", len(variants))[k]
    return (grp["t_setup"] + grp["t_solve"] + coarse,
            dict(color=colour, marker=solver_style("augmented_projection")["marker"],
                 ls=VARIANT_LINES[k % len(VARIANT_LINES)], mfc=colour if k == 0 else "none"),
            config)


#: Line styles of Alg. 8.4's configurations in the time figure (the main one solid).
VARIANT_LINES = ("-", "--", "-.", ":")


def figure_time(study: pd.DataFrame, thesis: pd.DataFrame | None, path: str) -> None:
    """T_solve against N (log-log; Figs. 9.1, 9.6): our configurations, the multigrid-PCG
    floor, the thesis; the legend below the axes."""
    fig, ax = plt.subplots(figsize=(9, 5.6))
    rows = study[study.config != "reference"]
    configs = sorted(rows.config.unique())
    variants = [MAIN] + [c for c in configs if c != MAIN and c not in NOT_VARIANTS
                         and not c.startswith("amg_pcg")]
    for config, grp in rows.groupby("config"):
        grp = grp.sort_values("N")
        t, kw, label = _time_series(config, grp, variants)
        ax.loglog(grp["N"], t, ms=4, label=f"{label}, slope {slope(grp['N'], t):.2f}", **kw)
    if thesis is not None:
        col = next(c for c in thesis.columns if c.startswith("t_solve"))
        ax.loglog(thesis["nodes"], thesis[col], "^-", color=THESIS_COLOR, ms=5,
                  label=f"thesis ({col}), slope {slope(thesis['nodes'], thesis[col]):.2f}")
    n = np.array([study["N"].min(), study["N"].max()], float)
    main = study[study.config == MAIN].sort_values("N")
    if len(main):
        t0 = float((main["t_setup"] + main["t_solve"]).iloc[0])
        ax.loglog(n, t0 * n / n[0], color="0.6", lw=1, label="slope 1 guide")
    ax.set_xlabel("nodes N")
    ax.set_ylabel("T_solve incl. setup [s]\n(floor: time to the same energy error)")
    ax.set_title("Solve time against N (Figs. 9.1/9.6; slopes over the finest three levels; "
                 "thesis on its 1999 machine)", fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    legend_below(ax, ncol=2)
    save_figure(fig, path)


def figure_kappa(study: pd.DataFrame, thesis: pd.DataFrame | None, path: str) -> None:
    """kappa(S-hat) against N (Figs. 9.3, 9.8) with the O(h^-1) guide and the thesis's values."""
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for config, grp in study[study.config.isin([MAIN])].groupby("config"):
        grp = grp.sort_values("N")
        ax.loglog(grp["N"], grp["kappa_S"], "o-", label=f"kappa(S-hat), {config}")
        if "kappa_SinvS" in grp and np.isfinite(grp["kappa_SinvS"]).any():
            ax.loglog(grp["N"], grp["kappa_SinvS"], "s--", label="kappa(S-hat^-1 S)")
        n = grp["N"].to_numpy(float)
        d = int(grp["dim"].iloc[0]) if "dim" in grp else 2
        ax.loglog(n, grp["kappa_S"].iloc[0] * (n / n[0]) ** (1 / d), color="0.6", lw=1,
                  label=f"O(h^-1) = O(N^1/{d}) guide")
    if thesis is not None and "kappa_S" in thesis:
        ax.loglog(thesis["nodes"], thesis["kappa_S"], "^-", color=THESIS_COLOR, label="thesis")
    ax.set_xlabel("nodes N")
    ax.set_ylabel("condition number (Lanczos)")
    ax.set_title("kappa(S-hat) against N (Figs. 9.3/9.8, Lemma 8.13)", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    save_figure(fig, path)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--study", required=True)
    ap.add_argument("--thesis", default=None, help="the thesis's table (reference/*.csv)")
    ap.add_argument("--table", required=True)
    ap.add_argument("--claims", required=True)
    ap.add_argument("--fig-time", required=True, dest="fig_time")
    ap.add_argument("--fig-kappa", required=True, dest="fig_kappa")
    ap.add_argument("--fig-tnnmg", required=True, dest="fig_tnnmg")
    args = ap.parse_args(argv)
    study = read_csv(args.study)
    thesis = read_thesis(args.thesis)
    write_csv(args.table, thesis_table(study, thesis))
    write_csv(args.claims, claims(study))
    figure_time(study, thesis, args.fig_time)
    figure_kappa(study, thesis, args.fig_kappa)
    figure_tnnmg(study, args.fig_tnnmg)


if __name__ == "__main__":
    main()
