# Study hard_cases: every registered solver at one preset on hard variants of the scenes,
# each run in its own process with a hard wall-clock limit. Paths: workflows/studies.py.
HC = config.get("hard_cases", {})

rule hard_case:
    output: PATHS["hard_case_runs"]
    log: log_path("hard_case", "{scene}_L{level}")
    benchmark: bench_path("hard_case", "{scene}_L{level}")
    resources: **rule_resources(config, "hard_case")
    wildcard_constraints: level=r"\d+"
    threads: 2  # timings: nothing else runs beside it
    conda: ENV
    params:
        py=PY, scene=lambda w: set_args(config, w.scene), preset=HC.get("preset", "mid"),
        limit=HC.get("time_limit", 60)
    shell:
        "{params.py} -m workflows.scripts.hard_case --scene {wildcards.scene} {params.scene} "
        "--level {wildcards.level} --preset {params.preset} --time-limit {params.limit} "
        "--out {output} > {log} 2>&1"

rule hard_cases_report:
    input:
        [PATHS["hard_case_runs"].format(scene=s, level=lv)
         for s, levels in scenes_of(config, "hard_cases").items() for lv in levels]
    output:
        table=report(PATHS["hard_table"], caption="../report/captions/hard_table.rst",
            category="hard cases", subcategory="solvers"),
        heatmap=report(PATHS["hard_heatmap"], caption="../report/captions/hard_cases.rst",
                       category="hard cases", subcategory="solvers")
    log: log_path("hard_cases_report", "all")
    conda: ENV
    params: py=PY
    shell:
        "{params.py} -m report.hard_cases --inputs {input} --table {output.table} "
        "--heatmap {output.heatmap} > {log} 2>&1"
