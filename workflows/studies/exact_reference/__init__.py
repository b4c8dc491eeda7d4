"""The exact reference two ways: PDAS through the dual problem (7.3) against PDAS with a
KKT LU per active-set step (thesis Sect. 7.1)."""
from workflows.studies._base import ConfigError, Study, scenes_of


def exact_args(config: dict, scene: str) -> str:
    """A scene's levels of the exact_reference study as script arguments."""
    entry = config["exact_reference"]
    levels = scenes_of(config, "exact_reference")[scene]
    kkt = entry.get("kkt_levels", {}).get(scene, levels)
    return (f"--levels {' '.join(map(str, levels))} --kkt-levels {' '.join(map(str, kkt))} "
            f"--time-limit {entry['time_limit']}")


def check(config: dict, registry: dict) -> None:
    """The KKT-LU levels are among the study's levels of the scene."""
    runs = scenes_of(config, "exact_reference")
    for scene, levels in config.get("exact_reference", {}).get("kkt_levels", {}).items():
        extra = sorted(set(levels) - set(runs.get(scene, [])))
        if extra:
            raise ConfigError(f"config 'exact_reference.kkt_levels.{scene}': levels {extra} are "
                              f"not allowed; allowed: among exact_reference.scenes.{scene} "
                              f"{runs.get(scene, [])}")


STUDY = Study(
    name="exact_reference",
    summary="the exact reference two ways, side by side: PDAS through the dual problem "
            "on the contact rows (A factorised once by a sparse Cholesky, partial "
            "solves) against PDAS with a KKT LU per active-set step; times, memory, "
            "agreement of the multipliers",
    thesis="Sect. 7.1 (the dual problem (7.3)); the suite's reference for Ch. 9",
    order=60,
    scripts={"exact_reference": "workflows.studies.exact_reference.run"},
    paths={
        "exact_runs": "results/{scene}/exact_reference_runs.csv",
        "exact_table": "results/{scene}/exact_reference.csv",
        "exact_claims": "results/{scene}/exact_reference_claims.csv",
        "exact_figure": "results/{scene}/exact_reference.png",
    },
    outputs=("exact_table", "exact_claims", "exact_figure"),
    heavy_rules=("exact_reference",),
    runs_alone=("exact_reference",),
    check=check,
    claims=("exact_claims",),
    inline={"exact_table": ("level", "N", "backend", "status_schur", "total_time_schur",
                            "status_kkt", "total_time_kkt", "speedup", "p_difference")},
)
