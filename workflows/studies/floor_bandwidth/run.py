"""The floor against the machine: the bytes one V-cycle and one PCG step of the linear
floor (:func:`workflows.measure.amg_pcg_floor`: geometric-multigrid PCG on the refinement
hierarchy) must move, over their measured time, against this core's STREAM triad
bandwidth measured in the same process.

Per level: the hierarchy (levels, operator complexity), the bytes of a V-cycle split into
matrix values, index arrays and vectors, the bytes of a PCG step (its V-cycle, ``A p``
and the vector operations), the median time of each, the attained bandwidth in GB/s and
its share of the triad's. One process, one thread, the levels one after the other
(timings comparable). Called by the rule ``floor_bandwidth_study``.

Example::

    python -m workflows.studies.floor_bandwidth.run --problem circle_square --levels 2 3 \\
        --repeats 7 --out results/circle_square/floor_bandwidth_runs.csv
"""
from __future__ import annotations

import argparse

import pandas as pd

from workflows.io import write_csv
from workflows.measure import floor_traffic, stream_triad_gbs
from workflows.progress import study_progress
from workflows.scene_args import add_scene_arguments, check_levels, scene_from_args
from workflows.settings import study_defaults

#: The study's defaults, declared once in the config schema (workflows/settings.py).
DEFAULTS = study_defaults("floor_bandwidth")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(parser)
    parser.add_argument("--levels", type=int, nargs="+", required=True)
    parser.add_argument("--repeats", type=int, default=DEFAULTS["repeats"],
                        help="timed runs per level, the median kept (>= 1)")
    parser.add_argument("--cg-steps", type=int, default=DEFAULTS["cg_steps"],
                        help="PCG steps per timed run (>= 1)")
    parser.add_argument("--stream-mb", type=float, default=DEFAULTS["stream_mb"],
                        help="MB of the STREAM triad's three arrays (>= 24; beyond the "
                             "caches)")
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    spec, params = scene_from_args(parser, args)
    levels = check_levels(parser, spec, args.levels)
    for name in ("repeats", "cg_steps"):
        if getattr(args, name) < 1:
            parser.error(f"argument --{name.replace('_', '-')}: {getattr(args, name)} is not "
                         "allowed; allowed: >= 1")
    if not args.stream_mb >= 24:
        parser.error(f"argument --stream-mb: {args.stream_mb} is not allowed; allowed: >= 24")
    entries = int(args.stream_mb * 1e6 / 24)
    rows = []
    for level in study_progress(levels, rule="floor_bandwidth_study", out=args.out,
                                desc=f"floor bandwidth on {spec.name}"):
        qp = spec.build(level, params)
        row = floor_traffic(qp, args.repeats, args.cg_steps)
        rows.append({"scene_problem": spec.name, "level": level, "N": qp.n_nodes,
                     "dim": qp.dim, **row})
    stream = stream_triad_gbs(entries)          # after the levels: the same warm process
    table = pd.DataFrame(rows)
    table["stream_triad_gbs"] = stream
    table["stream_mb"] = 24 * entries / 1e6
    write_csv(args.out, table)


if __name__ == "__main__":
    main()
