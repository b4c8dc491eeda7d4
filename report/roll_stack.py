"""The roll stack (thesis Sect. 9.3, Figs. 9.10-9.16): tables, claims and figures.

Reads the outputs of ``workflows/studies/roll_stack/run.py`` for one scene and writes

* ``table``: per strip force and crown, the FE values beside plane-strain Hertz (at the FE
  line load at the barrel centre) and the beam model (sag of both axes, the work roll's
  rise, strip crown, line load), with the resolution (cells across ``2 b``) and the
  equilibrium and spring-force checks;
* ``claims``: equilibrium to 0.5 %; springs below 1e-4 of the strip force; every solve
  verified; Hertz ``b`` and ``p0`` at the barrel centre within 5 % -- judged only where at
  least 8 cells cross the contact width ``2 b`` (else "not judged", with the count);
* ``solver table``: the solvers on the scene at the coarser levels (verified status,
  n_o = iterations, times);
* figures: the strip's line load and the contact pressure on the work roll (Fig. 9.10), the
  mesh (Fig. 9.11), von Mises stress on the cuts ``x = 0`` and ``y = 0`` (Figs. 9.12/9.13),
  the contact line load ``q(x)`` and half-width ``b(x)``, the sag along axes and contact
  lines with and without the crown (Figs. 9.14-9.16), and the strip thickness profile for
  crowned and cylindrical work rolls.

Example::

    python -m report.roll_stack --runs results/roll_stack/roll_stack_runs.csv \\
        --profiles results/roll_stack/roll_stack_profiles.csv \\
        --contact results/roll_stack/roll_stack_contact.csv \\
        --solvers results/roll_stack/roll_stack_solvers.csv \\
        --vtu results/roll_stack/roll_stack_F15MN.vtu results/roll_stack/roll_stack_F30MN.vtu \\
        --table t.csv --claims c.csv --solver-table s.csv --pressure-figure a.png \\
        --mesh-figure b.png --stress-figure c.png --line-load-figure d.png \\
        --sag-figure e.png --strip-figure f.png
"""
from __future__ import annotations

import argparse

import matplotlib.pyplot as plt
import matplotlib.tri as mtri
import numpy as np
import pandas as pd

from reference.roll_stack import THESIS_FIG_9_11
from report.claims import Claim
from report.figure_audit import KEY_GREY
from report.figures import legend_below, save_figure
from workflows.io import read_checked, read_csv, write_csv

#: The suite's bars: equilibrium, springs, Hertz at the barrel centre, resolution needed.
EQUILIBRIUM, SPRINGS, HERTZ, MIN_CELLS = 5e-3, 1e-4, 0.05, 8.0

UM, MM = 1e6, 1e3


def table(runs: pd.DataFrame) -> pd.DataFrame:
    """One row per force and crown: FE beside Hertz and the beam model."""
    t = pd.DataFrame({
        "force_MN": runs.force / 1e6, "crown_um": runs.crown * UM, "level": runs.level,
        "N": runs.N, "NC": runs.m, "status": runs.status, "kkt_max": runs.kkt_max,
        "wall_time_s": runs.wall_time, "peak_mb": runs.peak_mb,
        "equilibrium_error": runs.equilibrium_error, "spring_fraction": runs.spring_fraction,
        "q0_MN_per_m": runs.q0 / 1e6, "q0_beam_MN_per_m": runs.beam_q0 / 1e6,
        "b0_mm": runs.b0 * MM, "b0_hertz_mm": runs.b0_hertz * MM, "dev_b0": runs.dev_b0,
        "p0_nodal_GPa": runs.p0_nodal / 1e9, "p0_hertz_GPa": runs.p0_hertz / 1e9,
        "dev_p0_nodal": runs.dev_p0_nodal, "dev_p0_moment": runs.dev_p0_moment,
        "cells_across_2b": runs.cells_across_2b,
        "sag_work_axis_um": runs.sag_work_axis * UM,
        "sag_work_axis_beam_um": runs.beam_sag_work_axis * UM,
        "sag_backup_axis_um": runs.sag_backup_axis * UM,
        "sag_backup_axis_beam_um": runs.beam_sag_backup_axis * UM,
        "work_roll_rise_um": runs.work_roll_rise * UM,
        "work_roll_rise_beam_um": runs.beam_work_roll_rise * UM,
        "strip_crown_um": runs.strip_crown * UM,
        "strip_crown_surface_um": runs.strip_crown_surface * UM,
        "strip_crown_beam_um": runs.beam_strip_crown * UM,
    })
    return t.sort_values(["crown_um", "force_MN"], ascending=[False, True]).reset_index(drop=True)


