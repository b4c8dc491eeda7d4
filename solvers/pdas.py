"""Primal-dual active set method: the exact reference solver.

The semismooth Newton method of Hintermüller, Ito and Kunisch (SIAM J. Optim.
13, 2003) for ``min 1/2 u'Au - f'u  s.t.  Bu - Cp <= g`` (``C`` = 0 unless the
ContactQP carries the stabilisation block of Sect. 7.5). Each step solves the
equality-constrained problem of the current active set ``I`` exactly,

    [ A     B_I^T ] [ u   ]   [ f   ]
    [ B_I  -C_II  ] [ p_I ] = [ g_I ],      p_i = 0 for i not in I,

either by a sparse LU of the reduced KKT matrix per step (``method="kkt"``,
``scipy.sparse.linalg.splu``) or through the dual problem (7.3) on the contact
rows (``method="schur"``, the default up to 5000 constraints): ``A`` factorised
once by a sparse Cholesky (:mod:`solvers.kernels.cholesky`: MKL PARDISO with METIS,
partial solves on the support of ``B``), the dense ``S = B A^{-1} B^T`` formed
once (``N^C`` columns), each step a dense Cholesky of ``S_II`` and one solve
with ``A`` for ``u``; iterative refinement after every solve with ``A``. On the
large scenes the ``schur`` route is far faster than the ``kkt`` route
(docs/guide/measurements.md); ``kkt`` stays as the cross-check (tests compare them). The
active set is then updated
by the PDAS rule ``I = {i : p_i + c (Bu - Cp - g)_i > 0}``. After the first
step ``p_i = 0`` off ``I`` and ``(Bu - Cp - g)_i = 0`` on ``I``, so the rule
keeps ``i`` in ``I`` while ``p_i >= 0`` and adds ``i`` when it is violated; ``c``
only matters for an initial guess ``(u0, p0)``. Changes at round-off level
(relative ``flip_tol``) are ignored so that a degenerate (weakly active)
constraint cannot make the iteration flip forever.

Linearly dependent active rows (LICQ fails: two constrained nodes with the same
constraint row, corners, symmetry planes, mortar rows sharing nodes): ``u`` is still
unique, the multipliers are not. A step whose ``S_II`` (or KKT matrix) is singular
takes a basis ``J`` of the active rows from a rank-revealing pivoted Cholesky of the
scaled ``S_II`` (:func:`solvers.kernels.cholesky.row_basis`), solves on ``J`` and sets
``p = 0`` on the dependent rows ``D``, which stay in the active set. The basis is
consistent with the gaps (``B_D u <= g_D`` on the face of ``J``; a violated dependent
row is exchanged into ``J``), and rows that no ``u`` satisfies end the run as
``failed`` with a Farkas certificate ("the problem is infeasible"). The multiplier
returned is therefore the *basic* one of the final step: supported on the rows that
the pivoted Cholesky (largest remaining diagonal first, ties to the lower row number)
and the exchanges pick, zero on the others; the KKT residuals and the certificate
judge it as any other. A problem with independent active rows takes exactly the path
it took before (the plain Cholesky of ``S_II`` is tried first).

Stopping: the active set repeats (then ``(u, p)`` solves the KKT system up to
round-off). Safeguard: PDAS converges for M-matrix-like problems but may cycle
otherwise; when an active set recurs, the method switches to a damped update
that applies only the ``k`` largest violations (``k`` halved at each further
cycle, down to one). Cycling at ``k = 1``, a singular active-set system or
``max_iter`` end the run with the honest status.
"""
from __future__ import annotations

import time

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from problems.floating import floating_modes
from problems.kkt import kkt_residuals
from problems.qp import ContactQP
from problems.spec import Options, Parameter
from solvers.kernels.cholesky import (InfeasibleError, dense_schur, factorize, row_basis,
                                      shared_floating_factor)
from solvers.kernels.active_set import (check_positive_diagonal, damped_update, initial_active_set,
                                        pdas_update, stiffness_scale)
from solvers.base import Role, SolveResult, SolverSpec


#: Largest number of constraints for ``method="schur"`` (dense m x m complement,
#: one solve with A per constraint).
SCHUR_MAX_M = 5000


