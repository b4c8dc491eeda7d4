"""The solver leaderboards: one per problem class, size class and preset.

Like against like. A frictionless QP, a 2D Tresca step (a QP in ``(u, t)``), a 3D
Tresca step (a second-order cone program) and a 3D faceted step are different problems
for a solver (:data:`workflows.problem_set.PROBLEM_CLASSES`), so each class has its own
table over the solvers that take it; a solver that declines a whole class (``skipped``
on every problem of it) is not ranked there and is named under the table with its reason;
one that skips some problems of a class it takes is charged for them.

Time at matched accuracy. Each solver climbs its tolerance ladder on every problem
(:mod:`workflows.ladder`); its time on a problem is the median of the repeated runs of
its loosest rung verified at the preset's ``tol`` (min and max beside it), so a library
whose default mapping stops short is timed at the rung that reaches the target, and one
whose mapping overshoots at the looser rung that still does.

Metrics (qpbenchmark's definitions where they exist, so the tables read beside its
Maros-Meszaros results):

* ``verified``: problems whose ladder reached a verified answer at the target, of the
  class's problems (qpbenchmark's success rate, over the ladder); ``plain``: the same at
  rung 0, the solver's own mapping of the preset;
* ``correct``: share of rung-0 claims that are true against the exact reference
  (qpbenchmark's correct rate: a claimed convergence within what the verification
  certifies at ``tol``, or a failure the solver admitted);
* ``median ratio``: the median over the class's problems of the solver's time over the
  best contestant's time on that problem (the performance profile's ratio at its median;
  a problem not verified, skipped ones included, counts as infinitely slow). The table is
  ranked by it: a solver verified on fewer than half of the class ranks below every one
  verified on more, and among those the faster at matched accuracy ranks higher;
* ``sgm time``: the shifted geometric mean of the times over the problems the solver
  attempted (an attempted problem not verified counts as the time limit, qpbenchmark's
  penalty; a skipped problem is counted in ``skipped`` and the median ratio, never as a
  time it did not take) with the shift :func:`shift_of`: the median over the class's
  problems of the best contestant's time. qpbenchmark's shift of 10 s suits solves of
  seconds to minutes; here solves take milliseconds to a second, and a 10 s shift would
  leave every verified time within a few per cent of every other, so that the penalty of
  a failure decided the order;
* ``spread``: the largest relative spread ``(max - min) / median`` of a solver's repeated
  runs over the class.

The fastest verified solver is the one with the best median ratio among those verified
on at least :data:`COVERAGE` of the class, named with its coverage. The exact references
(role ``exact``) are the baseline: they are listed apart and never ranked against
themselves; their own correctness is shown against an independent route, the closest
answer of another solver verified on the same problem (its energy distance to the
reference).
"""
from __future__ import annotations

import html

import numpy as np
import pandas as pd

from solvers.base import TOLERANCES, Role
from solvers.certificate import certifiable
from report.tables import table_html
from workflows.problem_set import PROBLEM_CLASSES, plain_rows

#: Verified share a solver needs to be named the fastest of a class.
COVERAGE = 0.9
#: The columns one leaderboard is computed over.
BOARD = ("problem_class", "size_class", "preset")
#: The suite's factor on top of what the verification certifies for a correct claim.
ACCURATE = 1.001


def is_reference(solver: str, roles: dict[str, str]) -> bool:
    """Whether ``solver`` is an exact reference (role ``exact``)."""
    return roles.get(solver) == Role.EXACT


def accurate(t: pd.DataFrame) -> pd.Series:
    """Runs whose energy error against the exact reference is within what the verification
    certifies at their tolerance (:func:`solvers.certificate.certifiable`)."""
    floor = t["energy_bound_floor"].fillna(0.0) if "energy_bound_floor" in t else 0.0
    return t["energy_error"].fillna(np.inf) <= certifiable(t["tol"], floor) * ACCURATE


def matched_times(t: pd.DataFrame) -> pd.DataFrame:
    """Per problem, solver and preset of cold runs: the time at matched accuracy
    (``time``: the counted rung's median, NaN where no rung verified), its ``time_min``,
    ``time_max``, the counted ``rung``, and the verified flag."""
    keys = ["problem", "family", *BOARD, "solver"]
    counted = t[t["counted"].fillna(False).astype(bool)]
    out = t[keys].drop_duplicates().merge(
        counted[keys + ["rung", "time_median", "time_min", "time_max"]], on=keys, how="left")
    out = out.rename(columns={"time_median": "time"})
    out["verified"] = out["time"].notna()
    return out


