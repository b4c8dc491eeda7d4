"""Tables and figures of the adaptive study (Sect. 7.4, Tables 9.2/9.4, Figs. 7.3/7.4,
9.2/9.4/9.7) and of the contact patch test.

``tables`` reads ``adaptive_steps.csv`` of one scene (``workflows/studies/adaptive/run.py``)
and, when the scene runs with the thesis's parameters, the thesis's table
(``--thesis reference/table_9_2.csv`` or ``table_9_4.csv``), and writes

* ``--table``: our run of the table variant (eta_1 + eta_2) in the thesis's columns
  (N, N^C, n_o at 1e-2 and 1e-3, mean n_i, T_solve, T_proj, kappa(S-hat), plus the
  multigrid levels of the adaptive hierarchy), the thesis's rows beside it (``source``);
* ``--accuracy``: per variant the energy error against the reference at the finest
  compared step, its fitted rate against N, the node-saving factor at the finest
  uniform level's error, force error and Hertz deviations; the reference and the
  estimate of its own error;
* ``--pileup``: per variant (last step and a common N) the nodes of both contact
  surfaces in the contact zone, their ratio, the nodal pressure's zig-zag and its rms
  deviation from Hertz;
* ``--convergence``: Sect. 7.3 under uniform refinement: energy error (globally and
  in the contact zone, near the singular points, elsewhere), pressure and force
  errors, fitted rates in h against the O(h^1/2) of (7.8).

How the reference's own error is estimated (for absolute errors and rates only; the
node-saving factor does not need it): every compared mesh is nested in the reference,
so ``e_h^2 = m_h^2 + e_ref^2`` with ``m_h`` the measured difference (Galerkin
orthogonality), and the residual estimator eta_1 is proportional to the error with the
same efficiency constant on the reference and on a compared mesh, so each compared mesh
gives ``e_ref = m_h / sqrt(eta_h^2/eta_ref^2 - 1)`` (:func:`reference_error`: the
median; the spread is reported). A fit of ``e_L = C N_L^-s`` to the uniform levels alone
(:func:`uniform_fit`) is reported beside it as a check.

``figures``: the meshes near the contact per variant (Figs. 7.3/7.4), a snapshot of the
table variant's mesh (Fig. 9.4; 3D: its contact surfaces, Fig. 9.9), max eta_T against
N (Figs. 9.2/9.7), the accuracy per node and the nodal pressures against Hertz.

``patch``: the patch-test summary table and its figure.
"""
from __future__ import annotations

import argparse
import re

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.tri import Triangulation

from report.claims import Claim
from report.figures import COUPLING_STYLE, legend_below, legend_outside, save_figure
from report.rates import fitted_slope
from workflows.io import write_csv

TABLE_VARIANT = "eta1+eta2"
STYLE = {"uniform": ("k", "o", "-"), "eta1": ("tab:orange", "s", "-"),
         "eta1+eta2": ("tab:blue", "^", "-"), "stabilised": ("tab:green", "d", "-"),
         "reference": ("0.5", "*", "")}


def _style(variant: str):
    return STYLE.get(variant, ("tab:green", "d", "-"))


def read_thesis(path: str | None) -> pd.DataFrame | None:
    """A thesis table with our column names (``nodes`` -> ``N``, ``1e-3`` -> ``1e-03``)."""
    if not path:
        return None
    t = pd.read_csv(path, comment="#")
    ren = {c: re.sub(r"1e-(\d)$", r"1e-0\1", c) for c in t.columns}
    ren.update({"nodes": "N"})
    return t.rename(columns=ren)


# --------------------------------------------------------------------------- tables
def thesis_table(steps: pd.DataFrame, thesis: pd.DataFrame | None,
                 variant: str = TABLE_VARIANT) -> pd.DataFrame:
    """Our table variant's steps in the thesis's columns, the thesis's rows beside them."""
    ours = steps[steps.variant == variant].sort_values("step").copy()
    ours["t_solve_per_node_us_1e-03"] = 1e6 * ours.get("t_solve_1e-03", np.nan) / ours["N"]
    if "t_vcycle" in ours:
        ours["t_vcycle_per_node_us"] = 1e6 * ours["t_vcycle"] / ours["n_vcycles"] / ours["N"]
    keep = ["step", "N", "NC", "n_outer_1e-02", "n_outer_1e-03", "n_inner_mean_1e-02",
            "n_inner_mean_1e-03", "t_solve_1e-02", "t_solve_1e-03", "t_proj_1e-02",
            "t_proj_1e-03", "n_outer_nested_1e-03", "t_solve_nested_1e-03", "kappa_S", "mg_levels",
            "mg_refinement_levels", "mg_work_ratio", "mg_deep_ratio", "mg_size_ratio", "t_vcycle_per_node_us",
            "t_setup", "t_solve_per_node_us_1e-03",
            "n_outer_total", "solver", "kkt_max", "eta2_weight"]
    ours = ours[[c for c in keep if c in ours.columns]]
    ours.insert(0, "source", "ours")
    if thesis is None:
        return ours.reset_index(drop=True)
    th = thesis.copy()
    if "n_inner_mean" in th:
        eps = "1e-03" if "n_outer_1e-03" in th else "1e-02"
        th = th.rename(columns={"n_inner_mean": f"n_inner_mean_{eps}"})
    th.insert(0, "source", "thesis")
    return pd.concat([ours, th], ignore_index=True)


