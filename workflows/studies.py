"""The studies the Snakefile regenerates, declared once.

Every file a rule writes has one path template here (:data:`PATHS`); the rules
(``workflows/*.smk``) and the default target read them back, so an output is
named in one place. A study runs on the scenes its config entry lists::

    scenes:                                    # a scene = a registered problem + overrides
      circle_square: {problem: circle_square}
      circle_square_stiff: {problem: circle_square, params: {E2: 10.0}}
    solver_comparison:
      scenes: {circle_square: [1, 2, 3], circle_square_stiff: [1, 2]}

so a new scene joins a study by a config line; results land under
``results/<scene>/``. The Laplace study of Ch. 6 is not a contact scene and has
its own entry.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

RESULTS = "results"
#: The thesis's tables (absolute: the workflow may run in another working directory).
REFERENCE = Path(__file__).resolve().parent.parent / "reference"

#: Path templates of every file the workflow writes ({scene}, {level}, {case} wildcards).
PATHS = {
    # contact_solution: exact solve per level, fields, Hertz
    "contact_level": "results/{scene}/contact_L{level}.csv",
    "hertz_level": "results/{scene}/hertz_L{level}.csv",
    "fields_level": "results/{scene}/fields_L{level}.vtu",
    "hertz": "results/{scene}/hertz.csv",
    "fields_figure": "results/{scene}/fields.png",
    "pressure_figure": "results/{scene}/pressure.png",
    "surface_figure": "results/{scene}/contact_surfaces.png",
    # solver_comparison
    "solver_runs": "results/{scene}/solvers_L{level}.csv",
    "solver_table": "results/{scene}/solvers.csv",
    "solver_presets": "results/{scene}/solver_presets.csv",
    "solver_times": "results/{scene}/solver_times.png",
    "solver_work": "results/{scene}/solver_error_vs_time.png",
    "solver_costs": "results/{scene}/solver_costs.csv",
    # test_set: the contact QP test set exported per size class, every solver on it, the
    # summary over it (qpbenchmark's way) and one work-precision figure per family
    "test_set_export": "results/test_set/{set}/export/{size_class}",
    "test_set_runs": "results/test_set/{set}/runs/{size_class}/{scene}.csv",
    "solver_summary": "results/solver_summary/summary.csv",
    "solver_summary_by_class": "results/solver_summary/summary_by_class.csv",
    "solver_summary_by_scene": "results/solver_summary/summary_by_scene.csv",
    "solver_summary_claims": "results/solver_summary/claims.csv",
    "solver_profiles": "results/solver_summary/performance_profiles.png",
    "solver_work_precision": "results/solver_summary/work_precision/{scene}.png",
    # augmented_projection
    "ap_study": "results/{scene}/augmented_projection_study.csv",
    "ap_table": "results/{scene}/augmented_projection_table.csv",
    "ap_claims": "results/{scene}/augmented_projection_claims.csv",
    "ap_time": "results/{scene}/augmented_projection_time.png",
    "ap_kappa": "results/{scene}/augmented_projection_kappa.png",
    "ap_tnnmg": "results/{scene}/augmented_projection_tnnmg.png",
    # adaptive (Sect. 7.4): runs per variant, accuracy against a common refinement
    "adaptive_steps": "results/{scene}/adaptive_steps.csv",
    "adaptive_fields": "results/{scene}/adaptive_{variant}.vtu",
    "adaptive_surface": "results/{scene}/adaptive_{variant}_surface.csv",
    "adaptive_table": "results/{scene}/adaptive_table.csv",
    "adaptive_accuracy": "results/{scene}/adaptive_accuracy.csv",
    "adaptive_pileup": "results/{scene}/adaptive_pileup.csv",
    "adaptive_convergence": "results/{scene}/adaptive_convergence.csv",
    "adaptive_meshes": "results/{scene}/adaptive_meshes.png",
    "adaptive_snapshot": "results/{scene}/adaptive_snapshot.png",
    "adaptive_eta": "results/{scene}/adaptive_eta.png",
    "adaptive_error": "results/{scene}/adaptive_error.png",
    "adaptive_pressure": "results/{scene}/adaptive_pressure.png",
    # adaptive: the contact patch test
    "patch_runs": "results/{scene}/patch_test_runs.csv",
    "patch_pressure": "results/{scene}/patch_test_pressure.csv",
    "patch_table": "results/{scene}/patch_test.csv",
    "patch_figure": "results/{scene}/patch_test.png",
    # laplace_nonmatching (Ch. 6)
    "laplace_runs": "results/laplace_nonmatching/runs/{case}_{side}.csv",
    "laplace_errors": "results/laplace_nonmatching/errors.csv",
    "laplace_errors_by_side": "results/laplace_nonmatching/errors_by_side.csv",
    "laplace_rates": "results/laplace_nonmatching/rates.csv",
    "laplace_convergence": "results/laplace_nonmatching/convergence_{case}.png",
    "laplace_mesh": "results/laplace_nonmatching/mesh.png",
    # exact_reference: the dual route against the KKT-LU PDAS
    "exact_runs": "results/{scene}/exact_reference_runs.csv",
    "exact_table": "results/{scene}/exact_reference.csv",
    "exact_claims": "results/{scene}/exact_reference_claims.csv",
    "exact_figure": "results/{scene}/exact_reference.png",
    # hard_cases: the test set's runs on its hard families; one table and heat map
    "hard_table": "results/hard_cases/hard_cases.csv",
    "hard_heatmap": "results/hard_cases/hard_cases.png",
    "hard_nu_runs": "results/hard_cases/incompressibility.csv",
    "hard_nu_claims": "results/hard_cases/incompressibility_claims.csv",
    "hard_nu_figure": "results/hard_cases/incompressibility.png",
    # roll_stack (Sect. 9.3): both strip forces at one level, profiles, fields, solvers
    "roll_runs": "results/{scene}/roll_stack_runs.csv",
    "roll_profiles": "results/{scene}/roll_stack_profiles.csv",
    "roll_contact": "results/{scene}/roll_stack_contact.csv",
    "roll_solver_runs": "results/{scene}/roll_stack_solvers.csv",
    "roll_fields": "results/{scene}/roll_stack_F{force}MN.vtu",
    "roll_table": "results/{scene}/roll_stack_table.csv",
    "roll_claims": "results/{scene}/roll_stack_claims.csv",
    "roll_solver_table": "results/{scene}/roll_stack_solver_table.csv",
    "roll_pressure": "results/{scene}/roll_stack_pressure.png",
    "roll_mesh": "results/{scene}/roll_stack_mesh.png",
    "roll_stress": "results/{scene}/roll_stack_von_mises.png",
    "roll_line_load": "results/{scene}/roll_stack_line_load.png",
    "roll_sag": "results/{scene}/roll_stack_sag.png",
    "roll_strip": "results/{scene}/roll_stack_strip_profile.png",
    # element_order (Remark 7.11): P1 against P2, Alg. 8.4 on P2
    "eo_study": "results/{scene}/element_order.csv",
    "eo_claims": "results/{scene}/element_order_claims.csv",
    "eo_figure": "results/{scene}/element_order.png",
    # the summary page at the top of the report (report/summary.py)
    "summary_html": "results/summary/summary.html",
    "summary_claims": "results/summary/claims.csv",
    # logs and benchmarks of every rule
    "log": "results/logs/{rule}/{name}.log",
    "benchmark": "results/benchmarks/{rule}/{name}.tsv",
}


@dataclass(frozen=True)
class Study:
    """One study: what it shows, the thesis it regenerates, its final outputs.

    ``outputs`` are keys of :data:`PATHS`: a template with ``{scene}`` is expanded
    over the scenes the study's config entry lists, one with ``{case}`` over its
    cases; any other is one file (e.g. a table across scenes).
    """

    name: str
    summary: str
    thesis: str
    outputs: tuple[str, ...]
    #: ``(config key, outputs)``: further per-scene outputs for the scenes listed under
    #: ``config[name][key]["scenes"]`` (e.g. the adaptive study's patch test).
    extra: tuple = ()

    def items(self, config: dict) -> list[tuple[str, str | None, str]]:
        """``(PATHS key, scene or None, path)`` of every file this study produces."""
        if self.name not in config:
            return []
        out = []
        for key in self.outputs:
            template = PATHS[key]
            if "{scene}" in template:
                out += [(key, s, template.format(scene=s)) for s in scenes_of(config, self.name)]
            elif "{case}" in template:
                out += [(key, None, template.format(case=c)) for c in
                        config[self.name].get("cases", ["sin10x", "linear"])]
            else:
                out.append((key, None, template))
        for extra, outputs in self.extra:
            scenes = config[self.name].get(extra, {}).get("scenes", {})
            out += [(k, s, PATHS[k].format(scene=s)) for s in scenes for k in outputs]
        return out

    def targets(self, config: dict) -> list[str]:
        """The files this study produces under ``config``."""
        return [path for _, _, path in self.items(config)]


def coarser_levels(config: dict, study: str, scene: str, level) -> list[int]:
    """The configured levels of ``scene`` in ``study`` below ``level`` (a study whose jobs
    run coarse to fine, each reading the coarser results)."""
    return [l for l in scenes_of(config, study).get(scene, []) if l < int(level)]


def scenes_of(config: dict, study: str) -> dict[str, list[int]]:
    """``{scene: levels}`` a per-scene study runs (empty if the study is not configured);
    for the test set its families (levels by size class: :func:`test_set_runs`)."""
    if study == "test_set":
        if study not in config:
            return {}
        return {f: [] for f in config[study].get("families") or test_set_of(config).families}
    return dict(config.get(study, {}).get("scenes", {}))


def test_set_of(config: dict):
    """The test set the config names (``test_set.name``; the current one by default)."""
    from workflows.test_set import CURRENT, load

    return load(config.get("test_set", {}).get("name", CURRENT))


def scenes_with_families(config: dict) -> dict:
    """``config['scenes']`` with the test set's families added (a family is a scene: the
    studies name the hard cases and variants by it, typed once in the set).

    Raises
    ------
    ConfigError
        If a scene of the config has a family's name but another definition.
    """
    scenes = dict(config.get("scenes") or {})
    for family, entry in test_set_of(config).families.items():
        entry = {"problem": entry["problem"], **({"params": dict(entry["params"])}
                                                  if entry.get("params") else {})}
        mine = scenes.get(family)
        if mine is not None and ({**mine, "params": dict(mine.get("params") or {})}
                                 != {**entry, "params": entry.get("params", {})}):
            raise ConfigError(f"config 'scenes.{family}': the test set defines this name as "
                              f"{entry}; allowed: another name, or leave it out")
        scenes[family] = entry
    return scenes


def test_set_runs(config: dict) -> list[str]:
    """Every run table of the test_set study: family x size class (with problems)."""
    if "test_set" not in config:
        return []
    ts, cfg = test_set_of(config), config["test_set"]
    return [PATHS["test_set_runs"].format(set=ts.id, size_class=c, scene=f)
            for c in cfg["classes"] for f in scenes_of(config, "test_set")
            if ts.problems(c, [f])]


def test_set_hard_cases(config: dict) -> tuple[list[str], list[str]]:
    """The run tables holding the hard cases and the cases as ``family:level``."""
    if "test_set" not in config:
        return [], []
    ts = test_set_of(config)
    cases, files = [], []
    for family, levels in scenes_of(config, "hard_cases").items():
        for level in levels:
            cases.append(f"{family}:{level}")
            for c in config["test_set"]["classes"]:
                if any(p.level == level for p in ts.problems(c, [family])):
                    files.append(PATHS["test_set_runs"].format(set=ts.id, size_class=c,
                                                               scene=family))
    return sorted(set(files)), cases


def scene_problem(config: dict, scene: str) -> tuple[str, dict]:
    """The registered problem behind a scene and its parameter overrides."""
    entry = config["scenes"][scene]
    return entry["problem"], dict(entry.get("params") or {})


def thesis_table(config: dict, scene: str, study: str) -> str | None:
    """``reference/<table>.csv`` a scene regenerates in ``study``, if it runs with the
    thesis's own parameters (no overrides) and its problem declares one."""
    from problems.spec import problems

    problem, params = scene_problem(config, scene)
    table = problems()[problem].thesis_tables.get(study)
    return str(REFERENCE / f"{table}.csv") if table and not params else None


