"""Interactive Vega-Lite charts beside the report's PNGs: hover a point for its solver,
preset, size, time and error.

A chart is drawn from the same tidy frame as its PNG (the figure's module declares the
data once and hands it to both), its colours and shapes are the PNG's
(:func:`report.figures.solver_style` as the Vega-Lite scales), and it is written as one
self-contained HTML page: Snakemake's report shows an HTML result framed, and the
page carries the vega, vega-lite and vega-embed JavaScript that Snakemake itself
bundles for its report (``snakemake.assets``), so that the report opens offline; they
are packed (gzip, base64: ~0.7 MB) because the report frames the page as a ``data:`` URL,
which Chromium refuses beyond 2 MB. Several charts of one rule share a page.

The rule files import :func:`chart_path` from here; matplotlib (with the palette of
:mod:`report.figures`) is imported only when a chart is drawn.
"""
from __future__ import annotations

import base64
import gzip
import html
import json
import re
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd

from workflows.io import write_text
from workflows.studies import PATHS, path_pattern

#: The Vega-Lite version of the scripts Snakemake bundles (5.x).
SCHEMA = "https://vega.github.io/schema/vega-lite/v5.json"
#: The scripts a page carries, in load order (paths below ``snakemake/assets/data``).
SCRIPTS = ("vega/vega.js", "vega-lite/vega-lite.js", "vega-embed/vega-embed.js")
#: The PATHS keys of the figures that have an interactive chart beside them (the page's
#: path is the PNG's with ``.html``: :func:`chart_path`).
CHARTED = ("solver_profiles", "solver_times")


def _polygon(corners: int, start: float = 90.0, inner: float | None = None,
             squash: float = 1.0) -> str:
    """A Vega-Lite custom shape: a regular polygon (a star where ``inner`` gives the
    radius of its inner corners) as an SVG path in the unit square, the first corner at
    ``start`` degrees, x scaled by ``squash``."""
    radii = [1.0] if inner is None else [1.0, inner]
    steps = corners * len(radii)
    points = []
    for k in range(steps):
        a = np.radians(start + 360.0 * k / steps)
        r = radii[k % len(radii)]
        points.append(f"{squash * r * np.cos(a):.3f},{-r * np.sin(a):.3f}")
    return "M" + "L".join(points) + "Z"


#: A matplotlib marker (report.figures.MARKERS) as a Vega-Lite point shape, one shape a
#: marker: Vega-Lite's own where it has one, an SVG path of matplotlib's where not.
SHAPES = {"o": "circle", "s": "square", "^": "triangle-up", "D": "diamond",
          "v": "triangle-down", "P": "cross", "<": "triangle-left", ">": "triangle-right",
          "X": "M-1,-0.6L-0.6,-1L0,-0.4L0.6,-1L1,-0.6L0.4,0L1,0.6L0.6,1L0,0.4L-0.6,1L-1,0.6"
               "L-0.4,0Z",
          "p": _polygon(5), "h": _polygon(6), "H": _polygon(6, start=0.0),
          "*": _polygon(5, inner=0.4), "d": _polygon(4, squash=0.6), "8": _polygon(8, 22.5),
          (7, 0, 0): _polygon(7), (4, 1, 0): _polygon(4, inner=0.4), "_": "stroke"}
#: A preset's line style (report.figures.PRESET_LINES) as a Vega-Lite stroke dash.
DASHES = {"-": [1, 0], "--": [6, 3], ":": [2, 2]}


def chart_path(figure: str) -> str:
    """The interactive page beside the PNG ``figure`` (same name, ``.html``)."""
    return str(Path(figure).with_suffix(".html"))


def charted(path: str) -> bool:
    """True if the figure at ``path`` is one of :data:`CHARTED` (matched against the
    workflow's path templates)."""
    return any(path_pattern(PATHS[key]).fullmatch(str(path)) for key in CHARTED)


def solver_scales(solvers) -> tuple[dict, dict]:
    """Vega-Lite colour and shape scales giving each solver its PNG colour and marker
    (a matplotlib colour as CSS hex: ``"k"`` is ``#000000``)."""
    from matplotlib.colors import to_hex

    from report.figures import solver_style
    names = sorted(set(solvers))
    styles = [solver_style(s) for s in names]
    return ({"domain": names, "range": [to_hex(s["color"]) for s in styles]},
            {"domain": names, "range": [SHAPES.get(s["marker"], "circle") for s in styles]})


def preset_dashes(presets) -> dict:
    """A Vega-Lite strokeDash scale giving each preset its PNG line style."""
    from report.figures import PRESET_LINES
    names = [p for p in PRESET_LINES if p in set(presets)]
    return {"domain": names, "range": [DASHES[PRESET_LINES[p]] for p in names]}


