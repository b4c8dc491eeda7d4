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


def _child(conn, qp, solver, time_limit, options):
    """Solve each request ``(tol, extra)`` the parent sends, sending each result at once,
    until the parent sends None. Each run starts without the work of the runs before it
    (``qp.cache``: factorisations, the verification's solver): every run pays its own;
    its verification, after the run, reuses the earlier verifications' work."""
    kept = qp.cache
    while (request := conn.recv()) is not None:
        tol, extra = request
        qp.cache = kept.problem_only()
        try:
            with peak_rss() as mem:
                res = solve(qp, solver=solver, tol=tol, time_limit=time_limit,
                            verification_work=kept, **options, **extra)
            kept = qp.cache
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
    with IsolatedSolver(qp, solver, time_limit, **options) as child:
        return child.solve(tol)


def solve_batch_isolated(qp: ContactQP, solver: str, tols: list, time_limit: float | None,
                         **options) -> list[SolveResult]:
    """:func:`solve_isolated` at several tolerances, in one child process where it lives
    through them (:class:`IsolatedSolver`); one result per tolerance, in order."""
    with IsolatedSolver(qp, solver, time_limit, **options) as child:
        return [child.solve(tol) for tol in tols]


class IsolatedSolver:
    """Runs of one solver on one problem, each in a forked child with a hard limit.

    One child serves the runs in turn (a fork, the problem and its caches shared), each
    run with its own hard limit ``GRACE_FACTOR * time_limit + GRACE_SECONDS``. A run
    past it is killed (a ``time_limit`` row) and a child that dies takes only its
    current run with it (a ``failed`` row): the next run starts a fresh child. Use as a
    context manager; :meth:`solve` takes the arguments of
    :func:`solvers.interface.solve` beyond the problem, solver, time limit and the
    options given here.
    """

    def __init__(self, qp: ContactQP, solver: str, time_limit: float | None, **options):
        self.qp, self.solver, self.time_limit, self.options = qp, solver, time_limit, options
        self.hard = hard_limit(time_limit)
        self._proc = self._conn = None

    def __enter__(self) -> "IsolatedSolver":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _start(self) -> None:
        ctx = mp.get_context("fork")
        self._conn, theirs = ctx.Pipe(duplex=True)
        self._proc = ctx.Process(target=_child, args=(theirs, self.qp, self.solver,
                                                      self.time_limit, self.options),
                                 daemon=True)
        self._proc.start()
        theirs.close()

    def _stop(self, clean: bool) -> None:
        if self._proc is None:
            return
        try:
            if clean:
                self._conn.send(None)
                self._proc.join(10.0)
        except (BrokenPipeError, OSError):
            pass
        finally:
            self._conn.close()
            if self._proc.is_alive():
                self._proc.kill()
                self._proc.join(10.0)
            self._proc = self._conn = None

    def close(self) -> None:
        """End the child (if one lives)."""
        self._stop(clean=True)

    def solve(self, tol, **extra) -> SolveResult:
        """One verified run at ``tol`` (and ``extra``, e.g. ``stop_factor``, ``u0``,
        ``p0``) in the child, or the row of its kill, death or exception."""
        from solvers.interface import parse_tolerance

        tol_value = parse_tolerance(tol)
        if self._proc is None:
            self._start()
        t0 = time.perf_counter()
        try:
            self._conn.send((tol, extra))
            if not self._conn.poll(self.hard):
                self._stop(clean=False)
                return _row(self.qp, self.solver, tol_value, "time_limit",
                            f"killed after the hard wall-clock limit of {self.hard:.0f} s "
                            f"(solver time limit {self.time_limit:g} s)",
                            time.perf_counter() - t0, "hard_time_limit")
            kind, payload = self._conn.recv()
        except (EOFError, BrokenPipeError, OSError):  # the child died (killed, segfault, memory)
            self._proc.join(10.0)
            code = self._proc.exitcode
            name = (signal.Signals(-code).name if code is not None and code < 0
                    else f"exit code {code}")
            self._stop(clean=False)
            return _row(self.qp, self.solver, tol_value, "failed",
                        f"solver process died ({name})", time.perf_counter() - t0, "process")
        if kind == "ok":
            return payload
        return _row(self.qp, self.solver, tol_value, "failed", f"failed: {payload[0]}",
                    time.perf_counter() - t0, "exception", payload[1])
