"""The studies the Snakefile regenerates: one folder each, discovered.

A study is one folder of this package, named after it (:mod:`workflows.studies._base`):
its declaration ``STUDY = Study(...)`` in the folder's ``__init__.py`` (what it shows, the
thesis items it regenerates, every path template its rules write, its final outputs, its
heavy rules, the config checks the schema cannot make, its claims tables), its config
section in ``settings.yaml`` (the schema, and its settings and resources per scale), its
run steps, ``rules.smk``, ``captions.rst`` and the docs page ``page.md``; its report step
is ``report/<name>.py``. The package finds the folders like the registries find solvers
and scenes (:func:`workflows.studies._base.discover_studies`) and builds the views the
Snakefile, the config validation, the report, the docs and the command line read: :data:`STUDIES`, :data:`PATHS`, :data:`HEAVY_RULES`,
:data:`RUNS_ALONE`, :data:`THESIS_ITEMS`, :func:`config_schema`, :func:`at_scale`,
:func:`claim_keys`, :func:`caption_files`. A study runs on the scenes its config entry
lists::

    scenes:                                    # a scene = a registered problem + overrides
      circle_square: {problem: circle_square}
      circle_square_stiff: {problem: circle_square, params: {E2: 10.0}}
    solver_comparison:
      scenes: {circle_square: [1, 2, 3], circle_square_stiff: [1, 2]}

so a new scene joins a study by a config line; results land under ``results/<scene>/``.

Importing the package in a job the Snakefile started (``$CONTACTBENCH_CACHE_DIR`` set) keeps
netgen's meshes there (:mod:`workflows.mesh_store`): a run meshes each geometry once.
"""
from __future__ import annotations

import contextlib
import copy
import os
import re
import sys
import tempfile
from pathlib import Path
from types import ModuleType

import yaml

from workflows.settings import SCHEMA
from workflows.yaml_io import read_yaml
from workflows.studies._base import (CHART, COMMON_PATHS, REFERENCE, RESULTS, SCALES, AtScale,
                                     ConfigError, Study, ThesisItem, bench_path, captions_of,
                                     coarser_levels, discover_studies, log_path, path_pattern,
                                     problem_set_of, scene_problem, scenes_of,
                                     scenes_with_families, set_args, thesis_table)

if os.environ.get("CONTACTBENCH_CACHE_DIR"):
    from workflows.mesh_store import keep_meshes_from_environment

    keep_meshes_from_environment()

__all__ = ["ALONE_CPUS", "COMMON_PATHS", "HEAVY_RULES", "MACHINE_SHARE", "PATHS", "REFERENCE",
           "RESULTS", "RUNS_ALONE", "SCALES", "STUDIES", "THESIS_ITEMS", "AtScale", "ConfigError",
           "Study", "ThesisItem", "all_targets", "at_scale", "bench_path", "caption_files", "CHART",
           "captions_of", "check_config", "claim_keys", "coarser_levels", "config_schema",
           "load_config", "log_path", "path_pattern", "problem_set_of", "rule_resources", "scene_problem",
           "scenes_of", "scenes_with_families", "schema_file", "set_args", "study_commands",
           "study_module", "study_of", "summary_items", "thesis_item_files", "thesis_table"]


def _thesis_order(item: ThesisItem) -> tuple[int, int]:
    """Where an item stands in the thesis: (chapter, number) of its first "c.n"."""
    found = re.search(r"(\d+)\.(\d+)", item.item)
    return (int(found[1]), int(found[2])) if found else (99, 0)


def _collect(studies: dict[str, Study]) -> dict[str, str]:
    """Every path template, by key: the common ones and each study's (keys unique)."""
    paths = dict(COMMON_PATHS)
    for study in studies.values():
        clash = sorted(set(study.paths) & set(paths))
        if clash:
            raise RuntimeError(f"study {study.name!r} declares the path keys {clash} again")
        paths.update(study.paths)
    return paths


#: Every study, ``{name: Study}``, in the order of the report.
STUDIES = dict(sorted(discover_studies().items(), key=lambda item: item[1].order))
#: Path templates of every file the workflow writes ({scene}, {level}, {case} wildcards).
PATHS = _collect(STUDIES)
#: The rules whose jobs carry a ``benchmark:`` file and measured ``resources:`` (the
#: heavy ones), and the study each belongs to.
HEAVY_RULES = {rule: s.name for s in STUDIES.values() for rule in s.heavy_rules}
#: The heavy rules that time solvers, so that nothing may run beside them on the machine.
RUNS_ALONE = frozenset(rule for s in STUDIES.values() for rule in s.runs_alone)
#: Every table and figure of the thesis's numerical chapters, and what regenerates it
#: (the summary page lists them with their status), in the thesis's order.
THESIS_ITEMS = tuple(sorted((item for s in STUDIES.values() for item in s.thesis_items),
                            key=_thesis_order))

