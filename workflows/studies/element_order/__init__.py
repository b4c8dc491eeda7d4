"""The element_order study: P1 against P2 elements (thesis Remark 7.11). Its page in the docs is ``page.md``."""
from workflows.studies._base import (ConfigError, Study, ThesisItem,
                                     check_reference_levels, scenes_of)

RULE = "element_order_study"


def element_order_args(config: dict, scene: str) -> str:
    """A scene's settings of the element_order study as arguments of
    ``workflows/studies/element_order/run.py``."""
    eo = config["element_order"]
    levels = " ".join(map(str, scenes_of(config, "element_order")[scene]))
    return (f"--levels {levels} --reference-level {eo['reference_level'][scene]} "
            f"--time-limit {eo['time_limit']}")


def planned_jobs(config: dict, rule: str) -> list[tuple[str, str, int]]:
    """One job per scene, sized by its P2 reference level (the largest solve)."""
    return [(s, s, config["element_order"]["reference_level"][s])
            for s in scenes_of(config, "element_order")]


def check(config: dict, registry: dict) -> None:
    """Scenes whose problem has the 'degree' parameter, each with a reference level above
    its levels and within the problem's range."""
    eo = config.get("element_order")
    if not eo:
        return
    for scene in scenes_of(config, "element_order"):
        spec = registry[config["scenes"][scene]["problem"]]
        if "degree" not in {p.name for p in spec.parameters}:
            raise ConfigError(f"config 'element_order.scenes.{scene}': problem {spec.name!r} "
                              "has no 'degree' parameter; allowed: a problem with P2 elements")
        if "degree" in (config["scenes"][scene].get("params") or {}):
            raise ConfigError(f"config 'element_order.scenes.{scene}': the scene sets "
                              "'degree'; allowed: a scene without it (the study runs P1 and P2)")
    check_reference_levels(config, "element_order", registry)


STUDY = Study(
    name="element_order",
    summary="P1 against P2 elements on a contact scene (Remark 7.11): the energy error "
            "against a common P2 reference per unknown and per second of solve time, "
            "with fitted rates; Hertz at the finest P2 level; Alg. 8.4 on P2 with its "
            "p-multigrid step (Table 9.1's columns: n_o, kappa(S-hat), times)",
    thesis="Remark 7.11, Sect. 8.6 (p0 = 0 for quadratic elements), Table 9.1 for P2",
    order=100,
    scripts={"element_order": "workflows.studies.element_order.run"},
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
    claims=("eo_claims",),
    planned_jobs=planned_jobs,
    proxies={RULE: "contact_level"},     # its jobs keep their size between quick and full
)
