# The one-page summary at the top of the HTML report: provenance, every checked claim with
# its bar and pass/miss, every thesis table and figure with its output, ours beside the
# thesis's, run time and peak memory per rule. Runs after every study's outputs, and writes
# the page of every table a rule names with shown_table (workflows/table_pages.py), which
# the report shows with the table's caption and place (it offers a CSV only as a download):
# all of them in one process, as the last job.

SUMMARY_CLAIMS = shown_table(PATHS["summary_claims"],
                             caption="../report/captions/summary_claims.rst",
                             category="0 summary", subcategory="claims")
SHOWN_PAGES = shown_pages(TARGETS + [SUMMARY_CLAIMS])

rule summary:
    input: TARGETS
    output:
        *[report(page, caption=shown.caption, category=shown.category,
                 subcategory=shown.subcategory) for _, page, shown in SHOWN_PAGES],
        html=report(PATHS["summary_html"], caption="../report/captions/summary.rst",
                    category="0 summary", subcategory="summary"),
        claims=SUMMARY_CLAIMS,
        # the HTML report's landing page (Snakefile: report:)
        landing=PATHS["summary_landing"]
    log: log_path("summary", "all")
    conda: ENV
    params:
        py=PY, outputs=summary_items(config), scale=SCALE,
        bench=os.path.dirname(os.path.dirname(PATHS["benchmark"])),
        tables=[table for table, _, _ in SHOWN_PAGES],
        pages=[page for _, page, _ in SHOWN_PAGES]
    shell:
        "{params.py} -m report.summary --items {params.outputs} --benchmarks {params.bench} "
        "--scale {params.scale} --html {output.html} --claims {output.claims} "
        "--landing {output.landing} > {log} 2>&1 && "
        "{params.py} -m report.tables --csv {params.tables} --html {params.pages} >> {log} 2>&1"
