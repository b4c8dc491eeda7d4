"""Nodal, stabilised and mortar couplings on a contact scene: the claims and the figures
from ``workflows/studies/coupling/run.py``'s tables (one per scene).

The optimal rate: with the contact's pressure edge the solution is in ``H^{5/2-eps}`` at
best, so P1's energy error is ``O(h)`` at best (Hüeber, Wohlmuth, SIAM J. Numer. Anal.
43 (2005), for the mortar discretisation), i.e. ``O(N^{-1/2})`` in 2D and
``O(N^{-1/3})`` in 3D on uniform meshes. The thesis proves less for its nodal
constraints on contact, ``O(h^{1/2})`` under ``H^2`` regularity (Prop. 7.6, (7.8)), and
on the Laplace problem of Ch. 6 shows that nodal constraints on non-matching grids lose
the optimal primal rate unless stabilised (Sect. 6.3, Remark 6.25): a statement about
the Laplace problem and a lower bound on the rate, not a prediction for contact, so the
nodal and stabilised rates are reported beside it, not judged. In 3D the rate judged is
the same O(h): the scenes' lines where a prescribed displacement meets a free surface
(cube-sphere: the rim of the ball's held cap, the cube's clamped bottom edges) carry
``r^{1/2}`` singularities that bound it by ``O(h^{1/2})`` asymptotically, but at the
levels run they hold a few percent of the error, not growing (the table's
``err_share_singular``; the study's page has the numbers).

Claims, per scene: every solve (the reference and every compared one) verified
converged; the fitted energy-error rate against N of each coupling (least squares in
log-log over the finest three levels), the mortar ones (standard and dual) within 0.1 of
the optimal rate, the nodal and stabilised ones reported; at the finest level of each
coupling the contact half-width (2D) or radius (3D) and peak pressure against Hertz's,
and the nodal pressure's discrete L2 deviation from Hertz's over the contact zone
(reported); the fitted rate against N of each coupling's multiplier error in the dual
(energy) norm of the reference's discretisation, ``err_pressure_dual``, the
``H^{-1/2}``-type norm of the mortar theory (reported: Hüeber and Wohlmuth bound it
together with the energy error by ``O(h)``, an upper bound; the Hertz pressure's
square-root edge, in ``H^{1-eps}``, lets its best approximation in ``H^{-1/2}`` fall
as ``O(h^{3/2-eps})``, so no published rate of the multiplier error alone applies).

P2 rows (``order`` 2; the study's ``orders``), each against a P2 reference: their fitted
energy-error rate reported beside P2's optimal ``O(h^{3/2})`` (``N^{-3/4}`` in 2D,
``N^{-1/2}`` in 3D; not judged: the ``r^{1/2}`` singularities at the supports' ends bound
every order by ``O(h^{1/2})`` asymptotically and their share of P2's error is not
measured), their Hertz rows at the finest P2 level; a coupling the scene refuses at P2
(``skipped``) as a row with its reason, left out of the converged count.

Figures: the energy error against N per coupling with the fitted slopes and the optimal
slope; ``a / a_H`` and ``p0 / p0_H`` against N per coupling; P2 rows dashed with open
markers, with P2's optimal slope dash-dotted.

Example::

    python -m report.coupling --tables results/circle_square/coupling.csv \\
        --claims c.csv --figure e.png --hertz-figure h.png
"""
from __future__ import annotations

import argparse

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from report.claims import COLUMNS, Claim
from report.figures import COUPLING_STYLE, drawable, save_figure
from report.rates import fitted_slope
from workflows.io import read_csv, write_csv

