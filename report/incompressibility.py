"""Alg. 8.4 towards incompressibility (study hard_cases): the claims and the figure
from ``workflows/scripts/incompressibility.py``'s table.

Claims, per scene: every run of the solver's defaults (``robust``) converged and was
verified; ``n_o`` at the largest ``nu`` is at most twice ``n_o`` at the smallest (the suite's
bar: Theorem 8.8's bounded n_o, allowing a factor two over the whole range). The figure shows ``n_o`` and the V-cycles of a solve against ``1 - 2 nu`` for both
configurations, the plain V-cycle's ``kappa(V A)`` beside it.

Example::

    python -m report.incompressibility --table results/hard_cases/incompressibility.csv \\
        --claims c.csv --figure f.png
"""
from __future__ import annotations

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from report.claims import COLUMNS, Claim  # noqa: E402
from report.figures import save_figure  # noqa: E402
from workflows.io import read_csv, write_csv  # noqa: E402

#: n_o at the largest nu over n_o at the smallest, at most (Theorem 8.8's bounded n_o, with
#: a factor two of room over the whole range of nu).
GROWTH_BAR = 2.0


#: Alg. 8.4 towards incompressibility (report/claims.py).
CLAIMS = {
    "converged": Claim("suite bar (every run of the defaults must count)", "{scene}: Alg. 8.4 verified converged at every nu ({nus})",
                       "given", "all"),
    "growth": Claim("Theorem 8.8 (n_o bounded by the spectral equivalence of A-hat)",
                    "{scene}: n_o at nu = {hi:g} over n_o at nu = {lo:g}", "<=", GROWTH_BAR),
}


def claims(t: pd.DataFrame) -> pd.DataFrame:
    """Per scene: the robust runs all converged, and their n_o grows at most 2x over nu."""
    rows = []
    for scene, g in t[t.variant == "robust"].groupby("scene", sort=True):
        g = g.sort_values("nu")
        ok = int((g.status == "converged").sum())
        rows.append(CLAIMS["converged"].row(f"{ok} of {len(g)}", passed=ok == len(g),
                                            scene=scene, nus=", ".join(f"{v:g}" for v in g.nu)))
        lo, hi = g.iloc[0], g.iloc[-1]
        judged = lo.status == hi.status == "converged" and len(g) > 1
        growth = hi.n_outer / lo.n_outer if judged else np.nan
        rows.append(CLAIMS["growth"].row(growth, judged=bool(judged), scene=scene, hi=hi.nu,
                                         lo=lo.nu, reason="needs converged runs at the "
                                         "smallest and the largest nu"))
    return pd.DataFrame(rows, columns=COLUMNS)


def figure(t: pd.DataFrame, path: str) -> None:
    """n_o, V-cycles per solve and kappa(V A) against 1 - 2 nu, per scene and variant."""
    fig, ax = plt.subplots(1, 3, figsize=(14, 4.2))
    styles = {"robust": "o-", "vcycle": "s--"}
    for i, (scene, g) in enumerate(t.groupby("scene", sort=True)):
        for variant, h in g.groupby("variant"):
            h = h.sort_values("nu")
            x = 1.0 - 2.0 * h.nu
            done = h.status == "converged"
            label = f"{scene}, {variant}"
            ax[0].loglog(x, h.n_outer, styles.get(variant, "o-"), color=f"C{i}", label=label)
            ax[0].loglog(x[~done], h.n_outer[~done], "x", color="k", ms=9)
            ax[1].loglog(x, h.n_vcycles, styles.get(variant, "o-"), color=f"C{i}", label=label)
            if variant == "robust":
                ax[2].loglog(x, h.kappa_vcycle, "o-", color=f"C{i}",
                             label=f"{scene}: kappa(V A), one V-cycle")
                ax[2].loglog(x, h.gamma_bar, "^:", color=f"C{i}",
                             label=f"{scene}: gamma_bar of A-hat (Chebyshev)")
    ax[0].plot([], [], "x", color="k", label="not converged (max_iter)")
    for a, ylabel in zip(ax, ("outer steps n_o to KKT 1e-6", "V-cycles in the solve",
                              "spectral ratio")):
        a.set_xlabel("1 - 2 nu  (towards incompressibility ->)")
        a.set_ylabel(ylabel)
        a.invert_xaxis()
        a.grid(True, which="both", alpha=0.3)
        a.legend(fontsize=7)
    ax[0].set_title("Alg. 8.4: outer steps")
    ax[1].set_title("work per solve")
    ax[2].set_title("the V-cycle loses its equivalence")
    save_figure(fig, path)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--table", required=True)
    ap.add_argument("--claims", required=True)
    ap.add_argument("--figure", required=True)
    args = ap.parse_args(argv)
    t = read_csv(args.table)
    write_csv(args.claims, claims(t))
    figure(t, args.figure)


if __name__ == "__main__":
    main()