#: Sect. 9.3's checks (report/claims.py).
CLAIMS = {
    "equilibrium": Claim("Sect. 9.3", "equilibrium: contact resultant = strip force - "
                         "work-roll weight", "<=", EQUILIBRIUM,
                         details="largest relative error over the runs"),
    "springs": Claim("Sect. 9.3 (the floating work roll)", "weak springs on the floating work "
                     "roll: force / strip force", "<", SPRINGS,
                     details="largest over the runs"),
    "verified": Claim("Sect. 9.3", "every solve verified", "given", "all",
                      details="KKT <= 1e-10, certified energy bound"),
    "hertz": Claim("Sect. 9.3 (Hertz, plane strain)", "Hertz {name} at the barrel centre",
                   "<=", HERTZ, details="{force:g} MN; plane strain, FE line load; "
                   f"{{cells:.1f}} cells across 2b, judged from {MIN_CELLS:g}"),
}


def claims(t: pd.DataFrame) -> pd.DataFrame:
    """The measured claims (claim, thesis, measured, bar, pass) of a :func:`table`; Hertz is
    judged only where ``cells_across_2b >= MIN_CELLS`` (``pass`` empty otherwise)."""
    rows = [CLAIMS["equilibrium"].row(float(t.equilibrium_error.abs().max())),
            CLAIMS["springs"].row(float(t.spring_fraction.max()))]
    ok = int((t.status == "converged").sum())
    rows.append(CLAIMS["verified"].row(f"{ok}/{len(t)}", passed=ok == len(t)))
    crowned = t[t.crown_um == t.crown_um.max()]
    for _, r in crowned.iterrows():
        resolved = bool(r.cells_across_2b >= MIN_CELLS)
        for name, dev in (("half-width b", r.dev_b0), ("peak pressure p0 (nodal)", r.dev_p0_nodal)):
            rows.append(CLAIMS["hertz"].row(float(abs(dev)), judged=resolved,
                                            reason="{cells:.1f} cells across the contact width "
                                            f"2b: too coarse to resolve Hertz (judged from "
                                            f"{MIN_CELLS:g})", force=r.force_MN,
                                            level=int(r.level), name=name,
                                            cells=r.cells_across_2b))
    return pd.DataFrame(rows)


def solver_table(sol: pd.DataFrame) -> pd.DataFrame:
    """The solver runs, ordered by level and time (n_o = iterations of the solver)."""
    if not len(sol):
        return sol
    return sol.sort_values(["level", "status", "wall_time"]).reset_index(drop=True)


def _label(force: float) -> str:
    return f"{force / 1e6:g} MN"


def pressure_figure(profiles: pd.DataFrame, contact: pd.DataFrame, path: str) -> None:
    """Fig. 9.10: the strip's line load on the work roll along x, and the contact pressure
    on the work roll's top (the largest force)."""
    crowned = profiles[profiles.crown == profiles.crown.max()]
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    for i, (force, g) in enumerate(crowned.groupby("force")):
        s = g[g.source == "strip"].sort_values("x")
        edges = np.concatenate([s.x - s.interval / 2, [s.x.iloc[-1] + s.interval.iloc[-1] / 2]])
        ax[0].stairs(s.strip_line_load / 1e6, edges, color=f"C{i}",
                     label=f"strip on the work roll, {_label(force)}")
        q = g[g.source == "fe"].dropna(subset=["q"]).sort_values("x")
        ax[0].plot(q.x, q.q / 1e6, "o-", ms=3, color=f"C{i}", alpha=0.6,
                   label=f"contact WR-BUR, {_label(force)}")
    ax[0].set_xlabel("x along the rolls [m]")
    ax[0].set_ylabel("line load [MN/m]")
    ax[0].set_title("strip load on the work roll (uniform over |x| <= L/2) and contact line load",
                    fontsize=8)
    ax[0].grid(alpha=0.3)
    legend_below(ax[0])
    top = contact[contact.force == contact.force.max()]
    loaded = top[top.pressure > 0]
    sc = ax[1].scatter(top.x, top.y * MM, c=top.pressure / 1e9, s=6, cmap="viridis")
    ax[1].set_xlabel("x along the rolls [m]")
    ax[1].set_ylabel("y (rolling direction) [mm]")
    ax[1].set_ylim(0, max(float(loaded.y.max()) * MM * 1.6, 5) if len(loaded) else None)
    ax[1].set_title(f"contact pressure on the work roll, {_label(top.force.iloc[0])} "
                    "(constrained nodes)", fontsize=8)
    fig.colorbar(sc, ax=ax[1], label="pressure [GPa]")
    save_figure(fig, path)


