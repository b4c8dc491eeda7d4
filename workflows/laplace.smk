# Non-matching Laplace study (thesis Ch. 6): errors per case and constrained side,
# merged tables with fitted rates, convergence figures and the mesh picture.
LAP = CFG["laplace_nonmatching"]
LAPDIR = "results/laplace_nonmatching"

rule laplace_errors:
    output: f"{LAPDIR}/runs/{{case}}_{{side}}.csv"
    wildcard_constraints: case="sin10x|linear", side="coarse|fine"
    params: levels=" ".join(map(str, LAP["levels"])), ratio=LAP["ratio"]
    shell:
        "{PY} -m workflows.scripts.laplace_errors --case {wildcards.case} "
        "--constrained {wildcards.side} --levels {params.levels} --ratio {params.ratio} --out {output}"

rule laplace_summary:
    input: expand(f"{LAPDIR}/runs/{{case}}_{{side}}.csv", case=["sin10x", "linear"], side=["coarse", "fine"])
    output:
        f"{LAPDIR}/errors.csv", f"{LAPDIR}/errors_by_side.csv", f"{LAPDIR}/rates.csv",
        f"{LAPDIR}/provenance.json"
    params: side=LAP["default_side"]
    shell:
        "{PY} -m workflows.scripts.laplace_summary {input} --default-side {params.side} --outdir {LAPDIR}"

rule laplace_convergence_figure:
    input: errors=f"{LAPDIR}/errors_by_side.csv", rates=f"{LAPDIR}/rates.csv"
    output: f"{LAPDIR}/convergence_{{case}}.png"
    shell:
        "{PY} -m report.laplace convergence --errors {input.errors} --rates {input.rates} "
        "--case {wildcards.case} --out {output}"

rule laplace_mesh_figure:
    output: f"{LAPDIR}/mesh.png"
    params: ratio=LAP["ratio"]
    shell: "{PY} -m report.laplace mesh --level 0 --ratio {params.ratio} --out {output}"
