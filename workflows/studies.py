"""The studies the Snakefile regenerates: one entry each, with the files it produces.

The Snakefile's default target is the union of every study's ``outputs``;
``contactbench list`` prints this table. Paths are relative to the repository.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Study:
    name: str
    summary: str
    thesis: str
    outputs: tuple[str, ...]


STUDIES = {
    s.name: s
    for s in (
        Study(
            name="laplace_nonmatching",
            summary="convergence of nodal constraints with/without the stabilisation (6.18) on a "
                    "non-matching grid: H1 and L2 errors, fitted rates, both constrained sides",
            thesis="Ch. 6, Figs. 6.3, 6.5, 6.6, Theorems 6.17/6.24",
            outputs=(
                "results/laplace_nonmatching/errors.csv",
                "results/laplace_nonmatching/errors_by_side.csv",
                "results/laplace_nonmatching/rates.csv",
                "results/laplace_nonmatching/convergence_sin10x.png",
                "results/laplace_nonmatching/convergence_linear.png",
                "results/laplace_nonmatching/mesh.png",
            ),
        ),
        Study(
            name="circle_square",
            summary="circle pressed onto a square (plane strain): exact contact solution per "
                    "level against plane-strain Hertz, fields, contact pressure",
            thesis="Sect. 9.1",
            outputs=(
                "results/circle_square/hertz.csv",
                "results/circle_square/fields.png",
                "results/circle_square/pressure.png",
            ),
        ),
        Study(
            name="solver_comparison",
            summary="OSQP, ProxSuite, Clarabel and the exact PDAS on identical circle-square QPs at "
                    "three tolerance presets: verified status, KKT residuals, time, energy error",
            thesis="Sect. 9.1 (problems), Ch. 8 (solvers)",
            outputs=(
                "results/circle_square/solvers.csv",
                "results/circle_square/solver_presets.csv",
                "results/circle_square/solver_times.png",
                "results/circle_square/solver_error_vs_time.png",
            ),
        ),
        Study(
            name="augmented_projection",
            summary="the thesis's solver (Alg. 8.4) with multigrid A-hat and a sparse multilevel "
                    "S-hat: Table 9.1 regenerated beside the thesis's, the O(N) claim tested "
                    "against the AMG-PCG linear solve as the floor",
            thesis="Ch. 8, Table 9.1, Figs. 9.1, 9.3",
            outputs=(
                "results/circle_square/table_9_1.csv",
                "results/circle_square/claims_ch8.csv",
                "results/circle_square/fig_9_1_time.png",
                "results/circle_square/fig_9_3_kappa.png",
            ),
        ),
    )
}
