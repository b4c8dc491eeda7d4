"""The hard-case table and heat map (study hard_cases): per case and solver the verified
status, the worst KKT residual, the energy error against the reference and the time.

The hard cases are families of the contact QP test set; their rows come from the
test set's runs (``workflows/studies/test_set/run.py``), filtered to the configured
cases, levels and preset.

The table also checks the study's two promises on every row: a ``converged`` run
has KKT residuals and a certified energy bound within the tolerance
(``claim_ok``), and its answer is accurate against the reference
(``accurate``: energy error and S-norm multiplier error <= tolerance).

Alg. 8.4 towards incompressibility (``incompressibility``): the claims and the figure from
``workflows/studies/hard_cases/run.py``'s table. Claims, per scene: every run of the
solver's defaults (``robust``) converged and was verified; ``n_o`` at the largest ``nu`` is
at most twice ``n_o`` at the smallest (the suite's bar: Theorem 8.8's bounded n_o, allowing
a factor two over the whole range). The figure shows ``n_o`` and the V-cycles of a solve
against ``1 - 2 nu`` for both configurations, the plain V-cycle's ``kappa(V A)`` beside it.

The random frictional family's harder sample (``random-friction``): the claims from
``workflows/studies/hard_cases/random_friction.py``'s table (:func:`random_friction_claims`).

Example::

    python -m report.hard_cases random-friction \
        --table results/hard_cases/random_friction.csv --claims c.csv
    python -m report.hard_cases table --inputs runs/*.csv --cases hard_grazing:0 \
        --preset mid --table t.csv --heatmap h.png
    python -m report.hard_cases incompressibility \
        --table results/hard_cases/incompressibility.csv --claims c.csv --figure f.png
"""
from __future__ import annotations

import argparse
import textwrap

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.colors import ListedColormap

from report.claims import COLUMNS, Claim
from report.figures import save_figure
from workflows.io import read_csv, write_csv
from workflows.problem_set import plain_rows

#: n_o at the largest nu over n_o at the smallest, at most (Theorem 8.8's bounded n_o, with
#: a factor two of room over the whole range of nu).
GROWTH_BAR = 2.0

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
                                "hard cases: no run reported converged without meeting its "
                                "KKT tolerance and certified bound", "given", "0"),
    "converged_accurate": Claim("Ch. 8 (the solvers' stopping rules); suite bar: a verdict is never wrong",
                                "hard cases: every verified-converged run is accurate "
                                "against the reference", "given", "0",
                                details="energy and S-norm multiplier errors <= tol"),
    # the random frictional family's harder sample
    "rf_owned": Claim("suite bar (the suite's frictional solvers converge on every draw)",
                      "random frictional draws: the suite's frictional solvers verified "
                      "converged", "given", "all",
                      details="{solvers} at {preset}; {draws}; {fallbacks}"),
    "rf_within_bound": Claim("suite bar: a verdict is never wrong",
                             "random frictional draws: every converged run within its "
                             "certified bound of the reference", "given", "0",
                             details="the {taking} solvers that take the steps, at "
                                     "{preset}; {draws}; energy-norm distance to the exact "
                                     "reference (slack 1e-12)"),
    "rf_refuted": Claim("the libraries' own stopping tests",
                        "random frictional draws: claims the verification refutes",
                        unjudged="information: a refuted claim is reported inaccurate, "
                                 "never converged",
                        details="{refuting}; {draws}"),
    # Alg. 8.4 towards incompressibility
    "nu_converged": Claim("suite bar (every run of the defaults must count)",
                          "Alg. 8.4 verified converged at every Poisson ratio nu", "given",
                          "all", details="nu = {nus}"),
    "nu_growth": Claim("Theorem 8.8 (n_o bounded by the spectral equivalence of A-hat)",
                       "Alg. 8.4's outer steps n_o towards incompressibility", "<=",
                       GROWTH_BAR, details="n_o at nu = {hi:g} over n_o at nu = {lo:g}"),
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
    rows, cols, size = heatmap_layout(len(solvers), len(cases))
    fig, axes = plt.subplots(rows, cols, figsize=size, squeeze=False)
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
        ax.set_xlabel("solver", fontsize=8)
        ax.set_ylabel("hard case", fontsize=8)
        ax.set_title(title, fontsize=9)
        for (i, j), v in np.ndenumerate(vals):
            ax.text(j, i, _cell_text(v, panel) if np.isfinite(v) else "--", ha="center",
                    va="center", fontsize=6.5,
                    color=_ink(im.cmap(im.norm(v))) if np.isfinite(v) else "k")
        if panel == "status":
            shown = set(grid("status").stack())
            ax.legend(handles=[Patch(color=c, label=s) for s, c in
                               zip(STATUS_ORDER, STATUS_COLORS) if s in shown],
                      loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7,
                      title="status", title_fontsize=7)
        else:
            bar = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.02)
            bar.set_label(COLOURBAR_LABELS[panel], fontsize=7)
    preset = t["preset"].iloc[0]
    families = f"{len(cases)} famil{'y' if len(cases) == 1 else 'ies'}"
    fig.suptitle(textwrap.fill(f"Hard cases: {families}, preset {preset} (tol "
                               f"{t['tol'].iloc[0]:g}), every solver in its own process with "
                               "a hard time limit", width=int(13 * fig.get_figwidth())),
                 fontsize=10)
    blank = blank_columns(t)
    if blank:
        note = textwrap.fill("-- : no value (no solution, or a skip's time). "
                             + "; ".join(blank), width=int(14 * fig.get_figwidth()))
        fig.text(0.01, 0.0, note, fontsize=7, ha="left", va="top")
    save_figure(fig, path)


