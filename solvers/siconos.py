"""Siconos's frictional-contact solvers (INRIA's numerics library, the solvers of the
frictional-contact community's benchmarks over fclib's collection), on the local form of
a frictional step, in a process of their own under the system Python.

The step's fclib form (:mod:`solvers.kernels.fclib_form`: ``M = A``, ``H_i = [-B_i',
-T_i']`` per contact, ``w`` from the gaps and the previous state) gives the local problem
``u = W r + q`` with the Delassus operator ``W = H'A^-1 H`` (dense; ``A`` factorised once,
``W``'s columns partial solves on the contact rows, the factor kept to recover
``u = A^-1 (f - B'p - T'lam)`` from the reactions ``r_i = (p_i, lam_i)``). Siconos's
solvers take the law per contact in three dimensions; a 2D step is solved as a 3D one
whose second tangential component is decoupled (:func:`embed_2d`: ``W`` extended by
``c I`` on it, ``q`` by zero), where the law forces that component's reaction to zero, so
the 2D law is solved exactly.

Two solvers:

``siconos_nsgs``
    Nonsmooth Gauss-Seidel over the contacts: Coulomb's law itself on a Coulomb step
    (``SICONOS_FRICTION_3D_NSGS``), and on a Tresca step the Tresca problem of the
    step's slip bounds (Siconos's Tresca fixed point held to one outer step: its inner
    Gauss-Seidel, with the projection onto each contact's cylinder, is that problem; the
    cylinders' radii ``s_i`` are handed over as the normal part of its initial reactions
    with ``mu = 1``, the only way Python can set them).
``siconos_newton``
    The nonsmooth Newton method on Alart and Curnier's function with its line search
    (``SICONOS_FRICTION_3D_NSN_AC``), Coulomb steps only: Siconos offers no Newton method
    for a Tresca step (its Tresca solvers are the fixed point above and a projected
    gradient whose radii Python cannot set).

A Coulomb step is solved monolithically (``s = mu p`` inside Siconos's iteration,
``stats["friction"]`` :data:`solvers.base.COULOMB_MONOLITHIC`) and verified as the Tresca
step of its own bound ``mu p``, as every monolithic answer is. The stop is Siconos's own
error (a scaled natural-map residual of the law) at ``tol_factor * tol``; the suite's
verification decides the status like any solver's.

Skipped at once, with the reason: a frictionless problem (the suite's own and the QP
libraries take it), the faceted law and a stabilised problem (no fclib form), a local form
beyond :data:`solvers.kernels.fclib_form.LOCAL_MAX_ENTRIES` (dense ``W``), and a machine
without Siconos (the install command). Where it runs: the interpreter with
``siconos.numerics`` is ``CONTACTBENCH_SICONOS_PYTHON`` (default ``/usr/bin/python3``).
"""
from __future__ import annotations

import base64
import json
import os
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from problems.qp import ContactQP
from problems.spec import Options, Parameter
from solvers import system_python
from solvers.base import (COULOMB_MONOLITHIC, TOLERANCES, Role, SolveResult, SolverSpec,
                          guess_not_used)
from solvers.kernels.cholesky import FactorizationError
from solvers.kernels.fclib_form import (LOCAL_MAX_ENTRIES, contact_columns, fclib_form,
                                        global_problem, local_factor, local_problem)

#: The worker script, shipped beside this module (run by the interpreter with Siconos).
WORKER = Path(__file__).with_name("_siconos_worker.py")
#: The first word of the worker's answer line.
TAG = "contactbench-siconos"
#: How to get Siconos on Debian (the skip reason names it).
INSTALL = "apt-get install --no-install-recommends python3-siconos"


def interpreter() -> tuple[str, str]:
    """``(python, "")``: the interpreter that imports ``siconos.numerics``, or ``("", why)``."""
    python = os.environ.get("CONTACTBENCH_SICONOS_PYTHON", "/usr/bin/python3")
    why = system_python.probe(python, "siconos.numerics")
    if why:
        return "", f"{why} (CONTACTBENCH_SICONOS_PYTHON): install Siconos ({INSTALL} on Debian)"
    return python, ""


