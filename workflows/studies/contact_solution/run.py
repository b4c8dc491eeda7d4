"""One scene at one level, solved by the reference and checked against Hertz (study
contact_solution): the exact PDAS where a factorisation is affordable, else the
iterative reference to verified KKT residuals <= 1e-10 (:func:`solvers.reference.reference_solve`;
the column ``reference`` says which).

Writes, into ``--outdir``: ``contact_L{level}.csv`` (per constrained node:
position, multiplier, pressure, gap, active), ``hertz_L{level}.csv`` (one row:
the measured contact zone against Hertz, three estimators; only the solve's
numbers if the scene has no Hertz reference) and ``fields_L{level}.vtu``
(displacement, von Mises stress, contact pressure).

Example::

    python -m workflows.studies.contact_solution.run --problem circle_square --level 2 \\
        --outdir results/circle_square
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

from problems.fem.fields import contact_fields, contact_state, hertz_comparison, in_plane
from solvers.reference import reference_solve
from workflows.io import write_csv, write_vtu
from workflows.scene_args import add_scene_arguments, check_levels, scene_from_args


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(parser)
    parser.add_argument("--level", type=int, required=True)
    parser.add_argument("--outdir", required=True)
    args = parser.parse_args(argv)
    spec, params = scene_from_args(parser, args)
    (level,) = check_levels(parser, spec, [args.level])
    out = Path(args.outdir)
    t0 = time.perf_counter()
    qp = spec.build(level, params)
    t_build = time.perf_counter() - t0
    result = reference_solve(qp, tol=1e-10)
    state = contact_state(qp, result.u, result.p)
    row = {"level": level, "nodes": qp.n_nodes, "NC": qp.m, "n": qp.n,
           "reference": result.solver, "status": result.status,
           "kkt_max": result.kkt.max, "build_time": t_build, "solve_time": result.total_time,
           "force": float(np.sum(result.p))}
    if qp.hertz is not None and result.p.sum() > 0:
        row.update(hertz_comparison(qp, result.p))
    x, s = state["x"], in_plane(qp)
    columns = {**{f"x{i}": x[:, i] for i in range(x.shape[1])},
               **{f"s{i}": s[:, i] for i in range(s.shape[1])}}
    write_csv(out / f"contact_L{level}.csv",
              pd.DataFrame({**columns, "p": result.p, "pressure": state["pressure"],
                            "gap": state["gap"], "active": state["active"]}))
    write_vtu(out / f"fields_L{level}.vtu", contact_fields(qp, result.u, result.p))
    write_csv(out / f"hertz_L{level}.csv", pd.DataFrame([row]))
    print(f"{qp.name}: {row['nodes']} nodes, {result.status}, kkt {result.kkt.max:.1e}"
          + (f", a/a_H - 1 = {row['dev_a_moment']:+.2%}, p0/p0_H - 1 = "
             f"{row['dev_p0_moment']:+.2%}" if "dev_a_moment" in row else ""))


if __name__ == "__main__":
    main()
