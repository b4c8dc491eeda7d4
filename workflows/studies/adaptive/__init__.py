"""Adaptive refinement by eta_1 and eta_1 + eta_2 (thesis Sects. 7.3-7.5), and the contact
patch test on non-matching meshes."""
from workflows.studies._base import ConfigError, Study, ThesisItem, scenes_of

def adaptive_variant_file(variant: str) -> str:
    """The ``{variant}`` of an adaptive output path: ``eta1+eta2`` -> ``eta1_eta2``."""
    return variant.replace("+", "_")


def adaptive_args(config: dict, scene: str) -> str:
    """A scene's settings of the adaptive study as arguments of
    ``workflows/studies/adaptive/run.py`` (start level, node budget, marking and its minimum share, the
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


def check(config: dict, registry: dict) -> None:
    """Known variants, one start level per scene, every per-scene
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


STUDY = Study(
    name="adaptive",
    summary="adaptive refinement by eta_1 and eta_1 + eta_2 (Sect. 7.4): the thesis's "
            "adaptive tables beside its values, meshes near the contact, max eta_T "
            "against N, accuracy per node against a common finer reference (energy, "
            "force, Hertz), the hanging-node pile-up quantified, Sect. 7.3 rates; the "
            "contact patch test on non-matching meshes",
    thesis="Sects. 7.3-7.5, Tables 9.2/9.4, Figs. 7.3-7.5, 9.2, 9.4, 9.7",
    order=80,
    scripts={"adaptive": "workflows.studies.adaptive.run",
             "patch_test": "workflows.studies.adaptive.patch_test"},
    paths={
        # runs per variant, accuracy against a common refinement (Sect. 7.4)
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
        # the contact patch test
        "patch_runs": "results/{scene}/patch_test_runs.csv",
        "patch_pressure": "results/{scene}/patch_test_pressure.csv",
        "patch_table": "results/{scene}/patch_test.csv",
        "patch_figure": "results/{scene}/patch_test.png",
    },
    outputs=("adaptive_table", "adaptive_accuracy", "adaptive_pileup", "adaptive_convergence",
             "adaptive_meshes", "adaptive_snapshot", "adaptive_eta", "adaptive_error",
             "adaptive_pressure"),
    extra=(("patch_test", ("patch_table", "patch_figure")),),
    heavy_rules=("adaptive_study", "patch_test"),
    runs_alone=("adaptive_study",),
    thesis_items=(
        ThesisItem("Figs. 7.3/7.4", "adaptive meshes by eta_1 and eta_1 + eta_2 (pile-up)",
                   "adaptive_meshes", "circle_square"),
        ThesisItem("Fig. 7.5", "mesh by stabilised two-sided nodal constraints and eta_1",
                   "adaptive_meshes", "circle_square"),
        ThesisItem("(7.8)", "convergence rates under uniform refinement, O(h^1/2)",
                   "adaptive_convergence", "circle_square"),
        ThesisItem("Table 9.2", "circle-square, adaptive (eta_1 + eta_2)", "adaptive_table",
                   "circle_square"),
        ThesisItem("Fig. 9.2", "circle-square: max eta_T against N", "adaptive_eta",
                   "circle_square"),
        ThesisItem("Fig. 9.4", "adaptive mesh snapshot (2D view)", "adaptive_snapshot",
                   "circle_square"),
        ThesisItem("Table 9.4", "cube-sphere, adaptive (eta_1 + eta_2)", "adaptive_table",
                   "cube_sphere"),
        ThesisItem("Fig. 9.7", "cube-sphere: max eta_T against N", "adaptive_eta", "cube_sphere"),
        ThesisItem("Fig. 9.9", "cube-sphere: contact surface mesh of the adaptive run",
                   "adaptive_snapshot", "cube_sphere"),
    ),
    check=check,
    inline={"adaptive_table": ("source", "step", "N", "NC", "n_outer_1e-03",
                               "n_inner_mean_1e-03", "t_solve_1e-03", "t_proj_1e-03", "kappa_S",
                               "kkt_max")},
    derived_claims={"adaptive_accuracy": "report.adaptive:accuracy_claims",
                    "adaptive_pileup": "report.adaptive:pileup_claims",
                    "patch_table": "report.adaptive:patch_claims"},
)
