"""Contact patch test (issue item 8): the flat blocks on non-matching meshes, every
coupling and constrained side, level by level, solved exactly (PDAS).

The exact contact pressure is uniform (``problems/flat_blocks.py``:
``q = E (indent - gap) / ((1 - nu^2) 2)``). Per run: the largest and the rms
deviation of the nodal pressure (multiplier over lumped contact mass) from q, the
deviation of the total force, and the verified KKT residual. A coupling that
transmits the uniform pressure shows round-off; one that does not shows a
deviation that refinement does not remove.

Writes ``--out`` (one row per run) and ``--pressure`` (per constrained node of every
run: position and pressure / q, for the figure).

Example::

    python -m workflows.studies.adaptive.patch_test --problem flat_blocks --levels 0 1 2 3 \\
        --couplings nodal mortar stabilised two_pass --out results/flat_blocks/patch_test.csv \\
        --pressure results/flat_blocks/patch_test_pressure.csv
"""
from __future__ import annotations

import argparse

import numpy as np
import pandas as pd

from problems.qp import surface_multipliers
from problems.spec import ParameterError
from solvers.interface import solve
from workflows.io import write_csv
from workflows.scene_args import add_scene_arguments, check_levels, parse_sets, scene_from_args


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(parser)
    parser.add_argument("--levels", type=int, nargs="+", required=True)
    parser.add_argument("--couplings", nargs="+", default=["nodal", "mortar", "stabilised", "two_pass"])
    parser.add_argument("--sides", nargs="+", default=["coarse", "fine"])
    parser.add_argument("--out", required=True)
    parser.add_argument("--pressure", required=True)
    args = parser.parse_args(argv)
    spec, params = scene_from_args(parser, args)
    levels = check_levels(parser, spec, args.levels)
    module = __import__(f"problems.{spec.name}", fromlist=["exact_pressure"])
    if not hasattr(module, "exact_pressure"):
        parser.error(f"problem {spec.name!r} has no exact uniform pressure (exact_pressure)")
    given = parse_sets(args.set)
    rows, nodes = [], []
    for coupling in args.couplings:
        for side in args.sides:
            try:
                p = spec.options(**{**given, "coupling": coupling, "constrained": side})
            except ParameterError as err:
                parser.error(str(err))
            q = module.exact_pressure(p)
            for level in levels:
                qp = spec.build(level, p)
                res = solve(qp, "pdas", tol=1e-10)
                force = surface_multipliers(qp, res.p)      # on the constrained surface
                pressure = force / qp.contact.mass
                dev = pressure / q - 1.0
                rows.append({"coupling": coupling, "constrained": side, "ratio": p.ratio,
                             "level": level, "N": qp.n_nodes, "NC": qp.m_contact,
                             "n_reverse_rows": qp.m - qp.m_contact,
                             "h_constrained": float(np.median(np.diff(np.sort(
                                 qp.constrained_points()[:, 0])))),
                             "q_exact": q, "dev_max": float(np.abs(dev).max()),
                             "dev_rms": float(np.sqrt(np.mean(dev ** 2))),
                             "dev_mean": float(np.mean(dev)),
                             "dev_force": float(force.sum() / q - 1.0),
                             "n_active": int(np.sum(force > 0)), "status": res.status,
                             "kkt_max": res.kkt.max})
                nodes.append(pd.DataFrame({"coupling": coupling, "constrained": side,
                                           "level": level, "x": qp.constrained_points()[:, 0],
                                           "pressure_over_q": pressure / q}))
                r = rows[-1]
                print(f"{coupling:10s} {side:6s} L{level}: N^C = {qp.m_contact:3d}, pressure deviation "
                      f"max {r['dev_max']:.2e} rms {r['dev_rms']:.2e}, force {r['dev_force']:+.1e}, "
                      f"{res.status}")
    write_csv(args.out, pd.DataFrame(rows))
    write_csv(args.pressure, pd.concat(nodes, ignore_index=True))


if __name__ == "__main__":
    main()