#: "Run alone" as a named resource: the local profile provides ``machine_share=100``
#: and gives every job 1 by default; a rule of :data:`RUNS_ALONE` takes all 100, so
#: Snakemake starts nothing beside it, however many cores it is given. On a cluster
#: (no global share) such a job asks for :data:`ALONE_CPUS` CPUs of its own instead.
MACHINE_SHARE = ("machine_share", 100)
ALONE_CPUS = 2


def study_commands() -> dict[str, str]:
    """``{command: script module}`` of ``contactbench study COMMAND``: every study's
    scripts (:attr:`Study.scripts`), in the order of the report."""
    found = {}
    for study in STUDIES.values():
        for command, module in study.scripts.items():
            if command in found:
                raise RuntimeError(f"study {study.name!r} declares the command {command!r} "
                                   "again")
            found[command] = module
    return found


def study_module(study: Study) -> ModuleType:
    """The module that declares ``study`` (its folder's ``__init__.py``)."""
    return sys.modules[f"{__name__}.{study.name}"]


def study_of(key: str) -> Study:
    """The study whose outputs include the path key ``key``."""
    return next(s for s in STUDIES.values() if s.owns(key))


def thesis_item_files(config: dict, item: ThesisItem) -> list[str]:
    """The files regenerating ``item`` under ``config`` (empty: not at this config)."""
    if item.key is None:
        return []
    return study_of(item.key).item_files(config, item)


def check_config(config: dict) -> None:
    """What the JSON schema cannot check: every scene a study names is defined, its
    problem is registered, its parameters and levels are valid; then each study's own
    checks (:attr:`Study.check`) and the declared resources of the heavy rules.

    Raises
    ------
    ConfigError
        Naming the config key and what is allowed.
    """
    from problems.spec import contact_scene_error, problems

    config = {**config, "scenes": scenes_with_families(config)}
    registry = problems()
    for scene, entry in config.get("scenes", {}).items():
        wrong = contact_scene_error(entry["problem"], entry.get("params"))
        if wrong is not None:
            raise ConfigError(f"config 'scenes.{scene}.{wrong[0]}': {wrong[1]}")
    for name in STUDIES:
        for scene, levels in scenes_of(config, name).items():
            if scene not in config.get("scenes", {}):
                raise ConfigError(f"config '{name}.scenes.{scene}': no such scene; defined: "
                                  f"{', '.join(config.get('scenes', {}))}")
            lo, hi = registry[config["scenes"][scene]["problem"]].levels
            bad = [lv for lv in levels if not lo <= lv <= hi]
            if bad:
                raise ConfigError(f"config '{name}.scenes.{scene}': levels {bad} are not "
                                  f"allowed; allowed: {lo}..{hi}")
    for study in STUDIES.values():
        if study.check is not None:
            study.check(config, registry)
    unknown = sorted(set(config.get("resources", {})) - set(HEAVY_RULES))
    if unknown:
        raise ConfigError(f"config 'resources.{unknown[0]}': not a heavy rule; allowed: "
                          f"{', '.join(sorted(HEAVY_RULES))}")
    shared = sorted(set(config.get("shared") or ()) - RUNS_ALONE)
    if shared:
        raise ConfigError(f"config 'shared': {shared[0]!r} is not a timing rule; allowed: "
                          f"{', '.join(sorted(RUNS_ALONE))}")
    for rule, study in HEAVY_RULES.items():
        if study in config and not {"mem_mb", "runtime"} <= set(
                config.get("resources", {}).get(rule, {})):
            raise ConfigError(f"config 'resources.{rule}': the study {study!r} runs, so declare "
                              "its measured mem_mb and runtime (minutes)")