def shift_of(times: pd.DataFrame) -> float:
    """The shifted geometric mean's shift for one leaderboard: the median over its problems
    of the best contestant's verified time (:func:`matched_times` of the contestants)."""
    best = times[times["verified"]].groupby("problem")["time"].min()
    return float(best.median()) if len(best) else 1.0


def sgm(values, shift: float) -> float:
    """Shifted geometric mean ``exp(mean(log(v + shift))) - shift``."""
    v = np.asarray(values, dtype=float)
    return float(np.exp(np.mean(np.log(v + shift))) - shift) if v.size else float("nan")


def declined(plain: pd.DataFrame) -> dict[str, str]:
    """``{solver: reason}`` of the solvers skipping every problem of a board's plain runs."""
    out = {}
    for solver, g in plain.groupby("solver"):
        if (g["status"] == "skipped").all():
            out[solver] = str(g["message"].iloc[0]).removeprefix("skipped: ")
    return out


def not_verified(t: pd.DataFrame, times: pd.DataFrame) -> dict[str, str]:
    """Per solver, its unverified problems by how the tightest rung run ended and which
    check failed there, e.g. ``"2 inaccurate (kkt_stationarity), 1 skipped"``."""
    missing = times[~times["verified"]][["problem", "solver"]]
    if missing.empty:
        return {}
    last = t.sort_values("rung").groupby(["problem", "solver"]).tail(1)
    last = missing.merge(last, on=["problem", "solver"], how="left")
    out = {}
    for solver, g in last.groupby("solver"):
        parts = []
        for status, h in g.groupby("status"):
            checks = sorted({c for cs in h["failed_check"].fillna("") for c in str(cs).split(",")
                             if c})
            parts.append(f"{len(h)} {status}" + (f" ({', '.join(checks)})" if checks else ""))
        out[solver] = ", ".join(parts)
    return out


def board(t: pd.DataFrame, roles: dict[str, str], time_limit: float) -> dict:
    """One leaderboard from the cold runs ``t`` of one problem class, size class and preset:
    ``{"table", "references", "declined", "shift", "problems", "fastest"}`` (the module
    docstring defines every column)."""
    plain = plain_rows(t)
    refused = declined(plain)
    t = t[~t["solver"].isin(refused)]
    plain = plain[~plain["solver"].isin(refused)]
    times = matched_times(t)
    problems = sorted(t["problem"].unique())
    contest = times[~times["solver"].map(lambda s: is_reference(s, roles))]
    best = contest[contest["verified"]].groupby("problem")["time"].min()
    shift = shift_of(contest)
    failures = not_verified(t, times)
    rows = []
    for solver, g in times.groupby("solver"):
        p = plain[plain["solver"] == solver]
        claimed = p["claimed_status"] == "converged"
        correct = np.where(claimed, accurate(p), True)
        ratio = (g.set_index("problem")["time"] / best).reindex(problems).fillna(np.inf)
        spread = ((g["time_max"] - g["time_min"]) / g["time"]).max()
        rungs = g.loc[g["verified"], "rung"]
        skipped = set(p.loc[p["status"] == "skipped", "problem"])
        attempted = g[~g["problem"].isin(skipped)]
        rows.append({
            "solver": solver, "role": roles.get(solver, "other"),
            "problems": len(problems), "verified": int(g["verified"].sum()),
            "verified_share": float(g["verified"].sum()) / len(problems),
            "skipped": len(skipped),
            "plain_verified": int((p["status"] == "converged").sum()),
            "correct_share": float(np.mean(correct)) if len(p) else np.nan,
            "median_ratio": float(np.median(ratio)) if len(ratio) else np.nan,
            "sgm_time": sgm(attempted["time"].fillna(time_limit), shift)
            if len(attempted) else np.nan,
            "spread": float(spread) if np.isfinite(spread) else np.nan,
            "counted_rungs": ", ".join(f"{int(k)}: {n}" for k, n in
                                       rungs.value_counts().sort_index().items()),
            "not_verified": failures.get(solver, "")})
    table = pd.DataFrame(rows, columns=[
        "solver", "role", "problems", "verified", "verified_share", "skipped",
        "plain_verified", "correct_share", "median_ratio", "sgm_time", "spread",
        "counted_rungs", "not_verified"])
    ref_mask = table["solver"].map(lambda s: is_reference(s, roles))
    references = table[ref_mask].reset_index(drop=True)
    agreement = [independent_agreement(t, s, roles) for s in references["solver"]]
    references["independent_agreement"] = [a for a, _ in agreement]
    references["independent_within"] = [w for _, w in agreement]
    table = table[~ref_mask].sort_values(["median_ratio", "sgm_time", "solver"]) \
        .reset_index(drop=True)
    table.insert(0, "rank", np.arange(1, len(table) + 1))
    covered = table[table["verified_share"] >= COVERAGE]
    fastest = (covered.sort_values(["median_ratio", "sgm_time"]).iloc[0]["solver"]
               if len(covered) else None)
    return {"table": table, "references": references, "declined": refused,
            "shift": shift, "problems": problems, "fastest": fastest}


