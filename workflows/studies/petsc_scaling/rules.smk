# Study petsc_scaling: petsc_tao under MPI at each configured number of ranks and TNNMG in
# one process on the same problems, per scene; one job per scene, alone on the machine (it
# times solvers), asking for the ranks as MPI tasks (workflows/studies/petsc_scaling/__init__.py).
from workflows.studies.petsc_scaling import mpi_resources, petsc_scaling_args
rule petsc_scaling_study:
    output:
        runs=PATHS["ps_runs"],
        facts=PATHS["ps_facts"]
    log: log_path("petsc_scaling_study")
    benchmark: bench_path("petsc_scaling_study")
    resources: **{**rule_resources(config, "petsc_scaling_study"), **mpi_resources(config)}
    conda: ENV
    params:
        py=PY, scene=lambda w: set_args(config, w.scene),
        settings=lambda w: petsc_scaling_args(config, w.scene),
        launcher=lambda w: config["petsc_scaling"]["launcher"]
    shell:
        "CONTACTBENCH_MPIEXEC={params.launcher} "
        "{params.py} -m workflows.studies.petsc_scaling.run {params.scene} {params.settings} "
        "--out {output.runs} --claims {output.facts} > {log} 2>&1"

rule petsc_scaling_report:
    input: PATHS["ps_runs"]
    output:
        claims=shown_table(PATHS["ps_claims"], caption=CAPTIONS["ps_claims"],
                      category="{scene}", subcategory="PETSc strong scaling"),
        figure=report(PATHS["ps_figure"], caption=CAPTIONS["ps_figure"],
                      category="{scene}", subcategory="PETSc strong scaling")
    log: log_path("petsc_scaling_report")
    conda: ENV
    params: py=PY
    shell:
        "{params.py} -m report.petsc_scaling --runs {input} --scene {wildcards.scene} "
        "--claims {output.claims} "
        "--figure {output.figure} > {log} 2>&1"