def set_args(config: dict, scene: str) -> str:
    """Command-line arguments for a scene: ``--problem P --set k=v ...``."""
    problem, params = scene_problem(config, scene)
    sets = " ".join(f"--set {k}={v}" for k, v in params.items())
    return f"--problem {problem} {sets}".strip()


STUDIES = {
    s.name: s
    for s in (
        Study(
            name="laplace_nonmatching",
            summary="convergence of nodal constraints with/without the stabilisation (6.18) on a "
                    "non-matching grid: H1 and L2 errors, fitted rates, both constrained sides",
            thesis="Ch. 6, Figs. 6.3, 6.5, 6.6, Theorems 6.17/6.24",
            outputs=("laplace_errors", "laplace_errors_by_side", "laplace_rates",
                     "laplace_convergence", "laplace_mesh"),
        ),
        Study(
            name="contact_solution",
            summary="exact contact solution per level of each scene: Hertz check (2D line or 3D "
                    "point contact), fields (VTU), von Mises stress and contact pressure figures",
            thesis="Sects. 9.1, 9.2 (Figs. 9.5, 9.9)",
            outputs=("hertz", "fields_figure", "pressure_figure", "surface_figure"),
        ),
        Study(
            name="solver_comparison",
            summary="every registered solver at three tolerance presets on identical QPs: "
                    "verified status, KKT residuals, certified bound, time, memory, energy "
                    "error; cost exponents and the ratio to the linear floor per scene",
            thesis="Ch. 8 (solvers) on the scenes of Ch. 9",
            outputs=("solver_table", "solver_presets", "solver_times", "solver_work",
                     "solver_costs"),
        ),
        Study(
            name="test_set",
            summary="the contact QP test set (workflows/config/test_sets/): every family at "
                    "the configured size classes exported (contactbench export) and solved by "
                    "every registered solver at every preset; qpbenchmark's summary (success "
                    "and correct rates, shifted geometric means, performance profiles) "
                    "overall, by size class and by scene; a work-precision figure per family",
            thesis="Ch. 8 (solvers) on every scene of Ch. 9 and its hard variants",
            outputs=("solver_summary", "solver_summary_by_class", "solver_summary_by_scene",
                     "solver_summary_claims", "solver_profiles", "solver_work_precision"),
        ),
        Study(
            name="augmented_projection",
            summary="the thesis's solver (Alg. 8.4) with multigrid A-hat and a sparse multilevel "
                    "S-hat: the thesis's table regenerated beside its values, the O(N) claim "
                    "tested against the multigrid-PCG linear solve as the floor",
            thesis="Ch. 8, Tables 9.1/9.3, Figs. 9.1/9.6, 9.3/9.8",
            outputs=("ap_table", "ap_claims", "ap_time", "ap_kappa", "ap_tnnmg"),
        ),
        Study(
            name="exact_reference",
            summary="the exact reference two ways, side by side: PDAS through the dual problem "
                    "on the contact rows (A factorised once by a sparse Cholesky, partial "
                    "solves) against PDAS with a KKT LU per active-set step; times, memory, "
                    "agreement of the multipliers",
            thesis="Sect. 7.1 (the dual problem (7.3)); the suite's reference for Ch. 9",
            outputs=("exact_table", "exact_claims", "exact_figure"),
        ),
        Study(
            name="hard_cases",
            summary="every registered solver at one preset (the test set's runs), each in its "
                    "own process with a hard time limit, on hard variants of the scenes (stiffness contrast, near "
                    "incompressibility, mesh ratio, single-node and whole-edge contact, no "
                    "contact, initial penetration, SI units, grazing contact, a thin body): "
                    "verified status, certified bound, errors against the reference, time; "
                    "Alg. 8.4's outer steps against Poisson's ratio up to 0.4999",
            thesis="Ch. 8 solvers on variants of Sects. 9.1, 9.2",
            outputs=("hard_table", "hard_heatmap", "hard_nu_runs", "hard_nu_claims",
                     "hard_nu_figure"),
        ),
        Study(
            name="adaptive",
            summary="adaptive refinement by eta_1 and eta_1 + eta_2 (Sect. 7.4): the thesis's "
                    "adaptive tables beside its values, meshes near the contact, max eta_T "
                    "against N, accuracy per node against a common finer reference (energy, "
                    "force, Hertz), the hanging-node pile-up quantified, Sect. 7.3 rates; the "
                    "contact patch test on non-matching meshes",
            thesis="Sects. 7.3-7.5, Tables 9.2/9.4, Figs. 7.3-7.5, 9.2, 9.4, 9.7",
            outputs=("adaptive_table", "adaptive_accuracy", "adaptive_pileup",
                     "adaptive_convergence", "adaptive_meshes", "adaptive_snapshot",
                     "adaptive_eta", "adaptive_error", "adaptive_pressure"),
            extra=(("patch_test", ("patch_table", "patch_figure")),),
        ),
        Study(
            name="roll_stack",
            summary="the roll stack of a four-high mill (crowned work roll floating on a backup "
                    "roll, SI units) at both strip forces: equilibrium, Hertz at the barrel "
                    "centre, contact line load and half-width along the barrel, sag of axes and "
                    "contact lines with and without the crown, strip profile for crowned and "
                    "cylindrical work rolls beside the beam model, von Mises cuts, VTU; the "
                    "solvers on the scene at coarser levels",
            thesis="Sect. 9.3, Figs. 9.10-9.16",
            outputs=("roll_table", "roll_claims", "roll_solver_table", "roll_pressure",
                     "roll_mesh", "roll_stress", "roll_line_load", "roll_sag", "roll_strip"),
        ),
        Study(
            name="element_order",
            summary="P1 against P2 elements on a contact scene (Remark 7.11): the energy error "
                    "against a common P2 reference per unknown and per second of solve time, "
                    "with fitted rates; Hertz at the finest P2 level; Alg. 8.4 on P2 with its "
                    "p-multigrid step (Table 9.1's columns: n_o, kappa(S-hat), times)",
            thesis="Remark 7.11, Sect. 8.6 (p0 = 0 for quadratic elements), Table 9.1 for P2",
            outputs=("eo_study", "eo_claims", "eo_figure"),
        ),
    )
}


