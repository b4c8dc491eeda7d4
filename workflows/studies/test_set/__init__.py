"""The contact QP test set: every family at the configured size classes exported and run by
every registered solver over its tolerance ladder; one leaderboard per problem class (the
``{case}`` of the results pages) and qpbenchmark's summary over the runs."""
from workflows.problem_set import PROBLEM_CLASSES
from workflows.studies._base import (ConfigError, Study, check_registered_solvers, scenes_of,
                                     problem_set_of)

PATHS = {
    "test_set_export": "results/test_set/{set}/export/{size_class}",
    "test_set_runs": "results/test_set/{set}/runs/{size_class}/{scene}.csv",
    "solver_summary": "results/solver_summary/summary.csv",
    "solver_summary_by_class": "results/solver_summary/summary_by_class.csv",
    "solver_summary_by_scene": "results/solver_summary/summary_by_scene.csv",
    "solver_summary_claims": "results/solver_summary/claims.csv",
    "solver_leaderboards": "results/solver_summary/leaderboards.csv",
    "solver_leaderboard_page": "results/solver_summary/leaderboard_{case}.md",
    "solver_warm_starts": "results/solver_summary/warm_starts.csv",
    "solver_facets": "results/solver_summary/facets.csv",
    "solver_profiles": "results/solver_summary/performance_profiles.png",
    "solver_work_precision": "results/solver_summary/work_precision/{scene}.png",
}


def family_scenes(config: dict) -> dict[str, list[int]]:
    """The families the test set runs, as scenes: ``families`` (else every family of the
    set), less ``exclude_families``; their levels are per size class (:func:`workflows.studies._base.run_levels`)."""
    cfg = config["test_set"]
    skip = set(cfg.get("exclude_families") or ())
    return {f: [] for f in cfg.get("families") or problem_set_of(config).families
            if f not in skip}


def warm_starts(config: dict) -> str:
    """``test_set.warm_starts`` (``all``, ``paths`` or ``none``: which frictional steps with
    a recorded warm start run warm too), the schema's default if unset."""
    from workflows.settings import study_defaults

    return config["test_set"].get("warm_starts") or study_defaults("test_set")["warm_starts"]


def problem_set_runs(config: dict) -> list[str]:
    """Every run table of the test_set study: family x size class (with problems)."""
    if "test_set" not in config:
        return []
    ts, cfg = problem_set_of(config), config["test_set"]
    return [PATHS["test_set_runs"].format(set=ts.id, size_class=c, scene=f)
            for c in cfg["classes"] for f in scenes_of(config, "test_set")
            if ts.problems(c, [f])]


def check(config: dict, registry: dict) -> None:
    """A known set, its families, registered solvers; every hard case a family of the set
    at a level of the configured classes."""
    from workflows.problem_set import TestSetError

    if "test_set" not in config:
        return
    cfg = config["test_set"]
    try:
        ts = problem_set_of(config)
        ts.problems(families=cfg.get("families") or None)
    except TestSetError as err:
        raise ConfigError(f"config 'test_set': {err}") from None
    unknown = sorted(set(cfg.get("exclude_families") or ()) - set(ts.families))
    if unknown:
        raise ConfigError(f"config 'test_set.exclude_families': {unknown[0]!r} is not a family "
                          f"of {ts.id}; allowed: {', '.join(ts.families)}")
    check_registered_solvers(config, "test_set")


STUDY = Study(
    name="test_set",
    summary="the contact QP test set (workflows/config/test_sets/): every family at "
            "the configured size classes exported (contactbench export) and solved by "
            "every registered solver at every preset; qpbenchmark's summary (success "
            "and correct rates, shifted geometric means, performance profiles) "
            "overall, by size class and by scene; a work-precision figure per family; cold "
            "against warm starts on the frictional load paths; the faceted friction law's "
            "model error and cost beside its isotropic twin",
    thesis="Ch. 8 (solvers) on every scene of Ch. 9 and its hard variants",
    order=40,
    scripts={"test_set": "workflows.studies.test_set.run"},
    paths=PATHS,
    outputs=("solver_summary", "solver_summary_by_class", "solver_summary_by_scene",
             "solver_summary_claims", "solver_leaderboards", "solver_leaderboard_page",
             "solver_warm_starts", "solver_facets", "solver_profiles",
             "solver_work_precision"),
    heavy_rules=("test_set_export", "test_set_runs"),
    runs_alone=("test_set_runs",),
    check=check,
    cases=lambda config: list(PROBLEM_CLASSES),
    scenes=family_scenes,
    front={"solver_leaderboards": "report.leaderboard:leaderboards_front",
           "solver_summary_by_scene": "report.leaderboard:failures_front"},
    landing={"solver_leaderboards": "report.leaderboard:leaderboards_landing"},
)
