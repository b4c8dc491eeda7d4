"""The one-page summary at the top of the HTML report.

For a finished regeneration: where the numbers came from (commit, dirty tree,
packages, CPU, cores and BLAS/OpenMP threads, config file and hash -- read from
the results' provenance sidecars, with any disagreement between them shown), every
checked claim with its measured value, its bar and pass/miss, every table and
figure of the thesis with the output that regenerates it (the thesis's tables
with their values beside ours, inline), the solver summary, and the peak memory
and run time of every study from the rules' benchmark files.

Inputs are named ``key@scene=path`` (``key`` a :data:`workflows.studies.PATHS`
key, ``scene`` or ``-``), as the rule ``summary`` passes them.

Example::

    python -m report.summary --items ap_claims@circle_square=results/... \\
        --benchmarks results/benchmarks --html summary.html --claims claims.csv
"""
from __future__ import annotations

import argparse
import html
from collections import Counter
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from report import adaptive, contact, hard_cases, laplace
from report.claims import NOT_REACHED
from report.leaderboard import COVERAGE
from solvers.interface import TOLERANCES
from workflows.problem_set import PROBLEM_CLASSES
from workflows.io import META, provenance, read_csv, read_json, write_csv, write_text
from workflows.studies import HEAVY_RULES, PATHS, STUDIES, THESIS_ITEMS, claim_keys

#: PATHS key -> claims of that output (a frame with claim, measured, bar, pass): the
#: tables derived here, and every study's claims tables as they are (``Study.claims``).
CLAIMS: dict[str, Callable[[pd.DataFrame], pd.DataFrame]] = {
    **{key: lambda t: t for key in claim_keys()},
    "laplace_rates": laplace.claims,
    "hertz": contact.claims,
    "adaptive_accuracy": lambda t: adaptive.claims(accuracy=t),
    "adaptive_pileup": lambda t: adaptive.claims(pileup=t),
    "patch_table": lambda t: adaptive.claims(patch=t),
    "hard_table": hard_cases.claims,
}

