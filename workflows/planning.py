"""Per-job resources of a scale predicted from measured scaling.

Snakemake writes one benchmark file per heavy job (``results/benchmarks/<rule>/<job>.tsv``:
wall seconds, peak RSS). Given those of runs at two or more scales (say ``quick`` and
``full``) and the target scale's config (``huge``), this fits, per heavy rule, the time
and the memory above the interpreter's floor as ``c N^e`` against the size of the job's
largest problem, and carries each target job on from its scene's largest measured job:

    t_target = t_measured (N_target / N_measured) ** e_time

The size of a job is its scene's finest level in nodes up to a constant,
``2 ** (dim * level)`` (:attr:`problems.spec.ProblemSpec.dim`), the adaptive runs'
node budget, the P2 reference level of the element-order study. The exponent of a rule
is the largest over its scenes measured at two sizes (the two largest), so a rule is
planned by its worst-growing scene. A rule with no scene measured at two sizes borrows
the exponents of the rule that runs the same solves (:data:`PROXY`), and says so.
The declared resources add headroom (x1.5 memory, x2 time, as every scale's
``resources:`` do).

Example::

    python -m workflows.planning \\
        --measured workflows/config/quick.yaml=quick/results/benchmarks \\
                   workflows/config/full.yaml=full/results/benchmarks \\
        --target workflows/config/huge.yaml --out plan.csv
"""
from __future__ import annotations

import argparse
import fnmatch
import math
import sys
from pathlib import Path

import pandas as pd

from workflows.io import write_csv
from workflows.studies import (HEAVY_RULES, STUDIES, load_config, problem_set_of,
                               scenes_of, scenes_with_families)

#: A rule whose own jobs do not change size between the measured scales borrows the
#: exponents of the rule that runs the same kind of solves.
PROXY = {"test_set_runs": "solver_comparison", "test_set_export": "contact_level",
         "hard_cases_incompressibility": "augmented_projection_study",
         "patch_test": "contact_level",
         **{rule: proxy for study in STUDIES.values() for rule, proxy in study.proxies.items()}}

#: Headroom of the declared resources over the prediction.
MEMORY_HEADROOM, TIME_HEADROOM = 1.5, 2.0


def _dim(config: dict, scene: str) -> int:
    from problems.spec import problems

    return problems()[config["scenes"][scene]["problem"]].dim


def _size(config: dict, scene: str, level: int) -> float:
    return 2.0 ** (_dim(config, scene) * level)


def rule_jobs(config: dict, rule: str) -> list[tuple[str, str, float]]:
    """``(benchmark name pattern, scene, size)`` of every job of ``rule`` under
    ``config``; the size is relative within a scene (nodes up to a constant)."""
    study = HEAVY_RULES[rule]
    if study not in config:
        return []
    cfg = config[study]
    if rule == "laplace_errors":
        return [("*", "laplace_nonmatching", 4.0 ** max(cfg["levels"]))]
    if rule in ("contact_level", "solver_comparison"):
        return [(f"{s}_L{lv}", s, _size(config, s, lv))
                for s, levels in scenes_of(config, study).items() for lv in levels]
    if rule == "exact_reference":
        return [(s, s, _size(config, s, max(levels + cfg.get("kkt_levels", {}).get(s, []))))
                for s, levels in scenes_of(config, study).items()]
    if rule == "adaptive_study":
        return [(s, s, float(cfg["max_nodes"][s])) for s in scenes_of(config, study)]
    if rule == "patch_test":
        return [(s, s, _size(config, s, max(lv)))
                for s, lv in cfg.get("patch_test", {}).get("scenes", {}).items()]
    if STUDIES[study].planned_jobs is not None:
        return [(name, s, _size(config, s, level))
                for name, s, level in STUDIES[study].planned_jobs(config, rule)]
    if rule == "hard_cases_incompressibility":
        inc = cfg["incompressibility"]      # one job over all scenes: sized by the 3D one
        scene = max(inc["scenes"], key=lambda s: _dim(config, s))
        return [("all", scene, _size(config, scene, inc["level"]))]
    if rule in ("test_set_runs", "test_set_export"):
        ts, jobs = problem_set_of(config), []
        for c in cfg["classes"]:
            for family in ts.families:
                levels = ts.levels(family, c)
                if levels:
                    name = f"{ts.id}_{c}" + ("" if rule == "test_set_export" else f"_{family}")
                    jobs.append((name, family, _size(config, family, max(levels))))
        return jobs
    return [(s, s, _size(config, s, max(levels)))          # one job per scene, all levels
            for s, levels in scenes_of(config, study).items()]


