"""Friction: Tresca partial slip against Cattaneo-Mindlin, and the frictional solvers

The thesis's problem is frictionless; the suite adds Tresca and Coulomb friction on the
same ContactQP ({doc}`/guide/friction`). This study measures it on the contact scenes with
the `friction`, `mu` and `shift` parameters: circle–square (2D) and cube–sphere (3D). Per
scene and level (`workflows/scripts/friction_study.py`):

The 2D scene is `circle_square_matched`: circle–square with `square_cells` 20, so that the
square's top-edge nodes are spaced as the circle's boundary nodes (0.0499 at level 0).
With the default 16 the two spacings differ by a factor 1.25 at every level, and the nodal
forces of the nodal constraints (Alg. 7.1) carry the beat of the two, a scatter with a
period of four cells that refinement does not shrink: the nodal pressure lies 6 % from
Hertz's ellipse in L2 at levels 3 and 4 alike, against 1.0 % on the matched scene (level
3). At Q/(μP) = 0.3 the stick zone's traction is the difference of two ellipses of about
μp0 each, a third of μp in L2, and the same scatter is a three times larger relative
error: the traction's L2 error at level 3 is 16.7 % on the default scene against 6.6 % on
the matched one (10.7 % and 6.1 % at level 4). The matched scene costs
14 % more nodes (75,206 at level 3); the contact solution study reports the beat on the
default scene.

- **Reference paths.** Tresca friction with `mu` (0.5), the normal load first, then the
  held arc (cap) moved along x; the tangential step is scaled until Q/(μP) of the last step
  is 0.3 and 0.7 (`solvers.kernels.tresca.path_for_ratio`). The reference is `tresca_exact` (exact
  to round-off) where it takes the problem: up to 2000 constrained rows and 4e8 entries
  of its dense A⁻¹G' (cube–sphere level 3 has 1.3e9); beyond, the first of
  `semismooth_newton` and `tnnmg` that takes it, verified at `high`, and the table's
  `reference` column says which.
- **Cattaneo–Mindlin** (Johnson, *Contact Mechanics*, 1985, Sects. 7.1–7.2). The contact
  size a and the stick-zone size c (half-widths on the cylinder, radii on the sphere) are
  second moments of the nodal normal forces and of the deficit s − |λ|, so no node has to
  be classified. c/a is compared with √(1 − Q/(μP)) (cylinder) or (1 − Q/(μP))^(1/3)
  (sphere). The tangential traction (2D: λ/mass; 3D: each node's component along the
  total tangential force) is compared with
  q = μp0(√(1 − x²/a²) − (c/a)√(1 − (x − e)²/c²)), as a relative L2 error over the
  contact nodes (the lumped surface mass the weights): the centre, a and μp0 those of
  Tresca's slip bound s (μ times the normal step's forces: the theory's μp), c the
  analytic one, and e the stick zone's offset from the contact's centre, the first moment
  of the deficit (`reference.cattaneo_mindlin.partial_slip_reference`). The theory's zones
  are concentric because the normal load leaves no tangential traction between similar
  half-planes; the scene's normal step, loaded with friction, leaves a small traction odd
  in x (about 3 % of μP in all), which moves the stick zone by e/a = 2.3–2.8 % at both
  ratios and levels 2–4 (the table's `stick_offset`; 0.0 % when the normal step is loaded
  without friction, level 2). Centred at the
  contact, the profile's error at Q/(μP) = 0.3 would be 14.3 % at level 3 and 16.6 % at
  level 4 instead of 6.6 % and 6.1 %: the offset does not shrink with h.
- **The solvers.** `tnnmg` and `semismooth_newton` run the same scaled load path as
  `contactbench solve` runs it (`solvers.interface.run_load_path`), every Tresca step
  verified at `high`, twice: each solve started from the path's last answer (`warm`, as
  a quasi-static computation and `contactbench solve` run it) and from zero (`cold`,
  `--cold`); TNNMG a third time by nested iteration (`nested`,
  `solvers.kernels.tresca.run_nested_load_path`): the same path on the two coarser levels first,
  and each solve on a level started from its own last answer plus the coarser level's
  prolongated change over that solve, so that the slip front's place comes from below
  (Alg. 8.5 on each load step). The table records status, iterations in the normal and
  the tangential step (the finest level's; nested rows add the coarser levels'), setup
  and solve time, and the relative energy-norm distance of the last step to the
  reference's.
- **Timing.** TNNMG on the reference's last Tresca step, from zero, from the normal
  step's answer and nested from zero on the two coarser levels (each coarser step solved
  to KKT residuals 1e-3 and prolongated, their time included), its time (setup
  included) to relative energy error 1e-6 against the
  reference, beside one linear solve from zero of the same system without contact
  (geometric-multigrid PCG to the same accuracy); the median of five runs each, taken in
  rounds (one of each per round, so that a drift of the machine's speed meets all alike), the job
  alone on the machine.
- **μ = 0.** The reference's path with μ = 0 is compared with `pdas` on the
  frictionless scene, both load steps.
- **Coulomb** (`friction=coulomb`, shift 0.02): the fixed point s = μp over the
  reference's Tresca steps; its Tresca solves and last contraction ratio per load step.
- **The faceted law** (cube–sphere, `friction_facets` = k = 8, 16, …, 256: the friction
  disc replaced by the inscribed regular k-gon, a QP): the reference's path at the last
  ratio against the isotropic one, per k: the energy gap J* − J_k* (between 0 and
  (1 − cos(π/k)) times the dissipation: O(k⁻²)), the relative energy-norm distance of u
  and the largest traction difference (O(k⁻¹): a slipping node's traction points at a
  vertex, off the slip by up to π/k), and the exact reference's Newton steps.

| file | content |
| --- | --- |
| `results/<scene>/friction.csv` | one row per level, ratio and role (`reference`, `solver`, `timing`, `mu_zero`, `coulomb`) and start (`warm`, `cold`, `nested`): N, rows, status, iterations per load step (TNNMG's tangential step also split at the last change of its face, and its contraction on the face; nested: the coarser levels' iterations and time beside), times, the energy distance to the reference, a, c, c/a against theory, the traction's L2 error, TNNMG's and the linear floor's time to the target, Coulomb's solves and contraction |
| `results/<scene>/friction_profiles.csv` | per level, ratio and constrained node of the reference's last step: the distance from the contact's centre over a (signed in 2D) and the position in the contact plane, the measured and analytic traction, μ times the measured and Hertz pressure, the stick/slip state |
| `results/<scene>/friction_claims.csv` | the claims below, each judged or with the reason it is not |
| `results/<scene>/friction_traction.png` | the traction profiles at the finest level, both ratios, with the Cattaneo–Mindlin curve and μp |
| `results/<scene>/friction_stick.png` | c/a against Q/(μP): measured points per level, the analytic curve |
| `results/<scene>/friction_map.png` | the stick and slip nodes in the contact plane at the finest level, with the measured contact boundary and the analytic stick zone |
| `results/<scene>/friction_cost.png` | iterations of the tangential step and solve time against N per solver, with fitted exponents |

How to read the figures: in the traction profiles, the measured nodal traction (markers)
should follow the analytic curve (line): inside the stick zone (distance below c) it lies
below μp, and in the slip annulus it lies on μp. In the stick-zone figure, the points of
each level should approach the analytic curve as the level rises. In the map, the sticking
nodes should fill the analytic stick zone and the slipping ones the annulus around it. In
the cost figure, an exponent near 0 for the iterations means the solver's steps do not
grow with N.

The claims (`report/friction.py`):

- c/a within 5 % (circle–square) or 10 % (cube–sphere) at the finest level, for both
  ratios;
- the 2D traction profile within 10 % in L2 at the finest level (the sphere's is reported:
  Mindlin's solution takes the traction parallel to Q, exact only for ν = 0);
- TNNMG, semismooth Newton and the reference agree to 1e-8 in relative energy at every
  level where they all ran;
- the μ = 0 path equals `pdas` to 1e-10;
- every frictional solve is verified `converged`;
- TNNMG's tangential-step iterations on the finest level, nested from the coarser
  levels, grow at most 15 % over the last two levels (from the normal step's answer and
  from zero: reported; reported too, the residual's contraction per step after the
  step's face last changed, its multigrid phase, with the steps that find the face and
  those on it: the table's `contraction_tangential_on_face`, `steps_tangential_to_face`
  and `steps_tangential_on_face`, {doc}`/guide/friction`);
- TNNMG's time to 1e-6 on the tangential step, nested from zero with the coarser
  levels' time included, is at most 3 linear solves from zero at the finest level (from
  zero on the finest level alone and from the normal step's answer: reported);
- Coulomb's fixed point converges at every level;
- the faceted law's energy gap lies in its bracket [0, (1 − cos(π/k)) D] at every k and
  level, and falls like k^(−2 ± 0.3) over the four largest k at the finest level (over
  every k, and the displacement's exponent, −1 in theory, reported: the small k are
  pre-asymptotic while π/k exceeds the slip directions' angles to the tangential load).

The rates of the c/a error and the traction error against N are fitted and reported.
The accuracy bars and TNNMG's growth are judged only where the contact zone has at least
25 nodes on circle–square (level 3) or 150 on cube–sphere (level 3, about 240); the coarser
levels give that reason instead.

Measured at cube–sphere levels 1–2 and at `circle_square_matched` levels 2–3
(`contactbench study friction --problem P --levels L --mu 0.5 --ratios 0.3 0.7 --shift 0.01
--coulomb-shift 0.02 --solvers tnnmg semismooth_newton --tol high --time-limit 120 --target
1e-6 --repeats 5 --out F --profiles G`, with `--set square_cells=20` in 2D; cube–sphere
levels 1–2 in 147 s and 2.1 GB); TNNMG's iterations and times by the same command with
`--solvers tnnmg --coulomb-shift 0`, the job alone on a quiet 2-core machine (AMD EPYC with
AVX-512; in 2D `--repeats 3`). Iterations are those of the tangential step, started from
the normal step's answer (in brackets: from zero); the time ratio is TNNMG's time to 1e-6
over the linear solve's from zero, TNNMG from zero (in brackets: from the normal step's
answer), medians taken in rounds:

| scene, level | N | contact nodes | c/a deviation (0.3 / 0.7) | traction L2 error (0.3 / 0.7) | TNNMG iterations | SSN iterations | TNNMG time / linear solve | Coulomb: Tresca solves (contraction) |
| --- | --- | --- | --- | --- | --- | --- | --- | --- |
| circle–square matched 2 | 18,972 | 15 | −0.5 % / −3.5 % | 12.3 % / 5.8 % | 11 / 11 (14 / 13) | 2 / 4 (7 / 6) | 2.5 / 2.6 (2.2 / 1.9) | 2 + 10 (0.060) |
| circle–square matched 3 | 75,206 | 31 | −0.2 % / −1.0 % | 6.6 % / 2.9 % | 11 / 13 (16 / 16) | 4 / 6 (7 / 7) | 2.6 / 2.5 (1.4 / 1.8) | 2 + 10 (0.061) |
| cube–sphere 1 | 2,691 | 15 | −0.8 % / −0.9 % | 39.8 % / 15.6 % | 9 / 10 (9 / 11) | 6 / 6 (7 / 7) | 4.9 / 5.3 (4.6 / 6.4) | 8 + 8 (0.046) |
| cube–sphere 2 | 18,360 | 61 | −1.9 % / −6.3 % | 37.4 % / 14.3 % | 9 / 11 (11 / 11) | 6 / 9 (8 / 9) | 3.7 / 3.9 (3.2 / 3.9) | 9 + 10 (0.059) |

On circle–square, c/a meets its 5 % bar at level 3 for both ratios, and its error falls
with N. The traction meets its 10 % bar at level 3 at both ratios (6.6 % and 2.9 %; 6.1 %
and 2.1 % at level 4), its stick zone 2.3–2.8 % of a off the contact's centre (above).
What is left at 0.3 lies at the stick zone's ends (level 3: 98 % of the squared error on
the 10 of 31 nodes within 0.15 a of x = ±c), where q has its square-root kink and a node's
position within its cell counts most. On cube–sphere c/a lies
within 7 % of (1 − Q/(μP))^(1/3) at levels 1 and 2; the bar is judged at level 3 (full
scale; measured once by semismooth Newton, {doc}`/guide/friction`: −1.1 % and −3.1 %).
TNNMG, semismooth Newton and the exact reference agree to 9.4e-10 in relative energy at
every level of both scenes, from either start; the μ = 0 path equals `pdas` to 2e-14;
every solver path is verified `converged`. Started from the normal step's answer, TNNMG's
tangential step (CG on the face in 2D) takes 11–13 iterations at circle–square levels 2
and 3, and 9–10 to 9–11 at cube–sphere levels 1 and 2 (0–18 %; from zero 0–23 %). With
one presmoothing sweep (`presmoothing=1`; a Tresca step takes two by default,
{doc}`/guide/friction`) its steps split into a nonsmooth phase, TNNMG steps until the stick set settles, and 5–6 CG
steps on the face; the CG phase stays flat, and the nonsmooth phase grows with the number
of nodes whose state flips (the slip zone's front moves by a few nodes per step, fewer as
it nears its place: on the default circle–square at Q/(μP) = 0.7, 4, 6 and 8 TNNMG steps
for 5, 11 and 24 flips at levels 2–4, then 6, 5 and 5 CG steps). The truncated coarse
correction holds every sticking node's tangential unknown, so only the smoother and the
line search move the front. On the matched scene at 0.7 the tangential step grows from 11
to 13 (18 %, over the 15 % bar): 5 TNNMG and 6 CG steps for 6 flips at level 2; at level 3,
6 TNNMG steps for 13 of its 14 flips, one CG step on a face the last flip then leaves, 2
more TNNMG and 4 CG. After the face's last change the step takes 5 / 7 steps at level 2 and
8 / 5 at level 3 (0.3 / 0.7), its residual contracting by 0.136 / 0.126 and 0.122 / 0.132
per step (reported beside the bar), and TNNMG steps alone
(`krylov=none`) take 15 / 15 and 14 / 15: the growth lies in finding the face
({doc}`/guide/friction` gives the analysis and what else was measured). From zero, TNNMG's
time to 1e-6 is 2.5–2.6 linear solves at circle–square level 3 and 3.7–3.9 at cube–sphere
level 2; from the normal step's answer, as the load path runs it, 1.4–1.8 and 3.2–3.9. The
floor, a sub-second run at these levels, varies by a third between whole runs of the job; the timed
runs therefore take turns, so that both sides of a ratio see the same machine.

Circle–square level 4: on the matched scene (299,466 nodes; the reference paths alone) c/a
+0.01 % / 0.00 % and the traction 6.1 % / 2.1 %. TNNMG there (the same command with
`--levels 4 --coulomb-shift 0 --solvers tnnmg --time-limit 600 --repeats 3`, 2.2 min and
9.7 GB alone on the quiet machine): the tangential step takes 13 / 13 iterations from the
normal step's answer, 16 / 20 from zero and 9 / 10 nested (9 / 10 at level 3: no growth);
its time to 1e-6 is 2.09 / 2.66 linear solves from zero, 1.44 / 1.66 from the normal step's
answer and 1.61 / 1.55 nested, the coarser levels' time included. On the default scene
(262,474 nodes) μ = 0 equals `pdas` to 3e-14. Coulomb's fixed point converges at every
level in 8–10 Tresca solves of the tangential step, with a contraction ratio of 0.04–0.07.

The faceted law on cube–sphere at Q/(μP) = 0.7 (k = 8, 16, …, 256, `tresca_exact`,
measured on the loaded shared machine): the energy gap in its bracket at every k; its
exponent over k = 32–256 −1.99 at level 1 and −1.92 at level 2 (over every k −1.66 and
−1.64), the displacement's −1.00 and −0.98; the exact reference's Newton steps in the
tangential step grow with k (level 2: 39 at k = 8, 87 at k = 256), the seven paths of
level 2 take about five minutes, those of level 1 about 20 s.
"""
from workflows.studies._base import AtScale, ConfigError, Study, scenes_of