def uniform_fit(uniform: pd.DataFrame) -> dict:
    """``e_ref`` and the rate ``s`` (in N) from the uniform levels' measured differences
    alone: ``m_L^2 + e_ref^2 = C^2 N_L^-2s`` (three levels determine it; a check on
    :func:`reference_error`). NaN with fewer than three levels or no fit with
    ``e_ref^2 >= 0``."""
    u = uniform.dropna(subset=["err_energy"]).sort_values("N")
    if len(u) < 3:
        return {"e_ref": np.nan, "rate_N": np.nan}
    N, m2 = u["N"].to_numpy(float), u["err_energy"].to_numpy(float) ** 2
    best = (np.inf, np.nan, np.nan)
    for s in np.linspace(0.02, 2.0, 991):
        M = np.stack([N ** (-2 * s), -np.ones_like(N)], axis=1)
        (c2, r), *_ = np.linalg.lstsq(M, m2, rcond=None)
        if c2 <= 0 or r < 0:
            continue
        res = float(np.sum((np.log(c2 * N ** (-2 * s) - r) - np.log(m2)) ** 2))
        if res < best[0]:
            best = (res, s, r)
    return {"e_ref": float(np.sqrt(best[2])) if np.isfinite(best[2]) else np.nan,
            "rate_N": float(best[1])}


def reference_error(steps: pd.DataFrame, min_ratio: float = 4.0) -> dict:
    """The reference's own relative energy error ``e_ref`` (module docstring).

    Every compared mesh is nested in the reference: ``e_h^2 = m_h^2 + e_ref^2``
    (Galerkin orthogonality). The residual estimator is proportional to the error
    with one efficiency constant for meshes of the same family, ``e_ref / e_h =
    eta_ref / eta_h`` (``eta^2 = sum eta_T1^2``), so each compared mesh gives
    ``e_ref = m_h / sqrt(eta_h^2 / eta_ref^2 - 1)``; the median over the compared meshes
    with ``eta_h^2 >= min_ratio eta_ref^2`` (a well-conditioned root) is returned with
    the spread.
    """
    ref = steps[steps.variant == "reference"]
    out = {"e_ref": np.nan, "e_ref_min": np.nan, "e_ref_max": np.nan, "n_anchors": 0}
    if not len(ref) or "sum_eta1_sq" not in ref or "err_energy" not in steps:
        return out
    eta_ref = float(ref["sum_eta1_sq"].iloc[0])
    c = steps[(steps.variant != "reference")].dropna(subset=["err_energy"])
    ratio = c["sum_eta1_sq"].to_numpy(float) / eta_ref
    ok = ratio >= min_ratio
    if not ok.any() or not eta_ref > 0:
        return out
    est = c["err_energy"].to_numpy(float)[ok] / np.sqrt(ratio[ok] - 1.0)
    return {"e_ref": float(np.median(est)), "e_ref_min": float(est.min()),
            "e_ref_max": float(est.max()), "n_anchors": int(ok.sum())}


def _crossing(N: np.ndarray, err: np.ndarray, target: float) -> float:
    """Smallest N at which ``err`` (in step order) falls to ``target`` (log-log
    interpolation between the bracketing steps); NaN if never."""
    for k in range(len(err)):
        if err[k] <= target:
            if k == 0:
                return float(N[0])
            t = (np.log(err[k - 1]) - np.log(target)) / (np.log(err[k - 1]) - np.log(err[k]))
            return float(np.exp(np.log(N[k - 1]) + t * (np.log(N[k]) - np.log(N[k - 1]))))
    return float("nan")


def _adaptive_fit(N, err) -> float:
    """Slope of log err against log N over the steps in the upper half (log scale) of N."""
    N, err = np.asarray(N, float), np.asarray(err, float)
    ok = np.isfinite(err) & (err > 0)
    N, err = N[ok], err[ok]
    if len(N) < 2:
        return float("nan")
    upper = N >= np.sqrt(N.min() * N.max())
    return fitted_slope(N, err, last=max(2, int(upper.sum())))


