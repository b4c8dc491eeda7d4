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
  tighter rungs 1, 2, 3 until one verifies (the cap: rung 3, a thousand times tighter),
  unless a tighter rung changed nothing (the same iterations and the same certified
  bound: the solver's tolerance is not what limits it);
* stopped at its iteration limit (``max_iter``): the looser rungs, which may finish (a
  tighter one would not);
* a run that fails, is skipped or reaches its time limit ends the ladder.

At least :data:`MIN_RUNGS` rungs are run where the ladder goes on (looser ones first, which
cost less), so that each solver's work-precision front over its ladder is a line, not a
point. The
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


@dataclass(frozen=True)
class Outcome:
    """What the ladder reads of a rung's verified run: ``status``, ``iterations`` and the
    certified relative energy ``bound``."""

    status: str
    iterations: int = 0
    bound: float = float("inf")

    @classmethod
    def of(cls, result) -> "Outcome":
        gap = getattr(result, "gap", None)
        return cls(result.status, int(getattr(result, "iterations", 0) or 0),
                   gap.certified_bound if gap is not None else float("inf"))


def _stalled(runs: dict[int, Outcome], rung: int) -> bool:
    """Whether ``rung`` changed nothing against the rung before it (the same iterations
    and certified bound to 1e-9 relative)."""
    a, b = runs.get(rung - 1), runs.get(rung)
    return (a is not None and b is not None and a.iterations == b.iterations
            and abs(a.bound - b.bound) <= 1e-9 * max(abs(a.bound), abs(b.bound)))


def next_rung(runs: dict[int, Outcome | str]) -> int | None:
    """The rung to run next given the outcomes of the rungs run so far (``{rung:
    Outcome}``, or ``{rung: status}``), or None when the ladder is done (the module
    docstring)."""
    runs = {k: v if isinstance(v, Outcome) else Outcome(v) for k, v in runs.items()}
    if 0 not in runs:
        return 0
    status = {k: r.status for k, r in runs.items()}
    if any(s in ENDS for s in status.values()):
        return None
    loosest, tightest = min(runs), max(runs)
    going_on = ("converged", "max_iter")
    if loosest > LOOSEST and status[loosest] in going_on and status[0] in going_on:
        return loosest - 1
    verified = "converged" in status.values()
    if (not verified and tightest < TIGHTEST and status[tightest] == "inaccurate"
            and not _stalled(runs, tightest)):
        return tightest + 1
    if len(runs) < MIN_RUNGS:                  # the front: looser first, which costs less
        if loosest > LOOSEST:
            return loosest - 1
        if tightest < TIGHTEST and status[tightest] != "max_iter":
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
    while (rung := next_rung({k: Outcome.of(r) for k, r in results.items()})) is not None:
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