#: What the colour of each numeric panel of the heat map measures.
COLOURBAR_LABELS = {"kkt": "log10 KKT residual", "error": "log10 energy error",
                    "time": "log10 wall time [s]"}
#: The widest the heat map may be (inches at 130 dpi, about 1,430 pixels) for its 6.5 pt
#: cell text to stay legible in the report's frame (report.figure_audit).
HEATMAP_MAX_WIDTH = 11.0


def heatmap_layout(solvers: int, cases: int) -> tuple[int, int, tuple[float, float]]:
    """The heat map's panel grid and size: 2 x 2 while that fits
    :data:`HEATMAP_MAX_WIDTH`, else the four panels one under another, each as wide as its
    solvers' columns need (0.42 in a column, room for the case names and the key)."""
    panel = (1.9 + 0.42 * solvers + 1.1, 0.26 * cases + 2.0)
    if 2 * panel[0] <= HEATMAP_MAX_WIDTH:
        return 2, 2, (2 * panel[0], 2 * panel[1])
    return 4, 1, (panel[0], 4 * panel[1])


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


# ------------------------------------------ the random frictional family's harder sample
#: The suite's own frictional solvers: each must converge on every draw's every step.
OWNED_FRICTION = ("tresca_exact", "tnnmg", "semismooth_newton")
#: Round-off allowance of a converged run's distance to the reference over its bound.
BOUND_SLACK = 1e-12


def random_friction_claims(t: pd.DataFrame) -> pd.DataFrame:
    """The random frictional draws (``workflows/studies/hard_cases/random_friction.py``):
    the suite's frictional solvers (:data:`OWNED_FRICTION`) verified converged on every
    step, the draws that needed semismooth Newton's fallback named; every converged run of
    every solver within its certified bound of the exact reference; the claims the
    verification refuted, per solver (information)."""
    draws = t.drop_duplicates("seed")
    level = ", ".join(str(v) for v in sorted(draws.level.unique()))
    fields = dict(preset=", ".join(sorted(t.preset.unique())), level=level,
                  taking=t.loc[t.status != "skipped", "solver"].nunique(),
                  draws=(f"draws {draws.seed.min()}..{draws.seed.max()} ({len(draws)}: "
                         f"{int((draws.dim == 2).sum())} 2D, {int((draws.dim == 3).sum())} 3D), "
                         f"{len(t.drop_duplicates(['seed', 'step']))} steps"))
    owned = t[t.solver.isin(OWNED_FRICTION)]
    ok = int((owned.status == "converged").sum())
    fell_back = sorted(set(t.loc[t.fallback.astype(bool) & (t.solver == "semismooth_newton"),
                                 "draw"]))
    fallbacks = (f"semismooth Newton's fallback on {len(fell_back)} draws"
                 + (f": {', '.join(fell_back)}" if fell_back else ""))
    conv = t[t.status == "converged"]
    outside = int((conv.energy_error > conv.energy_bound + BOUND_SLACK).sum())
    refuted = t[(t.claimed_status == "converged") & (t.status != "converged")]
    per_solver = refuted.groupby("solver").size()
    runs = t[t.status != "skipped"].groupby("solver").size()
    refuting = ("per solver, of its runs: " + ", ".join(
        f"{name} {count} of {runs[name]}" for name, count in per_solver.items())
        if len(per_solver) else "no solver's claim refuted")
    return pd.DataFrame([
        CLAIMS["rf_owned"].row(f"{ok} of {len(owned)} runs", passed=ok == len(owned)
                               and len(owned) > 0, solvers=", ".join(OWNED_FRICTION),
                               fallbacks=fallbacks, **fields),
        CLAIMS["rf_within_bound"].row(f"{outside} of {len(conv)} converged runs outside",
                                      passed=outside == 0, **fields),
        CLAIMS["rf_refuted"].row(f"{len(refuted)} of {int(runs.sum())} runs",
                                 refuting=refuting, **fields)], columns=COLUMNS)


