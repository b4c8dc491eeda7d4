"""Every registered solver on one hard scene (study hard_cases).

The reference (:func:`solvers.reference.reference_solve`) gives ``(u_ref, p_ref)``;
each solver runs at one preset in its own process with a hard wall-clock limit
(:func:`workflows.isolation.solve_isolated`). A row per solver: verified and
claimed status, the worst KKT residual, the certified energy bound, the energy
error against the reference, the multipliers' error (max norm, relative to the
largest reference multiplier, and in the S-norm ``||A^-1 B'(p - p_ref)||_A``
relative to ``||u_ref||_A``, the norm the certificate bounds), the total-force
error, wall time and the solver's message.

Example::

    python -m workflows.scripts.hard_case --scene hard_si_units --problem circle_square \\
        --set E1=2.1e11 --set E2=2.1e11 --set load=2.1e9 --level 1 --out hard.csv
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import pandas as pd
from tqdm import tqdm

from problems.kkt import energy_error
from solvers.interface import TOLERANCES, linear_solver, parse_tolerance, solvers
from solvers.reference import reference_solve
from workflows.io import write_csv
from workflows.isolation import solve_isolated
from workflows.scene_args import add_scene_arguments, check_levels, scene_from_args


def multiplier_errors(qp, p, p_ref, u_ref) -> dict:
    """Errors of the multipliers against the reference (max norm, S-norm, total force)."""
    top = float(np.max(np.abs(p_ref))) if p_ref.size else 0.0
    dp = np.asarray(p) - p_ref
    w = linear_solver(qp)(qp.B.T @ dp)
    s_norm = float(np.sqrt(max(w @ (qp.A @ w), 0.0)))
    norm_u = float(np.sqrt(max(u_ref @ (qp.A @ u_ref), 0.0)))
    force = float(np.sum(p_ref))
    return {"multiplier_error": float(np.max(np.abs(dp))) / top if top > 0
            else float(np.max(np.abs(dp), initial=0.0)),
            "multiplier_error_S": s_norm / norm_u if norm_u > 0 else s_norm,
            "force_error": abs(float(np.sum(p)) - force) / abs(force) if force > 0
            else abs(float(np.sum(p)))}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(parser)
    parser.add_argument("--scene", required=True, help="the case's name (a config scene)")
    parser.add_argument("--level", type=int, required=True)
    parser.add_argument("--preset", default="mid", choices=list(TOLERANCES))
    parser.add_argument("--time-limit", type=float, default=60.0)
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    spec, params = scene_from_args(parser, args)
    (level,) = check_levels(parser, spec, [args.level])
    tol = parse_tolerance(args.preset)
    qp = spec.build(level, params)
    t0 = time.perf_counter()
    ref = reference_solve(qp, tol=1e-10)
    t_ref = time.perf_counter() - t0
    base = {"case": args.scene, "problem": spec.name, "level": level, "n": qp.n, "m": qp.m,
            "dropped_rows": qp.contact.dropped if qp.contact is not None else 0,
            "reference": ref.solver, "reference_status": ref.status,
            "reference_active": int(np.sum(ref.p > 0)), "preset": args.preset, "tol": tol}
    rows = []
    for solver in tqdm(list(solvers()), desc=f"hard case {args.scene}"):
        t0 = time.perf_counter()
        res = solve_isolated(qp, solver, args.preset, time_limit=args.time_limit)
        row = {**base, **res.summary(), "wall_time": time.perf_counter() - t0,
               "reference_time": t_ref}
        if res.kkt is not None:
            row.update(energy_error=energy_error(qp, res.u, ref.u),
                       **multiplier_errors(qp, res.p, ref.p, ref.u))
        rows.append(row)
    write_csv(args.out, pd.DataFrame(rows))


if __name__ == "__main__":
    main()
