# Study friction: Tresca partial slip against Cattaneo-Mindlin, the frictional solvers on the
# same load paths, TNNMG timed against the linear floor, mu = 0 and Coulomb; one process per
# scene, alone on the machine (the study's runs_alone: its time claim compares two timings).
from workflows.studies.friction import friction_args
rule friction_study:
    output:
        runs=PATHS["fr_runs"],
        profiles=PATHS["fr_profiles"]
    log: log_path("friction_study")
    benchmark: bench_path("friction_study")
    resources: **rule_resources(config, "friction_study")
    conda: ENV
    params:
        py=PY, scene=lambda w: set_args(config, w.scene),
        settings=lambda w: friction_args(config, w.scene)
    shell:
        "{params.py} -m workflows.studies.friction.run {params.scene} {params.settings} "
        "--out {output.runs} --profiles {output.profiles} > {log} 2>&1"

rule friction_report:
    input:
        runs=PATHS["fr_runs"],
        profiles=PATHS["fr_profiles"]
    output:
        claims=shown_table(PATHS["fr_claims"], caption=CAPTIONS["fr_claims"],
                      category="{scene}", subcategory="friction"),
        traction=report(PATHS["fr_traction"], caption=CAPTIONS["fr_traction"],
                        category="{scene}", subcategory="friction"),
        stick=report(PATHS["fr_stick"], caption=CAPTIONS["fr_stick"],
                     category="{scene}", subcategory="friction"),
        map=report(PATHS["fr_map"], caption=CAPTIONS["fr_map"],
                   category="{scene}", subcategory="friction"),
        cost=report(PATHS["fr_cost"], caption=CAPTIONS["fr_cost"],
                    category="{scene}", subcategory="friction")
    log: log_path("friction_report")
    conda: ENV
    params: py=PY
    shell:
        "{params.py} -m report.friction --runs {input.runs} --profiles {input.profiles} "
        "--claims {output.claims} --traction {output.traction} --stick {output.stick} "
        "--map {output.map} --cost {output.cost} > {log} 2>&1"
