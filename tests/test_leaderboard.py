"""The solver comparison's leaderboards: the tolerance ladder's policy, one board per
problem class with the references apart, time at matched accuracy, and the fastest
verified solver named from the runs as a reader would compute it."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from problems.spec import ParameterError, problems
from report import leaderboard
from solvers.interface import solve
from workflows.ladder import (LOOSEST, MIN_RUNGS, TIGHTEST, Outcome, climb, counted_rung,
                              next_rung)


def _climb(outcome) -> dict[int, str]:
    statuses = {}
    while (rung := next_rung(statuses)) is not None:
        statuses[rung] = outcome(rung)
    return statuses


@pytest.mark.parametrize("outcome, rungs, counted", [
    (lambda k: "converged", [0, -1, -2], -2),                       # overshooting rule
    (lambda k: "converged" if k >= 0 else "inaccurate", [0, -1, -2], 0),
    (lambda k: "converged" if k >= 2 else "inaccurate", [0, 1, 2], 2),   # stops short
    (lambda k: Outcome("inaccurate", 10 + k, 10.0 ** -k), [0, 1, 2, 3], None),  # the cap
    (lambda k: Outcome("inaccurate", 5, 1e-5), [0, 1, -1], None),   # tighter changes nothing
    (lambda k: "max_iter" if k >= 0 else "converged", [0, -1, -2], -2),
    (lambda k: "skipped", [0], None),
    (lambda k: "time_limit", [0], None),
])
def test_the_ladder_climbs_until_verified_and_keeps_a_front(outcome, rungs, counted):
    statuses = _climb(outcome)
    assert sorted(statuses) == sorted(rungs) and list(statuses)[0] == 0
    assert all(LOOSEST <= k <= TIGHTEST for k in statuses)
    assert counted_rung({k: getattr(v, "status", v) for k, v in statuses.items()}) == counted
    if getattr(outcome(0), "status", outcome(0)) in ("converged", "inaccurate"):
        assert len(statuses) >= MIN_RUNGS                  # a line, not a point


def test_climb_repeats_the_counted_rung():
    class Run:
        def __init__(self, status, t):
            self.status, self.total_time = status, t

    times = iter([5.0, 1.0, 2.0, 3.0, 9.0])
    ladder = climb(lambda k: Run("converged" if k >= 0 else "inaccurate", next(times)))
    assert ladder.counted == 0 and list(ladder.results) == [0, -1, -2]
    assert ladder.times == [5.0, 3.0, 9.0]
    assert ladder.time_stats() == {"time_median": 5.0, "time_min": 3.0, "time_max": 9.0,
                                   "repeats": 3}


def test_a_rung_asks_the_solver_for_its_own_tolerance_and_verifies_at_the_target():
    qp = problems()["flat_blocks"].make(1)
    plain = solve(qp, "clarabel", tol=1e-3)
    tight = solve(qp, "clarabel", tol=1e-3, stop_factor=1e-3)
    assert tight.tol == plain.tol == 1e-3                 # judged at the target
    assert tight.iterations > plain.iterations and tight.kkt.max < 1e-2 * plain.kkt.max
    # Clarabel's mapping of 1e-3 stops short of the suite's 1e-3; a tighter rung reaches it
    assert (plain.status, tight.status) == ("inaccurate", "converged")
    with pytest.raises(ParameterError, match="'stop_factor'.*tol \\* stop_factor < 1"):
        solve(qp, "osqp", tol=0.1, stop_factor=100)
    with pytest.raises(ParameterError, match="'stop_factor'"):
        solve(qp, "osqp", tol=1e-6, stop_factor=0.0)


def _runs() -> pd.DataFrame:
    """A small runs table: two frictionless problems, one 2D frictional one; the exact
    references, a fast solver that skips one problem, a slower one that verifies all,
    one that needs a tighter rung, and one that declines friction."""
    rows = []

    def add(problem, cls, solver, rung, status, time, counted=False, err=1e-8,
            median=None, message=""):
        rows.append({"problem": problem, "family": problem[:-3], "problem_class": cls,
                     "size_class": "small", "preset": "mid", "tol": 1e-6, "start": "cold",
                     "solver": solver, "rung": rung, "status": status,
                     "claimed_status": "converged" if status in ("converged", "inaccurate")
                     else status, "time": time, "total_time": time, "counted": counted,
                     "time_median": median if median is not None else
                     (time if counted else np.nan),
                     "time_min": time if counted else np.nan,
                     "time_max": 1.1 * time if counted else np.nan,
                     "energy_error": err if status != "skipped" else np.nan,
                     "energy_bound_floor": 8e-8, "failed_check": "" if status != "inaccurate"
                     else "energy_bound", "message": message})

    for p in ("fa_L0", "fb_L0"):
        add(p, "frictionless", "pdas", 0, "converged", 0.01, True, err=0.0)
        add(p, "frictionless", "steady", 0, "converged", 0.20, True)
        add(p, "frictionless", "tight", 0, "inaccurate", 0.05, err=1e-5)
        add(p, "frictionless", "tight", 1, "converged", 0.08, True)
        add(p, "frictionless", "tresca_only", 0, "skipped", 0.0,
            message="skipped: a frictionless problem")
    add("fa_L0", "frictionless", "quick", 0, "converged", 0.02, True)
    add("fb_L0", "frictionless", "quick", 0, "skipped", 0.0, message="skipped: too large")
    add("ft_L0", "friction_2d", "tresca_only", 0, "converged", 0.03, True, err=0.0)
    add("ft_L0", "friction_2d", "steady", 0, "converged", 0.5, True)
    add("ft_L0", "friction_2d", "pdas", 0, "skipped", 0.0, message="skipped: frictionless only")
    return pd.DataFrame(rows)


ROLES = {"pdas": "exact", "tresca_only": "exact", "steady": "newton", "tight": "library",
         "quick": "library"}


def test_one_board_per_class_with_the_references_apart_and_skips_charged():
    boards = dict(leaderboard.boards(_runs(), ROLES, time_limit=20.0))
    assert list(boards) == [("frictionless", "small", "mid"), ("friction_2d", "small", "mid")]
    flat = boards["frictionless", "small", "mid"]
    assert set(flat["table"]["solver"]) == {"steady", "tight", "quick"}      # contestants
    assert list(flat["references"]["solver"]) == ["pdas"]                    # the baseline
    assert flat["declined"] == {"tresca_only": "a frictionless problem"}
    table = flat["table"].set_index("solver")
    assert table.loc["quick", "verified"] == 1 and table.loc["quick", "problems"] == 2
    # time at matched accuracy: tight's counted rung 1, not its refuted rung 0
    assert table.loc["tight", "verified"] == 2 and table.loc["tight", "plain_verified"] == 0
    assert table.loc["tight", "correct_share"] == 0.0                     # claims refuted
    assert flat["fastest"] == "tight"      # quick is faster but verified on half the class
    # the reference's own correctness from an independent answer, never from itself
    ref = flat["references"].iloc[0]
    assert ref["independent_agreement"] == pytest.approx(1e-8) and ref["independent_within"]
    fric = boards["friction_2d", "small", "mid"]
    assert list(fric["references"]["solver"]) == ["tresca_only"]
    assert "pdas" in fric["declined"] and list(fric["table"]["solver"]) == ["steady"]


def test_the_fastest_verified_is_the_best_median_ratio_among_the_covering_solvers():
    """Computed from the runs table as a reader would, without the module's helpers."""
    t = _runs()
    t = t[t["problem_class"] == "frictionless"]
    verified = t[t["counted"]].set_index(["problem", "solver"])["time_median"]
    contest = [s for s in t["solver"].unique() if ROLES[s] != "exact"
               and not (t[t.solver == s]["status"] == "skipped").all()]
    problems_ = sorted(t["problem"].unique())
    best = {p: min(verified[p, s] for s in contest if (p, s) in verified) for p in problems_}
    ratios = {s: np.median([verified[p, s] / best[p] if (p, s) in verified else np.inf
                            for p in problems_]) for s in contest}
    covering = [s for s in contest
                if sum((p, s) in verified for p in problems_) >= 0.9 * len(problems_)]
    expected = min(covering, key=lambda s: ratios[s])
    board = dict(leaderboard.boards(_runs(), ROLES, 20.0))["frictionless", "small", "mid"]
    assert board["fastest"] == expected


def test_the_results_page_states_its_settings():
    all_boards = leaderboard.boards(_runs(), ROLES, time_limit=20.0)
    settings = {"test_set": "contact-qp-5", "scale": "quick", "ladder": "-2 to 3",
                "repeats": 3, "time_limit": 20.0, "load": "taken alone", "machine": "x, 2 cores",
                "commit": "abc", "versions": "osqp 1"}
    page = leaderboard.markdown_page(
        "frictionless", [(k, b) for k, b in all_boards if k[0] == "frictionless"], settings)
    for words in ("Time limit** 20 s", "Repeats**: the counted rung is run 3 times",
                  "**Shift**", "**Load**: taken alone", "**Machine**: x, 2 cores",
                  "Fastest verified: tight", "Baseline (the exact references, not ranked)",
                  "- tresca_only: a frictionless problem", "| 1 | tight |"):
        assert words in page, words
    empty = leaderboard.markdown_page("friction_3d_cone", [], settings)
    assert "No problem of this class runs in this configuration." in empty
