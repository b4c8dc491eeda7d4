"""``contactbench``: list the registries and solve one problem from the shell.

Examples
--------
::

    contactbench list
    contactbench solve --problem laplace_nonmatching --level 3 \\
        --set case=linear --set variant=nodal --out run.json

Bad input (unknown names, out-of-range values) ends with exit code 2 and a
message naming the parameter and what is allowed; nothing is written then.
"""
from __future__ import annotations

import argparse
import sys
import time
from typing import Any

import numpy as np

from problems.spec import ParameterError, lookup, problems, resolve_parameters
from workflows.io import provenance, write_json


def parse_sets(items: list[str]) -> dict[str, str]:
    out = {}
    for item in items or ():
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ParameterError(f"option '--set': {item!r} is not allowed; allowed: key=value")
        if key.strip() in out:
            raise ParameterError(f"option '--set': {key.strip()!r} is given twice")
        out[key.strip()] = value.strip()
    return out


def cmd_list(args: argparse.Namespace) -> int:
    from solvers.interface import TOLERANCES, solvers
    from workflows.studies import STUDIES

    print("problems:")
    for name, spec in problems().items():
        print(f"  {name}  [{spec.kind}; levels {spec.levels[0]}..{spec.levels[1]}, "
              f"default {spec.default_level}]\n      {spec.summary}")
        for p in spec.parameters:
            print(f"      --set {p.name}=...  (default {p.default!r}; {p.allowed()})  {p.help}")
    print("solvers:")
    for name, spec in solvers().items():
        print(f"  {name}  [{spec.role}]  {spec.summary}")
        for p in spec.parameters:
            print(f"      --set {p.name}=...  (default {p.default!r}; {p.allowed()})  {p.help}")
    print("tolerance presets: " + ", ".join(f"{k}={v:g}" for k, v in TOLERANCES.items()))
    print("studies (snakemake targets):")
    for name, study in STUDIES.items():
        print(f"  {name}  ({study.thesis})\n      {study.summary}")
    return 0


def contact_state(qp, result) -> dict[str, Any]:
    """The contact state of a solved ContactQP, for the JSON output.

    ``force`` is sum_i p_i n_i: the total force the constrained body exerts on the
    opposing one (the constrained body feels its negative).
    """
    p = np.asarray(result.p, dtype=float)
    out: dict[str, Any] = {"p": p}
    if qp.contact_nodes is not None and "points" in qp.geometry:
        out["x"] = np.asarray(qp.geometry["points"])[qp.contact_nodes]
    if qp.contact_mass is not None:
        out["pressure"] = p / qp.contact_mass
    if qp.contact_direction is not None:
        out["force"] = (p[:, None] * qp.contact_direction).sum(axis=0)
    slack = qp.g - qp.B @ result.u
    out["active"] = (p > 0) & (slack <= 1e-8 * max(np.max(np.abs(qp.g)), 1e-300))
    return out


def cmd_solve(args: argparse.Namespace) -> int:
    spec = lookup(problems(), args.problem, "problem")
    params = parse_sets(args.set)
    level = spec.check_level(spec.default_level if args.level is None else args.level)
    record: dict[str, Any] = {"problem": spec.name, "level": level, "kind": spec.kind}
    if spec.kind == "linear":
        if args.solver not in (None, "direct"):
            raise ParameterError(f"option '--solver': {args.solver!r} is not allowed for the linear "
                                 f"problem {spec.name!r}; allowed: direct")
        problem = spec.make(level, **resolve_parameters(spec.parameters, params,
                                                        f"problem '{spec.name}'"))
        t0 = time.perf_counter()
        sol = problem.solve()
        record.update(solver="direct", status="converged" if sol.residual < 1e-10 else "inaccurate",
                      time=time.perf_counter() - t0, params=problem.params, **sol.record())
    else:
        from solvers.interface import solve, solvers

        solver = args.solver or "pdas"
        lookup(solvers(), solver, "solver")
        # parameters of the scene vs. of the solver: --set names are split by owner
        solver_spec = solvers()[solver]
        solver_names = {p.name for p in solver_spec.parameters}
        scene_params = resolve_parameters(
            spec.parameters, {k: v for k, v in params.items() if k not in solver_names},
            f"problem '{spec.name}' (or solver '{solver}')")
        solver_params = resolve_parameters(
            solver_spec.parameters, {k: v for k, v in params.items() if k in solver_names},
            f"solver '{solver}'")
        t0 = time.perf_counter()
        qp = spec.make(level, **scene_params)
        t_build = time.perf_counter() - t0
        result = solve(qp, solver=solver, tol=args.tol, max_iter=args.max_iter,
                       time_limit=args.time_limit, **solver_params)
        record.update(params=scene_params, solver_options=solver_params, n=qp.n, m=qp.m,
                      build_time=t_build, **result.summary(),
                      kkt=result.kkt.as_dict(prefix=""), contact=contact_state(qp, result))
        if args.vtu:
            from problems.fem.output import write_vtu  # noqa: PLC0415 (optional dependency path)
            write_vtu(args.vtu, qp, result)
    record["provenance"] = provenance()
    write_json(args.out, record)
    print(f"{spec.name} level {level}: status {record['status']} -> {args.out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="contactbench", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("list", help="list problems, solvers and studies").set_defaults(func=cmd_list)
    s = sub.add_parser("solve", help="solve one problem at one level and write JSON")
    s.add_argument("--problem", required=True, help="problem name (see 'contactbench list')")
    s.add_argument("--level", type=int, default=None, help="refinement level")
    s.add_argument("--solver", default=None, help="solver name (contact problems; default pdas)")
    s.add_argument("--tol", default="mid", help="low | mid | high or a number in (0, 1)")
    s.add_argument("--max-iter", type=int, default=None, dest="max_iter")
    s.add_argument("--time-limit", type=float, default=None, dest="time_limit", help="seconds")
    s.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="problem or solver parameter (repeatable)")
    s.add_argument("--out", required=True, help="JSON file to write (atomically)")
    s.add_argument("--vtu", default=None, help="also write fields as VTU (contact problems)")
    s.set_defaults(func=cmd_solve)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except ParameterError as err:
        print(f"contactbench: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