# --------------------------------------------------------------------- the local form
def embed_2d(W: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A 2D local problem (two components per contact) as a 3D one: the second tangential
    component of each contact decoupled with ``W = c`` (``c`` the mean of ``W``'s
    diagonal) and ``q = 0``. The law then forces its reaction to zero (``u = c r`` on it
    must oppose ``r`` where the contact slips, and vanish where it sticks), and the other
    two components solve the 2D law. Returns ``W3, q3`` and the 3D positions of the 2D
    entries."""
    m = W.shape[0] // 2
    kept = (3 * np.arange(m)[:, None] + np.arange(2)).ravel()
    W3 = np.zeros((3 * m, 3 * m))
    W3[np.ix_(kept, kept)] = W
    W3[3 * np.arange(m) + 2, 3 * np.arange(m) + 2] = float(np.mean(np.diag(W)))
    q3 = np.zeros(3 * m)
    q3[kept] = q
    return W3, q3, kept


def _tresca(qp: ContactQP) -> bool:
    """A Tresca step (its bounds given), not a Coulomb step Siconos solves itself."""
    return qp.friction.law != "coulomb"


def local_form(qp: ContactQP) -> tuple:
    """``(W3, q3, mu, kept, solve_A)``: the step's local problem in three dimensions
    (:func:`embed_2d` in 2D), its friction coefficients (a Tresca step: ones, the radii
    going with the initial reactions), the 3D positions of fclib's entries and the solve
    with ``A``.

    Raises
    ------
    solvers.kernels.cholesky.FactorizationError
        Where ``A`` is not positive definite (a floating body: no ``A^-1``).
    """
    coulomb = not _tresca(qp)
    as_coulomb = qp if coulomb else replace(qp, friction=replace(qp.friction, law="coulomb"))
    problem = global_problem(as_coulomb, coulomb=True)
    factor = local_factor(problem)
    local = local_problem(problem, factor)
    if qp.dim == 2:
        W3, q3, kept = embed_2d(local.W, local.q)
    else:
        W3, q3, kept = local.W, local.q, np.arange(local.q.size)
    mu = np.asarray(local.mu, dtype=float) if coulomb else np.ones(qp.m)
    return W3, q3, mu, kept, factor.solve


def answer(qp: ContactQP, r_fclib: np.ndarray, solve_A) -> tuple:
    """``(u, p, lam)`` of fclib's reactions ``r`` (normal first per contact):
    ``p = r_N``, ``lam = r_T``, ``u = A^-1 (f - B'p - T'lam)``."""
    normal, tangential = contact_columns(qp.m, qp.dim)
    p, lam = r_fclib[normal], r_fclib[tangential]
    u = solve_A(qp.f - qp.B.T @ p - qp.friction.T.T @ lam)
    return np.asarray(u, dtype=float), p, lam


# ----------------------------------------------------------------------- the solvers
def supports_for(method: str):
    def supports(qp: ContactQP) -> tuple[bool, str]:
        fr = qp.friction
        if fr is None:
            return False, ("a frictionless problem: Siconos's friction-contact solvers are "
                           "offered for frictional steps (the frictionless problem is the "
                           "suite's own solvers' and the QP libraries')")
        why = fclib_form(qp)
        if why:
            return False, f"no fclib form: {why}"
        if method == "nsn_ac" and _tresca(qp):
            return False, ("a Tresca step: Siconos's nonsmooth Newton methods solve Coulomb's "
                           "law only (its Tresca solvers are the fixed point siconos_nsgs "
                           "takes and a projected gradient whose radii Python cannot set)")
        k = qp.m * 3
        if k * k > LOCAL_MAX_ENTRIES:
            return False, (f"the local form's dense Delassus operator: {k} x {k} entries "
                           f"exceed {LOCAL_MAX_ENTRIES}")
        python, why = interpreter()
        return bool(python), why
    return supports


def _no_answer(qp: ContactQP, status: str, message: str, **fields) -> SolveResult:
    """The row of a solve that gave no reactions (``status``, ``message`` say why)."""
    return SolveResult(u=np.zeros(qp.n), p=np.zeros(qp.m), claimed_status=status,
                       message=message, tangential=np.zeros(qp.friction.T.shape[0]), **fields)


def _claimed(record: dict, tol: float, max_iter: int) -> str:
    if record["info"] == 0 or record["error"] <= tol:
        return "converged"
    return "max_iter" if record["iterations"] >= max_iter else "failed"


def solve_with(method: str):
    def solve(qp: ContactQP, tol: float, max_iter: int, time_limit: float | None,
              u0: np.ndarray | None, p0: np.ndarray | None, opts: Options) -> SolveResult:
        t_start = time.perf_counter()
        python, why = interpreter()
        if not python:
            raise RuntimeError(why)
        fr, coulomb = qp.friction, not _tresca(qp)
        try:
            W3, q3, mu, kept, solve_A = local_form(qp)
        except FactorizationError as err:
            return _no_answer(qp, "failed", f"the local form needs A^-1: {err}",
                              solve_time=time.perf_counter() - t_start)
        r0 = np.zeros(q3.size)
        normal3 = 3 * np.arange(qp.m)
        note = ""
        if coulomb:
            if p0 is not None:
                r0[normal3] = np.maximum(np.asarray(p0, dtype=float), 0.0)
        else:
            r0[normal3] = fr.slip_bound                  # the cylinders' radii (mu = 1)
            if u0 is not None or p0 is not None:
                note = "the Tresca route's initial reactions carry the slip bounds"
        internal = "tresca" if (method == "nsgs" and not coulomb) else method
        stop = tol * opts.tol_factor
        header = json.dumps({"method": internal, "contacts": qp.m, "tol": stop,
                             "max_iter": max_iter}).encode() + b"\n"
        stream = header + b"".join(np.ascontiguousarray(a, dtype="<f8").tobytes()
                                   for a in (W3, q3, mu, r0))
        hard = None if time_limit is None else time_limit + opts.grace
        setup_time = time.perf_counter() - t_start
        # isolated (-I): the worker's directory is not on its path, where this module would
        # stand for the package ``siconos``
        job = system_python.run_job([python, "-I", str(WORKER)], system_python.clean_environment(),
                                    stream, hard, TAG, "Siconos's process")
        stats = {"friction": COULOMB_MONOLITHIC if coulomb else "tresca_step",
                 "form": "local, 2D embedded in 3D" if qp.dim == 2 else "local",
                 "contacts": qp.m, "job_wall_time": job.wall}
        if job.record is None:
            return _no_answer(qp, job.status, job.message, setup_time=setup_time,
                              solve_time=job.wall, stats=stats)
        rec = job.record
        r3 = np.frombuffer(base64.b64decode(rec["r"]), dtype="<f8").astype(float)
        if r3.shape != q3.shape:
            raise RuntimeError(f"Siconos answered {r3.size} reactions for {q3.size}")
        t_back = time.perf_counter()
        u, p, lam = answer(qp, r3[kept], solve_A)
        status = _claimed(rec, stop, max_iter)
        law = "Coulomb's law" if coulomb else "the Tresca step (fixed point held to one step)"
        message = (f"Siconos {rec['version']} {rec['solver']} on {law}: info {rec['info']}, "
                   f"{rec['iterations']} iterations, Siconos's error {rec['error']:.2g}")
        if note:
            message = guess_not_used(message, note)
        stats.update({"siconos_solver": rec["solver"], "siconos_info": rec["info"],
                      "siconos_error": rec["error"], "siconos_solve_time": rec["solve_time"]})
        return SolveResult(u=u, p=p, claimed_status=status, message=message,
                           iterations=int(rec["iterations"]), setup_time=setup_time,
                           solve_time=job.wall + time.perf_counter() - t_back, stats=stats,
                           tangential=lam)
    return solve


def _parameters() -> tuple:
    cost = ("the local form costs A's factorisation and one partial solve with it (the "
            "contact rows only) per column of H (one per component of each contact), and "
            "Siconos's dense W grows as the contacts squared")
    return (
        Parameter("max_unknowns_2d", 160_000, f"{cost}: in 2D the largest taken is "
                  "circle-square's load path at 149,616 unknowns (161 contacts)", low=1,
                  kind=int),
        Parameter("max_unknowns_3d", 60_000, f"{cost}: in 3D the largest taken is "
                  "cube-sphere's load path at 51,459 unknowns (289 contacts)", low=1,
                  kind=int),
        Parameter("tol_factor", 0.01, "Siconos's stop at tol_factor * tol on its own error (the "
                  "suite's verification decides)", low=0.0, high=1.0, low_open=True),
        Parameter("grace", 30.0, "wall seconds the process gets beyond time_limit (start-up, "
                  "the answer) before it is killed", low=0.0, low_open=True),
    )


_PRESETS = {name: f"Siconos's error <= tol_factor * {tol:g} (tol_factor = 0.01)"
            for name, tol in TOLERANCES.items()}


def _spec(name: str, method: str, summary: str, default_max_iter: int) -> SolverSpec:
    """A Siconos solver of ``method`` (the worker's) with the options they share."""
    return SolverSpec(
        name=name, summary=summary, solve=solve_with(method), parameters=_parameters(),
        presets=_PRESETS, default_max_iter=default_max_iter, role=Role.OTHER,
        handles_friction=True, size_limit={2: "max_unknowns_2d", 3: "max_unknowns_3d"},
        facets_reason="fclib's and Siconos's cone is the isotropic one",
        supports=supports_for(method))


SOLVERS = (
    _spec("siconos_nsgs", "nsgs",
          "Siconos's nonsmooth Gauss-Seidel on the local (Delassus) form: Coulomb's law "
          "itself, or a Tresca step through its Tresca fixed point held to one step; under "
          "the system Python", 100_000),
    _spec("siconos_newton", "nsn_ac",
          "Siconos's nonsmooth Newton method on Alart and Curnier's function (line search) "
          "on the local (Delassus) form, Coulomb steps; under the system Python", 1_000),
)
