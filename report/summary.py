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
import importlib
import re
from collections import Counter
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from report.claims import NOT_REACHED
from report.tables import SCRIPT, STYLE, new_page, table_html
from workflows.io import META, provenance, read_csv, read_json, write_csv, write_text
from workflows.studies import HEAVY_RULES, PATHS, STUDIES, THESIS_ITEMS, claim_keys


def resolve(ref: str) -> Callable:
    """The function a study's declaration names as ``"module:function"``."""
    module, _, name = ref.partition(":")
    return getattr(importlib.import_module(module), name)


#: PATHS key -> claims of that output (a frame with claim, measured, bar, pass): every
#: study's claims tables as they are (``Study.claims``) and the claims its report step
#: derives from a table (``Study.derived_claims``).
CLAIMS: dict[str, Callable[[pd.DataFrame], pd.DataFrame]] = {
    **{key: lambda t: t for key in claim_keys()},
    **{key: resolve(ref) for study in STUDIES.values()
       for key, ref in study.derived_claims.items()}}
#: Tables shown inline (ours beside the thesis's where it has values), each with the
#: columns a reader compares (None: all; ``Study.inline``); every column with a thesis
#: value is shown too, and the rest are named under the table (the file is in the report).
INLINE = {key: cols for study in STUDIES.values() for key, cols in study.inline.items()}
#: What a table's columns mean where a name alone would mislead (``Study.notes``).
NOTES = {key: text for study in STUDIES.values() for key, text in study.notes.items()}
#: The outputs the headline shows and what renders each (``Study.front``), in the order of
#: the studies.
FRONT = [(key, resolve(ref)) for study in STUDIES.values() for key, ref in study.front.items()]

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


#: The columns of the summary's claims file: a claims table's (report/claims.py) with the
#: study, the result and the claims file (``source``).
SUMMARY_CLAIMS = ["study", "scene", "claim", "level", "parameters", "thesis", "measured",
                  "bar", "result", "reason", "source"]


def claims_of_item(key: str, scene: str | None, path: str) -> pd.DataFrame:
    """The claims of one output with its study and file; the scene a row names (a
    scene's variant) or else the output's, the level and conditions empty where a
    claims table written without them has none."""
    c = CLAIMS[key](read_csv(path))
    for column in ("scene", "level", "parameters"):
        values = c[column] if column in c else pd.Series("", index=c.index)
        c[column] = values.fillna("").astype(str).replace("nan", "")
    c.loc[c["scene"] == "", "scene"] = scene or "-"
    return c.assign(study=study_of(key), source=path)


def collect_claims(items) -> pd.DataFrame:
    """Every claim of every configured output (:data:`SUMMARY_CLAIMS`)."""
    frames = [c for key, scene, path in items if key in CLAIMS
              for c in [claims_of_item(key, scene, path)] if len(c)]
    if not frames:
        return pd.DataFrame(columns=SUMMARY_CLAIMS)
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
    return c[SUMMARY_CLAIMS]


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


THESIS_MATE = {"N": "thesis_nodes"}


def thesis_mate(column) -> str:
    """The thesis's column of the same quantity as our ``column``."""
    return THESIS_MATE.get(column, f"thesis_{column}")


def beside_thesis(frame: pd.DataFrame, keep=None) -> pd.DataFrame:
    """The columns ``keep`` (all if None) and every column the thesis has a value for,
    reordered so that each ``thesis_X`` stands right after our ``X``."""
    out = []
    for c in frame.columns:
        if str(c).startswith("thesis_"):
            continue
        mate = thesis_mate(c)
        if keep is None or c in keep or mate in frame.columns:
            out.append(c)
            if mate in frame.columns:
                out.append(mate)
    out += [c for c in frame.columns if str(c).startswith("thesis_") and c not in out]
    return frame[out]


