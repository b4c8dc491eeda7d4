"""The roll stack of a four-high mill (thesis Sect. 9.3, Figs. 9.10-9.16): both strip
forces solved at one mesh level, profiles along the rolls beside the beam model and
plane-strain Hertz, fields, and the solvers on the scene at coarser levels.

For every strip force (``--forces``) and work-roll crown (``--crowns``: the crowned roll
of the thesis, 150 um, and a cylindrical one for the strip profile) the scene
(:mod:`problems.roll_stack`) at ``--level`` is solved by the exact reference: PDAS
through the dual problem on the contact rows with the floating work roll's vertical
translation kept as an unknown of each step (:class:`solvers.kernels.cholesky.FloatingCholesky`,
``solvers/pdas.py``), verified to KKT residuals <= 1e-10 with a certified energy bound.
Then (quarter model: forces of the whole stack are 4x the model's):

* equilibrium: contact resultant against strip force minus the work roll's weight
  (meshed volume x weight density), the springs' force as a fraction of the strip force;
* along the barrel (one value per ``x`` layer): the contact line load ``q(x)`` (the
  constrained nodes' forces per tributary length, both halves in ``y``), the half-width
  ``b(x)`` and peak ``p0(x)`` by the pressure's second moment (``b^2 = 4 <y^2>``, as
  :func:`reference.hertz.moment_estimate`) and the nodal peak; plane-strain Hertz
  (:func:`reference.hertz.two_cylinders`) at the FE ``q(x)`` and the local radii;
* sag (vertical displacement, up) along the work roll's and the backup roll's axes, along
  their contact lines (work-roll top, backup-roll bottom) and along the work roll's
  strip-side line (its bottom), with and without the crown added back;
* the strip thickness profile ``h(x) - h(0) = 2 (s(x) - s(0))`` over ``|x| <= L/2``, with
  ``s`` the work roll's strip-side position: from its axis plus the crown (the beam
  model's definition) and from its bottom surface line (including the local
  flattening under the strip's bite);
* the strip's line load on the work roll along ``x`` (Fig. 9.10);
* the beam model (:func:`reference.roll_stack.solve`) at the same force and crown.

Writes, into ``--outdir``: ``roll_stack_runs.csv`` (one row per force and crown),
``roll_stack_profiles.csv`` (per force, crown, source and ``x``: ``fe`` per x layer,
``beam``, ``strip`` the strip's line load per interval between layers),
``roll_stack_contact.csv`` (per constrained node of the crowned runs), ``roll_stack_solvers.csv``
(every solver in ``--solvers`` at ``--solver-levels``, and the augmented projection alone at
``--alg84-levels``, 15 MN crowned; n_o is the outer iteration count of the augmented
projection, with its kappa(S-hat), gamma_bar, A-hat kind, kappa(V A), Chebyshev degree,
S-hat kind and V-cycles), and ``roll_stack_F{MN}MN.vtu`` per force
(crowned). Every file is written atomically with its provenance sidecar.

Example::

    python -m workflows.studies.roll_stack.run --problem roll_stack --level 3 \\
        --forces 15e6 30e6 --crowns 150e-6 0 --solver-levels 0 1 \\
        --solvers pdas osqp augmented_projection --outdir results/roll_stack
"""
from __future__ import annotations

import argparse
import gc
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from problems.fem.elasticity import boundary_facets
from problems.fem.fields import contact_fields
from problems.fem.two_body import assemble_two_body, spring_forces
from problems.roll_stack import SHOULDER, UNITS, _radius, scene, stack_geometry
from problems.spec import Options, ParameterError
from reference import roll_stack as beam
from reference.hertz import effective_modulus, two_cylinders
from solvers.interface import solve, solvers
from workflows.io import write_csv, write_vtu
from workflows.measure import peak_rss
from workflows.progress import study_progress
from workflows.scene_args import add_scene_arguments, check_levels, scene_from_args

#: Verified KKT tolerance of the study's solves (the reference's).
TOL = 1e-10


#: The running study's bar (:mod:`workflows.progress`), set by :func:`main`.
_PROGRESS: list = []


def log(msg: str) -> None:
    """Progress on stdout (the rule's log) and on the console's progress line."""
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", flush=True)
    for bar in _PROGRESS:
        bar.set_postfix_str(msg[:120])
        bar.update()


