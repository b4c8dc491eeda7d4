"""The thesis's solver (Alg. 8.4): its tables regenerated beside the thesis's values, the
O(N) claim against the multigrid-PCG linear solve as the floor (thesis Ch. 8)."""
from workflows.studies._base import ConfigError, Study, ThesisItem


def check(config: dict, registry: dict) -> None:
    """The configurations the study runs are variants of the solver."""
    from solvers.augmented_projection import VARIANTS

    for variant in config.get("augmented_projection", {}).get("configs", []):
        if variant not in VARIANTS:
            raise ConfigError(f"config 'augmented_projection.configs': {variant!r} is not "
                              f"allowed; allowed: {', '.join(VARIANTS)}")


STUDY = Study(
    name="augmented_projection",
    summary="the thesis's solver (Alg. 8.4) with multigrid A-hat and a sparse multilevel "
            "S-hat: the thesis's table regenerated beside its values, the O(N) claim "
            "tested against the multigrid-PCG linear solve as the floor",
    thesis="Ch. 8, Tables 9.1/9.3, Figs. 9.1/9.6, 9.3/9.8",
    order=50,
    scripts={"augmented_projection": "workflows.studies.augmented_projection.run"},
    paths={
        "ap_study": "results/{scene}/augmented_projection_study.csv",
        "ap_table": "results/{scene}/augmented_projection_table.csv",
        "ap_claims": "results/{scene}/augmented_projection_claims.csv",
        "ap_time": "results/{scene}/augmented_projection_time.png",
        "ap_kappa": "results/{scene}/augmented_projection_kappa.png",
        "ap_tnnmg": "results/{scene}/augmented_projection_tnnmg.png",
    },
    outputs=("ap_table", "ap_claims", "ap_time", "ap_kappa", "ap_tnnmg"),
    heavy_rules=("augmented_projection_study",),
    runs_alone=("augmented_projection_study",),
    thesis_items=(
        ThesisItem("Table 9.1", "circle-square, uniform: N^C, n_o, n_i, T_solve, T_proj, kappa",
                   "ap_table", "circle_square"),
        ThesisItem("Fig. 9.1", "circle-square: T_solve against N", "ap_time", "circle_square"),
        ThesisItem("Fig. 9.3", "circle-square: kappa(S-hat) against N", "ap_kappa",
                   "circle_square"),
        ThesisItem("Table 9.3", "cube-sphere, uniform", "ap_table", "cube_sphere"),
        ThesisItem("Fig. 9.6", "cube-sphere: T_solve against N", "ap_time", "cube_sphere"),
        ThesisItem("Fig. 9.8", "cube-sphere: kappa(S-hat) against N", "ap_kappa",
                   "cube_sphere"),
    ),
    check=check,
    claims=("ap_claims",),
    inline={"ap_table": ("level", "N", "NC", "kappa_S", "energy_error", "kkt_max",
                         "stop_8_25", "status")},
    notes={"ap_table": "Alg. 8.4 stops by the thesis's criterion (8.25), an estimate of the "
                       "error, at eps = 1e-3 (stop_8_25: it got there); the columns are read "
                       "at that step. status checks that step against the KKT conditions: "
                       "converged where the largest scaled KKT residual (kkt_max) is within "
                       "eps, inaccurate where (8.25) stopped the iteration before its "
                       "residuals reached eps (kkt_max says by how much, energy_error is the "
                       "energy-norm error there). thesis columns: the thesis's values at the "
                       "same level, beside ours."},
)
