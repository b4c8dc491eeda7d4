"""Sphinx configuration of the contactbench documentation (``make docs``)."""
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))
if (HERE.parent / "solvers").is_dir():
    sys.path.insert(0, str(HERE.parent))      # the suite's packages, from this checkout

project = "contactbench"
author = "the contactbench developers"
copyright = "the contactbench developers"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",      # MathJax bundled: the pages render their mathematics offline
    "numpydoc",
    "registry_pages",
]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
exclude_patterns = ["_build", "**/.ipynb_checkpoints"]
myst_enable_extensions = ["colon_fence", "deflist", "dollarmath", "amsmath"]
myst_heading_anchors = 3

autodoc_default_options = {"members": True, "undoc-members": False}
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_validation_checks = set()
suppress_warnings = ["myst.header"]

html_theme = "furo"
html_title = "contactbench"
