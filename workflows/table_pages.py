"""CSV tables shown in the HTML report as pages.

Snakemake's report shows images, PDFs and HTML pages and offers any other file, a CSV
table among them, as a download only. A rule's output that is a table for the reader is
therefore named with :func:`shown_table` where a figure is named with ``report()``: the
CSV stays the rule's output, and a rule of its own (:func:`page_rule`,
``workflows/summary.smk``) writes its page (:func:`page_path`, by ``python -m report.tables``), which the report
shows with the table's caption, category and subcategory.
"""
from __future__ import annotations

import re
from pathlib import PurePosixPath
from typing import NamedTuple

from workflows.studies._base import path_pattern


class Shown(NamedTuple):
    """How the report shows one table: ``report()``'s caption, category, subcategory."""

    caption: object = None
    category: str | None = None
    subcategory: str | None = None


#: The tables the report shows as pages: their path templates -> :class:`Shown`, filled by
#: the rules (:func:`shown_table`) as the Snakefile includes them.
TABLE_PAGES: dict[str, Shown] = {}


def shown_table(path: str, caption=None, category: str | None = None,
                subcategory: str | None = None) -> str:
    """A rule's CSV output the HTML report shows as a page (in place of ``report(path,
    caption, category, subcategory)``, which would offer the CSV as a download).

    Returns
    -------
    str
        ``path`` itself, unflagged: the page (:func:`page_path`) is the report's item.
    """
    TABLE_PAGES[path] = Shown(caption, category, subcategory)
    return path


def page_path(path: str) -> str:
    """The page of the table at ``path`` (a path or a template): ``x.csv`` -> ``x.html``."""
    return str(PurePosixPath(path).with_suffix(".html"))


def page_rule(path: str) -> str:
    """The name of the rule writing the page of the table at ``path``: ``page_`` and the
    file's name (``page_augmented_projection_table``)."""
    return "page_" + re.sub(r"\W+", "_", PurePosixPath(path).stem)


def page_log_name(path: str) -> str:
    """The name of the log of the page rule's job for the table at ``path``: its
    wildcards (``{scene}``), or ``all`` for a path without any."""
    wildcards = re.findall(r"\{\w+\}", path)
    return "_".join(wildcards) or "all"


def pages_of(targets: list[str]) -> list[str]:
    """The pages of those ``targets`` that are shown tables (:data:`TABLE_PAGES`)."""
    patterns = [path_pattern(t) for t in TABLE_PAGES]
    return [page_path(t) for t in targets if any(p.fullmatch(t) for p in patterns)]