@dataclass(frozen=True)
class ThesisItem:
    """A table or figure of the thesis and the output that regenerates it.

    ``key`` is a :data:`PATHS` key (None: not regenerated, ``note`` says why);
    ``problem`` picks the scene (the scene named like the problem); ``cases``
    expands a ``{case}`` template.
    """

    item: str
    what: str
    key: str | None
    problem: str | None = None
    note: str = ""


#: Every table and figure of the thesis's numerical chapters, and what regenerates it
#: (the summary page lists them with their status).
THESIS_ITEMS = (
    ThesisItem("Fig. 6.3", "non-matching grid of the Laplace problem", "laplace_mesh"),
    ThesisItem("Figs. 6.5/6.6", "H1 and L2 errors against h: nodal, stabilised, mortar",
               "laplace_convergence"),
    ThesisItem("Figs. 6.5/6.6 (rates)", "fitted convergence rates", "laplace_rates"),
    ThesisItem("Figs. 7.3/7.4", "adaptive meshes by eta_1 and eta_1 + eta_2 (pile-up)",
               "adaptive_meshes", "circle_square"),
    ThesisItem("Fig. 7.5", "mesh by stabilised two-sided nodal constraints and eta_1",
               "adaptive_meshes", "circle_square"),
    ThesisItem("(7.8)", "convergence rates under uniform refinement, O(h^1/2)",
               "adaptive_convergence", "circle_square"),
    ThesisItem("Table 9.1", "circle-square, uniform: N^C, n_o, n_i, T_solve, T_proj, kappa",
               "ap_table", "circle_square"),
    ThesisItem("Fig. 9.1", "circle-square: T_solve against N", "ap_time", "circle_square"),
    ThesisItem("Table 9.2", "circle-square, adaptive (eta_1 + eta_2)", "adaptive_table",
               "circle_square"),
    ThesisItem("Fig. 9.2", "circle-square: max eta_T against N", "adaptive_eta",
               "circle_square"),
    ThesisItem("Fig. 9.3", "circle-square: kappa(S-hat) against N", "ap_kappa",
               "circle_square"),
    ThesisItem("Sect. 9.1 (Hertz)", "circle-square against the Hertz line contact", "hertz",
               "circle_square"),
    ThesisItem("Table 9.3", "cube-sphere, uniform", "ap_table", "cube_sphere"),
    ThesisItem("Fig. 9.4", "adaptive mesh snapshot (2D view)", "adaptive_snapshot",
               "circle_square"),
    ThesisItem("Table 9.4", "cube-sphere, adaptive (eta_1 + eta_2)", "adaptive_table",
               "cube_sphere"),
    ThesisItem("Fig. 9.5", "cube-sphere: von Mises stress", "fields_figure", "cube_sphere"),
    ThesisItem("Fig. 9.6", "cube-sphere: T_solve against N", "ap_time", "cube_sphere"),
    ThesisItem("Fig. 9.7", "cube-sphere: max eta_T against N", "adaptive_eta", "cube_sphere"),
    ThesisItem("Fig. 9.8", "cube-sphere: kappa(S-hat) against N", "ap_kappa", "cube_sphere"),
    ThesisItem("Fig. 9.9", "cube-sphere: contact surface mesh of the adaptive run",
               "adaptive_snapshot", "cube_sphere"),
    ThesisItem("Sect. 9.2 (Hertz)", "cube-sphere against the Hertz point contact", "hertz",
               "cube_sphere"),
    ThesisItem("Fig. 9.10", "roll stack: strip pressure along the work roll", "roll_pressure",
               "roll_stack"),
    ThesisItem("Fig. 9.11", "roll stack: mesh (thesis: 46,611 nodes, 7,089 inequalities)",
               "roll_mesh", "roll_stack"),
    ThesisItem("Figs. 9.12/9.13", "roll stack: von Mises stress on cuts", "roll_stress",
               "roll_stack"),
    ThesisItem("Figs. 9.14-9.16", "roll stack: sag along the rolls' lines, 15 and 30 (MN), "
               "corrected by the crown (Schliff)", "roll_sag", "roll_stack"),
    ThesisItem("Sect. 9.3 (line load)", "roll stack: contact line load and half-width along "
               "the barrel, Hertz at the barrel centre", "roll_line_load", "roll_stack"),
    ThesisItem("Sect. 9.3 (strip)", "roll stack: strip thickness profile, crowned and "
               "cylindrical work rolls", "roll_strip", "roll_stack"),
    ThesisItem("Sect. 9.3 (numbers)", "roll stack: FE beside plane-strain Hertz and the beam "
               "model", "roll_table", "roll_stack"),
    ThesisItem("Remark 7.11 (2D)", "second-order elements, circle-square: P1 against P2, "
               "Alg. 8.4 on P2", "eo_figure", "circle_square"),
    ThesisItem("Remark 7.11 (3D)", "second-order elements, cube-sphere: P1 against P2, "
               "Alg. 8.4 on P2", "eo_figure", "cube_sphere"),
)


