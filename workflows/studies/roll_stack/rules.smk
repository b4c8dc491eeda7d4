# Study roll_stack: the roll stack of thesis Sect. 9.3 (Figs. 9.10-9.16) at one level, both
# strip forces, crowned and cylindrical work rolls, and the solvers on the scene at coarser
# levels; one process (the study's runs_alone: snakemake runs nothing beside it, so the
# recorded times are comparable). Paths: workflows/studies/.
from workflows.studies.roll_stack import roll_args, roll_fields

rule roll_stack_study:
    output:
        runs=PATHS["roll_runs"], profiles=PATHS["roll_profiles"], contact=PATHS["roll_contact"],
        solvers=PATHS["roll_solver_runs"],
        vtu=[PATHS["roll_fields"].replace("{force}", f"{f / 1e6:g}")
             for f in config.get("roll_stack", {}).get("forces", [])]
    log: log_path("roll_stack_study")
    benchmark: bench_path("roll_stack_study")
    resources: **rule_resources(config, "roll_stack_study")
    conda: ENV
    params:
        py=PY, scene=lambda w: set_args(config, w.scene), args=lambda w: roll_args(config, w.scene),
        outdir=lambda w, output: os.path.dirname(output.runs)
    shell:
        "{params.py} -m workflows.studies.roll_stack.run {params.scene} {params.args} "
        "--outdir {params.outdir} > {log} 2>&1"

rule roll_stack_report:
    input:
        runs=PATHS["roll_runs"], profiles=PATHS["roll_profiles"], contact=PATHS["roll_contact"],
        solvers=PATHS["roll_solver_runs"], vtu=lambda w: roll_fields(config, w.scene)
    output:
        table=shown_table(PATHS["roll_table"], caption=CAPTIONS["roll_table"],
                     category="{scene}", subcategory="roll stack"),
        claims=shown_table(PATHS["roll_claims"], caption=CAPTIONS["roll_claims"],
                      category="{scene}", subcategory="roll stack"),
        solver_table=shown_table(PATHS["roll_solver_table"],
                            caption=CAPTIONS["roll_solver_table"],
                            category="{scene}", subcategory="roll stack"),
        pressure=report(PATHS["roll_pressure"], caption=CAPTIONS["roll_pressure"],
                        category="{scene}", subcategory="roll stack"),
        mesh=report(PATHS["roll_mesh"], caption=CAPTIONS["roll_mesh"],
                    category="{scene}", subcategory="roll stack"),
        stress=report(PATHS["roll_stress"], caption=CAPTIONS["roll_stress"],
                      category="{scene}", subcategory="roll stack"),
        line_load=report(PATHS["roll_line_load"], caption=CAPTIONS["roll_line_load"],
                         category="{scene}", subcategory="roll stack"),
        sag=report(PATHS["roll_sag"], caption=CAPTIONS["roll_sag"],
                   category="{scene}", subcategory="roll stack"),
        strip=report(PATHS["roll_strip"], caption=CAPTIONS["roll_strip"],
                     category="{scene}", subcategory="roll stack")
    log: log_path("roll_stack_report")
    conda: ENV
    params: py=PY
    shell:
        "{params.py} -m report.roll_stack --runs {input.runs} --profiles {input.profiles} "
        "--contact {input.contact} --solvers {input.solvers} --vtu {input.vtu} "
        "--table {output.table} --claims {output.claims} --solver-table {output.solver_table} "
        "--pressure-figure {output.pressure} --mesh-figure {output.mesh} "
        "--stress-figure {output.stress} --line-load-figure {output.line_load} "
        "--sag-figure {output.sag} --strip-figure {output.strip} > {log} 2>&1"
