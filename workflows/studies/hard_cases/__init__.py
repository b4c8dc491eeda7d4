"""Every solver on hard variants of the scenes (the test set's runs of its hard families),
on the random frictional family's harder sample, and Alg. 8.4's outer steps towards
incompressibility."""
from workflows.studies._base import (ConfigError, Study, levels_choice, problem_set_of,
                                     run_levels, scenes_of)


def hard_case_runs(config: dict) -> tuple[list[str], list[str]]:
    """The test set's run tables holding the hard cases (the test_set study's output
    ``test_set_runs``) and the cases as ``family:level``."""
    from workflows.studies import PATHS

    if "test_set" not in config:
        return [], []
    ts = problem_set_of(config)
    cases, files = [], []
    for family, levels in scenes_of(config, "hard_cases").items():
        for level in levels:
            cases.append(f"{family}:{level}")
            for c in config["test_set"]["classes"]:
                if ts.problems(c, [family]) and level in run_levels(config, c, family, ts):
                    files.append(PATHS["test_set_runs"].format(set=ts.id, size_class=c,
                                                               scene=family))
    return sorted(set(files)), cases


def check(config: dict, registry: dict) -> None:
    """The hard cases: families the test set runs, at levels it runs, at a preset it runs;
    the incompressibility table: registered contact problems, a level and Poisson's ratios
    each scene accepts."""
    from problems.spec import ParameterError

    check_cases(config)
    rf = config.get("hard_cases", {}).get("random_friction") or {}
    if rf.get("solvers"):
        from solvers.interface import solvers
        unknown = [n for n in rf["solvers"] if n not in solvers()]
        if unknown:
            raise ConfigError(f"config 'hard_cases.random_friction.solvers': {unknown} are not "
                              f"allowed; allowed: registered solvers "
                              f"({', '.join(sorted(solvers()))})")
    inc = config.get("hard_cases", {}).get("incompressibility")
    if not inc:
        return
    contact = sorted(n for n, s in registry.items() if s.kind == "contact")
    for name in inc["scenes"]:
        if name not in contact:
            raise ConfigError(f"config 'hard_cases.incompressibility.scenes': {name!r} is not "
                              f"allowed; allowed: {', '.join(contact)}")
        spec = registry[name]
        try:
            spec.check_level(inc["level"])
            for nu in inc["nus"]:
                spec.options(nu1=nu, nu2=nu)
        except ParameterError as err:
            raise ConfigError(f"config 'hard_cases.incompressibility' for {name!r}: {err}") \
                from None


def check_cases(config: dict) -> None:
    """Every hard case a family of the test set's runs at a level and preset they run."""
    hc = config.get("hard_cases", {})
    if "test_set" not in config:
        if scenes_of(config, "hard_cases"):
            raise ConfigError("config 'hard_cases': the hard cases are the test set's runs; "
                              "allowed: with a 'test_set' entry")
        return
    cfg, ts = config["test_set"], problem_set_of(config)
    run = set(scenes_of(config, "test_set"))
    for family, levels in scenes_of(config, "hard_cases").items():
        have = {level for c in cfg["classes"] for level in run_levels(config, c, family, ts)} \
            if family in ts.families else set()
        if family not in run or not set(levels) <= have:
            raise ConfigError(f"config 'hard_cases.scenes.{family}': levels {levels} are not "
                              f"among the test set's runs; allowed: a family of "
                              f"test_set.families at a level it runs (test_set.classes "
                              f"{cfg['classes']}, test_set.levels "
                              f"{levels_choice(config)!r})")
    if hc and hc["preset"] not in cfg["presets"]:
        raise ConfigError(f"config 'hard_cases.preset': {hc.get('preset')!r} is not run; "
                          f"allowed: one of test_set.presets {cfg['presets']}")


STUDY = Study(
    name="hard_cases",
    summary="every registered solver at one preset (the test set's runs), each in its "
            "own process with a hard time limit, on hard variants of the scenes (stiffness "
            "contrast, near incompressibility, mesh ratio, single-node and whole-edge "
            "contact, no contact, initial penetration, SI units, grazing contact, a thin "
            "body; friction), and on random frictional draws at a finer level: verified "
            "status, certified bound, errors against the reference, time; "
            "Alg. 8.4's outer steps against Poisson's ratio up to 0.4999",
    thesis="Ch. 8 solvers on variants of Sects. 9.1, 9.2",
    order=70,
    scripts={"hard_cases": "workflows.studies.hard_cases.run",
             "random_friction": "workflows.studies.hard_cases.random_friction"},
    paths={
        "hard_table": "results/hard_cases/hard_cases.csv",
        "hard_heatmap": "results/hard_cases/hard_cases.png",
        "hard_nu_runs": "results/hard_cases/incompressibility.csv",
        "hard_nu_claims": "results/hard_cases/incompressibility_claims.csv",
        "hard_nu_figure": "results/hard_cases/incompressibility.png",
        "hard_rf_runs": "results/hard_cases/random_friction.csv",
        "hard_rf_claims": "results/hard_cases/random_friction_claims.csv",
    },
    outputs=("hard_table", "hard_heatmap", "hard_nu_runs", "hard_nu_claims", "hard_nu_figure",
             "hard_rf_runs", "hard_rf_claims"),
    heavy_rules=("hard_cases_incompressibility", "hard_cases_random_friction"),
    check=check,
    claims=("hard_nu_claims", "hard_rf_claims"),
    derived_claims={"hard_table": "report.hard_cases:claims"},
)