def _read_vtu(path: str):
    import meshio

    m = meshio.read(read_checked(path))
    cells = m.cells_dict["tetra"]
    vm = np.asarray(m.cell_data_dict["von_mises"]["tetra"], dtype=float)
    # nodal von Mises: the average over the adjacent tetrahedra
    n = len(m.points)
    acc = np.bincount(cells.ravel(), weights=np.repeat(vm, 4), minlength=n)
    cnt = np.bincount(cells.ravel(), minlength=n)
    return m.points, cells, m.point_data["body"].astype(int), acc / np.maximum(cnt, 1), \
        m.point_data["displacement"]


def plane_faces(points, cells, axis: int, tol: float = 1e-9) -> np.ndarray:
    """Triangles (faces of the tetrahedra) lying in the plane ``x_axis = 0``."""
    on = np.abs(points[:, axis]) < tol
    faces = np.vstack([cells[:, [0, 1, 2]], cells[:, [0, 1, 3]], cells[:, [0, 2, 3]],
                       cells[:, [1, 2, 3]]])
    faces = faces[on[faces].all(axis=1)]
    return np.unique(np.sort(faces, axis=1), axis=0)


def mesh_figure(vtu: str, path: str) -> None:
    """Fig. 9.11: the mesh on the cut x = 0 (both rolls, and a zoom on the contact line)
    and on the cut y = 0 (side view)."""
    pts, cells, body, _, _ = _read_vtu(vtu)
    fig, ax = plt.subplots(1, 3, figsize=(14, 4.6), gridspec_kw={"width_ratios": [1, 1, 1.6]})
    f0 = plane_faces(pts, cells, 0)
    for a in ax[:2]:
        a.triplot(pts[:, 1], pts[:, 2], f0, lw=0.3, color="k")
        a.set_aspect("equal")
        a.set_xlabel("y (rolling direction) [m]")
        a.set_ylabel("z [m]")
    thesis = THESIS_FIG_9_11
    ax[0].set_title(f"cut x = 0: {len(pts):,} nodes, {len(cells):,} tetrahedra\n(thesis "
                    f"Fig. 9.11: {thesis['nodes']:,} nodes, {thesis['tetrahedra']:,} "
                    f"tetrahedra, {thesis['inequalities']:,} inequalities)", fontsize=8)
    z0 = float(pts[body == 0, 2].max())
    ax[1].set_xlim(-0.002, 0.03)
    ax[1].set_ylim(z0 - 0.02, z0 + 0.02)
    ax[1].set_title("zoom: the contact line (graded mesh)", fontsize=8)
    f1 = plane_faces(pts, cells, 1)
    ax[2].triplot(pts[:, 0], pts[:, 2], f1, lw=0.2, color="k")
    ax[2].set_xlabel("x along the rolls [m]")
    ax[2].set_ylabel("z [m]")
    ax[2].set_title("cut y = 0 (symmetry plane): x layers", fontsize=8)
    save_figure(fig, path)


