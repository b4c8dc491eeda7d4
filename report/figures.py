"""Shared figure helpers: one solver palette and marker set, the scene in every title,
and every figure saved the same way, atomically, with what it shows recorded.

A solver has the same colour and marker in every figure of the report
(:func:`solver_style`); every figure of a scene names that scene in its title
(:func:`save_figure` adds it where the figure's own titles do not); a figure with
nothing to draw says why instead of showing empty axes (:func:`nothing_to_draw`).
:func:`save_figure` writes into the PNG's text chunks the titles, the number of drawn
data artists and the number of empty panels, and the figure audit's record
(:mod:`report.figure_audit`: legends, labels, solver styles, the smallest font;
:data:`AUDIT_KEYS`), so that the figure audit (``tests/test_regeneration.py``) can check
each figure without re-plotting it.
"""
from __future__ import annotations

import re
import zlib
from functools import lru_cache

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.ticker import (FixedLocator, FuncFormatter, LogLocator,
                               NullFormatter)

from report import figure_audit
from workflows.io import atomic_path
from workflows.studies import PATHS, path_pattern

#: The report's solver colours: the built-in solvers (sorted) take these in turn, then
#: the report's other rows (:data:`EXTRA_SOLVERS`); colour and marker together tell
#: every solver apart, and solvers whose markers look alike at a few pixels (a plus and
#: a star, the hexagons) get colours of different hues.
PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
           "#7f7f7f", "#bcbd22", "#17becf", "#393b79", "#e7ba52", "#637939", "#843c39",
           "#7b4173", "#8c6d31", "#de9ed6", "#00a087")
#: One marker fewer than colours: the pair (colour, marker) repeats only after
#: 18 x 17 solvers.
#: (The last two are matplotlib's (sides, style, angle) markers: a heptagon and a
#: four-pointed star, filled like the others.)
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "p", "h", "*", "d", "H", "8",
           (7, 0, 0), (4, 1, 0))
#: Rows of the report that are not registered solvers but are drawn like one.
EXTRA_SOLVERS = ("pdas_kkt",)
#: Drawn in black: the floors and references every solver is measured against.
REFERENCE_STYLE = {"linear_floor": dict(color="k", marker="_"),
                   "reference": dict(color="k", marker="*")}
#: The thesis's values wherever a figure overlays them (a colour no solver has).
THESIS_COLOR = "#b15928"
#: Format and colour per contact coupling, the same in the coupling study's figures and
#: the patch test's.
COUPLING_STYLE = {"nodal": ("o-", "C0"), "stabilised": ("s-", "C1"), "two_pass": ("v-", "C4"),
                  "mortar": ("^-", "C2"), "mortar_dual": ("D-", "C3")}
#: Line style per tolerance preset (a preset is a line style in every figure).
PRESET_LINES = {"low": ":", "mid": "--", "high": "-"}
#: PNG text chunks :func:`save_figure` writes for the figure audit.
AUDIT_KEYS = ("Title", "contactbench:scene", "contactbench:data_artists",
              "contactbench:empty_panels", "contactbench:nothing_to_draw", *figure_audit.KEYS)


@lru_cache(maxsize=1)
def solver_order() -> tuple[str, ...]:
    """The solvers in palette order: the built-in ones sorted, then the extra rows. A
    plug-in takes its colour from its name (:func:`solver_style`), so that installing
    one changes no other solver's colour."""
    from solvers.interface import external_solvers, solvers
    plugins = set(external_solvers())
    return (*sorted(n for n in solvers() if n not in plugins), *EXTRA_SOLVERS)


def solver_style(name: str) -> dict:
    """Colour and marker of ``name``, the same in every figure (``color``, ``marker``).

    An unregistered name gets a colour and marker from a hash of its name (stable
    between runs and machines)."""
    if name in REFERENCE_STYLE:
        return dict(REFERENCE_STYLE[name])
    order = solver_order()
    i = order.index(name) if name in order else len(order) + zlib.crc32(name.encode()) % 97
    return {"color": PALETTE[i % len(PALETTE)], "marker": MARKERS[i % len(MARKERS)]}