# ------------------------------------------------- Alg. 8.4 towards incompressibility
def incompressibility_claims(t: pd.DataFrame) -> pd.DataFrame:
    """Per scene: the robust runs all converged, and their n_o grows at most 2x over nu."""
    rows = []
    for scene, g in t[t.variant == "robust"].groupby("scene", sort=True):
        g = g.sort_values("nu")
        ok = int((g.status == "converged").sum())
        rows.append(CLAIMS["nu_converged"].row(f"{ok} of {len(g)}", passed=ok == len(g),
                                            scene=scene, nus=", ".join(f"{v:g}" for v in g.nu)))
        lo, hi = g.iloc[0], g.iloc[-1]
        judged = lo.status == hi.status == "converged" and len(g) > 1
        growth = hi.n_outer / lo.n_outer if judged else np.nan
        rows.append(CLAIMS["nu_growth"].row(growth, judged=bool(judged), scene=scene, hi=hi.nu,
                                         lo=lo.nu, reason="needs converged runs at the "
                                         "smallest and the largest nu"))
    return pd.DataFrame(rows, columns=COLUMNS)


def incompressibility_figure(t: pd.DataFrame, path: str) -> None:
    """n_o, V-cycles per solve and kappa(V A) against 1 - 2 nu, per scene and variant."""
    fig, ax = plt.subplots(1, 3, figsize=(12.5, 4.4))
    styles = {"robust": "o-", "vcycle": "s--"}
    for i, (scene, g) in enumerate(t.groupby("scene", sort=True)):
        for variant, h in g.groupby("variant"):
            h = h.sort_values("nu")
            x = 1.0 - 2.0 * h.nu
            done = h.status == "converged"
            label = f"{scene}, {variant}"
            ax[0].loglog(x, h.n_outer, styles.get(variant, "o-"), color=f"C{i}", label=label)
            ax[0].loglog(x[~done], h.n_outer[~done], "x", color="k", ms=9)
            ax[1].loglog(x, h.n_vcycles, styles.get(variant, "o-"), color=f"C{i}", label=label)
            if variant == "robust":
                ax[2].loglog(x, h.kappa_vcycle, "o-", color=f"C{i}",
                             label=f"{scene}: kappa(V A), one V-cycle")
                ax[2].loglog(x, h.gamma_bar, "^:", color=f"C{i}",
                             label=f"{scene}: gamma_bar of A-hat (Chebyshev)")
    if (t.status != "converged").any():
        ax[0].plot([], [], "x", color="k", label="not converged (max_iter)")
    for a, ylabel in zip(ax, ("outer steps n_o to KKT 1e-6", "V-cycles in the solve",
                              "spectral ratio")):
        a.set_xlabel("1 - 2 nu  (towards incompressibility ->)")
        a.set_ylabel(ylabel)
        a.invert_xaxis()
        a.grid(True, which="both", alpha=0.3)
        a.legend(fontsize=7)
    ax[0].set_title("Alg. 8.4: outer steps")
    ax[1].set_title("work per solve")
    ax[2].set_title("the V-cycle loses its equivalence")
    save_figure(fig, path)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    steps = ap.add_subparsers(dest="step", required=True)
    cases = steps.add_parser("table", help="the hard-case table and heat map")
    cases.add_argument("--inputs", nargs="+", required=True, help="the test set's run tables")
    cases.add_argument("--cases", nargs="*", default=None, metavar="FAMILY:LEVEL",
                       help="the hard cases (default: every row)")
    cases.add_argument("--preset", default=None, help="the preset shown (default: every row)")
    cases.add_argument("--table", required=True)
    cases.add_argument("--heatmap", required=True)
    nu = steps.add_parser("incompressibility",
                          help="Alg. 8.4 towards incompressibility: claims and figure")
    nu.add_argument("--table", required=True, help="the incompressibility runs")
    nu.add_argument("--claims", required=True)
    nu.add_argument("--figure", required=True)
    rf = steps.add_parser("random-friction",
                          help="the random frictional family's harder sample: claims")
    rf.add_argument("--table", required=True, help="the random frictional runs")
    rf.add_argument("--claims", required=True)
    args = ap.parse_args(argv)
    if args.step == "random-friction":
        write_csv(args.claims, random_friction_claims(read_csv(args.table)))
        return
    if args.step == "incompressibility":
        t = read_csv(args.table)
        write_csv(args.claims, incompressibility_claims(t))
        incompressibility_figure(t, args.figure)
        return
    t = table(args.inputs, args.cases, args.preset)
    if t.empty:
        raise SystemExit(f"no rows of the cases {args.cases} at preset {args.preset} in "
                         f"{args.inputs}")
    write_csv(args.table, t)
    heatmap(t, args.heatmap)


if __name__ == "__main__":
    main()
