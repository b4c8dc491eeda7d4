# Study augmented_projection: the thesis's solver (Alg. 8.4) level by level in one process,
# alone on the machine (the study's runs_alone: nothing runs beside it), with
# the multigrid-PCG linear solve as the floor; the thesis's table beside ours.
AP = config.get("augmented_projection", {})

rule augmented_projection_study:
    output: PATHS["ap_study"]
    log: log_path("augmented_projection_study")
    benchmark: bench_path("augmented_projection_study")
    resources: **rule_resources(config, "augmented_projection_study")
    conda: ENV
    params:
        py=PY, scene=lambda w: set_args(config, w.scene),
        levels=lambda w: " ".join(map(str, scenes_of(config, "augmented_projection")[w.scene])),
        configs=" ".join(AP.get("configs", [])), limit=AP["time_limit"]
    shell:
        "{params.py} -m workflows.studies.augmented_projection.run {params.scene} "
        "--levels {params.levels} --configs {params.configs} --time-limit {params.limit} "
        "--kappa-exact --out {output} > {log} 2>&1"

rule augmented_projection_report:
    input: PATHS["ap_study"]
    output:
        table=shown_table(PATHS["ap_table"], caption=CAPTIONS["ap_table"],
            category="{scene}", subcategory="augmented projection"),
        claims=shown_table(PATHS["ap_claims"], caption=CAPTIONS["ap_claims"],
            category="{scene}", subcategory="augmented projection"),
        time=report(PATHS["ap_time"], caption=CAPTIONS["ap_time"],
                    category="{scene}", subcategory="augmented projection"),
        kappa=report(PATHS["ap_kappa"], caption=CAPTIONS["ap_kappa"],
                     category="{scene}", subcategory="augmented projection"),
        tnnmg=report(PATHS["ap_tnnmg"], caption=CAPTIONS["ap_tnnmg"],
                     category="{scene}", subcategory="augmented projection")
    log: log_path("augmented_projection_report")
    conda: ENV
    params:
        py=PY,
        thesis=lambda w: (lambda t: f"--thesis {t}" if t else "")(
            thesis_table(config, w.scene, "augmented_projection"))
    shell:
        "{params.py} -m report.augmented_projection --study {input} {params.thesis} "
        "--table {output.table} --claims {output.claims} --fig-time {output.time} "
        "--fig-kappa {output.kappa} --fig-tnnmg {output.tnnmg} > {log} 2>&1"