def solve(qp: ContactQP, tol: float, max_iter: int, time_limit: float | None,
          u0: np.ndarray | None, p0: np.ndarray | None, opts: Options) -> SolveResult:
    """Solve ``qp`` by the primal-dual active set method.

    Parameters
    ----------
    qp : ContactQP
    tol : float
        Target for the scaled KKT residuals; the method itself is exact and
        stops when the active set repeats.
    max_iter : int
        Maximum number of active-set solves.
    time_limit : float, optional
        Wall seconds, checked after every step.
    u0, p0 : arrays, optional
        Initial guess; without one the first step solves the unconstrained
        problem (empty active set).
    opts : Options
        ``c`` (PDAS parameter, relative to the stiffness scale
        ``mean(diag A) / mean(||B_i||^2)``), ``method`` (linear algebra of a
        step, see the module docstring), ``refine`` (iterative refinement
        steps after each direct solve), ``flip_tol`` (relative size below which
        a sign change does not change the active set); see :data:`SOLVER`.

    Returns
    -------
    SolveResult
        ``claimed_status`` is ``converged`` (active set fixed, KKT max <= tol),
        ``inaccurate`` (active set fixed, residual above tol), ``max_iter``,
        ``time_limit`` or ``failed`` (cycling, singular system).
    """
    t_start = time.perf_counter()
    check_positive_diagonal(qp.A)
    c_eff = opts.c * stiffness_scale(qp)
    method = opts.method if opts.method != "auto" else (
        "schur" if qp.m <= SCHUR_MAX_M else "kkt")
    system = _ActiveSetSystem(qp, method, opts.refine, opts.factorization)
    setup_time = time.perf_counter() - t_start

    t_solve = time.perf_counter()
    active = initial_active_set(qp, u0, p0, c_eff)
    history = {"n_active": [], "n_added": [], "n_removed": [], "kkt_max": [], "time": []}
    seen: set[bytes] = {active.tobytes()}
    limit: int | None = None  # None: full PDAS update; k: damped, at most k changes
    u, p = np.zeros(qp.n), np.zeros(qp.m)
    n_active = 0  # size of the active set behind the current (u, p)
    best = (np.inf, u, p, 0)  # (kkt max, u, p, n_active) of the best step so far
    status, message = "max_iter", f"no fixed active set after {max_iter} steps"
    iterations = 0
    for iterations in range(1, max_iter + 1):
        try:
            u, p = system.solve(active)
            n_active = int(active.sum())
        except InfeasibleError as err:
            status, message = "failed", f"step {iterations}: {err}"
            break
        except RuntimeError as err:
            status = "failed"
            message = (f"singular active-set system at step {iterations} with "
                       f"{int(active.sum())} active constraints (linearly dependent rows "
                       f"of B, or an infeasible problem?): {err}")
            break
        res = kkt_residuals(qp, u, p)
        if res.max < best[0]:
            best = (res.max, u, p, n_active)
        proposed = pdas_update(qp, active, u, p, opts.flip_tol)
        new = proposed if limit is None else damped_update(qp, active, proposed, u, p, limit)
        _record(history, active, new, res.max, time.perf_counter() - t_solve)
        if np.array_equal(new, active):
            status, message = _fixed_point_status(res.max, tol, iterations)
            if system.n_dependent:
                message += (f"; {system.n_dependent} linearly dependent active row(s) carry "
                            f"p = 0 (basic multiplier)")
            break
        key = new.tobytes()
        if key in seen:
            n_changes = int(np.count_nonzero(proposed != active))
            if limit == 1:
                _, u, p, n_active = best
                status, message = _cycling_status(best[0], tol, iterations)
                break
            limit = max(1, n_changes // 2) if limit is None else max(1, limit // 2)
            seen = set()
            new = damped_update(qp, active, proposed, u, p, limit)
        seen.add(new.tobytes())
        active = new
        if time_limit is not None and time.perf_counter() - t_start > time_limit:
            status, message = "time_limit", f"time limit {time_limit:g} s reached at step {iterations}"
            break

    stats = {"n_active": n_active, "factor_time": system.factor_time,
             "n_factorisations": system.n_factorisations, "method": method,
             "factorization": getattr(system, "chol", None) and system.chol.backend, "c_eff": c_eff,
             "n_dependent": system.n_dependent,
             "damped": limit is not None, "damping_limit": -1 if limit is None else limit}
    return SolveResult(u=u, p=p, claimed_status=status, message=message,
                       iterations=iterations, setup_time=setup_time,
                       solve_time=time.perf_counter() - t_solve, history=history, stats=stats)


def _fixed_point_status(kkt_max: float, tol: float, step: int) -> tuple[str, str]:
    """Status once the active set repeats."""
    if kkt_max <= tol:
        return "converged", f"active set fixed after {step} steps, KKT max {kkt_max:.2e}"
    return "inaccurate", (f"active set fixed after {step} steps but KKT max {kkt_max:.2e} > "
                          f"tol {tol:.1e} (ill-conditioned active-set system?)")


def _cycling_status(kkt_max: float, tol: float, step: int) -> tuple[str, str]:
    """Status when the active set cycles even with single changes (best step returned)."""
    if kkt_max <= tol:
        return "converged", (f"active set cycles at round-off level (step {step}); best step "
                             f"has KKT max {kkt_max:.2e}")
    return "failed", (f"active set cycles even with single changes (step {step}); best step "
                      f"has KKT max {kkt_max:.2e}")


def _record(history: dict, active: np.ndarray, new: np.ndarray, kkt_max: float,
            elapsed: float) -> None:
    history["n_active"].append(int(active.sum()))
    history["n_added"].append(int(np.count_nonzero(new & ~active)))
    history["n_removed"].append(int(np.count_nonzero(active & ~new)))
    history["kkt_max"].append(float(kkt_max))
    history["time"].append(float(elapsed))


class _ActiveSetSystem:
    """Solves the equality-constrained problem of one active set exactly.

    Parameters
    ----------
    qp : ContactQP
    method : {"kkt", "schur"}
    refine : int
        Iterative refinement steps.
    factorization : str
        Backend of :func:`solvers.kernels.cholesky.factorize` (``method="schur"``).
    """

    def __init__(self, qp: ContactQP, method: str, refine: int, factorization: str = "auto"):
        self.qp = qp
        self.method = method
        self.refine = refine
        self.factorization = factorization
        self.factor_time = 0.0
        self.n_factorisations = 0
        self.n_dependent = 0     # dependent active rows (p = 0) of the last step
        self.A = sp.csc_matrix(qp.A)
        self.B = sp.csr_matrix(qp.B)
        self.C = None if qp.C is None else sp.csr_matrix(qp.C)
        if method == "schur":
            self._prepare_schur()

    def solve(self, active: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(u, p)`` for the active set (``p = 0`` off it).

        Raises
        ------
        InfeasibleError
            The active rows admit no ``u`` with ``B_I u <= g_I``.
        RuntimeError
            If the system is singular otherwise.
        """
        idx = np.flatnonzero(active)
        u, p_act = (self._solve_kkt(idx) if self.method == "kkt" else self._solve_schur(idx))
        p = np.zeros(self.qp.m)
        p[idx] = p_act
        if not (np.all(np.isfinite(u)) and np.all(np.isfinite(p))):
            raise RuntimeError("the factorisation produced non-finite values")
        return u, p

    # -- reduced KKT system ---------------------------------------------------
    def _kkt_matrix(self, idx: np.ndarray) -> sp.csc_matrix:
        B_I = self.B[idx]
        C_II = (sp.csr_matrix((idx.size, idx.size)) if self.C is None
                else self.C[idx][:, idx])
        return sp.csc_matrix(sp.bmat([[self.A, B_I.T], [B_I, -C_II]]))

    def _solve_kkt(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The reduced KKT system by a sparse LU; exactly singular (dependent active rows):
        on a basis of the rows chosen from their Gram matrix ``B_I B_I'``."""
        self.n_dependent = 0
        try:
            return self._solve_kkt_rows(idx)
        except RuntimeError:
            pass
        B_I = self.B[idx]
        basis = row_basis((B_I @ B_I.T).toarray(), self._gaps(idx), labels=idx)
        self.n_dependent = basis.dropped.size
        u, p_kept = self._solve_kkt_rows(idx[basis.kept])
        p_I = np.zeros(idx.size)
        p_I[basis.kept] = p_kept
        return u, p_I

    def _gaps(self, idx: np.ndarray) -> np.ndarray | None:
        """The gaps a row basis must be consistent with (none with a stabilisation block,
        whose rows ``B_I u - C_II p_I = g_I`` are not dependent like ``B_I``'s)."""
        return self.qp.g[idx] if self.C is None else None

    def _solve_kkt_rows(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = self.qp.n
        K = self._kkt_matrix(idx)
        rhs = np.concatenate([self.qp.f, self.qp.g[idx]])
        t0 = time.perf_counter()
        lu = spla.splu(K)
        self.factor_time += time.perf_counter() - t0
        self.n_factorisations += 1
        x = lu.solve(rhs)
        for _ in range(self.refine):
            x = x + lu.solve(rhs - K @ x)
        return x[:n], x[n:]

    # -- Schur complement -----------------------------------------------------
    def _prepare_schur(self) -> None:
        """Factorise ``A`` once (:func:`solvers.kernels.cholesky.factorize`) and form the dense
        ``S = B A^{-1} B^T`` by partial solves on the support of ``B``.

        With floating bodies (:func:`problems.floating.floating_modes`: a body held only by
        contact and weak springs) ``A`` is factorised without its near-kernel
        (:class:`solvers.kernels.cholesky.FloatingCholesky`) and the rigid amplitudes ``alpha``
        stay unknowns of each step, as in FETI for contact: ``S = B_r A_rr^{-1} B_r^T``
        is the complement of the held part only (see :meth:`_solve_floating`).
        """
        if self.qp.m > SCHUR_MAX_M:
            raise ValueError(f"method='schur' forms a dense {self.qp.m} x {self.qp.m} Schur "
                             f"complement (one solve with A per constraint); it is meant for "
                             f"at most {SCHUR_MAX_M} constraints: use method='kkt'")
        t0 = time.perf_counter()
        modes = floating_modes(self.qp)
        self.floating = None
        B = self.B
        if modes.shape[1]:
            fl = shared_floating_factor(self.qp, modes, self.factorization)
            self.floating, self.chol = fl, fl.chol
            self.z_f = fl.rest_solve(self.qp.f[fl.rest])      # A_rr^{-1} f_r, once
            B = self.B[:, fl.rest].tocsr()
            self.B_rest = B
            self.G = self.B @ fl.R - B @ fl.W          # G~ = B R - B_r A_rr^{-1} C  (m x k)
        else:
            self.chol = factorize(self.A, self.factorization, components=self.B.indices)
        self.S = dense_schur(self.chol, B)
        if self.floating is None:
            self.w = self._solve_A(self.qp.f)  # unconstrained solution A^{-1} f
        self.factor_time += time.perf_counter() - t0
        self.n_factorisations += 1

    def _solve_A(self, rhs: np.ndarray) -> np.ndarray:
        x = self.chol.solve(rhs)
        for _ in range(self.refine):
            x = x + self.chol.solve(rhs - self.A @ x)
        return x

    def _solve_schur(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        self.n_dependent = 0
        if self.floating is not None:
            return self._solve_floating(idx)
        if idx.size == 0:
            return self.w.copy(), np.zeros(0)
        S_II = self.S[np.ix_(idx, idx)]
        if self.C is not None:
            S_II = S_II + self.C[idx][:, idx].toarray()
        rhs = self.B[idx] @ self.w - self.qp.g[idx]
        basis = row_basis(S_II, self._gaps(idx), labels=idx)
        self.n_dependent = basis.dropped.size
        p_I = np.zeros(idx.size)
        p_I[basis.kept] = sla.cho_solve(basis.factor, rhs[basis.kept])
        u = self._solve_A(self.qp.f - self.B[idx].T @ p_I)
        return u, p_I

    def _solve_floating(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The active-set step with floating bodies, iteratively refined.

        In the basis ``u = u_r + R alpha`` (:class:`solvers.kernels.cholesky.FloatingCholesky`)
        the step ``A u + B_I^T p_I = f``, ``B_I u - C_II p_I = g_I`` becomes, after
        eliminating ``u_r``,

            Sigma~ alpha + G~_I^T p_I = f~,     G~_I alpha - (S_II + C_II) p_I = g~_I,

        (``f~ = R^T f - C^T A_rr^{-1} f_r``, ``g~ = g - B_r A_rr^{-1} f_r``): a dense
        Cholesky of ``S_II + C_II`` and a ``k x k`` system for the rigid amplitudes.
        Nothing here is of the size of ``1 / spring``: the springs enter only through
        ``Sigma~``, which is small beside ``G~^T S^{-1} G~`` (the contact's stiffness).
        Dependent rows of ``S_II`` (:func:`solvers.kernels.cholesky.row_basis`, not checked
        against the gaps: ``S_II`` couples only the held part) carry ``p = 0``.
        """
        if idx.size:
            S_II = self.S[np.ix_(idx, idx)]
            if self.C is not None:
                S_II = S_II + self.C[idx][:, idx].toarray()
            basis = row_basis(S_II, labels=idx)
            if basis.dropped.size:
                u, p_kept = self._solve_floating(idx[basis.kept])
                self.n_dependent = basis.dropped.size
                p_I = np.zeros(idx.size)
                p_I[basis.kept] = p_kept
                return u, p_I
        g_I = self.qp.g[idx]
        u, p_I = self._floating_step(idx, self.qp.f, g_I, self.z_f)
        B_I = self.B[idx]
        C_II = None if self.C is None else self.C[idx][:, idx]
        for _ in range(self.refine):      # until the correction is at round-off
            r_f = self.qp.f - self.A @ u - B_I.T @ p_I
            r_g = g_I - B_I @ u + (C_II @ p_I if C_II is not None else 0.0)
            du, dp = self._floating_step(idx, r_f, r_g)
            u, p_I = u + du, p_I + dp
            if np.max(np.abs(du)) <= 1e-14 * np.max(np.abs(u)):
                break
        return u, p_I

    def _floating_step(self, idx, r_f, r_g, z=None):
        """One solve of the step's system for the right-hand side ``(r_f, r_g)``
        (``z = A_rr^{-1} r_f`` on the rest if known); see :meth:`_solve_floating`."""
        fl = self.floating
        if z is None:
            z = fl.rest_solve(r_f[fl.rest], refine=False)
        f_t = fl.R.T @ r_f - fl.C.T @ z
        if idx.size:
            g_t = r_g - self.B_rest[idx] @ z
            S_II = self.S[np.ix_(idx, idx)]
            if self.C is not None:
                S_II = S_II + self.C[idx][:, idx].toarray()
            G_I = self.G[idx]
            try:
                cho = sla.cho_factor(S_II)
            except sla.LinAlgError as err:
                raise RuntimeError(f"Schur complement not positive definite: {err}") from None
            X = sla.cho_solve(cho, np.column_stack([G_I, g_t]))
            M = fl.sigma + G_I.T @ X[:, :-1]
            alpha = np.linalg.solve(0.5 * (M + M.T), f_t + G_I.T @ X[:, -1])
            p_I = X[:, :-1] @ alpha - X[:, -1]
            rhs_r = r_f[fl.rest] - fl.C @ alpha - self.B_rest[idx].T @ p_I
        else:
            alpha = np.linalg.solve(fl.sigma, f_t)
            p_I = np.zeros(0)
            rhs_r = r_f[fl.rest] - fl.C @ alpha
        u = fl.R @ alpha
        u[fl.rest] += fl.rest_solve(rhs_r, refine=False)
        return u, p_I


SOLVER = SolverSpec(
    name="pdas",
    summary="primal-dual active set (semismooth Newton, Hintermüller-Ito-Kunisch), exact: "
            "A factorised once and the dual problem on the contact rows (or a KKT LU per "
            "step); the exact reference",
    solve=solve,
    parameters=(
        Parameter("c", 1.0, "PDAS parameter relative to the stiffness scale (only matters "
                  "with an initial guess)", low=0.0, low_open=True),
        Parameter("method", "auto", "linear algebra: reduced KKT LU per step, or A factorised "
                  "once + dense Schur complement (the dual problem on the contact rows); "
                  f"auto: schur up to {SCHUR_MAX_M} constraints", choices=("auto", "kkt", "schur")),
        Parameter("factorization", "auto", "sparse Cholesky backend of method='schur' "
                  "(solvers/kernels/cholesky.py; auto: MKL PARDISO where installed, else SuperLU)",
                  choices=("auto", "pardiso", "splu")),
        Parameter("refine", 3, "iterative refinement steps per direct solve", low=0, high=20),
        Parameter("flip_tol", 1e-13, "relative size below which a sign change does not "
                  "change the active set", low=0.0, high=1e-6),
    ),
    presets={"low": "exact (stops when the active set repeats); tol only judges the result",
             "mid": "exact (stops when the active set repeats); tol only judges the result",
             "high": "exact (stops when the active set repeats); tol only judges the result"},
    default_max_iter=100,
    role=Role.EXACT,
    handles_C=True,
)
