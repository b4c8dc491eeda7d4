"""Every registered solver at every preset on one family's problems of an exported test set.

Reads the exported class folder (``contactbench export``; rule ``test_set_export``):
each problem's exact reference (``solution.npz``) and objective (``meta.json``).
Each problem is rebuilt from its definition (the solvers need its mesh hierarchy)
and checked against the exported ``P, q, G, h`` (a 3D frictional step's ``P, q, A,
b``; relative difference <= 1e-12),
so every solver sees the problem a QP user downloads. Per solver, one child
process runs the presets in turn, each with a hard wall-clock limit
(:func:`workflows.isolation.solve_batch_isolated`): a hung or crashed run is a
row. A frictional problem is one Tresca step, handed to each solver as it takes
friction (a solver without friction: ``skipped`` with its reason). A row per run:
verified and claimed status, KKT residuals, certified energy
bound, time, the energy error ``||u - u_ref||_A / ||u_ref||_A``, the objective (a Tresca
step's energy) and
its error relative to the reference's, the multipliers' errors and the total-force
error. Called by the rule ``test_set_runs``.

Example::

    python -m workflows.scripts.problem_set_runs --set contact-qp-1 --class small \\
        --family hard_si_units --export results/test_set/contact-qp-1/small \\
        --presets low mid high --time-limit 20 --out runs.csv
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
import scipy.sparse.linalg as spla

from problems.kkt import energy_error
from solvers.interface import TOLERANCES, solvers
from workflows.export import load_problem, objective, qp_arrays
from problems.spec import ParameterError
from workflows.io import read_json, run_solvers, write_csv
from workflows.isolation import log_traceback, solve_batch_isolated
from workflows.measure import multiplier_errors
from workflows.progress import study_progress
from workflows.problem_set import TestSetError, check_class, load

#: Largest relative difference between a rebuilt problem and its exported arrays.
IDENTICAL = 1e-12


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


def run_problem(item, folder: Path, names: list[str], presets: list[str],
                time_limit: float) -> list[dict]:
    """The rows of every solver at every preset on one exported problem."""
    meta = read_json(folder / "meta.json")
    qp = item.build()
    check_identical(qp, folder)
    with np.load(folder / "solution.npz") as z:          # a frictional step's: x = (u, t)
        u_ref, p_ref = z["x"][:qp.n], z["p"] if "p" in z.files else z["z"]
    J_ref = float(meta["objective"])
    scale = max(abs(J_ref), np.finfo(float).tiny)
    base = {"set": meta["set"], "problem": item.name, "family": item.family,
            "scene_problem": item.problem, "level": item.level, "size_class": item.size_class,
            "n": meta["n"], "m": meta["m"], "objective_ref": J_ref,
            "dropped_rows": qp.contact.dropped if qp.contact is not None else 0}
    rows = []
    for solver in names:
        results = solve_batch_isolated(qp, solver, presets, time_limit=time_limit)
        for preset, res in zip(presets, results):
            log_traceback(res, f"{item.name} ({preset})")
            row = {**base, "preset": preset, **res.summary()}
            if res.kkt is not None:
                J = objective(qp, res.u, res.p)
                row.update(objective=J, objective_error=abs(J - J_ref) / scale,
                           energy_error=energy_error(qp, res.u, u_ref),
                           **multiplier_errors(qp, res.p, p_ref, u_ref))
            rows.append(row)
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
    rows = []
    for item in study_progress(items, rule="test_set_runs", out=args.out,
                               desc=f"{args.family} ({args.size_class})"):
        rows += run_problem(item, Path(args.export) / item.name, names, args.presets,
                            args.time_limit)
    write_csv(args.out, pd.DataFrame(rows))


if __name__ == "__main__":
    main()
