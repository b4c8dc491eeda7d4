"""The Laplace problem on a non-matching grid (thesis Ch. 6): nodal constraints with and
without the stabilisation (6.18), and mortar, under refinement."""
from workflows.studies._base import Study, ThesisItem

STUDY = Study(
    name="laplace_nonmatching",
    summary="convergence of nodal constraints with/without the stabilisation (6.18) on a "
            "non-matching grid: H1 and L2 errors, fitted rates, both constrained sides",
    thesis="Ch. 6, Figs. 6.3, 6.5, 6.6, Theorems 6.17/6.24",
    order=10,
    scripts={"laplace_nonmatching": "workflows.studies.laplace_nonmatching.run"},
    paths={
        "laplace_runs": "results/laplace_nonmatching/runs/{case}_{side}.csv",
        "laplace_errors": "results/laplace_nonmatching/errors.csv",
        "laplace_errors_by_side": "results/laplace_nonmatching/errors_by_side.csv",
        "laplace_rates": "results/laplace_nonmatching/rates.csv",
        "laplace_convergence": "results/laplace_nonmatching/convergence_{case}.png",
        "laplace_mesh": "results/laplace_nonmatching/mesh.png",
    },
    outputs=("laplace_errors", "laplace_errors_by_side", "laplace_rates",
             "laplace_convergence", "laplace_mesh"),
    heavy_rules=("laplace_errors",),
    thesis_items=(
        ThesisItem("Fig. 6.3", "non-matching grid of the Laplace problem", "laplace_mesh"),
        ThesisItem("Figs. 6.5/6.6", "H1 and L2 errors against h: nodal, stabilised, mortar",
                   "laplace_convergence"),
        ThesisItem("Figs. 6.5/6.6 (rates)", "fitted convergence rates", "laplace_rates"),
    ),
    inline={"laplace_rates": None},
    derived_claims={"laplace_rates": "report.laplace_nonmatching:claims"},
)
