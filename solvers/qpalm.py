"""QPALM adapter (proximal augmented Lagrangian with semismooth Newton inner solves;
Hermans, Themelis & Patrinos, Math. Prog. Comp. 2022).

QPALM solves ``min 1/2 x'Qx + q'x  s.t.  bmin <= Ax <= bmax`` with the Lagrangian
``Qx + q + A'y = 0``, ``y >= 0`` at the upper bound. With ``Q = A``, ``q = -f``,
``A = B``, ``bmin`` = minus infinity and ``bmax = g`` its ``y`` is our ``p``
without a sign change.

Its stopping test (``QPALM/src/termination.c``) is OSQP-like on the unscaled
primal and dual residuals (``eps_abs + eps_rel max(...)``) and has no
duality-gap or complementarity test: complementarity holds only up to the primal
residual, which the verification shows. The presets map ``eps_abs = eps_rel =
tol`` (qpbenchmark sets ``eps_rel = 0``; measured here, both pass verification,
and ``eps_rel = tol`` is OSQP's convention in this suite); the problem is
rescaled (:mod:`solvers._scaling`). QPALM checks ``time_limit`` between
iterations (its first factorisation can overshoot it); it warm-starts from
``(u0, p0)``. ``solve`` runs synchronously (its default starts a thread) and
quietly (its default prints).
"""
from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp

from problems.qp import ContactQP
from problems.spec import Options, Parameter, resolve_parameters
from solvers._scaling import (ADAPTER_PARAMETERS, require_plain_constraints, scale_qp,
                              upper_triangle)
from solvers.base import TOLERANCES, Role, SolveResult, SolverSpec

#: QPALM ``info.status`` -> SolveResult status.
_STATUS = {
    "solved": "converged",
    "maximum iterations reached": "max_iter",
    "time limit exceeded": "time_limit",
    "primal infeasible": "failed",
    "dual infeasible": "failed",
    "dual terminated": "failed",
    "cancelled by user": "failed",
    "unsolved": "failed",
    "error": "failed",
}

#: The adapter's options, declared once (defaults here).
PARAMETERS = (
    *ADAPTER_PARAMETERS,
    Parameter("scaling", 10, "QPALM's Ruiz equilibration iterations", low=0, high=100,
              kind=int),
)


def settings_for(tol: float, opts: Options) -> dict:
    """QPALM settings for the target ``tol`` (the preset table of the report)."""
    return {"eps_abs": tol, "eps_rel": tol, "scaling": int(opts.scaling), "verbose": 0}


def solve(qp: ContactQP, tol: float, max_iter: int, time_limit: float | None,
          u0: np.ndarray | None, p0: np.ndarray | None, opts: Options) -> SolveResult:
    """Solve ``qp`` with QPALM; see the module docstring."""
    import qpalm  # the library (this module is solvers.qpalm)

    require_plain_constraints(qp)
    t0 = time.perf_counter()
    data = scale_qp(qp, enabled=opts.scale)
    problem = qpalm.Data(qp.n, qp.m)
    problem.Q = upper_triangle(data.A)
    problem.q = -data.f
    problem.A = sp.csc_matrix(data.B)
    problem.bmin = np.full(qp.m, -np.inf)
    problem.bmax = data.g
    settings = qpalm.Settings()
    for key, value in settings_for(tol * opts.tol_factor, opts).items():
        setattr(settings, key, value)
    settings.max_iter = int(max_iter)
    if time_limit is not None:
        settings.time_limit = float(time_limit)
    solver = qpalm.Solver(problem, settings)
    u_s0, p_s0 = data.scale_guess(u0, p0)
    if u_s0 is not None or p_s0 is not None:
        solver.warm_start(u_s0, p_s0)
    setup_time = time.perf_counter() - t0
    t1 = time.perf_counter()
    solver.solve(asynchronous=False)
    solve_time = time.perf_counter() - t1
    info = solver.info
    u, p = data.unscale(np.asarray(solver.solution.x, dtype=float),
                        np.asarray(solver.solution.y, dtype=float))
    stats = {"qpalm_pri_res": float(info.pri_res_norm), "qpalm_dua_res": float(info.dua_res_norm),
             "iter_out": int(info.iter_out), "scaled": bool(opts.scale)}
    return SolveResult(u=u, p=p, claimed_status=_STATUS.get(info.status, "failed"),
                       message=f"qpalm: {info.status}", iterations=int(info.iter),
                       setup_time=setup_time, solve_time=solve_time, stats=stats)


def _describe(tol: float) -> str:
    s = settings_for(tol, resolve_parameters(PARAMETERS, {}, "qpalm"))
    return (f"eps_abs=eps_rel={s['eps_abs']:g} (no duality-gap test in QPALM), scaling=10, "
            "time_limit; scale=true, tol_factor=1")


SOLVER = SolverSpec(
    name="qpalm",
    summary="QPALM 1.3 (proximal augmented Lagrangian, semismooth Newton inner solves)",
    solve=solve,
    parameters=PARAMETERS,
    presets={name: _describe(tol) for name, tol in TOLERANCES.items()},
    default_max_iter=10_000,
    role=Role.LIBRARY,
)