def accuracy_table(steps: pd.DataFrame) -> pd.DataFrame:
    """Accuracy per node per variant (module docstring)."""
    ref = steps[steps.variant == "reference"]
    uniform = steps[steps.variant == "uniform"].sort_values("N")
    fit = reference_error(steps)
    e_ref = fit["e_ref"]
    has_err = "err_energy" in steps and steps["err_energy"].notna().any()
    u_best = uniform.dropna(subset=["err_energy"]).iloc[-1] if has_err and len(uniform) else None
    rows = []
    for variant, grp in steps[steps.variant != "reference"].groupby("variant", sort=False):
        grp = grp.sort_values("N" if variant == "uniform" else "step")
        row = {"variant": variant, "n_steps": len(grp), "N_min": int(grp["N"].min()),
               "N_max": int(grp["N"].max())}
        last = grp.iloc[-1]
        for col in ("force", "dev_a_moment", "dev_p0_moment", "zigzag_rms", "dev_hertz_rms",
                    "zone_ratio"):
            if col in grp:
                row[f"{col}_last"] = last[col]
        if has_err:
            g = grp.dropna(subset=["err_energy"])
            row.update({"N_compared_max": int(g["N"].max()),
                        "err_energy_measured": float(g["err_energy"].iloc[-1]),
                        "err_energy_estimated": float(np.hypot(g["err_energy"].iloc[-1], e_ref))
                        if np.isfinite(e_ref) else np.nan,
                        "err_force": float(g["err_force"].iloc[-1]),
                        "err_pressure": float(g["err_pressure"].iloc[-1])})
            if variant == "uniform":
                row["rate_N_measured"] = -fitted_slope(g["N"], g["err_energy"])
                if np.isfinite(e_ref):
                    row["rate_N_estimated"] = -fitted_slope(g["N"], np.hypot(g["err_energy"],
                                                                             e_ref))
            else:
                row["rate_N_measured"] = -_adaptive_fit(g["N"], g["err_energy"])
                if np.isfinite(e_ref):
                    row["rate_N_estimated"] = -_adaptive_fit(g["N"], np.hypot(g["err_energy"],
                                                                              e_ref))
                if u_best is not None:
                    n_star = _crossing(g["N"].to_numpy(float), g["err_energy"].to_numpy(float),
                                       float(u_best["err_energy"]))
                    factor = float(u_best["N"]) / n_star
                row.update({"uniform_N": int(u_best["N"]),
                            "uniform_err_measured": float(u_best["err_energy"]),
                            "N_at_uniform_error": n_star, "node_saving_factor": factor,
                            "at_least_3x_fewer_nodes": bool(factor >= 3.0)})
        rows.append(row)
    out = pd.DataFrame(rows)
    if len(ref):
        r = ref.iloc[0]
        out["reference"] = (f"common refinement of the compared meshes, bisected twice more: "
                            f"N = {int(r['N'])}, N^C = {int(r['NC'])}, {r.get('solver', '')} "
                            f"({r.get('status', '')}, KKT {r.get('kkt_max', np.nan):.1e})")
        out["e_ref_estimated"] = e_ref
        out["e_ref_range"] = f"{fit['e_ref_min']:.4f}..{fit['e_ref_max']:.4f}"
        out["e_ref_method"] = ("Galerkin orthogonality e_h^2 = m_h^2 + e_ref^2 and e_ref/e_h = "
                               f"eta_ref/eta_h (median over {fit['n_anchors']} compared meshes)")
        out["e_ref_uniform_fit"] = uniform_fit(uniform)["e_ref"]
    return out


def pileup_table(steps: pd.DataFrame) -> pd.DataFrame:
    """Contact-zone nodes of both surfaces, zig-zag and Hertz deviation per variant at its
    last step and at the step nearest a common N (the smallest of the variants' last N)."""
    cols = ["variant", "step", "N", "NC", "zone_constrained", "zone_opposing", "zone_ratio",
            "h_zone_constrained", "h_zone_opposing", "zigzag_rms", "zigzag_max",
            "dev_hertz_rms", "dev_a_moment", "dev_p0_moment", "dev_p0_nodal_max", "a_over_h"]
    runs = steps[~steps.variant.isin(["uniform", "reference"])]
    if not len(runs):
        return pd.DataFrame(columns=["at"] + cols)
    common = runs.groupby("variant")["N"].max().min()
    rows = []
    for variant, grp in runs.groupby("variant", sort=False):
        near = grp.iloc[[int(np.argmin(np.abs(np.log(grp["N"] / common))))]]
        rows.append(near.assign(at=f"N ~ {int(common)}"))
        rows.append(grp.sort_values("step").iloc[[-1]].assign(at="last step"))
    for variant in ("uniform", "reference"):
        grp = steps[steps.variant == variant]
        if len(grp):
            rows.append(grp.sort_values("N").iloc[[-1]].assign(at="finest"))
    out = pd.concat(rows, ignore_index=True)
    out["h_ratio_opposing_over_constrained"] = out["h_zone_opposing"] / out["h_zone_constrained"]
    return out[["at"] + [c for c in cols if c in out] + ["h_ratio_opposing_over_constrained"]]


def convergence_table(steps: pd.DataFrame, dim: int) -> pd.DataFrame:
    """Sect. 7.3: the uniform levels' errors and their fitted rates in h (h ~ N^-1/d)."""
    u = steps[steps.variant == "uniform"].sort_values("N")
    errs = [c for c in ("err_energy", "err_energy_contact", "err_energy_singular",
                        "err_energy_rest", "err_pressure", "err_force") if c in u]
    if not len(u) or not errs:
        return pd.DataFrame({"note": ["no uniform levels with a reference (3D: meshes of "
                                      "different runs are not nested)"]})
    h = u["N"].to_numpy(float) ** (-1.0 / dim)
    rows = []
    for col in errs:
        e = u[col].to_numpy(float)
        rate = fitted_slope(h, e, last=len(h), finest="smallest")
        pairs = np.diff(np.log(e)) / np.diff(np.log(h))
        rows.append({"quantity": col, **{f"L{int(L)}": v for L, v in zip(u["level"], e)},
                     "rate_h": rate, "rate_h_finest_pair": float(pairs[-1]) if len(pairs) else np.nan,
                     "rate_7_8": 0.5, "at_least_7_8": bool(rate >= 0.5)})
    for region in ("contact", "singular", "rest"):
        col = f"err_share_{region}"
        if col in u:
            rows.append({"quantity": col, **{f"L{int(L)}": v for L, v in zip(u["level"], u[col])}})
    e_ref = reference_error(steps)["e_ref"]
    if np.isfinite(e_ref):
        e = np.hypot(u["err_energy"].to_numpy(float), e_ref)
        rate = fitted_slope(h, e, last=len(h), finest="smallest")
        rows.append({"quantity": "err_energy estimated: sqrt(m^2 + e_ref^2)",
                     **{f"L{int(L)}": v for L, v in zip(u["level"], e)}, "rate_h": rate,
                     "rate_h_finest_pair": float(np.diff(np.log(e))[-1] / np.diff(np.log(h))[-1]),
                     "rate_7_8": 0.5, "at_least_7_8": bool(rate >= 0.5)})
    return pd.DataFrame(rows)


