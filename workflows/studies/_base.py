"""What every study declares, and the scene helpers the studies share.

A study is one folder of :mod:`workflows.studies`, named after it, holding everything of
it: its declaration (``__init__.py``, ``STUDY = Study(...)``: path templates, final
outputs, heavy rules, the thesis items it regenerates, the config checks the JSON schema
cannot make, its claims tables), its config section (``settings.yaml``: the schema, and
its settings and resources per scale), its run steps (``run.py``, ...), its rules
(``rules.smk``), its captions (``captions.rst``) and its page in the docs
(``page.md``); its report step is ``report/<name>.py``. The package discovers the
folders like the registries discover solvers and scenes (:func:`discover_studies`).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable

from workflows.yaml_io import read_yaml

RESULTS = "results"
#: The scales a study declares its config section at (``workflows/config/<scale>.yaml``
#: names one as ``scale:``).
SCALES = ("tiny", "quick", "full", "huge")
#: The thesis's tables (absolute: the workflow may run in another working directory).
REFERENCE = Path(__file__).resolve().parents[2] / "reference"

#: Path templates no single study owns: the summary page and every rule's log and benchmark.
COMMON_PATHS = {
    # the summary page at the top of the report (report/summary.py)
    "summary_html": "results/summary/summary.html",
    "summary_claims": "results/summary/claims.csv",
    "summary_landing": "results/summary/landing.rst",
    # logs and benchmarks of every rule
    "log": "results/logs/{rule}/{name}.log",
    "benchmark": "results/benchmarks/{rule}/{name}.tsv",
}


class ConfigError(ValueError):
    """The workflow configuration is inconsistent (the message says where)."""


@dataclass(frozen=True)
class ThesisItem:
    """A table or figure of the thesis and the output that regenerates it.

    ``key`` is a path key of the study that declares the item (None: not regenerated,
    ``note`` says why); ``problem`` picks the scene (the scene named like the problem).
    """

    item: str
    what: str
    key: str | None
    problem: str | None = None
    note: str = ""


@dataclass(frozen=True)
class AtScale:
    """A study's config section at one scale, and its heavy rules' resources there.

    ``settings`` is the section (validated against the study's ``settings`` schema, which
    fills in its defaults); ``resources`` is ``{heavy rule: {"mem_mb": MB, "runtime":
    minutes}}``, the rule's largest job at this scale as measured, with headroom;
    ``scenes`` the scenes it defines for itself at this scale (``{name: {problem,
    params}}``, joining the config's ``scenes`` where the config has no such name).
    """

    settings: dict
    resources: dict = field(default_factory=dict)
    scenes: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Study:
    """One study: what it shows, the thesis it regenerates, its files and its rules.

    Attributes
    ----------
    name : str
        The study's name: its config section, its page in the docs, ``contactbench study``.
    summary, thesis : str
        What it shows; the thesis items it regenerates.
    order : int
        Its place in the report and in ``contactbench list``.
    paths : dict
        ``{key: path template}`` of every file its rules write ({scene}, {level}, {case}
        wildcards); the keys are unique across studies.
    outputs : tuple of str
        Keys of ``paths``: the final outputs. A template with ``{scene}`` is expanded over
        the scenes the study's config entry lists, one with ``{case}`` over its cases; any
        other is one file (e.g. a table across scenes).
    extra : tuple
        ``(config key, outputs)``: further per-scene outputs for the scenes listed under
        ``config[name][key]["scenes"]`` (e.g. the adaptive study's patch test).
    heavy_rules : tuple of str
        Its rules that carry a benchmark file and measured ``resources:``.
    runs_alone : tuple of str
        Those of them that time solvers, so that nothing may run beside them.
    thesis_items : tuple of ThesisItem
        The thesis's tables and figures it regenerates (the summary page lists them).
    check : callable, optional
        ``check(config, registry)``: what the JSON schema cannot check about its section
        (``config`` with the test set's families among its scenes, ``registry`` the
        problems); raises :class:`ConfigError` naming the config key.
    scripts : dict
        ``{command: module}``: its run steps (modules of its folder) whose ``main(argv)``
        run its heavy steps by hand (``contactbench study COMMAND ...``; the rules call
        the same steps). The first command is the study's name.
    settings : dict, optional
        The JSON schema of its config section (``config[name]``), read from its
        ``settings.yaml`` (:func:`read_settings`); the workflow's schema is assembled from
        the studies' (:func:`workflows.studies.config_schema`).
    scales : dict
        ``{scale: AtScale}``: its config section, resources and own scenes at each scale
        of :data:`SCALES` it runs at, from its ``settings.yaml``; a config naming the
        scale (``scale: quick``) gets them, a setting it gives winning
        (:func:`workflows.studies.at_scale`).
    claims : tuple of str
        Keys of ``paths``: its checked-claims tables (columns claim, measured, bar, pass),
        collected by the summary page.
    planned_jobs : callable, optional
        ``planned_jobs(config, rule) -> [(benchmark name, scene, level)]``: the jobs of a
        heavy rule and the level that sizes each, for the resource plan
        (:mod:`workflows.planning`; default: one job per scene at its finest level).
    proxies : dict
        ``{heavy rule: rule}``: a rule whose jobs keep their size between the measured
        scales borrows the other rule's fitted exponents in the plan.
    cases : callable, optional
        ``cases(config) -> [case]``: what its ``{case}`` outputs run over (default: its
        config section's ``cases``, :func:`cases_of`).
    scenes : callable, optional
        ``scenes(config) -> {scene: levels}``: the scenes it runs (default: its config
        section's ``scenes``; :func:`scenes_of`).
    inline : dict
        ``{path key: columns or None}``: its tables the summary page shows inline, with the
        columns a reader compares (None: all).
    derived_claims : dict
        ``{path key: "module:function"}``: claims the summary page derives from one of its
        tables, by a function of its report step (``function(table) -> claims frame``).
    front : dict
        ``{path key: "module:function"}``: its outputs the summary page's headline shows,
        rendered by a function of the report (``function(table) -> [html]``).
    landing : dict
        ``{path key: "module:function"}``: its outputs the HTML report's landing page shows,
        rendered by a function of the report (``function(table) -> [reStructuredText lines]``).
    notes : dict
        ``{path key: text}``: what a table's columns mean where a name alone would mislead
        (shown under it on the summary page).
    folder : Path
        Its folder (set by the registry when it discovers the study).
    """

    name: str
    summary: str
    thesis: str
    order: int
    paths: dict
    outputs: tuple[str, ...]
    extra: tuple = ()
    heavy_rules: tuple[str, ...] = ()
    runs_alone: tuple[str, ...] = ()
    thesis_items: tuple[ThesisItem, ...] = ()
    check: Callable[[dict, dict], None] | None = None
    scripts: dict = field(default_factory=dict)
    settings: dict | None = None
    scales: dict = field(default_factory=dict)
    claims: tuple[str, ...] = ()
    planned_jobs: Callable[[dict, str], list] | None = None
    proxies: dict = field(default_factory=dict)
    cases: Callable[[dict], list[str]] | None = None
    scenes: Callable[[dict], dict] | None = None
    inline: dict = field(default_factory=dict)
    derived_claims: dict = field(default_factory=dict)
    front: dict = field(default_factory=dict)
    landing: dict = field(default_factory=dict)
    notes: dict = field(default_factory=dict)
    folder: Path | None = None

    def __post_init__(self):
        unknown = sorted(set(self.scales) - set(SCALES))
        if unknown:
            raise ValueError(f"study {self.name!r}: scales {unknown} are not allowed; "
                             f"allowed: {', '.join(SCALES)}")
        if self.scales and self.settings is None:
            raise ValueError(f"study {self.name!r} declares scales but no settings schema")
        undeclared = sorted({rule for at in self.scales.values() for rule in at.resources}
                            - set(self.heavy_rules))
        if undeclared:
            raise ValueError(f"study {self.name!r}: resources of {undeclared}, which are "
                             "not among its heavy_rules")

    def items(self, config: dict) -> list[tuple[str, str | None, str]]:
        """``(path key, scene or None, path)`` of every file this study produces."""
        if self.name not in config:
            return []
        out = []
        for key in self.outputs:
            template = self.paths[key]
            if "{scene}" in template:
                out += [(key, s, template.format(scene=s)) for s in scenes_of(config, self.name)]
            elif "{case}" in template:
                out += [(key, None, template.format(case=c)) for c in self.case_list(config)]
            else:
                out.append((key, None, template))
        for extra, outputs in self.extra:
            scenes = config[self.name].get(extra, {}).get("scenes", {})
            out += [(k, s, self.paths[k].format(scene=s)) for s in scenes for k in outputs]
        return out

    def case_list(self, config: dict) -> list[str]:
        """What the study's ``{case}`` outputs run over under ``config``."""
        return self.cases(config) if self.cases is not None else cases_of(config, self.name)

    def targets(self, config: dict) -> list[str]:
        """The files this study produces under ``config``."""
        return [path for _, _, path in self.items(config)]

    def owns(self, key: str) -> bool:
        """Whether ``key`` is one of this study's outputs (extra outputs included)."""
        return key in self.outputs or any(key in outs for _, outs in self.extra)

    def item_files(self, config: dict, item: ThesisItem) -> list[str]:
        """The files regenerating ``item`` under ``config`` (empty: not at this config)."""
        if item.key is None or self.name not in config:
            return []
        template = self.paths[item.key]
        if "{case}" in template:
            return [template.format(case=c) for c in self.case_list(config)]
        if "{scene}" not in template:
            return [template]
        return [template.format(scene=item.problem)] if item.problem in scenes_of(
            config, self.name) else []


#: A section of a captions file: ``.. caption: KEY [KEY ...]`` on a line of its own (an
#: RST comment), then the caption of those outputs up to the next section.
CAPTION_SECTION = re.compile(r"^\.\. caption: (\w+(?:[ \t]+\w+)*)[ \t]*$", flags=re.M)
#: The suffix of the caption key of an output's interactive chart page
#: (:func:`report.charts.chart_path` of the output ``KEY``: ``KEY_chart``).
CHART = "_chart"


def captions_of(study: Study, folder: Path | None = None) -> dict[str, str]:
    """``{key: caption}`` of the study's ``captions.rst`` (empty if it has none): a key is
    a path key of the study, or one followed by :data:`CHART` (its chart page).

    Raises
    ------
    ValueError
        If a section names a key the study does not declare, or a key twice.
    """
    path = (folder or study.folder) / "captions.rst"
    if not path.is_file():
        return {}
    parts = CAPTION_SECTION.split(path.read_text(encoding="utf-8"))
    heads, bodies = parts[1::2], [body.strip() for body in parts[2::2]]
    keys = [k for head in heads for k in head.split()]
    allowed = set(study.paths) | {k + CHART for k in study.paths}
    wrong = sorted({k for k in keys if k not in allowed} | {k for k in keys
                                                             if keys.count(k) > 1})
    if wrong or parts[0].strip():
        raise ValueError(f"{path}: sections {wrong} are not allowed; allowed: "
                         f"'.. caption: KEY' once per key of {', '.join(study.paths)} (or "
                         f"KEY{CHART}), the first line a section")
    return {k: body for head, body in zip(heads, bodies) for k in head.split()}


def read_settings(folder: Path) -> tuple[dict | None, dict]:
    """A study folder's ``settings.yaml``: the schema of its config section and
    ``{scale: AtScale}`` (``None, {}`` without the file).

    Raises
    ------
    ValueError
        If the file names a scale not in :data:`SCALES` or keys other than ``schema`` and
        ``scales`` (and ``settings``, ``resources``, ``scenes`` per scale).
    """
    path = folder / "settings.yaml"
    if not path.is_file():
        return None, {}
    raw = read_yaml(path.read_text(encoding="utf-8")) or {}
    wrong = sorted(set(raw) - {"schema", "scales"}) + sorted(
        f"scales.{s}" for s in raw.get("scales") or {} if s not in SCALES) + sorted(
        f"scales.{s}.{k}" for s, at in (raw.get("scales") or {}).items()
        for k in at or {} if k not in ("settings", "resources", "scenes"))
    if wrong:
        raise ValueError(f"{path}: keys {wrong} are not allowed; allowed: schema, "
                         f"scales.<{'|'.join(SCALES)}>.<settings|resources|scenes>")
    scales = {s: AtScale(at.get("settings") or {}, at.get("resources") or {},
                         at.get("scenes") or {}) for s, at in (raw.get("scales") or {}).items()}
    return raw.get("schema"), scales


def discover_studies(package: str = "workflows.studies") -> dict[str, Study]:
    """Every study of ``package``: each sub-package (a folder) defining ``STUDY``, with its
    folder, schema and scales (:func:`read_settings`) filled in, ``{name: Study}``.

    Raises
    ------
    RuntimeError
        If a folder's study is named otherwise than the folder, or a study declares its
        settings both in its module and in its folder.
    """
    import importlib
    import pkgutil

    pkg = importlib.import_module(package)
    found = {}
    for info in pkgutil.iter_modules(pkg.__path__):
        if not info.ispkg or info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{package}.{info.name}")
        study = getattr(module, "STUDY", None)
        if study is None:
            continue
        if study.name != info.name:
            raise RuntimeError(f"the study in {package}.{info.name} is named {study.name!r}; "
                               f"allowed: the folder's name, {info.name!r}")
        folder = Path(module.__file__).parent
        schema, scales = read_settings(folder)
        if schema is not None and (study.settings is not None or study.scales):
            raise RuntimeError(f"study {study.name!r} declares its settings in its module and "
                               f"again in {folder / 'settings.yaml'}")
        found[study.name] = replace(study, folder=folder, settings=study.settings or schema,
                                    scales=study.scales or scales)
    global _REGISTRY
    _REGISTRY = found
    return found


#: The discovered studies (:func:`discover_studies`), for :func:`scenes_of`'s hooks.
_REGISTRY: dict[str, Study] = {}


def cases_of(config: dict, study: str) -> list[str]:
    """The cases a study with a ``{case}`` output runs (the Laplace study's right-hand
    sides)."""
    return config[study].get("cases", ["sin10x", "linear"])


def coarser_levels(config: dict, study: str, scene: str, level) -> list[int]:
    """The configured levels of ``scene`` in ``study`` below ``level`` (a study whose jobs
    run coarse to fine, each reading the coarser results)."""
    return [l for l in scenes_of(config, study).get(scene, []) if l < int(level)]


def scenes_of(config: dict, study: str) -> dict[str, list[int]]:
    """``{scene: levels}`` a per-scene study runs: its section's ``scenes``, or what its
    :attr:`Study.scenes` hook says (empty if the study is not configured)."""
    declared = _REGISTRY.get(study)
    if declared is not None and declared.scenes is not None:
        return declared.scenes(config) if study in config else {}
    return dict(config.get(study, {}).get("scenes", {}))


def check_reference_levels(config: dict, study: str, registry: dict) -> None:
    """A study with a common finer reference per scene (``config[study]["reference_level"]``,
    ``{scene: level}``): every scene it names is among the study's scenes, and each scene's
    reference level lies above its levels and within its problem's range."""
    section, runs = config[study], scenes_of(config, study)
    for scene in section["reference_level"]:
        if scene not in runs:
            raise ConfigError(f"config '{study}.reference_level.{scene}': not among "
                              f"{study}.scenes ({', '.join(runs)})")
    for scene, levels in runs.items():
        ref = section["reference_level"].get(scene)
        lo, hi = registry[config["scenes"][scene]["problem"]].levels
        if ref is None or not max(levels) < ref <= hi:
            raise ConfigError(f"config '{study}.reference_level.{scene}': {ref} is not "
                              f"allowed; allowed: a level in {max(levels) + 1}..{hi}")


def problem_set_of(config: dict):
    """The test set the config names (``test_set.name``; the current one by default)."""
    from workflows.problem_set import CURRENT, load

    return load(config.get("test_set", {}).get("name", CURRENT))


def levels_choice(config: dict) -> str:
    """``test_set.levels`` (``all`` or ``smallest``), the schema's default if unset."""
    from workflows.settings import study_defaults

    return config["test_set"].get("levels") or study_defaults("test_set")["levels"]


def run_levels(config: dict, size_class: str, family: str, ts=None) -> list[int]:
    """The levels of ``family`` in ``size_class`` that the test_set study runs: every one,
    or with ``test_set.levels: smallest`` only the smallest (the quick scale's choice:
    one problem per family keeps every family and solver in the quick regeneration).
    ``ts``: the config's test set if the caller has it loaded already."""
    ts = ts or problem_set_of(config)
    levels = sorted({p.level for p in ts.problems(size_class, [family])})
    if levels_choice(config) == "smallest":
        return levels[:1]
    return levels


def scenes_with_families(config: dict) -> dict:
    """``config['scenes']`` with the test set's families added (a family is a scene: the
    studies name the hard cases and variants by it, typed once in the set).

    Raises
    ------
    ConfigError
        If a scene of the config has a family's name but another definition.
    """
    scenes = dict(config.get("scenes") or {})
    for family, entry in problem_set_of(config).families.items():
        entry = {"problem": entry["problem"], **({"params": dict(entry["params"])}
                                                  if entry.get("params") else {})}
        mine = scenes.get(family)
        if mine is not None and ({**mine, "params": dict(mine.get("params") or {})}
                                 != {**entry, "params": entry.get("params", {})}):
            raise ConfigError(f"config 'scenes.{family}': the test set defines this name as "
                              f"{entry}; allowed: another name, or leave it out")
        scenes[family] = entry
    return scenes


def scene_problem(config: dict, scene: str) -> tuple[str, dict]:
    """The registered problem behind a scene and its parameter overrides."""
    entry = config["scenes"][scene]
    return entry["problem"], dict(entry.get("params") or {})


def thesis_table(config: dict, scene: str, study: str) -> str | None:
    """``reference/<table>.csv`` a scene regenerates in ``study``, if it runs with the
    thesis's own parameters (no overrides) and its problem declares one."""
    from problems.spec import problems

    problem, params = scene_problem(config, scene)
    table = problems()[problem].thesis_tables.get(study)
    return str(REFERENCE / f"{table}.csv") if table and not params else None


def set_args(config: dict, scene: str) -> str:
    """Command-line arguments for a scene: ``--problem P --set k=v ...``."""
    problem, params = scene_problem(config, scene)
    sets = " ".join(f"--set {k}={v}" for k, v in params.items())
    return f"--problem {problem} {sets}".strip()


def path_pattern(template: str) -> re.Pattern:
    """A path template (``results/{scene}/x.png``) as a regular expression of its paths,
    for ``fullmatch``: each wildcard a named group of one path component, the path possibly
    under a leading folder."""
    parts = re.split(r"\{(\w+)\}", template)
    return re.compile(r"(?:.*/)?" + "".join(
        re.escape(part) if i % 2 == 0 else f"(?P<{part}>[^/]+)" for i, part in enumerate(parts)))


def log_path(rule: str, name: str = "{scene}") -> str:
    """The log file of a rule's job (``name`` may hold wildcards)."""
    return COMMON_PATHS["log"].format(rule=rule, name=name)


def bench_path(rule: str, name: str = "{scene}") -> str:
    """The Snakemake benchmark file of a rule's job."""
    return COMMON_PATHS["benchmark"].format(rule=rule, name=name)


def check_registered_solvers(config: dict, study: str) -> None:
    """``config[study]['solvers']``, if given, names registered solvers only."""
    chosen = config.get(study, {}).get("solvers", [])
    if chosen:
        from solvers.interface import solvers
        unknown = sorted(set(chosen) - set(solvers()))
        if unknown:
            raise ConfigError(f"config '{study}.solvers': {unknown} are not registered; "
                              f"allowed: {', '.join(solvers())}")
