"""Nodal, stabilised and mortar couplings (thesis Ch. 6, Sect. 7.5, Prop. 7.6)

The thesis discretises body-body contact by nodal constraints (Alg. 7.1) and proves for
them the rate O(h^{1/2}) under H^2 regularity (Prop. 7.6, (7.8)); on a Laplace problem
with non-matching grids (Ch. 6) nodal constraints lose the optimal primal rate, which a
mesh-dependent stabilisation restores (Sect. 6.3, Remark 6.25, Fig. 6.5), and the
mortar method is the yardstick that has it. This study puts the couplings the contact
scenes offer (`coupling` = `nodal`, `stabilised` (Sect. 7.5), `mortar`, `mortar_dual`;
`docs/guide/mortar.md`) side by side on the contact scenes.

Per scene and coupling at the configured levels, and for a common reference (the same
scene at `reference_level` with the `mortar_dual` coupling), every problem is solved
exactly: PDAS through `solvers.interface.solve` at the `high` tolerance, verified
(`workflows/scripts/coupling.py`). Against the reference: the energy error
||P u_h - u_ref||_A / ||u_ref||_A (P the P1 interpolation onto the reference's nested
mesh, the adaptive study's comparison), the contact force, and the nodal pressure
against the reference's; against Hertz: the half-width a and the peak pressure p0
(moments of the nodal forces, as the contact_solution study) and the nodal pressure's
rms deviation over the contact zone, a discrete L2 norm of the multiplier error.

The multiplier error is also measured in the H^{-1/2}-type norm of the mortar theory
(Wohlmuth 2000; Hüeber, Wohlmuth 2005), as the dual (energy) norm of the reference's
discretisation: `err_pressure_dual` = ||A^{-1/2}(F_h - F_ref)|| / ||A^{-1/2} F_ref||,
with A the reference's stiffness and F = B_C'(m lambda) the nodal forces a pressure
lambda exerts on both bodies through the reference's constrained rows B_C (m the lumped
surface mass, the compared pressure interpolated P1 onto the reference's constrained
nodes; the reference's own forces are B' p_ref). By the trace theorem this dual norm of
a load on Gamma_C is equivalent to the H^{-1/2}(Gamma_C) norm of its density; what is
approximated (the polygonal surfaces, the interpolation, the sup over the reference's
P1 space) is listed in `workflows/scripts/coupling.py`. One solve with the reference's
A per compared solve (its factorisation; multigrid PCG for the 3D level-3 reference). Its fitted rate per coupling is reported, not
judged: the published estimate bounds the energy and the multiplier error together by
O(h) at H^2 regularity, an upper bound for the multiplier; the Hertz pressure's
square-root edge (in H^{1-eps}) lets the multiplier's best approximation in H^{-1/2}
fall as O(h^{3/2-eps}), and no rate of the multiplier error alone is published.

The optimal rate: the contact solution is in H^{5/2-eps} at best, so P1's energy error is
O(h) at best (Hüeber, Wohlmuth, SIAM J. Numer. Anal. 43 (2005)): O(N^{-1/2}) in 2D,
O(N^{-1/3}) in 3D on uniform meshes. The mortar rates are judged against it (within
0.1, fitted over the finest three levels); the nodal and stabilised rates are reported
beside it (the thesis's (7.8) is a lower bound, and Ch. 6's loss of the rate is shown
for the Laplace problem, not for contact). Both scenes have boundary lines where a
prescribed displacement meets a free surface (the ends of the circle's held arc, the rim
of the ball's held cap, the clamped bottom edges), whose r^{1/2} singularities bound the
rate asymptotically by O(h^{1/2}). On cube–sphere they do not show at the levels run
here: 83-92 % of the squared energy error lies within 2a of the contact centre and 4-7 %
within 2a of those lines (the table's `err_share_*` columns), the singular share not
growing from level 0 to 2, so the rate judged in 3D is O(h), as in 2D.

| file | content |
| --- | --- |
| `results/<scene>/coupling.csv` | per coupling, element order (`order`) and level: N, n, N^C, status (`skipped` with the `reason` for a coupling the scene refuses at P2), KKT, the energy, force and pressure errors against the reference (the pressure in discrete L2, `err_pressure`, and in the dual norm, `err_pressure_dual`), force, a and p0 against Hertz, the pressure's rms deviation from Hertz; the reference's row |
| `results/<scene>/coupling_claims.csv` | every solve converged; each coupling's fitted energy-error rate (mortar: within 0.1 of the optimal) and dual-norm pressure-error rate (reported); a/a_H, p0/p0_H and the pressure deviation at the finest level; with P2 rows: each P2 coupling's fitted rate beside the optimal O(h^{3/2}) (reported), its Hertz rows, each skipped coupling with its reason |
| `results/<scene>/coupling.png` | energy error against N per coupling (log-log), fitted rates in the legend, the optimal slope dotted; P2 rows dashed with open markers, their optimal slope dash-dotted |
| `results/<scene>/coupling_hertz.png` | a/a_H and p0/p0_H against N per coupling, Hertz dotted at 1 |

Read the energy-error figure as the difference to a finer discrete solution, not the true
error: for nested spaces the two differ by the reference's own error, which steepens the
finest point a little. The quick scale runs circle–square levels 0-2 against level 3
(48 s, 0.7 GB); the full scale levels 0-3 against level 4 (6.9 min, 2.0 GB: the reference
solve and the interpolations onto its 262k nodes dominate). Cube–sphere runs levels 0-2
against level 3 (135,102 nodes) at every scale from quick: 2.1 min and 2.5 GB, of which
the reference's solve (TNNMG, `solvers.reference.reference_solve` beyond a factorisation)
takes 11 s; a level-4 reference (1.08M nodes) has not been measured. Measured on a
2-core machine shared with other work (`/usr/bin/time -v`, each job alone). The interpolation onto
the reference locates each fine node in the coarse mesh of its body; on the ball a
quarter of the fine surface nodes lie outside the coarse ball (projected onto the
sphere) and get the linear extension of their nearest cell.

Measured on circle–square, levels 0-3 (N = 1,099 to 65,926) against level 4:

| coupling | energy error, levels 0-3 | rate (levels 1-3) | a/a_H, level 3 | p0/p0_H, level 3 | pressure rms / p0, level 3 |
| --- | --- | --- | --- | --- | --- |
| nodal | 0.232 0.136 0.074 0.039 | -0.45 | 0.989 | 1.011 | 0.051 |
| stabilised | 0.232 0.132 0.073 0.038 | -0.45 | 0.990 | 1.010 | 0.035 |
| mortar | 0.234 0.136 0.073 0.038 | -0.46 | 0.985 | 1.015 | 0.052 |
| mortar_dual | 0.231 0.133 0.072 0.038 | -0.46 | 0.990 | 1.010 | 0.017 |

The multiplier error at quick (levels 0-2 against level 3; `contactbench study coupling
--problem circle_square --levels 0 1 2 --reference-level 3 --couplings nodal stabilised
mortar mortar_dual --out F`), in the dual norm and, beside it, in discrete L2:

| coupling | `err_pressure_dual`, levels 0-2 | its rate | `err_pressure`, levels 0-2 |
| --- | --- | --- | --- |
| nodal | 0.045 0.029 0.012 | -0.48 | 0.141 0.106 0.067 |
| stabilised | 0.067 0.024 0.011 | -0.67 | 0.172 0.092 0.058 |
| mortar | 0.092 0.044 0.024 | -0.50 | 0.270 0.169 0.125 |
| mortar_dual | 0.048 0.024 0.008 | -0.67 | 0.139 0.095 0.045 |

Dual multipliers give the smallest multiplier error in both norms at level 2, and their
rate, -0.67 in N (h^{4/3}), lies between the published O(h) and the O(h^{3/2}) the
pressure's regularity allows; the standard mortar multipliers' nodal values oscillate
(the pressure overshoot below), which their dual-norm error shows as a rate of h^1 only.

At quick (levels 0-2 against level 3) the rates are -0.47 (nodal, stabilised) and -0.47,
-0.47 (mortar, mortar_dual; within 0.1 of -1/2). On this scene the four couplings' energy
errors agree to 3 %: the square's top edge is straight and the circle's chords resolve it
at every level, so the non-matching interface costs nodal constraints no order here,
unlike Ch. 6's Laplace example. The couplings differ in the pressure: the standard mortar
multipliers' nodal pressure overshoots Hertz's peak by 24 % at level 0 and 4 % at level 2
(rms deviation 0.34 to 0.16) where the dual ones stay within 4 % (rms 0.02 to 0.05).

Measured on cube–sphere, levels 0-2 (N = 450, 2,691, 18,360) against level 3 (quick):

| coupling | energy error, levels 0-2 | rate (levels 0-2) | a/a_H, level 2 | p0/p0_H, level 2 | pressure rms / p0, level 2 |
| --- | --- | --- | --- | --- | --- |
| nodal | 0.589 0.346 0.174 | -0.33 | 0.966 | 1.072 | 0.097 |
| stabilised | 0.543 0.329 0.169 | -0.32 | 0.984 | 1.033 | 0.073 |
| mortar | 0.561 0.337 0.172 | -0.32 | 0.927 | 1.163 | 0.265 |
| mortar_dual | 0.575 0.337 0.169 | -0.33 | 0.973 | 1.055 | 0.065 |

The mortar rates lie within 0.02 of the optimal -1/3 (-0.32, -0.33); per halving of h the
error falls by 2^{0.73-0.77} from level 0 to 1 and 2^{0.96-1.00} from level 1 to 2 (the
last against a reference one level finer, biased upwards). As in 2D the four couplings'
energy errors agree to 3 % at level 2, and they differ in the pressure: the standard
mortar multipliers overshoot Hertz's peak by 59 % at level 1 and 16 % at level 2 (rms
deviation 0.36, 0.26), and at level 0 (h = 1/4 against a = 0.28) put the whole force on
the top face's centre node (moment radius 0, no peak pressure to measure); the dual ones stay within
9 % (rms 0.12 to 0.07).

P2 rows (`orders: [1, 2]`, the full scale; quick runs P1 only): every coupling the scene
takes at `degree=2` (`nodal`, `mortar`, and `mortar_dual` in 2D; `stabilised` is built for
P1 and the dual basis of the P2 trace on a triangle does not exist, so these are
`skipped` rows with the scene's reason) at the scene's levels below `p2_reference.level`,
against a P2 reference of their own (`p2_reference`: circle–square `mortar_dual` at level
3, 262,474 nodes; cube–sphere `nodal` at level 2, 135,102 nodes, the one P2 coupling there
that TNNMG takes beyond a factorisation). A P1 reference would not do: its own error is
O(h_ref), P2's at best O(h^{3/2}). The P2 solution enters the comparison as its P2 field
evaluated at the reference's P2 nodes (vertices and edge midpoints, per body: the reference
space's P2 interpolant, exact on nested meshes), measured in the reference's P2 stiffness;
the pressure is the one recovered from the forces at both sides; the dual-norm pressure
error and the energy shares are P1 only. The optimal rate: with the solution in
H^{5/2-eps} at best, P2's energy error is O(h^{3/2}), N^{-3/4} in 2D and N^{-1/2} in 3D.
The P2 rates are reported beside it, not judged: the r^{1/2} singularities at the supports'
ends bound every order by O(h^{1/2}) asymptotically, and at P2, whose error near the contact
falls faster, their share is not known to be small (not measured at P2).

At P2 the force and Hertz's a and p0 (moments of the nodal forces) take the normal forces
the rows exert on the constrained nodes (`problems.fem.fields.contact_forces`: the
multipliers for nodal and dual rows, the consistent loads for the standard mortar rows),
whose total is the force the rows transmit; the standard mortar multipliers of the P2
trace in 3D are no nodal forces.

Measured on circle–square, P2 levels 0-2 (N = 4,237, 16,636, 65,926) against P2 level 3
(`contactbench study coupling --problem circle_square --levels 0 1 2 --reference-level 3
--orders 2 --p2-reference-level 3 --out F`, 2.6 GB peak; with `--levels 0 1 2 3
--reference-level 4 --orders 1 2` the same P2 rows follow the P1 rows of the table above,
which come out the same to the digits shown, 3.8 GB peak):

| coupling | P2 energy error, levels 0-2 | per halving of h | fitted rate (levels 0-2) | a/a_H, p0/p0_H, level 2 | pressure rms / p0, level 2 |
| --- | --- | --- | --- | --- | --- |
| nodal | 0.088 0.041 0.025 | 1.11, 0.73 | -0.47 | 0.990, 1.010 | 0.025 |
| mortar | 0.084 0.031 0.015 | 1.45, 1.03 | -0.63 | 0.991, 1.009 | 0.024 |
| mortar_dual | 0.076 0.030 0.015 | 1.32, 1.01 | -0.59 | 0.989, 1.011 | 0.026 |

The optimal -0.75 (h^{3/2}) is not reached: from level 0 to 1 the mortar errors fall as
h^{1.3-1.5}, from level 1 to 2 as h^{1.0} (the last against a reference one level finer,
which biases it upwards, not down), the nodal P2 rows as h^{1.1} and h^{0.7}. At 65,926
nodes the mortar P2 rows are 2.5 times closer to their reference than P1 to its own
(0.015 against 0.038, both references at 262k nodes; nodal P2 1.6 times), and P2's pressure deviates from Hertz by 0.024-0.026 of p0
for every coupling, where P1's standard mortar pressure deviates by 0.052 at level 3.

On cube–sphere, P2 levels 0-1 (N = 2,691, 18,360) against nodal P2 at level 2
(`contactbench study coupling --problem cube_sphere --levels 0 1 --reference-level 2
--orders 2 --p2-reference-level 2 --p2-reference-coupling nodal --out F`, 3.2 GB peak):
nodal P2 0.263 and 0.126 (h^{1.06}; two levels, no rate fitted), a/a_H 0.989 and p0/p0_H
1.022 at level 1; the standard mortar P2 rows 1.233 and 0.712. Their vertex rows, whose
weights integrate to zero (`docs/guide/mortar.md`), bound only the gap's variation over a
vertex's patch: the solution penetrates the cube by up to 0.011 (level 0) and 0.007
(level 1) at the nodes, against displacements of 0.08, and at level 0 it differs from the
nodal P2 solution on the same mesh by 1.3 times that solution's energy norm. They transmit
a force 25 % (level 0) and 4 % (level 1) below the reference's (the multipliers' sum is
about 5 times it), their recovered pressure deviates from Hertz by 0.29 and 0.12 of p0 (nodal
P2: 0.25, 0.10), and the second moment of their consistent loads about the centre is
negative, so a and p0 have no moment estimate (NaN).

Run by hand:

    contactbench study coupling --problem circle_square --levels 0 1 2 \\
        --reference-level 3 --out results/circle_square/coupling.csv
    contactbench study coupling --problem cube_sphere --levels 0 1 2 \\
        --reference-level 3 --out results/cube_sphere/coupling.csv
"""
from problems.fem.stabilised import COUPLINGS
from problems.spec import ParameterError
from workflows.studies._base import (ConfigError, Study, ThesisItem, check_reference_levels,
                                     scenes_of)

