"""Tables and figures of the non-matching Laplace study (thesis Ch. 6, Figs. 6.3, 6.5, 6.6)."""
from __future__ import annotations

import argparse

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from report.claims import Claim
from report.figures import legend_below, save_figure
from report.rates import rate_table
from workflows.io import read_csv, write_csv

STYLE = {"conforming": ("k", "o", "-"), "nodal": ("tab:red", "s", "--"),
         "stabilised_a0.5": ("tab:orange", "^", "-."), "stabilised_a1": ("tab:blue", "D", "-"),
         "mortar": ("tab:green", "v", "-")}


#: Ch. 6's claims (report/claims.py).
CLAIMS = {
    "nodal_h1": Claim("Sect. 6.2", "nodal constraints: H1 rate >= 1/2", ">=", 0.45,
                      details="{where}"),
    "stabilised_h1": Claim("Sect. 6.3", "stabilised alpha = 1: optimal H1 rate", ">=", 0.95,
                           details="{where}"),
    "stabilised_l2": Claim("Sect. 6.3", "stabilised alpha = 1: optimal L2 rate", ">=", 1.9,
                           details="{where}"),
}


def claims(rates: pd.DataFrame) -> pd.DataFrame:
    """Ch. 6's claims, measured (claim, thesis, measured, bar, pass): nodal constraints on
    the non-matching grid converge at least like O(h^1/2) in H^1 (Sect. 6.2), the
    stabilised constraints with alpha = 1 (h^-2) at the optimal rates (Sect. 6.3)."""
    rows = []
    for (case, side), g in rates.groupby(["case", "constrained"], sort=False):
        g = g.set_index("variant")
        where = f"{case}, {side} side constrained"
        if "nodal" in g.index:
            rows.append(CLAIMS["nodal_h1"].row(float(g.loc["nodal", "rate_h1"]), where=where))
        if "stabilised_a1" in g.index:
            for col, key in (("rate_h1", "stabilised_h1"), ("rate_l2", "stabilised_l2")):
                rows.append(CLAIMS[key].row(float(g.loc["stabilised_a1", col]), where=where))
    return pd.DataFrame(rows)


def add_slope(ax, h: np.ndarray, anchor: float, slope: int, label: str) -> None:
    """Reference line err = C h^slope through (h.max(), anchor), drawn dotted."""
    hh = np.array([h.min(), h.max()])
    ax.loglog(hh, anchor * (hh / h.max()) ** slope, ":", color="0.5", lw=1)
    ax.annotate(label, (hh[0], anchor * (hh[0] / h.max()) ** slope), fontsize=8, color="0.4",
                ha="left", va="top")