#: The optimal energy-error rate against N of P1 on contact, per dimension (module
#: docstring): O(h) = O(N^{-1/d}).
OPTIMAL_RATE = {2: -1 / 2, 3: -1 / 3}
#: The optimal energy-error rate against N of P2 on contact, per dimension: the
#: solution in ``H^{5/2-eps}`` at best gives ``O(h^{3/2})`` = ``O(N^{-3/(2d)})``.
OPTIMAL_RATE_P2 = {2: -3 / 4, 3: -1 / 2}
#: Levels the fitted rates take (the finest ones).
FIT_LEVELS = 3
#: How far a mortar rate may lie from the optimal one.
RATE_BAR = 0.1
MORTAR = ("mortar", "mortar_dual")
#: Where the optimal slopes end: this factor below the smallest error of their order (so
#: that they run beside the measured lines, not on them).
SLOPE_BELOW = 0.7
#: Marker and colour per coupling in the figures (shared with the patch test's).
STYLE = COUPLING_STYLE

CLAIMS = {
    "converged": Claim("suite bar (every compared solve must count)",
                       "PDAS at 'high' verified converged on every compared solve", "given",
                       "all", details="the reference and every coupling and level"),
    "rate_mortar": Claim("Hüeber-Wohlmuth 2005 (O(h) for H^{5/2-eps})",
                         "{coupling}: energy-error rate in N minus the optimal rate",
                         "|<=|", RATE_BAR, details="finest three levels; optimal "
                         "{optimal:.3f} (P1: O(h) = O(N^-1/{dim}))"),
    "rate": Claim("Prop. 7.6 (O(h^1/2) for nodal), Ch. 6 (Laplace)",
                  "{coupling}: energy-error rate in N", details="finest three levels",
                  unjudged="the thesis proves a lower bound for nodal constraints on contact "
                  "((7.8)) and the loss of the optimal rate only on the Laplace problem: "
                  "reported beside the mortar rates"),
    "hertz": Claim("Sects. 9.1/9.2 (Hertz)",
                   "{coupling}: {what} over Hertz's", details="finest level",
                   unjudged="a comparison of the couplings at this scale's finest level; the "
                   "contact_solution study judges Hertz on the suite's scenes"),
    "pressure": Claim("Sect. 6.1 (the multiplier)",
                      "{coupling}: nodal pressure's rms deviation from Hertz",
                      details="over the contact zone, / p0; finest level",
                      unjudged="a discrete L2 norm against Hertz, reported: the "
                      "H^{-1/2}-type norm of the mortar estimates is the dual-norm rate's row"),
    "rate_p2": Claim("Hüeber-Wohlmuth 2005 (regularity H^{5/2-eps}: P2 at best O(h^3/2))",
                     "{coupling}: P2 energy-error rate in N", details="finest three "
                     "levels; optimal {optimal:.3f}: O(h^3/2) in {dim}D",
                     unjudged="reported beside the optimal rate: the r^1/2 singularities "
                     "where a prescribed displacement meets a free surface bound every "
                     "order by O(h^1/2) asymptotically, and P2's error near the contact "
                     "falls faster than P1's, so their share is not small at these levels "
                     "(not measured at P2)"),
    "skipped": Claim("suite bar (a coupling a scene refuses says why)",
                     "{coupling} at P{order}: not solved",
                     unjudged="not solved: the scene refuses this coupling at this "
                     "element order"),
    "rate_dual": Claim("Wohlmuth 2000, Hüeber-Wohlmuth 2005 (multiplier in H^{-1/2})",
                       "{coupling}: rate in N of the multiplier error in the dual norm",
                       details="err_pressure_dual, finest three levels",
                       unjudged="the published estimate bounds energy and H^{-1/2} multiplier "
                       "error together by O(h), an upper bound; the Hertz pressure's "
                       "square-root edge lets the multiplier's best approximation fall as "
                       "O(h^{3/2-eps}): no rate of the multiplier error alone is published"),
}


def compared(t: pd.DataFrame) -> pd.DataFrame:
    """The converged compared solves."""
    return t[(t.role == "compared") & (t.status == "converged")]


def orders(t: pd.DataFrame) -> pd.Series:
    """Each row's element order (1 for a table without the ``order`` column)."""
    return t["order"].fillna(1).astype(int) if "order" in t else pd.Series(1, index=t.index)


def by_coupling(t: pd.DataFrame):
    """``(coupling, order, rows)`` per coupling and element order, in the table's order."""
    for (coupling, order), g in t.groupby([t.coupling, orders(t)], sort=False):
        yield coupling, int(order), g