RULE = "coupling_study"


def coupling_args(config: dict, scene: str) -> str:
    """A scene's settings of the coupling study as arguments of
    ``workflows/scripts/coupling.py``."""
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
    rule_file="coupling.smk",
    scripts={"coupling": "workflows.scripts.coupling"},
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
    settings={
        "type": "object",
        "description": "nodal, stabilised and mortar couplings (workflows/scripts/coupling.py): "
                       "per scene, every coupling at the listed levels against a mortar_dual "
                       "reference at reference_level, each solved exactly",
        "additionalProperties": False,
        "required": ["scenes", "reference_level", "couplings"],
        "properties": {
            "scenes": {"$ref": "#/definitions/scene_levels", "description":
                       "{scene: [levels]} (a scene whose problem has the 'coupling' "
                       "parameter)"},
            "reference_level": {"type": "object", "description": "{scene: level} of the "
                                "mortar_dual reference, above every level of the scene",
                                "additionalProperties": {"type": "integer", "minimum": 0}},
            "couplings": {"type": "array", "minItems": 1, "uniqueItems": True,
                          "items": {"enum": list(COUPLINGS)},
                          "description": "the couplings compared (the reference's, "
                                         "mortar_dual, is offered by every scene too)"},
            "orders": {"type": "array", "minItems": 1, "uniqueItems": True,
                       "items": {"enum": [1, 2]},
                       "description": "element orders (the scenes' degree; omitted: P1, "
                                      "the thesis's elements): 1, and 2 for "
                                      "P2 rows of the couplings a scene takes at degree=2 "
                                      "(the others: skipped rows with the reason), against "
                                      "the P2 reference of p2_reference"},
            "p2_reference": {"type": "object", "description": "{scene: {level, coupling}} "
                             "of the P2 rows' reference (required with orders containing "
                             "2): P2 at that level and coupling; the P2 rows run at the "
                             "scene's levels below it",
                             "additionalProperties": {
                                 "type": "object", "additionalProperties": False,
                                 "required": ["level", "coupling"],
                                 "properties": {
                                     "level": {"type": "integer", "minimum": 0},
                                     "coupling": {"enum": list(COUPLINGS)}}}},
        },
    },
    claims=("cp_claims",),
    planned_jobs=planned_jobs,
    proxies={RULE: "contact_level"},     # its jobs keep their size between quick and full
    captions="coupling.rst",
)
