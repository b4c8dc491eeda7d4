"""P1 against P2 elements on a contact scene (thesis Remark 7.11), Alg. 8.4 on P2."""
from workflows.studies._base import ConfigError, Study, ThesisItem, scenes_of


def element_order_args(config: dict, scene: str) -> str:
    """A scene's settings of the element_order study as arguments of
    ``workflows/scripts/element_order.py``."""
    eo = config["element_order"]
    levels = " ".join(map(str, scenes_of(config, "element_order")[scene]))
    return (f"--levels {levels} --reference-level {eo['reference_level'][scene]} "
            f"--time-limit {eo['time_limit']}")


def check(config: dict, registry: dict) -> None:
    """Scenes whose problem has the 'degree' parameter, each with a reference level above
    its levels and within the problem's range."""
    eo = config.get("element_order")
    if not eo:
        return
    runs = scenes_of(config, "element_order")
    for scene in eo["reference_level"]:
        if scene not in runs:
            raise ConfigError(f"config 'element_order.reference_level.{scene}': not among "
                              f"element_order.scenes ({', '.join(runs)})")
    for scene, levels in runs.items():
        spec = registry[config["scenes"][scene]["problem"]]
        if "degree" not in {p.name for p in spec.parameters}:
            raise ConfigError(f"config 'element_order.scenes.{scene}': problem {spec.name!r} "
                              "has no 'degree' parameter; allowed: a problem with P2 elements")
        if "degree" in (config["scenes"][scene].get("params") or {}):
            raise ConfigError(f"config 'element_order.scenes.{scene}': the scene sets "
                              "'degree'; allowed: a scene without it (the study runs P1 and P2)")
        ref = eo["reference_level"].get(scene)
        lo, hi = spec.levels
        if ref is None or not max(levels) < ref <= hi:
            raise ConfigError(f"config 'element_order.reference_level.{scene}': {ref} is not "
                              f"allowed; allowed: a level in {max(levels) + 1}..{hi}")


STUDY = Study(
    name="element_order",
    summary="P1 against P2 elements on a contact scene (Remark 7.11): the energy error "
            "against a common P2 reference per unknown and per second of solve time, "
            "with fitted rates; Hertz at the finest P2 level; Alg. 8.4 on P2 with its "
            "p-multigrid step (Table 9.1's columns: n_o, kappa(S-hat), times)",
    thesis="Remark 7.11, Sect. 8.6 (p0 = 0 for quadratic elements), Table 9.1 for P2",
    order=100,
    rule_file="element_order.smk",
    scripts={"element_order": "workflows.scripts.element_order"},
    paths={
        "eo_study": "results/{scene}/element_order.csv",
        "eo_claims": "results/{scene}/element_order_claims.csv",
        "eo_figure": "results/{scene}/element_order.png",
    },
    outputs=("eo_study", "eo_claims", "eo_figure"),
    heavy_rules=("element_order_study",),
    runs_alone=("element_order_study",),
    thesis_items=(
        ThesisItem("Remark 7.11 (2D)", "second-order elements, circle-square: P1 against P2, "
                   "Alg. 8.4 on P2", "eo_figure", "circle_square"),
        ThesisItem("Remark 7.11 (3D)", "second-order elements, cube-sphere: P1 against P2, "
                   "Alg. 8.4 on P2", "eo_figure", "cube_sphere"),
    ),
    check=check,
)
