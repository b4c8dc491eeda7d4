"""The documentation site builds with warnings as errors, and its scene, solver and
command-line pages come from the code: every registered problem and solver has its page,
an installed plug-in solver included (the example package of ``conftest.py``).

The site is built from a copy of ``docs/`` into a temporary folder (the generated pages are
written beside the sources at build time), in a subprocess that sees the plug-in.
"""
from __future__ import annotations

import html
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from problems.spec import problems
from solvers.interface import solvers

DOCS = Path(__file__).resolve().parents[1] / "docs"


@pytest.fixture(scope="module")
def site(plugin_env, tmp_path_factory) -> Path:
    """The built site (HTML) of a user who has installed the example solver."""
    source = tmp_path_factory.mktemp("docs") / "docs"
    shutil.copytree(DOCS, source, ignore=shutil.ignore_patterns("_build", "generated"))
    out = tmp_path_factory.mktemp("html")
    done = subprocess.run([sys.executable, "-m", "sphinx", "-b", "html", "-W", "--keep-going",
                           "-q", str(source), str(out)], capture_output=True, text=True,
                          env=plugin_env, timeout=600)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-5000:]
    return out


def text_of(page: Path) -> str:
    return page.read_text(encoding="utf-8")


def plain_text_of(page: Path) -> str:
    """The page's text without its tags and entities, whitespace collapsed."""
    text = html.unescape(re.sub(r"<[^>]+>", "", text_of(page)))
    return " ".join(text.split())


@pytest.mark.slow
def test_every_registered_solver_and_scene_has_its_generated_page(site):
    solver_pages = {p.stem for p in (site / "generated" / "solvers").glob("*.html")}
    assert solver_pages == set(solvers()) | {"dual_bb"}       # the plug-in joins the built-ins
    scene_pages = {p.stem for p in (site / "generated" / "scenes").glob("*.html")}
    assert scene_pages == set(problems())
    # a page says what its spec says: the summary, the role, each option with its range
    spec = solvers()["augmented_projection"]
    page = text_of(site / "generated" / "solvers" / "augmented_projection.html")
    assert spec.role.value in page and "Alg. 8.4" in page
    declared = [*spec.parameters,
                *(q for p in spec.parameters for kind in getattr(p, "kinds", {}).values()
                  for q in kind)]
    assert len(declared) > 10
    for p in declared:
        assert f'<span class="pre">{p.name}' in page or f"{p.name}</span>" in page, p.name
        assert p.allowed() in page, p.allowed()
    # a size limit is on the page with its default and its reason
    highs = plain_text_of(site / "generated" / "solvers" / "highs.html")
    assert "max_unknowns (default 2,000) is skipped at once" in highs
    assert "qp_nullspace_limit of 4000" in highs
    # a QP library takes a 2D Tresca step and says why it skips a 3D one
    assert "friction (Tresca, Coulomb): one Tresca step per solve" in highs
    assert "without second-order cones skips a 3D Tresca step" in highs
    thesis = plain_text_of(site / "generated" / "solvers" / "augmented_projection.html")
    assert "frictionless problem only (not built: " in thesis
    assert "friction (Tresca, Coulomb): skipped (below)" in thesis


@pytest.mark.slow
def test_the_plugin_solver_gets_its_page(site):
    page = text_of(site / "generated" / "solvers" / "dual_bb.html")
    assert "plug-in" in page and "rtol" in page            # its origin and its declared option
    assert "Barzilai" in page                               # its module's own docstring
    assert "dual_bb" in text_of(site / "generated" / "solvers.html")


@pytest.mark.slow
def test_the_command_line_page_and_the_guides_are_built(site):
    cli = text_of(site / "generated" / "cli.html")
    for command in ("contactbench list", "contactbench solve", "contactbench export"):
        assert command in cli
    assert "--problem" in cli
    assert (site / "guide" / "add-a-solver.html").is_file()
    assert "guide/add-a-solver.html" in text_of(site / "index.html")   # the globbed toctree


