# Study test_set: the contact QP test set (workflows/config/test_sets/<set>.yaml) exported per
# size class, every registered solver on every problem at every preset, and the summary
# over it. Paths: workflows/studies/.
from report.charts import chart_path
from workflows.problem_set import PROBLEM_CLASSES
from workflows.studies.problem_set import problem_set_runs, run_levels, warm_starts
TS = config.get("test_set", {})
TS_ID = problem_set_of(config).id if TS else ""
TS_FAMILIES = list(scenes_of(config, "test_set"))

rule test_set_export:
    output: directory(PATHS["test_set_export"])
    log: log_path("test_set_export", "{set}_{size_class}")
    benchmark: bench_path("test_set_export", "{set}_{size_class}")
    resources: **rule_resources(config, "test_set_export")
    conda: ENV
    params:
        py=PY,
        families=" ".join(["--families", *TS["families"]]) if TS.get("families") else ""
    shell:
        "{params.py} -m workflows.cli export --set {wildcards.set} --class {wildcards.size_class} "
        "{params.families} --out {output} --quiet > {log} 2>&1"

rule test_set_runs:
    input: PATHS["test_set_export"]
    output: PATHS["test_set_runs"]
    log: log_path("test_set_runs", "{set}_{size_class}_{scene}")
    benchmark: bench_path("test_set_runs", "{set}_{size_class}_{scene}")
    resources: **rule_resources(config, "test_set_runs")
    conda: ENV
    params:
        py=PY, presets=" ".join(TS.get("presets", [])), limit=TS.get("time_limit"),
        solvers=" ".join(["--solvers", *TS["solvers"]]) if TS.get("solvers") else "",
        levels=lambda w: " ".join(map(str, run_levels(config, w.size_class, w.scene))),
        warm=warm_starts(config) if TS else ""
    shell:
        "{params.py} -m workflows.scripts.problem_set_runs --set {wildcards.set} "
        "--class {wildcards.size_class} --family {wildcards.scene} --export {input} "
        "--presets {params.presets} --time-limit {params.limit} {params.solvers} "
        "--levels {params.levels} --warm-starts {params.warm} --out {output} > {log} 2>&1"

rule solver_summary:
    input: problem_set_runs(config)
    output:
        summary=report(PATHS["solver_summary"], caption="../report/captions/solver_summary_table.rst",
            category="solvers", subcategory="test set summary"),
        by_class=report(PATHS["solver_summary_by_class"],
                        caption="../report/captions/solver_summary_table.rst",
                        category="solvers", subcategory="test set summary"),
        by_scene=report(PATHS["solver_summary_by_scene"],
                        caption="../report/captions/solver_summary_table.rst",
                        category="solvers", subcategory="test set summary"),
        claims=PATHS["solver_summary_claims"],
        leaderboards=report(PATHS["solver_leaderboards"],
                            caption="../report/captions/solver_leaderboards.rst",
                            category="solvers", subcategory="test set summary"),
        pages=[report(PATHS["solver_leaderboard_page"].format(case=c),
                      caption="../report/captions/solver_leaderboards.rst",
                      category="solvers", subcategory="leaderboards")
               for c in PROBLEM_CLASSES],
        warm=report(PATHS["solver_warm_starts"], caption="../report/captions/solver_warm_starts.rst",
                    category="solvers", subcategory="test set summary"),
        facets=report(PATHS["solver_facets"], caption="../report/captions/solver_facets.rst",
                      category="solvers", subcategory="test set summary"),
        profiles=report(PATHS["solver_profiles"], caption="../report/captions/solver_profiles.rst",
                        category="solvers", subcategory="test set summary"),
        charts=report(chart_path(PATHS["solver_profiles"]),
                      caption="../report/captions/solver_summary_charts.rst",
                      category="solvers", subcategory="test set summary"),
        work=[report(PATHS["solver_work_precision"].format(scene=f),
                     caption="../report/captions/solver_work_precision.rst",
                     category="solvers", subcategory="work-precision per family")
              for f in TS_FAMILIES]
    log: log_path("solver_summary", "all")
    conda: ENV
    params:
        py=PY, limit=TS.get("time_limit"), scale=config.get("scale", "?"),
        load="shared" if "test_set_runs" in config.get("shared", []) else "alone",
        pages=" ".join(f"{c}={PATHS['solver_leaderboard_page'].format(case=c)}"
                       for c in PROBLEM_CLASSES),
        work=" ".join(f"{f}={PATHS['solver_work_precision'].format(scene=f)}"
                      for f in TS_FAMILIES)
    shell:
        "{params.py} -m report.solver_summary --inputs {input} --time-limit {params.limit} "
        "--summary {output.summary} --by-class {output.by_class} --by-scene {output.by_scene} "
        "--claims {output.claims} --leaderboards {output.leaderboards} "
        "--pages {params.pages} --scale {params.scale} --load {params.load} "
        "--warm-starts {output.warm} --facets {output.facets} "
        "--profiles {output.profiles} "
        "--charts {output.charts} --work-precision {params.work} > {log} 2>&1"
