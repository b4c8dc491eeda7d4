# Study adaptive (thesis Sects. 7.3-7.5): adaptive runs per variant from each scene's start
# level, Tables 9.2/9.4 beside the thesis, Figs. 7.3/7.4, 9.2/9.4/9.7, accuracy per node
# against a common finer reference (2D), the pile-up quantified; and the contact patch test.
# The study times Alg. 8.4 (Tables 9.2/9.4), so it runs alone (the study's runs_alone).
# Paths: workflows/studies/.
from workflows.studies.adaptive import adaptive_args, adaptive_variant_file
AD = config.get("adaptive", {})
AD_VARIANTS = AD.get("variants", [])
AD_FILES = [adaptive_variant_file(v) for v in AD_VARIANTS]


rule adaptive_study:
    output:
        steps=PATHS["adaptive_steps"],
        fields=expand(PATHS["adaptive_fields"], variant=AD_FILES, allow_missing=True),
        surfaces=expand(PATHS["adaptive_surface"], variant=AD_FILES, allow_missing=True)
    log: log_path("adaptive_study")
    benchmark: bench_path("adaptive_study")
    resources: **rule_resources(config, "adaptive_study")
    conda: ENV
    params:
        py=PY, scene=lambda w: set_args(config, w.scene),
        args=lambda w: adaptive_args(config, w.scene)
    shell:
        "{params.py} -m workflows.studies.adaptive.run {params.scene} {params.args} "
        "--steps {output.steps} --fields {output.fields} --surfaces {output.surfaces} "
        "> {log} 2>&1"

rule adaptive_tables:
    input: PATHS["adaptive_steps"]
    output:
        table=shown_table(PATHS["adaptive_table"], caption=CAPTIONS["adaptive_table"],
            category="{scene}", subcategory="adaptive"),
        accuracy=shown_table(PATHS["adaptive_accuracy"], caption=CAPTIONS["adaptive_accuracy"],
            category="{scene}", subcategory="adaptive"),
        pileup=shown_table(PATHS["adaptive_pileup"], caption=CAPTIONS["adaptive_pileup"],
            category="{scene}", subcategory="adaptive"),
        convergence=shown_table(PATHS["adaptive_convergence"], caption=CAPTIONS["adaptive_convergence"],
            category="{scene}", subcategory="adaptive")
    log: log_path("adaptive_tables")
    conda: ENV
    params:
        py=PY,
        thesis=lambda w: (lambda t: f"--thesis {t}" if t else "")(
            thesis_table(config, w.scene, "adaptive"))
    shell:
        "{params.py} -m report.adaptive tables --steps {input} {params.thesis} "
        "--table {output.table} --accuracy {output.accuracy} --pileup {output.pileup} "
        "--convergence {output.convergence} > {log} 2>&1"

rule adaptive_figures:
    input:
        steps=PATHS["adaptive_steps"], accuracy=PATHS["adaptive_accuracy"],
        fields=expand(PATHS["adaptive_fields"], variant=AD_FILES, allow_missing=True),
        surfaces=expand(PATHS["adaptive_surface"], variant=AD_FILES, allow_missing=True)
    output:
        meshes=report(PATHS["adaptive_meshes"], caption=CAPTIONS["adaptive_meshes"],
                      category="{scene}", subcategory="adaptive"),
        snapshot=report(PATHS["adaptive_snapshot"],
                        caption=CAPTIONS["adaptive_snapshot"],
                        category="{scene}", subcategory="adaptive"),
        eta=report(PATHS["adaptive_eta"], caption=CAPTIONS["adaptive_eta"],
                   category="{scene}", subcategory="adaptive"),
        error=report(PATHS["adaptive_error"], caption=CAPTIONS["adaptive_error"],
                     category="{scene}", subcategory="adaptive"),
        pressure=report(PATHS["adaptive_pressure"],
                        caption=CAPTIONS["adaptive_pressure"],
                        category="{scene}", subcategory="adaptive")
    log: log_path("adaptive_figures")
    conda: ENV
    params:
        py=PY, variants=" ".join(f"'{v}'" for v in AD_VARIANTS)
    shell:
        "{params.py} -m report.adaptive figures --steps {input.steps} "
        "--accuracy {input.accuracy} --variants {params.variants} --vtus {input.fields} "
        "--surfaces {input.surfaces} --fig-meshes {output.meshes} "
        "--fig-snapshot {output.snapshot} --fig-eta {output.eta} --fig-error {output.error} "
        "--fig-pressure {output.pressure} > {log} 2>&1"

rule patch_test:
    output: runs=PATHS["patch_runs"], pressure=PATHS["patch_pressure"]
    log: log_path("patch_test")
    benchmark: bench_path("patch_test")
    resources: **rule_resources(config, "patch_test")
    conda: ENV
    params:
        py=PY, scene=lambda w: set_args(config, w.scene),
        levels=lambda w: " ".join(map(str, AD["patch_test"]["scenes"][w.scene])),
        couplings=" ".join(AD.get("patch_test", {}).get("couplings", []))
    shell:
        "{params.py} -m workflows.studies.adaptive.patch_test {params.scene} --levels {params.levels} "
        "--couplings {params.couplings} --out {output.runs} --pressure {output.pressure} "
        "> {log} 2>&1"

rule patch_report:
    input: runs=PATHS["patch_runs"], pressure=PATHS["patch_pressure"]
    output:
        table=shown_table(PATHS["patch_table"], caption=CAPTIONS["patch_table"],
            category="{scene}", subcategory="patch test"),
        figure=report(PATHS["patch_figure"], caption=CAPTIONS["patch_figure"],
                      category="{scene}", subcategory="patch test")
    log: log_path("patch_report")
    conda: ENV
    params: py=PY
    shell:
        "{params.py} -m report.adaptive patch --runs {input.runs} --pressure {input.pressure} "
        "--table {output.table} --figure {output.figure} > {log} 2>&1"
