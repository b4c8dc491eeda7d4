"""The figure audit: what every figure of the report must show, checked on the matplotlib
figure as :func:`report.figures.save_figure` writes it and on the PNG it wrote.

A figure passes when

* its title names its own scene and no other (:func:`scene_problems`);
* every legend entry is drawn: a series with points in the axes, a line style by a line
  of two points or more, a colour of a key in the data (:func:`undrawn_entries`);
* no label, legend, title or tick reads ``nan`` (:func:`nan_texts`);
* a legend inside the axes covers no plotted point (:func:`covering_legends`);
* every panel with data has both axis labels, a time or memory with its unit, and every
  colour-mapped field a labelled colourbar or a key (:func:`label_problems`);
* a legend entry naming a solver shows that solver's colour and marker
  (:func:`report.figures.solver_style`; :func:`solver_entries`), and across figures one
  solver has one style and two solvers never share one (:func:`style_conflicts`);
* its smallest text stays legible when the report shows the image in its frame, about
  :data:`FRAME_PX` wide (:func:`legibility_problem`).

:func:`record` gathers what the PNG's text chunks keep (the problems found on the figure,
the solvers' styles, the smallest font and the resolution); :func:`png_problems` reads
them back with the image's width, so that the regeneration's test checks every figure
without re-plotting it.
"""
from __future__ import annotations

import json
import re

import numpy as np
from matplotlib.colors import to_hex, to_rgba
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.text import Text

#: The width, in pixels, at which the report's frame shows a figure (a wider image is
#: scaled down to it).
FRAME_PX = 950
#: The smallest font size, in pixels in that frame, that still reads.
MIN_TEXT_PX = 7.0
#: The grey of a legend entry that explains an encoding (a preset's line style, filled =
#: verified) rather than naming a series: it stands for every colour.
KEY_GREY = "0.3"
#: A quantity in an axis label (pattern) and the units it must carry (pattern); a label
#: that speaks of a factor, ratio or share is a pure number.
UNITS = {"time": (r"\btime\b|\bT_solve\b", r"[\[(]\s*(?:s|ms|min)\s*[\]),]"),
         "memory": (r"\bmemory\b", r"[\[(]\s*(?:[kMG]i?B)\s*[\]),]")}
PURE_NUMBER = re.compile(r"\bfactor\b|\bratio\b|\bshare\b|\brelative\b|\befficiency\b")
#: The PNG text chunks :func:`record` fills.
KEYS = ("contactbench:problems", "contactbench:solver_styles",
        "contactbench:smallest_font_pt", "contactbench:dpi")


# ------------------------------------------------------------------ helpers
def panels(fig) -> list:
    """The figure's visible axes that draw data (colourbars left out)."""
    return [ax for ax in fig.axes if ax.axison and ax.get_visible() and not is_colorbar(ax)]


def is_colorbar(ax) -> bool:
    """True for the axes of a colourbar."""
    return ax.get_label() == "<colorbar>" or hasattr(ax, "_colorbar")


def _name(ax) -> str:
    """A panel as a reader finds it: its title, else its y label."""
    return repr(ax.get_title() or ax.get_ylabel() or "untitled panel")


def _finite(xy) -> np.ndarray:
    """The rows of ``xy`` (n x 2) with both coordinates finite."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    return xy[np.isfinite(xy).all(axis=1)]


def _line_points(line) -> np.ndarray:
    """The finite points (n x 2, data coordinates) a line draws."""
    x = np.asarray(line.get_xdata(orig=False), dtype=float).ravel()
    y = np.asarray(line.get_ydata(orig=False), dtype=float).ravel()
    return _finite(np.column_stack([x, y])) if len(x) == len(y) else np.empty((0, 2))


def _visible(style) -> bool:
    """True for a marker or line style that draws something."""
    return style not in (None, "", "None", "none", " ")


def _same_colour(a, b) -> bool:
    """True if two matplotlib colours are the same, transparency aside."""
    return np.allclose(to_rgba(a)[:3], to_rgba(b)[:3], atol=2e-3)


def _dashes(line) -> tuple:
    """A line's dash pattern, independent of its width (``'-'`` and ``'solid'`` alike)."""
    _offset, seq = getattr(line, "_unscaled_dash_pattern", (0, None))
    return tuple(np.round(seq, 3)) if seq else ()