def work_roll_weight(points: np.ndarray, cells: np.ndarray, body_of_node: np.ndarray,
                     weight_density: float) -> float:
    """Weight of the meshed work roll (body 0): its tetrahedra's volume times the weight
    density (the scene's gravity load sums to exactly this)."""
    c = cells[body_of_node[cells[:, 0]] == 0]
    x = points[c]
    vol = np.abs(np.einsum("ij,ij->i", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]),
                           x[:, 3] - x[:, 0])).sum() / 6
    return float(vol * weight_density)


def tributary(layers: np.ndarray) -> np.ndarray:
    """Tributary length of each ``x`` layer (``layers`` sorted, the first at the symmetry
    plane x = 0: half a spacing there)."""
    mid = 0.5 * (layers[1:] + layers[:-1])
    lo = np.concatenate([[layers[0]], mid])
    hi = np.concatenate([mid, [layers[-1]]])
    return hi - lo


def line(points, disp, body_of_node, body, z_of_x, tol):
    """``(x, u_z)`` along the material line ``y = 0, z = z_of_x(x)`` of one body."""
    on = np.flatnonzero((body_of_node == body) & (np.abs(points[:, 1]) < tol))
    x, z = points[on, 0], points[on, 2]
    keep = np.abs(z - z_of_x(x)) < tol
    on = on[keep]
    order = np.argsort(points[on, 0])
    return points[on[order], 0], disp[on[order], 2]