def records(frame: pd.DataFrame) -> list[dict]:
    """``frame`` as inline Vega-Lite data: plain numbers, a missing or non-finite value
    as null (Vega-Lite leaves such a point out)."""
    out = []
    for row in frame.to_dict(orient="records"):
        clean = {}
        for k, v in row.items():
            if isinstance(v, (np.bool_, bool)):
                clean[str(k)] = bool(v)
            elif isinstance(v, (int, np.integer)):
                clean[str(k)] = int(v)
            elif isinstance(v, (float, np.floating)):
                clean[str(k)] = float(v) if np.isfinite(v) else None
            else:
                clean[str(k)] = None if v is None else str(v)
        out.append(clean)
    return out


def _field(name: str, kind: str = "quantitative", title: str | None = None,
           log: bool = False) -> dict:
    enc = {"field": name, "type": kind, "title": title or name}
    if log:
        enc["scale"] = {"type": "log"}
        enc["axis"] = {"format": "~g", "labelOverlap": "greedy"}
    return enc


def solver_chart(frame: pd.DataFrame, x: tuple, y: tuple, title: str,
                 tooltip: tuple[str, ...] = (), line_by: tuple[str, ...] = (),
                 dash: str | None = None, facet: str | None = None,
                 filled: str | None = None, interpolate: str = "linear",
                 points: bool = True) -> dict:
    """A Vega-Lite spec: one line per solver (and per each column of ``line_by``) through
    the points of ``frame``, coloured and shaped as in the PNGs.

    ``x``, ``y``: ``(column, axis title, log scale)``; ``dash``: a preset column drawn
    as the PNG's line styles; ``facet``: a column with one panel per value; ``filled``:
    a boolean column, a point hollow where False (verified converged or not);
    ``tooltip``: the columns a hover shows (x, y and the solver always)."""
    colour, shape = solver_scales(frame["solver"])
    x_enc = _field(x[0], title=x[1], log=x[2])
    y_enc = _field(y[0], title=y[1], log=y[2])
    shown = dict.fromkeys(["solver", x[0], y[0], *tooltip])
    tips = [{"field": c, "type": "quantitative" if pd.api.types.is_numeric_dtype(frame[c])
             and not pd.api.types.is_bool_dtype(frame[c]) else "nominal"} for c in shown]
    detail = [{"field": c, "type": "nominal"} for c in line_by]
    line_enc = {"x": x_enc, "y": y_enc,
                "color": {"field": "solver", "type": "nominal", "scale": colour,
                          "legend": {"title": "solver"}},
                "detail": detail}
    if dash is not None:
        line_enc["strokeDash"] = {"field": dash, "type": "nominal",
                                  "scale": preset_dashes(frame[dash]),
                                  "legend": {"title": dash}}
    layers = [{"mark": {"type": "line", "interpolate": interpolate, "strokeWidth": 1.4},
               "encoding": line_enc}]
    if points:
        point_enc = {"x": x_enc, "y": y_enc,
                     "color": {"field": "solver", "type": "nominal", "scale": colour,
                               "legend": None},
                     "shape": {"field": "solver", "type": "nominal", "scale": shape,
                               "legend": None},
                     "tooltip": tips}
        mark = {"type": "point", "size": 45, "filled": True}
        if filled is not None:
            mark["filled"] = False
            point_enc["fill"] = {"condition": {"test": f"datum['{filled}']",
                                               "field": "solver", "type": "nominal",
                                               "scale": colour, "legend": None},
                                 "value": "white"}
        layers.append({"mark": mark, "encoding": point_enc})
    else:       # a hover target on the lines themselves
        layers[0]["encoding"]["tooltip"] = tips
    spec = {"$schema": SCHEMA, "title": title, "width": 380, "height": 260,
            "data": {"values": records(frame)}}
    if facet is None:
        return {**spec, "layer": layers}
    del spec["width"], spec["height"]
    return {**spec,
            "facet": {"column": {"field": facet, "type": "ordinal",
                                 "sort": sorted(frame[facet].unique().tolist(), key=_order)}},
            "spec": {"width": 250, "height": 230, "layer": layers},
            "resolve": {"scale": {"x": "independent"}}}


def _order(value) -> tuple:
    """Presets in their order low, mid, high, other values as they sort."""
    from solvers.interface import TOLERANCES
    presets = list(TOLERANCES)
    return (0, presets.index(value), "") if value in presets else (1, 0, str(value))


def script_text(name: str) -> str:
    """The JavaScript ``name`` (one of :data:`SCRIPTS`) from Snakemake's bundled assets;
    raises FileNotFoundError naming it if this Snakemake has none (the page would need
    the network)."""
    path = resources.files("snakemake.assets") / "data" / name
    if not path.is_file():
        raise FileNotFoundError(f"{name}: not among snakemake's bundled report assets "
                                f"({path}); the interactive charts need it to open offline")
    return path.read_text(encoding="utf-8")


def spec_json(spec: dict) -> str:
    """``spec`` as JSON safe inside a ``<script>`` element (no ``</`` to end it early)."""
    return json.dumps(spec, allow_nan=False).replace("</", "<\\/")


def packed_script(name: str) -> str:
    """The script ``name`` (:data:`SCRIPTS`) gzipped and base64-encoded: the page loads
    the three at a quarter of their size, so that Snakemake's report, which frames an
    HTML result as a ``data:`` URL, stays under Chromium's 2 MB limit for one."""
    return base64.b64encode(gzip.compress(script_text(name).encode(), 9, mtime=0)).decode()


