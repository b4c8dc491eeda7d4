"""Sphinx extension: the pages that are generated from the suite's own objects.

At every build, before Sphinx reads the sources, it writes

* ``generated/scenes/<name>.md``: one page per registered problem
  (:func:`problems.spec.problems`);
* ``generated/solvers/<name>.md``: one page per registered solver
  (:func:`solvers.interface.solvers`), an installed plug-in solver included;
* ``generated/studies/<name>.md``: each study's page, from its folder
  (``workflows/studies/<name>/``): its ``page.md``, then what it regenerates: its thesis
  items, its outputs with the captions the report shows beside them (``captions.rst``),
  the claims its report step checks, its commands; and ``toctree.inc``, the studies'
  table of contents;
* ``generated/cli.md``: the command line, from :func:`workflows.cli.build_parser`;
* ``generated/api/<module>.md``: the API reference of :data:`API_MODULES` (autodoc).

So a page cannot drift from the code: the summary, role, options with defaults and
ranges, presets and the reason a solver skips a problem are read from the registry.
"""
from __future__ import annotations

import argparse
import inspect
import os
import re
import shutil
from pathlib import Path

from workflows.studies._base import CHART

GENERATED = "generated"
#: The modules a user of the suite calls from Python, one API page each.
API_MODULES = ("problems.spec", "problems.qp", "problems.kkt", "problems.friction.data",
               "problems.friction.polygon", "problems.friction.residuals", "solvers.interface",
               "solvers.base", "solvers.certificate", "workflows.problem_set", "workflows.export",
               "workflows.io", "report.claims")


#: The suite's checkout (the rule files and captions the study pages read).
SUITE = Path(__import__("workflows").__file__).resolve().parents[1]


def cell(text) -> str:
    """A Markdown table cell: one line, no bare pipe."""
    return " ".join(str(text).split()).replace("|", "\\|")


def option_rows(parameters, prefix: str = "") -> list[str]:
    """Table rows ``| name | default | allowed | meaning |`` of declared parameters; a
    component's own options follow it as ``name.option``."""
    rows = []
    for p in parameters:
        name = prefix + p.name
        rows.append(f"| `{name}` | `{p.default!r}` | {cell(p.allowed())} | {cell(p.help)} |")
        for kind, options in getattr(p, "kinds", {}).items():
            for q in options:
                rows.append(f"| `{name}.{q.name}` (with `{name}={kind}`) | `{q.default!r}` | "
                            f"{cell(q.allowed())} | {cell(q.help)} |")
    return rows


def options_table(parameters, empty: str) -> list[str]:
    """The options section's table, or ``empty`` when nothing is declared."""
    if not parameters:
        return [empty]
    return ["| option | default | allowed | meaning |", "| --- | --- | --- | --- |",
            *option_rows(parameters)]


def module_doc(module: str) -> list[str]:
    """The module's own docstring, rendered by autodoc (numpydoc)."""
    return ["```{eval-rst}", f".. automodule:: {module}", "   :no-members:", "   :no-index:",
            "```"]


def solver_page(spec, builtin: bool) -> str:
    """One solver's page: summary, role, options, presets, what it skips and why."""
    module = spec.solve.__module__
    origin = "built in" if builtin else "a plug-in (entry-point group `contactbench.solvers`)"
    lines = [f"# `{spec.name}`", "", spec.summary, "",
             f"- role: `{spec.role.value}`",
             f"- module: `{module}` ({origin})",
             f"- default iteration cap: {spec.default_max_iter}",
             "- stabilisation block `C` (Sect. 7.5): "
             + ("taken as it is" if spec.handles_C else "handed over in its slack form"),
             "- friction (Tresca, Coulomb): "
             + ("one Tresca step per solve, the load path run around it "
                "({doc}`/guide/friction`)" if spec.handles_friction
                else "skipped (below)"),
             "", "## Options", "",
             f"Set with `contactbench solve --solver {spec.name} --set NAME=VALUE`, or from "
             "Python as `solve(qp, ...)` keywords.", "",
             *options_table(spec.parameters, "The solver declares no options."), "",
             "## Presets", ""]
    if spec.presets:
        lines += ["| preset | what it means to this solver |", "| --- | --- |",
                  *(f"| `{k}` | {cell(v)} |" for k, v in spec.presets.items())]
    else:
        lines += ["The presets `low`, `mid`, `high` set only the verification's tolerance."]
    lines += ["", "## When it skips a problem", ""]
    if spec.supports is None and spec.size_limit is None:
        lines += ["It takes every contact problem (no `supports` check)."]
    if spec.supports is not None:
        doc = inspect.getdoc(spec.supports)
        lines += [doc if doc else "It checks each problem before running (`supports`); the "
                  "run's row says `skipped` with the reason."]
    if not spec.handles_friction:
        lines += ["", "A problem with friction (Tresca or Coulomb) is `skipped` at once: it "
                  "solves the frictionless problem only"
                  + (f" ({spec.friction_reason})." if spec.friction_reason else ".")]
    for dim, limit in spec.size_parameters.items():
        which = "A problem" if dim is None else f"A {dim}D problem"
        lines += ["", f"{which} with more unknowns than its option `{limit.name}` (default "
                  f"{limit.default:,}) is `skipped` at once, and `--set {limit.name}=N` runs "
                  f"it anyway. The reason: {limit.help}."]
    lines += ["", "## Description and references", "", *module_doc(module), ""]
    return "\n".join(lines)


