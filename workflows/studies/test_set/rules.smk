# Study test_set: the contact QP test set (workflows/config/test_sets/<set>.yaml) exported per
# size class, every registered solver on every problem at every preset, and the summary
# over it. Paths: workflows/studies/.
from report.charts import chart_path
import shlex

from workflows.problem_set import CURRENT, PROBLEM_CLASSES
from workflows.studies._base import run_levels
from workflows.studies.test_set import problem_set_runs, warm_starts
TS = config.get("test_set", {})
TS_ID = problem_set_of(config).id if TS else ""
# the set as the config names it: a set of the suite or a set file of your own
TS_NAME = shlex.quote(str(TS.get("name") or CURRENT))
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
        f"{{params.py}} -m workflows.cli export --set {TS_NAME} --class {{wildcards.size_class}} "
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
        f"{{params.py}} -m workflows.studies.test_set.run --set {TS_NAME} "
        "--class {wildcards.size_class} --family {wildcards.scene} --export {input} "
        "--presets {params.presets} --time-limit {params.limit} {params.solvers} "
        "--levels {params.levels} --warm-starts {params.warm} --out {output} > {log} 2>&1"

rule solver_summary:
    input: problem_set_runs(config)
    output:
        summary=shown_table(PATHS["solver_summary"], caption=CAPTIONS["solver_summary"],
            category="solvers", subcategory="test set summary"),
        by_class=shown_table(PATHS["solver_summary_by_class"],
                        caption=CAPTIONS["solver_summary_by_class"],
                        category="solvers", subcategory="test set summary"),
        by_scene=shown_table(PATHS["solver_summary_by_scene"],
                        caption=CAPTIONS["solver_summary_by_scene"],
                        category="solvers", subcategory="test set summary"),
        claims=PATHS["solver_summary_claims"],
        leaderboards=shown_table(PATHS["solver_leaderboards"],
                            caption=CAPTIONS["solver_leaderboards"],
                            category="solvers", subcategory="test set summary"),
        pages=[report(PATHS["solver_leaderboard_page"].format(case=c),
                      caption=CAPTIONS["solver_leaderboard_page"],
                      category="solvers", subcategory="leaderboards")
               for c in PROBLEM_CLASSES],
        warm=shown_table(PATHS["solver_warm_starts"], caption=CAPTIONS["solver_warm_starts"],
                    category="solvers", subcategory="test set summary"),
        facets=shown_table(PATHS["solver_facets"], caption=CAPTIONS["solver_facets"],
                      category="solvers", subcategory="test set summary"),
        profiles=report(PATHS["solver_profiles"], caption=CAPTIONS["solver_profiles"],
                        category="solvers", subcategory="test set summary"),
        charts=report(chart_path(PATHS["solver_profiles"]),
                      caption=CAPTIONS["solver_profiles_chart"],
                      category="solvers", subcategory="test set summary"),
        work=[report(PATHS["solver_work_precision"].format(scene=f),
                     caption=CAPTIONS["solver_work_precision"],
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
        "{params.py} -m report.test_set --inputs {input} --time-limit {params.limit} "
        "--summary {output.summary} --by-class {output.by_class} --by-scene {output.by_scene} "
        "--claims {output.claims} --leaderboards {output.leaderboards} "
        "--pages {params.pages} --scale {params.scale} --load {params.load} "
        "--warm-starts {output.warm} --facets {output.facets} "
        "--profiles {output.profiles} "
        "--charts {output.charts} --work-precision {params.work} > {log} 2>&1"
