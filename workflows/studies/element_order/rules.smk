# Study element_order (Remark 7.11): P1 against P2 on a contact scene, the energy error
# against a common P2 reference per unknown and per second, Alg. 8.4 on P2; one process
# per scene, alone on the machine (its solve times are the figure's abscissa).
from workflows.studies.element_order import element_order_args
rule element_order_study:
    output: PATHS["eo_study"]
    log: log_path("element_order_study")
    benchmark: bench_path("element_order_study")
    resources: **rule_resources(config, "element_order_study")
    conda: ENV
    params:
        py=PY, scene=lambda w: set_args(config, w.scene),
        settings=lambda w: element_order_args(config, w.scene)
    shell:
        "{params.py} -m workflows.studies.element_order.run {params.scene} {params.settings} "
        "--out {output} > {log} 2>&1"

rule element_order_report:
    input: PATHS["eo_study"]
    output:
        claims=shown_table(PATHS["eo_claims"], caption=CAPTIONS["eo_claims"],
                      category="{scene}", subcategory="P1 against P2"),
        figure=report(PATHS["eo_figure"], caption=CAPTIONS["eo_figure"],
                      category="{scene}", subcategory="P1 against P2")
    log: log_path("element_order_report")
    conda: ENV
    params: py=PY
    shell:
        "{params.py} -m report.element_order --tables {input} --claims {output.claims} "
        "--figure {output.figure} > {log} 2>&1"
