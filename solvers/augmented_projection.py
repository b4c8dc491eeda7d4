"""Augmented projection method (thesis Alg. 8.4, Sects. 8.1-8.6).

The contact problem is rewritten by the Bramble-Pasciak transformation as the
box-constrained quadratic problem (8.20) in ``(u, p)``::

    minimise  Jt(U) = 1/2 U' At U - Ft' U   over  U = (u, p),  p >= 0,
    At = [[(A - Ah) Ah^-1 A,  (A - Ah) Ah^-1 B'],
          [ B Ah^-1 (A - Ah), B Ah^-1 B' + C   ]],
    Ft = [(A - Ah) Ah^-1 F,  B Ah^-1 F - G]

(the thesis prints the (2,1) block as ``B Ah^-1 (Ah - A)``; symmetry and the
multiplication in Sect. 8.4 give ``(A - Ah)``). It is solved by projected
preconditioned Richardson with the block preconditioner (8.22)
``diag(gamma_bar (A - Ah), S-hat)`` and an approximate projection of ``p`` onto
``p >= 0`` in the ``S-hat`` norm that only multiplies by ``S-hat`` ((8.24)).

Ingredients (:mod:`solvers.preconditioners`): ``Ah`` one symmetric V-cycle
(geometric multigrid on ``qp.multilevel['prolongations']`` or pyamg smoothed
aggregation with rigid-body modes), scaled by Lanczos so that
``Ah < A <= gamma_bar Ah`` (8.18, Remark 8.14); ``S-hat`` the inexact Schur
complement ``S_in`` or a sparse one (multilevel surface operator, Jacobi-type),
scaled so that ``S_in <= S-hat``. Then ``alpha_bar <= 1 + sqrt(1 - 1/gamma_bar)``
(Theorem 8.8, Remark 8.9) and ``tau = 1/alpha_bar`` (Sect. 8.5).

Approximate projection: Alg. 8.3 (projected Richardson, ``n_i`` by (8.15)) or
Dostál's MPRGP (Sect. 8.6, ref. [19]) stopped at a relative reduction of the
projected gradient. ``u`` is updated additively or multiplicatively (Alg. 8.4).
Termination by (8.25): ``sqrt(eta_k / eta_0) <= eps`` with
``eta_k = <w_u, d_u> + <p^{k+1} - p^k, w_p>``.

What Theorem 8.2 guarantees here: the *transformed* functional ``Jt(u^k, p^k)``
decreases monotonically (recorded as ``history['J_transformed']``), not the
primal energy ``J(u^k) = 1/2 u'Au - f'u`` (``u^k`` is infeasible on the way and
``J(u^k)`` may undershoot ``J(u)``). The multiplicative update is a block
Gauss-Seidel step: with ``S_in <= S-hat`` the ``p``-step decreases ``Jt`` for any
``tau <= 1`` (the inner functional of (8.24) decreases from ``p^k``) and the
``u``-step with the new ``p`` does for ``tau < 2`` (``(A - Ah) Ah^-1 A <=
gamma_bar (A - Ah)``), so its default is ``tau = 1`` (measured: half the outer
steps of ``tau = 1/alpha_bar``); the additive update keeps the thesis's
``tau = 1/alpha_bar``.

Nested iteration (Alg. 8.5) is :func:`nested_initial_guess`; the solver itself
never builds coarser problems.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from problems.spec import Parameter
from solvers import preconditioners as pc
from solvers.interface import ContactQP, SolveResult, SolverSpec, kkt_residuals


# ---------------------------------------------------------------------------
# Approximate projections (Alg. 8.3, MPRGP)
# ---------------------------------------------------------------------------
def projected_richardson(S_hat: Callable, d: np.ndarray, q0: np.ndarray, tau_2: float,
                         n: int) -> tuple[np.ndarray, int]:
    """Alg. 8.3: ``n`` steps of projected Richardson for (8.24).

    Minimises ``1/2 q'S-hat q - d'q`` over ``q >= 0``, i.e. (8.24) with
    ``d = S-hat p^k + tau w_p`` (``S-hat^{-1}`` never appears)::

        w^0 = p^k;  w^{j+1} = P_I^N(w^j + tau_2 (d - S-hat w^j))

    Returns
    -------
    (q, n_steps)
    """
    w = np.maximum(q0, 0.0)
    for _ in range(n):
        w = np.maximum(w + tau_2 * (d - S_hat(w)), 0.0)
    return w, n


def mprgp(S_hat: Callable, d: np.ndarray, q0: np.ndarray, alpha_bar: float, rtol: float,
          max_steps: int, Gamma: float = 1.0) -> tuple[np.ndarray, int]:
    """Dostál's MPRGP for (8.24) (Sect. 8.6, ref. [19]).

    Modified proportioning with reduced gradient projections for
    ``min 1/2 q'S-hat q - d'q, q >= 0``: CG steps on the free set, expansion
    steps with the fixed step ``alpha_bar in (0, 2/||S-hat||]`` and
    proportioning steps along the chopped gradient. The functional decreases
    monotonically, so (8.9) holds.

    Parameters
    ----------
    rtol : float
        Stop when ``||g^P(q)|| <= rtol ||g^P(q0)||`` (projected gradient).
    max_steps : int
        Cap on the number of steps.

    Returns
    -------
    (q, n_steps)
    """
    x = np.maximum(q0, 0.0)
    g = S_hat(x) - d

    def parts(x, g):
        free = x > 0
        phi = np.where(free, g, 0.0)
        beta = np.where(free, 0.0, np.minimum(g, 0.0))
        return phi, beta

    phi, beta = parts(x, g)
    gp0 = np.linalg.norm(phi + beta)
    if gp0 == 0.0:
        return x, 0
    p = phi.copy()
    steps = 0
    while steps < max_steps:
        if np.linalg.norm(phi + beta) <= rtol * gp0:
            break
        phi_red = np.where(x > 0, np.minimum(x / alpha_bar, phi), 0.0)
        steps += 1
        if beta @ beta <= Gamma ** 2 * (phi_red @ phi):
            Sp = S_hat(p)
            pSp = float(p @ Sp)
            if pSp <= 0.0:
                break
            a_cg = float(g @ p) / pSp
            pos = p > 0
            a_f = float(np.min(x[pos] / p[pos])) if np.any(pos) else np.inf
            if a_cg <= a_f:  # conjugate gradient step
                x = x - a_cg * p
                g = g - a_cg * Sp
                phi, beta = parts(x, g)
                p = phi - (float(phi @ Sp) / pSp) * p
            else:  # expansion step
                x = x - a_f * p
                g = g - a_f * Sp
                phi, _ = parts(x, g)
                x = np.maximum(x - alpha_bar * phi, 0.0)
                g = S_hat(x) - d
                phi, beta = parts(x, g)
                p = phi.copy()
        else:  # proportioning step
            Sb = S_hat(beta)
            a_cg = float(g @ beta) / float(beta @ Sb)
            x = x - a_cg * beta
            g = g - a_cg * Sb
            phi, beta = parts(x, g)
            p = phi.copy()
    return x, steps


# ---------------------------------------------------------------------------
# Alg. 8.4
# ---------------------------------------------------------------------------
@dataclass
class OuterStep:
    """Quantities of one outer step ``k`` handed to the monitor."""

    k: int
    u: np.ndarray
    p: np.ndarray
    eta: float             # (8.25): <w_u, d_u> + <p^{k+1} - p^k, w_p>
    eta_rel: float         # sqrt(eta_k / eta_0)
    corollary_8_4: float   # <U^{k+1} - U^k, Ft - At U^k>
    J_transformed: float   # Jt(U^k) (8.20), before the step
    n_inner: int
    t_proj: float


def augmented_projection_algorithm(A, B, C, F, G, A_hat_inv: Callable, S_hat: Callable,
                                   tau: float, gamma_bar: float, project: Callable,
                                   u: np.ndarray, p: np.ndarray, eps: float, max_iter: int,
                                   update: str = "multiplicative",
                                   monitor: Callable[[OuterStep], bool] | None = None):
    """Alg. 8.4 (approximate augmented projection), line by line.

    Parameters
    ----------
    A, B, C, F, G
        The contact problem ``A u + B'p = F``, ``B u - C p <= G``, ``p >= 0``
        (``C`` may be None).
    A_hat_inv : callable
        Scaled preconditioner, ``A_hat < A <= gamma_bar A_hat`` (8.18).
    S_hat : callable
        Product with the Schur-complement preconditioner (never its inverse).
    tau : float
        Relaxation parameter of the Richardson step.
    project : callable
        ``project(d, p_k) -> (p_{k+1}, n_inner)``: approximate minimiser of
        ``1/2 q'S_hat q - d'q`` over ``q >= 0`` ((8.24), Alg. 8.3 or MPRGP).
    u, p : arrays
        Initial guess ``(u^0, p^0)``, ``p^0 >= 0``.
    eps : float
        Relative tolerance of the termination criterion (8.25).
    update : {"additive", "multiplicative"}
    monitor : callable, optional
        Called after each step with an :class:`OuterStep`; returning True
        stops the iteration (time limit, KKT-based stopping).

    Returns
    -------
    (u, p, k, reason) with ``reason`` in {"converged", "max_iter", "monitor"}.
    """
    Cp = (lambda q: C @ q) if C is not None else (lambda q: 0.0)
    z = A_hat_inv(F)                                         # for Jt(U^k) only
    Ft_dot = lambda u, p, Au: Au @ z - F @ u + p @ (B @ z) - p @ G
    eta_0 = None
    for k in range(max_iter):
        Au = A @ u
        d_u = F - Au - B.T @ p                               # (8.23)
        w_u = A_hat_inv(d_u)                                 # (8.23)
        w_p = B @ w_u - (G - B @ u + Cp(p))                  # (8.23)
        J_t = -0.5 * Ft_dot(u, p, Au) - 0.5 * (Au @ w_u - u @ d_u + p @ w_p)
        t0 = time.perf_counter()
        p_new, n_inner = project(S_hat(p) + tau * w_p, p)    # p^{k+1} = P~(S-hat p^k + tau w_p), (8.24)
        t_proj = time.perf_counter() - t0
        u_add = u + (tau / gamma_bar) * w_u                  # additive update
        if update == "multiplicative":
            u_new = u_add + (tau / gamma_bar) * A_hat_inv(B.T @ (p - p_new))
        else:
            u_new = u_add
        eta = float(w_u @ d_u + (p_new - p) @ w_p)           # (8.25)
        du = u_new - u
        cor = float(du @ (A @ w_u) - du @ d_u + (p_new - p) @ w_p)  # Corollary 8.4
        if eta_0 is None:
            eta_0 = max(eta, 1e-300)
        eta_rel = float(np.sqrt(max(eta, 0.0) / eta_0))
        u, p = u_new, p_new
        stop = monitor(OuterStep(k + 1, u, p, eta, eta_rel, cor, float(J_t), n_inner, t_proj)) \
            if monitor else False
        if eta_rel <= eps:                                   # termination (8.25)
            return u, p, k + 1, "converged"
        if stop:
            return u, p, k + 1, "monitor"
    return u, p, max_iter, "max_iter"


# ---------------------------------------------------------------------------
# Variant beyond the thesis: Krylov acceleration of the outer iteration
# ---------------------------------------------------------------------------
def face_cg_variant(A, B, C, F, G, A_hat_inv: Callable, S_hat: Callable, S_dense: np.ndarray,
                    tau: float, gamma_bar: float, project: Callable, u: np.ndarray,
                    p: np.ndarray, eps: float, max_iter: int, Gamma: float = 1.0,
                    monitor: Callable[[OuterStep], bool] | None = None):
    """Alg. 8.4 accelerated by preconditioned CG on the face of the active set.

    *Not in the thesis* (option ``accelerate="face_cg"``). An MPRGP-like
    outer method for the transformed problem (8.20): multiplicative Alg. 8.4
    steps (which also play the role of proportioning/expansion steps) until
    the set ``{p > 0}`` repeats; then Bramble-Pasciak CG for (8.20) with
    ``p`` restricted to that face and the block preconditioner
    ``diag(gamma_bar (A - A_hat), S_hat_II)`` (8.22), one V-cycle per step
    (the ``u``-part of the residual stays of the form ``(A - A_hat) y``, so
    ``(A - A_hat)^{-1}`` is never needed). The CG phase ends at a step that
    would leave ``p >= 0`` (truncated, feasible step), or when the chopped
    gradient of the zero multipliers outgrows the face residual (factor
    ``Gamma``). Both steps decrease ``Jt`` monotonically. ``S_hat_II^{-1}`` is a
    dense Cholesky factor of the face block of ``S_hat`` (size = number of
    active constraints; in 2D far below N).

    Returns
    -------
    (u, p, k, reason, n_cg) as :func:`augmented_projection_algorithm` plus
    the number of CG steps among the ``k`` outer steps.
    """
    import scipy.linalg as sla
    Cp = (lambda q: C @ q) if C is not None else (lambda q: 0.0)
    S_diag = np.diag(S_dense).copy()
    eta_0, k, n_cg, last_face = None, 0, 0, None

    def emit(eta, cor, n_inner, t_proj):
        eta_rel = float(np.sqrt(max(eta, 0.0) / eta_0))
        stop = monitor(OuterStep(k, u, p, eta, eta_rel, cor, np.nan, n_inner, t_proj)) \
            if monitor else False
        return eta_rel, stop

    while k < max_iter:
        # -- one multiplicative step of Alg. 8.4 ---------------------------
        d_u = F - A @ u - B.T @ p
        w_u = A_hat_inv(d_u)
        w_p = B @ w_u - (G - B @ u + Cp(p))
        t0 = time.perf_counter()
        p_new, n_inner = project(S_hat(p) + tau * w_p, p)
        t_proj = time.perf_counter() - t0
        u_new = u + (tau / gamma_bar) * (w_u + A_hat_inv(B.T @ (p - p_new)))
        eta = float(w_u @ d_u + (p_new - p) @ w_p)
        eta_0 = max(eta, 1e-300) if eta_0 is None else eta_0
        u, p, k = u_new, p_new, k + 1
        eta_rel, stop = emit(eta, np.nan, n_inner, t_proj)
        if eta_rel <= eps:
            return u, p, k, "converged", n_cg
        if stop:
            return u, p, k, "monitor", n_cg
        face = p > 0
        if last_face is None or not np.array_equal(face, last_face) or not face.any():
            last_face = face
            continue
        # -- CG on the face {p > 0} ------------------------------------------
        I = np.flatnonzero(face)
        chol = sla.cho_factor(S_dense[np.ix_(I, I)])
        d = F - A @ u - B.T @ p
        y = A_hat_inv(d)
        Ay = A @ y
        r_p = B @ y - (G - B @ u + Cp(p))
        P_u = AP_u = P_p = None
        rz_old = None
        while k < max_iter:
            z = sla.cho_solve(chol, r_p[I])
            rz = float(Ay @ y - y @ d) / gamma_bar + float(r_p[I] @ z)
            chopped = np.where(face, 0.0, np.maximum(r_p, 0.0))
            eta_beta = float(chopped @ (chopped / S_diag))
            if eta_beta > Gamma ** 2 * rz:
                break                                    # a zero multiplier wants to grow
            Z_p = np.zeros_like(p)
            Z_p[I] = z
            if rz_old is None:
                P_u, AP_u, P_p = y / gamma_bar, Ay / gamma_bar, Z_p
            else:
                beta = rz / rz_old
                P_u = y / gamma_bar + beta * P_u
                AP_u = Ay / gamma_bar + beta * AP_u
                P_p = Z_p + beta * P_p
            rz_old = rz
            q = AP_u + B.T @ P_p
            v = A_hat_inv(q)
            BPv = B @ v - B @ P_u + Cp(P_p)
            pAp = float(AP_u @ v - P_u @ q + P_p @ BPv)
            if pAp <= 0.0:
                break
            alpha = rz / pAp
            neg = P_p < 0
            alpha_f = float(np.min(-p[neg] / P_p[neg])) if neg.any() else np.inf
            step = min(alpha, alpha_f)
            u = u + step * P_u
            p = np.maximum(p + step * P_p, 0.0)
            d = d - step * q
            y = y - step * v
            Ay = A @ y
            r_p = r_p - step * BPv
            k, n_cg = k + 1, n_cg + 1
            eta_rel, stop = emit(rz + eta_beta, step * rz, 0, 0.0)
            if eta_rel <= eps and eta_beta <= eps ** 2 * eta_0:
                return u, p, k, "converged", n_cg
            if stop:
                return u, p, k, "monitor", n_cg
            if alpha_f <= alpha:
                break                                    # the face shrinks: back to Alg. 8.4
        last_face = None
    return u, p, max_iter, "max_iter", n_cg


# ---------------------------------------------------------------------------
# Setup and the registered solve()
# ---------------------------------------------------------------------------
def theorem_8_8_alpha(gamma_bar: float) -> tuple[float, float]:
    """Spectral constants of (8.22) vs (8.20) for ``S-hat = S_in`` (Theorem 8.8)."""
    r = np.sqrt(max(0.0, 1.0 - 1.0 / gamma_bar))
    return 1.0 - r, 1.0 + r


def make_projection(kind: str, S_hat: pc.SchurPreconditioner, inner_rtol: float,
                    max_inner: int, n_i_factor: float, tau_2_hat: float = 1.0):
    """The approximate projection ``project(d, p_k) -> (p_{k+1}, n_inner)``.

    ``richardson``: Alg. 8.3 with ``tau_2 = tau_2_hat / lambda_max(S-hat)`` and
    ``n_i = ceil(c 2 kappa(S-hat) / tau_2_hat)`` (8.15), ``c = n_i_factor``,
    i.e. ``rho_P <= exp(-c)``. ``mprgp``: MPRGP with ``alpha_bar = 1/lambda_max``
    stopped at the relative projected-gradient reduction ``inner_rtol``.
    """
    lam_max = S_hat.lam_max
    if kind == "richardson":
        n_i = int(min(max_inner, np.ceil(n_i_factor * 2.0 * S_hat.kappa / tau_2_hat)))
        tau_2 = tau_2_hat / lam_max
        return (lambda d, p: projected_richardson(S_hat, d, p, tau_2, n_i)), n_i
    if kind == "mprgp":
        return (lambda d, p: mprgp(S_hat, d, p, 1.0 / lam_max, inner_rtol, max_inner)), None
    raise ValueError(f"unknown projection {kind!r}; allowed: mprgp, richardson")


def _default_kinds(qp: ContactQP, ahat: str, schur: str) -> tuple[str, str]:
    if ahat == "auto":
        ahat = "gmg" if qp.multilevel.get("prolongations") else "sa"
    if schur == "auto":
        ok = qp.dim == 2 and qp.contact_nodes is not None and "points" in qp.geometry and qp.m > 2
        schur = "multilevel" if ok else "inexact"
    return ahat, schur


def solve(qp: ContactQP, tol: float, max_iter: int, time_limit: float | None = None,
          u0: np.ndarray | None = None, p0: np.ndarray | None = None, *,
          ahat: str = "auto", smoother: str = "symmetric_gs", max_coarse: int = 500,
          schur: str = "auto", projection: str = "mprgp", update: str = "multiplicative",
          eps: float = 0.0, stop: str = "estimate", tau: float = 0.0, inner_rtol: float = 0.1,
          n_i_factor: float = 1.0, max_inner: int = 2000, lanczos_steps: int = 12,
          kappa_exact: bool = False, record_kkt: bool = True, seed: int = 0,
          accelerate: str = "none", callback: Callable | None = None) -> SolveResult:
    """Solve ``qp`` by Alg. 8.4 (see the module docstring for the options).

    ``callback(step: OuterStep) -> bool`` (Python only, not a registry option)
    is called after each outer step; True stops the run (status ``max_iter``
    unless (8.25) is met). Measurement scripts use it for error-vs-time curves.

    Returns
    -------
    SolveResult
        ``claimed_status`` ``converged`` when (8.25) (``stop="estimate"``) or
        the verified KKT residual (``stop="kkt"``) meets the tolerance;
        ``stats`` has the columns of Table 9.1 and the setup details;
        ``history`` per outer step: ``energy`` J(u^k), ``J_transformed``,
        ``kkt_max``, ``eta_rel``, ``corollary_8_4``, ``n_inner``, ``time``.
    """
    t_start = time.perf_counter()
    deadline = None if time_limit is None else t_start + time_limit
    ahat, schur = _default_kinds(qp, ahat, schur)
    if qp.m == 0:
        raise ValueError("augmented projection needs at least one constraint")
    A_hat_inv = pc.scaled_vcycle(qp.A, ahat, qp.multilevel, qp.dim, qp.free_dofs, smoother,
                                 max_coarse, lanczos_steps, seed)
    gamma_bar = A_hat_inv.gamma_bar
    S_hat = pc.build_schur(schur, qp, A_hat_inv, lanczos_steps, seed)
    alpha_low, alpha_bar = theorem_8_8_alpha(gamma_bar)
    if tau <= 0.0:  # Sect. 8.5: tau = 1/alpha_bar; block Gauss-Seidel (multiplicative): 1
        tau = 1.0 / alpha_bar if update == "additive" else 1.0
    project, n_i_fixed = make_projection(projection, S_hat, inner_rtol, max_inner, n_i_factor)
    # Theorem 8.2 rate (known rho_P only for Alg. 8.3, where rho_P <= exp(-c)).
    mu = S_hat.ritz_Sin[0] / S_hat.scale if S_hat.name in ("jacobi", "multilevel") else 1.0
    rho_P = np.exp(-n_i_factor) if projection == "richardson" else np.nan
    rho = 1.0 - 0.5 * tau * alpha_low * mu * (1.0 - rho_P)
    if accelerate == "face_cg":
        if update != "multiplicative":
            raise ValueError("accelerate='face_cg' uses the multiplicative update")
        S_dense = S_hat.dense()
        S_hat.n_applications = 0
    setup_time = time.perf_counter() - t_start
    vcycles_setup = A_hat_inv.n_applications

    u = np.zeros(qp.n) if u0 is None else np.array(u0, dtype=float)
    p = np.zeros(qp.m) if p0 is None else np.maximum(np.asarray(p0, dtype=float), 0.0)
    eps_eff = eps if eps > 0 else tol
    history = {k: [] for k in ("energy", "J_transformed", "kkt_max", "eta_rel", "eta",
                               "corollary_8_4", "n_inner", "t_proj", "time")}
    t_solve = time.perf_counter()
    state = {"reason": None}

    def monitor(step: OuterStep) -> bool:
        history["energy"].append(qp.energy(step.u))
        history["J_transformed"].append(step.J_transformed)
        history["eta_rel"].append(step.eta_rel)
        history["eta"].append(step.eta)
        history["corollary_8_4"].append(step.corollary_8_4)
        history["n_inner"].append(step.n_inner)
        history["t_proj"].append(step.t_proj)
        kmax = kkt_residuals(qp, step.u, step.p).max if (record_kkt or stop == "kkt") else np.nan
        history["kkt_max"].append(kmax)
        history["time"].append(time.perf_counter() - t_solve)
        if callback is not None and callback(step):
            state["reason"] = "callback"
            return True
        if stop == "kkt" and kmax <= tol:
            state["reason"] = "kkt"
            return True
        if deadline is not None and time.perf_counter() > deadline:
            state["reason"] = "time_limit"
            return True
        return False

    eps_run = eps_eff if stop == "estimate" else 0.0
    n_cg = 0
    if accelerate == "face_cg":
        u, p, k, reason, n_cg = face_cg_variant(
            qp.A, qp.B, qp.C, qp.f, qp.g, A_hat_inv, S_hat, S_dense, tau, gamma_bar, project,
            u, p, eps_run, max_iter, monitor=monitor)
    else:
        u, p, k, reason = augmented_projection_algorithm(
            qp.A, qp.B, qp.C, qp.f, qp.g, A_hat_inv, S_hat, tau, gamma_bar, project, u, p,
            eps_run, max_iter, update, monitor)
    solve_time = time.perf_counter() - t_solve
    if reason == "converged" or state["reason"] == "kkt":
        status = "converged"
        message = (f"(8.25) estimate reduced by {history['eta_rel'][-1]:.2e} <= eps {eps_eff:.1e}"
                   if reason == "converged" else f"KKT max <= {tol:.1e}") + f" after {k} outer steps"
    elif state["reason"] == "time_limit":
        status, message = "time_limit", f"time limit {time_limit:g} s reached after {k} outer steps"
    elif state["reason"] == "callback":
        status, message = "max_iter", f"stopped by the callback after {k} outer steps"
    else:
        status, message = "max_iter", f"(8.25) not met after {k} outer steps"
    n_vcycles, t_vcycle = A_hat_inv.n_applications - vcycles_setup, A_hat_inv.time
    kappa_SinvS = np.nan
    if kappa_exact:  # diagnostic, after the timed solve (Sect. 8.6: kappa(S-hat^-1 S))
        kappa_SinvS = pc.kappa_schur_exact(qp, A_hat_inv, S_hat, max(lanczos_steps, 20))[0]
    n_inner = np.asarray(history["n_inner"], dtype=float)
    stats = {
        "N": int(len(qp.geometry["points"])) if "points" in qp.geometry else qp.n // qp.dim,
        "NC": qp.m, "n": qp.n,
        "n_outer": k, "n_inner_mean": float(n_inner.mean()) if n_inner.size else 0.0,
        "n_inner_total": int(n_inner.sum()),
        "t_solve": solve_time, "t_setup": setup_time, "t_proj": float(np.sum(history["t_proj"])),
        "t_vcycle": t_vcycle, "n_vcycles": n_vcycles,
        "t_ahat_setup": A_hat_inv.setup_time, "t_ahat_lanczos": A_hat_inv.lanczos_time,
        "t_shat_setup": S_hat.setup_time,
        "ahat": ahat, "smoother": smoother, "schur": schur, "projection": projection,
        "update": update, "accelerate": accelerate, "n_cg": n_cg, "stop": stop, "eps": eps_eff, "tau": tau,
        "gamma_bar": gamma_bar, "ritz_AhatA_min": A_hat_inv.ritz[0],
        "ritz_AhatA_max": A_hat_inv.ritz[1], "amg_levels": len(A_hat_inv.ml.levels),
        "operator_complexity": A_hat_inv.operator_complexity(),
        "kappa_S": S_hat.kappa, "kappa_SinvSin": S_hat.kappa_Sin, "kappa_SinvS": kappa_SinvS,
        "alpha_low": alpha_low * mu, "alpha_bar": alpha_bar, "rho_bound": rho,
        "n_i_fixed": -1 if n_i_fixed is None else n_i_fixed,
        "eta_rel_final": history["eta_rel"][-1] if history["eta_rel"] else np.nan,
    }
    return SolveResult(u=u, p=p, claimed_status=status, message=message, iterations=k,
                       setup_time=setup_time, solve_time=solve_time, history=history, stats=stats)


# ---------------------------------------------------------------------------
# Nested iteration (Alg. 8.5)
# ---------------------------------------------------------------------------
def nested_initial_guess(qp_coarse: ContactQP, result_coarse, qp_fine: ContactQP,
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Initial guess on level L from the solution on level L-1 (Alg. 8.5, Sect. 8.6).

    ``u0 = P u_{L-1}`` with ``P = qp_fine.multilevel['prolongations'][-1]``;
    ``p0 = M_L Prolongate(M_{L-1}^{-1} p_{L-1})``: the pressure
    ``p / contact_mass`` is a grid function on the constrained surface; it is
    prolongated with the same nodal prolongation (the contact direction as the
    vector component) and multiplied by the fine lumped mass, so ``p0 >= 0``.

    Parameters
    ----------
    qp_coarse, qp_fine : ContactQP
        Consecutive levels of one scene (``qp_fine`` carries the prolongation).
    result_coarse : SolveResult or (u, p) tuple

    Returns
    -------
    (u0, p0)
    """
    u_c, p_c = (result_coarse.u, result_coarse.p) if hasattr(result_coarse, "u") else result_coarse
    P = qp_fine.multilevel["prolongations"][-1]
    if P.shape != (qp_fine.n, qp_coarse.n):
        raise ValueError(f"prolongation has shape {P.shape}, expected {(qp_fine.n, qp_coarse.n)}")
    u0 = P @ u_c
    dim = qp_fine.dim
    pos_c = _dof_position(qp_coarse)
    pos_f = _dof_position(qp_fine)
    v = np.zeros(qp_coarse.n)
    lam_c = p_c / qp_coarse.contact_mass
    for comp in range(dim):
        idx = pos_c[qp_coarse.contact_nodes * dim + comp]
        ok = idx >= 0
        v[idx[ok]] += lam_c[ok] * qp_coarse.contact_direction[ok, comp]
    vf = P @ v
    lam_f = np.zeros(qp_fine.m)
    for comp in range(dim):
        idx = pos_f[qp_fine.contact_nodes * dim + comp]
        ok = idx >= 0
        lam_f[ok] += vf[idx[ok]] * qp_fine.contact_direction[ok, comp]
    return u0, np.maximum(lam_f, 0.0) * qp_fine.contact_mass