def _hollow(line) -> bool:
    """True for a line whose markers are not filled."""
    mfc = line.get_markerfacecolor()
    return isinstance(mfc, str) and mfc.lower() == "none"


# ------------------------------------------------------------------ legend entries drawn
def _legends(fig) -> list[tuple]:
    """``(legend, axes it speaks for)``: an axes' own legend, a figure legend for all."""
    out = [(ax.get_legend(), [ax]) for ax in fig.axes if ax.get_legend() is not None]
    return out + [(leg, panels(fig)) for leg in fig.legends]


def _line_drawn(handle, axes) -> bool:
    """A Line2D entry is drawn if its marker (with its fill) is on a point of the same
    colour and its line style on a line of two points or more (a key entry, in
    :data:`KEY_GREY`, in any colour; a key marker in any shape). A filled entry in a
    colour (a solver's) is drawn by its hollow points too: the fill is the key's to
    explain (verified or not), so a solver none of whose points is filled keeps its entry."""
    key = _same_colour(handle.get_color(), KEY_GREY)
    marker, ls = handle.get_marker(), handle.get_linestyle()
    lines = [ln for ax in axes for ln in ax.lines if ln.get_visible()]
    steps = [p for ax in axes for p in ax.patches if p.get_visible()]

    def colour_ok(artist_colour):
        return key or _same_colour(artist_colour, handle.get_color())

    ok = True
    if _visible(marker):
        ok = any(len(_line_points(ln)) and colour_ok(ln.get_color())
                 and (ln.get_marker() == marker or (key and not _visible(ls)
                                                    and _visible(ln.get_marker())))
                 and (_hollow(ln) == _hollow(handle) or (not key and not _hollow(handle)))
                 for ln in lines)
    if ok and _visible(ls):
        ok = any(len(_line_points(ln)) >= 2 and colour_ok(ln.get_color())
                 and _dashes(ln) == _dashes(handle) and _visible(ln.get_linestyle())
                 for ln in lines) or any(colour_ok(p.get_edgecolor()) for p in steps) \
            or any(colour_ok(c.get_colors()[0]) for c in _segment_sets(axes))
    return ok


def _segment_sets(axes) -> list:
    """The visible line collections of ``axes`` (vlines, hlines) with a segment."""
    return [c for ax in axes for c in ax.collections if c.get_visible()
            and hasattr(c, "get_segments") and len(c.get_segments()) and len(c.get_colors())]


def _patch_drawn(handle, axes) -> bool:
    """A Patch entry is drawn if a patch, a filled collection or an image of the axes
    shows its face colour."""
    colour = handle.get_facecolor()
    for ax in axes:
        if any(_same_colour(p.get_facecolor(), colour) for p in ax.patches if p.get_visible()):
            return True
        for c in ax.collections:
            faces = c.get_facecolors()
            if len(faces) and any(_same_colour(f, colour) for f in faces):
                return True
        for im in ax.images:
            shown = np.asarray(im.to_rgba(im.get_array()), dtype=float).reshape(-1, 4)
            if np.isclose(shown[:, :3], to_rgba(colour)[:3], atol=2e-3).all(axis=1).any():
                return True
    return False


def _collection_drawn(handle, axes) -> bool:
    """A scatter's entry is drawn if a collection of the axes has points."""
    return any(len(c.get_offsets()) for ax in axes for c in ax.collections)


def entry_drawn(handle, axes) -> bool:
    """True if the legend entry ``handle`` has something drawn behind it in ``axes``
    (an entry of a kind not checked counts as drawn)."""
    if isinstance(handle, Line2D):
        return _line_drawn(handle, axes)
    if isinstance(handle, Patch):
        return _patch_drawn(handle, axes)
    if hasattr(handle, "get_offsets"):
        return _collection_drawn(handle, axes)
    return True


def undrawn_entries(fig) -> list[str]:
    """The legend entries of ``fig`` with nothing drawn behind them (a line style no line
    of two points shows, a solver without a point, a key colour absent from the data)."""
    return [f"legend entry {text.get_text()!r} of {_name(axes[0])} is not drawn"
            for legend, axes in _legends(fig)
            for handle, text in zip(legend.legend_handles, legend.get_texts())
            if not entry_drawn(handle, axes)]


