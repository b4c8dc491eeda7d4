"""Clarabel adapter (primal-dual interior point with homogeneous embedding; Goulart & Chen 2024).

Clarabel solves ``min 1/2 x'Px + q'x  s.t.  Ax + s = b,  s in K`` with the
Lagrangian ``Px + q + A'z = 0``, ``z in K*``. With ``P = A``, ``q = -f``,
``A = B``, ``b = g`` and ``K = NonnegativeConeT(m)`` the slack is
``s = g - Bu >= 0`` and the dual ``z >= 0`` is our ``p`` without a sign change.

Clarabel's default tolerances (``tol_gap_abs = tol_gap_rel = tol_feas = 1e-8``)
are fixed numbers that lose meaning as the mesh (and the objective) is refined;
the adapter sets all of them from the target ``tol``, keeps equilibration on and
rescales the problem (:mod:`solvers._scaling`, ``scale=true``). Clarabel's gap
and residual tests divide by ``max(1, ...)`` (``gap_rel = gap / max(1,
min(|cost_primal|, |cost_dual|))``), so they turn absolute when the objective in
the solver's units is below one; the rescaling makes the load O(1), which keeps
loaded problems in the relative regime (a zero-load, gap-driven problem can still
fall below it, and verification then shows it). The static regularisation stays
at Clarabel's default: with iterative refinement, 1e-8, 1e-11 and 1e-13 gave the
same residuals on the test problems. Clarabel has no warm start: ``u0``/``p0``
are ignored.
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

#: Clarabel status name -> SolveResult status.
_STATUS = {
    "Solved": "converged",
    "AlmostSolved": "inaccurate",
    "MaxIterations": "max_iter",
    "MaxTime": "time_limit",
    "PrimalInfeasible": "failed",
    "DualInfeasible": "failed",
    "AlmostPrimalInfeasible": "failed",
    "AlmostDualInfeasible": "failed",
    "NumericalError": "failed",
    "InsufficientProgress": "failed",
    "Unsolved": "failed",
    "CallbackTerminated": "failed",
}


#: The adapter's options, declared once (defaults here).
PARAMETERS = (
    *ADAPTER_PARAMETERS,
    Parameter("equilibrate", True, "Clarabel's Ruiz equilibration"),
)


def settings_for(tol: float, opts: Options) -> dict:
    """Clarabel settings for the target ``tol`` (the preset table of the report).

    Parameters
    ----------
    tol : float
        Target for the verified scaled KKT residuals.
    opts : Options
        Resolved options (``equilibrate``: Clarabel's Ruiz equilibration).

    Returns
    -------
    dict
        Attribute values for ``clarabel.DefaultSettings``.
    """
    return {"tol_gap_abs": tol, "tol_gap_rel": tol, "tol_feas": tol,
            "equilibrate_enable": bool(opts.equilibrate), "verbose": False}


def solve(qp: ContactQP, tol: float, max_iter: int, time_limit: float | None,
          u0: np.ndarray | None, p0: np.ndarray | None, opts: Options) -> SolveResult:
    """Solve ``qp`` with Clarabel.

    Parameters
    ----------
    qp : ContactQP
        ``qp.C`` must be ``None``.
    tol, max_iter, time_limit
        As in :func:`solvers.interface.solve`.
    u0, p0
        Ignored (interior point methods are not warm-started).
    opts : Options
        ``tol_factor``, ``scale``, ``equilibrate`` (see :data:`SOLVER`).

    Returns
    -------
    SolveResult
    """
    import clarabel  # the library (this module is solvers.clarabel)

    require_plain_constraints(qp)
    t0 = time.perf_counter()
    data = scale_qp(qp, enabled=opts.scale)
    settings = clarabel.DefaultSettings()
    for key, value in settings_for(tol * opts.tol_factor, opts).items():
        setattr(settings, key, value)
    settings.max_iter = int(max_iter)
    if time_limit is not None:
        settings.time_limit = float(time_limit)
    cones = [clarabel.NonnegativeConeT(qp.m)] if qp.m else []
    solver = clarabel.DefaultSolver(upper_triangle(data.A), -data.f, data.B, data.g,
                                    cones, settings)
    setup_time = time.perf_counter() - t0

    t1 = time.perf_counter()
    sol = solver.solve()
    solve_time = time.perf_counter() - t1
    status_name = str(sol.status)
    u, p = data.unscale(np.asarray(sol.x), np.asarray(sol.z))
    message = f"clarabel: {status_name}"
    if u0 is not None or p0 is not None:
        message += "; initial guess ignored (no warm start)"
    stats = {"clarabel_r_prim": float(sol.r_prim), "clarabel_r_dual": float(sol.r_dual),
             "clarabel_solve_time": float(sol.solve_time), "scaled": bool(opts.scale)}
    return SolveResult(u=u, p=p, claimed_status=_STATUS.get(status_name, "failed"),
                       message=message, iterations=int(sol.iterations),
                       setup_time=setup_time, solve_time=solve_time, stats=stats)


def _describe(tol: float) -> str:
    return (f"tol_gap_abs=tol_gap_rel=tol_feas={tol:g}, equilibrate, default static "
            f"regularisation; scale=true, tol_factor=1")


SOLVER = SolverSpec(
    name="clarabel",
    summary="Clarabel (interior point, homogeneous embedding), general conic solver",
    solve=solve,
    parameters=PARAMETERS,
    presets={name: _describe(tol) for name, tol in TOLERANCES.items()},
    default_max_iter=200,
    role=Role.LIBRARY,
)
