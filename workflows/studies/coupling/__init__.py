"""The coupling study: nodal, stabilised and mortar couplings (thesis Ch. 6, Sect. 7.5, Prop. 7.6). Its page in the docs is ``page.md``."""
from problems.spec import ParameterError
from workflows.studies._base import (ConfigError, Study, ThesisItem, check_reference_levels,
                                     scenes_of)

RULE = "coupling_study"


def coupling_args(config: dict, scene: str) -> str:
    """A scene's settings of the coupling study as arguments of
    ``workflows/studies/coupling/run.py``."""
    cs = config["coupling"]
    levels = " ".join(map(str, scenes_of(config, "coupling")[scene]))
    args = (f"--levels {levels} --reference-level {cs['reference_level'][scene]} "
            f"--couplings {' '.join(cs['couplings'])}")
    if cs.get("orders"):
        args += f" --orders {' '.join(map(str, cs['orders']))}"
    if 2 in (cs.get("orders") or ()):
        p2 = cs["p2_reference"][scene]
        args += (f" --p2-reference-level {p2['level']} "
                 f"--p2-reference-coupling {p2['coupling']}")
    return args


def planned_jobs(config: dict, rule: str) -> list[tuple[str, str, int]]:
    """One job per scene, sized by its reference level (the largest solve)."""
    return [(s, s, config["coupling"]["reference_level"][s])
            for s in scenes_of(config, "coupling")]


def check(config: dict, registry: dict) -> None:
    """Scenes whose problem offers every listed coupling and ``mortar_dual`` (the
    reference's), without a ``coupling`` of their own, each with a reference level above
    its levels and within the problem's range."""
    cs = config.get("coupling")
    if not cs:
        return
    for scene in scenes_of(config, "coupling"):
        spec = registry[config["scenes"][scene]["problem"]]
        offered = next((p.choices for p in spec.parameters if p.name == "coupling"), None) or ()
        missing = [c for c in (*cs["couplings"], "mortar_dual") if c not in offered]
        if missing:
            raise ConfigError(f"config 'coupling.scenes.{scene}': problem {spec.name!r} does "
                              f"not offer the couplings {missing}; allowed: a problem offering "
                              f"{', '.join(cs['couplings'])} and mortar_dual")
        if "coupling" in (config["scenes"][scene].get("params") or {}):
            raise ConfigError(f"config 'coupling.scenes.{scene}': the scene sets 'coupling'; "
                              "allowed: a scene without it (the study sets it)")
    check_reference_levels(config, "coupling", registry)
    if 2 not in (cs.get("orders") or ()):
        return
    p2 = cs.get("p2_reference") or {}
    for scene, levels in scenes_of(config, "coupling").items():
        spec = registry[config["scenes"][scene]["problem"]]
        key = f"config 'coupling.p2_reference.{scene}"
        if "degree" not in {p.name for p in spec.parameters}:
            raise ConfigError(f"config 'coupling.orders': 2 is not allowed with scene "
                              f"{scene!r} (problem {spec.name!r} has no 'degree'); allowed: "
                              "[1], or scenes whose problem takes degree=2")
        if scene not in p2:
            raise ConfigError(f"{key}': missing; allowed: {{level, coupling}} of the P2 rows' "
                              "reference (required with orders containing 2)")
        lo, hi = spec.levels
        if not min(levels) < p2[scene]["level"] <= hi:
            raise ConfigError(f"{key}.level': {p2[scene]['level']} is not allowed; allowed: a "
                              f"level in {min(levels) + 1}..{hi} (above a level of the scene)")
        try:
            spec.make(min(levels), **{"degree": 2, "coupling": p2[scene]["coupling"]})
        except ParameterError as err:
            raise ConfigError(f"{key}.coupling': {err}") from err


STUDY = Study(
    name="coupling",
    summary="nodal, stabilised and mortar (standard and dual) couplings on the contact "
            "scenes: the energy error against a common fine reference with fitted rates "
            "beside the optimal O(h), the pressure error in L2 and in the H^{-1/2}-type dual "
            "norm, Hertz's a and p0 and the pressure's deviation per coupling and level",
    thesis="Ch. 6 (nodal against stabilised against mortar), Sect. 7.5, Prop. 7.6",
    order=85,
    scripts={"coupling": "workflows.studies.coupling.run"},
    paths={
        "cp_study": "results/{scene}/coupling.csv",
        "cp_claims": "results/{scene}/coupling_claims.csv",
        "cp_figure": "results/{scene}/coupling.png",
        "cp_hertz": "results/{scene}/coupling_hertz.png",
    },
    outputs=("cp_study", "cp_claims", "cp_figure", "cp_hertz"),
    heavy_rules=(RULE,),
    thesis_items=(
        ThesisItem("Ch. 6 / Prop. 7.6 (2D)", "couplings on circle-square: energy-error rates "
                   "of nodal, stabilised and mortar", "cp_figure", "circle_square"),
        ThesisItem("Ch. 6 / Prop. 7.6 (3D)", "couplings on cube-sphere: energy-error rates "
                   "of nodal, stabilised and mortar", "cp_figure", "cube_sphere"),
    ),
    check=check,
    claims=("cp_claims",),
    planned_jobs=planned_jobs,
    proxies={RULE: "contact_level"},     # its jobs keep their size between quick and full
)
