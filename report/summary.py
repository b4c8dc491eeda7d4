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
from workflows.io import META, provenance, read_csv, read_json, write_csv, write_text
from workflows.studies import HEAVY_RULES, PATHS, STUDIES, THESIS_ITEMS

#: PATHS key -> claims of that output (a frame with claim, measured, bar, pass).
CLAIMS: dict[str, Callable[[pd.DataFrame], pd.DataFrame]] = {
    "laplace_rates": laplace.claims,
    "hertz": contact.claims,
    "ap_claims": lambda t: t,
    "exact_claims": lambda t: t,
    "adaptive_accuracy": lambda t: adaptive.claims(accuracy=t),
    "adaptive_pileup": lambda t: adaptive.claims(pileup=t),
    "patch_table": lambda t: adaptive.claims(patch=t),
    "hard_table": hard_cases.claims,
    "hard_nu_claims": lambda t: t,
    "roll_claims": lambda t: t,
    "eo_claims": lambda t: t,
    "ps_claims": lambda t: t,
}

#: Tables shown inline (ours beside the thesis's where it has values).
INLINE = ("ap_table", "adaptive_table", "hertz", "laplace_rates", "exact_table",
          "solver_summary", "roll_table")

STYLE = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:1.2em 2em;
     color:#222;max-width:1400px}
h1{font-size:1.5em;margin-bottom:.2em} h2{font-size:1.2em;border-bottom:1px solid #ccc;
   margin-top:1.6em} h3{font-size:1em;margin-bottom:.3em}
table{border-collapse:collapse;font-size:.8em;margin:.4em 0 1em}
th,td{border:1px solid #ddd;padding:2px 6px;text-align:right;vertical-align:top}
th{background:#f3f3f3} td.l,th.l{text-align:left}
.pass{background:#e3f5e1;color:#1a6b1a;font-weight:600}
.miss{background:#fde2e1;color:#a11;font-weight:600}
.na{background:#f4f4f4;color:#666} .small{font-size:.8em;color:#555}
.wide{overflow-x:auto}
.counts span{margin-right:1.2em;font-weight:600}
"""


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
                                     "result", "source"])
    c = pd.concat(frames, ignore_index=True)
    c["result"] = [("n/a" if p is None or (isinstance(p, float) and np.isnan(p)) else
                    "pass" if str(p).lower() in ("true", "1", "1.0") else "miss")
                   for p in c["pass"]]
    if "thesis" not in c:
        c["thesis"] = "-"
    c["thesis"] = c["thesis"].fillna("-")
    return c[["study", "scene", "claim", "thesis", "measured", "bar", "result", "source"]]


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
    if isinstance(x, (bool, np.bool_)):
        return str(bool(x))
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    if isinstance(x, (float, np.floating)):
        if np.isnan(x):
            return ""
        return f"{x:.4g}"
    try:                      # numbers read back as text (mixed columns)
        return f"{float(x):.4g}" if str(x).strip().lower() not in ("nan", "inf", "-inf") \
            and not str(x).strip().isdigit() else html.escape(str(x))
    except ValueError:
        return html.escape(str(x))


def table_html(frame: pd.DataFrame, left: tuple[str, ...] = (), classes: dict | None = None,
               max_rows: int = 60) -> str:
    """A compact HTML table (numbers to 4 digits; ``classes``: column -> value -> class)."""
    head = "".join(f'<th class="{"l" if c in left else ""}">{html.escape(str(c))}</th>'
                   for c in frame.columns)
    body = []
    for _, row in frame.head(max_rows).iterrows():
        cells = []
        for c in frame.columns:
            cls = ["l"] if c in left else []
            if classes and c in classes:
                cls.append(classes[c].get(str(row[c]), ""))
            cells.append(f'<td class="{" ".join(cls)}">{_fmt(row[c])}</td>')
        body.append("<tr>" + "".join(cells) + "</tr>")
    more = (f'<p class="small">{len(frame) - max_rows} more rows in the file.</p>'
            if len(frame) > max_rows else "")
    return (f"<div class='wide'><table><tr>{head}</tr>{''.join(body)}</table></div>{more}")


def thesis_rows(items, config_files: str) -> pd.DataFrame:
    """Every thesis item, its output files and whether this run regenerated them."""
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
            status, where = "not in this configuration", f"{PATHS[t.key]} ({config_files})"
        rows.append({"thesis": t.item, "what": t.what, "status": status, "output": where})
    return pd.DataFrame(rows)


def page(items, claims: pd.DataFrame, prov: dict, varying: dict, res: pd.DataFrame,
         scale: str) -> str:
    """The summary page as one self-contained HTML document."""
    counts = Counter(claims["result"])
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>contactbench summary "
             f"({html.escape(scale)})</title><style>{STYLE}</style></head><body>",
             "<h1>contactbench: summary of the regeneration</h1>",
             "<p>Hackl (Linz 1999), <i>frictionless two-body contact</i>: each thesis table and "
             "figure regenerated, each checked claim measured against its bar. Figures and "
             "full tables are in the report's other sections.</p>"]
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
    # claims
    parts.append("<h2>Checked claims</h2><p class='counts'>"
                 f"<span class='pass'>{counts.get('pass', 0)} pass</span>"
                 f"<span class='miss'>{counts.get('miss', 0)} miss</span>"
                 f"<span class='na'>{counts.get('n/a', 0)} not judged at this scale</span></p>")
    parts.append(table_html(claims.drop(columns=["source"]),
                            left=("study", "scene", "claim", "thesis", "bar", "measured"),
                            classes={"result": {"pass": "pass", "miss": "miss", "n/a": "na"}},
                            max_rows=500))
    # thesis items
    th = thesis_rows(items, prov.get("configfile") or scale)
    parts.append("<h2>The thesis's tables and figures</h2>")
    parts.append(table_html(th, left=tuple(th.columns), classes={"status": {
        "regenerated": "pass", "not regenerated": "miss", "not in this configuration": "na"}},
        max_rows=100))
    # inline tables
    parts.append("<h2>Tables: ours beside the thesis's</h2>")
    for key in INLINE:
        for k, scene, path in items:
            if k != key:
                continue
            frame = read_csv(path)
            parts.append(f"<h3>{html.escape(key)} -- {html.escape(scene or 'all scenes')} "
                         f"<span class='small'>({html.escape(path)})</span></h3>")
            parts.append(table_html(frame, left=tuple(c for c in frame.columns
                                                      if frame[c].dtype == object)))
    # resources
    parts.append("<h2>Run time and peak memory per rule</h2>")
    if len(res):
        per_study = res.groupby("study").agg(jobs=("jobs", "sum"),
                                             wall_s_total=("wall_s_total", "sum"),
                                             max_rss_mb=("max_rss_mb", "max")).reset_index()
        parts.append(table_html(per_study, left=("study",)))
        parts.append(table_html(res, left=("study", "rule")))
    else:
        parts.append("<p class='na'>No benchmark files found.</p>")
    parts.append("</body></html>")
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
