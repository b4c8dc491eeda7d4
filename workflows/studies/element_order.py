"""P1 against P2 elements on a contact scene (thesis Remark 7.11), Alg. 8.4 on P2."""
from workflows.studies._base import AtScale, ConfigError, Study, ThesisItem, scenes_of

RULE = "element_order_study"


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
    heavy_rules=(RULE,),
    runs_alone=(RULE,),
    thesis_items=(
        ThesisItem("Remark 7.11 (2D)", "second-order elements, circle-square: P1 against P2, "
                   "Alg. 8.4 on P2", "eo_figure", "circle_square"),
        ThesisItem("Remark 7.11 (3D)", "second-order elements, cube-sphere: P1 against P2, "
                   "Alg. 8.4 on P2", "eo_figure", "cube_sphere"),
    ),
    check=check,
    settings={
        "type": "object",
        "description": "P1 against P2 (Remark 7.11, workflows/scripts/element_order.py): "
                       "per scene, P2 at the listed levels and P1 at one level more, against "
                       "a P2 reference at reference_level; Alg. 8.4 on each",
        "additionalProperties": False,
        "required": ["scenes", "reference_level", "time_limit"],
        "properties": {
            "scenes": {"$ref": "#/definitions/scene_levels", "description":
                       "{scene: [P2 levels]} (a scene whose problem has the 'degree' "
                       "parameter)"},
            "reference_level": {"type": "object", "description": "{scene: level} of the P2 "
                                "reference, above every level of the scene",
                                "additionalProperties": {"type": "integer", "minimum": 0}},
            "time_limit": {"$ref": "#/definitions/time_limit"},
        },
    },
    # P2 levels per scene; P1 runs one level more. Resources: the largest job, measured
    # (quick) or predicted from the quick and full runs (full, huge: `make plan`).
    scales={
        # 3D from the full scale on: its P2 level-2 reference takes 18 min
        "quick": AtScale({"scenes": {"circle_square": [0, 1, 2]},
                          "reference_level": {"circle_square": 3}, "time_limit": 120},
                         {RULE: {"mem_mb": 3500, "runtime": 2}}),    # measured 35 s, 2.3 GB
        "full": AtScale({"scenes": {"circle_square": [0, 1, 2], "cube_sphere": [0, 1]},
                         "reference_level": {"circle_square": 3, "cube_sphere": 2},
                         "time_limit": 600},
                        # e_t 0.89, e_mem 1.15 (contact_level (proxy)); cube_sphere x1
                        {RULE: {"mem_mb": 4000, "runtime": 47}}),
        "huge": AtScale({"scenes": {"circle_square": [0, 1, 2, 3], "cube_sphere": [0, 1, 2]},
                         "reference_level": {"circle_square": 4, "cube_sphere": 3},
                         "time_limit": 600},
                        # e_t 0.89, e_mem 1.15 (contact_level (proxy)); cube_sphere x8
                        {RULE: {"mem_mb": 37400, "runtime": 298}}),
    },
    claims=("eo_claims",),
    captions="element_order.rst",
)
