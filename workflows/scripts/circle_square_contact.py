"""Circle-square contact at one level, solved exactly, checked against Hertz.

Writes ``contact_L{level}.csv`` (x, p, pressure, active per constrained node),
``hertz_L{level}.csv`` (one row: measured vs. Hertz half-width and peak
pressure, three estimators) and ``fields_L{level}.vtu`` (displacement, von
Mises stress, contact pressure). Called by the rule ``circle_square_level``.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

from problems.circle_square import PROBLEM
from problems.fem.output import write_vtu
from reference import hertz
from solvers.interface import solve
from problems.spec import ParameterError
from workflows.cli import parse_sets
from workflows.io import write_csv


def hertz_record(qp, result) -> dict:
    """Measured contact (moment and least-squares estimates) against plane-strain Hertz."""
    x = np.asarray(qp.geometry["points"])[qp.contact_nodes, 0]
    p = result.p
    pressure = p / qp.contact_mass
    E1, nu1, E2, nu2 = qp.geometry["E_star_params"]
    e_star = hertz.effective_modulus(E1, nu1, E2, nu2)
    P = float(p.sum())
    a_h = hertz.half_width(P, qp.geometry["radius"], e_star)
    p0_h = hertz.peak_pressure(P, a_h)
    xbar, a_m, p0_m = hertz.moment_estimate(x, p)
    a_f, p0_f = hertz.fit_semi_ellipse(x, pressure, xbar)
    h = float(np.min(np.diff(np.sort(x))))
    return {"force": P, "x_center": xbar, "a_hertz": a_h, "p0_hertz": p0_h,
            "a_moment": a_m, "p0_moment": p0_m, "a_fit": a_f, "p0_fit": p0_f,
            "p0_nodal_max": float(pressure.max()), "n_active": int((p > 0).sum()), "h": h,
            "a_over_h": a_m / h,
            "dev_a_moment": a_m / a_h - 1, "dev_p0_moment": p0_m / p0_h - 1,
            "dev_a_fit": a_f / a_h - 1, "dev_p0_fit": p0_f / p0_h - 1,
            "dev_p0_nodal_max": float(pressure.max()) / p0_h - 1,
            "check_P_pi2_a_p0": float(np.pi / 2 * a_m * p0_m / P - 1)}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--level", type=int, required=True)
    ap.add_argument("--outdir", required=True)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = ap.parse_args(argv)
    try:
        params = parse_sets(args.set)
    except ParameterError as err:
        raise SystemExit(f"error: {err}") from None
    out = Path(args.outdir)
    t0 = time.perf_counter()
    qp = PROBLEM.make(args.level, **params)
    t_build = time.perf_counter() - t0
    result = solve(qp, solver="pdas", tol=1e-10)
    row = {"level": args.level, "nodes": len(qp.geometry["points"]), "NC": qp.m, "n": qp.n,
           "status": result.status, "kkt_max": result.kkt.max, "build_time": t_build,
           "solve_time": result.total_time, **hertz_record(qp, result)}
    x = np.asarray(qp.geometry["points"])[qp.contact_nodes, 0]
    write_csv(out / f"contact_L{args.level}.csv",
              pd.DataFrame({"x": x, "p": result.p, "pressure": result.p / qp.contact_mass,
                            "gap": qp.g - qp.B @ result.u, "active": result.p > 0}))
    write_vtu(out / f"fields_L{args.level}.vtu", qp, result)
    write_csv(out / f"hertz_L{args.level}.csv", pd.DataFrame([row]))
    print(f"level {args.level}: {row['nodes']} nodes, {result.status}, kkt {result.kkt.max:.1e}, "
          f"a/a_H - 1 = {row['dev_a_moment']:+.2%}, p0/p0_H - 1 = {row['dev_p0_moment']:+.2%}")


if __name__ == "__main__":
    main()
