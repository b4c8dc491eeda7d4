# Study exact_reference: the suite's exact reference two ways on each configured scene, one
# process, one solve after the other (the study's runs_alone: snakemake runs nothing
# beside it). Paths: workflows/studies/.
from workflows.studies.exact_reference import exact_args

rule exact_reference:
    output: PATHS["exact_runs"]
    log: log_path("exact_reference")
    benchmark: bench_path("exact_reference")
    resources: **rule_resources(config, "exact_reference")
    conda: ENV
    params: py=PY, scene=lambda w: set_args(config, w.scene), levels=lambda w: exact_args(config, w.scene)
    shell:
        "{params.py} -m workflows.studies.exact_reference.run {params.scene} {params.levels} "
        "--out {output} > {log} 2>&1"

rule exact_reference_report:
    input: PATHS["exact_runs"]
    output:
        table=shown_table(PATHS["exact_table"], caption=CAPTIONS["exact_table"],
            category="{scene}", subcategory="exact reference"),
        claims=shown_table(PATHS["exact_claims"], caption=CAPTIONS["exact_claims"],
            category="{scene}", subcategory="exact reference"),
        figure=report(PATHS["exact_figure"], caption=CAPTIONS["exact_figure"],
                      category="{scene}", subcategory="exact reference")
    log: log_path("exact_reference_report")
    conda: ENV
    params: py=PY
    shell:
        "{params.py} -m report.exact_reference --runs {input} --table {output.table} "
        "--claims {output.claims} --figure {output.figure} > {log} 2>&1"
