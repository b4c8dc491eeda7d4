# Study laplace_nonmatching (thesis Ch. 6): errors per case and constrained side, merged
# tables with fitted rates, convergence figures and the mesh picture. Paths: workflows/studies/.
LAP = config.get("laplace_nonmatching", {})

rule laplace_errors:
    output: PATHS["laplace_runs"]
    log: log_path("laplace_errors", "{case}_{side}")
    benchmark: bench_path("laplace_errors", "{case}_{side}")
    resources: **rule_resources(config, "laplace_errors")
    wildcard_constraints: case="sin10x|linear", side="coarse|fine"
    conda: ENV
    params: py=PY, levels=" ".join(map(str, LAP.get("levels", []))), ratio=LAP.get("ratio")
    shell:
        "{params.py} -m workflows.studies.laplace_nonmatching.run --case {wildcards.case} "
        "--constrained {wildcards.side} --levels {params.levels} --ratio {params.ratio} "
        "--out {output} > {log} 2>&1"

rule laplace_summary:
    input: expand(PATHS["laplace_runs"], case=["sin10x", "linear"], side=["coarse", "fine"])
    output:
        errors=PATHS["laplace_errors"], by_side=PATHS["laplace_errors_by_side"],
        rates=shown_table(PATHS["laplace_rates"], caption=CAPTIONS["laplace_rates"],
            category="laplace_nonmatching", subcategory="convergence")
    log: log_path("laplace_summary", "all")
    conda: ENV
    params: py=PY, side=LAP.get("default_side")
    shell:
        "{params.py} -m report.laplace_nonmatching tables --inputs {input} --default-side {params.side} "
        "--errors {output.errors} --by-side {output.by_side} --rates {output.rates} > {log} 2>&1"

rule laplace_convergence_figure:
    input: errors=PATHS["laplace_errors_by_side"], rates=PATHS["laplace_rates"]
    output:
        report(PATHS["laplace_convergence"], caption=CAPTIONS["laplace_convergence"],
               category="laplace_nonmatching", subcategory="convergence")
    log: log_path("laplace_convergence_figure", "{case}")
    conda: ENV
    params: py=PY
    shell:
        "{params.py} -m report.laplace_nonmatching convergence --errors {input.errors} --rates {input.rates} "
        "--case {wildcards.case} --out {output} > {log} 2>&1"

rule laplace_mesh_figure:
    output:
        report(PATHS["laplace_mesh"], caption=CAPTIONS["laplace_mesh"],
               category="laplace_nonmatching", subcategory="mesh")
    log: log_path("laplace_mesh_figure", "all")
    conda: ENV
    params: py=PY, ratio=LAP.get("ratio")
    shell: "{params.py} -m report.laplace_nonmatching mesh --level 0 --ratio {params.ratio} --out {output} > {log} 2>&1"