# --------------------------------------------------------------------------- figures
def _read_vtu(path: str):
    import meshio

    m = meshio.read(path)
    kind = "triangle" if "triangle" in m.cells_dict else "tetra"
    return m.points, m.cells_dict[kind], m.point_data["body"].astype(int), \
        m.point_data["contact_pressure"]


def _zone(surface: pd.DataFrame, dim: int):
    """Centre and size of the window around the loaded constrained nodes."""
    con = surface[surface.kind == "constrained"]
    act = con[con.active.astype(bool)]
    xs = [f"x{i}" for i in range(dim)]
    if not len(act):
        return con[xs].mean().to_numpy(), 0.2
    w = act["pressure"].to_numpy()
    c = (act[xs].to_numpy() * w[:, None]).sum(axis=0) / w.sum()
    return c, max(float(np.ptp(act[xs[0]].to_numpy())), 1e-3)


def _mesh_panel_2d(ax, vtu: str, surface: pd.DataFrame, title: str, zoom: float = 0.65,
                   at: float = 0.0, key: bool = False):
    """The mesh around ``at`` (in units of the contact width from the zone's centre),
    half-width ``zoom`` contact widths, both surfaces' nodes marked (their key right of
    the panel where ``key``)."""
    pts, cells, body, _ = _read_vtu(vtu)
    c, width = _zone(surface, 2)
    half = zoom * width
    x0 = c[0] + at * width
    ax.triplot(Triangulation(pts[:, 0], pts[:, 1], cells), color="0.35", lw=0.3)
    con = surface[surface.kind == "constrained"]
    opp = surface[surface.kind == "opposing"]
    ms = 3.0 if zoom < 0.3 else 2.0
    ax.plot(con.x0, con.x1, "ks", ms=ms, label="constrained surface nodes")
    ax.plot(opp.x0, opp.x1, "o", color="tab:red", ms=ms + 0.5, mfc="none",
            label="opposing surface nodes")
    ax.set_xlim(x0 - half, x0 + half)
    ax.set_ylim(c[1] - 0.45 * half, c[1] + 0.45 * half)
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=8)
    _xy_labels(ax)
    if key:
        legend_outside(ax)


def _xy_labels(ax) -> None:
    """The coordinates' labels of a mesh panel (the scenes are dimensionless)."""
    ax.set_xlabel("x", fontsize=8)
    ax.set_ylabel("y", fontsize=8)


def _surface_panel_3d(ax, vtu: str, title: str, whole: bool = False):
    from problems.fem.elasticity import boundary_facets

    pts, cells, body, pressure = _read_vtu(vtu)
    loaded = pressure > 0
    cb = int(np.bincount(body[loaded]).argmax()) if loaded.any() else 0
    cell_body = body[cells[:, 0]]
    c = pts[loaded].mean(axis=0) if loaded.any() else pts.mean(axis=0)
    size = 0.65 * max(np.ptp(pts[loaded, 0]), 0.05) if loaded.any() else 0.5
    for b, color, lw in ((cb, "k", 0.35), (1 - cb, "tab:red", 0.45)):
        f = boundary_facets(cells[cell_body == b], pts)
        cen = pts[f].mean(axis=1)
        normal = np.cross(pts[f[:, 1]] - pts[f[:, 0]], pts[f[:, 2]] - pts[f[:, 0]])
        facing = normal[:, 2] > 0 if b == cb else normal[:, 2] < 0
        inside = np.all(np.abs(cen[:, :2] - c[:2]) <= (10.0 if whole else 1.05) * size, axis=1)
        near = np.abs(cen[:, 2] - c[2]) < (0.02 if b == cb else 0.25 * size + 0.02)
        sel = f[facing & near & inside]
        if b == cb:
            tri = Triangulation(pts[:, 0], pts[:, 1], sel)
            shade = ax.tripcolor(tri, pressure, shading="gouraud", cmap="Greys", alpha=0.6)
            ax.figure.colorbar(shade, ax=ax, fraction=0.046, pad=0.02).set_label(
                "contact pressure (nodal)", fontsize=8)
        ax.triplot(Triangulation(pts[:, 0], pts[:, 1], sel), color=color, lw=lw,
                   label="constrained surface (shaded by pressure)" if b == cb
                   else "opposing surface facets")
    if not whole:
        ax.set_xlim(c[0] - size, c[0] + size)
        ax.set_ylim(c[1] - size, c[1] + size)
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=8)
    _xy_labels(ax)
    legend_below(ax)