def scene_page(spec) -> str:
    """One problem's page: summary, kind, levels, parameters, the thesis tables."""
    module = spec.build.__module__
    lines = [f"# `{spec.name}`", "", spec.summary, "",
             f"- kind: `{spec.kind}`" + (" (a contact problem every solver takes)"
                                          if spec.kind == "contact" else
                                          " (no contact: the solvers do not apply)"),
             f"- dimension: {spec.dim}",
             f"- levels: {spec.levels[0]} to {spec.levels[1]} (default {spec.default_level})",
             f"- module: `{module}`"]
    if spec.thesis_tables:
        lines.append("- regenerates: " + ", ".join(
            f"`reference/{table}.csv` in the study `{study}`"
            for study, table in spec.thesis_tables.items()))
    lines += ["", "## Parameters", "",
              f"Set with `contactbench solve --problem {spec.name} --set NAME=VALUE`, or as "
              "`params:` of a scene in a config. Units are SI unless the meaning says "
              "otherwise.", "",
              *options_table(spec.parameters, "The problem declares no parameters."), "",
              "## Description and references", "", *module_doc(module), ""]
    return "\n".join(lines)


def cli_page(parser: argparse.ArgumentParser) -> str:
    """The command line: the help of ``contactbench`` and of each subcommand."""
    lines = ["# Command line", "",
             "Generated from the parser (`workflows.cli.build_parser`). Every failure ends "
             "with exit code 2 and one line naming the parameter and what is allowed; "
             "`--debug` shows the traceback.", "",
             "```text", parser.format_help().rstrip(), "```", ""]
    for action in parser._subparsers._group_actions:
        for name, sub in action.choices.items():
            lines += [f"## `contactbench {name}`", "", "```text", sub.format_help().rstrip(),
                      "```", ""]
    return "\n".join(lines)


def study_facts(study) -> str:
    """What a study regenerates, from its folder: its declaration, rules and captions."""
    import importlib

    from workflows.studies import captions_of

    rules = (study.folder / "rules.smk").read_text(encoding="utf-8")
    captions = captions_of(study)
    modules = sorted(set(re.findall(r"-m (report\.\w+)", rules)))
    lines = ["## What the workflow regenerates", "",
             f"Generated from the study's folder, `workflows/studies/{study.name}/` (its "
             "declaration, `rules.smk` and `captions.rst`).", "",
             f"- thesis: {study.thesis}",
             "- by hand: " + ", ".join(f"`contactbench study {c}`" for c in study.scripts)
             + " (`--help` lists the arguments)",
             "- heavy rules (benchmarked, with measured resources): "
             + (", ".join(f"`{r}`" + (" (runs alone)" if r in study.runs_alone else "")
                          for r in study.heavy_rules) or "none")]
    if study.thesis_items:
        lines += ["", "### The thesis's tables and figures", "",
                  "| thesis | what | output |", "| --- | --- | --- |",
                  *(f"| {cell(i.item)} | {cell(i.what)} | `{study.paths[i.key]}` "
                    f"({i.problem or 'every scene'}) |" for i in study.thesis_items)]
    lines += ["", "### Outputs and how to read them", ""]
    for key, text in captions.items():
        shown = (study.paths[key] if key in study.paths else
                 f"{study.paths[key.removesuffix(CHART)]} (its interactive chart page)")
        lines += [f"**`{shown}`**", "", "```{eval-rst}", text, "```", ""]
    claims = [(name, c) for module in modules
              for name, c in getattr(importlib.import_module(module), "CLAIMS", {}).items()]
    if claims:
        lines += ["### Checked claims", "",
                  "Declared once in " + ", ".join(f"`{m}`" for m in modules) + " (`CLAIMS`); "
                  "the summary page shows each with its measured value and pass or miss.", "",
                  "| claim | source | title | conditions | bar |",
                  "| --- | --- | --- | --- | --- |",
                  *(f"| `{name}` | {cell(c.thesis)} | {cell(c.title)} | {cell(c.details)} | "
                    f"{cell(c.bar_text())} |" for name, c in claims)]
    return "\n".join(lines) + "\n"


