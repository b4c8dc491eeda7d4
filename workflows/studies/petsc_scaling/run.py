"""Strong scaling of the distributed solver: PETSc/Tao (:mod:`solvers.petsc_tao`) at each
configured number of MPI ranks on the same problems, and TNNMG in one process beside it.

Per scene level: ``petsc_tao`` at every ``--ranks`` and ``tnnmg`` once, each run in its
own process with a hard wall-clock limit (:func:`workflows.isolation.solve_isolated`: a
hung, killed or failed MPI job is a row), at one preset. The table
(:func:`scaling_table`) adds, per level and solver run, the speed-up over the one-rank
run ``T(1) / T(r)``, the parallel efficiency ``T(1) / (r T(r))`` and TNNMG's time over
PETSc's (above 1: PETSc pays there); ``T`` is the run's total time, the MPI job's start-up
and the problem's transfer included (what a user waits for). Rows that did not converge
have no speed-up. Each PETSc run at more than one rank also records how far its answer
lies from the one-rank answer, ``||u_r - u_1||_A / ||u_1||_A``, and the bar the two
certified energy-error bounds give it (:func:`agreement`). The claims (:func:`scaling_claims`) say it as data: the best
efficiency at the most ranks, and the smallest problem where PETSc beats TNNMG.

Example::

    python -m workflows.studies.petsc_scaling.run --problem cube_sphere --levels 1 2 \\
        --ranks 1 2 --out results/cube_sphere/petsc_scaling.csv
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from solvers.interface import TOLERANCES
from workflows.io import write_csv
from workflows.isolation import solve_isolated
from workflows.progress import study_progress
from workflows.scene_args import add_scene_arguments, check_levels, scene_from_args

#: The one-process solver beside the distributed one.
BESIDE = "tnnmg"


def scaling_table(rows: pd.DataFrame) -> pd.DataFrame:
    """``rows`` (one per run: ``level``, ``solver``, ``ranks``, ``status``, ``total_time``)
    with ``speedup``, ``efficiency`` (PETSc's rows, against its one-rank run of the same
    level) and ``tnnmg_over_petsc`` (TNNMG's time over the run's)."""
    t = rows.copy()
    ok = t["status"] == "converged"
    time = t["total_time"].where(ok)
    t["speedup"] = np.nan
    t["efficiency"] = np.nan
    t["tnnmg_over_petsc"] = np.nan
    for level, g in t.groupby("level"):
        petsc = g[g["solver"] == "petsc_tao"]
        one = time[petsc.index[petsc["ranks"] == 1]]
        beside = time[g.index[g["solver"] == BESIDE]]
        t1 = float(one.iloc[0]) if len(one) else np.nan
        tb = float(beside.iloc[0]) if len(beside) else np.nan
        t.loc[petsc.index, "speedup"] = t1 / time[petsc.index]
        t.loc[petsc.index, "efficiency"] = t1 / (petsc["ranks"] * time[petsc.index])
        t.loc[petsc.index, "tnnmg_over_petsc"] = tb / time[petsc.index]
    return t


def agreement(A, u_r, u_1, bound_r: float, bound_1: float) -> tuple[float, float]:
    """How far the ``r``-rank answer lies from the one-rank answer, and how far it may.

    Returns ``(distance, bar)``: ``distance = ||u_r - u_1||_A / ||u_1||_A`` and, from the
    certified relative energy-error bounds ``b`` of the two runs (each at least its
    floating-point floor; :class:`solvers.certificate.DualityGap`), ``bar = (b_r + b_1)
    / (1 - b_1)``: by the triangle inequality ``||u_r - u_1||_A <= (b_r + b_1) ||u*||_A``
    and ``||u*||_A <= ||u_1||_A / (1 - b_1)``. Two correct runs always meet the bar; a
    distributed solve that converged to something else does not.
    """
    d = np.asarray(u_r, dtype=float) - np.asarray(u_1, dtype=float)
    norm_1 = float(np.sqrt(max(float(u_1 @ (A @ u_1)), 0.0)))
    distance = float(np.sqrt(max(float(d @ (A @ d)), 0.0))) / norm_1 if norm_1 > 0 else np.nan
    bar = (bound_r + bound_1) / (1.0 - bound_1) if bound_1 < 1.0 else np.inf
    return distance, bar


def _bound(res) -> float:
    """A run's certified relative energy-error bound, at least its floating-point floor
    (inf without a certificate)."""
    if res.gap is None or not res.gap.certified:
        return np.inf
    return res.gap.certified_bound


def scaling_claims(table: pd.DataFrame) -> pd.DataFrame:
    """The study's statements as data: per scene, the parallel efficiency at the most ranks
    on the largest level, and the smallest problem (unknowns) where PETSc at some rank
    count is faster than TNNMG in one process (NaN: nowhere measured)."""
    out = []
    for scene, g in table.groupby("scene_problem"):
        petsc = g[g["solver"] == "petsc_tao"]
        top = petsc[petsc["level"] == petsc["level"].max()]
        most = top[top["ranks"] == top["ranks"].max()]
        pays = petsc[petsc["tnnmg_over_petsc"] > 1.0]
        out += [{"scene_problem": scene, "claim": "efficiency_at_most_ranks",
                 "ranks": int(most["ranks"].iloc[0]) if len(most) else np.nan,
                 "n": int(most["n"].iloc[0]) if len(most) else np.nan,
                 "value": float(most["efficiency"].iloc[0]) if len(most) else np.nan},
                {"scene_problem": scene, "claim": "petsc_faster_than_tnnmg_from_n",
                 "ranks": int(pays.sort_values("n")["ranks"].iloc[0]) if len(pays) else np.nan,
                 "n": int(pays["n"].min()) if len(pays) else np.nan,
                 "value": float(pays.sort_values("n")["tnnmg_over_petsc"].iloc[0])
                 if len(pays) else np.nan}]
    return pd.DataFrame(out)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(parser)
    parser.add_argument("--levels", type=int, nargs="+", required=True)
    parser.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--preset", default="mid", choices=list(TOLERANCES))
    parser.add_argument("--time-limit", type=float, default=600.0)
    parser.add_argument("--out", required=True, help="the runs with speed-up and efficiency")
    parser.add_argument("--claims", default=None, help="default: <out>_claims.csv")
    args = parser.parse_args(argv)
    if min(args.ranks) < 1 or 1 not in args.ranks:
        parser.error(f"argument --ranks: {args.ranks} is not allowed; allowed: integers >= 1 "
                     "including 1 (the speed-up's base)")
    spec, params = scene_from_args(parser, args)
    levels = check_levels(parser, spec, args.levels)
    runs = [(level, "petsc_tao", r) for level in levels for r in sorted(set(args.ranks))]
    runs += [(level, BESIDE, 1) for level in levels]
    rows, built, one_rank = [], {}, {}
    for level, solver, ranks in study_progress(sorted(runs), rule="petsc_scaling",
                                               out=args.out, desc=f"{spec.name} scaling"):
        if level not in built:
            built = {level: spec.build(level, params)}
        qp = built[level]
        options = {"ranks": ranks} if solver == "petsc_tao" else {}
        res = solve_isolated(qp, solver, args.preset, time_limit=args.time_limit, **options)
        distance = bar = np.nan
        if solver == "petsc_tao" and res.status == "converged":
            if ranks == 1:
                one_rank[level] = res
            elif level in one_rank:
                base = one_rank[level]
                distance, bar = agreement(qp.A, res.u, base.u, _bound(res), _bound(base))
        rows.append({"scene_problem": spec.name, "level": level, "n": qp.n, "m": qp.m,
                     "ranks": ranks, "preset": args.preset, **res.summary(),
                     "distance_to_one_rank": distance, "agreement_bar": bar})
    table = scaling_table(pd.DataFrame(rows))
    write_csv(args.out, table)
    claims = args.claims or str(Path(args.out).with_name(Path(args.out).stem + "_claims.csv"))
    write_csv(claims, scaling_claims(table))


if __name__ == "__main__":
    main()
