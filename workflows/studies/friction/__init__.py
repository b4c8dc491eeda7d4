"""The friction study: Tresca partial slip against Cattaneo-Mindlin, and the frictional solvers. Its page in the docs is ``page.md``."""
from workflows.studies._base import ConfigError, Study, scenes_of

RULE = "friction_study"
#: The scene parameters the study sets itself.
FRICTION_PARAMETERS = ("friction", "mu", "shift")


def friction_args(config: dict, scene: str) -> str:
    """A scene's settings of the friction study as arguments of
    ``workflows/studies/friction/run.py``."""
    fr = config["friction"]
    levels = " ".join(map(str, scenes_of(config, "friction")[scene]))
    ratios = " ".join(f"{r:g}" for r in fr["ratios"])
    solvers = " ".join(fr["solvers"])
    return (f"--levels {levels} --mu {fr['mu']:g} --ratios {ratios} --shift {fr['shift']:g} "
            f"--coulomb-shift {fr['coulomb_shift']:g} --solvers {solvers} --tol {fr['tol']} "
            f"--time-limit {fr['time_limit']:g} --target {fr['target']:g} "
            f"--repeats {fr['repeats']}"
            + (" --facets " + " ".join(map(str, fr["facets"])) if fr.get("facets") else ""))


def check(config: dict, registry: dict) -> None:
    """Scenes whose problem takes friction and that leave its parameters to the study;
    registered solvers that take friction."""
    fr = config.get("friction")
    if not fr:
        return
    for scene in scenes_of(config, "friction"):
        spec = registry[config["scenes"][scene]["problem"]]
        if not set(FRICTION_PARAMETERS) <= {p.name for p in spec.parameters}:
            raise ConfigError(f"config 'friction.scenes.{scene}': problem {spec.name!r} "
                              "takes no friction; allowed: a problem with the parameters "
                              f"{', '.join(FRICTION_PARAMETERS)}")
        fixed = sorted(set(config["scenes"][scene].get("params") or {})
                       & set(FRICTION_PARAMETERS))
        if fixed:
            raise ConfigError(f"config 'friction.scenes.{scene}': the scene sets "
                              f"{', '.join(fixed)}; allowed: a scene without them (the "
                              "study sets friction, mu and shift)")
    from solvers.interface import solvers

    registered = solvers()
    frictional = sorted(n for n, s in registered.items() if s.handles_friction)
    wrong = sorted(set(fr.get("solvers", [])) - set(frictional))
    if wrong:
        raise ConfigError(f"config 'friction.solvers': {wrong} are not allowed; allowed: "
                          f"{', '.join(frictional)} (registered solvers that take friction)")


STUDY = Study(
    name="friction",
    summary="Tresca partial slip on a contact scene against Cattaneo-Mindlin (stick zone "
            "c/a and the tangential traction, their convergence under refinement); TNNMG, "
            "semismooth Newton and the exact reference on the same load paths (iterations, "
            "time, agreement); mu = 0 against the frictionless reference; Coulomb's fixed "
            "point",
    thesis="beyond the thesis (frictionless): its Alg. 7.1 rows carry the tangential "
           "relative displacement",
    order=110,
    scripts={"friction": "workflows.studies.friction.run"},
    paths={
        "fr_runs": "results/{scene}/friction.csv",
        "fr_profiles": "results/{scene}/friction_profiles.csv",
        "fr_claims": "results/{scene}/friction_claims.csv",
        "fr_traction": "results/{scene}/friction_traction.png",
        "fr_stick": "results/{scene}/friction_stick.png",
        "fr_map": "results/{scene}/friction_map.png",
        "fr_cost": "results/{scene}/friction_cost.png",
    },
    outputs=("fr_runs", "fr_profiles", "fr_claims", "fr_traction", "fr_stick", "fr_map",
             "fr_cost"),
    heavy_rules=(RULE,),
    runs_alone=(RULE,),
    check=check,
    claims=("fr_claims",),
)