def read_benchmark(path: Path) -> tuple[float, float]:
    """Wall seconds and peak RSS (MB) of one Snakemake benchmark file."""
    row = pd.read_csv(path, sep="\t").iloc[-1]
    return float(row["s"]), float(row["max_rss"])


def measured_points(measured: list[tuple[dict, Path]], rule: str) -> pd.DataFrame:
    """Every measured job of ``rule``: scale, name, scene, size, seconds, MB."""
    rows = []
    for scale, (config, bench) in enumerate(measured):
        for pattern, scene, size in rule_jobs(config, rule):
            for path in sorted((bench / rule).glob("*.tsv")):
                if fnmatch.fnmatchcase(path.stem, pattern):
                    t, mb = read_benchmark(path)
                    rows.append({"scale": scale, "job": path.stem, "scene": scene,
                                 "size": size, "t": t, "mb": mb})
    return pd.DataFrame(rows, columns=["scale", "job", "scene", "size", "t", "mb"])


def fitted_exponents(points: pd.DataFrame, floor_mb: float) -> tuple[float, float, str] | None:
    """Time and memory exponents in N: per scene between its two largest measured
    sizes (the later scale's measurement where a size was measured twice); the largest
    over the scenes. None without a scene measured at two sizes."""
    best = None
    for scene, g in points.groupby("scene"):
        g = g.sort_values(["size", "scale"]).drop_duplicates("size", keep="last")
        if len(g) < 2:
            continue
        a, b = g.iloc[-2], g.iloc[-1]
        ratio = math.log(b["size"] / a["size"])
        e_t = math.log(max(b["t"], 1e-3) / max(a["t"], 1e-3)) / ratio
        e_m = math.log(max(b["mb"] - floor_mb, 1.0) / max(a["mb"] - floor_mb, 1.0)) / ratio
        if best is None:
            best = [e_t, e_m, []]
        best[0], best[1] = max(best[0], e_t), max(best[1], e_m)
        best[2].append(f"{scene} {a['job']}->{b['job']}")
    return None if best is None else (max(best[0], 0.0), max(best[1], 0.0), "; ".join(best[2]))


