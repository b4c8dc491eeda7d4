"""Every registered solver at every preset on one family's problems of an exported test set.

Reads the exported class folder (``contactbench export``; rule ``test_set_export``):
each problem's exact reference (``solution.npz``) and objective (``meta.json``).
Each problem is rebuilt from its definition (the solvers need its mesh hierarchy) and
checked against the exported ``P, q, G, h`` (a 3D frictional step's ``P, q, A, b``;
relative difference <= 1e-12), so every solver sees the problem a QP user downloads.
Per solver, one child process runs the presets in turn, each run with a hard wall-clock
limit (:class:`workflows.isolation.IsolatedSolver`): a hung or crashed run is a row. At
each preset a solver climbs its tolerance ladder (:mod:`workflows.ladder`: its own
tolerance ``tol * 10^-rung``, every rung verified at the preset's ``tol``): a row per
rung (``rung``, ``stop_factor``), rung 0 the plain run; the counted rung (``counted``:
the loosest verified) is repeated, its time's median, min and max over the ``repeats``
runs in ``time_median``, ``time_min``, ``time_max``. Before its first timed run a
solver's process solves the problem once, untimed (one iteration at the loosest rung): a
library's first call in a process loads it (imports, compiled kernels), which no later
call pays; and each run starts without the factorisations of the runs before it (its
verification, after the timed run, reuses them). ``problem_class`` is the problem's
class (:func:`workflows.problem_set.problem_class`). A frictional problem is one Tresca
step, handed to each solver as it takes friction (a solver without friction: ``skipped``
with its reason). A row per run: verified and claimed status, KKT residuals, certified
energy bound, time, the energy error ``||u - u_ref||_A / ||u_ref||_A``, the objective (a
Tresca step's energy) and its error relative to the reference's, the multipliers' errors
and the total-force error. Called by the rule ``test_set_runs``.

Cold and warm starts: every row has ``start`` ``cold`` (the solver starts from zero,
as every other table of the test set reads it). A frictional step has a recorded warm
start (``warm_start.npz``: the previous step of its load path's reference, the first
tangential step's the normal step's); with ``--warm-starts all`` (every such step) or
``paths`` (only the steps of a load-path family, ``step: all``) each solver that took
the cold problem runs it a second time started from ``u0, p0`` of that file (``start``
``warm``). ``used_guess`` says whether the run started from a guess: false for a cold
row, a run without an answer (skipped, killed, raised), and a solver that notes in its
message that it ignores a guess
(:data:`solvers.base.GUESS_NOT_USED`: the QP libraries that take none, the exact
reference). A faceted step (``friction_facets`` = k) records ``facets``, its isotropic
twin (the same family without ``friction_facets``) and ``model_error``, the faceted
reference's relative energy-norm distance ``||u_k - u_iso||_A / ||u_iso||_A`` to the
twin's exported reference (empty where the twin is not exported).

Example::

    python -m workflows.studies.test_set.run --set contact-qp-1 --class small \\
        --family hard_si_units --export results/test_set/contact-qp-1/small \\
        --presets low mid high --time-limit 20 --warm-starts paths --out runs.csv
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
import scipy.sparse.linalg as spla

from problems.kkt import energy_error
from solvers.base import GUESS_NOT_USED
from solvers.interface import TOLERANCES, solvers
from workflows.export import load_problem, objective, qp_arrays
from problems.spec import ParameterError
from workflows.io import read_json, run_solvers, write_csv
from workflows.isolation import IsolatedSolver, log_traceback
from workflows.ladder import LOOSEST, climb, stop_factor
from workflows.measure import multiplier_errors
from workflows.progress import study_progress
from workflows.settings import study_defaults
from workflows.problem_set import TestSetError, check_class, load, problem_class, step_choice

#: Largest relative difference between a rebuilt problem and its exported arrays.
IDENTICAL = 1e-12
#: ``--warm-starts``: which steps with a recorded warm start run warm too.
WARM_STARTS = ("all", "paths", "none")
#: The export's file of a frictional step's warm start.
WARM_FILE = "warm_start.npz"


def check_identical(qp, folder: Path) -> None:
    """Raise if the rebuilt ``qp`` is not the exported problem (to :data:`IDENTICAL`)."""
    mine, theirs = qp_arrays(qp), load_problem(folder)
    if set(mine) != set(theirs):
        raise RuntimeError(f"{folder.name}: the rebuilt problem has the arrays "
                           f"{sorted(mine)}, exported {sorted(theirs)}; re-export the set")
    for key in mine:
        a, b = mine[key], theirs[key]
        if a.shape != b.shape:
            raise RuntimeError(f"{folder.name}: {key} has shape {a.shape}, exported {b.shape}")
        diff = spla.norm(a - b) if hasattr(a, "tocsr") else np.linalg.norm(a - b)
        size = spla.norm(b) if hasattr(b, "tocsr") else np.linalg.norm(b)
        if diff > IDENTICAL * max(size, np.finfo(float).tiny):
            raise RuntimeError(f"{folder.name}: the rebuilt {key} differs from the exported "
                               f"one by {diff / size:.2e} (relative); re-export the set")


def runs_warm(family: dict, choice: str) -> bool:
    """Whether the steps of ``family`` (its entry in the set) with a recorded warm start run
    warm too under ``--warm-starts`` ``choice`` (:data:`WARM_STARTS`)."""
    if choice not in WARM_STARTS:
        raise ValueError(f"parameter 'warm_starts': {choice!r} is not allowed; allowed: "
                         f"{', '.join(WARM_STARTS)}")
    return choice == "all" or (choice == "paths" and step_choice(family) == "all")


def warm_guess(folder: Path) -> dict | None:
    """The recorded warm start of an exported problem as ``solve``'s ``u0``, ``p0`` (the
    displacements and normal multipliers of ``warm_start.npz``), ``None`` without one."""
    path = folder / WARM_FILE
    if not path.exists():
        return None
    with np.load(path) as z:
        return {"u0": np.array(z["u"], dtype=float), "p0": np.array(z["p"], dtype=float)}


def used_guess(res, warm: bool) -> bool:
    """Whether a run started from its guess: a warm run that returned an answer (not
    skipped, killed or raised: those say nothing of the guess) and whose message does not
    say it ignored the guess (:data:`solvers.base.GUESS_NOT_USED`)."""
    return bool(warm and res.kkt is not None and GUESS_NOT_USED not in (res.message or ""))


def isotropic_twin(ts, item) -> str | None:
    """The problem name of a faceted step's isotropic twin in the set ``ts``: the family
    with the same problem, parameters but ``friction_facets`` and step choice, at the
    same level and step (``None`` if ``item`` is not faceted or the set has no twin)."""
    params = dict(item.params)
    if not params.pop("friction_facets", 0):
        return None
    entry = ts.families[item.family]
    for family, other in ts.families.items():
        if (family != item.family and other["problem"] == item.problem
                and dict(other.get("params") or {}) == params
                and step_choice(other) == step_choice(entry)):
            return item.name.replace(item.family, family, 1)
    return None


def facet_columns(qp, item, twin: str | None, u_ref: np.ndarray, export: Path) -> dict:
    """A faceted step's ``facets``, ``isotropic_twin`` and ``model_error``
    ``||u_k - u_iso||_A / ||u_iso||_A`` of its reference ``u_ref`` against the twin's
    exported one (NaN if the twin is not in the export); ``{}`` for any other problem."""
    k = int(item.params.get("friction_facets", 0) or 0)
    if not k:
        return {}
    error = np.nan
    twin_file = None if twin is None else export / twin / "solution.npz"
    if twin_file is not None and twin_file.exists():
        with np.load(twin_file) as z:
            u_iso = np.asarray(z["u"], dtype=float)
        if u_iso.shape == (qp.n,):
            error = energy_error(qp, u_ref, u_iso)      # relative to the isotropic one
    return {"facets": k, "isotropic_twin": twin or "", "model_error": error}


def run_problem(item, folder: Path, names: list[str], presets: list[str],
                time_limit: float, warm: bool = False, twin: str | None = None) -> list[dict]:
    """The rows of every solver at every preset on one exported problem, started from
    zero (``start`` ``cold``); with ``warm`` and a recorded warm start (:func:`warm_guess`)
    also from it (``warm``) by every solver that did not skip the problem. ``twin``: a
    faceted step's isotropic twin (:func:`facet_columns`)."""
    meta = read_json(folder / "meta.json")
    qp = item.build()
    check_identical(qp, folder)
    with np.load(folder / "solution.npz") as z:          # a frictional step's: x = (u, t)
        u_ref, p_ref = z["x"][:qp.n], z["p"] if "p" in z.files else z["z"]
    J_ref = float(meta["objective"])
    scale = max(abs(J_ref), np.finfo(float).tiny)
    base = {"set": meta["set"], "problem": item.name, "family": item.family,
            "scene_problem": item.problem, "level": item.level, "size_class": item.size_class,
            "problem_class": problem_class(meta), "n": meta["n"], "m": meta["m"],
            "objective_ref": J_ref,
            "dropped_rows": qp.contact.dropped if qp.contact is not None else 0,
            **facet_columns(qp, item, twin, u_ref, folder.parent)}
    guess = warm_guess(folder) if warm else None

    def row_of(res, preset, start, rung=0, extra=None):
        log_traceback(res, f"{item.name} ({preset}, {start}, rung {rung})")
        row = {**base, "preset": preset, "start": start, "rung": rung,
               "stop_factor": stop_factor(rung), **res.summary(),
               "used_guess": used_guess(res, start == "warm"), **(extra or {})}
        if res.kkt is not None:
            J = objective(qp, res.u, res.p)
            row.update(objective=J, objective_error=abs(J - J_ref) / scale,
                       energy_error=energy_error(qp, res.u, u_ref),
                       **multiplier_errors(qp, res.p, p_ref, u_ref))
        return row

    rows = []
    for solver in names:
        with IsolatedSolver(qp, solver, time_limit) as child:
            taken = []
            for preset in presets:              # cold: the tolerance ladder (workflows.ladder)
                if preset == presets[0]:        # the process's first call, not timed
                    child.solve(preset, stop_factor=stop_factor(LOOSEST), max_iter=1)
                ladder = climb(lambda k: child.solve(preset, stop_factor=stop_factor(k)))
                for k, res in ladder.results.items():
                    counted = k == ladder.counted
                    rows.append(row_of(res, preset, "cold", k, {
                        "counted": counted, **(ladder.time_stats() if counted else
                                               {"repeats": 1})}))
                if ladder.results[0].status != "skipped":
                    taken.append(preset)
            if guess is not None:               # warm: the plain run from the guess
                rows += [row_of(child.solve(preset, **guess), preset, "warm")
                         for preset in taken]
    return rows


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--set", required=True, help="test set name, e.g. contact-qp-1")
    parser.add_argument("--class", dest="size_class", required=True, help="size class")
    parser.add_argument("--family", required=True, help="a family of the set")
    parser.add_argument("--export", required=True, help="the exported class folder")
    parser.add_argument("--solvers", nargs="+", default=None,
                        help="default: every registered solver (in a regeneration: of the "
                             "solver set fixed when it started)")
    parser.add_argument("--presets", nargs="+", default=list(TOLERANCES),
                        choices=list(TOLERANCES))
    parser.add_argument("--time-limit", type=float, required=True,
                        help="seconds per run (killed at 1.25 x + 30 s)")
    parser.add_argument("--levels", nargs="+", type=int, default=None,
                        help="only these levels of the family (default: the class's)")
    parser.add_argument("--warm-starts", choices=WARM_STARTS,
                        default=study_defaults("test_set")["warm_starts"],
                        help="run warm too: every step with a recorded warm start, only "
                             "the steps of load-path families (step: all), or none")
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    try:
        ts = load(args.set)
        items = ts.problems(check_class(args.size_class), [args.family])
    except TestSetError as err:
        parser.error(str(err))
    if args.levels is not None:
        items = [p for p in items if p.level in args.levels]
        if not items:
            parser.error(f"argument --levels: none of {args.levels} is a level of "
                         f"{args.family} in the class {args.size_class}")
    registry = solvers()
    unknown = sorted(set(args.solvers or ()) - set(registry))
    if unknown:
        parser.error(f"argument --solvers: unknown {unknown}; allowed: {', '.join(registry)}")
    try:
        names = args.solvers or run_solvers(registry)   # a regeneration's fixed set
    except ParameterError as err:
        parser.error(str(err))
    warm = runs_warm(ts.families[args.family], args.warm_starts)
    rows = []
    for item in study_progress(items, rule="test_set_runs", out=args.out,
                               desc=f"{args.family} ({args.size_class})"):
        rows += run_problem(item, Path(args.export) / item.name, names, args.presets,
                            args.time_limit, warm=warm, twin=isotropic_twin(ts, item))
    write_csv(args.out, pd.DataFrame(rows))


if __name__ == "__main__":
    main()