def analyse(qp, sc, res, p, level: int) -> tuple[dict, pd.DataFrame, pd.DataFrame]:
    """Summary row, FE profiles along ``x`` and the per-node contact table of one solve."""
    ell = UNITS[p.units][0]
    s = stack_geometry(Options({**p.flat(), "units": "m"}))
    Rw, Rb = s.work_diameter / 2, s.backup_diameter / 2
    quarter = p.model == "quarter"
    mirror_y = 2.0 if quarter else 1.0
    share = 4.0 if quarter else 2.0
    mesh = qp.mesh
    pts = mesh.points / ell
    disp = qp.full_displacement(res.u) / ell
    tol = 1e-9
    # equilibrium
    contact = share * float((res.p[:, None] * qp.contact.direction).sum(axis=0)[2])
    weight = share * work_roll_weight(mesh.points, mesh.cells, mesh.body_of_node,
                                      p.weight_density * UNITS[p.units][2])
    spring = share * spring_forces(sc, qp, res.u)
    expected = p.force - weight
    # contact line load and half-width per layer
    xc = pts[qp.contact.nodes]
    layers_w = np.unique(np.round(pts[mesh.body_of_node == 0, 0], 12))
    trib = dict(zip(layers_w, tributary(layers_w)))
    rows = []
    for xj in np.unique(np.round(xc[:, 0], 12)):
        on = np.abs(xc[:, 0] - xj) < tol
        y, f = xc[on, 1], res.p[on]
        lj = trib[xj]
        q = mirror_y * f.sum() / lj
        if quarter:
            yy = np.concatenate([y, -y[y > tol]])
            ff = np.concatenate([np.where(y > tol, f, 2 * f), f[y > tol]])
        else:
            yy, ff = y, f
        ff = ff / lj
        loaded = ff > 0
        if ff.sum() > 0:
            ybar = (ff * yy).sum() / ff.sum()
            b = float(np.sqrt(4.0 * (ff * (yy - ybar) ** 2).sum() / ff.sum()))
        else:
            b = 0.0
        pressure = res.p[on] / qp.contact.mass[on] * ell ** 2       # Pa
        r_w = Rw - float(np.nan_to_num(s.crown_drop(xj)))
        r_b = Rb - float(np.nan_to_num(s.relief_drop(xj)))
        b_h, p0_h = two_cylinders(q, r_w, r_b, effective_modulus(s.E, s.nu, s.E, s.nu))
        spacing = np.diff(np.sort(yy[loaded])) if loaded.sum() > 1 else np.array([np.nan])
        rows.append({"x": xj, "q": q, "b": b, "p0_moment": 2 * q / (np.pi * b) if b > 0 else 0.0,
                     "p0_nodal": float(pressure.max()), "b_hertz": float(b_h),
                     "p0_hertz": float(p0_h), "n_loaded": int(loaded.sum()),
                     "h_y": float(np.median(np.diff(np.sort(np.unique(yy))))),
                     "loaded_spacing": float(np.median(spacing))})
    prof = pd.DataFrame(rows).set_index("x")
    # sag lines (y = 0)
    s_w = lambda x: _radius(x, Rw, s.work_barrel_length / 2, s.work_neck_diameter / 2,  # noqa: E731
                            s.crown_drop, SHOULDER)
    s_b = lambda x: _radius(x, Rb, s.backup_barrel_length / 2, s.backup_neck_diameter / 2,  # noqa: E731
                            s.relief_drop, SHOULDER)
    zb = Rw + Rb
    lines = {
        "work_axis": line(pts, disp, mesh.body_of_node, 0, lambda x: 0 * x, 1e-9),
        "backup_axis": line(pts, disp, mesh.body_of_node, 1, lambda x: 0 * x + zb, 1e-9),
        "work_contact_line": line(pts, disp, mesh.body_of_node, 0, s_w, 1e-9),
        "backup_contact_line": line(pts, disp, mesh.body_of_node, 1, lambda x: zb - s_b(x), 1e-9),
        "work_strip_line": line(pts, disp, mesh.body_of_node, 0, lambda x: -s_w(x), 1e-9),
    }
    lines = {k: (np.round(x, 12), w) for k, (x, w) in lines.items()}   # one key per layer
    xs = np.unique(np.concatenate([v[0] for v in lines.values()]))
    out = pd.DataFrame({"x": xs})
    for name, (x, w) in lines.items():
        out[name] = np.interp(xs, x, w, left=np.nan, right=np.nan)
    on_barrel = np.abs(xs) <= s.work_barrel_length / 2 + 1e-12
    cw = np.where(on_barrel, s.crown_drop(np.where(on_barrel, xs, 0.0)), np.nan)
    # with the crown added back: the surface's position relative to the unloaded position
    # of the barrel centre (a crowned roll's surface at x lies c_w(x) inside it)
    out["work_contact_line_crowned"] = out["work_contact_line"] - cw
    out["work_surface"] = out["work_axis"] + cw             # beam model's definition
    out["work_strip_surface"] = out["work_strip_line"] + cw
    half = s.strip_width / 2
    in_strip = out["x"] <= half + 1e-12
    for col, name in (("work_surface", "strip_profile"), ("work_strip_surface", "strip_profile_surface")):
        s0 = float(out.loc[out.x.abs() < 1e-12, col].iloc[0])
        out[name] = np.where(in_strip, 2 * (out[col] - s0), np.nan)
    # the strip's line load on the work roll along x (Fig. 9.10): the traction's resultant
    # per interval between x layers (facet areas times the pressure, by facet centroid),
    # per length; both halves in y. (Nodal sums per layer would show the tetrahedral
    # split's uneven lumping, not the load.)
    tr = sc.tractions[0]
    cw_cells = mesh.cells[mesh.body_of_node[mesh.cells[:, 0]] == 0]
    facets = boundary_facets(cw_cells, mesh.points)
    facets = facets[tr.on(mesh.points[facets].mean(axis=1))]
    v = mesh.points[facets]
    area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
    fz = area * float(tr.traction[2])                                      # N per facet
    cx = v[:, :, 0].mean(axis=1) / ell
    bins = np.searchsorted(layers_w, cx) - 1
    per = np.bincount(bins, weights=fz, minlength=len(layers_w) - 1)[:len(layers_w) - 1]
    strip = pd.DataFrame({"x": 0.5 * (layers_w[1:] + layers_w[:-1]),
                          "strip_line_load": mirror_y * per / np.diff(layers_w),
                          "interval": np.diff(layers_w)})
    out = out.merge(prof.reset_index(), on="x", how="left")
    # summary at the barrel centre
    c0 = prof.loc[prof.index.min()]
    h_c = float(c0["h_y"])
    strip_crown = float(out.loc[out.x.abs() < 1e-12, "strip_profile"].iloc[0]
                        - out.loc[np.abs(out.x - half) < 1e-9, "strip_profile"].iloc[0])
    strip_crown_s = float(out.loc[out.x.abs() < 1e-12, "strip_profile_surface"].iloc[0]
                          - out.loc[np.abs(out.x - half) < 1e-9, "strip_profile_surface"].iloc[0])
    at0 = out.loc[out.x.abs() < 1e-12].iloc[0]
    row = {
        "force": p.force, "crown": p.crown, "level": level, "model": p.model,
        "N": qp.n_nodes, "n": qp.n, "m": qp.m, "solver": res.solver, "status": res.status,
        "kkt_max": res.kkt.max, "energy_bound": res.gap.certified_bound,
        "energy_bound_floor": res.gap.floor,
        "steps": res.iterations, "factor_time": res.stats.get("factor_time", np.nan),
        "contact_force": contact, "expected_force": expected, "work_roll_weight": weight,
        "equilibrium_error": contact / expected - 1,
        "spring_force": float(np.linalg.norm(spring)),
        "spring_fraction": float(np.linalg.norm(spring)) / p.force,
        "q0": float(c0["q"]), "b0": float(c0["b"]), "b0_hertz": float(c0["b_hertz"]),
        "p0_moment": float(c0["p0_moment"]), "p0_nodal": float(c0["p0_nodal"]),
        "p0_hertz": float(c0["p0_hertz"]), "h_c": h_c, "cells_across_2b": 2 * float(c0["b"]) / h_c,
        "dev_b0": float(c0["b"] / c0["b_hertz"] - 1),
        "dev_p0_moment": float(c0["p0_moment"] / c0["p0_hertz"] - 1),
        "dev_p0_nodal": float(c0["p0_nodal"] / c0["p0_hertz"] - 1),
        "sag_work_axis": float(at0["work_axis"]), "sag_backup_axis": float(at0["backup_axis"]),
        "work_roll_rise": float(out.loc[np.abs(out.x - s.work_bearing_span / 2) < 1e-9,
                                        "work_axis"].iloc[0]),
        "strip_crown": strip_crown, "strip_crown_surface": strip_crown_s,
    }
    table = pd.DataFrame({"x": xc[:, 0], "y": xc[:, 1], "z": xc[:, 2], "p": res.p,
                          "pressure": res.p / qp.contact.mass * ell ** 2})
    return row, pd.concat([out.assign(source="fe"), strip.assign(source="strip")],
                          ignore_index=True), table


