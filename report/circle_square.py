"""Figures of the circle-square scene (thesis Sect. 9.1): mesh, deformed
configuration, von Mises stress and contact pressure against Hertz."""
from __future__ import annotations

import argparse
import re

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.tri import Triangulation  # noqa: E402

from report.figures import save_figure  # noqa: E402



def _read(vtu: str):
    import meshio

    m = meshio.read(vtu)
    cells = m.cells_dict["triangle"]
    return (m.points[:, :2], cells, m.point_data["displacement"][:, :2],
            m.cell_data_dict["von_mises"]["triangle"], m.point_data["body"])


def fields_figure(vtu: str, path: str, magnify: float = 5.0) -> None:
    """Left: mesh and deformed configuration; right: von Mises stress near the contact."""
    pts, cells, u, vm, body = _read(vtu)
    fig, axes = plt.subplots(1, 2, figsize=(11, 5.2))
    ax = axes[0]
    ax.triplot(Triangulation(pts[:, 0], pts[:, 1], cells), color="0.8", lw=0.2)
    d = pts + magnify * u
    ax.triplot(Triangulation(d[:, 0], d[:, 1], cells), color="tab:blue", lw=0.25)
    ax.set_aspect("equal")
    ax.set_title(f"reference mesh (grey) and deformed configuration (blue, x{magnify:g})", fontsize=9)
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax = axes[1]
    true = pts + u
    im = ax.tripcolor(Triangulation(true[:, 0], true[:, 1], cells), facecolors=vm, cmap="viridis",
                      shading="flat")
    ax.set_xlim(0.2, 0.8)
    ax.set_ylim(0.75, 1.3)
    ax.set_aspect("equal")
    ax.set_title("von Mises stress near the contact (deformed configuration, true scale)", fontsize=9)
    ax.set_xlabel("x")
    fig.colorbar(im, ax=ax, label="von Mises stress (units of E)")
    save_figure(fig, path)


def pressure_figure(contacts: list[str], hertz_rows: list[str], path: str) -> None:
    """Contact pressure against x per level, with the plane-strain Hertz curve for the
    measured total force of the finest level."""
    fig, ax = plt.subplots(figsize=(7.5, 4.6))
    rows = pd.concat([pd.read_csv(f) for f in hertz_rows]).sort_values("level")
    by_level = {int(re.search(r"_L(\d+)\.csv$", f).group(1)): f for f in contacts}
    for _, row in rows.iterrows():
        c = pd.read_csv(by_level[int(row["level"])])
        ax.plot(c["x"], c["pressure"], "o-", ms=3, lw=0.8,
                label=f"level {int(row['level'])} ({int(row['nodes'])} nodes): "
                      f"a {row['dev_a_moment']:+.1%}, p0 {row['dev_p0_moment']:+.1%} vs Hertz")
    last = rows.iloc[-1]
    x = np.linspace(last["x_center"] - 1.5 * last["a_hertz"], last["x_center"] + 1.5 * last["a_hertz"], 400)
    ax.plot(x, last["p0_hertz"] * np.sqrt(np.clip(1 - ((x - last["x_center"]) / last["a_hertz"]) ** 2, 0, None)),
            "k--", lw=1.2, label=f"Hertz (plane strain), P = {last['force']:.4g}")
    ax.set_xlim(x[0], x[-1])
    ax.set_xlabel("x on the square's top edge")
    ax.set_ylabel("contact pressure p / lumped mass (units of E)")
    ax.set_title("Circle-square contact pressure (deviations: moment estimate of a, p0)", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    save_figure(fig, path)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    sub = ap.add_subparsers(dest="what", required=True)
    f = sub.add_parser("fields")
    f.add_argument("--vtu", required=True)
    f.add_argument("--out", required=True)
    p = sub.add_parser("pressure")
    p.add_argument("--contacts", nargs="+", required=True)
    p.add_argument("--hertz", nargs="+", required=True)
    p.add_argument("--out", required=True)
    args = ap.parse_args(argv)
    if args.what == "fields":
        fields_figure(args.vtu, args.out)
    else:
        pressure_figure(args.contacts, args.hertz, args.out)


if __name__ == "__main__":
    main()
