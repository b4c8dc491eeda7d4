"""The solver summary over the contact QP test set, in the style of qpbenchmark.

Inputs are the test set's run tables (``workflows/studies/test_set/run.py``: one per
family and size class; every registered solver at every preset, each problem's
exact reference exported beside it). Broken down overall, by size class and by
scene (the registered problem behind a family); one work-precision figure per
family (energy error against time, every solver, one panel per level).

The leaderboards (:mod:`report.leaderboard`): one per problem class, size class and preset,
each solver timed at matched accuracy over its tolerance ladder, the exact references
apart; a Markdown results page per class with the settings beside the tables.

The tables below read each solver's plain run (rung 0 of its ladder, the preset's own
mapping), per problem class (``problem_class``) and solver and preset
(qpbenchmark's conventions, adapted to the suite's verification):

* ``success_rate``: share of runs verified ``converged`` (the KKT residuals and
  the certified energy bound meet the preset's tolerance);
* ``correct_rate``: share of runs whose claim is true against the exact reference:
  a claimed convergence whose energy error ``||u - u_ref||_A / ||u_ref||_A`` is
  within what the verification certifies at the preset's tolerance (the tolerance, or
  the certified bound's floating-point floor where that is higher, ~1e-7 relative at
  ``high``; :func:`accurate_runs`), or a non-convergence the solver admitted (a
  solver that claims success and is wrong is not "correct");
* shifted geometric means (shift 10, over all runs) of the plain run's wall time, a
  failed or unverified run counting as the time limit (qpbenchmark's penalty: its
  numbers, the leaderboards rank the time at matched accuracy), and of the worst KKT
  residual and the certified energy bound in units of the preset's tolerance (so that
  the shift 10 separates "within 10x of the target" from far off), a run without a
  solution counting as 1/tol;
* failures are counted, never dropped.

Cold against warm starts (:func:`warm_frame`): the tables above read the runs started
from zero (``start`` ``cold``); a frictional step with a recorded warm start (the previous
load step's reference) is also run from it (``warm``), and per solver and preset the
median and total iterations and times of the two, their ratios (warm / cold) and the
verified convergences of each are compared over those steps, with whether the solver
used the guess. The faceted friction law's trade-off (:func:`facet_frame`): per faceted
step beside its isotropic twin, the model error of the k-gon law and per solver the
status and time on the faceted QP against the isotropic cone program.

Performance profiles (Dolan and Moré, Math. Program. 91, 2002), one panel per problem
class and preset: for each problem the ratio of a contestant's time at matched accuracy
to the best contestant's; a problem its ladder did not verify has an infinite ratio; the
curve is the share of problems solved within a factor tau of the best. The work-precision
figures draw each solver's ladder on a family's problem as a line (energy error against
time, one point per rung; the counted rung's time the median of its repeats).
"""
from __future__ import annotations

import argparse

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from report import charts, leaderboard
from report.claims import COLUMNS, Claim
from report.figures import (nothing_to_draw, save_figure, solver_legend,
                            solver_style)
from solvers.base import GUESS_NOT_USED
from solvers.interface import TOLERANCES, solvers
from workflows.io import read_csv, write_csv, write_text
from workflows.problem_set import PROBLEM_CLASSES, cold_rows, plain_rows

#: The problem classes' order in the figures and tables.
CLASS_ORDER = {c: i for i, c in enumerate(PROBLEM_CLASSES)}

SHIFT = 10.0
SKIP = ("reference", "linear_floor")
def runs(inputs: list[str], time_limit: float) -> pd.DataFrame:
    """Every solver run of the test set's run tables, cold and warm (``start``; a table
    without the column is all cold), every rung of the ladders (a table without the
    column: rung 0 only), with the penalised time and whether the claim is correct
    against the reference."""
    t = pd.concat([read_csv(path) for path in inputs], ignore_index=True)
    t = t[~t.solver.isin(SKIP)].copy()
    if "start" not in t:
        t["start"] = "cold"
    t["start"] = t["start"].fillna("cold")
    for column, default in (("rung", 0), ("counted", False), ("time_median", np.nan),
                            ("time_min", np.nan), ("time_max", np.nan)):
        if column not in t:
            t[column] = default
    t["rung"] = t["rung"].fillna(0).astype(int)
    t["scene"] = t["scene_problem"]
    t["time"] = t["total_time"]
    verified = t["status"] == "converged"
    t["penalised_time"] = np.where(verified, t["time"], time_limit)
    claimed = t["claimed_status"] == "converged"
    accurate = accurate_runs(t)
    t["correct"] = np.where(claimed, accurate, True)
    return t


