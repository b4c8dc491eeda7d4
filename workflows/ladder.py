"""The tolerance ladder: each solver's time to a verified answer at matched accuracy.

A preset names the accuracy the suite verifies (``tol``: the scaled KKT residuals and the
certified energy bound). How close a solver's own stopping rule comes to it is the
solver's mapping, not the problem's: a library's defaults may stop short of a target its
tighter settings reach in a few more iterations, or go far past it. So the comparison
runs each solver on a ladder of its own tolerances, ``tol * 10^-k`` for rungs ``k``
(:func:`solvers.interface.solve`'s ``stop_factor``), every rung verified at ``tol``:

* rung 0 first, the plain run (its claim is the one the correct rate judges);
* verified there: the looser rungs -1, -2 while they still verify (a solver whose own
  rule overshoots reaches the target sooner); one not verified ends the descent;
* not verified (``inaccurate``: its claim refuted, or its tolerance too loose): the
  tighter rungs 1, 2, 3 until one verifies (the cap: rung 3, a thousand times tighter);
* stopped at its iteration limit (``max_iter``): the looser rungs, which may finish (a
  tighter one would not);
* a run that fails, is skipped or reaches its time limit ends the ladder.

At least :data:`MIN_RUNGS` rungs are run where the ladder goes on (the next tighter ones),
so that each solver's work-precision front over its ladder is a line, not a point. The
*counted* rung is the loosest verified one (:func:`counted_rung`); its run is repeated to
:data:`REPEATS` runs and its time is their median, with the min and max beside it.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

#: The ratio of the solver's tolerance between neighbouring rungs.
STEP = 10.0
#: The loosest and the tightest rung.
LOOSEST, TIGHTEST = -2, 3
#: Rungs run at least (where no run was stopped), for a work-precision front.
MIN_RUNGS = 3
#: Runs of the counted rung whose times give its median and spread.
REPEATS = 3
#: Statuses that end a ladder.
ENDS = ("failed", "skipped", "time_limit")


def stop_factor(rung: int) -> float:
    """The solver's tolerance over the target at ``rung``: ``10^-rung``."""
    return STEP ** -rung


def next_rung(statuses: dict[int, str]) -> int | None:
    """The rung to run next given the verified ``statuses`` of the rungs run so far
    (``{rung: status}``), or None when the ladder is done (the module docstring)."""
    if 0 not in statuses:
        return 0
    if any(s in ENDS for s in statuses.values()):
        return None
    loosest, tightest = min(statuses), max(statuses)
    if loosest > LOOSEST and statuses[loosest] in ("converged", "max_iter") and \
            statuses[0] in ("converged", "max_iter"):
        return loosest - 1
    verified = any(s == "converged" for s in statuses.values())
    if tightest < TIGHTEST and statuses[tightest] != "max_iter" and \
            (not verified or len(statuses) < MIN_RUNGS):
        return tightest + 1
    return None


def counted_rung(statuses: dict[int, str]) -> int | None:
    """The loosest rung verified ``converged`` (None if none is)."""
    verified = [k for k, s in statuses.items() if s == "converged"]
    return min(verified) if verified else None


@dataclass
class LadderRun:
    """One solver's ladder on one problem at one target.

    ``results``: ``{rung: SolveResult}`` in the order run; ``counted``: the counted rung
    (None: no rung verified); ``times``: the counted rung's run times (``total_time``,
    :data:`REPEATS` of them), empty without one."""

    results: dict
    counted: int | None
    times: list

    def time_stats(self) -> dict:
        """The counted rung's ``time_median``, ``time_min``, ``time_max`` and ``repeats``
        (NaN and 0 without one)."""
        if not self.times:
            return {"time_median": np.nan, "time_min": np.nan, "time_max": np.nan,
                    "repeats": 0}
        t = np.asarray(self.times, dtype=float)
        return {"time_median": float(np.median(t)), "time_min": float(t.min()),
                "time_max": float(t.max()), "repeats": len(t)}


def climb(run: Callable[[int], object], repeats: int = REPEATS) -> LadderRun:
    """Run the ladder: ``run(rung)`` returns a verified ``SolveResult`` at that rung
    (:func:`stop_factor`); the counted rung is run ``repeats - 1`` more times and the
    times of the runs that end as the first did are kept (one stopped by the machine,
    e.g. at its time limit, is not a repeat of a verified run)."""
    results: dict = {}
    while (rung := next_rung({k: r.status for k, r in results.items()})) is not None:
        results[rung] = run(rung)
    counted = counted_rung({k: r.status for k, r in results.items()})
    times = []
    if counted is not None:
        times = [results[counted].total_time]
        for _ in range(repeats - 1):
            again = run(counted)
            if again.status == results[counted].status:
                times.append(again.total_time)
    return LadderRun(results, counted, times)