@pytest.mark.slow
def test_the_pages_render_their_mathematics_offline(site):
    """Dollar math becomes MathJax markup, MathJax ships with the site (no network needed
    to read it), and no built page shows raw TeX or names what a user cannot see."""
    mortar = text_of(site / "guide" / "mortar.html")
    assert mortar.count('class="math') >= 10
    assert (site / "_static" / "mathjax" / "tex-chtml.js").is_file()
    assert 'src="../_static/mathjax/tex-chtml.js"' in mortar
    for page in site.rglob("*.html"):
        text = plain_text_of(page)
        assert "$\\" not in text and "$$" not in text, page
        assert "steering" not in text.lower(), page


# --------------------------------------------------------------------------- commands
ROOT = DOCS.parent
#: The pages a user reads commands from: the front page and the hand-written docs.
PAGES = [ROOT / "README.md", *sorted(p for p in DOCS.rglob("*.md")
                                     if not {"_build", "generated"} & set(p.parts))]


def page_texts() -> dict[str, str]:
    """``{page: text}`` of :data:`PAGES` and of every study's page text (its folder's
    ``page.md``)."""
    from workflows.studies import STUDIES

    texts = {page.name: page.read_text(encoding="utf-8") for page in PAGES}
    for name, study in STUDIES.items():
        texts[f"{name}/page.md"] = (study.folder / "page.md").read_text(encoding="utf-8")
    return texts


def shell_lines(text: str) -> list[str]:
    """The lines of the ``bash`` fenced blocks of a page, continuation lines joined and
    comments dropped."""
    lines, inside, block = [], False, []
    for line in text.splitlines():
        if line.startswith("```"):
            if inside:
                lines += " ".join(block).replace("\\ ", " ").split("\n")
            inside, block = (line.strip() == "```bash") and not inside, []
            continue
        if inside:
            block.append(line + ("" if line.endswith("\\") else "\n"))
    return [l.split(" #")[0].strip() for l in lines if l.split(" #")[0].strip()]


def shown_commands() -> list[tuple[str, list[str]]]:
    """``(page, argv)`` of every ``contactbench`` command in a fenced block of the pages
    (continuation lines joined, comments dropped)."""
    found = []
    for page, text in page_texts().items():
        for line in shell_lines(text):
            words = shlex.split(line)
            if words[0].endswith("contactbench"):
                found.append((page, words[1:]))
    return found


def at_the_tiny_scale(argv: list[str]) -> list[str]:
    """The command at the tiny scale: level 0, and an export of one family."""
    out = list(argv)
    if "--level" in out:
        out[out.index("--level") + 1] = "0"
    if out[0] == "export":
        out += ["--families", "circle_square"]
    return out


def test_the_pages_show_only_suite_commands():
    """The docs show contactbench, make and snakemake (and qpbenchmark on an export)."""
    allowed = ("contactbench", "make", "snakemake", "qpbenchmark", "pip")
    for page, text in page_texts().items():
        assert "python -m" not in text, page
        for line in shell_lines(text):
            assert shlex.split(line)[0].split("/")[-1] in allowed, (page, line)


@pytest.mark.slow
def test_every_contactbench_command_shown_runs_at_the_tiny_scale(tmp_path):
    commands = shown_commands()
    assert {argv[0] for _, argv in commands} >= {"list", "solve", "export", "study"}
    contactbench = Path(sys.executable).parent / "contactbench"
    tiny = {tuple(at_the_tiny_scale(argv)): page for page, argv in commands}  # each once
    for i, (argv, page) in enumerate(tiny.items()):
        cwd = tmp_path / str(i)
        cwd.mkdir()
        done = subprocess.run([str(contactbench), *argv], cwd=cwd, capture_output=True,
                              text=True, timeout=600)
        assert done.returncode == 0, (page, argv, done.stderr[-3000:])


