"""P1 against P2 elements (thesis Remark 7.11)

Every contact scene takes `degree=2` (`--set degree=2`, or `params: {degree: 2}` in a scene):
quadratic Lagrange elements on straight-sided simplices (the geometry stays the P1 mesh's, as
in the remark), one constraint at every vertex and edge midpoint of the constrained surface,
the opposing point found on the flat facet through the opposing facet's vertices and weighted
by the facet's P2 shape functions (`problems/fem/quadratic.py`). The stiffness is a
vectorised closed form that equals scikit-fem's `ElementTriP2`/`ElementTetP2` assembly (a
test) and is ~3× faster than it (scikit-fem takes 38 s on cube–sphere P2 level 2). P2's nodal
forces alternate between vertices and midpoints (±20 % with the positive HRZ lumped mass; in
3D a vertex function integrates to zero), so the suite's P2 pressure is the P1-aggregated
one: the forces restricted to the vertices by the p-multigrid prolongation's transpose,
divided by the P1 lumped mass, exact for a constant pressure in 2D and 3D (a test); on the
flat-block patch test it is uniform to 1.5 % where P1's nodal pressure varies by 17 %. The
hierarchy below a P2 problem is a p-multigrid step (P2 → P1 on the same mesh) and the P1
geometric levels, so Alg. 8.4's Â, the multilevel Ŝ and the multigrid solvers take P2 as
they are. The P2 scenes are in the test set (`circle_square_p2`, `cube_sphere_p2`,
`hard_incompressible_p2`, `roll_stack_p2`), so every registered solver runs on them, and in
`contact_solution` (their Hertz tables and pressure plots under `results/circle_square_p2/`
and `results/cube_sphere_p2/`).

The study runs, per scene, P2 at the configured levels and P1 at one level more (both end at
the same N), each solved by Alg. 8.4 at `mid`, against a common P2 reference one level finer
(`workflows/scripts/element_order.py`; the quick scale runs circle–square, the full scale adds
cube–sphere, whose P2 level-2 reference takes 18 min):

| file | content |
| --- | --- |
| `results/<scene>/element_order.csv` | per degree and level: N, N^C, n, Alg. 8.4's n_o, κ(Ŝ), κ(Ŝ⁻¹S_in), Ŝ kind, setup and solve time (Table 9.1's columns for P2), the energy error against the reference, Hertz deviations |
| `results/<scene>/element_order_claims.csv` | every solve converged; fitted P1 and P2 rates; P2's error over P1's at equal N; Hertz at the finest P2 level (bar 5 %); Alg. 8.4 on P2: n_o growth over the last two levels (bar 1.15) and the fitted time exponent over the last three (bar 1.15) |
| `results/<scene>/element_order.png` | energy error against N and against Alg. 8.4's solve time, P1 and P2, fitted rates |

Measured alone on a 2-core machine (`contactbench study element_order
--problem circle_square --levels 0 1 2 --reference-level 3 --time-limit 120 --out F`, 35 s,
2.3 GB; cube–sphere `--levels 0 1 --reference-level 2`, 19.6 min, 3.0 GB):

| circle–square | N | P1 error | P2 error | P1 n_o / t_solve | P2 n_o / t_solve |
| --- | --- | --- | --- | --- | --- |
| P1 level 1 / P2 level 0 | 4,237 | 0.139 | 0.089 | 39 / 0.09 s | 60 / 0.18 s |
| P1 level 2 / P2 level 1 | 16,636 | 0.078 | 0.043 | 47 / 0.37 s | 39 / 0.73 s |
| P1 level 3 / P2 level 2 | 65,926 | 0.044 | 0.029 | 51 / 1.76 s | 39 / 3.38 s |

Fitted rates against N: −0.41 for both (the pressure's square-root edge and the polygonal
circle bound both; against a reference one level finer the finest point flattens); P2
reaches P1's finest error (0.044) at a quarter of the nodes and in 0.73 s against 1.76 s.
Alg. 8.4 on P2: n_o 39 → 39 on the last two levels, fitted solve-time exponent 1.07 (bar 1.15),
κ(Ŝ⁻¹S_in) 2.8–3.5 (P1 2.1–2.7); Hertz at P2 level 2 within 1.0 % (a and p0). Cube–sphere
at 18,360 nodes: P2 0.126 against P1 0.209 (ratio 0.60), Hertz at P2 level 1 −1.1 % (a) and
+2.2 % (p0) where P1 level 2 has −3.4 % and +7.2 %; Alg. 8.4's default picks S_in on P2
level 1 (κ(Ŝ⁻¹S_in) 4.9 at level 0 exceeds its switch), so n_o drops from 107 to 12 and no
3D time exponent is judged from two levels.
"""
from workflows.studies._base import (AtScale, ConfigError, Study, ThesisItem,
                                     check_reference_levels, scenes_of)

RULE = "element_order_study"


def element_order_args(config: dict, scene: str) -> str:
    """A scene's settings of the element_order study as arguments of
    ``workflows/scripts/element_order.py``."""
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
    planned_jobs=planned_jobs,
    proxies={RULE: "contact_level"},     # its jobs keep their size between quick and full
    captions="element_order.rst",
)
