# Study hard_cases: the hard variants of the scenes are families of the contact QP test
# set; their table and heat map are a view of the test set's runs (workflows/test_set.smk)
# at one preset. Paths: workflows/studies.py.
HC = config.get("hard_cases", {})
HC_FILES, HC_CASES = test_set_hard_cases(config)

rule hard_cases_report:
    input: HC_FILES
    output:
        table=report(PATHS["hard_table"], caption="../report/captions/hard_table.rst",
            category="hard cases", subcategory="solvers"),
        heatmap=report(PATHS["hard_heatmap"], caption="../report/captions/hard_cases.rst",
                       category="hard cases", subcategory="solvers")
    log: log_path("hard_cases_report", "all")
    conda: ENV
    params: py=PY, cases=" ".join(HC_CASES), preset=HC.get("preset", "mid")
    shell:
        "{params.py} -m report.hard_cases --inputs {input} --cases {params.cases} "
        "--preset {params.preset} --table {output.table} --heatmap {output.heatmap} > {log} 2>&1"
