# Study coupling (Ch. 6, Sect. 7.5, Prop. 7.6): nodal, stabilised and mortar couplings on a
# contact scene, the energy error against a common mortar_dual reference, Hertz's a and p0;
# one process per scene, every solve exact (no timings are compared).
from workflows.studies.coupling import coupling_args
rule coupling_study:
    output: PATHS["cp_study"]
    log: log_path("coupling_study")
    benchmark: bench_path("coupling_study")
    resources: **rule_resources(config, "coupling_study")
    conda: ENV
    params:
        py=PY, scene=lambda w: set_args(config, w.scene),
        settings=lambda w: coupling_args(config, w.scene)
    shell:
        "{params.py} -m workflows.studies.coupling.run {params.scene} {params.settings} "
        "--out {output} > {log} 2>&1"

rule coupling_report:
    input: PATHS["cp_study"]
    output:
        claims=shown_table(PATHS["cp_claims"], caption=CAPTIONS["cp_claims"],
                      category="{scene}", subcategory="couplings"),
        figure=report(PATHS["cp_figure"], caption=CAPTIONS["cp_figure"],
                      category="{scene}", subcategory="couplings"),
        hertz=report(PATHS["cp_hertz"], caption=CAPTIONS["cp_hertz"],
                     category="{scene}", subcategory="couplings")
    log: log_path("coupling_report")
    conda: ENV
    params: py=PY
    shell:
        "{params.py} -m report.coupling --tables {input} --claims {output.claims} "
        "--figure {output.figure} --hertz-figure {output.hertz} > {log} 2>&1"