# ------------------------------------------------------------------ nan in any text
def _texts(fig) -> list[Text]:
    """Every visible, non-empty text of the figure (titles, labels, ticks, legends,
    annotations)."""
    return [t for t in fig.findobj(Text) if t.get_visible() and t.get_text().strip()]


def nan_texts(fig) -> list[str]:
    """The texts of ``fig`` that read ``nan`` (a number that was never there)."""
    return [f"text reads nan: {t.get_text()!r}" for t in _texts(fig)
            if re.search(r"\bnan\b", t.get_text(), flags=re.I)]


# ------------------------------------------------------------------ legends over data
def _display_points(ax, step: float = 3.0) -> np.ndarray:
    """The display coordinates of what the axes plots: every point of its lines (and
    along their segments every ``step`` pixels), scatter points, the corners and centre of
    bars and patches, inside the axes' box."""
    pts = []
    for ln in ax.lines:
        if not ln.get_visible():
            continue
        xy = ln.get_transform().transform(_line_points(ln))
        pts.append(xy)
        if _visible(ln.get_linestyle()) and len(xy) > 1:
            pts.append(_along(xy, step))
    for c in ax.collections:
        if c.get_visible() and hasattr(c, "get_segments"):
            pts += [_along(c.get_transform().transform(_finite(seg)), step)
                    for seg in c.get_segments() if len(_finite(seg)) > 1]
        elif c.get_visible() and len(c.get_offsets()):
            pts.append(c.get_offset_transform().transform(_finite(c.get_offsets())))
    for p in ax.patches:
        if p.get_visible():
            box = p.get_window_extent()
            pts.append(np.array([[box.x0, box.y0], [box.x1, box.y1], [box.x0, box.y1],
                                 [box.x1, box.y0], [(box.x0 + box.x1) / 2, (box.y0 + box.y1) / 2]]))
    xy = _finite(np.concatenate(pts)) if pts else np.empty((0, 2))
    return xy[_within(xy, ax.get_window_extent())]


def _within(xy: np.ndarray, box) -> np.ndarray:
    """Which display points ``xy`` lie in the box ``box`` (edges included)."""
    return ((xy[:, 0] >= box.x0) & (xy[:, 0] <= box.x1)
            & (xy[:, 1] >= box.y0) & (xy[:, 1] <= box.y1))


def _along(xy: np.ndarray, step: float) -> np.ndarray:
    """Points along the segments of a polyline (display coordinates) every ``step``
    pixels, at most 200 a segment."""
    a, b = xy[:-1], xy[1:]
    n = np.clip((np.hypot(*(b - a).T) / step).astype(int), 1, 200)
    t = np.concatenate([np.arange(k) / k for k in n])
    start = np.repeat(a, n, axis=0)
    return start + t[:, None] * (np.repeat(b, n, axis=0) - start)


def covering_legends(fig) -> list[str]:
    """The legends of ``fig`` that lie over plotted points of an axes they overlap (the
    figure drawn: legends placed, ticks labelled)."""
    if fig.stale:
        fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    out = []
    for legend, axes in _legends(fig):
        box = legend.get_window_extent(renderer).padded(-1.0)
        for ax in axes:
            hidden = int(_within(_display_points(ax), box).sum())
            if hidden:
                out.append(f"the legend covers data of {_name(ax)} ({hidden} plotted points "
                           "under it)")
    return out


# ------------------------------------------------------------------ axis labels, units, keys
def _unit_problem(label: str) -> str | None:
    """A label naming a quantity of :data:`UNITS` without its unit (None if fine)."""
    if PURE_NUMBER.search(label):
        return None
    for quantity, (names, units) in UNITS.items():
        if re.search(names, label, flags=re.I) and not re.search(units, label):
            return f"axis label {label!r}: a {quantity} without its unit"
    return None


def _mapped(ax) -> list:
    """The colour-mapped artists of a panel: images, and collections whose colours come
    from an array of values."""
    return [*ax.images, *(c for c in ax.collections if c.get_array() is not None
                          and np.size(c.get_array()))]