def thesis_mates(frame: pd.DataFrame) -> dict[str, str]:
    """Our column -> the thesis's column of the same quantity, where both are in
    ``frame`` (the inline tables show the thesis's value beneath ours)."""
    mates = {c: thesis_mate(c) for c in frame.columns if not str(c).startswith("thesis_")}
    return {c: mate for c, mate in mates.items() if mate in frame.columns}


def item_path(item) -> str:
    """The output path of a thesis item with its scene filled in (``results/{scene}/x.png``
    of the item on cube_sphere reads ``results/cube_sphere/x.png``); a wildcard the item
    does not fix reads ``<name>``."""
    return re.sub(r"\{(\w+)\}", lambda m: item.problem if m.group(1) == "scene" and
                  item.problem else f"<{m.group(1)}>", PATHS[item.key])


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
            where = f"{item_path(t)}: not at the {scale} scale (a larger one regenerates it)"
        rows.append({"thesis": t.item, "what": t.what, "status": status, "output": where})
    return pd.DataFrame(rows)


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


#: The outputs the HTML report's landing page shows and what renders each
#: (``Study.landing``), in the order of the studies.
LANDING = [(key, resolve(ref)) for study in STUDIES.values()
           for key, ref in study.landing.items()]

#: The report's description without a run's results (``report/workflow.rst``): the
#: landing page keeps its body under the run's headline.
WORKFLOW_RST = Path(__file__).resolve().parent / "workflow.rst"

#: What the suite covers, the title of the report and of the summary page.
TITLE = ("contactbench: elastic two-body contact after Hackl (Linz 1999), frictionless "
         "and frictional, regenerated")


def coverage(items, claims: pd.DataFrame, th: pd.DataFrame) -> tuple[Counter, list, Counter]:
    """What the headline and the landing page count: the claims by result, the scenes and
    test-set families of the run's outputs, the thesis items by status."""
    return (Counter(claims["result"]), sorted({s for _, s, _ in items if s}),
            Counter(th["status"]))


def landing(items, claims: pd.DataFrame, th: pd.DataFrame, scale: str) -> str:
    """The HTML report's landing page (reStructuredText, Snakemake's report description):
    the headline's counts, the leaderboards' verdicts (``Study.landing``), then the
    description of the report's sections (``report/workflow.rst`` without its title)."""
    counts, scenes, status = coverage(items, claims, th)
    lines = [TITLE, "=" * len(TITLE), "",
             f"**Scale {scale or '?'}**: {len(items)} outputs over {len(scenes)} scenes and "
             f"test-set families; of the thesis's {len(th)} tables and figures, "
             f"{status.get('regenerated', 0)} regenerated here, "
             f"{status.get('not in this configuration', 0)} left to a larger scale, "
             f"{status.get('not regenerated', 0)} not regenerated by the suite.", "",
             f"**Claims checked**: {counts.get('pass', 0)} pass, {counts.get('miss', 0)} miss, "
             f"{counts.get('n/a', 0)} not judged at this scale (each with its reason); every "
             "claim with its measured value and bar is in **0 summary → summary**, the misses "
             "first.", ""]
    for key, render in LANDING:
        for k, _, path in items:
            if k == key:
                lines += render(read_csv(path))
    body = WORKFLOW_RST.read_text(encoding="utf-8").split("\n")
    start = next(i for i, line in enumerate(body) if line.startswith("===")) + 1
    return "\n".join(lines + body[start:])


