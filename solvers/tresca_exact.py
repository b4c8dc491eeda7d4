"""The exact reference of one Tresca step, registered as a solver (``tresca_exact``).

One Tresca step (:class:`problems.friction.data.Friction`, its ``slip_bound`` given) is solved by
:func:`solvers.kernels.tresca.tresca_exact`: the dual problem in ``y = (p, lam)``
(``p >= 0``, ``|lam_i| <= s_i``) with the dense Hessian ``S = G A^-1 G'``, ``G = [B; T]``,
``u = A^-1 (f - G'y)``. 2D: a box, by a primal active-set method that ends on the exact
active sets; 3D (two tangential rows per node): a disc per node, by a semismooth Newton
method on the projection equation driven to round-off on fixed sets; the faceted law
(``friction_facets`` = k: a regular k-gon per node) by the same method with the
projection onto the k-gons, exact on its final sets.
The answer carries the tangential multipliers in ``SolveResult.tangential``. A load path
(normal load, then the tangential step; Coulomb's fixed point ``s = mu p``) is run around
this solver by :func:`solvers.kernels.tresca.run_load_path` (``contactbench solve`` on a
frictional scene).

Refused at once (``skipped``): a frictionless problem (its exact reference is ``pdas``;
the dense dual would only add a slower second route to every frictionless study), more than
:data:`solvers.kernels.tresca.TRESCA_EXACT_MAX_M` rows or a dense ``A^-1 G'`` beyond
:data:`solvers.kernels.tresca.TRESCA_EXACT_MAX_ENTRIES`, friction on anything but nodal rows
(``dim - 1`` tangential rows per constrained node), and a floating body (``A`` is then nearly singular and a plain
factorisation of it useless).
"""
from __future__ import annotations

import time

import numpy as np

from problems.floating import floating_modes
from problems.qp import ContactQP
from problems.spec import Options
from solvers.base import Role, SolveResult, SolverSpec, guess_not_used, preset_texts
from solvers.kernels.tresca import (TRESCA_EXACT_MAX_ENTRIES, TRESCA_EXACT_MAX_M, dense_dual_size,
                                    dual_operators, tresca_exact)


def supports(qp: ContactQP) -> tuple[bool, str]:
    """``(True, "")`` if :func:`solve` takes ``qp``, else ``(False, reason)``."""
    if qp.friction is None:
        return False, ("a frictionless problem: this is the reference of a Tresca step; "
                       "the frictionless problem's exact reference is pdas")
    if qp.m > TRESCA_EXACT_MAX_M:
        return False, (f"{qp.m} constraint rows: the dual Hessian is dense, at most "
                       f"{TRESCA_EXACT_MAX_M} rows")
    if qp.C is not None:
        return False, "a stabilisation block C: the dual box problem has no C"
    fr = qp.friction
    if qp.stabilisation is not None or fr.T.shape[0] != qp.m * (qp.dim - 1):
        return False, ("friction on nodal rows only (dim - 1 tangential rows per "
                       "constrained node)")
    if dense_dual_size(qp) > TRESCA_EXACT_MAX_ENTRIES:
        return False, (f"A^-1 G' is dense: {dense_dual_size(qp):.1e} entries, at most "
                       f"{TRESCA_EXACT_MAX_ENTRIES:.0e}")
    if floating_modes(qp).shape[1]:
        return False, "a floating body: A is nearly singular, its plain factorisation useless"
    return True, ""


def solve(qp: ContactQP, tol: float, max_iter: int, time_limit: float | None,
          u0: np.ndarray | None, p0: np.ndarray | None, opts: Options) -> SolveResult:
    """One Tresca step solved exactly
    (:func:`solvers.kernels.tresca.tresca_exact`).

    ``tol`` is left to the verification: the method is exact on its final active sets
    (2D) or driven to round-off on them (3D). ``max_iter`` caps the active-set or Newton
    steps (``max_iter`` claimed when it is reached); ``time_limit``, ``u0`` and ``p0``
    are not used (the method starts from ``p = lam = 0``; a guess given is noted in the
    message, :func:`solvers.base.guess_not_used`).

    Returns
    -------
    SolveResult
        ``tangential`` is ``lam`` on a frictional problem (``None`` otherwise); ``stats``
        hold the number of dual unknowns, the sticking and slipping rows.
    """
    t0 = time.perf_counter()
    ops = dual_operators(qp)
    t1 = time.perf_counter()
    try:
        sol = tresca_exact(qp, ops, max_iter=max_iter)
    except np.linalg.LinAlgError as err:          # S singular on a face: no answer
        nan = lambda k: np.full(k, np.nan)
        return SolveResult(u=nan(qp.n), p=nan(qp.m), claimed_status="failed",
                           message=f"the dual Hessian is singular on the free set (linearly "
                                   f"dependent rows, or no feasible point): {err}",
                           setup_time=t1 - t0, solve_time=time.perf_counter() - t1,
                           tangential=None if qp.friction is None
                           else nan(qp.friction.T.shape[0]))
    t2 = time.perf_counter()
    stats = {"dual_unknowns": int(ops.S.shape[0])}
    if qp.friction is not None:
        bounded = qp.friction.slip_bound > 0
        stats.update(n_stick=int(sol.stick.sum()), n_slip=int((bounded & ~sol.stick).sum()))
    discs = qp.friction is not None and qp.friction.components > 1
    method = "semismooth Newton method" if discs else "active-set method"
    message = (("sets fixed, projection residual at round-off" if discs else
                "active sets exact")
               if sol.status == "converged" else
               f"{method} stopped after {sol.iterations} steps")
    if u0 is not None or p0 is not None:
        message = guess_not_used(message, "the method (it starts from p = lam = 0)")
    return SolveResult(u=sol.u, p=sol.p, claimed_status=sol.status, message=message,
                       iterations=int(sol.iterations), setup_time=t1 - t0, solve_time=t2 - t1,
                       stats=stats, tangential=sol.lam if qp.friction is not None else None)


SOLVER = SolverSpec(
    name="tresca_exact",
    summary="exact reference of one Tresca step: the dual problem in (p, lam) with A "
            "factorised once and S = G A^-1 G' dense; 2D (a box) by a primal active-set "
            "method, 3D (a disc per node) by semismooth Newton on the projection equation, "
            "to round-off (frictional problems only)",
    solve=solve,
    presets=preset_texts("exact active sets; verified at"),
    default_max_iter=100_000,
    role=Role.EXACT,
    supports=supports,
    handles_friction=True,
)
