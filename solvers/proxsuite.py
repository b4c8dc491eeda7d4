"""ProxSuite adapter (ProxQP: proximal augmented Lagrangian; Bambade et al., RSS 2022).

ProxQP solves ``min 1/2 x'Hx + g'x  s.t.  Ax = b,  l <= Cx <= u`` with the
Lagrangian ``Hx + g + A'y + C'z = 0``, ``z >= 0`` where the upper bound is
active. With ``H = A``, ``g = -f``, ``C = B``, ``l = -inf``, ``u = g`` its ``z``
is our ``p`` (``Bu <= g``, ``p >= 0``) without a sign change.

Pitfalls handled here (measured on contact QPs of this kind):

* ProxQP's default stopping test checks only the primal and dual residuals, not
  complementarity: at ``eps_abs = 1e-8`` in physical units it reports
  ``PROXQP_SOLVED`` with a 5e-2 error. The adapter turns on
  ``check_duality_gap`` (with ``eps_duality_gap_abs = eps_duality_gap_rel =
  tol``) and by default rescales the problem (:mod:`solvers._scaling`).
* With ``SparseBackend.Automatic`` ProxQP switches to a matrix-free backend on
  large problems (~27x slower at ~130k DOFs); the adapter forces the sparse
  Cholesky backend (``proxsuite.proxqp.sparse`` + ``SparseBackend.SparseCholesky``).
* At loose tolerances ProxQP can stop with multipliers of the wrong sign on
  inactive rows (``min z = -0.66 max z`` at ``eps = 1e-3`` on circle_square
  level 1; a finite lower bound ``l`` instead of ``-inf`` changes nothing): its
  tests do not check ``z >= 0``. The adapter returns ``z`` as it is, so the
  verified dual residual shows it.
* ProxQP has no time limit: the adapter cannot interrupt it and reports
  ``time_limit`` when the finished run took longer than allowed.
"""
from __future__ import annotations

import time

import numpy as np

from problems.spec import Parameter
from solvers._scaling import ADAPTER_PARAMETERS, require_plain_constraints, scale_qp
from problems.qp import ContactQP
from problems.spec import Options, resolve_parameters
from solvers.base import TOLERANCES, Role, SolveResult, SolverSpec

#: ProxQP status name -> SolveResult status.
_STATUS = {
    "PROXQP_SOLVED": "converged",
    "PROXQP_MAX_ITER_REACHED": "max_iter",
    "PROXQP_PRIMAL_INFEASIBLE": "failed",
    "PROXQP_DUAL_INFEASIBLE": "failed",
    "PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE": "failed",
    "PROXQP_NOT_RUN": "failed",
}


#: The adapter's options, declared once (defaults here).
PARAMETERS = (
    *ADAPTER_PARAMETERS,
    Parameter("check_duality_gap", True, "also stop on the duality gap (ProxQP's default "
              "is off, which stops with complementarity unresolved)"),
    Parameter("backend", "sparse_cholesky", "ProxQP sparse backend (automatic may switch "
              "to the ~27x slower matrix-free mode)",
              choices=("sparse_cholesky", "automatic", "matrix_free")),
)


def settings_for(tol: float, opts: Options) -> dict:
    """ProxQP settings for the target ``tol`` (the preset table of the report).

    Parameters
    ----------
    tol : float
        Target for the verified scaled KKT residuals.
    opts : Options
        Resolved options (``check_duality_gap``: also stop on the duality gap;
        ProxQP's default is off).

    Returns
    -------
    dict
        Attribute values for ``qp.settings``.
    """
    return {"eps_abs": tol, "eps_rel": tol, "check_duality_gap": bool(opts.check_duality_gap),
            "eps_duality_gap_abs": tol, "eps_duality_gap_rel": tol,
            "verbose": False, "compute_timings": True}