#: Runs whose energy error against the exact reference is within what the verification
#: certifies at their tolerance: ``tol``, or the certified bound's floating-point floor
#: where that is higher (~1e-7 relative at the ``high`` preset;
#: :func:`solvers.certificate.certifiable`).
accurate_runs = leaderboard.accurate


def summary(t: pd.DataFrame, by: tuple[str, ...] = ()) -> pd.DataFrame:
    """One row per solver and preset (and per value of the columns ``by``; see the module
    docstring)."""
    rows = []
    keys = [*by, "solver", "preset"]
    for values, g in t.groupby(keys):
        group = dict(zip(keys, values))
        preset = group["preset"]
        tol = TOLERANCES[preset]
        kkt = g["kkt_max"].fillna(1.0).clip(upper=1.0) / tol
        bound = (g["energy_bound"].fillna(1.0).clip(upper=1.0) / tol
                 if "energy_bound" in g else kkt)
        rows.append({**group, "tol": tol, "problems": g["problem"].nunique(),
                     "runs": len(g), "converged": int((g.status == "converged").sum()),
                     "inaccurate": int((g.status == "inaccurate").sum()),
                     "max_iter": int((g.status == "max_iter").sum()),
                     "time_limit": int((g.status == "time_limit").sum()),
                     "failed": int((g.status == "failed").sum()),
                     "skipped": int((g.status == "skipped").sum()),
                     "success_rate": float((g.status == "converged").mean()),
                     "correct_rate": float(g["correct"].mean()),
                     "sgm_time": leaderboard.sgm(g["penalised_time"], SHIFT),
                     "sgm_kkt_over_tol": leaderboard.sgm(kkt, SHIFT),
                     "sgm_energy_bound_over_tol": leaderboard.sgm(bound, SHIFT)})
    out = pd.DataFrame(rows)
    # qpbenchmark reports the time SGM relative to the best solver of the preset
    best = out.groupby([*by, "preset"])["sgm_time"].transform("min")
    out["sgm_time_relative"] = out["sgm_time"] / best
    return out.sort_values([*by, "preset", "sgm_time"]).reset_index(drop=True)


#: The performance profiles' range of tau (time within tau x the best verified).
TAU_MAX = 1e3


def profile_frame(t: pd.DataFrame, roles: dict[str, str]) -> pd.DataFrame:
    """The performance profiles as data (problem_class, preset, solver, tau, share,
    problems): per class, preset and contestant (the exact references are the baseline,
    not profiled), the share of problems verified within ``tau`` x the best contestant's
    time at matched accuracy (:func:`report.leaderboard.matched_times`), at tau = 1, at
    every finite ratio up to :data:`TAU_MAX` and at :data:`TAU_MAX` (a step curve: the
    share holds until the next tau). ``t``: cold runs."""
    rows = []
    times = leaderboard.matched_times(t)
    times = times[~times["solver"].map(lambda s: leaderboard.is_reference(s, roles))]
    order = {p: i for i, p in enumerate(TOLERANCES)}
    for (cls, preset), g in sorted(times.groupby(["problem_class", "preset"]),
                                   key=lambda kv: (CLASS_ORDER[kv[0][0]], order[kv[0][1]])):
        pivot = g.pivot_table(index="problem", columns="solver", values="time",
                              aggfunc="first", dropna=False)
        ratio = pivot.div(pivot.min(axis=1), axis=0).fillna(np.inf)
        for solver in sorted(ratio.columns):
            r = ratio[solver].to_numpy(float)
            taus = np.unique([1.0, *r[np.isfinite(r) & (r <= TAU_MAX)], TAU_MAX])
            rows += [{"problem_class": cls, "preset": preset, "solver": solver,
                      "tau": float(tau), "share": float((r <= tau).mean()),
                      "problems": len(r)} for tau in taus]
    return pd.DataFrame(rows, columns=["problem_class", "preset", "solver", "tau", "share",
                                       "problems"])