def beam_profiles(p) -> tuple[dict, pd.DataFrame]:
    """The beam model (:func:`reference.roll_stack.solve`) at the scene's force and crown, SI."""
    s = stack_geometry(Options({**p.flat(), "units": "m"}))
    sol = beam.solve(p.force, s)
    keep = sol.x >= -1e-12
    frame = pd.DataFrame({name: getattr(sol, name)[keep] for name in (
        "x", "q", "half_width", "peak_pressure", "work_axis", "backup_axis",
        "work_contact_line", "backup_contact_line", "work_surface", "strip_profile")})
    frame = frame.rename(columns={"half_width": "b_hertz", "peak_pressure": "p0_hertz"})
    frame["work_contact_line_crowned"] = frame["work_contact_line"] - np.where(
        np.abs(frame.x) <= s.work_barrel_length / 2, s.crown_drop(frame.x.clip(upper=s.work_barrel_length / 2)), np.nan)
    row = {"beam_q0": sol.at("q", 0.0), "beam_b0": sol.at("half_width", 0.0),
           "beam_sag_work_axis": sol.at("work_axis", 0.0),
           "beam_sag_backup_axis": sol.at("backup_axis", 0.0),
           "beam_work_roll_rise": sol.work_roll_rise, "beam_strip_crown": sol.strip_crown,
           "beam_contact_force": sol.contact_force}
    return row, frame


#: Alg. 8.4's own columns in the solver table (Sect. 9.3 reports its times): kappa(S-hat),
#: gamma_bar of A-hat, the Chebyshev degree of A-hat, the S-hat kind and the V-cycles.
ALG84_STATS = ("kappa_S", "gamma_bar", "ahat_kind", "kappa_vcycle", "ahat_degree", "schur_kind",
               "n_vcycles")


