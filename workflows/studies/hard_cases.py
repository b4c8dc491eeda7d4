"""Every solver on hard variants of the scenes (the test set's runs of its hard families),
and Alg. 8.4's outer steps towards incompressibility."""
from workflows.studies._base import ConfigError, Study


def check(config: dict, registry: dict) -> None:
    """The incompressibility table: registered contact problems, a level and Poisson's
    ratios each scene accepts (the hard cases themselves: :mod:`workflows.studies.problem_set`)."""
    from problems.spec import ParameterError

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


STUDY = Study(
    name="hard_cases",
    summary="every registered solver at one preset (the test set's runs), each in its "
            "own process with a hard time limit, on hard variants of the scenes (stiffness "
            "contrast, near incompressibility, mesh ratio, single-node and whole-edge "
            "contact, no contact, initial penetration, SI units, grazing contact, a thin "
            "body): verified status, certified bound, errors against the reference, time; "
            "Alg. 8.4's outer steps against Poisson's ratio up to 0.4999",
    thesis="Ch. 8 solvers on variants of Sects. 9.1, 9.2",
    order=70,
    rule_file="hard_cases.smk",
    scripts={"hard_cases": "workflows.scripts.incompressibility"},
    paths={
        "hard_table": "results/hard_cases/hard_cases.csv",
        "hard_heatmap": "results/hard_cases/hard_cases.png",
        "hard_nu_runs": "results/hard_cases/incompressibility.csv",
        "hard_nu_claims": "results/hard_cases/incompressibility_claims.csv",
        "hard_nu_figure": "results/hard_cases/incompressibility.png",
    },
    outputs=("hard_table", "hard_heatmap", "hard_nu_runs", "hard_nu_claims", "hard_nu_figure"),
    heavy_rules=("hard_cases_incompressibility",),
    check=check,
    claims=("hard_nu_claims",),
)