def independent_agreement(t: pd.DataFrame, reference: str,
                          roles: dict[str, str]) -> tuple[float, bool]:
    """The reference's largest distance, over the problems it was verified on, to the
    closest answer of another solver verified on the same problem (relative energy norm;
    the exported reference is the reference's own answer, so this is the independent
    route's word on it), and whether every such distance lies within what that answer's
    verification certifies (:func:`accurate`). ``(nan, False)`` where no other solver was
    verified."""
    mine = t[(t["solver"] == reference) & (t["status"] == "converged")]["problem"].unique()
    others = t[(t["status"] == "converged")
               & ~t["solver"].map(lambda s: is_reference(s, roles))
               & t["problem"].isin(mine)]
    if others.empty:
        return float("nan"), False
    closest = others.loc[others.groupby("problem")["energy_error"].idxmin()]
    return float(closest["energy_error"].max()), bool(accurate(closest).all())


def boards(t: pd.DataFrame, roles: dict[str, str], time_limit: float) -> list[tuple]:
    """Every leaderboard of the cold runs ``t``: ``[((class, size class, preset), board)]``
    in the order of :data:`PROBLEM_CLASSES`, size class and preset."""
    order = {p: i for i, p in enumerate(TOLERANCES)}
    keys = sorted({tuple(k) for k in t[list(BOARD)].drop_duplicates().itertuples(index=False)},
                  key=lambda k: (list(PROBLEM_CLASSES).index(k[0]), k[1], order[k[2]]))
    return [(k, board(t[(t[list(BOARD)] == pd.Series(k, index=list(BOARD))).all(axis=1)],
                      roles, time_limit)) for k in keys]


def board_frame(all_boards: list[tuple]) -> pd.DataFrame:
    """Every board in one frame: its ranked solvers, its references and the solvers that
    declined its class, each row with its ``problem_class``, ``size_class``, ``preset``,
    ``standing`` (``ranked``, ``reference`` or ``declined``: then ``note`` gives the
    reason), the board's ``shift`` and ``fastest`` (the fastest verified solver's row)."""
    frames = []
    for (cls, size, preset), b in all_boards:
        declined_rows = pd.DataFrame({"solver": list(b["declined"]),
                                      "note": list(b["declined"].values())})
        for standing, part in (("ranked", b["table"]), ("reference", b["references"]),
                               ("declined", declined_rows)):
            if len(part):
                frames.append(part.assign(problem_class=cls, size_class=size, preset=preset,
                                          standing=standing, shift=b["shift"],
                                          fastest=part["solver"] == b["fastest"]))
    if not frames:
        return pd.DataFrame(columns=["problem_class", "size_class", "preset", "standing",
                                     "solver"])
    out = pd.concat(frames, ignore_index=True)
    first = ["problem_class", "size_class", "preset", "standing", "rank", "solver"]
    return out[first + [c for c in out.columns if c not in first]]


def _cell(value, digits: int = 3) -> str:
    """A Markdown cell: numbers to ``digits`` significant digits, inf and NaN in words."""
    if isinstance(value, (float, np.floating)):
        if np.isnan(value):
            return "-"
        if np.isinf(value):
            return "inf"
        return f"{value:.{digits}g}"
    return str(value).replace("|", "/") if value != "" else "-"