def _dof_position(qp: ContactQP) -> np.ndarray:
    """Map full DOF index -> position among the free DOFs (-1 if prescribed)."""
    size = len(qp.u_fixed) if qp.u_fixed is not None else int(qp.free_dofs.max()) + 1
    pos = -np.ones(size, dtype=int)
    pos[qp.free_dofs] = np.arange(qp.n)
    return pos


SOLVER = SolverSpec(
    name="augmented_projection",
    summary="Hackl's augmented projection (Alg. 8.4): projected preconditioned Richardson on the "
            "Bramble-Pasciak-transformed problem, multigrid A-hat, sparse S-hat, MPRGP projection",
    solve=solve,
    parameters=(
        Parameter("ahat", "auto", "A-hat: one symmetric V-cycle of geometric MG on the hierarchy "
                  "(gmg) or pyamg SA with rigid-body modes (sa); auto = gmg if prolongations exist",
                  choices=("auto", "gmg", "sa")),
        Parameter("smoother", "symmetric_gs", "V(1,1) smoother", choices=tuple(pc._SMOOTHERS)),
        Parameter("max_coarse", 500, "SA: largest coarsest level", low=10, kind=int),
        Parameter("schur", "auto", "S-hat: multilevel surface operator (O(N^C)), inexact S_in "
                  "(matrix-free), inexact_assembled (N^C V-cycles) or jacobi B diag(A)^-1 B'",
                  choices=("auto", "multilevel", "inexact", "inexact_assembled", "jacobi")),
        Parameter("projection", "mprgp", "approximate projection: MPRGP (Sect. 8.6) or "
                  "projected Richardson (Alg. 8.3, n_i by (8.15))", choices=("mprgp", "richardson")),
        Parameter("update", "multiplicative", "u-update of Alg. 8.4",
                  choices=("multiplicative", "additive")),
        Parameter("eps", 0.0, "relative tolerance of (8.25); 0 = tol", low=0.0, high=1.0),
        Parameter("stop", "estimate", "stop by (8.25) or by the verified KKT residual <= tol",
                  choices=("estimate", "kkt")),
        Parameter("tau", 0.0, "relaxation; 0 = auto: 1/alpha_bar (Theorem 8.8) for the additive, "
                  "1 for the multiplicative update", low=0.0, high=2.0),
        Parameter("inner_rtol", 0.1, "MPRGP: relative projected-gradient reduction", low=0.0,
                  high=1.0, low_open=True),
        Parameter("n_i_factor", 1.0, "Alg. 8.3: c in n_i = c 2 kappa(S-hat) (8.15)", low=0.0,
                  low_open=True),
        Parameter("max_inner", 2000, "cap on inner steps per projection", low=1, kind=int),
        Parameter("lanczos_steps", 12, "Lanczos steps for gamma_bar and S-hat scaling", low=5,
                  kind=int),
        Parameter("kappa_exact", False, "also estimate kappa(S-hat^-1 S), S = B A^-1 B' (costly)"),
        Parameter("accelerate", "none", "beyond the thesis: 'face_cg' = Bramble-Pasciak CG on the "
                  "face of the active set between Alg. 8.4 steps", choices=("none", "face_cg")),
        Parameter("record_kkt", True, "verified KKT residual in the history at every step"),
        Parameter("seed", 0, "Lanczos start vectors", low=0, kind=int),
    ),
    presets={"low": "eps = 1e-3 in (8.25)", "mid": "eps = 1e-6 in (8.25)",
             "high": "eps = 1e-9 in (8.25)"},
    default_max_iter=2000,
    role="thesis",
)