def thesis_item_files(config: dict, item: ThesisItem) -> list[str]:
    """The files regenerating ``item`` under ``config`` (empty: not at this config)."""
    if item.key is None:
        return []
    study = next(s for s in STUDIES.values() if item.key in s.outputs or any(
        item.key in outs for _, outs in s.extra))
    if study.name not in config:
        return []
    template = PATHS[item.key]
    if "{case}" in template:
        return [template.format(case=c) for c in
                config[study.name].get("cases", ["sin10x", "linear"])]
    if "{scene}" not in template:
        return [template]
    scenes = scenes_of(config, study.name)
    return [template.format(scene=item.problem)] if item.problem in scenes else []


def exact_args(config: dict, scene: str) -> str:
    """A scene's levels of the exact_reference study as script arguments."""
    entry = config["exact_reference"]
    levels = scenes_of(config, "exact_reference")[scene]
    kkt = entry.get("kkt_levels", {}).get(scene, levels)
    return (f"--levels {' '.join(map(str, levels))} --kkt-levels {' '.join(map(str, kkt))} "
            f"--time-limit {entry['time_limit']}")


def roll_args(config: dict, scene: str) -> str:
    """A scene's settings of the roll_stack study as arguments of
    ``workflows/scripts/roll_stack_study.py``."""
    rs = config["roll_stack"]
    (level,) = scenes_of(config, "roll_stack")[scene]
    args = [f"--level {level}", "--forces " + " ".join(f"{f:g}" for f in rs["forces"]),
            "--crowns " + " ".join(f"{c:g}" for c in rs["crowns"]),
            f"--time-limit {rs['time_limit']}"]
    if rs.get("solver_levels"):
        args += ["--solver-levels " + " ".join(map(str, rs["solver_levels"])),
                 "--solvers " + " ".join(rs["solvers"])]
    if rs.get("alg84_levels"):
        args.append("--alg84-levels " + " ".join(map(str, rs["alg84_levels"])))
    if rs.get("alg84_time_limit"):
        args.append(f"--alg84-time-limit {rs['alg84_time_limit']}")
    return " ".join(args)