def stress_figure(vtus: list[str], forces: list[float], path: str) -> None:
    """Figs. 9.12/9.13: von Mises stress on the cuts x = 0 (whole section and the contact
    zone) and y = 0, for each force."""
    fig, ax = plt.subplots(len(vtus), 3, figsize=(15, 4.2 * len(vtus)), squeeze=False,
                           gridspec_kw={"width_ratios": [1, 1, 1.6]})
    for row, (vtu, force) in enumerate(zip(vtus, forces)):
        pts, cells, body, vm, _ = _read_vtu(vtu)
        f0, f1 = plane_faces(pts, cells, 0), plane_faces(pts, cells, 1)
        z0 = float(pts[body == 0, 2].max())
        near = (np.abs(pts[:, 0]) < 1e-9) & (np.abs(pts[:, 2] - z0) < 0.03)
        vmax = float(np.percentile(vm[near], 99.5)) / 1e6 if near.any() else None
        for col, (tris, a, b) in enumerate(((f0, 1, 2), (f0, 1, 2), (f1, 0, 2))):
            axis = ax[row, col]
            tri = mtri.Triangulation(pts[:, a], pts[:, b], tris)
            im = axis.tripcolor(tri, vm / 1e6, shading="gouraud", cmap="viridis", vmin=0,
                                vmax=vmax if col == 1 else None)
            axis.set_aspect("equal" if col < 2 else "auto")
            axis.set_xlabel(("y (rolling direction)" if col < 2 else "x along the rolls") + " [m]")
            axis.set_ylabel("z [m]")
            fig.colorbar(im, ax=axis, label="von Mises [MPa]")
        ax[row, 0].set_title(f"{_label(force)}: cut x = 0", fontsize=8)
        ax[row, 1].set_xlim(0, 0.025)
        ax[row, 1].set_ylim(z0 - 0.02, z0 + 0.02)
        ax[row, 1].set_title(f"{_label(force)}: cut x = 0, contact zone (stress below the "
                             "surface, Hertz: max at 0.78 b)", fontsize=8)
        ax[row, 2].set_title(f"{_label(force)}: cut y = 0", fontsize=8)
    save_figure(fig, path)


def line_load_figure(profiles: pd.DataFrame, path: str) -> None:
    """Contact line load q(x) and half-width b(x) along the barrel: FE, beam model, and
    plane-strain Hertz at the FE line load."""
    crowned = profiles[profiles.crown == profiles.crown.max()]
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    for i, (force, g) in enumerate(crowned.groupby("force")):
        c = f"C{i}"
        fe = g[(g.source == "fe")].dropna(subset=["q"]).sort_values("x")
        bm = g[(g.source == "beam")].sort_values("x")
        bm = bm[bm.q > 0]
        ax[0].plot(fe.x, fe.q / 1e6, "o", ms=3, color=c, label=f"FE, {_label(force)}")
        ax[0].plot(bm.x, bm.q / 1e6, "-", color=c, label=f"beam model, {_label(force)}")
        ax[1].plot(fe.x, fe.b * MM, "o", ms=3, color=c, label=f"FE (2nd moment), {_label(force)}")
        ax[1].plot(fe.x, fe.b_hertz * MM, "--", color=c,
                   label=f"Hertz at FE q(x), {_label(force)}")
        ax[1].plot(bm.x, bm.b_hertz * MM, ":", color=c, label=f"Hertz at beam q(x), {_label(force)}")
    ax[0].set_ylabel("contact line load q [MN/m]")
    ax[1].set_ylabel("contact half-width b [mm]")
    for a in ax:
        a.set_xlabel("x along the rolls [m]")
        a.grid(alpha=0.3)
        legend_below(a)
    save_figure(fig, path)