RULE = "friction_study"
#: The scene parameters the study sets itself.
FRICTION_PARAMETERS = ("friction", "mu", "shift")


def friction_args(config: dict, scene: str) -> str:
    """A scene's settings of the friction study as arguments of
    ``workflows/scripts/friction_study.py``."""
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


#: The study's settings at every scale but the levels: mu, the load ratios Q/(mu P), the
#: shift the ratio search scales, Coulomb's shift (Q/(mu P) ~ 0.5 at mu = 0.5), the solvers
#: and their verified tolerance (the agreement claim's 1e-8 needs 'high'), the time limit,
#: the energy error TNNMG and the linear floor are timed to, and their timed runs (the
#: median of five, in rounds: the sub-second runs of the quick levels vary by a third
#: between whole runs of the job); the faceted law's facet counts (powers of two: the
#: error oscillates between k and 2k, six doublings average it out; the exact reference's
#: cost does not grow with k).
COMMON = {"mu": 0.5, "ratios": [0.3, 0.7], "shift": 0.01, "coulomb_shift": 0.02,
          "solvers": ["tnnmg", "semismooth_newton"], "tol": "high", "time_limit": 120,
          "target": 1e-6, "repeats": 5, "facets": [8, 16, 32, 64, 128, 256]}


def settings_at(circle_square: list[int], cube_sphere: list[int]) -> dict:
    """The study's section at a scale: the levels of the two scenes (the 2D one
    ``circle_square_matched``: module docstring), :data:`COMMON` else."""
    return {"scenes": {"circle_square_matched": circle_square, "cube_sphere": cube_sphere},
            **COMMON}


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
    rule_file="friction.smk",
    scripts={"friction": "workflows.scripts.friction_study"},
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
    settings={
        "type": "object",
        "description": "Friction (workflows/scripts/friction_study.py): per scene and level, "
                       "Tresca load paths scaled to each Q/(mu P) of 'ratios', against "
                       "Cattaneo-Mindlin, solved by the reference and 'solvers'; mu = 0; "
                       "Coulomb",
        "additionalProperties": False,
        "required": ["scenes", *COMMON],
        "properties": {
            "scenes": {"$ref": "#/definitions/scene_levels", "description":
                       "{scene: [levels]} (a scene whose problem takes friction)"},
            "mu": {"type": "number", "exclusiveMinimum": 0,
                   "description": "friction coefficient"},
            "ratios": {"type": "array", "minItems": 1,
                       "items": {"type": "number", "exclusiveMinimum": 0,
                                 "exclusiveMaximum": 1},
                       "description": "load ratios Q/(mu P) of the Tresca paths"},
            "shift": {"type": "number", "description":
                      "the tangential step's shift before its scaling (nonzero)"},
            "coulomb_shift": {"type": "number", "minimum": 0,
                              "description": "the Coulomb runs' tangential shift (0: none)"},
            "solvers": {"type": "array", "items": {"type": "string"},
                        "description": "registered solvers that take friction"},
            "tol": {"enum": ["low", "mid", "high"],
                    "description": "the solvers' verified tolerance"},
            "time_limit": {"$ref": "#/definitions/time_limit"},
            "target": {"type": "number", "exclusiveMinimum": 0, "exclusiveMaximum": 1,
                       "description": "relative energy error TNNMG and the linear floor are "
                                      "timed to"},
            "repeats": {"type": "integer", "minimum": 1,
                        "description": "timed runs of each (the median is kept)"},
            "facets": {"type": "array", "items": {"type": "integer", "minimum": 3},
                       "description": "facet counts k of the faceted law (3D: the disc "
                                      "replaced by the inscribed regular k-gon) compared "
                                      "with the isotropic one (empty: none)"},
        },
    },
    # resources: the largest job (one scene), measured alone at tiny and quick on the shared
    # 2-core machine (quick: circle-square 70 s and 1.6 GB, cube-sphere 99 s and 2.1 GB);
    # full and huge estimated: circle-square's paths cost ~4x per level (N x4,
    # iterations flat), cube-sphere level 3 goes to semismooth Newton (S of 3,267 columns
    # formed once per problem, 5.7 GB peak, minutes); the 2D scene's level 4, 6.9 GB with
    # the default square's 262,474 nodes, has 14 % more on the matched square (299,466)
    scales={
        "tiny": AtScale(settings_at([0, 1], [1]),             # measured 13 s, 0.4 GB (2D)
                        {RULE: {"mem_mb": 1000, "runtime": 1}}),
        # quick: cube-sphere level 2 (1.9 min of the study's 4.7) at full
        "quick": AtScale(settings_at([1, 2, 3], [1]),
                         {RULE: {"mem_mb": 3000, "runtime": 5}}),
        # full measured alone: cube-sphere 29 min and 11.6 GB, circle-square 5 min, 7.7 GB
        "full": AtScale(settings_at([1, 2, 3, 4], [1, 2, 3]),
                        {RULE: {"mem_mb": 13000, "runtime": 40}}),
        "huge": AtScale(settings_at([1, 2, 3, 4, 5], [1, 2, 3]),
                        {RULE: {"mem_mb": 30000, "runtime": 60}}),
    },
    claims=("fr_claims",),
    captions="friction.rst",
)