def roll_fields(config: dict, scene: str) -> list[str]:
    """The VTU files of the roll_stack study (one per strip force, crowned roll)."""
    return [PATHS["roll_fields"].format(scene=scene, force=f"{f / 1e6:g}")
            for f in config["roll_stack"]["forces"]]


def element_order_args(config: dict, scene: str) -> str:
    """A scene's settings of the element_order study as arguments of
    ``workflows/scripts/element_order.py``."""
    eo = config["element_order"]
    levels = " ".join(map(str, scenes_of(config, "element_order")[scene]))
    return (f"--levels {levels} --reference-level {eo['reference_level'][scene]} "
            f"--time-limit {eo['time_limit']}")


def adaptive_variant_file(variant: str) -> str:
    """The ``{variant}`` of an adaptive output path: ``eta1+eta2`` -> ``eta1_eta2``."""
    return variant.replace("+", "_")


def adaptive_args(config: dict, scene: str) -> str:
    """A scene's settings of the adaptive study as arguments of
    ``workflows/scripts/adaptive_study.py`` (start level, node budget, marking and its minimum share, the
    eta_2 constant, the stabilisation, variants; uniform levels of the accuracy comparison, if any),
    from the validated config (the schema's defaults filled in: :mod:`workflows.settings`)."""
    ad = config["adaptive"]
    args = [f"--start-level {scenes_of(config, 'adaptive')[scene][0]}",
            f"--max-nodes {ad['max_nodes'][scene]}", f"--theta {ad['theta']}",
            f"--min-marked {ad['min_marked']}",
            f"--eta2-weight {ad['eta2_weight']}", f"--time-limit {ad['time_limit']}",
            f"--tol {ad['tol']}",
            f"--alpha {ad['stabilisation']['alpha']}",
            f"--penalty {ad['stabilisation']['penalty']}",
            "--variants " + " ".join(f"'{v}'" for v in ad["variants"])]
    acc = ad.get("accuracy", {}).get(scene)
    if acc:
        args.append("--uniform-levels " + " ".join(map(str, acc["uniform"])))
        if acc.get("max_nodes"):
            args.append(f"--error-max-nodes {acc['max_nodes']}")
    return " ".join(args)