def solve(qp: ContactQP, tol: float, max_iter: int, time_limit: float | None,
          u0: np.ndarray | None, p0: np.ndarray | None, opts: Options) -> SolveResult:
    """Solve ``qp`` with ProxQP (sparse API).

    Parameters
    ----------
    qp : ContactQP
        ``qp.C`` must be ``None``.
    tol, max_iter, time_limit, u0, p0
        As in :func:`solvers.interface.solve`; ``(u0, p0)`` warm-start ProxQP.
        ``time_limit`` is checked after the run (ProxQP cannot be interrupted).
    opts : Options
        ``tol_factor``, ``scale``, ``check_duality_gap``, ``backend`` (see :data:`SOLVER`).

    Returns
    -------
    SolveResult
    """
    from proxsuite import proxqp  # the library (this module is solvers.proxsuite)

    require_plain_constraints(qp)
    t0 = time.perf_counter()
    data = scale_qp(qp, enabled=opts.scale)
    solver = proxqp.sparse.QP(qp.n, 0, qp.m)
    for key, value in settings_for(tol * opts.tol_factor, opts).items():
        setattr(solver.settings, key, value)
    solver.settings.max_iter = int(max_iter)
    solver.settings.sparse_backend = _backend(proxqp, opts.backend)
    u_s0, p_s0 = data.scale_guess(u0, p0)
    if u_s0 is not None or p_s0 is not None:
        solver.settings.initial_guess = proxqp.InitialGuess.WARM_START
    solver.init(H=data.A, g=-data.f, A=None, b=None, C=data.B,
                l=np.full(qp.m, -np.inf), u=data.g)
    setup_time = time.perf_counter() - t0

    t1 = time.perf_counter()
    if u_s0 is not None or p_s0 is not None:
        solver.solve(np.zeros(qp.n) if u_s0 is None else u_s0, np.zeros(0),
                     np.zeros(qp.m) if p_s0 is None else p_s0)
    else:
        solver.solve()
    solve_time = time.perf_counter() - t1
    res = solver.results
    info = res.info
    u, p = data.unscale(res.x, res.z)
    status_name = str(info.status).rsplit(".", 1)[-1]
    status = _STATUS.get(status_name, "failed")
    message = f"proxsuite: {status_name}"
    if time_limit is not None and setup_time + solve_time > time_limit:
        status = "time_limit"
        message += (f"; run took {setup_time + solve_time:.3g} s > time_limit "
                    f"{time_limit:g} s (ProxQP cannot be interrupted)")
    stats = {"backend": str(info.sparse_backend).rsplit(".", 1)[-1],
             "proxqp_pri_res": float(info.pri_res), "proxqp_dua_res": float(info.dua_res),
             "proxqp_duality_gap": float(info.duality_gap), "mu_updates": int(info.mu_updates),
             "rho_updates": int(info.rho_updates), "iter_ext": int(info.iter_ext),
             "proxqp_setup_time": float(info.setup_time) * 1e-6,
             "proxqp_solve_time": float(info.solve_time) * 1e-6, "scaled": bool(opts.scale)}
    return SolveResult(u=u, p=p, claimed_status=status, message=message,
                       iterations=int(info.iter), setup_time=setup_time,
                       solve_time=solve_time, stats=stats)


def _backend(proxqp, name: str):
    """``SparseBackend`` member for an option value."""
    return {"sparse_cholesky": proxqp.SparseBackend.SparseCholesky,
            "automatic": proxqp.SparseBackend.Automatic,
            "matrix_free": proxqp.SparseBackend.MatrixFree}[name]


def _describe(tol: float) -> str:
    return (f"eps_abs=eps_rel={tol:g}, check_duality_gap with eps_duality_gap_abs=_rel="
            f"{tol:g}, SparseBackend.SparseCholesky; scale=true, tol_factor=1")


SOLVER = SolverSpec(
    name="proxsuite",
    summary="ProxSuite ProxQP (proximal augmented Lagrangian), sparse Cholesky backend",
    solve=solve,
    parameters=PARAMETERS,
    presets={name: _describe(tol) for name, tol in TOLERANCES.items()},
    default_max_iter=10_000,
    role=Role.LIBRARY,
)
