"""Every registered solver on identical problems of each configured scene and level."""
from workflows.studies._base import Study, check_registered_solvers


def check(config: dict, registry: dict) -> None:
    """The solvers the study names are registered."""
    check_registered_solvers(config, "solver_comparison")


STUDY = Study(
    name="solver_comparison",
    summary="every registered solver at three tolerance presets on identical QPs: "
            "verified status, KKT residuals, certified bound, time, memory, energy "
            "error; cost exponents and the ratio to the linear floor per scene",
    thesis="Ch. 8 (solvers) on the scenes of Ch. 9",
    order=30,
    scripts={"solver_comparison": "workflows.studies.solver_comparison.run"},
    paths={
        "solver_runs": "results/{scene}/solvers_L{level}.csv",
        "solver_table": "results/{scene}/solvers.csv",
        "solver_presets": "results/{scene}/solver_presets.csv",
        "solver_times": "results/{scene}/solver_times.png",
        "solver_work": "results/{scene}/solver_error_vs_time.png",
        "solver_costs": "results/{scene}/solver_costs.csv",
    },
    outputs=("solver_table", "solver_presets", "solver_times", "solver_work", "solver_costs"),
    heavy_rules=("solver_comparison",),
    runs_alone=("solver_comparison",),
    check=check,
)
