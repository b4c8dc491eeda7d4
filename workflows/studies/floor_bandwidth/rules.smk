# Study floor_bandwidth: the linear floor's V-cycle and PCG step, bytes against time, and one
# core's STREAM triad bandwidth, per scene in one process, alone on the machine (it times).
from workflows.studies.floor_bandwidth import floor_bandwidth_args
rule floor_bandwidth_study:
    output: PATHS["fb_runs"]
    log: log_path("floor_bandwidth_study")
    benchmark: bench_path("floor_bandwidth_study")
    resources: **rule_resources(config, "floor_bandwidth_study")
    conda: ENV
    params:
        py=PY, scene=lambda w: set_args(config, w.scene),
        settings=lambda w: floor_bandwidth_args(config, w.scene)
    shell:
        "{params.py} -m workflows.studies.floor_bandwidth.run {params.scene} {params.settings} "
        "--out {output} > {log} 2>&1"

rule floor_bandwidth_report:
    input: PATHS["fb_runs"]
    output:
        table=shown_table(PATHS["fb_table"], caption=CAPTIONS["fb_table"],
                          category="{scene}", subcategory="floor bandwidth"),
        figure=report(PATHS["fb_figure"], caption=CAPTIONS["fb_figure"],
                      category="{scene}", subcategory="floor bandwidth")
    log: log_path("floor_bandwidth_report")
    conda: ENV
    params: py=PY
    shell:
        "{params.py} -m report.floor_bandwidth --runs {input} --table {output.table} "
        "--figure {output.figure} > {log} 2>&1"