def solver_runs(spec, params, levels, names, time_limit) -> pd.DataFrame:
    """Every solver in ``names`` on the 15 MN crowned scene at each level (tolerance 1e-6,
    the ``mid`` preset): verified status, iterations (n_o for the augmented projection),
    times, KKT residual, certified bound."""
    rows = []
    for level in levels:
        qp = spec.build(level, params)
        for name in names:
            opts = {}
            label = name
            if name == "pdas_kkt":
                name, opts = "pdas", {"method": "kkt"}
            t0 = time.perf_counter()
            res = solve(qp, name, tol="mid", time_limit=time_limit, **opts)
            wall = time.perf_counter() - t0
            kkt = res.kkt.max if res.kkt is not None else np.nan      # none when skipped
            bound, floor = ((res.gap.certified_bound, res.gap.floor) if res.gap is not None
                            else (np.nan, np.nan))
            rows.append({"level": level, "N": qp.n_nodes, "n": qp.n, "m": qp.m, "solver": label,
                         "status": res.status, "claimed_status": res.claimed_status,
                         "iterations": res.iterations, "setup_time": res.setup_time,
                         "solve_time": res.solve_time, "wall_time": wall,
                         "kkt_max": kkt, "energy_bound": bound, "energy_bound_floor": floor,
                         "message": res.message[:200],
                         **{k: res.stats.get(k, np.nan) for k in ALG84_STATS}})
            log(f"solver {label} at level {level}: {res.status} ({res.iterations} it, "
                f"{wall:.1f} s, KKT {kkt:.1e})" + (f": {res.message}" if res.status == "skipped"
                                                  else ""))
    return pd.DataFrame(rows)


def build_parser() -> argparse.ArgumentParser:
    """The study's command line: the level, the cases, the solver comparison."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(parser)
    parser.add_argument("--level", type=int, required=True, help="mesh level of the study")
    parser.add_argument("--forces", type=float, nargs="+", default=[15e6, 30e6],
                        help="strip forces, N (each in the scene's 'force' range)")
    parser.add_argument("--crowns", type=float, nargs="+", default=[150e-6, 0.0],
                        help="work-roll crowns on the diameter, m (the first is the crowned "
                             "roll whose fields are written; 0 = cylindrical)")
    parser.add_argument("--solver-levels", type=int, nargs="*", default=[],
                        help="levels of the solver comparison (15 MN, first crown)")
    parser.add_argument("--solvers", nargs="*", default=[],
                        help="registered solvers (and 'pdas_kkt') for the comparison")
    parser.add_argument("--alg84-levels", type=int, nargs="*", default=[],
                        help="further levels at which the augmented projection (Alg. 8.4) "
                             "alone runs (Sect. 9.3 reports its times)")
    parser.add_argument("--time-limit", type=float, default=600.0, help="seconds per solve (> 0)")
    parser.add_argument("--alg84-time-limit", type=float, default=None,
                        help="seconds per solve at --alg84-levels (> 0; default --time-limit): "
                             "level 3 takes ~8 min, where the QP libraries' limit is minutes")
    parser.add_argument("--outdir", required=True)
    return parser


def checked_cases(parser: argparse.ArgumentParser, args) -> tuple:
    """The checked arguments: ``(spec, level, solver levels, Alg. 8.4 levels, Alg. 8.4's
    time limit, cases)``, a case the scene's options at one force and crown; a bad value
    ends with the parser's error naming the argument."""
    spec, params = scene_from_args(parser, args)
    if spec.name != "roll_stack":
        parser.error(f"argument --problem: {spec.name!r} is not allowed; allowed: roll_stack")
    (level,) = check_levels(parser, spec, [args.level])
    solver_levels = check_levels(parser, spec, args.solver_levels)
    alg84_levels = check_levels(parser, spec, args.alg84_levels)
    known = set(solvers()) | {"pdas_kkt"}
    bad = [s for s in args.solvers if s not in known]
    if bad:
        parser.error(f"argument --solvers: {bad} not allowed; allowed: {', '.join(sorted(known))}")
    for name, value in (("--time-limit", args.time_limit),
                        ("--alg84-time-limit", args.alg84_time_limit)):
        if value is not None and not value > 0:
            parser.error(f"argument {name}: {value} is not allowed; allowed: > 0")
    cases = []
    try:
        for force in args.forces:
            for crown in args.crowns:
                cases.append(spec.options(**{**params.flat(), "force": force, "crown": crown}))
    except ParameterError as err:
        parser.error(str(err).replace("parameter 'force'", "argument --forces").replace(
            "parameter 'crown'", "argument --crowns"))
    return (spec, params, level, solver_levels, alg84_levels,
            args.alg84_time_limit or args.time_limit, cases)