def _keyed(fig, ax, artist) -> bool:
    """True if a colourbar of ``fig`` shows ``artist``'s colour map and norm, or the
    panel has a legend of colours (a categorical key)."""
    for bar in (a._colorbar for a in fig.axes if hasattr(a, "_colorbar")):
        if bar.mappable is artist or (bar.cmap.name == artist.get_cmap().name
                                      and bar.norm.vmin == artist.norm.vmin
                                      and bar.norm.vmax == artist.norm.vmax):
            return True
    legend = ax.get_legend()
    return legend is not None and any(isinstance(h, Patch) for h in legend.legend_handles)


def label_problems(fig) -> list[str]:
    """Panels with data but without an x or y label (an axis without tick labels needs
    none), a time or memory without its unit, a colour-mapped field without a colourbar or
    key, a colourbar without a label."""
    from report.figures import _drawn
    out = []
    for ax in panels(fig):
        if not _drawn(ax):
            continue
        for axis, label in (("x", ax.get_xlabel()), ("y", ax.get_ylabel())):
            ticks = ax.get_xticklabels() if axis == "x" else ax.get_yticklabels()
            if not label.strip() and any(t.get_visible() and t.get_text() for t in ticks):
                out.append(f"{_name(ax)} has no {axis} label")
            elif label.strip() and (problem := _unit_problem(label)):
                out.append(problem)
        out += [f"{_name(ax)}: colours without a colourbar or key" for artist in _mapped(ax)
                if not _keyed(fig, ax, artist)][:1]
    for ax in fig.axes:
        if hasattr(ax, "_colorbar"):
            long = ax.get_ylabel() if ax._colorbar.orientation == "vertical" else ax.get_xlabel()
            if not long.strip():
                out.append("a colourbar without a label")
    return out


# ------------------------------------------------------------------ solver styles
def _solver_of(label: str) -> str | None:
    """The solver a legend label names by its first word (None if none)."""
    from report.figures import REFERENCE_STYLE, solver_order
    first = re.split(r"[\s,:(]", label.strip(), maxsplit=1)[0]
    return first if first in solver_order() or first in REFERENCE_STYLE else None


def solver_entries(fig) -> dict[str, dict]:
    """The legend entries of ``fig`` that name a solver: solver -> ``color`` (hex) and
    ``marker`` ('' for a line without one)."""
    out = {}
    for legend, _axes in _legends(fig):
        for handle, text in zip(legend.legend_handles, legend.get_texts()):
            solver = _solver_of(text.get_text())
            if solver is None or not isinstance(handle, Line2D):
                continue
            marker = handle.get_marker() if _visible(handle.get_marker()) else ""
            out.setdefault(solver, {"color": to_hex(handle.get_color()), "marker": marker})
    return out


def _marker(marker):
    """A marker as one hashable, comparable value: matplotlib's ``(sides, style, angle)``
    markers come back from a figure's JSON metadata as lists."""
    return tuple(marker) if isinstance(marker, list) else marker


def solver_problems(styles: dict[str, dict]) -> list[str]:
    """The entries of :func:`solver_entries` whose colour or marker is not the solver's
    (:func:`report.figures.solver_style`)."""
    from report.figures import solver_style
    out = []
    for solver, style in styles.items():
        own = solver_style(solver)
        if not _same_colour(style["color"], own["color"]) or (
                style["marker"] and _marker(style["marker"]) != own["marker"]):
            out.append(f"solver {solver} drawn as {style['color']} {style['marker'] or 'line'}, "
                       f"not its {to_hex(own['color'])} {own['marker']}")
    return out


def style_conflicts(styles: dict[str, dict[str, dict]]) -> list[str]:
    """Across figures (``figure -> solver_entries``): a solver with more than one colour
    or marker, and two solvers with one colour and one marker."""
    seen: dict[str, set] = {}
    for per_figure in styles.values():
        for solver, style in per_figure.items():
            seen.setdefault(solver, set()).add((to_hex(style["color"]),
                                                _marker(style["marker"])))
    out = []
    for solver, pairs in sorted(seen.items()):
        colours, markers = {c for c, _ in pairs}, {m for _, m in pairs if m}
        if len(colours) > 1 or len(markers) > 1:
            out.append(f"solver {solver} has {len(pairs)} styles across figures: "
                       f"{sorted(pairs, key=str)}")
    owner: dict[tuple, str] = {}
    for solver, pairs in sorted(seen.items()):
        for pair in pairs:
            if pair[1] and owner.setdefault(pair, solver) != solver:
                out.append(f"solvers {owner[pair]} and {solver} share the style {pair}")
    return out