def rate(g: pd.DataFrame, error: str = "err_energy") -> float:
    """Fitted rate of the column ``error`` against N over the finest :data:`FIT_LEVELS`
    levels (NaN with fewer, or without the column)."""
    g = g.sort_values("N")
    return fitted_slope(g.N, g[error], last=FIT_LEVELS) \
        if len(g) >= FIT_LEVELS and error in g else float("nan")


def claims(t: pd.DataFrame) -> pd.DataFrame:
    """The claims of the module docstring, per scene."""
    rows = []
    for scene, s in t.groupby("scene", sort=True):
        skipped = s[s.status == "skipped"]
        s = s[s.status != "skipped"]
        ok = int((s.status == "converged").sum())
        rows.append(CLAIMS["converged"].row(f"{ok} of {len(s)}", passed=ok == len(s),
                                            scene=scene))
        dim = int(s.dim.iloc[0])
        optimal = OPTIMAL_RATE[dim]
        for coupling, order, g in by_coupling(skipped):
            row = CLAIMS["skipped"].row("skipped", scene=scene, coupling=coupling,
                                        order=order)
            rows.append({**row, "reason": f"{row['reason']}: {g.reason.iloc[0]}"})
        for coupling, order, g in by_coupling(compared(s)):
            r = rate(g)
            if order == 2:
                row = CLAIMS["rate_p2"].row(r, scene=scene, coupling=coupling,
                                            optimal=OPTIMAL_RATE_P2[dim], dim=dim)
                if not np.isfinite(r):
                    row["reason"] = (f"not fitted: needs {FIT_LEVELS} levels; this run has "
                                     f"{len(g)}. {row['reason']}")
                rows.append(row)
                _hertz_rows(rows, g, scene, f"{coupling} P2")
                continue
            if coupling in MORTAR:
                rows.append(CLAIMS["rate_mortar"].row(
                    r - optimal, judged=bool(np.isfinite(r)), scene=scene, coupling=coupling,
                    optimal=optimal, dim=int(s.dim.iloc[0]),
                    reason=f"needs {FIT_LEVELS} levels; this run has {len(g)}"))
            else:
                rows.append(CLAIMS["rate"].row(r, scene=scene, coupling=coupling))
            rows.append(CLAIMS["rate_dual"].row(rate(g, "err_pressure_dual"), scene=scene,
                                                coupling=coupling))
            _hertz_rows(rows, g, scene, coupling)
    return pd.DataFrame(rows, columns=COLUMNS)


def _hertz_rows(rows: list, g: pd.DataFrame, scene: str, coupling: str) -> None:
    """At the finest level of ``g``: a and p0 over Hertz's and the pressure's rms
    deviation (scenes with a Hertz reference)."""
    top = g.sort_values("N").iloc[-1]
    if np.isfinite(top.get("a_hertz", np.nan)):
        for what, ratio in (("a", top.a_moment / top.a_hertz),
                            ("p0", top.p0_moment / top.p0_hertz)):
            rows.append(CLAIMS["hertz"].row(float(ratio), scene=scene, coupling=coupling,
                                            level=int(top.level), what=what))
        rows.append(CLAIMS["pressure"].row(float(top.dev_hertz_rms), scene=scene,
                                           coupling=coupling, level=int(top.level)))


def _label(coupling: str, g: pd.DataFrame, order: int = 1) -> str:
    name = coupling if order == 1 else f"{coupling} P{order}"
    r = rate(g)
    return f"{name}: rate {r:.2f}" if np.isfinite(r) else name


def _style(coupling: str, order: int) -> dict:
    """Line style of a coupling at an element order: P1 solid with filled markers, P2
    dashed with open ones, the coupling's colour and marker at both."""
    style, color = STYLE.get(coupling, ("x-", "k"))
    if order == 1:
        return {"fmt": style, "color": color}
    return {"fmt": style[0] + "--", "color": color, "mfc": "none"}