def markdown_table(frame: pd.DataFrame, columns: dict[str, str]) -> list[str]:
    """``frame``'s ``columns`` (``{column: header}``) as Markdown table lines."""
    lines = ["| " + " | ".join(columns.values()) + " |",
             "|" + "|".join("---" for _ in columns) + "|"]
    for _, r in frame.iterrows():
        lines.append("| " + " | ".join(_cell(r[c]) for c in columns) + " |")
    return lines


#: The leaderboard's columns in a results page: ``{column: header}``.
RANKED = {"rank": "rank", "solver": "solver", "verified": "verified", "skipped": "skipped",
          "plain_verified": "verified at rung 0", "correct_share": "correct (rung 0)", "median_ratio":
          "median time / best", "sgm_time": "sgm time [s]", "spread": "repeat spread",
          "counted_rungs": "counted rungs (rung: problems)", "not_verified":
          "not verified (how the tightest rung ended)"}
BASELINE = {"solver": "reference", "verified": "verified", "sgm_time": "sgm time [s]",
            "median_ratio": "median time / best contestant", "independent_agreement":
            "largest distance to the closest independent verified answer"}


def markdown_page(cls: str, class_boards: list[tuple], settings: dict) -> str:
    """The results page of one problem class: its boards (``[((class, size, preset),
    board)]``) with the settings beside them (``settings``: ``test_set``, ``scale``,
    ``time_limit``, ``load``, ``machine``, ``commit``, ``versions``)."""
    label = PROBLEM_CLASSES[cls]
    out = [f"# Leaderboard: {label}", "",
           f"Test set `{settings['test_set']}`, scale `{settings['scale']}`; generated by "
           "`report.test_set` from the test set's run tables (rule `solver_summary`).",
           "", "## Settings", "",
           "- **Time at matched accuracy**: each solver's tolerance ladder, its own tolerance "
           f"`tol * 10^-rung` for rungs {settings['ladder']}, every rung verified at the "
           "preset's `tol` (KKT residuals and the certified energy bound); the time of the "
           "loosest verified rung counts.",
           f"- **Repeats**: the counted rung is run {settings['repeats']} times; its time is "
           "the median, the spread `(max - min) / median` is the *repeat spread* (the "
           "largest over the class).",
           f"- **Time limit** {settings['time_limit']:g} s per run; an attempted problem not "
           "verified counts as the time limit in the shifted geometric mean (qpbenchmark's "
           "penalty); a skipped one counts in `skipped` and as infinitely slow in the median "
           "time ratio, by which the table is ranked.",
           "- **Shift**: the median over the class's problems of the best contestant's time "
           "(given per table); qpbenchmark's 10 s would leave sub-second times "
           "indistinguishable.",
           f"- **Load**: {settings['load']}",
           f"- **Machine**: {settings['machine']}; commit `{settings['commit']}`.",
           f"- **Versions**: {settings['versions']}.", ""]
    if not class_boards:
        out += ["No problem of this class runs in this configuration.", ""]
    for (_, size, preset), b in class_boards:
        out += [f"## Size class {size}, preset {preset} (tol {TOLERANCES[preset]:g}, "
                f"{len(b['problems'])} problems)", "",
                f"Shift {b['shift']:.3g} s. "
                + (f"**Fastest verified: {b['fastest']}** (the best median time ratio among "
                   f"the solvers verified on at least {COVERAGE:.0%} of the class)."
                   if b["fastest"] else
                   f"No solver was verified on {COVERAGE:.0%} of the class: none is named "
                   "fastest."), ""]
        out += markdown_table(b["table"], RANKED) + [""]
        if len(b["references"]):
            out += ["Baseline (the exact references, not ranked):", ""]
            out += markdown_table(b["references"], BASELINE) + [""]
        if b["declined"]:
            out += ["Declined the class (not ranked):", ""]
            out += [f"- {s}: {why}" for s, why in sorted(b["declined"].items())] + [""]
    return "\n".join(out)