def test_the_study_commands_quoted_with_a_measurement_name_real_options(capsys):
    """A measurement is quoted with the command that made it (``contactbench study NAME
    --option ...``, elided): every name is a study command, every option one its script
    takes."""
    from workflows.cli import main
    from workflows.studies import study_commands

    quoted = []
    for page, text in page_texts().items():
        text = " ".join(text.split())
        quoted += [(page, m[0], m[1]) for m in
                   re.findall(r"contactbench study ([a-z_]+)((?: [^`]*)?)`", text)]
    assert len(quoted) >= 10
    for page, name, rest in quoted:
        assert name in study_commands(), (page, name)
        with pytest.raises(SystemExit) as stop:
            main(["study", name, "--help"])
        assert stop.value.code == 0
        usage = capsys.readouterr().out
        for option in re.findall(r"(?<!\S)(--[a-z][\w-]*)", rest):
            assert f"{option} " in usage or f"{option}\n" in usage or f"{option}," in usage, \
                (page, name, option)


def study_page(site: Path, name: str) -> Path:
    """A study's page, generated from its folder."""
    return site / "generated" / "studies" / f"{name}.html"


@pytest.mark.slow
def test_each_study_page_shows_what_its_declaration_and_rules_say(site):
    from report.element_order import CLAIMS
    from workflows.studies import STUDIES

    for name, study in STUDIES.items():
        page = plain_text_of(study_page(site, name))
        assert f"contactbench study {next(iter(study.scripts))}" in page, name
        for item in study.thesis_items:
            assert item.item in page, (name, item.item)
    page = plain_text_of(study_page(site, "element_order"))
    assert "Remark 7.11" in page and "κ(Ŝ⁻¹S_in)" in page      # its page.md
    for claim in CLAIMS.values():                   # the report module's declared claims
        assert claim.thesis in page
    assert "P1 (circles) against P2 (squares)" in page         # the figure's caption


# --------------------------------------------------------------------------- measured record
RECORD = DOCS / "measured" / "regenerations.csv"


def quoted_record(readme: str, row: dict) -> list[str]:
    """What the README must say of one recorded run: its table row's wall time, jobs and
    peak memory, and its claim counts."""
    line = next((l for l in readme.splitlines() if l.startswith(f"| `{row['command']}` |")),
                "")
    wanted = {"wall time and jobs": f"{row['wall_time']} for {row['jobs']} jobs",
              "peak memory": f"peak memory {row['peak_memory_gb']} GB"}
    missing = [f"{what} ({text!r})" for what, text in wanted.items() if text not in line]
    claims = (f"- {row['scale']} run: {row['claims']} checked claims ({row['passed']} pass, "
              f"{row['missed']} miss, {row['unjudged']} reported without a bar)")
    if claims not in readme:
        missing.append(f"claims ({claims!r})")
    return missing


def test_the_readme_quotes_the_measured_record():
    """The wall times, jobs, peak memory and claim counts the README quotes are the
    record's (one source per number); the docs pages include the record, they do not
    type its numbers again."""
    import csv

    rows = list(csv.DictReader(RECORD.open(encoding="utf-8")))
    assert {r["scale"] for r in rows} >= {"quick", "full"}
    for row in rows:
        assert int(row["claims"]) == sum(int(row[k]) for k in ("passed", "missed", "unjudged"))
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    for row in rows:
        assert not quoted_record(readme, row), (row["scale"], quoted_record(readme, row))
    for page in ("getting-started.md", "performance.md"):
        assert ":file: measured/regenerations.csv" in (DOCS / page).read_text(encoding="utf-8")


def test_a_readme_that_differs_from_the_record_is_caught():
    """The check above fails on a README whose quick wall time or claim count was typed
    differently from the record."""
    import csv

    row = next(r for r in csv.DictReader(RECORD.open(encoding="utf-8")) if r["scale"] == "quick")
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert not quoted_record(readme, row)
    assert quoted_record(readme.replace(row["wall_time"], "8.5 min"), row)
    assert quoted_record(readme.replace(f"{row['claims']} checked claims", "185 checked claims"),
                         row)
