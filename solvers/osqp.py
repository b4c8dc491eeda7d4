"""OSQP adapter (operator splitting / ADMM; Stellato et al., Math. Prog. Comp. 2020).

OSQP solves ``min 1/2 x'Px + q'x  s.t.  l <= Ax <= u`` with the Lagrangian
``Px + q + A'y = 0``, ``y >= 0`` where the upper bound is active. With
``P = A``, ``q = -f``, ``A = B``, ``l = -inf``, ``u = g`` its ``y`` is our ``p``
(``Bu <= g``, ``p >= 0``) without a sign change.

ADMM alone reaches the KKT conditions only to a few digits; the accuracy of the
presets comes from *solution polishing* (an exact solve on the guessed active
set with iterative refinement), which is always on unless ``polish=false``.
OSQP stops on ``||Bu - z||_inf <= eps_abs + eps_rel max(||Bu||, ||z||)``, the
analogous dual residual and (osqp >= 1.0) the duality gap; with ``scale=true``
(default) these are evaluated on the rescaled problem of
:mod:`solvers._scaling`, so the absolute part has the same meaning in every
unit system.
"""
from __future__ import annotations

import time

import numpy as np

from problems.spec import Parameter
from solvers._scaling import (ADAPTER_PARAMETERS, require_plain_constraints, scale_qp,
                              upper_triangle)
from problems.qp import ContactQP
from problems.spec import Options, resolve_parameters
from solvers.base import TOLERANCES, Role, SolveResult, SolverSpec

#: OSQP status strings -> SolveResult status (``solved inaccurate`` is resolved
#: by :func:`_map_status`).
_STATUS = {
    "solved": "converged",
    "maximum iterations reached": "max_iter",
    "run time limit reached": "time_limit",
    "primal infeasible": "failed",
    "primal infeasible inaccurate": "failed",
    "dual infeasible": "failed",
    "dual infeasible inaccurate": "failed",
    "problem non convex": "failed",
    "interrupted": "failed",
    "unsolved": "failed",
}

#: ``info.status_polish`` meaning in osqp 1.x.
_POLISH = {1: "polish succeeded", 0: "polish not performed", -1: "polish failed",
           2: "polish not needed (no active constraint)"}


#: The adapter's options, declared once (defaults here).
PARAMETERS = (
    *ADAPTER_PARAMETERS,
    Parameter("polish", True, "OSQP solution polishing (the source of its accuracy)"),
    Parameter("adaptive_rho", True, "OSQP adaptive ADMM step size"),
    Parameter("rho", 0.1, "initial ADMM step size", low=0.0, low_open=True),
)


def settings_for(tol: float, opts: Options) -> dict:
    """OSQP settings for the target ``tol`` (the preset table of the report).

    Parameters
    ----------
    tol : float
        Target for the verified scaled KKT residuals.
    opts : Options
        Resolved options (``polish``, ``adaptive_rho``).

    Returns
    -------
    dict
        Keyword arguments for ``osqp.OSQP.setup``.
    """
    return {"eps_abs": tol, "eps_rel": tol, "polishing": bool(opts.polish),
            "polish_refine_iter": 3 if tol >= 1e-6 else 10,
            "adaptive_rho": bool(opts.adaptive_rho), "check_dualgap": True,
            "scaled_termination": False, "verbose": False}


def solve(qp: ContactQP, tol: float, max_iter: int, time_limit: float | None,
          u0: np.ndarray | None, p0: np.ndarray | None, opts: Options) -> SolveResult:
    """Solve ``qp`` with OSQP.

    Parameters
    ----------
    qp : ContactQP
        ``qp.C`` must be ``None`` (OSQP has no stabilisation block).
    tol, max_iter, time_limit, u0, p0
        As in :func:`solvers.interface.solve`; ``(u0, p0)`` warm-start OSQP.
    opts : Options
        ``tol_factor`` (the library's tolerances are ``tol * tol_factor``),
        ``scale`` (hand OSQP the rescaled problem of :mod:`solvers._scaling`),
        ``polish``, ``adaptive_rho``, ``rho`` (see :data:`SOLVER`).

    Returns
    -------
    SolveResult
    """
    import osqp  # the library (this module is solvers.osqp)

    require_plain_constraints(qp)
    t0 = time.perf_counter()
    data = scale_qp(qp, enabled=opts.scale)
    settings = settings_for(tol * opts.tol_factor, opts)
    settings.update(max_iter=int(max_iter), rho=float(opts.rho))
    if time_limit is not None:
        settings["time_limit"] = float(time_limit)
    solver = osqp.OSQP()
    solver.setup(P=upper_triangle(data.A), q=-data.f, A=data.B,
                 l=np.full(qp.m, -np.inf), u=data.g, **settings)
    u_s0, p_s0 = data.scale_guess(u0, p0)
    if u_s0 is not None or p_s0 is not None:
        solver.warm_start(x=u_s0, y=p_s0)
    setup_time = time.perf_counter() - t0

    t1 = time.perf_counter()
    out = solver.solve(raise_error=False)
    solve_time = time.perf_counter() - t1
    info = out.info
    u, p = _unscaled(data, out.x, out.y, qp)
    status = _map_status(info.status, info.iter, max_iter, time_limit, setup_time + solve_time)
    polish_note = _POLISH.get(int(info.status_polish), f"polish status {info.status_polish}")
    stats = {"status_polish": int(info.status_polish), "rho_updates": int(info.rho_updates),
             "rho_estimate": float(info.rho_estimate), "osqp_prim_res": float(info.prim_res),
             "osqp_dual_res": float(info.dual_res), "osqp_run_time": float(info.run_time),
             "scaled": bool(opts.scale)}
    return SolveResult(u=u, p=p, claimed_status=status,
                       message=f"osqp: {info.status}; {polish_note}", iterations=int(info.iter),
                       setup_time=setup_time, solve_time=solve_time, stats=stats)


def _unscaled(data, x, y, qp: ContactQP) -> tuple[np.ndarray, np.ndarray]:
    """Unscale OSQP's ``(x, y)``; ``None`` or non-finite output becomes NaN."""
    x = np.full(qp.n, np.nan) if x is None else np.asarray(x, dtype=float)
    y = np.full(qp.m, np.nan) if y is None else np.asarray(y, dtype=float)
    return data.unscale(x, y)


def _map_status(status: str, iters: int, max_iter: int, time_limit: float | None,
                elapsed: float) -> str:
    """OSQP status string -> SolveResult status.

    ``solved inaccurate`` is what OSQP says when it stops on max_iter or the time
    limit with a solution meeting its relaxed tolerances: it becomes the limit
    that was hit, else ``inaccurate``.
    """
    if status == "solved inaccurate":
        if iters >= max_iter:
            return "max_iter"
        if time_limit is not None and elapsed >= time_limit:
            return "time_limit"
        return "inaccurate"
    return _STATUS.get(status, "failed")


def _describe(tol: float) -> str:
    s = settings_for(tol, resolve_parameters(PARAMETERS, {}, "osqp"))
    return (f"eps_abs=eps_rel={s['eps_abs']:g}, polishing (refine_iter="
            f"{s['polish_refine_iter']}), adaptive_rho, check_dualgap; scale=true, tol_factor=1")


SOLVER = SolverSpec(
    name="osqp",
    summary="OSQP 1.x (ADMM + solution polishing), general convex QP solver",
    solve=solve,
    parameters=PARAMETERS,
    presets={name: _describe(tol) for name, tol in TOLERANCES.items()},
    default_max_iter=100_000,
    role=Role.LIBRARY,
)