# ------------------------------------------------------------------ legibility
def smallest_font(fig) -> float:
    """The smallest font size (points) of any text the figure shows."""
    sizes = [t.get_fontsize() for t in _texts(fig)]
    return float(min(sizes)) if sizes else float("inf")


def legibility_problem(width_px: int, dpi: float, font_pt: float) -> str | None:
    """Whether the smallest text, ``font_pt`` points at ``dpi``, reads when an image
    ``width_px`` wide is shown in the report's frame (:data:`FRAME_PX`; a wider image is
    scaled down): at least :data:`MIN_TEXT_PX` pixels. None if it does."""
    shown = font_pt * dpi / 72.0 * min(1.0, FRAME_PX / width_px)
    if shown >= MIN_TEXT_PX:
        return None
    return (f"{width_px} px wide, its smallest text ({font_pt:g} pt at {dpi:g} dpi) is "
            f"{shown:.1f} px in the {FRAME_PX} px frame (at least {MIN_TEXT_PX:g})")


# ------------------------------------------------------------------ scenes in titles
def scene_problems(title: str, scene: str, scenes) -> list[str]:
    """A title that does not name its own ``scene`` or names another of ``scenes`` (one
    whose name is not part of the figure's own)."""
    from report.figures import scene_names
    text = title.lower()
    named = lambda s: any(n.lower() in text for n in scene_names(s))      # noqa: E731
    out = [] if not scene or named(scene) else [f"the title does not name the scene {scene}"]
    return out + [f"the title names another scene, {other}" for other in sorted(set(scenes))
                  if scene and other not in scene and named(other)]


# ------------------------------------------------------------------ record and read back
def figure_problems(fig, styles: dict[str, dict] | None = None) -> list[str]:
    """Every problem the figure itself shows (all checks but the title's scene, the
    cross-figure styles and the image's width, which :func:`png_problems` does); ``styles``:
    the figure's :func:`solver_entries`, if already taken. The legends' check comes first:
    it draws the figure, placing legends and labelling ticks."""
    return (covering_legends(fig) + undrawn_entries(fig) + nan_texts(fig)
            + label_problems(fig)
            + solver_problems(solver_entries(fig) if styles is None else styles))


def record(fig, dpi: float) -> dict[str, str]:
    """The PNG text chunks of the audit (:data:`KEYS`), taken from the laid-out figure."""
    styles = solver_entries(fig)
    return {"contactbench:problems": json.dumps(figure_problems(fig, styles)),
            "contactbench:solver_styles": json.dumps(styles, sort_keys=True),
            "contactbench:smallest_font_pt": f"{smallest_font(fig):g}",
            "contactbench:dpi": f"{dpi:g}"}


def png_text(path) -> tuple[dict[str, str], int]:
    """The PNG's text chunks and its width in pixels, after checking that it decodes."""
    from PIL import Image
    with Image.open(path) as im:
        im.verify()
    with Image.open(path) as im:
        im.load()
        return dict(im.text), im.size[0]


def png_problems(path, scenes=()) -> list[str]:
    """Everything the audit finds in the PNG at ``path``: the problems recorded on its
    figure, its title's scene (against the run's ``scenes``) and its legibility at its
    width."""
    text, width = png_text(path)
    missing = [k for k in KEYS if k not in text]
    if missing:
        return [f"no audit record {missing} (not saved by report.figures.save_figure)"]
    out = json.loads(text["contactbench:problems"])
    out += scene_problems(text.get("Title", ""), text.get("contactbench:scene", ""), scenes)
    font = float(text["contactbench:smallest_font_pt"])
    if np.isfinite(font):
        out += [p for p in [legibility_problem(width, float(text["contactbench:dpi"]), font)]
                if p]
    return out
