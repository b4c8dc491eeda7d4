# Study solver_comparison: every registered solver at every preset on identical QPs of
# each configured scene and level, against the exact reference. Paths: workflows/studies/.
from report.charts import chart_path
SC = config.get("solver_comparison", {})

rule solver_comparison:
    # the same scene's coarser levels first: a solver that timed out or failed there is
    # skipped here
    input:
        lambda w: expand(PATHS["solver_runs"], scene=w.scene,
                         level=coarser_levels(config, "solver_comparison", w.scene, w.level))
    output: PATHS["solver_runs"]
    log: log_path("solver_comparison", "{scene}_L{level}")
    benchmark: bench_path("solver_comparison", "{scene}_L{level}")
    resources: **rule_resources(config, "solver_comparison")
    wildcard_constraints: level=r"\d+"
    conda: ENV
    params:
        py=PY, scene=lambda w: set_args(config, w.scene), limit=SC["time_limit"],
        presets=" ".join(SC.get("presets", [])),
        solvers=" ".join(["--solvers", *SC["solvers"]]) if SC.get("solvers") else ""
    shell:
        "{params.py} -m workflows.studies.solver_comparison.run {params.scene} "
        "--level {wildcards.level} --presets {params.presets} --time-limit {params.limit} "
        "--coarser {input} {params.solvers} --out {output} > {log} 2>&1"

rule solver_comparison_report:
    input:
        lambda w: expand(PATHS["solver_runs"], scene=w.scene,
                         level=scenes_of(config, "solver_comparison")[w.scene])
    output:
        table=shown_table(PATHS["solver_table"], caption=CAPTIONS["solver_table"],
            category="{scene}", subcategory="solver comparison"),
        presets=PATHS["solver_presets"],
        times=report(PATHS["solver_times"], caption=CAPTIONS["solver_times"],
                     category="{scene}", subcategory="solver comparison"),
        work=report(PATHS["solver_work"], caption=CAPTIONS["solver_work"],
                    category="{scene}", subcategory="solver comparison"),
        costs=shown_table(PATHS["solver_costs"], caption=CAPTIONS["solver_costs"],
            category="{scene}", subcategory="solver comparison"),
        charts=report(chart_path(PATHS["solver_times"]),
                      caption=CAPTIONS["solver_times_chart"],
                      category="{scene}", subcategory="solver comparison")
    log: log_path("solver_comparison_report")
    conda: ENV
    params: py=PY
    shell:
        "{params.py} -m report.solver_comparison --inputs {input} --table {output.table} "
        "--presets {output.presets} --times {output.times} --work {output.work} "
        "--costs {output.costs} --charts {output.charts} > {log} 2>&1"
