# The one-page summary at the top of the HTML report: provenance, every checked claim with
# its bar and pass/miss, every thesis table and figure with its output, ours beside the
# thesis's, run time and peak memory per rule. Runs after every study's outputs.

rule summary:
    input: TARGETS
    output:
        html=report(PATHS["summary_html"], caption="../report/captions/summary.rst",
                    category="0 summary", subcategory="summary"),
        claims=shown_table(PATHS["summary_claims"],
                           caption="../report/captions/summary_claims.rst",
                           category="0 summary", subcategory="claims"),
        # the HTML report's landing page (Snakefile: report:)
        landing=PATHS["summary_landing"]
    log: log_path("summary", "all")
    conda: ENV
    params:
        py=PY, outputs=summary_items(config), scale=SCALE,
        bench=os.path.dirname(os.path.dirname(PATHS["benchmark"]))
    shell:
        "{params.py} -m report.summary --items {params.outputs} --benchmarks {params.bench} "
        "--scale {params.scale} --html {output.html} --claims {output.claims} "
        "--landing {output.landing} > {log} 2>&1"

# every table a rule names with shown_table (workflows/table_pages.py) as an HTML page the
# report shows, with the table's caption and place (the report offers a CSV only as a
# download)
for _table, _shown in TABLE_PAGES.items():
    rule:
        name: page_rule(_table)
        input: _table
        output:
            report(page_path(_table), caption=_shown.caption, category=_shown.category,
                   subcategory=_shown.subcategory)
        log: log_path(page_rule(_table), page_log_name(_table))
        conda: ENV
        params: py=PY
        shell: "{params.py} -m report.tables --csv {input} --html {output} > {log} 2>&1"