class ConfigError(ValueError):
    """The workflow configuration is inconsistent (the message says where)."""


def check_config(config: dict) -> None:
    """What the JSON schema cannot check: every scene a study names is defined, its
    problem is registered, its parameters and levels are valid, variant names exist.

    Raises
    ------
    ConfigError
        Naming the config key and what is allowed.
    """
    from problems.spec import contact_scene_error, problems
    from solvers.augmented_projection import VARIANTS

    config = {**config, "scenes": scenes_with_families(config)}
    registry = problems()
    for scene, entry in config.get("scenes", {}).items():
        wrong = contact_scene_error(entry["problem"], entry.get("params"))
        if wrong is not None:
            raise ConfigError(f"config 'scenes.{scene}.{wrong[0]}': {wrong[1]}")
    for name in STUDIES:
        for scene, levels in scenes_of(config, name).items():
            if scene not in config.get("scenes", {}):
                raise ConfigError(f"config '{name}.scenes.{scene}': no such scene; defined: "
                                  f"{', '.join(config.get('scenes', {}))}")
            lo, hi = registry[config["scenes"][scene]["problem"]].levels
            bad = [lv for lv in levels if not lo <= lv <= hi]
            if bad:
                raise ConfigError(f"config '{name}.scenes.{scene}': levels {bad} are not "
                                  f"allowed; allowed: {lo}..{hi}")
    for variant in config.get("augmented_projection", {}).get("configs", []):
        if variant not in VARIANTS:
            raise ConfigError(f"config 'augmented_projection.configs': {variant!r} is not "
                              f"allowed; allowed: {', '.join(VARIANTS)}")
    chosen = config.get("solver_comparison", {}).get("solvers", [])
    if chosen:
        from solvers.interface import solvers
        unknown = sorted(set(chosen) - set(solvers()))
        if unknown:
            raise ConfigError(f"config 'solver_comparison.solvers': {unknown} are not "
                              f"registered; allowed: {', '.join(solvers())}")
    runs = scenes_of(config, "exact_reference")
    for scene, levels in config.get("exact_reference", {}).get("kkt_levels", {}).items():
        extra = sorted(set(levels) - set(runs.get(scene, [])))
        if extra:
            raise ConfigError(f"config 'exact_reference.kkt_levels.{scene}': levels {extra} are "
                              f"not allowed; allowed: among exact_reference.scenes.{scene} "
                              f"{runs.get(scene, [])}")
    _check_adaptive(config, registry)
    _check_roll_stack(config, registry)
    _check_incompressibility(config, registry)
    _check_element_order(config, registry)
    _check_test_set(config)
    unknown = sorted(set(config.get("resources", {})) - set(HEAVY_RULES))
    if unknown:
        raise ConfigError(f"config 'resources.{unknown[0]}': not a heavy rule; allowed: "
                          f"{', '.join(sorted(HEAVY_RULES))}")
    for rule, study in HEAVY_RULES.items():
        if study in config and not {"mem_mb", "runtime"} <= set(
                config.get("resources", {}).get(rule, {})):
            raise ConfigError(f"config 'resources.{rule}': the study {study!r} runs, so declare "
                              "its measured mem_mb and runtime (minutes)")