def headline(items, claims: pd.DataFrame, th: pd.DataFrame, scale: str) -> list[str]:
    """The front page: scale and coverage, the claims' counts linking to the misses and
    the unjudged, the solver leaderboard in words and as a table."""
    counts, scenes, status = coverage(items, claims, th)
    parts = ["<h2 id='headline'>Headline</h2><ul class='lead'>",
             f"<li><b>Scale {html.escape(scale or '?')}</b>: {len(items)} outputs over "
             f"{len(scenes)} scenes and test-set families ({html.escape(', '.join(scenes))}); of the "
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
    fronts = [(render, path) for key, render in FRONT
              for k, _, path in items if k == key]
    parts.append("</ul>")
    for render, path in fronts:
        parts += render(read_csv(path))
    return parts


#: The columns of the summary's claims tables, in order, and their headers where the
#: file's name would mislead (the claims file's ``source`` is the claims table's path).
CLAIM_COLUMNS = ["study", "scene", "claim", "level", "parameters", "measured", "bar",
                 "result", "thesis", "reason"]
CLAIM_HEADERS = {"thesis": "source"}
#: Names that may break after their underscores in a claims table (a study's, a scene's).
BREAK_AT_UNDERSCORES = {c: (lambda text: text.replace("_", "_<wbr>")) for c in ("study", "scene")}
#: Why a claims table's cell is empty, where it is not a value missing.
CLAIM_EMPTY = {"level": "a claim about every level, or about none in particular",
               "parameters": "no conditions beyond the claim's title"}


def claims_html(claims: pd.DataFrame) -> list[str]:
    """The claims in three tables: misses, passes, not judged (grouped by the reason and
    collapsed), each claim's title, scene, level and conditions in columns of their own."""
    parts = []
    for result, anchor, title in (("miss", "claims-miss", "Missed"),
                                  ("pass", "claims-pass", "Passed"),
                                  ("n/a", "claims-unjudged", "Not judged at this scale")):
        c = claims.loc[claims["result"] == result, CLAIM_COLUMNS]
        if result != "n/a":
            c = c.drop(columns=["reason"])
        else:           # grouped by their reason
            c = c.sort_values("reason", kind="stable")
        parts.append(f"<h3 id='{anchor}'>{title} ({len(c)})</h3>")
        if not len(c):
            continue
        table = table_html(c, left=("study", "scene", "claim", "parameters", "thesis", "bar",
                                    "measured", "reason"),
                           classes={"result": {"pass": "pass", "miss": "miss", "n/a": "na"}},
                           name=anchor, max_rows=500, headers=CLAIM_HEADERS,
                           empty_why=CLAIM_EMPTY, cell_html=BREAK_AT_UNDERSCORES)
        if result == "n/a":     # collapsed: the reasons first, the rows on a click
            reasons = Counter(c["reason"])
            table = ("<details><summary>" + html.escape("; ".join(
                f"{reason} ({n})" for reason, n in reasons.most_common(6)))
                + ("; ..." if len(reasons) > 6 else "") + "</summary>" + table + "</details>")
        parts.append(table)
    return parts


def page(items, claims: pd.DataFrame, prov: dict, varying: dict, res: pd.DataFrame,
         scale: str) -> str:
    """The summary page as one self-contained HTML document: the headline first, then
    the claims, the thesis's items, the tables beside the thesis's, the provenance and
    the resources."""
    new_page()                          # table ids count from 1 on every page
    th = thesis_rows(items, scale)
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>contactbench summary "
             f"({html.escape(scale)})</title><style>{STYLE}</style></head><body>",
             f"<h1>{html.escape(TITLE)}: summary</h1>",
             "<p>Each thesis table and "
             "figure regenerated, each checked claim measured against its bar. Figures and "
             "full tables are in the report's other sections; click a column's header to "
             "sort, type in a box to filter.</p>"]
    parts += headline(items, claims, th, scale)
    parts.append("<h2 id='claims'>Checked claims</h2>")
    parts += claims_html(claims)
    parts.append("<h2 id='thesis'>The thesis's tables and figures</h2>")
    parts.append(thesis_html(th))
    parts.append("<h2>Tables: ours beside the thesis's</h2><p class='small'>Beneath a value "
                 "of ours, in grey italics, the thesis's value of the same quantity at the "
                 "same level (its 1999 machine for the times).</p>")
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
                                    name=key, below=thesis_mates(frame)))
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
    ap.add_argument("--landing", default=None,
                    help="the HTML report's landing page (reStructuredText) to write")
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
    if args.landing:
        write_text(args.landing, landing(items, claims, thesis_rows(items, args.scale),
                                         args.scale))


if __name__ == "__main__":
    main()