def performance_profiles(profiles: pd.DataFrame, path: str) -> None:
    """One panel per problem class and preset: share of problems verified within tau x the
    best contestant's time at matched accuracy (``profiles``: :func:`profile_frame`)."""
    panels = profiles[["problem_class", "preset"]].drop_duplicates().values.tolist()
    if not panels:
        nothing_to_draw(path, "Performance profiles over the contact QP test set",
                        "no solver ran on the test set")
        return
    cols = min(len(panels), 2)
    rows_ = -(-len(panels) // cols)
    fig, axes = plt.subplots(rows_, cols, figsize=(4.8 * cols, 4.0 * rows_), squeeze=False)
    for ax, (cls, preset) in zip(axes.flat, panels):
        g = profiles[(profiles.problem_class == cls) & (profiles.preset == preset)]
        for solver, curve in g.groupby("solver"):
            style = solver_style(solver)
            ax.semilogx(curve.tau, curve.share, lw=1.5, color=style["color"],
                        drawstyle="steps-post")
            ax.semilogx(curve.tau.iloc[:-1], curve.share.iloc[:-1], marker=style["marker"],
                        color=style["color"], ms=4, ls="none")
        ax.set_xlabel("tau: time within this factor of the best (matched accuracy)")
        ax.set_ylabel("share of problems")
        ax.set_title(f"{PROBLEM_CLASSES[cls]}\npreset {preset} "
                     f"({int(g.problems.max())} problems)", fontsize=9)
        ax.set_xlim(1.0, TAU_MAX)
        ax.set_ylim(0, 1.02)
        ax.grid(True, which="both", alpha=0.3)
    for ax in list(axes.flat)[len(panels):]:
        ax.set_visible(False)
    solver_legend(axes.flat[cols - 1], sorted(profiles.solver.unique()), status=False,
                  axes=list(axes.flat)[:len(panels)])
    fig.suptitle("Performance profiles (Dolan-Moré) per problem class: time at matched "
                 "accuracy (tolerance ladder), only verified runs count; the exact references "
                 "are the baseline, not profiled", fontsize=10)
    save_figure(fig, path)


def profiles_chart(profiles: pd.DataFrame) -> tuple[str, dict]:
    """The performance profiles as an interactive chart (note, Vega-Lite spec)."""
    spec = charts.solver_chart(
        profiles.assign(panel=profiles.problem_class + ", " + profiles.preset),
        ("tau", "tau: time within this factor of the best (matched accuracy)", True),
        ("share", "share of problems", False),
        "Performance profiles (Dolan-Moré) per problem class",
        tooltip=("preset", "problems"), facet="panel", interpolate="step-after")
    return ("One panel per problem class and preset: the share of problems each contestant "
            "solves, verified converged over its tolerance ladder, within tau times the "
            "best contestant's time at matched accuracy.", spec)


def work_frame(t: pd.DataFrame, family: str) -> pd.DataFrame:
    """The work-precision data of one family: every cold run with an energy error against
    the exact reference, every rung of every ladder (level, n, solver, preset, rung, time:
    the median of the repeats on the counted rung, else the one run's; energy_error floored
    at 1e-16, verified, status, problem), sorted by level, solver, preset and rung."""
    g = t[(t.family == family) & np.isfinite(t.energy_error.astype(float))]
    g = g.assign(order=g.preset.map({p: k for k, p in enumerate(TOLERANCES)}))
    g = g.sort_values(["level", "solver", "order", "rung"])
    time = np.where(g["counted"].fillna(False).astype(bool), g["time_median"], g["time"])
    return pd.DataFrame({"family": family, "level": g.level.astype(int),
                         "n": g.n.astype(int), "solver": g.solver, "preset": g.preset,
                         "rung": g.rung.astype(int), "time": time.astype(float),
                         "energy_error": np.maximum(g.energy_error.astype(float), 1e-16),
                         "verified": g.status == "converged", "status": g.status,
                         "problem": g.problem}).reset_index(drop=True)


def work_chart(work: pd.DataFrame, family: str) -> tuple[str, dict]:
    """One family's work-precision as an interactive chart (note, Vega-Lite spec)."""
    spec = charts.solver_chart(
        work, ("time", "solver time (s)", True),
        ("energy_error", "energy error ||u - u_ref||_A / ||u_ref||_A", True),
        f"Work-precision, family {family}",
        tooltip=("preset", "rung", "status", "level", "n", "problem"), facet="level",
        filled="verified")
    return ("One panel per level, one line per solver and preset through the rungs of its "
            "tolerance ladder; hollow: not verified converged.", spec)


def work_precision(work: pd.DataFrame, family: str, path: str) -> None:
    """Energy error against time for every solver on one family (``work``:
    :func:`work_frame`): one panel per level (two abreast), one line per solver through its
    presets and rungs (its tolerance ladder; runs without a solution left out; a run that is
    not verified converged drawn hollow). A family without any such run gets no axes, only
    the reason (:func:`report.figures.nothing_to_draw`)."""
    g = work
    levels = sorted(g.level.unique())
    if not levels:
        nothing_to_draw(path, f"Work-precision, family {family}",
                        "no run of this family has an energy error against the exact "
                        "reference (no solution, or no reference at this scale)",
                        scene=family)
        return
    cols = min(len(levels), 2)
    rows = -(-len(levels) // cols)
    legend_room = 1.8 if len(levels) == 1 else 0.0      # one panel: its own legend inside
    fig, axes = plt.subplots(rows, cols, figsize=(5.0 * cols + legend_room, 4.4 * rows),
                             squeeze=False)
    panels = list(axes.flat)[:len(levels)]
    for ax in list(axes.flat)[len(levels):]:
        ax.set_visible(False)
    for ax, level in zip(panels, levels):
        gl = g[g.level == level]
        for (solver, _), r in gl.groupby(["solver", "preset"], sort=True):
            style = solver_style(solver)
            r = r.sort_values("rung")
            err = r.energy_error
            ax.loglog(r.time, err, "-", color=style["color"], lw=1.2)
            ok = r.verified
            ax.loglog(r.time[ok], err[ok], marker=style["marker"], color=style["color"], ms=5,
                      ls="none")
            ax.loglog(r.time[~ok], err[~ok], marker=style["marker"], mfc="none",
                      color=style["color"], ms=5, ls="none")
        for preset, tol in TOLERANCES.items():
            ax.axhline(tol, color="0.6", lw=0.6, ls=":")
            ax.annotate(preset, (1.0, tol), xycoords=("axes fraction", "data"), fontsize=7,
                        color="0.4", ha="right", va="bottom")
        n = int(gl.n.iloc[0])
        ax.set_title(f"{family} level {level} (n = {n:,})", fontsize=9)
        ax.set_xlabel("solver time (s)")
        ax.set_ylabel("energy error ||u - u_ref||_A / ||u_ref||_A")
        ax.grid(True, which="both", alpha=0.3)
    solver_legend(axes[0][-1], sorted(g.solver.unique()), axes=panels)
    fig.suptitle(f"Work-precision, family {family}: each solver's tolerance ladder along its "
                 "line (hollow: not verified)", fontsize=10)
    save_figure(fig, path, scene=family)


#: The columns a run pair (the same problem, solver and preset) is matched on.
PAIR = ["problem", "solver", "preset"]


def warm_pairs(t: pd.DataFrame) -> pd.DataFrame:
    """Every warm run beside the cold run of the same problem, solver and preset:
    the columns ``iterations``, ``time``, ``status``, ``claimed_status`` suffixed
    ``_cold`` and ``_warm``, the warm run's ``used_guess``, and ``ignored``: its message
    says it ignored the guess (:data:`solvers.base.GUESS_NOT_USED`)."""
    cols = ["iterations", "time", "status", "claimed_status"]
    warm = t[t["start"] == "warm"]
    if warm.empty:
        return pd.DataFrame(columns=[*PAIR, "used_guess", "ignored",
                                     *(f"{c}_{s}" for s in ("cold", "warm") for c in cols)])
    cold = t[t["start"] == "cold"][PAIR + cols]
    pairs = warm[PAIR + cols + ["used_guess", "message"]].merge(cold, on=PAIR,
                                                                suffixes=("_warm", "_cold"))
    pairs["used_guess"] = pairs["used_guess"].astype(str).str.lower() == "true"
    pairs["ignored"] = pairs.pop("message").fillna("").str.contains(GUESS_NOT_USED,
                                                                     regex=False)
    return pairs


def guess_use(g: pd.DataFrame) -> str:
    """How a solver's warm runs ``g`` (:func:`warm_pairs`) took the guess: ``ignored``
    (every run says so), ``used`` (none says so and some started from it), ``no answer``
    (no run returned one) or ``mixed``."""
    if g["ignored"].all():
        return "ignored"
    if not g["ignored"].any():
        return "used" if g["used_guess"].any() else "no answer"
    return "mixed"


def warm_frame(t: pd.DataFrame) -> pd.DataFrame:
    """Cold against warm starts per solver and preset over the steps run both ways
    (:func:`warm_pairs`): ``steps``; ``guess`` (:func:`guess_use`; ``ignored``: the
    solver says it does not start from a guess; ``used`` counts a primal guess alone); the median and total ``iterations``
    and ``time`` of each start and the ratios warm / cold of the medians; the steps
    verified ``converged`` cold and warm."""
    pairs = warm_pairs(t)
    rows = []
    for (solver, preset), g in pairs.groupby(["solver", "preset"]):
        row = {"solver": solver, "preset": preset, "steps": len(g),
               "guess": guess_use(g)}
        for q in ("iterations", "time"):
            for start in ("cold", "warm"):
                v = g[f"{q}_{start}"].astype(float)
                row[f"{q}_{start}_median"] = float(v.median())
                row[f"{q}_{start}_total"] = float(v.sum())
            cold = row[f"{q}_cold_median"]
            row[f"{q}_ratio"] = row[f"{q}_warm_median"] / cold if cold > 0 else np.nan
        for start in ("cold", "warm"):
            row[f"converged_{start}"] = int((g[f"status_{start}"] == "converged").sum())
        rows.append(row)
    out = pd.DataFrame(rows, columns=[
        "solver", "preset", "steps", "guess", "iterations_cold_median",
        "iterations_cold_total", "iterations_warm_median", "iterations_warm_total",
        "iterations_ratio", "time_cold_median", "time_cold_total", "time_warm_median",
        "time_warm_total", "time_ratio", "converged_cold", "converged_warm"])
    return out.sort_values(["preset", "solver"]).reset_index(drop=True)


def ignored_guess_mismatches(t: pd.DataFrame) -> tuple[int, int]:
    """Of the run pairs whose warm run says it ignored its guess (neither run stopped by
    its time limit, which cuts a run wherever the clock says), how many differ from the
    cold run in iterations or claimed status, and how many pairs there are: a solver that
    truly starts from zero either way runs the same deterministic iteration twice."""
    pairs = warm_pairs(t)
    pairs = pairs[pairs["ignored"] & ~pairs["claimed_status_cold"].eq("time_limit")
                  & ~pairs["claimed_status_warm"].eq("time_limit")]
    differ = ((pairs["iterations_cold"] != pairs["iterations_warm"])
              | (pairs["claimed_status_cold"] != pairs["claimed_status_warm"]))
    return int(differ.sum()), len(pairs)


def facet_frame(t: pd.DataFrame) -> pd.DataFrame:
    """The faceted friction law's accuracy against cost: per faceted step (``facets`` = k)
    whose isotropic twin was run, solver and preset: k, the ``model_error``
    ``||u_k - u_iso||_A / ||u_iso||_A`` of the two exact references, and the status and
    time of the solver on the faceted QP and on the isotropic cone program, and the time
    ratio faceted / isotropic where both are verified converged. ``t``: cold runs."""
    columns = ["family", "level", "problem", "facets", "isotropic_twin", "model_error",
               "solver", "preset", "status_faceted", "time_faceted", "status_isotropic",
               "time_isotropic", "time_ratio"]
    if "facets" not in t or "isotropic_twin" not in t:
        return pd.DataFrame(columns=columns)
    faceted = t[t["facets"].fillna(0) > 0]
    faceted = faceted[faceted["isotropic_twin"].isin(set(t["problem"]))]
    twin = t[PAIR + ["status", "time"]].rename(columns={"problem": "isotropic_twin",
                                                        "status": "status_isotropic",
                                                        "time": "time_isotropic"})
    out = faceted.rename(columns={"status": "status_faceted", "time": "time_faceted"}).merge(
        twin, on=["isotropic_twin", "solver", "preset"], how="left")
    both = (out["status_faceted"] == "converged") & (out["status_isotropic"] == "converged")
    out["time_ratio"] = np.where(both, out["time_faceted"] / out["time_isotropic"], np.nan)
    out["facets"] = out["facets"].astype(int)
    return out[columns].sort_values(["family", "level", "problem", "preset", "solver"]) \
        .reset_index(drop=True)


#: The verification's promises over the test set (report/claims.py).
CLAIMS = {
    "accurate": Claim("Ch. 8 (the solvers' stopping rules); suite bar: a verdict is never wrong",
                      "test set: every verified-converged run is within tol of the exact "
                      "reference", "given", "0", details="energy error; {problems} problems, "
                      "{runs} runs"),
    "refuted": Claim("suite figure (a solver's own stopping test, checked)", "test set: "
                     "claims of convergence refuted by the verification",
                     details="a solver's own stopping test against the suite's KKT and "
                     "certified bound",
                     unjudged="information: a solver's own stopping test measured against "
                     "the suite's verification, no bar"),
    "ignored_guess": Claim("suite bar (a solver that ignores its initial guess runs the same "
                           "deterministic iteration warm and cold)",
                           "test set: warm runs that ignore the guess repeat the cold run",
                           "given", "0 pairs differ", details="the cold run's iterations and "
                           "claim, {pairs} run pairs"),
    "warm_iterations": Claim("suite figure (quasi-static load paths start each step from the "
                             "last)", "test set: median iterations warm / cold per solver "
                             "that uses the guess", details="{steps} steps with a warm start",
                             unjudged="information: no method here promises fewer iterations "
                             "from the previous step's solution, no bar"),
    "facets": Claim("suite figure (the k-gon friction law approximates the disc, "
                    "problems/friction/data.py)", "test set: model error ||u_k - u_iso||_A "
                    "/ ||u_iso||_A of the faceted references",
                    unjudged="information: the faceted law's distance to the isotropic one "
                    "at this k, no bar"),
}


BOARD_CLAIMS = {
    "fastest": Claim("suite figure (time at matched accuracy, report/leaderboard.py)",
                     "test set, {label}: fastest verified solver", details="{size} class, "
                     "preset {preset}, {problems} problems",
                     unjudged="information: a ranking, no bar"),
    "independent": Claim("suite bar (an exact reference is checked by another route, not by "
                         "itself)", "test set, {label}: exact references agree with an "
                         "independent answer", "given", "within tol (or its floor)",
                         details="the closest independent verified answer; {size} class, "
                         "preset {preset}, {problems} problems"),
}


def board_claims(all_boards: list[tuple]) -> list[dict]:
    """Per leaderboard: its fastest verified solver (information) and whether its exact
    references agree with an independent verified answer within the preset's tolerance
    (:func:`report.leaderboard.independent_agreement`; the bound's floor where higher)."""
    rows = []
    for (cls, size, preset), b in all_boards:
        words = dict(label=PROBLEM_CLASSES[cls], size=size, preset=preset,
                     problems=len(b["problems"]))
        table = b["table"]
        if b["fastest"] is not None:
            r = table[table["solver"] == b["fastest"]].iloc[0]
            text = (f"{b['fastest']}: median time {r['median_ratio']:.3g} x the best, "
                    f"verified on {r['verified']} of {r['problems']}")
        else:
            text = f"none verified on {leaderboard.COVERAGE:.0%} of the class"
        rows.append(BOARD_CLAIMS["fastest"].row(text, **words))
        refs = b["references"]
        if len(refs):
            checked = refs["independent_agreement"].notna()
            rows.append(BOARD_CLAIMS["independent"].row(
                ", ".join(f"{r.solver}: {r.independent_agreement:.2g}"
                          for r in refs.itertuples()),
                judged=bool(checked.any()),
                passed=bool(refs.loc[checked, "independent_within"].all()),
                reason="no other solver was verified on a problem the reference solved",
                **words))
    return rows


def claims(t: pd.DataFrame) -> pd.DataFrame:
    """The verification's promises over the whole test set (claim, thesis, measured, bar,
    pass), and the count of problems and runs."""
    conv = t["status"] == "converged"
    accurate = accurate_runs(t)
    wrong = int((conv & ~accurate).sum())
    claimed = t["claimed_status"] == "converged"
    refuted = int((claimed & ~conv).sum())
    return pd.DataFrame([
        CLAIMS["accurate"].row(f"{wrong} of {int(conv.sum())} converged runs inaccurate",
                               passed=wrong == 0, problems=t["problem"].nunique(), runs=len(t)),
        CLAIMS["refuted"].row(f"{refuted} of {int(claimed.sum())} claimed")])


def warm_facet_claims(t: pd.DataFrame, warm: pd.DataFrame, facets: pd.DataFrame) -> list[dict]:
    """The claims rows of the warm-start comparison (``t``: every run, ``warm``:
    :func:`warm_frame`) and of the faceted law (``facets``: :func:`facet_frame`); none
    for a part without runs."""
    rows = []
    if len(warm):
        differ, pairs = ignored_guess_mismatches(t)
        rows.append(CLAIMS["ignored_guess"].row(
            f"{differ} of {pairs} pairs differ", judged=pairs > 0, passed=differ == 0,
            reason="no run here ignored its guess", pairs=pairs))
        used = warm[warm["guess"] != "ignored"]
        text = "; ".join(f"{r.solver} ({r.preset}): {r.iterations_ratio:.3g}"
                         for r in used.itertuples())
        rows.append(CLAIMS["warm_iterations"].row(text or "no solver used the guess",
                                                  steps=int(warm["steps"].max())))
    if len(facets):
        errors = facets.drop_duplicates("problem")
        rows.append(CLAIMS["facets"].row("; ".join(
            f"{r.problem} (k = {r.facets}): {r.model_error:.3g}"
            for r in errors.itertuples())))
    return rows


def page_settings(inputs: list[str], t: pd.DataFrame, time_limit: float, scale: str,
                  load: str) -> dict:
    """What a results page states beside its tables: the test set, scale, ladder,
    repeats, time limit, load, and the machine, commit and solver packages of the runs
    (their provenance sidecars)."""
    from workflows.io import META, PACKAGES, read_json
    from workflows.ladder import LOOSEST, REPEATS, TIGHTEST

    try:
        prov = read_json(str(inputs[0]) + META)["provenance"]
    except (OSError, KeyError, ValueError):
        prov = {}
    versions = prov.get("packages") or {}
    shown = [f"{name} {versions[name]}" for name in PACKAGES if versions.get(name)
             and name not in ("numpy", "scipy", "pandas", "meshio", "matplotlib", "snakemake",
                              "scikit-fem", "ngsolve")]
    return {"test_set": ", ".join(sorted(t["set"].astype(str).unique())) if "set" in t
            else "?", "scale": scale,
            "ladder": f"{LOOSEST} to {TIGHTEST} (a factor 10 apart)", "repeats": REPEATS,
            "time_limit": time_limit,
            "load": ("taken beside one other job (this scale's `shared`: the two cores are "
                     "shared, so absolute times are slower than alone; every solver ran under "
                     "the same conditions)" if load == "shared" else
                     "taken alone: no other job ran beside the runs"),
            "machine": f"{prov.get('cpu_model', '?')}, {prov.get('cpu_count', '?')} cores",
            "commit": prov.get("commit", "?"), "versions": ", ".join(shown) or "?"}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--inputs", nargs="+", required=True,
                    help="the test set's run tables (workflows/studies/test_set/run.py)")
    ap.add_argument("--time-limit", type=float, required=True,
                    help="the penalty time of an unverified run (the runs' time limit)")
    ap.add_argument("--summary", required=True,
                    help="CSV: per problem class, solver and preset (plain runs)")
    ap.add_argument("--by-class", required=True,
                    help="CSV: per problem class, size class, solver, preset (plain runs)")
    ap.add_argument("--by-scene", required=True, help="CSV: per scene, solver, preset")
    ap.add_argument("--claims", required=True, help="CSV: the verification's promises")
    ap.add_argument("--leaderboards", default=None,
                    help="CSV: every leaderboard (problem class, size class, preset)")
    ap.add_argument("--pages", nargs="*", default=[], metavar="CLASS=MD",
                    help="Markdown results pages, one per problem class")
    ap.add_argument("--scale", default="?", help="the configuration's scale, for the pages")
    ap.add_argument("--load", choices=("alone", "shared"), default="alone",
                    help="whether the runs were timed alone or beside another job")
    ap.add_argument("--warm-starts", default=None,
                    help="CSV: cold against warm starts per solver and preset")
    ap.add_argument("--facets", default=None,
                    help="CSV: the faceted friction law's model error and cost")
    ap.add_argument("--profiles", required=True, help="PNG: performance profiles")
    ap.add_argument("--work-precision", nargs="*", default=[], metavar="FAMILY=PNG",
                    help="work-precision figures, one per family")
    ap.add_argument("--charts", default=None,
                    help="HTML: the profiles and work-precision as interactive charts")
    args = ap.parse_args(argv)
    every = runs(args.inputs, args.time_limit)
    cold, plain = cold_rows(every), plain_rows(every)
    write_csv(args.summary, summary(plain, ("problem_class",)))
    write_csv(args.by_class, summary(plain, ("problem_class", "size_class")))
    write_csv(args.by_scene, summary(plain, ("scene",)))
    warm, facets = warm_frame(every[every["rung"] == 0]), facet_frame(plain)
    if args.warm_starts:
        write_csv(args.warm_starts, warm)
    if args.facets:
        write_csv(args.facets, facets)
    roles = {name: str(spec.role) for name, spec in solvers().items()}
    all_boards = leaderboard.boards(cold, roles, args.time_limit)
    settings = page_settings(args.inputs, every, args.time_limit, args.scale, args.load)
    if args.leaderboards:
        write_csv(args.leaderboards, leaderboard.board_frame(all_boards).assign(
            time_limit=args.time_limit, repeats=settings["repeats"], load=settings["load"]))
    for item in args.pages:
        cls, _, path = item.partition("=")
        write_text(path, leaderboard.markdown_page(
            cls, [(k, b) for k, b in all_boards if k[0] == cls], settings))
    write_csv(args.claims, pd.concat([claims(plain), pd.DataFrame(
        warm_facet_claims(every[every["rung"] == 0], warm, facets) + board_claims(all_boards),
        columns=COLUMNS)], ignore_index=True))
    profiles = profile_frame(cold, roles)
    performance_profiles(profiles, args.profiles)
    pages = [profiles_chart(profiles)] if len(profiles) else []
    for item in args.work_precision:
        family, _, path = item.partition("=")
        work = work_frame(cold, family)
        work_precision(work, family, path)
        if len(work):
            pages.append(work_chart(work, family))
    if args.charts:
        charts.write_page(args.charts, pages, "The contact QP test set: performance "
                          "profiles and work-precision, interactive")


if __name__ == "__main__":
    main()