def sag_figure(profiles: pd.DataFrame, path: str) -> None:
    """Figs. 9.14-9.16: sag along the axes and the contact lines, without and with the
    crown added back; FE (solid) and beam model (dashed)."""
    crowned = profiles[profiles.crown == profiles.crown.max()]
    forces = sorted(crowned.force.unique())
    fig, ax = plt.subplots(len(forces), 2, figsize=(10.5, 4 * len(forces)), squeeze=False)
    curves = (("work_axis", "WR axis", "C0"), ("backup_axis", "BUR axis", "C1"),
              ("work_contact_line", "WR top (contact) line", "C2"),
              ("backup_contact_line", "BUR bottom (contact) line", "C3"))
    crowned_curves = (("work_contact_line_crowned", "WR top line, crown added back", "C5"),
                      ("work_surface", "WR strip side (axis + crown)", "C4"),
                      ("backup_contact_line", "BUR bottom (contact) line", "C3"))
    for row, force in enumerate(forces):
        g = crowned[crowned.force == force]
        fe, bm = g[g.source == "fe"].sort_values("x"), g[g.source == "beam"].sort_values("x")
        for col, group in enumerate((curves, crowned_curves)):
            a = ax[row, col]
            for name, label, color in group:
                a.plot(fe.x, fe[name] * UM, "-", color=color, label=f"{label}, FE")
                if name in bm:
                    a.plot(bm.x, bm[name] * UM, "--", color=color, label=f"{label}, beam")
            a.set_xlabel("x along the rolls [m]")
            a.set_ylabel("vertical displacement (up) [µm]")
            a.grid(alpha=0.3)
        ax[row, 0].set_title(f"{_label(force)}: sag along lines (as measured)", fontsize=8)
        ax[row, 1].set_title(f"{_label(force)}: with the crown (Schliff) added back", fontsize=8)
    grouped_legend(fig, {label: color for group in (curves, crowned_curves)
                         for _, label, color in group},
                   {"FE": "-", "beam model": "--"})
    save_figure(fig, path)


def grouped_legend(ax, colours: dict[str, str], styles: dict[str, str]) -> None:
    """One legend right of ``ax`` (an axes, or a figure for a legend of all its panels),
    clear of the data: each curve by its colour, then each source by its line style
    (explained once, not per curve)."""
    from matplotlib.lines import Line2D
    handles = [Line2D([], [], color=c, lw=2, label=label) for label, c in colours.items()]
    handles += [Line2D([], [], color=KEY_GREY, ls=ls, label=label) for label, ls in styles.items()]
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0,
              fontsize=7)


def strip_figure(profiles: pd.DataFrame, path: str) -> None:
    """Strip thickness profile h(x) - h(0) for crowned and cylindrical work rolls."""
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    styles = {}
    for i, ((force, crown), g) in enumerate(profiles.groupby(["force", "crown"])):
        c = f"C{i}"
        lab = f"{_label(force)}, crown {crown * UM:g} µm"
        fe = g[g.source == "fe"].dropna(subset=["strip_profile"]).sort_values("x")
        bm = g[g.source == "beam"].dropna(subset=["strip_profile"]).sort_values("x")
        ax.plot(fe.x, fe.strip_profile * UM, "o-", ms=3, color=c)
        ax.plot(fe.x, fe.strip_profile_surface * UM, ":", color=c)
        ax.plot(bm.x, bm.strip_profile * UM, "--", color=c)
        styles[lab] = c
    ax.set_xlabel("x across the strip [m]")
    ax.set_ylabel("strip thickness h(x) - h(0) [µm]")
    ax.grid(alpha=0.3)
    grouped_legend(ax, styles, {"FE (axis + crown)": "-", "FE (bottom line)": ":",
                                "beam model": "--"})
    save_figure(fig, path)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    for name in ("runs", "profiles", "contact", "solvers", "table", "claims", "solver-table",
                 "pressure-figure", "mesh-figure", "stress-figure", "line-load-figure",
                 "sag-figure", "strip-figure"):
        ap.add_argument(f"--{name}", required=True)
    ap.add_argument("--vtu", nargs="+", required=True, help="fields per force (crowned roll)")
    args = ap.parse_args(argv)
    runs = read_csv(args.runs)
    profiles = read_csv(args.profiles)
    t = table(runs)
    write_csv(args.table, t)
    write_csv(args.claims, claims(t))
    write_csv(args.solver_table, solver_table(read_csv(args.solvers)))
    pressure_figure(profiles, read_csv(args.contact), args.pressure_figure)
    forces = sorted(runs.force.unique())
    if len(args.vtu) != len(forces):
        ap.error(f"argument --vtu: {len(args.vtu)} files for {len(forces)} forces")
    mesh_figure(args.vtu[0], args.mesh_figure)
    stress_figure(args.vtu, forces, args.stress_figure)
    line_load_figure(profiles, args.line_load_figure)
    sag_figure(profiles, args.sag_figure)
    strip_figure(profiles, args.strip_figure)


if __name__ == "__main__":
    main()