def figure_meshes(steps: pd.DataFrame, vtus: dict, surfaces: dict, path: str) -> None:
    """Figs. 7.3/7.4 (7.5 with the stabilised variant): each variant's last mesh near the
    contact (2D: the whole zone and a close-up of its left edge, where the contact takes
    off, both surfaces' nodes marked; 3D: both surfaces from above)."""
    variants = list(vtus)
    dim = 3 if _read_vtu(next(iter(vtus.values())))[1].shape[1] == 4 else 2
    rows = len(variants) if dim == 2 else -(-len(variants) // 2)
    cols = 2 if dim == 2 else min(len(variants), 2)
    fig, axes = plt.subplots(rows, cols, figsize=(5.6 * cols, (2.9 if dim == 2 else 5.4) * rows),
                             squeeze=False)
    panels = list(axes.flat)
    for j, v in enumerate(variants):
        last = steps[steps.variant == v].sort_values("step").iloc[-1]
        title = (f"{v}: N = {int(last['N'])}, N^C = {int(last['NC'])}; contact zone: "
                 f"{int(last.get('zone_opposing', 0))} opposing / "
                 f"{int(last.get('zone_constrained', 0))} constrained\nnodes (ratio "
                 f"{last.get('zone_ratio', np.nan):.2f}), mean spacing opposing / constrained "
                 f"{last.get('h_zone_opposing', np.nan) / last.get('h_zone_constrained', np.nan):.2f}")
        if dim == 2:
            surface = pd.read_csv(surfaces[v])
            _mesh_panel_2d(axes[j, 0], vtus[v], surface, title)
            _mesh_panel_2d(axes[j, 1], vtus[v], surface, f"{v}, close-up: the left end of the "
                           "contact zone (take-off)", zoom=0.12, at=-0.5, key=j == 0)
        else:
            _surface_panel_3d(panels[j], vtus[v], title)
    for ax in panels[len(variants) if dim == 3 else len(panels):]:
        ax.set_visible(False)
    figs = {"eta1": "Fig. 7.3: eta_1", "eta1+eta2": "Fig. 7.4: eta_1 + eta_2",
            "stabilised": "Fig. 7.5: stabilised (7.10), eta_1"}
    fig.suptitle("Meshes near the contact ("
                 + "; ".join(figs[v] for v in variants if v in figs) + ")",
                 fontsize=9)
    save_figure(fig, path)


def figure_snapshot(vtu: str, steps: pd.DataFrame, path: str, variant: str = TABLE_VARIANT):
    """Fig. 9.4 (2D: the whole adaptive mesh and a zoom) or Fig. 9.9 (3D: the contact
    surfaces of the adaptive mesh from above)."""
    pts, cells, body, pressure = _read_vtu(vtu)
    last = steps[steps.variant == variant].sort_values("step").iloc[-1]
    label = f"{variant}, step {int(last['step'])}: N = {int(last['N'])}, N^C = {int(last['NC'])}"
    if cells.shape[1] == 3:
        fig, axes = plt.subplots(1, 2, figsize=(11, 5.2))
        tri = Triangulation(pts[:, 0], pts[:, 1], cells)
        on = pressure > 0
        for ax, zoom in zip(axes, (None, 0.25)):
            ax.triplot(tri, color="0.3", lw=0.2 if zoom is None else 0.35)
            if zoom is not None:
                c = pts[on].mean(axis=0) if on.any() else pts.mean(axis=0)
                ax.set_xlim(c[0] - zoom, c[0] + zoom)
                ax.set_ylim(c[1] - zoom, c[1] + zoom)
            ax.set_aspect("equal")
            _xy_labels(ax)
        if on.any():
            nodes = axes[1].scatter(pts[on, 0], pts[on, 1], c=pressure[on], cmap="viridis",
                                    s=14, zorder=3)
            fig.colorbar(nodes, ax=axes[1], fraction=0.046, pad=0.02).set_label(
                "contact pressure at the nodes in contact", fontsize=8)
        axes[0].set_title(f"Adaptive mesh (Fig. 9.4): {label}", fontsize=8)
        axes[1].set_title("near the contact", fontsize=8)
    else:
        fig, ax = plt.subplots(figsize=(6.5, 6.2))
        _surface_panel_3d(ax, vtu, f"Contact surfaces of the adaptive mesh from above "
                                   f"(Fig. 9.9): {label}")
    save_figure(fig, path)


def figure_eta(steps: pd.DataFrame, path: str) -> None:
    """Figs. 9.2/9.7: the largest element indicator against N, uniform and adaptive."""
    fig, ax = plt.subplots(figsize=(7, 4.6))
    for variant, grp in steps[steps.variant != "reference"].groupby("variant", sort=False):
        grp = grp.sort_values("N")
        color, marker, ls = _style(variant)
        w = grp["eta2_weight"].iloc[-1]
        label = (f"{variant}" + (f" (c = {w:.3g})" if np.isfinite(w) and w > 0 else "")
                 + f", slope {fitted_slope(grp['N'], grp['max_eta'], last=max(2, len(grp) // 2)):.2f}")
        ax.loglog(grp["N"], grp["max_eta"], marker=marker, color=color, ls=ls, ms=4, label=label)
    ax.set_xlabel("nodes N")
    ax.set_ylabel("max_T eta_T,  eta_T^2 = eta_T1^2 + c eta_T2^2")
    ax.set_title("Largest element indicator against N (Figs. 9.2/9.7)", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    save_figure(fig, path)


def _error_panels(runs: pd.DataFrame) -> list[tuple[str, str, list[tuple[str, str]]]]:
    """The accuracy panels with something to draw: (title, y label, [(column, name), ...])
    each; the energy-error panel is its own case (:func:`_energy_panel`)."""
    force_col, force_title = "err_force", "contact force: |P_h - P_ref| / P_ref"
    if "err_force" not in runs or not runs["err_force"].notna().any():
        force_col = "force_dev"
        force_title = ("contact force against the finest mesh's (no reference): "
                       "|P_h / P_finest - 1|")
    panels = [(force_title, "relative force error", [(force_col, "force")]),
              ("Hertz deviation |a/a_H - 1| (solid), |p0/p0_H - 1| (dashed)",
               "relative deviation from Hertz", [("dev_a_moment", "a"), ("dev_p0_moment", "p0")]),
              ("nodal pressure / p0_H: zig-zag rms (solid), rms deviation from Hertz (dashed)",
               "rms / p0_H", [("zigzag_rms", "zig-zag"), ("dev_hertz_rms", "rms from Hertz")])]
    return [(title, ylabel, cols) for title, ylabel, cols in panels
            if any(col in runs and runs[col].notna().any() for col, _ in cols)]


def _energy_panel(ax, runs: pd.DataFrame, accuracy: pd.DataFrame) -> None:
    """Energy error against the reference with fitted slopes, and dotted with the
    reference's own estimated error added in quadrature (Galerkin orthogonality)."""
    e_ref = float(accuracy["e_ref_estimated"].iloc[0]) if "e_ref_estimated" in accuracy \
        and len(accuracy) else np.nan
    acc = accuracy.set_index("variant") if len(accuracy) else pd.DataFrame()
    for variant, grp in runs.groupby("variant", sort=False):
        g = grp.dropna(subset=["err_energy"]).sort_values("N")
        color, marker, ls = _style(variant)
        rate = acc.loc[variant, "rate_N_measured"] if variant in acc.index else np.nan
        extra = ""
        if variant in acc.index and "node_saving_factor" in acc \
                and np.isfinite(acc.loc[variant, "node_saving_factor"]):
            extra = f", {acc.loc[variant, 'node_saving_factor']:.1f}x fewer nodes"
        ax.loglog(g["N"], g["err_energy"], marker=marker, color=color, ls=ls, ms=4,
                  label=f"{variant}: slope {-rate:.2f}{extra}")
        if np.isfinite(e_ref):
            ax.loglog(g["N"], np.hypot(g["err_energy"], e_ref), color=color, ls=":", lw=1)
    u = runs[runs.variant == "uniform"].dropna(subset=["err_energy"])
    if len(u):
        ax.axhline(u["err_energy"].iloc[-1], color="k", lw=0.6, ls="--")
    ax.set_title("energy error ||u_ref - u_h||_A / ||u_ref||_A (solid);\n"
                 f"dotted: with the reference's own error {e_ref:.3f} (orthogonality)",
                 fontsize=8)
    ax.set_ylabel("relative energy error")
    ax.legend(fontsize=7)


def figure_error(steps: pd.DataFrame, accuracy: pd.DataFrame, path: str) -> None:
    """Accuracy per node: energy error (measured against the reference and estimated with
    its own error), force error, Hertz deviation and zig-zag against N, fitted rates.

    Only the panels with data are drawn: in 3D the meshes of different runs are not
    nested, so there is no energy error against a reference and the figure has three
    panels (the caption says why)."""
    runs = steps[steps.variant != "reference"]
    if "err_force" not in runs or not runs["err_force"].notna().any():
        runs = runs.assign(force_dev=runs["force"] / runs.loc[runs["N"].idxmax(), "force"] - 1)
    energy = "err_energy" in runs and runs["err_energy"].notna().any()
    panels = _error_panels(runs)
    n = len(panels) + energy
    if n == 0:
        raise ValueError("figure_error: no accuracy quantity measured in the steps")
    cols = min(n, 2)
    fig, axes = plt.subplots(-(-n // cols), cols, figsize=(5.5 * cols, 4.0 * -(-n // cols)),
                             squeeze=False)
    axes = list(axes.ravel())
    for ax in axes[n:]:
        ax.set_visible(False)
    if energy:
        _energy_panel(axes.pop(0), runs, accuracy)
    for ax, (title, ylabel, cols) in zip(axes, panels):
        for variant, grp in runs.groupby("variant", sort=False):
            g = grp.sort_values("N")
            color, marker, _ = _style(variant)
            labelled = False
            for (col, _name), ls in zip(cols, ("-", "--")):
                if col in g and g[col].notna().any():
                    y = np.abs(g[col].to_numpy(float))
                    ax.loglog(g["N"], np.where(y > 0, y, np.nan), marker=marker, color=color,
                              ls=ls, ms=3, label=None if labelled else variant)
                    labelled = True
        ax.set_title(title, fontsize=8)
        ax.set_ylabel(ylabel)
        ax.legend(fontsize=7)
    for ax in fig.axes:
        ax.set_xlabel("nodes N")
        ax.grid(True, which="both", alpha=0.3)
    save_figure(fig, path)


def figure_pressure(steps: pd.DataFrame, surfaces: dict, path: str) -> None:
    """Each variant's nodal contact pressure at its last step against Hertz."""
    fig, axes = plt.subplots(1, len(surfaces), figsize=(4.1 * len(surfaces), 3.9), squeeze=False)
    for ax, (variant, f) in zip(axes[0], surfaces.items()):
        s = pd.read_csv(f)
        dim = 3 if "x2" in s else 2
        con = s[(s.kind == "constrained")]
        last = steps[steps.variant == variant].sort_values("step").iloc[-1]
        if not np.isfinite(last.get("a_hertz", np.nan)):
            continue
        xs = con[[f"x{i}" for i in range(dim - 1)]].to_numpy()
        w = np.nan_to_num(con["pressure"].to_numpy(float))
        c = (xs * w[:, None]).sum(axis=0) / w.sum()          # the moment centre
        r = (xs - c)[:, 0] if dim == 2 else np.linalg.norm(xs - c, axis=1)
        a, p0 = last["a_hertz"], last["p0_hertz"]
        keep = np.abs(r) <= 1.5 * a
        order = np.argsort(r[keep])
        ax.plot(r[keep][order] / a, con["pressure"].to_numpy()[keep][order] / p0, "o-",
                color=_style(variant)[0], ms=2.5, lw=0.6, label="nodal pressure")
        rr = np.linspace(-1 if dim == 2 else 0, 1, 201)
        ax.plot(rr, np.sqrt(np.clip(1 - rr ** 2, 0, None)), "k--", lw=1,
                label="Hertz for the measured force")
        ax.set_xlabel("x / a_H" if dim == 2 else "r / a_H")
        ax.set_ylabel("p / p0_H")
        measured = [f"{name} {last.get(col, np.nan):.3f} p0" for col, name in
                     (("zigzag_rms", "zig-zag rms"), ("dev_hertz_rms", "rms from Hertz"))
                     if np.isfinite(last.get(col, np.nan))]
        ax.set_title(", ".join([f"{variant}: N = {int(last['N'])}", *measured]), fontsize=7)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    save_figure(fig, path)


# --------------------------------------------------------------------------- patch test
#: The adaptive study's claims (report/claims.py).
CLAIMS = {
    "node_saving": Claim("Sect. 7.4; suite bar: 3x, the saving that repays an adaptive solve",
                         "adaptive {variant}: nodes saved for the same energy error", ">=",
                         3.0, details="against uniform N = {N}"),
    "pileup": Claim("Figs. 7.3/7.4", "eta_2 removes the pile-up of surface nodes", "given",
                    "eta1+eta2 < eta1", details="opposing / constrained surface nodes in "
                    "the contact zone at {at}"),
    "zigzag": Claim("Fig. 7.5", "the stabilisation (7.10) smooths the nodal pressure", "given",
                    "stabilised < eta1", details="zig-zag rms / p0 at {at}, both marked by "
                    "eta_1"),
    "patch_mortar": Claim("Ch. 6 (mortar: the patch test passes)", "patch test: mortar "
                          "coupling transmits the uniform pressure", "<", 1e-8,
                          details="largest pressure deviation, finest level"),
    "patch_nodal": Claim("Ch. 6 (nodal constraints on non-matching meshes)", "patch test: "
                         "nodal coupling cannot transmit it on non-matching meshes", ">=",
                         1e-3, details="largest pressure deviation, finest level"),
    "patch_two_pass": Claim("Alg. 7.1 applied to both surfaces (two-pass; not in the thesis)",
                            "patch test: two-pass coupling transmits the uniform pressure",
                            "<", 1e-8, details="largest pressure deviation, finest level; its "
                            "coinciding nodes' rows are linearly dependent"),
    "patch_stabilised": Claim("Sect. 7.5", "patch test: stabilised coupling's pressure "
                              "deviation shrinks under refinement", ">", 0.25,
                              details="smallest fitted rate in h over both constrained "
                              "sides; the penalty grows like h^-2alpha"),
}


def claims(accuracy: pd.DataFrame | None = None, pileup: pd.DataFrame | None = None,
           patch: pd.DataFrame | None = None) -> pd.DataFrame:
    """The adaptive study's claims, measured (claim, thesis, measured, bar, pass):
    adaptivity saves nodes (at least 3x for the uniform finest level's energy error, the
    saving that repays an adaptive solve), eta_2 removes the pile-up of Fig. 7.3, and the contact patch test."""
    rows = []
    if accuracy is not None and "node_saving_factor" in accuracy:
        for _, r in accuracy.dropna(subset=["node_saving_factor"]).iterrows():
            rows.append(CLAIMS["node_saving"].row(float(r.node_saving_factor), variant=r.variant,
                                                  N=int(r.uniform_N)))
    if pileup is not None and {"variant", "zone_ratio"} <= set(pileup.columns):
        common = pileup[pileup["at"].astype(str).str.startswith("N ~")]   # comparable N
        for column, worse, better, key in (("zone_ratio", "eta1", "eta1+eta2", "pileup"),
                                           ("zigzag_rms", "eta1", "stabilised", "zigzag")):
            v = common.groupby("variant")[column].last() if column in common else pd.Series()
            if {worse, better} <= set(v.index):
                rows.append(CLAIMS[key].row(f"{worse} {v[worse]:.3f}, {better} {v[better]:.3f}",
                                            passed=v[better] < v[worse], at=common["at"].iloc[0]))
    if patch is not None and len(patch):
        for coupling in ("mortar", "nodal", "two_pass"):
            g = patch[patch.coupling == coupling]
            if len(g):
                rows.append(CLAIMS[f"patch_{coupling}"].row(
                    float(g["dev_max_finest"].abs().max())))
        g = patch[patch.coupling == "stabilised"]
        if len(g) and g["rate_h_dev_rms"].notna().all():
            rows.append(CLAIMS["patch_stabilised"].row(float(g["rate_h_dev_rms"].min())))
    return pd.DataFrame(rows)


def patch_table(runs: pd.DataFrame) -> pd.DataFrame:
    """Per coupling and constrained side: the finest level's deviations, how they change
    with refinement (rate of the rms deviation in h) and whether the uniform pressure is
    transmitted (rms deviation < 1e-8)."""
    rows = []
    for (coupling, side), g in runs.groupby(["coupling", "constrained"], sort=False):
        g = g.sort_values("level")
        f = g.iloc[-1]
        rows.append({"coupling": coupling, "constrained": side, "ratio": f["ratio"],
                     "levels": f"{int(g.level.min())}..{int(g.level.max())}",
                     "NC_finest": int(f["NC"]), "dev_max_finest": f["dev_max"],
                     "dev_rms_finest": f["dev_rms"], "dev_force_finest": f["dev_force"],
                     "rate_h_dev_rms": fitted_slope(g["h_constrained"], g["dev_rms"],
                                                    finest="smallest", roundoff=1e-10),
                     "transmits_uniform_pressure": bool(f["dev_rms"] < 1e-8)})
    return pd.DataFrame(rows)


#: Draw order and look of the patch test's couplings: the ones that transmit the uniform
#: pressure exactly (mortar, two-pass) lie on one line, so the one drawn first is larger
#: and hollow and the next one small, filled and dashed on top of it: both stay visible.
PATCH_LOOK = {"nodal": dict(ms=4), "stabilised": dict(ms=4),
              "mortar": dict(ms=8, mfc="none", lw=1.6, zorder=2.1),
              "two_pass": dict(ms=3.5, ls="--", lw=0.9, zorder=2.2)}


def patch_figure(runs: pd.DataFrame, pressure: pd.DataFrame, path: str) -> None:
    """Nodal pressure / q along the interface at the finest level, per coupling and side
    (each coupling in its colour and marker of the coupling study,
    :data:`report.figures.COUPLING_STYLE`, as :data:`PATCH_LOOK` draws it); the legend
    below."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6))
    finest = pressure["level"].max()
    for ax, side in zip(axes, ("coarse", "fine")):
        for (coupling, s), g in pressure[(pressure.level == finest)
                                         & (pressure.constrained == side)].groupby(
                                             ["coupling", "constrained"], sort=False):
            g = g.sort_values("x")
            r = runs[(runs.coupling == coupling) & (runs.constrained == side)
                     & (runs.level == finest)].iloc[0]
            fmt, color = COUPLING_STYLE.get(coupling, ("o-", "k"))
            look = {"lw": 0.7, **PATCH_LOOK.get(coupling, {})}
            ax.plot(g["x"], g["pressure_over_q"], fmt[0], color=color,
                    **{"ls": "-", **look},
                    label=f"{coupling}: max |p/q - 1| = {r['dev_max']:.1e}")
        ax.axhline(1.0, color="k", lw=0.6, ls=":", zorder=0)
        ax.set_xlabel("x")
        ax.set_ylabel("nodal pressure / q")
        ax.set_title(f"{side} side constrained, level {finest} (mesh ratio {r['ratio']})",
                     fontsize=8)
        legend_below(ax, ncol=2)
        ax.grid(alpha=0.3)
    save_figure(fig, path)


# --------------------------------------------------------------------------- CLI
def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="what", required=True)
    t = sub.add_parser("tables")
    t.add_argument("--steps", required=True)
    t.add_argument("--thesis", default=None)
    for name in ("table", "accuracy", "pileup", "convergence"):
        t.add_argument(f"--{name}", required=True)
    f = sub.add_parser("figures")
    f.add_argument("--steps", required=True)
    f.add_argument("--accuracy", required=True)
    f.add_argument("--variants", nargs="+", required=True)
    f.add_argument("--vtus", nargs="+", required=True, help="one per variant, same order")
    f.add_argument("--surfaces", nargs="+", required=True, help="one per variant, same order")
    for name in ("fig-meshes", "fig-snapshot", "fig-eta", "fig-error", "fig-pressure"):
        f.add_argument(f"--{name}", required=True)
    p = sub.add_parser("patch")
    p.add_argument("--runs", required=True)
    p.add_argument("--pressure", required=True)
    p.add_argument("--table", required=True)
    p.add_argument("--figure", required=True)
    args = ap.parse_args(argv)
    if args.what == "tables":
        steps = pd.read_csv(args.steps)
        dim = 3 if "center_s1" in steps and steps["center_s1"].notna().any() else 2
        write_csv(args.table, thesis_table(steps, read_thesis(args.thesis)))
        write_csv(args.accuracy, accuracy_table(steps))
        write_csv(args.pileup, pileup_table(steps))
        write_csv(args.convergence, convergence_table(steps, dim))
    elif args.what == "figures":
        steps = pd.read_csv(args.steps)
        accuracy = pd.read_csv(args.accuracy)
        if not len(args.variants) == len(args.vtus) == len(args.surfaces):
            ap.error("--variants, --vtus and --surfaces must have one entry per variant")
        vtus = dict(zip(args.variants, args.vtus))
        surfaces = dict(zip(args.variants, args.surfaces))
        figure_meshes(steps, vtus, surfaces, args.fig_meshes)
        snap = vtus.get(TABLE_VARIANT, next(iter(vtus.values())))
        figure_snapshot(snap, steps, args.fig_snapshot)
        figure_eta(steps, args.fig_eta)
        figure_error(steps, accuracy, args.fig_error)
        figure_pressure(steps, surfaces, args.fig_pressure)
    else:
        runs = pd.read_csv(args.runs)
        write_csv(args.table, patch_table(runs))
        patch_figure(runs, pd.read_csv(args.pressure), args.figure)


def accuracy_claims(accuracy: pd.DataFrame) -> pd.DataFrame:
    """The claims of the accuracy table alone (:func:`claims`)."""
    return claims(accuracy=accuracy)


def pileup_claims(pileup: pd.DataFrame) -> pd.DataFrame:
    """The claims of the pile-up table alone (:func:`claims`)."""
    return claims(pileup=pileup)


def patch_claims(patch: pd.DataFrame) -> pd.DataFrame:
    """The claims of the contact patch test's table alone (:func:`claims`)."""
    return claims(patch=patch)


if __name__ == "__main__":
    main()
