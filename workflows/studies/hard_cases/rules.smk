# Study hard_cases: the hard variants of the scenes are families of the contact QP test
# set; their table and heat map are a view of the test set's runs (workflows/studies/test_set/rules.smk)
# at one preset. Paths: workflows/studies/.
from workflows.studies.hard_cases import hard_case_runs
HC = config.get("hard_cases", {})
HC_FILES, HC_CASES = hard_case_runs(config)

rule hard_cases_report:
    input: HC_FILES
    output:
        table=shown_table(PATHS["hard_table"], caption=CAPTIONS["hard_table"],
            category="hard cases", subcategory="solvers"),
        heatmap=report(PATHS["hard_heatmap"], caption=CAPTIONS["hard_heatmap"],
                       category="hard cases", subcategory="solvers")
    log: log_path("hard_cases_report", "all")
    conda: ENV
    params: py=PY, cases=" ".join(HC_CASES), preset=HC["preset"]
    shell:
        "{params.py} -m report.hard_cases table --inputs {input} --cases {params.cases} "
        "--preset {params.preset} --table {output.table} --heatmap {output.heatmap} > {log} 2>&1"

HCI = HC.get("incompressibility", {})

rule hard_cases_incompressibility:
    output: PATHS["hard_nu_runs"]
    log: log_path("hard_cases_incompressibility", "all")
    benchmark: bench_path("hard_cases_incompressibility", "all")
    resources: **rule_resources(config, "hard_cases_incompressibility")
    conda: ENV
    params:
        py=PY, scenes=" ".join(HCI.get("scenes", [])), level=HCI.get("level"),
        nus=" ".join(f"{v:g}" for v in HCI.get("nus", [])), time_limit=HCI.get("time_limit")
    shell:
        "{params.py} -m workflows.studies.hard_cases.run --scenes {params.scenes} "
        "--level {params.level} --nus {params.nus} --time-limit {params.time_limit} "
        "--out {output} > {log} 2>&1"

rule hard_cases_incompressibility_report:
    input: PATHS["hard_nu_runs"]
    output:
        claims=shown_table(PATHS["hard_nu_claims"], caption=CAPTIONS["hard_nu_claims"],
                      category="hard cases", subcategory="incompressibility"),
        figure=report(PATHS["hard_nu_figure"], caption=CAPTIONS["hard_nu_figure"],
                      category="hard cases", subcategory="incompressibility")
    log: log_path("hard_cases_incompressibility_report", "all")
    conda: ENV
    params: py=PY
    shell:
        "{params.py} -m report.hard_cases incompressibility --table {input} "
        "--claims {output.claims} "
        "--figure {output.figure} > {log} 2>&1"

HCR = HC.get("random_friction", {})

rule hard_cases_random_friction:
    output: PATHS["hard_rf_runs"]
    log: log_path("hard_cases_random_friction", "all")
    benchmark: bench_path("hard_cases_random_friction", "all")
    resources: **rule_resources(config, "hard_cases_random_friction")
    conda: ENV
    params:
        py=PY, first=HCR.get("first"), draws=HCR.get("draws"), level=HCR.get("level"),
        preset=HC.get("preset"), time_limit=HCR.get("time_limit"),
        solvers=(" --solvers " + " ".join(HCR["solvers"])) if HCR.get("solvers") else ""
    shell:
        "{params.py} -m workflows.studies.hard_cases.random_friction --first {params.first} "
        "--draws {params.draws} --level {params.level} --preset {params.preset}"
        "{params.solvers} --time-limit {params.time_limit} --out {output} > {log} 2>&1"

rule hard_cases_random_friction_report:
    input: PATHS["hard_rf_runs"]
    output:
        claims=shown_table(PATHS["hard_rf_claims"], caption=CAPTIONS["hard_rf_claims"],
                           category="hard cases", subcategory="random friction")
    log: log_path("hard_cases_random_friction_report", "all")
    conda: ENV
    params: py=PY
    shell:
        "{params.py} -m report.hard_cases random-friction --table {input} "
        "--claims {output.claims} > {log} 2>&1"