#: Unpacks the scripts (``script.vl-lib``, in order; the browser's DecompressionStream)
#: and runs each, then embeds every spec of the page (``script.vl-spec``) in the ``div``
#: it names; a failure is written into the page and to the console.
EMBED = """
async function cbRun(node) {
  const bytes = Uint8Array.from(atob(node.textContent.trim()), c => c.charCodeAt(0));
  const text = await new Response(new Blob([bytes]).stream()
      .pipeThrough(new DecompressionStream('gzip'))).text();
  const script = document.createElement('script');
  script.textContent = text;
  document.head.appendChild(script);
}
(async () => {
  for (const node of document.querySelectorAll('script.vl-lib')) await cbRun(node);
  for (const s of document.querySelectorAll('script.vl-spec')) {
    const div = document.getElementById(s.dataset.target);
    await vegaEmbed(div, JSON.parse(s.textContent),
                    {actions: {export: true, source: false, compiled: false, editor: false}})
      .catch(e => {div.textContent = 'chart failed: ' + e; console.error(e)});
  }
})().catch(e => {document.body.append('charts failed: ' + e); console.error(e)});
"""


def page(charts: list[tuple[str, dict]], title: str) -> str:
    """One self-contained HTML page: a heading and a note per chart (``(note, spec)``),
    each spec inline as JSON (``script.vl-spec``), the scripts inline and packed
    (:func:`packed_script`; no network)."""
    scripts = "".join(f"<script type='application/octet-stream' class='vl-lib' "
                      f"data-name='{s}'>{packed_script(s)}</script>" for s in SCRIPTS)
    blocks = [f"<h2>{html.escape(str(spec.get('title', '')))}</h2>"
              f"<p class='note'>{html.escape(note)}</p>"
              f"<script type='application/json' class='vl-spec' data-target='chart-{i}'>"
              f"{spec_json(spec)}</script><div id='chart-{i}' class='chart'></div>"
              for i, (note, spec) in enumerate(charts)]
    if not blocks:
        blocks = ["<p>Nothing to draw: no solver run in this study has data for a chart.</p>"]
    return ("<!DOCTYPE html><html><head><meta charset='utf-8'>"
            f"<title>{html.escape(title)}</title><style>body{{font-family:system-ui,sans-serif;"
            "margin:1em 1.5em;color:#222}h1{font-size:1.3em}h2{font-size:1.05em;"
            "margin-bottom:.2em}.note{font-size:.85em;color:#555;max-width:60em}</style>"
            f"{scripts}</head><body><h1>{html.escape(title)}</h1>"
            "<p class='note'>Hover a point for its values; the PNGs beside this page in the "
            "report show the same data.</p>" + "".join(blocks)
            + f"<script>{EMBED}</script></body></html>")


def page_scripts(text: str) -> dict[str, str]:
    """The scripts a page written by :func:`page` carries, unpacked: name -> source."""
    found = re.findall(r"<script type='application/octet-stream' class='vl-lib' "
                       r"data-name='([^']+)'>([^<]*)</script>", text)
    return {name: gzip.decompress(base64.b64decode(data)).decode() for name, data in found}


def write_page(path: str, charts: list[tuple[str, dict]], title: str) -> None:
    """Write :func:`page` atomically to ``path``."""
    write_text(path, page(charts, title))


def page_specs(text: str) -> list[dict]:
    """The Vega-Lite specs inline in a page written by :func:`page`."""
    found = re.findall(r"<script type='application/json' class='vl-spec'[^>]*>(.*?)</script>",
                       text, flags=re.S)
    return [json.loads(f) for f in found]


def _encoded_fields(node) -> list[str]:
    """Every ``field`` an encoding, facet or tooltip of ``node`` names (recursively)."""
    out = []
    if isinstance(node, dict):
        if isinstance(node.get("field"), str):
            out.append(node["field"])
        for key, value in node.items():
            if key != "data":
                out += _encoded_fields(value)
    elif isinstance(node, list):
        for value in node:
            out += _encoded_fields(value)
    return out


def spec_problems(spec: dict) -> list[str]:
    """What is wrong with a chart's spec for the report: not Vega-Lite v5 (the version
    Snakemake bundles), data not inline or empty, an encoding naming a field the data do
    not have, a mark without encodings. Empty if none."""
    problems = []
    if spec.get("$schema") != SCHEMA:
        problems.append(f"$schema {spec.get('$schema')!r}, expected {SCHEMA}")
    values = spec.get("data", {}).get("values")
    if not isinstance(values, list) or not values:
        problems.append("data: not inline, or empty")
        return problems
    columns = set().union(*(row.keys() for row in values))
    missing = sorted(set(_encoded_fields(spec)) - columns)
    if missing:
        problems.append(f"encodings name fields the data do not have: {missing}")
    body = spec.get("spec", spec)
    layers = body.get("layer", [body])
    if not all(layer.get("mark") and layer.get("encoding") for layer in layers):
        problems.append("a layer without a mark or encodings")
    return problems
