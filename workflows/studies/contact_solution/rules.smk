# Study contact_solution: each scene solved exactly per level, checked against Hertz,
# fields and figures (thesis Sects. 9.1, 9.2). Paths: workflows/studies/.

rule contact_level:
    output:
        contact=PATHS["contact_level"], hertz=PATHS["hertz_level"], vtu=PATHS["fields_level"]
    log: log_path("contact_level", "{scene}_L{level}")
    benchmark: bench_path("contact_level", "{scene}_L{level}")
    resources: **rule_resources(config, "contact_level")
    wildcard_constraints: level=r"\d+"
    conda: ENV
    params:
        py=PY, scene=lambda w: set_args(config, w.scene),
        outdir=lambda w, output: os.path.dirname(output.contact)
    shell:
        "{params.py} -m workflows.studies.contact_solution.run {params.scene} --level {wildcards.level} "
        "--outdir {params.outdir} > {log} 2>&1"

rule contact_hertz_table:
    input:
        lambda w: expand(PATHS["hertz_level"], scene=w.scene,
                         level=scenes_of(config, "contact_solution")[w.scene])
    output:
        shown_table(PATHS["hertz"], caption=CAPTIONS["hertz"],
               category="{scene}", subcategory="contact solution")
    log: log_path("contact_hertz_table")
    conda: ENV
    params: py=PY
    shell: "{params.py} -m report.contact_solution hertz --inputs {input} --out {output} > {log} 2>&1"

rule contact_figures:
    input:
        vtu=lambda w: PATHS["fields_level"].format(
            scene=w.scene, level=max(scenes_of(config, "contact_solution")[w.scene])),
        contacts=lambda w: expand(PATHS["contact_level"], scene=w.scene,
                                  level=scenes_of(config, "contact_solution")[w.scene]),
        hertz=lambda w: expand(PATHS["hertz_level"], scene=w.scene,
                               level=scenes_of(config, "contact_solution")[w.scene])
    output:
        fields=report(PATHS["fields_figure"], caption=CAPTIONS["fields_figure"],
                      category="{scene}", subcategory="contact solution"),
        pressure=report(PATHS["pressure_figure"], caption=CAPTIONS["pressure_figure"],
                        category="{scene}", subcategory="contact solution"),
        surface=report(PATHS["surface_figure"], caption=CAPTIONS["surface_figure"],
                       category="{scene}", subcategory="contact solution")
    log: log_path("contact_figures")
    conda: ENV
    params: py=PY
    shell:
        "({params.py} -m report.contact_solution fields --vtu {input.vtu} --out {output.fields} && "
        "{params.py} -m report.contact_solution surface --vtu {input.vtu} --out {output.surface} && "
        "{params.py} -m report.contact_solution pressure --contacts {input.contacts} "
        "--hertz {input.hertz} --out {output.pressure}) > {log} 2>&1"
