"""The documentation site builds with warnings as errors, and its scene, solver and
command-line pages come from the code: every registered problem and solver has its page,
an installed plug-in solver included (the example package of ``conftest.py``).

The site is built from a copy of ``docs/`` into a temporary folder (the generated pages are
written beside the sources at build time), in a subprocess that sees the plug-in.
"""
from __future__ import annotations

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
