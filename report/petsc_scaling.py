"""Strong scaling of the distributed solver: the claims and the figure from
``workflows/studies/petsc_scaling/run.py``'s runs (one table per scene).

Claims, per scene: every run verified converged (petsc_tao at each rank count, TNNMG in
one process); the answers at more ranks agree with the one-rank answer within the sum of
the two runs' certified energy-error bounds (:func:`workflows.studies.petsc_scaling.run.agreement`:
two correct answers always do); the parallel efficiency at the most ranks on the largest
level and TNNMG's time over PETSc's best there, both reported and not judged (see
:data:`REPORTED`). Where PETSc and MPI are not installed every petsc_tao row is
``skipped`` with the reason; the claims then say so and judge nothing about PETSc.

Example::

    python -m report.petsc_scaling --runs results/cube_sphere/petsc_scaling.csv \\
        --scene cube_sphere --claims c.csv --figure f.png
"""
from __future__ import annotations

import argparse

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.ticker import NullFormatter

from report.claims import COLUMNS, Claim
from report.figures import (legend_below, nothing_to_draw, save_figure,
                            solver_style)
from workflows.io import read_csv, write_csv

#: Why the efficiency and the comparison with TNNMG are reported, not judged.
REPORTED = ("a time measured here shares the machine's cores with other work and includes "
            "the MPI job's start-up and the problem's transfer: it says how the run went "
            "here, not what PETSc can do; a bar needs a quiet machine or a cluster")

#: The petsc_scaling study's claims (report/claims.py).
CLAIMS = {
    "converged": Claim("suite bar (a timed run counts only if verified)",
                       "petsc_tao and TNNMG verified converged on every level", "given",
                       "all", details="petsc_tao at ranks {ranks}"),
    "petsc_skipped": Claim("suite bar (a run that cannot take place says why)",
                           "petsc_tao not run",
                           unjudged="a skipped run measures nothing; the measured column gives the reason"),
    "agreement": Claim("suite bar (two answers within their certified energy-error bounds "
                       "of the exact one lie within the bounds' sum of each other)",
                       "petsc_tao at r ranks agrees with one rank within the bounds", "<=",
                       1.0, details="largest ||u_r - u_1||_A / ||u_1||_A over its bar (b_r + "
                       "b_1) / (1 - b_1), r > 1, every level"),
    "efficiency": Claim("the suite (strong scaling of the distributed solver)",
                        "petsc_tao's parallel efficiency T(1) / (r T(r))", unjudged=REPORTED,
                        details="r = {ranks} ranks, n = {n:,}"),
    "tnnmg_over_petsc": Claim("the suite (where PETSc starts to pay)",
                              "TNNMG's time over petsc_tao's best (above 1: PETSc pays)",
                              unjudged=REPORTED, details="petsc_tao's best at r = {ranks}"),
}


def _petsc(t: pd.DataFrame) -> pd.DataFrame:
    return t[t.solver == "petsc_tao"]


def skip_reason(t: pd.DataFrame) -> str | None:
    """The reason every petsc_tao run was skipped (None if any ran)."""
    p = _petsc(t)
    if len(p) and (p.status == "skipped").all():
        return str(p.message.iloc[0])
    return None


def claims(t: pd.DataFrame, scene: str) -> pd.DataFrame:
    """The claims of the module docstring for one scene's runs."""
    rows = []
    ranks = ", ".join(map(str, sorted(_petsc(t).ranks.unique())))
    reason = skip_reason(t)
    if reason is not None:
        rows.append(CLAIMS["petsc_skipped"].row(reason, scene=scene))
    ok = int((t.status == "converged").sum())
    rows.append(CLAIMS["converged"].row(f"{ok} of {len(t)}", judged=reason is None,
                                        passed=ok == len(t), scene=scene, ranks=ranks,
                                        reason="petsc_tao was skipped"))
    p = _petsc(t)
    ratio = (p.distance_to_one_rank / p.agreement_bar)[p.ranks > 1].dropna()
    rows.append(CLAIMS["agreement"].row(float(ratio.max()) if len(ratio) else np.nan,
                                        judged=bool(len(ratio)), scene=scene,
                                        reason="needs converged petsc_tao runs at 1 and at "
                                        "more ranks on one level"))
    top = p[p.level == p.level.max()] if len(p) else p
    if len(top):
        most = top[top.ranks == top.ranks.max()].iloc[0]
        rows.append(CLAIMS["efficiency"].row(most.efficiency, scene=scene, ranks=int(most.ranks),
                                             level=int(most.level), n=int(most.n)))
        best = top[top.status == "converged"].sort_values("total_time")
        if len(best):
            rows.append(CLAIMS["tnnmg_over_petsc"].row(
                best.tnnmg_over_petsc.iloc[0], scene=scene, ranks=int(best.ranks.iloc[0]),
                level=int(best.level.iloc[0])))
    return pd.DataFrame(rows, columns=COLUMNS)