def _check_incompressibility(config: dict, registry: dict) -> None:
    """The hard cases' incompressibility table: registered contact problems, a level and
    Poisson's ratios each scene accepts."""
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


def _check_element_order(config: dict, registry: dict) -> None:
    """The element_order study: scenes whose problem has the 'degree' parameter, each with a
    reference level above its levels and within the problem's range."""
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


def _check_adaptive(config: dict, registry: dict) -> None:
    """The adaptive study: known variants, one start level per scene, every per-scene
    setting and the patch test naming defined scenes."""
    from problems.fem.adaptive import STUDY_VARIANTS

    ad = config.get("adaptive")
    if not ad:
        return
    for variant in ad.get("variants", []):
        if variant not in STUDY_VARIANTS:
            raise ConfigError(f"config 'adaptive.variants': {variant!r} is not allowed; "
                              f"allowed: {', '.join(STUDY_VARIANTS)}")
    runs = scenes_of(config, "adaptive")
    for scene, levels in runs.items():
        if len(levels) != 1:
            raise ConfigError(f"config 'adaptive.scenes.{scene}': {levels} is not allowed; "
                              "allowed: one start level, e.g. [0]")
        if scene not in ad.get("max_nodes", {}):
            raise ConfigError(f"config 'adaptive.max_nodes': no node budget for scene {scene!r}")
    for key in ("max_nodes", "accuracy"):
        for scene in ad.get(key, {}):
            if scene not in runs:
                raise ConfigError(f"config 'adaptive.{key}.{scene}': not among "
                                  f"adaptive.scenes ({', '.join(runs)})")
    for scene, levels in ad.get("patch_test", {}).get("scenes", {}).items():
        if scene not in config.get("scenes", {}):
            raise ConfigError(f"config 'adaptive.patch_test.scenes.{scene}': no such scene; "
                              f"defined: {', '.join(config.get('scenes', {}))}")
        spec = registry[config["scenes"][scene]["problem"]]
        offered = next((p.choices for p in spec.parameters if p.name == "coupling"), None) or ()
        missing = [c for c in ad["patch_test"].get("couplings", ()) if c not in offered]
        if missing:
            raise ConfigError(f"config 'adaptive.patch_test.scenes.{scene}': problem "
                              f"{spec.name!r} does not offer the couplings {missing} "
                              f"(offered: {list(offered)}; a patch-test scene offers every one "
                              "in adaptive.patch_test.couplings)")
        lo, hi = spec.levels
        bad = [lv for lv in levels if not lo <= lv <= hi]
        if bad:
            raise ConfigError(f"config 'adaptive.patch_test.scenes.{scene}': levels {bad} are "
                              f"not allowed; allowed: {lo}..{hi}")


def _check_roll_stack(config: dict, registry: dict) -> None:
    """The roll_stack study: roll-stack scenes, one level each, forces and crowns within
    the problem's ranges, known solvers at valid levels."""
    from problems.spec import ParameterError
    from solvers.interface import solvers

    rs = config.get("roll_stack")
    if not rs:
        return
    for scene, levels in scenes_of(config, "roll_stack").items():
        spec = registry[config["scenes"][scene]["problem"]]
        if spec.name != "roll_stack":
            raise ConfigError(f"config 'roll_stack.scenes.{scene}': problem {spec.name!r} is "
                              "not allowed; allowed: roll_stack")
        if len(levels) != 1:
            raise ConfigError(f"config 'roll_stack.scenes.{scene}': {levels} is not allowed; "
                              "allowed: one level, e.g. [3]")
        params = dict(config["scenes"][scene].get("params") or {})
        for key, name in (("forces", "force"), ("crowns", "crown")):
            for value in rs[key]:
                try:
                    spec.options(**{**params, name: value})
                except ParameterError as err:
                    raise ConfigError(f"config 'roll_stack.{key}': {err}") from None
        lo, hi = spec.levels
        bad = [lv for lv in rs.get("solver_levels", []) if not lo <= lv <= hi]
        if bad:
            raise ConfigError(f"config 'roll_stack.solver_levels': levels {bad} are not "
                              f"allowed; allowed: {lo}..{hi}")
    known = set(solvers()) | {"pdas_kkt"}
    bad = [s for s in rs.get("solvers", []) if s not in known]
    if bad:
        raise ConfigError(f"config 'roll_stack.solvers': {bad} are not allowed; allowed: "
                          f"{', '.join(sorted(known))}")
    if len({f"{f / 1e6:g}" for f in rs["forces"]}) != len(rs["forces"]):
        raise ConfigError("config 'roll_stack.forces': two forces round to the same MN "
                          "(the fields' file names); allowed: distinct values in MN")


