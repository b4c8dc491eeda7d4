"""``contactbench``: list the registries and solve one problem from the shell.

Examples
--------
::

    contactbench list
    contactbench solve --problem circle_square --level 2 --solver augmented_projection \\
        --set schur=multilevel --set ahat.sweeps=2 --out run.json --vtu run.vtu
    contactbench solve --problem laplace_nonmatching --level 3 \\
        --set case=linear --set variant=nodal --out run.json
    contactbench export --class small --out contact-qp-small
    contactbench study augmented_projection --problem circle_square --levels 1 2 \\
        --configs alg84 --out ap.csv

Every failure ends with exit code 2 and one line naming the parameter and what
is allowed (``--debug``, anywhere on the line, shows the traceback); nothing is
written then. A solver's own failure is not one: whatever it does (raises, returns a
broken answer; with ``--time-limit``, which runs it in a child process killed at
``1.25 x`` the limit ``+ 30 s``, also a crash of that process or a hang) is a ``failed``
or ``time_limit`` row in ``--out`` with ``failed_check`` saying why, exit code 0; a
traceback it raised is kept in the row (``--debug`` also prints it). A reader that
stops early (``contactbench list | head``) ends the command quietly (exit code 141,
as for SIGPIPE). The output paths are checked before any work starts; an existing
file is kept unless ``--force`` is given. Result files are written atomically.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any

from problems.spec import ParameterError, lookup, problems
from workflows.io import provenance, write_json, write_vtu
from workflows.mesh_store import keep_meshes_from_environment
from workflows.scene_args import parse_sets


def check_output(path: str | None, option: str, force: bool, suffix: str) -> None:
    """Refuse an output path that cannot be written or would overwrite a result.

    Raises
    ------
    ParameterError
        Naming ``option``: a directory, a missing or read-only parent directory,
        a wrong suffix, or an existing file without ``--force``.
    """
    if path is None:
        return
    p = Path(path)
    if p.suffix.lower() != suffix:
        raise ParameterError(f"option '{option}': {path!r} is not allowed; allowed: a file "
                             f"name ending in {suffix}")
    if p.is_dir():
        raise ParameterError(f"option '{option}': {path!r} is a directory; allowed: a file path")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise ParameterError(f"option '{option}': directory {str(parent)!r} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ParameterError(f"option '{option}': directory {str(parent)!r} is not writable")
    if p.exists() and not force:
        raise ParameterError(f"option '{option}': {path!r} exists; allowed: a new file, or "
                             "--force to replace it")


def cmd_list(args: argparse.Namespace) -> int:
    from solvers.interface import TOLERANCES, solvers
    from workflows.studies import STUDIES

    def show(parameters):
        for p in parameters:
            if hasattr(p, "kinds"):
                print(f"      --set {p.name}=...  (default {p.default!r}; {p.allowed()})  {p.help}")
                for kind, opts in p.kinds.items():
                    for o in opts:
                        print(f"          --set {p.name}.{o.name}=...  [{kind}] (default "
                              f"{o.default!r}; {o.allowed()})  {o.help}")
            else:
                print(f"      --set {p.name}=...  (default {p.default!r}; {p.allowed()})  {p.help}")

    print("problems:")
    for name, spec in problems().items():
        print(f"  {name}  [{spec.kind}; levels {spec.levels[0]}..{spec.levels[1]}, "
              f"default {spec.default_level}]\n      {spec.summary}")
        show(spec.parameters)
    print("solvers:")
    for name, spec in solvers().items():
        module = spec.solve.__module__
        origin = "" if module.startswith("solvers.") else f"; plug-in {module}"
        print(f"  {name}  [{spec.role}{origin}]  {spec.summary}")
        show(spec.parameters)
    print("tolerance presets: " + ", ".join(f"{k}={v:g}" for k, v in TOLERANCES.items()))
    print("studies (snakemake targets):")
    for name, study in STUDIES.items():
        print(f"  {name}  ({study.thesis})\n      {study.summary}")
    return 0


def _solve_linear(spec, level: int, params: dict, args: argparse.Namespace) -> dict[str, Any]:
    for option, value, default in (("--solver", args.solver, None), ("--tol", args.tol, None),
                                   ("--max-iter", args.max_iter, None),
                                   ("--time-limit", args.time_limit, None),
                                   ("--cold", args.cold, False), ("--vtu", args.vtu, None)):
        if value != default:
            raise ParameterError(f"option '{option}' does not apply to the linear problem "
                                 f"{spec.name!r} (it is solved directly, without contact); "
                                 "allowed: leave it out")
    problem = spec.make(level, **params)
    t0 = time.perf_counter()
    sol = problem.solve()
    return {"solver": "direct", "status": "converged" if sol.residual < 1e-10 else "inaccurate",
            "time": time.perf_counter() - t0, "params": problem.params, **sol.record()}


def split_sets(params: dict, scene, solver) -> tuple[dict, dict]:
    """``--set`` values split by owner: ``(scene's, solver's)``. A key (a dotted one by
    its head) belongs to the solver if it declares it, else to the scene.

    Raises
    ------
    ParameterError
        For a key that neither declares, naming both and listing their parameters
        (or saying that the solver has none).
    """
    def names(parameters):
        return [p.name for p in parameters]

    mine = {k: v for k, v in params.items() if k.partition(".")[0] in names(solver.parameters)}
    scene_keys = {k: v for k, v in params.items() if k not in mine}
    unknown = [k for k in scene_keys if k.partition(".")[0] not in names(scene.parameters)]
    if unknown:
        theirs = ", ".join(names(solver.parameters)) or "none (it takes no --set options)"
        raise ParameterError(
            f"problem {scene.name!r} has no parameter {', '.join(map(repr, unknown))}, nor has "
            f"solver {solver.name!r}; known parameters of problem {scene.name!r}: "
            f"{', '.join(names(scene.parameters)) or 'none'}; of solver {solver.name!r}: {theirs}")
    return scene_keys, mine


def _solve_contact(spec, level: int, params: dict, args: argparse.Namespace) -> dict[str, Any]:
    from problems.fem.fields import contact_fields, contact_state, friction_state
    from solvers.interface import check_limits, run_load_path, solve, solvers
    from solvers.kernels.tresca import warm_start
    from workflows.isolation import solve_isolated

    solver = lookup(solvers(), args.solver or "pdas", "solver")
    scene, mine = split_sets(params, spec, solver)
    scene_opts = spec.options(**scene)
    solver_opts = solver.options(**mine)
    tol, max_iter, time_limit = check_limits(solver, args.tol or "mid", args.max_iter,
                                             args.time_limit)
    if args.cold and scene_opts.get("friction", "none") == "none":   # before any work
        raise ParameterError("option '--cold' is not allowed on a frictionless problem; "
                             "allowed: a frictional scene (--set friction=tresca or "
                             "coulomb), whose load steps it starts from zero")
    t0 = time.perf_counter()
    qp = spec.build(level, scene_opts)
    t_build = time.perf_counter() - t0

    def solve_one(problem, start=None):
        guess = warm_start(start)
        if time_limit is None:
            return solve(problem, solver.name, tol, max_iter, **guess, **solver_opts)
        # in a child process: one that crashes or hangs past the hard limit is a row
        return solve_isolated(problem, solver.name, tol, time_limit, max_iter=max_iter,
                              **guess, **solver_opts)

    friction = None
    if qp.friction is None:
        result = solve_one(qp)
    else:   # the whole load path, each Tresca step by the solver (solvers.kernels.tresca)
        run = run_load_path(qp, solve_one, tol, warm=not args.cold)
        qp, result = run.qp, run.result
        friction = {"load_path": run.records}
    answer = result.kkt is not None
    record = {"params": dict(scene_opts), "n": qp.n, "m": qp.m, "n_nodes": qp.n_nodes,
              "units": qp.units, "build_time": t_build, **result.summary(),
              "solver_options": result.options,
              "kkt": result.kkt.as_dict(prefix="") if answer else None,
              "contact": contact_state(qp, result.u, result.p) if answer else None,
              "traceback": result.traceback or None}
    if friction is not None:
        if answer:
            friction.update(friction_state(qp, result.u, result.p, result.tangential, tol))
        record["friction"] = friction
    if args.vtu and answer:
        write_vtu(args.vtu, contact_fields(qp, result.u, result.p))
    return record


def cmd_solve(args: argparse.Namespace) -> int:
    spec = lookup(problems(), args.problem, "problem")
    check_output(args.out, "--out", args.force, ".json")
    check_output(args.vtu, "--vtu", args.force, ".vtu")
    params = parse_sets(args.set)
    level = spec.check_level(spec.default_level if args.level is None else args.level)
    run = _solve_linear if spec.kind == "linear" else _solve_contact
    record = {"problem": spec.name, "level": level, "kind": spec.kind,
              **run(spec, level, params, args), "provenance": provenance()}
    if args.out is not None:
        write_json(args.out, record)
    status = record["status"]
    why = f" ({record['message']})" if status in ("skipped", "failed") else ""
    if not why and record.get("failed_check"):
        why = f" (above tolerance: {record['failed_check']})"
    figures = "".join(f", {key} {record[key]:.1e}" for key in ("kkt_max", "energy_bound")
                      if isinstance(record.get(key), float))
    if isinstance(record.get("energy_bound"), float) and \
            record["energy_bound"] == record.get("energy_bound_floor"):
        figures += " (its rounding floor)"
    where = f" -> {args.out}" if args.out is not None else ""
    print(f"{spec.name} level {level}: {record['solver']} {status}{why}{figures}{where}")
    if record.get("traceback"):
        if args.debug:
            print(record["traceback"], end="", file=sys.stderr)
        else:
            kept = f"its traceback is in {args.out} ('traceback'; " if args.out else "("
            print(f"contactbench: the solver raised; {kept}--debug prints it)", file=sys.stderr)
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    from workflows.export import ExportError, export_set
    from workflows.problem_set import TestSetError, check_class, load

    try:
        ts = load(args.set)
        check_class(args.size_class)
        families = args.families or None
        items = ts.problems(args.size_class, families)
    except TestSetError as err:
        raise ParameterError(str(err)) from None
    if not items:
        raise ParameterError(f"option '--class': the set {ts.id} has no {args.size_class} "
                             "problems of the chosen families")
    try:
        out = export_set(ts, args.size_class, args.out, force=args.force, families=families,
                         progress=not args.quiet, fclib=args.format == "fclib",
                         multigrid=args.multigrid)
    except ExportError as err:
        raise ParameterError(str(err)) from None
    print(f"{ts.id} {args.size_class}: {len(items)} problems -> {out}/ (index.json; "
          f"qpbenchmark {out}/contact_qp.py run ...)")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="contactbench", description=__doc__.split("\n")[0])
    parser.add_argument("--debug", action="store_true",
                        help="show tracebacks (accepted anywhere on the command line)")
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("list", help="list problems, solvers and studies").set_defaults(func=cmd_list)
    s = sub.add_parser("solve", help="solve one problem at one level and write JSON")
    s.add_argument("--problem", required=True, help="problem name (see 'contactbench list')")
    s.add_argument("--level", default=None, help="refinement level")
    s.add_argument("--solver", default=None, help="solver name (contact problems; default pdas)")
    s.add_argument("--tol", default=None, help="low | mid | high or a number in (0, 1) "
                   "(contact problems; default mid)")
    s.add_argument("--max-iter", default=None, dest="max_iter", help="iteration cap")
    s.add_argument("--time-limit", default=None, dest="time_limit", help="seconds")
    s.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="problem or solver parameter (repeatable; solver components as "
                        "name=kind and name.option=value)")
    s.add_argument("--out", default=None,
                   help="JSON file to write (atomically); without it the run's status line "
                        "is printed and nothing is written")
    s.add_argument("--cold", action="store_true",
                   help="on a frictional scene, start every Tresca solve of the load path "
                        "from zero (default: from the path's last answer, as a "
                        "quasi-static computation does)")
    s.add_argument("--vtu", default=None, help="also write fields as VTU (contact problems)")
    s.add_argument("--force", action="store_true", help="replace existing output files")
    s.set_defaults(func=cmd_solve)
    from workflows.problem_set import CLASSES, CURRENT, available
    e = sub.add_parser("export", help="write a test set's problems as Matrix Market/npz "
                       "folders with the exact reference (min 1/2 x'Px + q'x s.t. Gx <= h)")
    e.add_argument("--set", default=CURRENT, help=f"test set (default {CURRENT}; allowed: "
                   f"{', '.join(available())})")
    e.add_argument("--class", dest="size_class", required=True,
                   help=f"size class: {' | '.join(CLASSES)}")
    e.add_argument("--families", nargs="+", default=None, metavar="FAMILY",
                   help="only these families of the set (default: all)")
    e.add_argument("--out", required=True, help="folder to create (written atomically)")
    e.add_argument("--format", choices=("qp", "fclib"), default="qp",
                   help="qp: the QP and cone folders (default); fclib: each folder also "
                        "with its fclib global file (fclib.hdf5: Coulomb steps and "
                        "frictionless problems; the reason in meta.json where there is none)")
    e.add_argument("--multigrid", action="store_true",
                   help="each folder also with what a multigrid solver needs "
                        "(multigrid.npz: the unknowns' nodes, components and coordinates, "
                        "the near-null space, the hierarchy's prolongations; mesh.vtu)")
    e.add_argument("--force", action="store_true", help="replace an existing folder")
    e.add_argument("--quiet", action="store_true", help="no progress bar")
    e.set_defaults(func=cmd_export)
    from workflows.studies import study_commands
    st = sub.add_parser("study", help="run one study's heavy step by hand (the script its "
                        "Snakemake rule runs); 'contactbench study NAME --help' lists its "
                        "arguments")
    st.add_argument("name", choices=list(study_commands()), metavar="NAME",
                    help=f"one of {', '.join(study_commands())}")
    st.add_argument("args", nargs=argparse.REMAINDER, help="the study's own arguments")
    st.set_defaults(func=cmd_study)
    return parser


def cmd_study(args: argparse.Namespace) -> int:
    """Run one study's script by hand, as its rule does: ``contactbench study NAME ARGS``
    hands ``ARGS`` to the script's own parser (so the same checks and exit codes)."""
    import importlib

    from workflows.studies import study_commands

    script = importlib.import_module(study_commands()[args.name])
    shown, sys.argv[0] = sys.argv[0], f"contactbench study {args.name}"   # the usage line
    try:
        script.main(args.args)
    finally:
        sys.argv[0] = shown
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    # --debug anywhere on the command line (before a "--" that ends the options)
    end = argv.index("--") if "--" in argv else len(argv)
    debug = "--debug" in argv[:end]
    argv = [a for i, a in enumerate(argv) if not (i < end and a == "--debug")]
    args = parser.parse_args(argv)
    args.debug = debug
    keep_meshes_from_environment()
    try:
        code = args.func(args)
        sys.stdout.flush()                 # a closed pipe is met here, not at exit
        return code
    except BrokenPipeError:           # the reader left (`contactbench list | head`): quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())    # no second error when Python flushes
        return 141
    except KeyboardInterrupt:
        print("contactbench: interrupted; nothing written", file=sys.stderr)
        return 130
    except Exception as err:  # noqa: BLE001 -- the one place a user could meet a traceback
        if args.debug:
            raise
        kind = "" if isinstance(err, ParameterError) else f"{type(err).__name__}: "
        text = " ".join(str(err).split())
        print(f"contactbench: error: {kind}{text}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