def plan(measured: list[tuple[dict, Path]], target: dict,
         floor_mb: float | None = None) -> pd.DataFrame:
    """Per heavy rule of ``target``: the fitted exponents, the largest predicted job
    and the resources to declare (``mem_mb``, ``runtime`` in minutes). Memory grows
    above ``floor_mb`` (the interpreter and its imports; default: the smallest measured
    peak of any job)."""
    measured = [(_with_families(c), bench) for c, bench in measured]
    target = _with_families(target)
    points = {rule: measured_points(measured, rule) for rule in HEAVY_RULES}
    if floor_mb is None:
        floor_mb = float(pd.concat([p for p in points.values() if len(p)])["mb"].min())
    fits = {rule: fitted_exponents(p, floor_mb) for rule, p in points.items() if len(p)}
    rows = []
    for rule in HEAVY_RULES:
        jobs = rule_jobs(target, rule)
        if not jobs:
            continue
        pts = points.get(rule)
        if pts is None or not len(pts):
            raise ValueError(f"rule {rule!r}: no measured benchmark file; allowed: a rule "
                             "the measured scales ran")
        bases = []
        for pattern, scene, size in jobs:
            own = pts[pts["scene"] == scene]
            base = (own if len(own) else pts).sort_values(["size", "scale"]).iloc[-1]
            bases.append((pattern, base, size / base["size"] if len(own) else 1.0))
        fit, basis = fits.get(rule), rule
        if fit is None:
            basis = PROXY.get(rule)
            fit = fits.get(basis)
        if fit is None:
            if any(grow > 1.0 for _, _, grow in bases):
                raise ValueError(f"rule {rule!r}: no scene measured at two sizes and no "
                                 f"measured proxy rule ({basis!r})")
            fit, basis = (0.0, 0.0, "no growth: measured at the target's sizes"), rule
        e_t, e_m, how = fit
        worst = None
        for pattern, base, grow in bases:
            t = base["t"] * max(grow, 1.0) ** e_t
            mb = floor_mb + (base["mb"] - floor_mb) * max(grow, 1.0) ** e_m
            if worst is None or t > worst["t_pred"]:
                worst = {"job": pattern, "from": base["job"], "growth": grow, "t_pred": t}
            worst["mb_pred"] = max(worst.get("mb_pred", 0.0), mb)
        rows.append({"rule": rule, "exponent_time": e_t, "exponent_memory": e_m,
                     "fitted_on": basis if basis == rule else f"{basis} (proxy)",
                     "fit_jobs": how, "largest_job": worst["job"], "from_job": worst["from"],
                     "size_growth": worst["growth"], "t_pred_s": worst["t_pred"],
                     "mb_pred": worst["mb_pred"],
                     "mem_mb": int(math.ceil(MEMORY_HEADROOM * worst["mb_pred"] / 100) * 100),
                     "runtime": max(1, int(math.ceil(TIME_HEADROOM * worst["t_pred"] / 60)))})
    return pd.DataFrame(rows)


def resources_yaml(table: pd.DataFrame) -> str:
    """The ``resources:`` section for the target config, one line per rule."""
    lines = ["resources:   # per heavy rule, its largest job at this scale: memory (MB), wall "
             "time (minutes),",
             "  # predicted from measured scaling by workflows/planning.py "
             "(docs/performance.md)"]
    for r in table.itertuples():
        lines.append(f"  {r.rule}: {{mem_mb: {r.mem_mb}, runtime: {r.runtime}}}   # "
                     f"e_t {r.exponent_time:.2f}, e_mem {r.exponent_memory:.2f} "
                     f"({r.fitted_on}); {r.largest_job} from {r.from_job} x{r.size_growth:g}")
    return "\n".join(lines) + "\n"


def _measured(arg: str) -> tuple[dict, Path]:
    config, sep, bench = arg.partition("=")
    if not sep or not Path(config).is_file() or not Path(bench).is_dir():
        raise argparse.ArgumentTypeError(
            f"{arg!r} is not allowed; allowed: CONFIG.yaml=BENCHMARK_DIR, both existing")
    return _load(config), Path(bench)


def _with_families(config: dict) -> dict:
    """``config`` with the test set's families among its scenes (read once per config)."""
    return {**config, "scenes": scenes_with_families(config)}


def _load(path: str) -> dict:
    return load_config(path)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--measured", nargs="+", type=_measured, required=True,
                    help="CONFIG.yaml=results/benchmarks of a finished run, per scale")
    ap.add_argument("--target", required=True, help="the config to plan (e.g. huge.yaml)")
    ap.add_argument("--out", help="CSV of the plan (written atomically)")
    args = ap.parse_args(argv)
    try:
        table = plan(args.measured, _load(args.target))
    except ValueError as e:
        ap.error(str(e))
    if args.out:
        write_csv(args.out, table)
    sys.stdout.write(resources_yaml(table))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