def _check_test_set(config: dict) -> None:
    """The test_set study: a known set, its families, registered solvers; every hard case
    a family of the set at a level of the configured classes."""
    from workflows.test_set import TestSetError

    if "test_set" not in config:
        if scenes_of(config, "hard_cases"):
            raise ConfigError("config 'hard_cases': the hard cases are the test set's runs; "
                              "allowed: with a 'test_set' entry")
        return
    cfg = config["test_set"]
    try:
        ts = test_set_of(config)
        ts.problems(families=cfg.get("families") or None)
    except TestSetError as err:
        raise ConfigError(f"config 'test_set': {err}") from None
    chosen = cfg.get("solvers", [])
    if chosen:
        from solvers.interface import solvers
        unknown = sorted(set(chosen) - set(solvers()))
        if unknown:
            raise ConfigError(f"config 'test_set.solvers': {unknown} are not registered; "
                              f"allowed: {', '.join(solvers())}")
    hc = config.get("hard_cases", {})
    run = set(scenes_of(config, "test_set"))
    for family, levels in scenes_of(config, "hard_cases").items():
        have = {p.level for c in cfg["classes"] for p in ts.problems(c, [family])} \
            if family in ts.families else set()
        if family not in run or not set(levels) <= have:
            raise ConfigError(f"config 'hard_cases.scenes.{family}': levels {levels} are not "
                              f"among the test set's runs; allowed: a family of "
                              f"test_set.families at a level of test_set.classes "
                              f"{cfg['classes']}")
    if hc and hc["preset"] not in cfg["presets"]:
        raise ConfigError(f"config 'hard_cases.preset': {hc.get('preset')!r} is not run; "
                          f"allowed: one of test_set.presets {cfg['presets']}")


def log_path(rule: str, name: str = "{scene}") -> str:
    """The log file of a rule's job (``name`` may hold wildcards)."""
    return PATHS["log"].format(rule=rule, name=name)


def bench_path(rule: str, name: str = "{scene}") -> str:
    """The Snakemake benchmark file of a rule's job."""
    return PATHS["benchmark"].format(rule=rule, name=name)


#: The rules whose jobs carry a ``benchmark:`` file and measured ``resources:`` (the
#: heavy ones), and the study each belongs to.
HEAVY_RULES = {
    "laplace_errors": "laplace_nonmatching",
    "contact_level": "contact_solution",
    "solver_comparison": "solver_comparison",
    "augmented_projection_study": "augmented_projection",
    "exact_reference": "exact_reference",
    "test_set_export": "test_set",
    "test_set_runs": "test_set",
    "adaptive_study": "adaptive",
    "patch_test": "adaptive",
    "roll_stack_study": "roll_stack",
    "hard_cases_incompressibility": "hard_cases",
    "element_order_study": "element_order",
}


#: The heavy rules that time solvers, so that nothing may run beside them on the machine.
RUNS_ALONE = frozenset({"solver_comparison", "augmented_projection_study", "exact_reference",
                        "test_set_runs", "adaptive_study", "roll_stack_study",
                        "element_order_study"})

#: "Run alone" as a named resource: the local profile provides ``machine_share=100``
#: and gives every job 1 by default; a rule of :data:`RUNS_ALONE` takes all 100, so
#: Snakemake starts nothing beside it, however many cores it is given. On a cluster
#: (no global share) such a job asks for :data:`ALONE_CPUS` CPUs of its own instead.
MACHINE_SHARE = ("machine_share", 100)
ALONE_CPUS = 2


def rule_resources(config: dict, rule: str) -> dict:
    """``resources:`` of a heavy rule: ``mem_mb`` and ``runtime`` (minutes) from the
    config's ``resources`` section, measured per scale from the rules' benchmark files
    (``check_config`` requires them for every configured study; empty otherwise), and
    for a rule of :data:`RUNS_ALONE` the whole :data:`MACHINE_SHARE` and
    ``cpus_per_task`` (the Slurm executor's CPUs per job)."""
    if rule not in HEAVY_RULES:
        raise KeyError(f"rule {rule!r} is not a heavy rule; allowed: {sorted(HEAVY_RULES)}")
    declared = dict(config.get("resources", {}).get(rule, {}))
    if rule in RUNS_ALONE:
        name, whole = MACHINE_SHARE
        declared.update({name: whole, "cpus_per_task": ALONE_CPUS})
    return declared


def summary_items(config: dict) -> str:
    """Every study output as ``key@scene=path`` arguments of ``report/summary.py``."""
    return " ".join(f"{key}@{scene or '-'}={path}" for study in STUDIES.values()
                    for key, scene, path in study.items(config))


def all_targets(config: dict) -> list[str]:
    """Every study's outputs under ``config`` (the Snakefile's default target)."""
    return [t for study in STUDIES.values() for t in study.targets(config)]
