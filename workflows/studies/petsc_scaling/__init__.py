"""Strong scaling of the distributed solver: PETSc/Tao under MPI at each configured number
of ranks on the same problems, and TNNMG in one process beside it."""
import math

from workflows.studies._base import ConfigError, Study, scenes_of

RULE = "petsc_scaling_study"


def petsc_scaling_args(config: dict, scene: str) -> str:
    """A scene's settings of the petsc_scaling study as arguments of
    ``workflows/studies/petsc_scaling/run.py``."""
    ps = config["petsc_scaling"]
    levels = " ".join(map(str, scenes_of(config, "petsc_scaling")[scene]))
    ranks = " ".join(map(str, ps["ranks"]))
    return (f"--levels {levels} --ranks {ranks} --preset {ps['preset']} "
            f"--time-limit {ps['time_limit']}")


def mpi_resources(config: dict) -> dict:
    """The MPI part of the study's ``resources:`` (beside the declared ``mem_mb``,
    ``runtime`` and the whole machine, :func:`workflows.studies.rule_resources`): the
    ranks as Slurm tasks of one CPU each, ``tasks`` = the most ranks configured, and the
    configured launcher as ``mpi`` (the Slurm executor then submits an MPI job; the rule
    hands the launcher to the solver as ``CONTACTBENCH_MPIEXEC``)."""
    ranks = max(config["petsc_scaling"]["ranks"])
    resources = {"tasks": ranks, "cpus_per_task": 1}
    if ranks > 1:      # the executor refuses an MPI job of one task
        resources["mpi"] = config["petsc_scaling"]["launcher"]
    return resources


def runtime_bound(config: dict) -> int:
    """The study job's wall time, bounded by its time limits (minutes, rounded up): per
    scene ``levels x (ranks + 1)`` runs (PETSc at each rank count, TNNMG once), each
    killed at its hard limit (:func:`workflows.isolation.hard_limit`); the largest scene.
    The problem's assembly is not in it (seconds at the sizes the configs run)."""
    from workflows.isolation import hard_limit

    ps = config["petsc_scaling"]
    runs = max(len(levels) for levels in scenes_of(config, "petsc_scaling").values()) * (
        len(ps["ranks"]) + 1)
    return math.ceil(runs * hard_limit(ps["time_limit"]) / 60)


def check(config: dict, registry: dict) -> None:
    """The ranks include 1 (the speed-up's base) and are distinct."""
    ps = config.get("petsc_scaling")
    if not ps:
        return
    ranks = ps["ranks"]
    if 1 not in ranks or len(set(ranks)) != len(ranks):
        raise ConfigError(f"config 'petsc_scaling.ranks': {ranks} is not allowed; allowed: "
                          "distinct integers >= 1 including 1 (the speed-up's base)")


STUDY = Study(
    name="petsc_scaling",
    summary="strong scaling of the distributed solver: petsc_tao (PETSc/Tao under MPI) "
            "at each configured number of ranks and TNNMG in one process on the same "
            "problems: time and iterations against ranks, parallel efficiency, where "
            "PETSc starts to pay, and the ranks' answers against each other",
    thesis="Example 8.1 (O(N)) beyond one process (the suite's addition)",
    order=35,
    # also by hand, on a quiet machine or inside a cluster allocation with the ranks
    # (docs/guide/distributed.md)
    scripts={"petsc_scaling": "workflows.studies.petsc_scaling.run"},
    paths={
        "ps_runs": "results/{scene}/petsc_scaling.csv",
        "ps_facts": "results/{scene}/petsc_scaling_facts.csv",
        "ps_claims": "results/{scene}/petsc_scaling_claims.csv",
        "ps_figure": "results/{scene}/petsc_scaling.png",
    },
    outputs=("ps_runs", "ps_claims", "ps_figure"),
    heavy_rules=(RULE,),
    runs_alone=(RULE,),
    check=check,
    claims=("ps_claims",),
)