def study_page(study) -> str:
    """A study's page: its folder's ``page.md`` (what the thesis says, what the study runs,
    its measurements), then :func:`study_facts`."""
    text = (study.folder / "page.md").read_text(encoding="utf-8").rstrip()
    return text + "\n\n" + study_facts(study)


def study_toctree(studies) -> str:
    """The studies' table of contents, in the order of the report."""
    entries = [f"/{GENERATED}/studies/{name}" for name in studies]
    return "\n".join(["```{toctree}", ":maxdepth: 1", "", *entries, "```", ""])


def api_page(module: str) -> str:
    """One module's API page (autodoc, numpydoc)."""
    return "\n".join([f"# `{module}`", "", "```{eval-rst}", f".. automodule:: {module}",
                      "   :members:", "```", ""])


def index_page(title: str, text: str, folder: str) -> str:
    """A section's page: ``text`` and a globbed table of contents of ``folder``."""
    return "\n".join([f"# {title}", "", text, "", "```{toctree}", ":glob:", ":maxdepth: 1",
                      "", f"{folder}/*", "```", ""])


def write_pages(srcdir: Path) -> None:
    """(Re)write every generated page under ``srcdir/generated``."""
    os.environ.setdefault("COLUMNS", "96")                       # argparse's help width
    from problems.spec import problems
    from solvers.interface import external_solvers, solvers
    from workflows.cli import build_parser

    out = srcdir / GENERATED
    shutil.rmtree(out, ignore_errors=True)
    (out / "scenes").mkdir(parents=True)
    (out / "solvers").mkdir(parents=True)
    (out / "api").mkdir(parents=True)
    (out / "studies").mkdir(parents=True)
    from workflows.studies import STUDIES
    for name, study in STUDIES.items():
        (out / "studies" / f"{name}.md").write_text(study_page(study), encoding="utf-8")
    (out / "studies" / "toctree.inc").write_text(study_toctree(STUDIES), encoding="utf-8")
    for module in API_MODULES:
        (out / "api" / f"{module}.md").write_text(api_page(module), encoding="utf-8")
    plugins = external_solvers()
    for name, spec in solvers().items():
        text = solver_page(spec, builtin=plugins.get(name) is not spec)
        (out / "solvers" / f"{name}.md").write_text(text, encoding="utf-8")
    for name, spec in problems().items():
        (out / "scenes" / f"{name}.md").write_text(scene_page(spec), encoding="utf-8")
    (out / "solvers.md").write_text(index_page(
        "Solvers", "Every registered solver, one page each, generated from its `SolverSpec` "
        "(an installed plug-in solver included). Each solve is verified by the suite: its "
        "status comes from the four KKT residuals and the certified energy bound, never "
        "from the solver's own word.", "solvers"), encoding="utf-8")
    (out / "scenes.md").write_text(index_page(
        "Scenes", "Every registered problem, one page each, generated from its "
        "`ProblemSpec`. A scene of a config is one of these problems with parameter "
        "overrides.", "scenes"), encoding="utf-8")
    (out / "cli.md").write_text(cli_page(build_parser()), encoding="utf-8")


def builder_inited(app) -> None:
    write_pages(Path(app.srcdir))


def setup(app):
    app.connect("builder-inited", builder_inited)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
