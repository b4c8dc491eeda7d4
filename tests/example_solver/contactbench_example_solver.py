"""An external solver for contactbench: projected Barzilai-Borwein gradient on the dual.

The template of the README's "Bring your own solver": one function with the suite's
signature, the options it declares, its status mapping, and a ``SolverSpec`` that the
package registers under the entry-point group ``contactbench.solvers``::

    [project.entry-points."contactbench.solvers"]
    dual_bb = "contactbench_example_solver:SOLVER"

The method: with ``A`` factorised once (SciPy's SuperLU), the dual of
``min 1/2 u'Au - f'u  s.t.  Bu <= g`` is the bound-constrained
``min_{p >= 0} 1/2 p'Sp - p'(B A^{-1} f - g)``, ``S = B A^{-1} B'``; projected gradient
steps with Barzilai-Borwein lengths (one solve with ``A`` per step), ``u = A^{-1}(f - B'p)``.
It stops on the suite's own measures (the scaled KKT residuals of :mod:`problems.kkt` and
the certified energy bound of :func:`solvers.certificate.certify`), so that its claimed
``converged`` is what the verification confirms.
Fine for small problems, slow for large ones: an example, not a contender.
"""
from __future__ import annotations

import time

import numpy as np
import scipy.sparse.linalg as spla

from problems.kkt import kkt_residuals
from problems.spec import Parameter
from solvers.base import Role, SolveResult, SolverSpec
from solvers.certificate import certify


def solve(qp, tol, max_iter, time_limit, u0, p0, opts) -> SolveResult:
    """The suite calls this with the problem, the target ``tol`` of its verification,
    the limits, an optional initial guess and the resolved options (``opts``)."""
    t0 = time.perf_counter()
    lu = spla.splu(qp.A.tocsc())
    setup = time.perf_counter() - t0
    B, Bt = qp.B.tocsr(), qp.B.T.tocsr()
    p = np.zeros(qp.m) if p0 is None else np.maximum(np.asarray(p0, dtype=float), 0.0)

    def primal(p):
        return lu.solve(qp.f - Bt @ p)

    def gradient(u):                       # of the dual objective: g - B u
        return qp.g - B @ u

    u = primal(p)
    grad = gradient(u)
    step = 1.0 / max(float(np.abs(B.multiply(B).sum(axis=1)).max()), 1e-300) * float(
        np.mean(qp.A.diagonal()))
    status, message, k = "max_iter", f"not converged in {max_iter} steps", 0
    t1 = time.perf_counter()
    for k in range(1, max_iter + 1):
        p_new = np.maximum(p - step * grad, 0.0)
        u_new = primal(p_new)
        grad_new = gradient(u_new)
        s, y = p_new - p, grad_new - grad
        sy = float(s @ y)
        step = float(s @ s) / sy if sy > 0 else step        # Barzilai-Borwein (BB1)
        p, u, grad = p_new, u_new, grad_new
        # the stop on the suite's own measures, so that a claimed convergence verifies:
        # the scaled KKT residuals (cheap: a few products), then the certified energy
        # bound (a solve with A, only once the residuals pass)
        kkt = kkt_residuals(qp, u, p).max
        if kkt <= opts.rtol * tol and certify(qp, u, p, tol).meets(tol):
            status, message = "converged", f"verified KKT {kkt:.1e} after {k} steps"
            break
        if time_limit is not None and time.perf_counter() - t0 > time_limit:
            status, message = "time_limit", f"time limit reached after {k} steps"
            break
    return SolveResult(u=u, p=p, claimed_status=status, message=f"dual_bb: {message}",
                       iterations=k, setup_time=setup, solve_time=time.perf_counter() - t1)


SOLVER = SolverSpec(
    name="dual_bb",
    summary="example external solver: projected Barzilai-Borwein on the dual (A factorised)",
    solve=solve,
    parameters=(Parameter("rtol", 0.5, "own stop: scaled KKT residuals <= rtol * tol and "
                          "the certified energy bound <= tol", low=0.0, high=1.0,
                          low_open=True),),
    presets={"low": "KKT <= 5e-4, energy bound <= 1e-3",
             "mid": "KKT <= 5e-7, energy bound <= 1e-6",
             "high": "KKT <= 5e-10, energy bound <= 1e-9"},
    default_max_iter=20_000,
    role=Role.OTHER,
)
