"""HTML tables of the report's summary page: compact, sortable, filterable offline, every
empty cell with its reason (shared by the summary page and the studies' headline parts)."""
from __future__ import annotations

import html
from collections import Counter
from typing import Callable

import numpy as np
import pandas as pd

EMPTY_THESIS = "the thesis prints no value for this row"
EMPTY_OURS = ("not measured in this run: a level or quantity this scale does not reach, or "
              "a run without a solution (its status and message say why)")
#: Columns whose empty cells have a reason of their own.
EMPTY_BY_COLUMN = {
    "rate_h1": "no rate: the errors are at round-off (the method reproduces this solution "
               "exactly)",
    "rate_l2": "no rate: the errors are at round-off (the method reproduces this solution "
               "exactly)",
}


def empty_reason(column: str, row) -> str:
    """Why the cell of ``column`` in ``row`` is empty."""
    if str(column).startswith("thesis_") or str(row.get("source", "")) == "thesis":
        return EMPTY_THESIS
    return EMPTY_BY_COLUMN.get(str(column), EMPTY_OURS)

#: What a table's columns mean where a name alone would mislead.
def cell_text(x) -> str:
    """A cell's text: numbers to 4 significant digits without a hyphen to wrap at
    (``1e-09`` is written ``1e−09``), text escaped; empty for a missing value."""
    if isinstance(x, (bool, np.bool_)):
        return str(bool(x))
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    if isinstance(x, (float, np.floating)):
        if np.isnan(x):
            return ""
        return f"{x:.4g}".replace("-", "\u2212")
    text = str(x).strip()
    if text.lower() in ("", "nan", "none"):
        return ""
    try:                      # numbers read back as text (mixed columns)
        if text.lower() not in ("inf", "-inf") and not text.isdigit():
            return f"{float(text):.4g}".replace("-", "\u2212")
    except ValueError:
        pass
    return html.escape(text)


_TABLE_IDS = Counter()


def new_page() -> None:
    """Start a page: its tables' ids count from 1 again."""
    _TABLE_IDS.clear()


def table_html(frame: pd.DataFrame, left: tuple[str, ...] = (), classes: dict | None = None,
               max_rows: int = 60, name: str = "t", filter_box: bool = True,
               cell_html: dict[str, Callable[[str], str]] | None = None,
               row_id: Callable[[pd.Series], str | None] | None = None) -> str:
    """A compact sortable HTML table (numbers to 4 digits; ``classes``: column -> value ->
    class; ``cell_html``: column -> a function of the escaped cell text returning the
    cell's HTML, e.g. with links; ``row_id``: a row's anchor, or None). An empty cell
    reads "--" with its reason as tooltip (:data:`EMPTY_THESIS`, :data:`EMPTY_OURS`);
    the reasons are listed under the table."""
    _TABLE_IDS[name] += 1
    tid = f"{name}-{_TABLE_IDS[name]}"
    head = "".join(f'<th class="{"l" if c in left else ""}">'
                   f'{html.escape(str(c)).replace("_", "_<wbr>")}</th>' for c in frame.columns)
    body, empty, seen_ids = [], set(), set()
    for _, row in frame.head(max_rows).iterrows():
        cells = []
        for c in frame.columns:
            cls = ["l"] if c in left else []
            if classes and c in classes:
                cls.append(classes[c].get(str(row[c]), ""))
            text = cell_text(row[c])
            if text == "":
                why = empty_reason(c, row)
                empty.add(why)
                cells.append(f'<td class="na" title="{html.escape(why)}">--</td>')
                continue
            value = row[c]
            data = (f' data-v="{float(value)!r}"' if isinstance(value, (int, float, np.integer,
                                                                        np.floating))
                    and not isinstance(value, (bool, np.bool_)) else "")
            if cell_html and c in cell_html:
                text = cell_html[c](text)
            cells.append(f'<td class="{" ".join(cls)}"{data}>{text}</td>')
        rid = row_id(row) if row_id else None
        attr = f" id='{html.escape(rid)}'" if rid and rid not in seen_ids else ""
        seen_ids.add(rid)
        body.append(f"<tr{attr}>" + "".join(cells) + "</tr>")
    more = (f'<p class="small">{len(frame) - max_rows} more rows in the file.</p>'
            if len(frame) > max_rows else "")
    notes = "".join(f'<p class="small">--: {html.escape(w)}.</p>' for w in sorted(empty))
    box = (f'<input class="filter" data-table="{tid}" placeholder="filter rows">'
           if filter_box and len(frame) > 8 else "")
    return (f"{box}<div class='wide'><table class='sortable' id='{tid}'><tr>{head}</tr>"
            f"{''.join(body)}</table></div>{notes}{more}")