def solver_shades(name: str, n: int) -> list[str]:
    """``n`` colours for variants of one solver: its own colour first, then shades of it
    alternately darker and lighter, so that the variants stay the solver's and are told
    apart from each other."""
    from matplotlib.colors import to_hex, to_rgb
    base = np.array(to_rgb(solver_style(name)["color"]))
    out = [to_hex(base)]
    for k in range(1, n):
        toward = np.zeros(3) if k % 2 else np.ones(3)
        out.append(to_hex(base + (toward - base) * min(0.25 * ((k + 1) // 2), 0.6)))
    return out


def drawable(fmt: str, x, y) -> str:
    """The format string ``fmt`` without its line where ``(x, y)`` has fewer than two
    finite points: a line through one point draws nothing, and its legend entry would
    show a line that is not there."""
    finite = np.isfinite(np.asarray(x, dtype=float)) & np.isfinite(np.asarray(y, dtype=float))
    return fmt if finite.sum() > 1 else re.sub(r"--|-\.|-|:", "", fmt)


def scene_of(path: str) -> str | None:
    """The scene a figure belongs to, read from its path against the workflow's path
    templates (``results/{scene}/...``); None for a figure across scenes."""
    for template in PATHS.values():
        if "{scene}" not in template or not template.endswith(".png"):
            continue
        m = path_pattern(template).fullmatch(str(path))
        if m:
            return m.group("scene")
    return None


def scene_names(scene: str) -> tuple[str, ...]:
    """How a title may spell a scene: ``cube_sphere``, ``cube-sphere``, ``cube sphere``."""
    return (scene, scene.replace("_", "-"), scene.replace("_", " "))


def titles(fig) -> str:
    """The figure's suptitle and every axes' title, joined by `` | ``."""
    parts = [fig._suptitle.get_text()] if fig._suptitle is not None else []
    for ax in fig.axes:
        parts += [t.get_text() for t in (ax.title, ax._left_title, ax._right_title)]
    return " | ".join(p for p in parts if p)


def _drawn(ax) -> int:
    """The data artists of one axes: lines and collections with points, images, bars."""
    lines = sum(1 for line in ax.lines if len(line.get_xdata()) > 0)
    coll = sum(1 for c in ax.collections
               if len(getattr(c, "get_offsets", lambda: [])()) or len(c.get_paths()))
    return lines + coll + len(ax.images) + len(ax.patches)


def name_scene(fig, scene: str | None) -> None:
    """Put ``scene`` into the figure's suptitle unless a title already names it."""
    if scene is None:
        return
    text = titles(fig).lower()
    if any(name.lower() in text for name in scene_names(scene)):
        return
    old = fig._suptitle.get_text() if fig._suptitle is not None else ""
    size = fig._suptitle.get_fontsize() if fig._suptitle is not None else 10
    fig.suptitle(f"{scene}: {old}" if old else f"scene {scene}", fontsize=size)


def save_figure(fig, path: str, dpi: int = 130, scene: str | None = None) -> None:
    """Name the scene (``scene``, else read from ``path``), label every log axis sparsely
    (:func:`sparse_log_ticks`), tight layout, write the PNG atomically to ``path`` with
    its audit text (:data:`AUDIT_KEYS`; :func:`report.figure_audit.record`), close the
    figure."""
    scene = scene or scene_of(path)
    name_scene(fig, scene)
    panels = figure_audit.panels(fig)
    for ax in panels:
        for axis in ("x", "y"):
            if (ax.get_xscale() if axis == "x" else ax.get_yscale()) == "log":
                sparse_log_ticks(ax, axis)
    drawn = [_drawn(ax) for ax in panels]
    meta = {"Title": titles(fig), "contactbench:scene": scene or "",
            "contactbench:data_artists": str(sum(drawn)),
            "contactbench:empty_panels": str(sum(1 for d in drawn if d == 0)),
            "contactbench:nothing_to_draw": getattr(fig, "nothing_to_draw", "")}
    fig.tight_layout()
    clear_suptitle(fig)
    meta.update(figure_audit.record(fig, dpi))
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format="png", metadata=meta, bbox_inches="tight")
    plt.close(fig)


def clear_suptitle(fig, pad: float = 6.0) -> None:
    """Lower the panels until their titles clear the suptitle by ``pad`` pixels (a tall
    figure's tight layout can leave them overlapping)."""
    if fig._suptitle is None or not fig.axes:
        return
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    bottom = fig._suptitle.get_window_extent(renderer).y0
    top = max(max(ax.bbox.y1, ax.title.get_window_extent(renderer).y1 if ax.get_title() else 0)
              for ax in fig.axes if ax.get_visible())
    if top + pad > bottom:
        shift = (top + pad - bottom) / fig.bbox.height
        pars = fig.subplotpars
        fig.subplots_adjust(top=max(pars.top - shift, pars.bottom + 0.5 * (pars.top - pars.bottom)))


def nothing_to_draw(path: str, title: str, reason: str, scene: str | None = None) -> None:
    """Write, in place of a figure without data, a small image saying why (``reason``)."""
    fig = plt.figure(figsize=(6.0, 1.6))
    fig.suptitle(title, fontsize=10)
    fig.text(0.5, 0.4, f"Nothing to draw: {reason}", ha="center", va="center", fontsize=9,
             wrap=True, color="0.3")
    fig.nothing_to_draw = reason
    save_figure(fig, path, scene=scene)


def sparse_log_ticks(ax, axis: str = "x") -> None:
    """Label a log axis at decades; over less than ~1.5 decades at a few 1-2-5 (or
    1-1.5-2-3-5-7) values in plain numbers. Minor ticks stay unlabelled, so no crowded
    ``4x10^3 6x10^3`` labels."""
    target = ax.xaxis if axis == "x" else ax.yaxis
    lo, hi = sorted(ax.get_xlim() if axis == "x" else ax.get_ylim())
    target.set_minor_formatter(NullFormatter())
    if not (lo > 0 and hi / lo < 30):
        target.set_major_locator(LogLocator(base=10, numticks=8))
        return
    ticks = []
    for mantissas in ((1.0, 2.0, 5.0), (1.0, 1.5, 2.0, 3.0, 5.0, 7.0)):
        decades = range(int(np.floor(np.log10(lo))), int(np.ceil(np.log10(hi))) + 1)
        ticks = [m * 10.0 ** k for k in decades for m in mantissas if lo <= m * 10.0 ** k <= hi]
        if len(ticks) >= 2:
            break
    if len(ticks) < 2:
        ticks = [float(f"{v:.2g}") for v in (lo * (hi / lo) ** 0.15, lo * (hi / lo) ** 0.85)]
    target.set_major_locator(FixedLocator(ticks))
    target.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))


def legend_outside(ax, **kwargs) -> None:
    """The axes' legend right of the plot, clear of the data (nothing if no labels)."""
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                  borderaxespad=0.0, **{"fontsize": 7, **kwargs})