# ------------------------------------------------------------- the summary page's part
#: What a leaderboard's columns mean, under each board on the summary page.
NOTE = ("Time at matched accuracy: each solver's loosest rung of its tolerance "
        "ladder verified at the preset's tol, the median of repeated runs (repeat "
        "spread: the largest (max - min) / median). verified: problems of the "
        "class verified over the ladder (a skip counts against it); at rung 0: "
        "at the preset's own mapping; correct %: share of rung-0 claims true "
        "against the exact reference; median time / best: over the class's "
        "problems, the solver's time over the best contestant's (inf: fewer "
        "than half verified), by which the table is ranked; sgm time: the shifted "
        "geometric mean over the problems attempted, shift {shift:.3g} s (the "
        "class's median best time), an attempted problem not verified counting "
        "as the time limit {limit:g} s. Load: {load}.")


FAILURE_COLUMNS = ("scene", "preset", "solver", "runs", "converged", "inaccurate", "max_iter",
                   "time_limit", "failed", "skipped")


def failures(by_scene: pd.DataFrame | None) -> pd.DataFrame:
    """The rows of the per-scene solver summary with a run not verified converged: scene,
    preset, solver, the runs and how each ended, sorted by scene, preset, solver."""
    if by_scene is None or not len(by_scene):
        return pd.DataFrame(columns=FAILURE_COLUMNS)
    bad = by_scene[by_scene["converged"] < by_scene["runs"]]
    bad = bad[[c for c in FAILURE_COLUMNS if c in bad]]
    order = {p: i for i, p in enumerate(TOLERANCES)}
    return bad.sort_values(["scene", "preset", "solver"],
                           key=lambda c: c.map(order) if c.name == "preset" else c
                           ).reset_index(drop=True)


def failure_anchor(scene: str) -> str:
    """The id of a scene's first row in the failures table."""
    return f"failures-{scene}"


#: A leaderboard's columns on the summary page: ``{column in leaderboards.csv: header}``.
BOARD_COLUMNS = {"rank": "rank", "solver": "solver", "verified": "verified",
                 "skipped": "skipped", "plain_verified": "at rung 0", "correct_share": "correct %",
                 "median_ratio": "median time / best", "sgm_time": "sgm time [s]",
                 "spread": "repeat spread", "not_verified": "not verified"}


def leaderboard(board: pd.DataFrame) -> pd.DataFrame:
    """One board's ranked solvers, then its references (rank ``baseline``), as shown on the
    summary page (:data:`BOARD_COLUMNS`; ``board``: its rows of ``leaderboards.csv``)."""
    shown = board[board["standing"].isin(["ranked", "reference"])].copy()
    shown["rank"] = [("baseline" if st == "reference" else int(r))
                     for st, r in zip(shown["standing"], shown["rank"])]
    shown["correct_share"] = (100 * shown["correct_share"]).round(1)
    shown["solver"] = [s + (" (fastest verified)" if f else "") + (" (exact reference)"
                                                                   if st == "reference" else "")
                       for s, f, st in zip(shown["solver"], shown["fastest"],
                                           shown["standing"])]
    out = shown[list(BOARD_COLUMNS)].rename(columns=BOARD_COLUMNS)
    out["verified"] = [f"{int(v)} of {int(n)}" for v, n in zip(shown["verified"],
                                                               shown["problems"])]
    return out


def board_words(board: pd.DataFrame, bold=lambda s: f"<b>{s}</b>",
                escape=html.escape) -> str:
    """A board's verdict in words: its fastest verified solver with its coverage, its
    references' independent check, the solvers that declined the class (HTML; ``bold``
    and ``escape`` give another markup, e.g. reStructuredText's)."""
    first = board.iloc[0]
    cls, size, preset = first["problem_class"], first["size_class"], first["preset"]
    ranked = board[board["standing"] == "ranked"]
    fast = ranked[ranked["fastest"].astype(bool)]
    head = (f"{bold(escape(PROBLEM_CLASSES.get(cls, cls)))}, {escape(str(size))} "
            f"class, preset {escape(preset)} (tol {TOLERANCES[preset]:g}, "
            f"{int(first['problems'])} problems): ")
    if len(fast):
        r = fast.iloc[0]
        head += (f"fastest verified {bold(escape(r.solver))} (median time "
                 f"{r.median_ratio:.3g} x the best, verified on {int(r.verified)} of "
                 f"{int(r.problems)})")
    else:
        head += f"no solver verified on {COVERAGE:.0%} of the class"
    refs = board[board["standing"] == "reference"]
    if len(refs):
        head += "; exact reference " + ", ".join(
            f"{escape(r.solver)} within {r.independent_agreement:.2g} of the closest "
            "independent verified answer" if np.isfinite(r.independent_agreement) else
            f"{escape(r.solver)} (no independent verified answer)"
            for r in refs.itertuples())
    declined = board[board["standing"] == "declined"]
    if len(declined):
        head += ("; not ranked, declining the class: "
                 + ", ".join(escape(s) for s in declined["solver"]))
    return head + "."