def convergence_figure(errors: pd.DataFrame, rates: pd.DataFrame, case: str, path: str) -> None:
    """H1 (left) and L2 (right) error against h, one line per variant, both sides; each
    panel's legend, with its fitted rates, below it."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.8), sharex=True)
    sub = errors[errors["case"] == case]
    worst = sub.groupby("variant")[["err_h1", "err_l2"]].max().max(axis=1)
    exact = sorted(worst[worst < 1e-10].index)  # patch test passed to round-off: no rate to plot
    sub = sub[~sub.variant.isin(exact)]
    for ax, col, rcol, title, slopes in (
            (axes[0], "err_h1", "rate_h1", "$H^1$-seminorm error (cf. Fig. 6.5)", (0.5, 1)),
            (axes[1], "err_l2", "rate_l2", "$L_2$ error (cf. Fig. 6.6)", (1, 2))):
        for (side, variant), grp in sub.groupby(["constrained", "variant"], sort=False):
            if variant == "conforming" and side != "coarse":
                continue  # the conforming grid has no constrained side
            color, marker, ls = STYLE[variant]
            r = rates[(rates.case == case) & (rates.variant == variant) & (rates.constrained == side)]
            rate = float(r[rcol].iloc[0]) if len(r) else float("nan")
            label = variant if variant == "conforming" else f"{variant}, {side} constrained"
            ax.loglog(grp["h"], grp[col], ls if side == "coarse" else ":", color=color,
                      marker=marker, mfc="none" if side == "fine" else color, ms=5,
                      label=f"{label} (rate {rate:.2f})")
        h = sub["h"].to_numpy()
        anchor = sub.loc[sub["h"] == h.max(), col].min() * 0.4
        for s in slopes:
            add_slope(ax, h, anchor, s, f"slope {s:g}")
        ax.set_xlabel("mesh size $h$ of the finer side (conforming: its one $h$)")
        ax.set_ylabel(f"{'$|u-u_h|_{1}$' if col == 'err_h1' else '$||u-u_h||_{0}$'} (dimensionless)")
        ax.set_title(title, fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.invert_xaxis()
        legend_below(ax)                           # each panel's rates, under it
    note = (f"; exact to round-off (max error {worst[exact].max():.1e}): {', '.join(exact)}"
            if exact else "")
    fig.suptitle(f"Non-matching Laplace problem, case '{case}' "
                 f"({'u = sin(10x)' if case == 'sin10x' else 'u = 1 + 2x - y, patch test'}); "
                 f"\nrates fitted over the finest three levels{note}", fontsize=10)
    save_figure(fig, path)


def mesh_figure(level: int, ratio: str, path: str) -> None:
    """The two independent meshes and their non-matching interface (cf. Fig. 6.3)."""
    from problems.laplace_nonmatching import (INTERFACE_X, cells_per_unit, interface_nodes,
                                              parse_ratio, subdomain_mesh)
    nc, nf = cells_per_unit(level, parse_ratio(ratio))
    fig, ax = plt.subplots(figsize=(5.2, 5))
    for mesh, color, label in ((subdomain_mesh(0, INTERFACE_X, nc), "tab:blue", f"$\\Omega_1$, h=1/{nc}"),
                               (subdomain_mesh(INTERFACE_X, 1, nf), "tab:red", f"$\\Omega_2$, h=1/{nf}")):
        ax.triplot(mesh.p[0], mesh.p[1], mesh.t.T, color=color, lw=0.6)
        i = interface_nodes(mesh)
        big = color == "tab:blue"  # hollow and larger, so coinciding nodes show both sides
        ax.plot(mesh.p[0, i], mesh.p[1, i], "o", color=color, ms=8 if big else 4,
                mfc="none" if big else color, label=label + " interface nodes")
    ax.set_aspect("equal")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_title(f"Non-matching grid, level {level}, ratio {ratio} (cf. Fig. 6.3)", fontsize=10)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=1)
    save_figure(fig, path)


def tables(inputs: list[str], default_side: str, errors_path: str, by_side_path: str,
           rates_path: str) -> None:
    """Merge the per-case/side error tables; fit rates over the finest three levels.

    Writes ``errors.csv`` (the default constrained side: case, variant, level,
    h, ndof, err_h1, err_l2), ``errors_by_side.csv`` (both sides, column
    ``constrained``) and ``rates.csv`` (case, variant, rate_h1, rate_l2 for the
    default side first, then the other side).
    """
    both = pd.concat([read_csv(p) for p in inputs], ignore_index=True)
    both = both.sort_values(["constrained", "case", "variant", "level"], kind="stable")
    columns = ["case", "variant", "level", "h", "ndof", "err_h1", "err_l2"]
    write_csv(by_side_path, both)
    write_csv(errors_path, both[both["constrained"] == default_side][columns])
    rates = rate_table(both, ["constrained", "case", "variant"],
                       {"err_h1": "rate_h1", "err_l2": "rate_l2"})
    rates["default_side"] = rates["constrained"] == default_side
    rates = rates.sort_values(["default_side", "constrained", "case", "variant"],
                              ascending=[False, True, True, True], kind="stable")
    write_csv(rates_path, rates[["case", "variant", "rate_h1", "rate_l2", "constrained", "levels"]])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    sub = ap.add_subparsers(dest="what", required=True)
    t = sub.add_parser("tables", help="merge error tables, fit rates")
    t.add_argument("--inputs", nargs="+", required=True)
    t.add_argument("--default-side", choices=("coarse", "fine"), default="coarse")
    t.add_argument("--errors", required=True)
    t.add_argument("--by-side", required=True, dest="by_side")
    t.add_argument("--rates", required=True)
    c = sub.add_parser("convergence")
    c.add_argument("--errors", required=True)
    c.add_argument("--rates", required=True)
    c.add_argument("--case", required=True)
    c.add_argument("--out", required=True)
    m = sub.add_parser("mesh")
    m.add_argument("--level", type=int, default=0)
    m.add_argument("--ratio", default="2:3")
    m.add_argument("--out", required=True)
    args = ap.parse_args(argv)
    if args.what == "tables":
        tables(args.inputs, args.default_side, args.errors, args.by_side, args.rates)
    elif args.what == "convergence":
        convergence_figure(read_csv(args.errors), read_csv(args.rates), args.case, args.out)
    else:
        mesh_figure(args.level, args.ratio, args.out)


if __name__ == "__main__":
    main()