#: Line style per level (the solver's colour and marker are the same at every level).
LEVEL_LINES = ("-", "--", "-.", ":")


def figure(t: pd.DataFrame, scene: str, path: str) -> None:
    """Time and iterations against ranks, per level, with TNNMG's time beside; the
    parallel efficiency against ranks. Each solver in its colour and marker of every
    figure, a level by its line style, the legends below the panels. Without a converged
    petsc_tao run (PETSc not installed, every run stopped short) the image says why
    instead."""
    p = _petsc(t)
    ok = p[p.status == "converged"]
    if not len(ok):
        reason = skip_reason(t)
        nothing_to_draw(path, f"{scene}: strong scaling of petsc_tao",
                        f"petsc_tao {reason}" if reason is not None else
                        "no petsc_tao run converged (the table gives each run's status)",
                        scene=scene)
        return
    fig, ax = plt.subplots(1, 3, figsize=(12.5, 4.6))
    petsc = solver_style("petsc_tao")
    for i, (level, g) in enumerate(t.groupby("level")):
        ls = LEVEL_LINES[i % len(LEVEL_LINES)]
        mine = ok[ok.level == level].sort_values("ranks")
        n = int(g.n.iloc[0])
        if len(mine):
            ax[0].loglog(mine.ranks, mine.total_time, ls=ls, **petsc,
                         label=f"petsc_tao, level {level} (n = {n})")
            ax[1].semilogx(mine.ranks, mine.iterations, ls=ls, **petsc,
                           label=f"Tao iterations, level {level}")
            if "ksp_iterations" in mine:
                ax[1].semilogx(mine.ranks, mine.ksp_iterations, ls=ls, **petsc, mfc="none",
                               label=f"Krylov iterations (hollow), level {level}")
            ax[2].semilogx(mine.ranks, mine.efficiency, ls=ls, **petsc,
                           label=f"petsc_tao, level {level} (n = {n})")
        beside = g[(g.solver != "petsc_tao") & (g.status == "converged")]
        if len(beside):
            solver = beside.solver.iloc[0]
            ax[0].axhline(float(beside.total_time.iloc[0]), ls=ls, lw=1,
                          color=solver_style(solver)["color"],
                          label=f"{solver}, one process, level {level}")
    ax[2].axhline(1.0, color="k", ls=":", lw=0.8, label="ideal")
    ax[0].set_ylabel("total time per solve [s]\n(this machine)")
    ax[1].set_ylabel("iterations")
    ax[2].set_ylabel("parallel efficiency T(1) / (r T(r))")
    titles = ("time against ranks", "iterations against ranks", "parallel efficiency")
    ranks = sorted(int(r) for r in p.ranks.unique())
    for a, title in zip(ax, titles):
        if ranks:
            a.set_xticks(ranks, [str(r) for r in ranks])
            a.xaxis.set_minor_formatter(NullFormatter())
        a.set_xlabel("MPI ranks r")
        a.set_title(f"{scene}: {title}", fontsize=10)
        a.grid(True, which="both", alpha=0.3)
        legend_below(a)
    save_figure(fig, path, scene=scene)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", required=True, help="the study's runs of one scene")
    parser.add_argument("--scene", required=True)
    parser.add_argument("--claims", required=True)
    parser.add_argument("--figure", required=True)
    args = parser.parse_args(argv)
    t = read_csv(args.runs)
    write_csv(args.claims, claims(t, args.scene))
    figure(t, args.scene, args.figure)


if __name__ == "__main__":
    main()
