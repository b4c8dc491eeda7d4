# Circle-square scene (thesis Sect. 9.1): exact solve per level checked against Hertz,
# fields and figures; every QP solver at every tolerance preset against the exact reference.
CS = CFG["circle_square"]
CSDIR = "results/circle_square"

rule circle_square_level:
    output:
        contact=f"{CSDIR}/contact_L{{level}}.csv", hertz=f"{CSDIR}/hertz_L{{level}}.csv",
        vtu=f"{CSDIR}/fields_L{{level}}.vtu"
    wildcard_constraints: level=r"\d+"
    shell: "{PY} -m workflows.scripts.circle_square_contact --level {wildcards.level} --outdir {CSDIR}"

rule circle_square_hertz_table:
    input: expand(f"{CSDIR}/hertz_L{{level}}.csv", level=CS["levels"])
    output: f"{CSDIR}/hertz.csv"
    run:
        import pandas as pd
        from workflows.io import write_csv
        write_csv(output[0], pd.concat([pd.read_csv(f) for f in input]).sort_values("level"))

rule circle_square_figures:
    input:
        vtu=f"{CSDIR}/fields_L{max(CS['levels'])}.vtu",
        contacts=expand(f"{CSDIR}/contact_L{{level}}.csv", level=CS["levels"]),
        hertz=expand(f"{CSDIR}/hertz_L{{level}}.csv", level=CS["levels"])
    output: fields=f"{CSDIR}/fields.png", pressure=f"{CSDIR}/pressure.png"
    shell:
        "{PY} -m report.circle_square fields --vtu {input.vtu} --out {output.fields} && "
        "{PY} -m report.circle_square pressure --contacts {input.contacts} --hertz {input.hertz} "
        "--out {output.pressure}"

rule solver_comparison:
    output: f"{CSDIR}/solvers_L{{level}}.csv"
    wildcard_constraints: level=r"\d+"
    threads: 2  # timings: nothing else runs beside it
    params: limit=CS["time_limit"]
    shell:
        "{PY} -m workflows.scripts.solver_comparison --level {wildcards.level} "
        "--time-limit {params.limit} --out {output}"

rule solver_comparison_report:
    input: expand(f"{CSDIR}/solvers_L{{level}}.csv", level=CS["solver_levels"])
    output:
        table=f"{CSDIR}/solvers.csv", presets=f"{CSDIR}/solver_presets.csv",
        times=f"{CSDIR}/solver_times.png", work=f"{CSDIR}/solver_error_vs_time.png"
    shell:
        "{PY} -m report.solvers --inputs {input} --table {output.table} --presets {output.presets} "
        "--times {output.times} --work {output.work}"

# Alg. 8.4 complexity study: all levels in one process, alone on the machine (threads:
# 2 keeps snakemake from running anything beside it), so timings are side by side.
rule augmented_projection_study:
    output: f"{CSDIR}/augmented_projection_study.csv"
    threads: 2
    params:
        levels=" ".join(map(str, CS["ap_levels"])), configs=" ".join(CS["ap_configs"]),
        limit=CS["time_limit"]
    shell:
        "{PY} -m workflows.scripts.augmented_projection_study --levels {params.levels} "
        "--configs {params.configs} --time-limit {params.limit} --kappa-exact --out {output}"

rule table_9_1:
    input: f"{CSDIR}/augmented_projection_study.csv"
    output:
        table=f"{CSDIR}/table_9_1.csv", claims=f"{CSDIR}/claims_ch8.csv",
        fig91=f"{CSDIR}/fig_9_1_time.png", fig93=f"{CSDIR}/fig_9_3_kappa.png"
    shell:
        "{PY} -m report.augmented_projection --study {input} --table {output.table} "
        "--claims {output.claims} --fig91 {output.fig91} --fig93 {output.fig93}"