#: Tables shown inline (ours beside the thesis's where it has values), each with the
#: columns a reader compares (None: all); every column with a thesis value is shown
#: too, and the rest are named under the table (the full file is in the report).
INLINE = {
    "ap_table": ("level", "N", "NC", "kappa_S", "energy_error", "stop_8_25", "status"),
    "adaptive_table": ("source", "step", "N", "NC", "n_outer_1e-03", "n_inner_mean_1e-03",
                       "t_solve_1e-03", "t_proj_1e-03", "kappa_S", "kkt_max"),
    "hertz": ("level", "nodes", "status", "force", "a_hertz", "a_moment", "dev_a_moment",
              "p0_hertz", "p0_moment", "dev_p0_moment", "a_over_h"),
    "laplace_rates": None,
    "exact_table": ("level", "N", "backend", "status_schur", "total_time_schur", "status_kkt",
                    "total_time_kkt", "speedup", "p_difference"),
    "roll_table": ("force_MN", "crown_um", "level", "N", "status", "q0_MN_per_m",
                   "q0_beam_MN_per_m", "b0_mm", "b0_hertz_mm", "p0_nodal_GPa",
                   "p0_hertz_GPa", "cells_across_2b", "sag_work_axis_um",
                   "sag_work_axis_beam_um", "strip_crown_um", "strip_crown_beam_um"),
}

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
td.l{white-space:normal;overflow-wrap:break-word;min-width:5em;max-width:34em}
.pass{background:#e3f5e1;color:#1a6b1a;font-weight:600}
.miss{background:#fde2e1;color:#a11;font-weight:600}
.na{background:#f4f4f4;color:#666} .small{font-size:.8em;color:#555}
.wide{overflow-x:auto;max-width:100%}
.counts a{margin-right:1.2em;font-weight:600;text-decoration:none;padding:1px 4px}
.lead{font-size:1em;line-height:1.45} .lead li{margin:.2em 0}
input.filter{font-size:.8em;margin:.2em 0;width:18em}
img.thumb{max-width:160px;max-height:110px;border:1px solid #ccc}
"""

#: Sortable and filterable tables, self-contained (no network): a click on a header sorts
#: by that column (numbers as numbers), the box above a table keeps the rows containing
#: its text.
SCRIPT = """
function cbSort(th){const t=th.closest('table'),i=[...th.parentNode.children].indexOf(th);
 const rows=[...t.querySelectorAll('tr')].slice(1),dir=th.dataset.dir==='a'?-1:1;
 th.dataset.dir=dir===1?'a':'d';
 const key=r=>{const c=r.children[i];const v=c?c.dataset.v??c.innerText:'';
  const x=parseFloat(v);return isNaN(x)?v:x};
 rows.sort((a,b)=>{const x=key(a),y=key(b);
  if(typeof x===typeof y)return (x>y?1:x<y?-1:0)*dir;return (typeof x==='number'?-1:1)*dir});
 rows.forEach(r=>t.appendChild(r))}
function cbFilter(box){const t=document.getElementById(box.dataset.table),q=box.value.toLowerCase();
 [...t.querySelectorAll('tr')].slice(1).forEach(r=>{
  r.style.display=r.innerText.toLowerCase().includes(q)?'':'none'})}
document.addEventListener('click',e=>{if(e.target.tagName==='TH'&&e.target.closest('table.sortable'))cbSort(e.target)});
document.addEventListener('input',e=>{if(e.target.classList.contains('filter'))cbFilter(e.target)});
"""

#: Why a cell is empty, by the kind of column (shown as the cell's tooltip and under
#: each table).
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
NOTES = {
    "ap_table": "status: the suite's verification of the run at the study's tolerance (all "
                "four scaled KKT residuals and the certified energy bound); the thesis stops "
                "Alg. 8.4 by (8.25) instead, and stop_8_25 says whether our run met that "
                "criterion. thesis_* columns: the thesis's values at the same level, beside "
                "ours.",
    "leaderboard": "Time at matched accuracy: each solver's loosest rung of its tolerance "
                   "ladder verified at the preset's tol, the median of repeated runs (repeat "
                   "spread: the largest (max - min) / median). verified: problems of the "
                   "class verified over the ladder (a skip counts against it); at rung 0: "
                   "at the preset's own mapping; correct %: share of rung-0 claims true "
                   "against the exact reference; median time / best: over the class's "
                   "problems, the solver's time over the best contestant's (inf: fewer "
                   "than half verified), by which the table is ranked; sgm time: the shifted "
                   "geometric mean over the problems attempted, shift {shift:.3g} s (the "
                   "class's median best time), an attempted problem not verified counting "
                   "as the time limit {limit:g} s. Load: {load}.",
}


def parse_items(items: list[str]) -> list[tuple[str, str | None, str]]:
    """``key@scene=path`` -> ``(key, scene or None, path)``; raises ValueError on a bad item."""
    out = []
    for item in items:
        name, sep, path = item.partition("=")
        key, at, scene = name.partition("@")
        if not (sep and at and path) or key not in PATHS:
            raise ValueError(f"--items: {item!r} is not allowed; allowed: key@scene=path "
                             f"with key one of the workflow's path keys")
        out.append((key, None if scene == "-" else scene, path))
    return out


def study_of(key: str) -> str:
    """The study a PATHS key belongs to."""
    for study in STUDIES.values():
        if key in study.outputs or any(key in outs for _, outs in study.extra):
            return study.name
    return "-"


def collect_claims(items) -> pd.DataFrame:
    """Every claim of every configured output, with study, scene and source file."""
    frames = []
    for key, scene, path in items:
        if key not in CLAIMS:
            continue
        c = CLAIMS[key](read_csv(path))
        if len(c):
            frames.append(c.assign(study=study_of(key), scene=scene or "-", source=path))
    if not frames:
        return pd.DataFrame(columns=["study", "scene", "claim", "thesis", "measured", "bar",
                                     "result", "reason", "source"])
    c = pd.concat(frames, ignore_index=True)
    c["result"] = [("n/a" if p is None or (isinstance(p, float) and np.isnan(p)) else
                    "pass" if str(p).lower() in ("true", "1", "1.0") else "miss")
                   for p in c["pass"]]
    if "thesis" not in c:
        c["thesis"] = "-"
    c["thesis"] = c["thesis"].fillna("-")
    if "reason" not in c:
        c["reason"] = ""
    c["reason"] = c["reason"].fillna("").astype(str)
    unjudged = (c["result"] == "n/a") & (c["reason"].str.strip() == "")
    c.loc[unjudged, "reason"] = NOT_REACHED
    return c[["study", "scene", "claim", "thesis", "measured", "bar", "result", "reason",
              "source"]]


def solver_set_text(fixed: dict | None) -> str:
    """A run's solver set (provenance ``solver_set``) in one line: the names, a plug-in
    with its package and version."""
    if not fixed:
        return "not recorded"
    return ", ".join(name if info.get("origin") != "plug-in" else
                     f"{name} (plug-in {info.get('package')} {info.get('version')})"
                     for name, info in sorted(fixed.items()))


def read_provenance(paths: list[str]) -> tuple[dict, dict[str, Counter]]:
    """The provenance of the newest result and, per field that varies between
    results, how many results carry each value."""
    metas = []
    for path in paths:
        meta = Path(str(path) + META)
        if meta.exists():
            try:
                metas.append(read_json(meta).get("provenance", {}))
            except (OSError, ValueError):
                continue
    if not metas:
        return provenance(), {}
    newest = max(metas, key=lambda m: m.get("created") or "")
    varying = {}
    for field in ("commit", "cpu_model", "node", "configfile", "config_sha256", "python",
                  "solver_set"):
        count = Counter(solver_set_text(m.get(field)) if field == "solver_set"
                        else str(m.get(field)) for m in metas)
        if len(count) > 1:
            varying[field] = count
    return newest, varying


def resources(bench_dir: str | None) -> pd.DataFrame:
    """Per rule with a benchmark file: jobs, summed and longest wall time, peak memory."""
    rows = []
    root = Path(bench_dir) if bench_dir else None
    if root is None or not root.is_dir():
        return pd.DataFrame(columns=["study", "rule", "jobs", "wall_s_total", "wall_s_max",
                                     "max_rss_mb"])
    for rule_dir in sorted(p for p in root.iterdir() if p.is_dir()):
        frames = []
        for tsv in sorted(rule_dir.glob("*.tsv")):
            try:
                frames.append(pd.read_csv(tsv, sep="\t"))
            except (OSError, ValueError, pd.errors.EmptyDataError):
                continue
        if not frames:
            continue
        b = pd.concat(frames, ignore_index=True)
        rows.append({"study": HEAVY_RULES.get(rule_dir.name, "-"),
                     "rule": rule_dir.name, "jobs": len(frames),
                     "wall_s_total": float(b["s"].sum()), "wall_s_max": float(b["s"].max()),
                     "max_rss_mb": float(pd.to_numeric(b["max_rss"], errors="coerce").max())})
    return pd.DataFrame(rows)


def _fmt(x) -> str:
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


#: Our column -> the thesis's, where the names differ.
THESIS_MATE = {"N": "thesis_nodes"}


def beside_thesis(frame: pd.DataFrame, keep=None) -> pd.DataFrame:
    """The columns ``keep`` (all if None) and every column the thesis has a value for,
    reordered so that each ``thesis_X`` stands right after our ``X``."""
    out = []
    for c in frame.columns:
        if str(c).startswith("thesis_"):
            continue
        mate = THESIS_MATE.get(c, f"thesis_{c}")
        if keep is None or c in keep or mate in frame.columns:
            out.append(c)
            if mate in frame.columns:
                out.append(mate)
    out += [c for c in frame.columns if str(c).startswith("thesis_") and c not in out]
    return frame[out]


#: How many tables of each name the page being written has (their ids: ``name-k``).
_TABLE_IDS = Counter()


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
            text = _fmt(row[c])
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


def thesis_rows(items, scale: str) -> pd.DataFrame:
    """Every thesis item, its output files and whether this run (at ``scale``) regenerated
    them."""
    present = {(k, s): p for k, s, p in items}
    rows = []
    for t in THESIS_ITEMS:
        files = [p for (k, s), p in present.items()
                 if k == t.key and (t.problem is None or s == t.problem)]
        if t.key is None:
            status, where = "not regenerated", t.note
        elif files:
            status, where = "regenerated", ", ".join(sorted(files))
        else:
            status = "not in this configuration"
            where = f"{PATHS[t.key]}: not at the {scale} scale (a larger one regenerates it)"
        rows.append({"thesis": t.item, "what": t.what, "status": status, "output": where})
    return pd.DataFrame(rows)


FAILURE_COLUMNS = ("scene", "preset", "solver", "runs", "converged", "inaccurate", "max_iter",
                   "time_limit", "failed", "skipped")


def failures(by_scene: pd.DataFrame | None) -> pd.DataFrame:
    """The rows of the per-scene solver summary with a run not verified converged: scene,
    preset, solver, the runs and how each ended, sorted by scene, preset, solver."""
    if by_scene is None or not len(by_scene):
        return pd.DataFrame(columns=FAILURE_COLUMNS)
    bad = by_scene[by_scene["converged"] < by_scene["runs"]]
    bad = bad[[c for c in FAILURE_COLUMNS if c in bad]]
    order = {p: i for i, p in enumerate(TOLERANCES)}
    return bad.sort_values(["scene", "preset", "solver"],
                           key=lambda c: c.map(order) if c.name == "preset" else c
                           ).reset_index(drop=True)


def failure_anchor(scene: str) -> str:
    """The id of a scene's first row in the failures table."""
    return f"failures-{scene}"


#: A leaderboard's columns on the summary page: ``{column in leaderboards.csv: header}``.
BOARD_COLUMNS = {"rank": "rank", "solver": "solver", "verified": "verified",
                 "skipped": "skipped", "plain_verified": "at rung 0", "correct_share": "correct %",
                 "median_ratio": "median time / best", "sgm_time": "sgm time [s]",
                 "spread": "repeat spread", "not_verified": "not verified"}


def leaderboard(board: pd.DataFrame) -> pd.DataFrame:
    """One board's ranked solvers, then its references (rank ``baseline``), as shown on the
    summary page (:data:`BOARD_COLUMNS`; ``board``: its rows of ``leaderboards.csv``)."""
    shown = board[board["standing"].isin(["ranked", "reference"])].copy()
    shown["rank"] = [("baseline" if st == "reference" else int(r))
                     for st, r in zip(shown["standing"], shown["rank"])]
    shown["correct_share"] = (100 * shown["correct_share"]).round(1)
    shown["solver"] = [s + (" (fastest verified)" if f else "") + (" (exact reference)"
                                                                   if st == "reference" else "")
                       for s, f, st in zip(shown["solver"], shown["fastest"],
                                           shown["standing"])]
    out = shown[list(BOARD_COLUMNS)].rename(columns=BOARD_COLUMNS)
    out["verified"] = [f"{int(v)} of {int(n)}" for v, n in zip(shown["verified"],
                                                               shown["problems"])]
    return out


def board_words(board: pd.DataFrame) -> str:
    """A board's verdict in words: its fastest verified solver with its coverage, its
    references' independent check, the solvers that declined the class."""
    first = board.iloc[0]
    cls, size, preset = first["problem_class"], first["size_class"], first["preset"]
    ranked = board[board["standing"] == "ranked"]
    fast = ranked[ranked["fastest"].astype(bool)]
    head = (f"<b>{html.escape(PROBLEM_CLASSES.get(cls, cls))}</b>, {html.escape(str(size))} "
            f"class, preset {html.escape(preset)} (tol {TOLERANCES[preset]:g}, "
            f"{int(first['problems'])} problems): ")
    if len(fast):
        r = fast.iloc[0]
        head += (f"fastest verified <b>{html.escape(r.solver)}</b> (median time "
                 f"{r.median_ratio:.3g} x the best, verified on {int(r.verified)} of "
                 f"{int(r.problems)})")
    else:
        head += f"no solver verified on {COVERAGE:.0%} of the class"
    refs = board[board["standing"] == "reference"]
    if len(refs):
        head += "; exact reference " + ", ".join(
            f"{html.escape(r.solver)} within {r.independent_agreement:.2g} of the closest "
            "independent verified answer" if np.isfinite(r.independent_agreement) else
            f"{html.escape(r.solver)} (no independent verified answer)"
            for r in refs.itertuples())
    declined = board[board["standing"] == "declined"]
    if len(declined):
        head += ("; not ranked, declining the class: "
                 + ", ".join(html.escape(s) for s in declined["solver"]))
    return head + "."


def leaderboards_html(frame: pd.DataFrame) -> list[str]:
    """The leaderboards of ``leaderboards.csv`` in words and as tables, one per problem
    class, size class and preset, each with its settings and the load it was timed under."""
    parts = []
    keys = ["problem_class", "size_class", "preset"]
    order = {c: i for i, c in enumerate(PROBLEM_CLASSES)}
    boards = sorted(frame.groupby(keys, sort=False),
                    key=lambda kv: (order.get(kv[0][0], 99), kv[0][1],
                                    list(TOLERANCES).index(kv[0][2])))
    parts.append("<ul class='lead'>" + "".join(f"<li>{board_words(b)}</li>"
                                               for _, b in boards) + "</ul>")
    for (cls, size, preset), b in boards:
        first = b.iloc[0]
        anchor = f"leaderboard-{cls}-{size}-{preset}"
        parts.append(f"<h3 id='{html.escape(anchor)}'>Leaderboard: "
                     f"{html.escape(PROBLEM_CLASSES.get(cls, cls))}, {html.escape(str(size))} "
                     f"class, preset {html.escape(preset)}</h3><p class='small'>"
                     + html.escape(NOTES["leaderboard"].format(
                         shift=first["shift"], limit=first["time_limit"], load=first["load"]))
                     + "</p>")
        parts.append(table_html(leaderboard(b), left=("solver", "not verified"),
                                name="leaderboard", max_rows=200, filter_box=False))
        declined = b[b["standing"] == "declined"]
        if len(declined):
            parts.append("<p class='small'>Declined the class (not ranked): " + "; ".join(
                f"{html.escape(r.solver)}: {html.escape(str(r.note))}"
                for r in declined.itertuples()) + "</p>")
    return parts


def thumbnail(path: str, width: int = 160) -> str:
    """A small inline PNG of the figure at ``path`` (a data URI; empty if unreadable)."""
    try:
        import base64
        import io

        from PIL import Image
        with Image.open(path) as im:
            im = im.convert("RGB")
            im.thumbnail((width * 3 // 2, width))
            buf = io.BytesIO()
            im.save(buf, format="PNG", optimize=True)
        return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode()
    except (OSError, ValueError, ImportError):
        return ""


def inline_anchor(key: str | None, scene: str | None) -> str:
    """The id of an inline table's heading."""
    return f"table-{key}-{scene or 'all'}"


def thumb_missing(status: str, pngs: list[str]) -> str:
    """Why a thesis item's row shows no thumbnail."""
    if status == "not regenerated":
        return "not regenerated by the suite"
    if status != "regenerated":
        return "not in this configuration"
    return "a table or numbers, no figure" if not pngs else "figure unreadable"


def thesis_html(th: pd.DataFrame) -> str:
    """The thesis's tables and figures: status, our file and, for a figure, its
    thumbnail."""
    cls = {"regenerated": "pass", "not regenerated": "miss", "not in this configuration": "na"}
    rows = []
    for r, item in zip(th.itertuples(), THESIS_ITEMS):
        anchor = inline_anchor(item.key, item.problem)
        if r.status == "regenerated" and item.key in INLINE:
            output = f"<a href='#{anchor}'>{html.escape(str(r.output))}</a> (below)"
        else:
            output = html.escape(str(r.output))
        pngs = [f for f in str(r.output).split(", ") if f.endswith(".png") and Path(f).exists()]
        thumb = thumbnail(pngs[0]) if pngs and r.status == "regenerated" else ""
        img = (f"<img class='thumb' alt='{html.escape(pngs[0])}' src='{thumb}'>" if thumb
               else f"<span class='small'>{thumb_missing(r.status, pngs)}</span>")
        rows.append(f"<tr><td class='l'><b>{html.escape(r.thesis)}</b></td>"
                    f"<td class='l'>{html.escape(r.what)}</td>"
                    f"<td class='l {cls.get(r.status, '')}'>{html.escape(r.status)}</td>"
                    f"<td class='l'>{output}</td><td>{img}</td></tr>")
    return ("<input class='filter' data-table='thesis-items' placeholder='filter, e.g. Fig. 9.5'>"
            "<div class='wide'><table class='sortable' id='thesis-items'><tr><th class='l'>"
            "thesis</th><th class='l'>what</th><th class='l'>status</th><th class='l'>our "
            "output</th><th>figure</th></tr>" + "".join(rows) + "</table></div>")


def headline(items, claims: pd.DataFrame, th: pd.DataFrame, scale: str) -> list[str]:
    """The front page: scale and coverage, the claims' counts linking to the misses and
    the unjudged, the solver leaderboard in words and as a table."""
    counts = Counter(claims["result"])
    scenes = sorted({s for _, s, _ in items if s})
    status = Counter(th["status"])
    parts = ["<h2 id='headline'>Headline</h2><ul class='lead'>",
             f"<li><b>Scale {html.escape(scale or '?')}</b>: {len(items)} outputs over "
             f"{len(scenes)} scenes and families ({html.escape(', '.join(scenes))}); of the "
             f"thesis's {len(th)} tables and figures, {status.get('regenerated', 0)} "
             f"regenerated here, {status.get('not in this configuration', 0)} left to a larger "
             f"scale (<code>quick</code>, <code>full</code>), "
             f"{status.get('not regenerated', 0)} not regenerated by the suite "
             "(<a href='#thesis'>list</a>).</li>",
             f"<li><b>Claims checked</b>: <span class='counts'>"
             f"<a class='pass' href='#claims-pass'>{counts.get('pass', 0)} pass</a>"
             f"<a class='miss' href='#claims-miss'>{counts.get('miss', 0)} miss</a>"
             f"<a class='na' href='#claims-unjudged'>{counts.get('n/a', 0)} not judged at "
             "this scale (each with its reason)</a></span></li>"]
    boards = [p for k, _, p in items if k == "solver_leaderboards"]
    by_scene = [p for k, _, p in items if k == "solver_summary_by_scene"]
    if boards:
        parts.append("</ul><h3 id='leaderboard'>Solver leaderboards over the contact QP test "
                     "set, one per problem class</h3>")
        parts += leaderboards_html(read_csv(boards[0]))
        scenes = read_csv(by_scene[0]) if by_scene else None
        fails = failures(scenes)
        parts.append("<h3 id='failures'>Where plain runs were not verified converged, by scene "
                     f"({len(fails)} row{'' if len(fails) == 1 else 's'})</h3>")
        if len(fails):
            parts.append("<p class='small'>Per scene of the test set, solver and preset: the "
                         "plain runs (rung 0 of each ladder) and how each ended (every run is "
                         "in the report's test-set tables).</p>")
            parts.append(table_html(fails, left=("scene", "preset", "solver"), name="failures",
                                    max_rows=500,
                                    row_id=lambda r: failure_anchor(str(r["scene"]))))
        else:
            parts.append("<p class='small'>Every run of every solver was verified "
                         "converged.</p>")
    else:
        parts.append("<li>No solver leaderboard: the test set is not in this "
                     "configuration.</li></ul>")
    return parts


def claims_html(claims: pd.DataFrame) -> list[str]:
    """The claims in three tables: misses, not judged (with the reason), passes."""
    parts = []
    for result, anchor, title in (("miss", "claims-miss", "Missed"),
                                  ("n/a", "claims-unjudged", "Not judged at this scale"),
                                  ("pass", "claims-pass", "Passed")):
        c = claims[claims["result"] == result].drop(columns=["source"])
        if result != "n/a":
            c = c.drop(columns=["reason"])
        parts.append(f"<h3 id='{anchor}'>{title} ({len(c)})</h3>")
        if len(c):
            parts.append(table_html(c, left=("study", "scene", "claim", "thesis", "bar",
                                             "measured", "reason"),
                                    classes={"result": {"pass": "pass", "miss": "miss",
                                                        "n/a": "na"}},
                                    name=anchor, max_rows=500))
    return parts


def page(items, claims: pd.DataFrame, prov: dict, varying: dict, res: pd.DataFrame,
         scale: str) -> str:
    """The summary page as one self-contained HTML document: the headline first, then
    the claims, the thesis's items, the tables beside the thesis's, the provenance and
    the resources."""
    _TABLE_IDS.clear()                  # table ids count from 1 on every page
    th = thesis_rows(items, scale)
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>contactbench summary "
             f"({html.escape(scale)})</title><style>{STYLE}</style></head><body>",
             "<h1>contactbench: summary of the regeneration</h1>",
             "<p>Hackl (Linz 1999), <i>frictionless two-body contact</i>: each thesis table and "
             "figure regenerated, each checked claim measured against its bar. Figures and "
             "full tables are in the report's other sections; click a column's header to "
             "sort, type in a box to filter.</p>"]
    parts += headline(items, claims, th, scale)
    parts.append("<h2 id='claims'>Checked claims</h2>")
    parts += claims_html(claims)
    parts.append("<h2 id='thesis'>The thesis's tables and figures</h2>")
    parts.append(thesis_html(th))
    parts.append("<h2>Tables: ours beside the thesis's</h2>")
    for key, keep in INLINE.items():
        for k, scene, path in items:
            if k != key:
                continue
            full = read_csv(path)
            frame = beside_thesis(full, keep)
            parts.append(f"<h3 id='{inline_anchor(key, scene)}'>{html.escape(key)} -- "
                         f"{html.escape(scene or 'all scenes')} "
                         f"<span class='small'>({html.escape(path)})</span></h3>")
            if key in NOTES:
                parts.append(f"<p class='small'>{html.escape(NOTES[key])}</p>")
            parts.append(table_html(frame, left=tuple(c for c in frame.columns
                                                      if frame[c].dtype == object),
                                    name=key))
            rest = [c for c in full.columns if c not in frame.columns]
            if rest:
                parts.append(f"<p class='small'>Also in the file: "
                             f"{html.escape(', '.join(map(str, rest)))}.</p>")
    # provenance
    pk = prov.get("packages", {}) or {}
    prov_rows = [("commit", prov.get("commit")), ("configuration", f"{scale}: "
                  f"{prov.get('configfile')} (sha256 {str(prov.get('config_sha256'))[:12]})"),
                 ("created", prov.get("created")), ("machine", f"{prov.get('cpu_model')}, "
                  f"{prov.get('cpu_count')} logical cores, {prov.get('machine')}, node "
                  f"{prov.get('node')}"),
                 ("threads", f"env {prov.get('threads')}; loaded pools {prov.get('blas')}"),
                 ("python", prov.get("python")),
                 ("solvers", solver_set_text(prov.get("solver_set"))),
                 ("packages", ", ".join(f"{k} {v}" for k, v in pk.items() if v))]
    parts.append("<h2>Provenance</h2><table>" + "".join(
        f"<tr><th class='l'>{k}</th><td class='l'>{html.escape(str(v))}</td></tr>"
        for k, v in prov_rows) + "</table>")
    if "+dirty" in str(prov.get("commit")):
        parts.append("<p class='miss'>The working tree had uncommitted changes when the "
                     "newest result was written.</p>")
    for field, count in varying.items():
        parts.append(f"<p class='miss'>Results disagree on {field}: "
                     + html.escape(", ".join(f"{v} ({n})" for v, n in count.items())) + "</p>")
    # resources
    parts.append("<h2>Run time and peak memory per rule</h2>")
    if len(res):
        per_study = res.groupby("study").agg(jobs=("jobs", "sum"),
                                             wall_s_total=("wall_s_total", "sum"),
                                             max_rss_mb=("max_rss_mb", "max")).reset_index()
        parts.append(table_html(per_study, left=("study",), name="resources"))
        parts.append(table_html(res, left=("study", "rule"), name="rules"))
    else:
        parts.append("<p class='na'>No benchmark files found.</p>")
    parts.append(f"<script>{SCRIPT}</script></body></html>")
    return "\n".join(parts)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--items", nargs="+", required=True, help="key@scene=path")
    ap.add_argument("--benchmarks", default=None, help="the rules' benchmark directory")
    ap.add_argument("--scale", default="", help="name of the configuration (quick, full)")
    ap.add_argument("--html", required=True)
    ap.add_argument("--claims", required=True)
    args = ap.parse_args(argv)
    try:
        items = parse_items(args.items)
    except ValueError as err:
        ap.error(str(err))
    claims = collect_claims(items)
    prov, varying = read_provenance([p for _, _, p in items])
    write_csv(args.claims, claims)
    write_text(args.html, page(items, claims, prov, varying, resources(args.benchmarks),
                               args.scale))


if __name__ == "__main__":
    main()
