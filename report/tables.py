"""HTML tables of the report: compact, sortable, filterable offline, every empty cell with
its reason (shared by the summary page, the studies' headline parts and the page the HTML
report shows for each CSV table).

Example (CSV tables as pages of their own, the n-th page for the n-th table)::

    python -m report.tables --csv results/circle_square/coupling_claims.csv \
        --html results/circle_square/coupling_claims.html
"""
from __future__ import annotations

import argparse
import html
from collections import Counter
from typing import Callable

import numpy as np
import pandas as pd

from workflows.io import read_csv, write_text

#: The style of the report's pages of tables (the summary page, each table's page).
STYLE = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:1.2em 1.5em;
     color:#222;max-width:1300px}
h1{font-size:1.5em;margin-bottom:.2em} h2{font-size:1.2em;border-bottom:1px solid #ccc;
   margin-top:1.6em} h3{font-size:1em;margin-bottom:.3em}
table{border-collapse:collapse;font-size:.8em;margin:.4em 0 1em}
th,td{border:1px solid #ddd;padding:2px 6px;text-align:right;vertical-align:top;
      white-space:nowrap}
th{background:#f3f3f3;cursor:pointer;white-space:normal;min-width:3em}
td.l,th.l{text-align:left}
td.l{white-space:normal;overflow-wrap:break-word;min-width:3em;max-width:34em}
.pass{background:#e3f5e1;color:#1a6b1a;font-weight:600}
.miss{background:#fde2e1;color:#a11;font-weight:600}
.na{background:#f4f4f4;color:#666} .small{font-size:.8em;color:#555}
.wide{overflow-x:auto;max-width:100%}
.counts a{margin-right:1.2em;font-weight:600;text-decoration:none;padding:1px 4px}
.lead{font-size:1em;line-height:1.45} .lead li{margin:.2em 0}
input.filter{font-size:.8em;margin:.2em 0;width:18em}
img.thumb{max-width:160px;max-height:110px;border:1px solid #ccc}
.under{color:#777;font-style:italic;font-weight:normal}
"""

#: Sortable and filterable tables, self-contained (no network): a click on a header sorts
#: by that column (numbers as numbers, a U+2212 minus a minus), the box above a table keeps
#: the rows containing its text.
SCRIPT = """
function cbSort(th){const t=th.closest('table'),i=[...th.parentNode.children].indexOf(th);
 const rows=[...t.querySelectorAll('tr')].slice(1),dir=th.dataset.dir==='a'?-1:1;
 th.dataset.dir=dir===1?'a':'d';
 const key=r=>{const c=r.children[i];const v=c?c.dataset.v??c.innerText:'';
  const x=parseFloat(String(v).replace(/\u2212/g,'-'));return isNaN(x)?v:x};
 rows.sort((a,b)=>{const x=key(a),y=key(b);
  if(typeof x===typeof y)return (x>y?1:x<y?-1:0)*dir;return (typeof x==='number'?-1:1)*dir});
 rows.forEach(r=>t.appendChild(r))}
function cbFilter(box){const t=document.getElementById(box.dataset.table),q=box.value.toLowerCase();
 [...t.querySelectorAll('tr')].slice(1).forEach(r=>{
  r.style.display=r.innerText.toLowerCase().includes(q)?'':'none'})}
document.addEventListener('click',e=>{if(e.target.tagName==='TH'&&e.target.closest('table.sortable'))cbSort(e.target)});
document.addEventListener('input',e=>{if(e.target.classList.contains('filter'))cbFilter(e.target)});
"""

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


def header_text(column) -> str:
    """A column's header as a table shows it: words apart where the name has underscores,
    hyphens that do not break (``n_outer_1e-03`` reads ``n outer 1e‑03``), escaped."""
    return html.escape(str(column).replace("_", " ").replace("-", "\u2011"))


def sort_value(x) -> str | None:
    """The number a cell sorts by (``data-v``), also for numbers read back as text and
    negatives written with U+2212; None for a cell that is not a number."""
    if isinstance(x, (bool, np.bool_)):
        return None
    try:
        v = float(str(x).strip().replace("\u2212", "-"))
    except ValueError:
        return None
    return None if np.isnan(v) else repr(v)


_TABLE_IDS = Counter()


def new_page() -> None:
    """Start a page: its tables' ids count from 1 again."""
    _TABLE_IDS.clear()


def table_html(frame: pd.DataFrame, left: tuple[str, ...] = (), classes: dict | None = None,
               max_rows: int = 60, name: str = "t", filter_box: bool = True,
               cell_html: dict[str, Callable[[str], str]] | None = None,
               row_id: Callable[[pd.Series], str | None] | None = None,
               headers: dict[str, str] | None = None,
               empty_why: dict[str, str] | None = None,
               below: dict[str, str] | None = None) -> str:
    """A compact sortable HTML table (numbers to 4 digits; ``classes``: column -> value ->
    class; ``cell_html``: column -> a function of the escaped cell text returning the
    cell's HTML, e.g. with links; ``row_id``: a row's anchor, or None; ``headers``:
    column -> the header to show, else :func:`header_text`). An empty cell reads "--"
    with its reason as tooltip (``empty_why``: column -> the reason, else
    :func:`empty_reason`); the reasons are listed under the table; a cell holding a
    number sorts as one (:func:`sort_value`). ``below``: column -> a column whose value
    is shown beneath it in the same cell, greyed (the thesis's under ours), not as a
    column of its own."""
    _TABLE_IDS[name] += 1
    tid = f"{name}-{_TABLE_IDS[name]}"
    headers, below = headers or {}, below or {}
    columns = [c for c in frame.columns if c not in below.values()]
    head = "".join(f'<th class="{"l" if c in left else ""}">'
                   f'{html.escape(headers[c]) if c in headers else header_text(c)}'
                   + (f"<br><span class='under'>{header_text(below[c])}</span>"
                      if c in below else "") + "</th>" for c in columns)
    body, empty, seen_ids = [], set(), set()
    for _, row in frame.head(max_rows).iterrows():
        cells = []
        for c in columns:
            cls = ["l"] if c in left else []
            if classes and c in classes:
                cls.append(classes[c].get(str(row[c]), ""))
            text = cell_text(row[c])
            under = cell_text(row[below[c]]) if c in below else ""
            under = f"<br><span class='under'>{under}</span>" if under else ""
            if text == "":
                why = (empty_why or {}).get(c) or empty_reason(c, row)
                empty.add(why)
                cells.append(f'<td class="na" title="{html.escape(why)}">--{under}</td>')
                continue
            v = sort_value(row[c])
            data = f' data-v="{v}"' if v is not None else ""
            if cell_html and c in cell_html:
                text = cell_html[c](text)
            text += under
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


#: The most rows a table's page shows (the rest are counted under it; the CSV has them).
PAGE_ROWS = 2000


def table_page(frame: pd.DataFrame, title: str) -> str:
    """One CSV table as a self-contained HTML page: its title, the table (text columns
    left-aligned, sortable, filterable) and the page's script."""
    new_page()
    left = tuple(c for c in frame.columns if frame[c].dtype == object)
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}"
            f"</title><style>{STYLE}</style></head><body><h1>{html.escape(title)}</h1>"
            f"<p class='small'>{len(frame)} rows; click a column's header to sort, type in "
            "the box to filter.</p>"
            + table_html(frame, left=left, name="table", max_rows=PAGE_ROWS)
            + f"<script>{SCRIPT}</script></body></html>")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--csv", required=True, nargs="+", help="the tables")
    ap.add_argument("--html", required=True, nargs="+",
                    help="their pages to write, one per table, in the tables' order")
    args = ap.parse_args(argv)
    if len(args.html) != len(args.csv):
        ap.error(f"--html: {len(args.html)} pages for {len(args.csv)} tables (--csv); "
                 "give one page per table")
    for table, page in zip(args.csv, args.html):
        write_text(page, table_page(read_csv(table), table))


if __name__ == "__main__":
    main()
