"""PIQP adapter (proximal interior point; Schwan, Jiang, Kuhn & Jones, CDC 2023).

PIQP solves ``min 1/2 x'Px + c'x  s.t.  Ax = b,  h_l <= Gx <= h_u,  x_l <= x <= x_u``
with the Lagrangian ``Px + c + A'y + G'(z_u - z_l) + ... = 0``, ``z >= 0``. With
``P = A``, ``c = -f``, ``G = B``, ``h_l`` = minus infinity and ``h_u = g`` its
``z_u`` is our ``p`` (``Bu <= g``, ``p >= 0``) without a sign change.

Its stopping test (``include/piqp/solver.hpp``, piqp 0.6-0.7) is an OR of an
absolute and a relative test per residual, the relative one with
``res / max(1, norm)``: a nonzero ``eps_rel`` loosens the stop. The adapter
therefore sets ``eps_rel = eps_duality_gap_rel = 0`` (as qpbenchmark's presets
do, ``qpbenchmark/solver_settings.py``) and by default rescales the problem
(:mod:`solvers._scaling`) so that the absolute test is relative to an O(1) load
(unscaled, PIQP claims SOLVED with verified residuals 5-100x the tolerance on
circle-square level 2). PIQP has no time limit (``time_limit`` is checked after
the run; the isolated runs of the studies kill it) and no warm start.
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

#: ``piqp.Status`` name -> SolveResult status.
_STATUS = {
    "PIQP_SOLVED": "converged",
    "PIQP_MAX_ITER_REACHED": "max_iter",
    "PIQP_PRIMAL_INFEASIBLE": "failed",
    "PIQP_DUAL_INFEASIBLE": "failed",
    "PIQP_NUMERICS": "failed",
    "PIQP_UNSOLVED": "failed",
    "PIQP_INVALID_SETTINGS": "failed",
}

#: The adapter's options, declared once (defaults here).
PARAMETERS = (
    *ADAPTER_PARAMETERS,
    Parameter("check_duality_gap", True, "also stop on the duality gap"),
    Parameter("kkt_solver", "sparse_ldlt", "PIQP sparse KKT backend",
              choices=("sparse_ldlt", "sparse_ldlt_ineq_cond", "sparse_ldlt_eq_cond",
                       "sparse_ldlt_cond")),
)


def settings_for(tol: float, opts: Options) -> dict:
    """PIQP settings for the target ``tol`` (the preset table of the report)."""
    return {"eps_abs": tol, "eps_rel": 0.0, "check_duality_gap": bool(opts.check_duality_gap),
            "eps_duality_gap_abs": tol, "eps_duality_gap_rel": 0.0, "verbose": False,
            "compute_timings": True}


def solve(qp: ContactQP, tol: float, max_iter: int, time_limit: float | None,
          u0: np.ndarray | None, p0: np.ndarray | None, opts: Options) -> SolveResult:
    """Solve ``qp`` with PIQP (sparse API); see the module docstring.

    ``u0``/``p0`` are ignored (no warm start); ``time_limit`` is checked after the run.
    """
    import piqp  # the library (this module is solvers.piqp)

    require_plain_constraints(qp)
    t0 = time.perf_counter()
    data = scale_qp(qp, enabled=opts.scale)
    solver = piqp.SparseSolver()
    for key, value in settings_for(tol * opts.tol_factor, opts).items():
        setattr(solver.settings, key, value)
    solver.settings.max_iter = int(max_iter)
    solver.settings.kkt_solver = getattr(piqp.KKTSolver, opts.kkt_solver)
    solver.setup(upper_triangle(data.A), -data.f, None, None, sp.csc_matrix(data.B), None,
                 data.g, None, None)
    setup_time = time.perf_counter() - t0
    t1 = time.perf_counter()
    name = solver.solve().name
    solve_time = time.perf_counter() - t1
    res, info = solver.result, solver.result.info
    status, message = _STATUS.get(name, "failed"), f"piqp: {name}"
    if time_limit is not None and setup_time + solve_time > time_limit:
        status = "time_limit"
        message += (f"; run took {setup_time + solve_time:.3g} s > time_limit {time_limit:g} s "
                    "(PIQP cannot be interrupted)")
    if u0 is not None or p0 is not None:
        message += "; initial guess ignored (no warm start)"
    u, p = data.unscale(np.asarray(res.x, dtype=float),
                        np.asarray(res.z_u, dtype=float) if qp.m else np.zeros(0))
    stats = {"piqp_primal_res": float(info.primal_res), "piqp_dual_res": float(info.dual_res),
             "piqp_duality_gap": float(info.duality_gap), "factor_retires": int(info.factor_retires),
             "scaled": bool(opts.scale)}
    return SolveResult(u=u, p=p, claimed_status=status, message=message,
                       iterations=int(info.iter), setup_time=setup_time, solve_time=solve_time,
                       stats=stats)


def _describe(tol: float) -> str:
    s = settings_for(tol, resolve_parameters(PARAMETERS, {}, "piqp"))
    return (f"eps_abs={s['eps_abs']:g}, eps_rel=0, check_duality_gap with "
            f"eps_duality_gap_abs={tol:g}, eps_duality_gap_rel=0, KKTSolver.sparse_ldlt; "
            "scale=true, tol_factor=1 (qpbenchmark's mapping)")


SOLVER = SolverSpec(
    name="piqp",
    summary="PIQP 0.7 (proximal interior point), sparse LDL' backend",
    solve=solve,
    parameters=PARAMETERS,
    presets={name: _describe(tol) for name, tol in TOLERANCES.items()},
    default_max_iter=250,
    role=Role.LIBRARY,
)