def run_case(p, level: int, time_limit: float, fields_to: Path | None) -> tuple:
    """One case (a force and a crown) at ``level``: built, solved exactly (PDAS), analysed
    beside the beam model; its ``(row, profiles, contact table)``, and its contact fields
    written to ``fields_to`` (VTU) when given."""
    tag = f"F = {p.force / 1e6:g} MN, crown {p.crown * 1e6:g} um"
    t0 = time.perf_counter()
    sc = scene(level, p)
    qp = assemble_two_body(sc, 0, name=f"roll_stack level {level} ({p.model})")
    qp.level = level           # (each level is its own single mesh, problems.roll_stack)
    t_build = time.perf_counter() - t0
    log(f"{tag}: level {level}, {qp.n_nodes} nodes, {qp.m} constraints, built in "
        f"{t_build:.1f} s")
    t1 = time.perf_counter()
    with peak_rss() as mem:
        # the exact reference at every level: the slender rolls' factor stays small
        # (nested dissection cuts them across), so no size limit applies here
        res = solve(qp, "pdas", tol=TOL, time_limit=time_limit, method="schur")
    t_solve = time.perf_counter() - t1
    row, prof, table = analyse(qp, sc, res, p, level)
    brow, bprof = beam_profiles(p)
    row.update({"build_time": t_build, "solve_time": t_solve,
                "wall_time": t_build + t_solve, "peak_mb": mem["peak_mb"], **brow})
    profiles = [prof.assign(force=p.force, crown=p.crown),
                bprof.assign(force=p.force, crown=p.crown, source="beam")]
    if fields_to is not None:
        write_vtu(fields_to, contact_fields(qp, res.u, res.p))
    log(f"{tag}: {res.status} by {res.solver} (KKT {res.kkt.max:.1e}) in {t_solve:.1f} s; "
        f"equilibrium {row['equilibrium_error']:+.2e}, springs {row['spring_fraction']:.1e} F, "
        f"b0 {row['b0'] * 1e3:.2f} mm ({row['dev_b0']:+.1%} vs Hertz, "
        f"{row['cells_across_2b']:.1f} cells across 2b), sag WR {row['sag_work_axis'] * 1e6:.0f} "
        f"um (beam {row['beam_sag_work_axis'] * 1e6:.0f}), strip crown "
        f"{row['strip_crown'] * 1e6:.1f} um (beam {row['beam_strip_crown'] * 1e6:.1f})")
    return row, profiles, table


def main(argv=None) -> None:
    parser = build_parser()
    args = parser.parse_args(argv)
    (spec, params, level, solver_levels, alg84_levels, alg84_time_limit,
     cases) = checked_cases(parser, args)
    out = Path(args.outdir)
    _PROGRESS[:] = [study_progress(rule="roll_stack_study", out=out / "roll_stack_runs.csv",
                                   desc="roll stack", unit="step", file=sys.stderr)]
    rows, profiles, contacts = [], [], []
    for p in cases:
        crowned = p.crown == args.crowns[0]   # the crowned roll: its fields and contact
        row, prof, table = run_case(p, level, args.time_limit, out / (
            f"roll_stack_F{p.force / 1e6:g}MN.vtu") if crowned else None)
        rows.append(row)
        profiles += prof
        if crowned:
            contacts.append(table.assign(force=p.force))
        gc.collect()          # frees the factorisation (PARDISO memory) before the next run
    write_csv(out / "roll_stack_runs.csv", pd.DataFrame(rows))
    write_csv(out / "roll_stack_profiles.csv", pd.concat(profiles, ignore_index=True))
    write_csv(out / "roll_stack_contact.csv", pd.concat(contacts, ignore_index=True))
    p0 = spec.options(**{**params.flat(), "force": args.forces[0], "crown": args.crowns[0]})
    sol = pd.concat([solver_runs(spec, p0, solver_levels, args.solvers, args.time_limit),
                     solver_runs(spec, p0, [lv for lv in alg84_levels if lv not in solver_levels
                                            or "augmented_projection" not in args.solvers],
                                 ["augmented_projection"], alg84_time_limit)], ignore_index=True)
    write_csv(out / "roll_stack_solvers.csv", sol if len(sol) else pd.DataFrame(
        columns=["level", "N", "n", "m", "solver", "status", "claimed_status", "iterations",
                 "setup_time", "solve_time", "wall_time", "kkt_max", "energy_bound",
                 "energy_bound_floor", "message",
                 *ALG84_STATS]))
    log("done")
    _PROGRESS.pop().close()


if __name__ == "__main__":
    main()