def _plot(plot, x, y, coupling: str, order: int, label: str) -> None:
    """One coupling's curve in its style (:func:`_style`; a lone point without a line,
    nothing, and no legend entry, without a finite point)."""
    if not (np.isfinite(np.asarray(x, float)) & np.isfinite(np.asarray(y, float))).any():
        return
    kw = _style(coupling, order)
    plot(x, y, drawable(kw.pop("fmt"), x, y), label=label, **kw)


def figure(t: pd.DataFrame, path: str) -> None:
    """The energy error against N per coupling, fitted rates and the optimal slope."""
    scenes = sorted(t.scene.unique())
    fig, ax = plt.subplots(len(scenes), 1, figsize=(6.5, 4.5 * len(scenes)), squeeze=False)
    for a, scene in zip(ax[:, 0], scenes):
        s = t[t.scene == scene]
        c = compared(s)
        for coupling, order, g in by_coupling(c):
            g = g.sort_values("N")
            _plot(a.loglog, g.N, g.err_energy, coupling, order, _label(coupling, g, order))
        dim = int(s.dim.iloc[0])
        for order, optimal, ls, text in ((1, OPTIMAL_RATE[dim], ":", "optimal, O(h)"),
                                         (2, OPTIMAL_RATE_P2[dim], "-.",
                                          "P2 optimal, O(h^3/2)")):
            co = c[orders(c) == order]
            if len(co):
                n = np.array([float(co.N.min()), float(co.N.max())])
                e0 = SLOPE_BELOW * float(co.err_energy.min()) * (n[1] / n[0]) ** -optimal
                a.loglog(n, e0 * (n / n[0]) ** optimal, ls, color="gray",
                         label=f"N^{optimal:.2f} ({text})")
        ref = s[s.role == "reference"]
        refs = [f"{r.coupling} P{o} level {int(r.level)}"
                for (_, r), o in zip(ref.iterrows(), orders(ref))]
        a.set_title(f"{scene}: energy error against the reference"
                    + (f" ({', '.join(refs)})" if refs else ""), fontsize=9)
        a.set_xlabel("nodes N")
        a.set_ylabel("||P u_h - u_ref||_A / ||u_ref||_A")
        a.grid(True, which="both", alpha=0.3)
        a.legend(fontsize=8)
    save_figure(fig, path)


def hertz_figure(t: pd.DataFrame, path: str) -> None:
    """``a / a_H`` and ``p0 / p0_H`` (moments of the nodal forces) against N per coupling."""
    scenes = sorted(t.scene.unique())
    fig, ax = plt.subplots(len(scenes), 2, figsize=(11, 4.2 * len(scenes)), squeeze=False)
    for row, scene in zip(ax, scenes):
        c = compared(t[t.scene == scene])
        size = "contact radius" if (t[t.scene == scene].dim == 3).all() else "half-width"
        for coupling, order, g in by_coupling(c):
            if "a_hertz" not in g or not np.isfinite(g.a_hertz).any():
                continue
            g = g.sort_values("N")
            label = coupling if order == 1 else f"{coupling} P{order}"
            _plot(row[0].semilogx, g.N, g.a_moment / g.a_hertz, coupling, order, label)
            _plot(row[1].semilogx, g.N, g.p0_moment / g.p0_hertz, coupling, order, label)
        for a, what in zip(row, (f"{size} a / a_H", "peak pressure p0 / p0_H")):
            a.axhline(1.0, color="gray", ls=":", label="Hertz")
            a.set_title(f"{scene}: {what}", fontsize=9)
            a.set_xlabel("nodes N")
            a.set_ylabel(what)
            a.grid(True, which="both", alpha=0.3)
            a.legend(fontsize=8)
    save_figure(fig, path)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tables", nargs="+", required=True)
    parser.add_argument("--claims", required=True)
    parser.add_argument("--figure", required=True)
    parser.add_argument("--hertz-figure", required=True)
    args = parser.parse_args(argv)
    t = pd.concat([read_csv(p) for p in args.tables], ignore_index=True)
    write_csv(args.claims, claims(t))
    figure(t, args.figure)
    hertz_figure(t, args.hertz_figure)


if __name__ == "__main__":
    main()
