"""CSV tables shown in the HTML report as pages.

Snakemake's report shows images, PDFs and HTML pages and offers any other file, a CSV
table among them, as a download only. A rule's output that is a table for the reader is
therefore named with :func:`shown_table` where a figure is named with ``report()``: the
CSV stays the rule's output, and the summary's job (``workflows/summary.smk``), which runs
after every table, writes the pages of all of them in one process (:func:`shown_pages`,
``python -m report.tables``); the report shows each with its table's caption, category and
subcategory.
"""
from __future__ import annotations

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


def shown_pages(targets: list[str]) -> list[tuple[str, str, Shown]]:
    """Each shown table among ``targets`` with its page and how the report shows it, the
    category and subcategory filled with the table's wildcards (``{scene}`` ->
    ``circle_square``).

    Returns
    -------
    list of (str, str, Shown)
        ``(table, page, shown)`` in the order of ``targets``.
    """
    patterns = [(path_pattern(template), shown) for template, shown in TABLE_PAGES.items()]
    pages = []
    for target in targets:
        for pattern, shown in patterns:
            match = pattern.fullmatch(target)
            if match:
                fill = match.groupdict()
                pages.append((target, page_path(target), shown._replace(
                    category=shown.category and shown.category.format(**fill),
                    subcategory=shown.subcategory and shown.subcategory.format(**fill))))
                break
    return pages