def legend_below(ax, ncol: int = 1, x: float = 0.5, **kwargs) -> None:
    """The axes' legend under the plot, clear of the data: centred at ``x`` (axes
    fraction) just below the x tick labels and the x label, whatever the axes' height, in
    ``ncol`` columns (nothing if no labels)."""
    from matplotlib.transforms import ScaledTranslation
    handles, labels = ax.get_legend_handles_labels()
    if not handles:
        return
    tick = max((t.get_fontsize() for t in ax.get_xticklabels()), default=10)
    label = ax.xaxis.label
    lines = label.get_text().count("\n") + 1 if label.get_text() else 0
    drop = (tick * 1.4 + 8 + label.get_fontsize() * 1.25 * lines) / 72      # inches
    below = ax.transAxes + ScaledTranslation(0, -drop, ax.figure.dpi_scale_trans)
    ax.legend(handles, labels, loc="upper center", bbox_to_anchor=(x, 0), ncol=ncol,
              bbox_transform=below, **{"fontsize": 7, **kwargs})


def solver_legend(ax, solvers, lines=(), status: bool = True, axes=None) -> None:
    """One legend right of the axes, each encoding explained once: a solver by colour and
    marker, then ``lines`` (label, line keywords: a preset's or level's line style, a
    guide), then filled = verified converged, hollow = not (``status``). An entry with
    nothing drawn behind it in ``axes`` (default: ``ax``; a line style no line of two
    points shows, a fill no marker has) is left out
    (:func:`report.figure_audit.entry_drawn`). For several ``axes`` the legend is the
    figure's, still placed right of ``ax``."""
    from matplotlib.lines import Line2D
    key = figure_audit.KEY_GREY
    handles = [Line2D([], [], ls="none", **solver_style(s), label=s) for s in solvers]
    handles += [Line2D([], [], **{"color": key, **kw}, label=label) for label, kw in lines]
    if status:
        handles += [Line2D([], [], color=key, marker="o", ls="none",
                           label="verified converged"),
                    Line2D([], [], color=key, marker="o", mfc="none", ls="none",
                           label="not verified")]
    axes = list(axes or [ax])
    shown = [h for h in handles if figure_audit.entry_drawn(h, axes)]
    if not shown:
        return
    place = dict(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=7)
    if len(axes) > 1:
        ax.figure.legend(handles=shown, bbox_transform=ax.transAxes, **place)
    else:
        ax.legend(handles=shown, **place)