def ordered_boards(frame: pd.DataFrame) -> list[tuple[tuple, pd.DataFrame]]:
    """The boards of ``leaderboards.csv``, ``((problem_class, size_class, preset), rows)``,
    in the problem classes' order, then by size class and preset."""
    order = {c: i for i, c in enumerate(PROBLEM_CLASSES)}
    return sorted(frame.groupby(["problem_class", "size_class", "preset"], sort=False),
                  key=lambda kv: (order.get(kv[0][0], 99), kv[0][1],
                                  list(TOLERANCES).index(kv[0][2])))


def leaderboards_landing(frame: pd.DataFrame) -> list[str]:
    """The report's landing page's part of ``leaderboards.csv`` (reStructuredText): each
    board's verdict in words (:func:`board_words`)."""
    return ["Solver leaderboards over the contact QP test set, one per problem class "
            "(the tables: **0 summary → summary**):", "",
            *(f"- {board_words(b, bold=lambda s: f'**{s}**', escape=str)}"
              for _, b in ordered_boards(frame)), ""]


def leaderboards_html(frame: pd.DataFrame) -> list[str]:
    """The leaderboards of ``leaderboards.csv`` in words and as tables, one per problem
    class, size class and preset, each with its settings and the load it was timed under."""
    parts = []
    boards = ordered_boards(frame)
    parts.append("<ul class='lead'>" + "".join(f"<li>{board_words(b)}</li>"
                                               for _, b in boards) + "</ul>")
    for (cls, size, preset), b in boards:
        first = b.iloc[0]
        anchor = f"leaderboard-{cls}-{size}-{preset}"
        parts.append(f"<h3 id='{html.escape(anchor)}'>Leaderboard: "
                     f"{html.escape(PROBLEM_CLASSES.get(cls, cls))}, {html.escape(str(size))} "
                     f"class, preset {html.escape(preset)}</h3><p class='small'>"
                     + html.escape(NOTE.format(
                         shift=first["shift"], limit=first["time_limit"], load=first["load"]))
                     + "</p>")
        parts.append(table_html(leaderboard(b), left=("solver", "not verified"),
                                name="leaderboard", max_rows=200, filter_box=False))
        declined = b[b["standing"] == "declined"]
        if len(declined):
            parts.append("<p class='small'>Declined the class (not ranked): " + "; ".join(
                f"{html.escape(r.solver)}: {html.escape(str(r.note))}"
                for r in declined.itertuples()) + "</p>")
    return parts


def leaderboards_front(frame: pd.DataFrame) -> list[str]:
    """The summary page's headline part of ``leaderboards.csv``: its heading, the verdicts in
    words and each board as a table (:func:`leaderboards_html`)."""
    return ["<h3 id='leaderboard'>Solver leaderboards over the contact QP test set, one per "
            "problem class</h3>", *leaderboards_html(frame)]


def failures_front(by_scene: pd.DataFrame) -> list[str]:
    """The summary page's headline part of the per-scene summary: where plain runs were not
    verified converged (:func:`failures`)."""
    fails = failures(by_scene)
    parts = ["<h3 id='failures'>Where plain runs were not verified converged, by scene "
             f"({len(fails)} row{'' if len(fails) == 1 else 's'})</h3>"]
    if len(fails):
        parts.append("<p class='small'>Per scene of the test set, solver and preset: the plain "
                     "runs (rung 0 of each ladder) and how each ended (every run is in the "
                     "report's test-set tables).</p>")
        parts.append(table_html(fails, left=("scene", "preset", "solver"), name="failures",
                                max_rows=500, row_id=lambda r: failure_anchor(str(r["scene"]))))
    else:
        parts.append("<p class='small'>Every run of every solver was verified converged.</p>")
    return parts