def rule_resources(config: dict, rule: str) -> dict:
    """``resources:`` of a heavy rule: ``mem_mb`` and ``runtime`` (minutes) from the
    config's ``resources`` section, measured per scale from the rules' benchmark files
    (``check_config`` requires them for every configured study; empty otherwise), and
    for a rule of :data:`RUNS_ALONE` the whole :data:`MACHINE_SHARE` and
    ``cpus_per_task`` (the Slurm executor's CPUs per job), unless the config's ``shared``
    lets it share the machine at this scale."""
    if rule not in HEAVY_RULES:
        raise KeyError(f"rule {rule!r} is not a heavy rule; allowed: {sorted(HEAVY_RULES)}")
    declared = dict(config.get("resources", {}).get(rule, {}))
    if rule in RUNS_ALONE and rule not in (config.get("shared") or ()):
        name, whole = MACHINE_SHARE
        declared.update({name: whole, "cpus_per_task": ALONE_CPUS})
    return declared


def summary_items(config: dict) -> str:
    """Every study output as ``key@scene=path`` arguments of ``report/summary.py``."""
    return " ".join(f"{key}@{scene or '-'}={path}" for study in STUDIES.values()
                    for key, scene, path in study.items(config))


def all_targets(config: dict) -> list[str]:
    """Every study's outputs under ``config`` (the Snakefile's default target)."""
    return [t for study in STUDIES.values() for t in study.targets(config)]


def config_schema() -> dict:
    """The workflow's config schema: ``workflows/config.schema.yaml`` (what the studies
    share: the scenes, the resources, the shared definitions) with every study's section
    from its folder's ``settings.yaml`` added, and ``scale`` naming one of :data:`SCALES`.

    Raises
    ------
    RuntimeError
        If a study's section is declared both in its folder and in the file.
    """
    with open(SCHEMA, encoding="utf-8") as f:
        schema = read_yaml(f)
    properties = schema["properties"]
    for study in STUDIES.values():
        if study.settings is None:
            continue
        if study.name in properties:
            raise RuntimeError(f"the config section of study {study.name!r} is declared in "
                               f"its folder and again in {SCHEMA.name}")
        properties[study.name] = copy.deepcopy(study.settings)
    properties["scale"] = {"enum": list(SCALES), "description":
                           "the scale whose study sections and resources the studies "
                           "declare (workflows/studies/); a setting the file gives wins"}
    return schema


@contextlib.contextmanager
def schema_file():
    """The path of a temporary file holding :func:`config_schema` (Snakemake validates a
    config against a schema file), removed on leaving."""
    fd, path = tempfile.mkstemp(prefix="contactbench-config-schema-", suffix=".yaml")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            yaml.safe_dump(config_schema(), f, sort_keys=False)
        yield path
    finally:
        os.unlink(path)


def at_scale(config: dict) -> dict:
    """``config`` with the sections, resources and scenes the studies declare at its
    ``scale`` (:attr:`Study.scales`): a key of a study's section the config gives wins over
    the declared one (``solver_comparison: {solvers: [mine, osqp]}`` changes that setting
    alone), as does a rule's resources or a scene it gives (a config without ``scale`` is
    returned as it is)."""
    scale = config.get("scale")
    if scale is None:
        return config
    if scale not in SCALES:
        raise ConfigError(f"config 'scale': {scale!r} is not allowed; allowed: "
                          f"{', '.join(SCALES)}")
    out = copy.deepcopy(config)
    for study in STUDIES.values():
        declared = study.scales.get(scale)
        if declared is None:
            continue
        out[study.name] = {**copy.deepcopy(declared.settings), **config.get(study.name, {})}
        resources = out.setdefault("resources", {})
        for rule, measured in declared.resources.items():
            resources.setdefault(rule, dict(measured))
        scenes = out.setdefault("scenes", {})
        for scene, entry in declared.scenes.items():
            scenes.setdefault(scene, copy.deepcopy(entry))
    return out


def load_config(path) -> dict:
    """A config file as the workflow sees it before validation: the file, then
    :func:`at_scale`."""
    return at_scale(read_yaml(Path(path).read_text(encoding="utf-8")))


def claim_keys() -> tuple[str, ...]:
    """Path keys of every study's checked-claims tables (:attr:`Study.claims`)."""
    return tuple(key for study in STUDIES.values() for key in study.claims)


def caption_files(folder) -> dict[str, str]:
    """``{key: caption file}``: each study's ``captions.rst`` split into one file per output
    under ``folder`` (Snakemake's ``report(..., caption=FILE)`` takes a file)."""
    out = {}
    for study in STUDIES.values():
        for key, text in captions_of(study).items():
            out[key] = os.path.join(folder, f"{key}.rst")
            Path(out[key]).write_text(text + "\n", encoding="utf-8")
    return out
