"""Solver runs in a child process with a hard wall-clock limit.

A hung solver (ProxSuite cannot be interrupted; OSQP's limit does not cover its
factorisation), one that exhausts the memory or one that crashes (a segfault in
a library) must cost a study a row, never the study. :func:`solve_isolated`
forks, runs :func:`solvers.interface.solve` (with its verification) in the
child and sends the result back through a pipe; past the hard limit the child
is killed and the row says so.
"""
from __future__ import annotations

import multiprocessing as mp
import signal
import sys
import time
import traceback


from problems.qp import ContactQP
from solvers.interface import SolveResult, solve
from workflows.measure import peak_rss

#: Extra wall seconds beyond the solver's own time limit before the child is killed
#: (verification, teardown): ``hard = GRACE_FACTOR * time_limit + GRACE_SECONDS``.
GRACE_FACTOR, GRACE_SECONDS = 1.25, 30.0


def _child(conn, qp, solver, tols, time_limit, options):
    """Solve at every tolerance of ``tols`` in turn, sending each result at once."""
    for tol in tols:
        try:
            with peak_rss() as mem:
                res = solve(qp, solver=solver, tol=tol, time_limit=time_limit, **options)
            res.stats["peak_mem_mb"] = mem["peak_mb"]
            conn.send(("ok", res))
        except BaseException as err:  # noqa: BLE001 -- anything the parent must turn into a row
            conn.send(("error", (f"{type(err).__name__}: {err}", traceback.format_exc())))
    conn.close()


def log_traceback(result: SolveResult, where: str) -> None:
    """Print the traceback a solver raised (kept in ``result.traceback``) to stderr, which
    a study's rule sends to its log: the plug-in's author sees where it broke."""
    if result.traceback:
        print(f"{result.solver} at tol {result.tol:g} on {where} raised (row: failed, "
              f"failed_check exception):\n{result.traceback}", file=sys.stderr, flush=True)


def _row(qp: ContactQP, solver: str, tol: float, status: str, message: str,
         elapsed: float, failed_check: str, traceback: str = "") -> SolveResult:
    return SolveResult.without_answer(qp.n, qp.m, solver, tol, status, message, elapsed,
                                      failed_check=failed_check, traceback=traceback)


def hard_limit(time_limit: float | None) -> float | None:
    """The wall seconds after which a run's child is killed:
    ``GRACE_FACTOR * time_limit + GRACE_SECONDS`` (None without a time limit)."""
    return None if time_limit is None else GRACE_FACTOR * time_limit + GRACE_SECONDS


def solve_isolated(qp: ContactQP, solver: str, tol, time_limit: float | None,
                   **options) -> SolveResult:
    """:func:`solvers.interface.solve` in a forked child, killed past the hard limit.

    Returns the child's verified :class:`SolveResult` (with ``stats['peak_mem_mb']``),
    or a row with status ``time_limit`` (killed, ``failed_check = "hard_time_limit"``)
    or ``failed`` (the child raised, ``"exception"`` with the traceback kept, or died,
    e.g. by a signal, ``"process"``) and a message saying which. ``u`` and ``p`` of such
    a row are zeros; its ``kkt`` and ``gap`` are None. Without a ``time_limit`` the
    child is never killed.
    """
    return solve_batch_isolated(qp, solver, [tol], time_limit, **options)[0]


def solve_batch_isolated(qp: ContactQP, solver: str, tols: list, time_limit: float | None,
                         **options) -> list[SolveResult]:
    """:func:`solve_isolated` at several tolerances, in as few child processes as can be.

    One child solves at every tolerance in turn; each run has its own hard limit
    ``GRACE_FACTOR * time_limit + GRACE_SECONDS``. A run past it is killed (a
    ``time_limit`` row) and a child that dies takes only its current run with it (a
    ``failed`` row): the remaining tolerances go to a fresh child. One result per
    tolerance, in order.
    """
    from solvers.interface import parse_tolerance

    values = [parse_tolerance(t) for t in tols]
    hard = hard_limit(time_limit)
    ctx = mp.get_context("fork")
    results: list[SolveResult] = []
    while len(results) < len(tols):
        todo = tols[len(results):]
        receive, send = ctx.Pipe(duplex=False)
        proc = ctx.Process(target=_child, args=(send, qp, solver, todo, time_limit, options),
                           daemon=True)
        proc.start()
        send.close()
        clean = False                    # every result of this child received
        try:
            while len(results) < len(tols):
                tol_value = values[len(results)]
                t0 = time.perf_counter()
                try:
                    if not receive.poll(hard):
                        results.append(_row(
                            qp, solver, tol_value, "time_limit",
                            f"killed after the hard wall-clock limit of {hard:.0f} s "
                            f"(solver time limit {time_limit:g} s)", time.perf_counter() - t0,
                            "hard_time_limit"))
                        break
                    kind, payload = receive.recv()
                except EOFError:   # the child died before sending (killed, segfault, memory)
                    proc.join(10.0)
                    code = proc.exitcode
                    name = (signal.Signals(-code).name if code is not None and code < 0
                            else f"exit code {code}")
                    results.append(_row(qp, solver, tol_value, "failed",
                                        f"solver process died ({name})",
                                        time.perf_counter() - t0, "process"))
                    break
                results.append(payload if kind == "ok" else _row(
                    qp, solver, tol_value, "failed", f"failed: {payload[0]}",
                    time.perf_counter() - t0, "exception", payload[1]))
            else:
                clean = True
        finally:
            receive.close()
            if clean:
                proc.join(10.0)
            if proc.is_alive():
                proc.kill()
                proc.join(10.0)
    return results
