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

Ingredients (:mod:`solvers.kernels.multigrid`, :mod:`solvers.kernels.schur`): ``Ah`` one
symmetric V-cycle (geometric multigrid on ``qp.multilevel.prolongations`` or pyamg smoothed
aggregation with rigid-body modes), scaled by Lanczos so that
``Ah < A <= gamma_bar Ah`` (8.18, Remark 8.14); ``S-hat`` the inexact Schur
complement ``S_in`` or a sparse one (multilevel surface operator, Jacobi-type),
scaled so that ``S_in <= S-hat``. Then ``alpha_bar <= 1 + sqrt(1 - 1/gamma_bar)``
(Theorem 8.8, Remark 8.9) and ``tau = 1/alpha_bar`` (Sect. 8.5).

Approximate projection: Alg. 8.3 (projected Richardson, ``n_i`` by (8.15)) or
Dostál's MPRGP (Sect. 8.6, ref. [19]) stopped at a relative reduction of the
projected gradient. ``u`` is updated additively or multiplicatively (Alg. 8.4).
Termination: by default when the suite's own verification passes (the scaled
KKT residuals and the certified energy bound of the duality gap,
:func:`solvers.interface.verify`), so that a claim of convergence is never
refuted by the verification; with ``stop="estimate"``
by the thesis's (8.25): ``sqrt(eta_k / eta_0) <= eps`` with
``eta_k = <w_u, d_u> + <p^{k+1} - p^k, w_p>`` (which defines n_o(eps) of
Tables 9.1 and 9.3). An infeasible problem ends ``failed`` with a Farkas certificate
("the problem is infeasible"): its multipliers run off along a ray of the unbounded dual,
which :class:`DualRay` reads off their increments and the direct solvers' exact test
confirms.

What Theorem 8.2 guarantees here: the *transformed* functional ``Jt(u^k, p^k)``
decreases monotonically (recorded as ``history['J_transformed']``), not the
primal energy ``J(u^k) = 1/2 u'Au - f'u`` (``u^k`` is infeasible on the way and
``J(u^k)`` may undershoot ``J(u)``). The multiplicative update is a block
Gauss-Seidel step: with ``S_in <= S-hat`` the ``p``-step decreases ``Jt`` for any
``tau <= 1`` (the inner functional of (8.24) decreases from ``p^k``) and the
``u``-step with the new ``p`` does for ``tau < 2`` (``(A - Ah) Ah^-1 A <=
gamma_bar (A - Ah)``), so its default is ``tau = 1`` (fewer outer steps than
``tau = 1/alpha_bar``: docs/guide/measurements.md); the additive update keeps the
thesis's ``tau = 1/alpha_bar``.

Beyond the thesis, three things keep the method's outer step count bounded where the
thesis's ingredients lose their spectral equivalence:

* Towards incompressibility a V-cycle's ``kappa(V A)`` grows without bound (independent
  of h; the hard-cases study's page): ``A-hat^{-1}`` is then a Chebyshev
  polynomial in the V-cycle whose degree comes from the measured spectrum
  (:func:`solvers.kernels.multigrid.scaled_vcycle`, ``ahat.degree = 0``), and ``S-hat = auto``
  takes ``S_in`` where the multilevel operator's ``kappa(S-hat^{-1} S_in)`` exceeds
  :data:`SCHUR_KAPPA_LIMIT`.
* A body held only by contact (the roll stack's work roll) is treated by FETI's natural
  coarse space (:class:`FloatingCoarseSpace`): ``A-hat`` on the complement of its rigid
  modes, its equilibrium ``G p = e`` in every projection (:func:`smalbe`), its rigid
  motion moved by the equality's multiplier.
* The stabilised problem (Sect. 7.5) adds reverse rows on the opposing surface, for which
  the thesis has no multilevel ``S-hat`` (Remark 7.10: it falls back to ``S_in``, not
  O(N)): :func:`solvers.kernels.schur.stabilised_schur_apply` carries them to the constrained
  surface's multilevel operator through their transfer and adds the mismatch on the
  fine scale, so the method stays O(N) there too.

Nested iteration (Alg. 8.5) is :func:`nested_initial_guess`; the solver itself
never builds coarser problems.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np


from problems.fem.adaptive import prolongate_solution
from problems.floating import floating_modes
from problems.kkt import kkt_residuals
from problems.qp import ContactQP
from problems.spec import Component, ComponentParameter, Options, Parameter, ParameterError
from solvers.kernels.multigrid import AHAT_SCALED, scaled_vcycle, vcycle_kind
from solvers.kernels.schur import SchurPreconditioner, build_schur, kappa_schur_exact
from solvers.base import Role, SolveResult, SolverSpec, preset_texts
from solvers.certificate import certify
from solvers.kernels.cholesky import InfeasibleError, row_basis


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


#: SMALBE's relative tolerance on the floating bodies' equilibrium ``||G q - e|| / ||e||``
#: per projection. The outer iteration corrects what one projection leaves: a tighter
#: tolerance costs augmented-Lagrangian steps per projection and saves no outer step
#: (docs/guide/measurements.md).
EQ_RTOL = 1e-6


def smalbe(S_hat: Callable, G: np.ndarray, e: np.ndarray, d: np.ndarray, q0: np.ndarray,
           lam_max: float, rtol: float, max_steps: int, eq_rtol: float = EQ_RTOL,
           max_outer: int = 100) -> tuple[np.ndarray, np.ndarray, int]:
    """(8.24) with the equilibrium of floating bodies: ``min 1/2 q'S-hat q - d'q`` over
    ``q >= 0, G q = e`` (Dostal's SMALBE, *Optimal Quadratic Programming Algorithms*,
    2009, Ch. 9: augmented Lagrangians with MPRGP for the bound-constrained steps).

    Each outer step minimises ``L(q, mu) = 1/2 q'S-hat q - d'q + mu'(Gq - e) +
    rho/2 ||Gq - e||^2`` over ``q >= 0`` by :func:`mprgp` (from the last ``q``) and
    updates ``mu += rho (Gq - e)``; ``rho = lam_max / ||G||^2`` doubles the largest
    eigenvalue at most and contracts the multiplier error by at least 1/2 per step.

    Returns
    -------
    (q, mu, n_steps)
        ``mu`` the multiplier of ``G q = e`` (``S-hat q - d + G'mu >= 0``, complementary
        to ``q``); ``n_steps`` the MPRGP steps of all outer steps.
    """
    G = np.atleast_2d(G)
    norm_G2 = float(np.linalg.eigvalsh(G @ G.T)[-1])
    rho = lam_max / norm_G2
    H = lambda q: S_hat(q) + rho * (G.T @ (G @ q))          # noqa: E731
    mu = np.zeros(G.shape[0])
    q, n = np.maximum(q0, 0.0), 0
    goal = eq_rtol * max(float(np.linalg.norm(e)), 1e-300)
    for _ in range(max_outer):
        q, steps = mprgp(H, d - G.T @ mu + rho * (G.T @ e), q, 1.0 / (2.0 * lam_max), rtol,
                         max_steps)
        n += steps
        r = G @ q - e
        mu = mu + rho * r
        if np.linalg.norm(r) <= goal:
            break
    return q, mu, n


# ---------------------------------------------------------------------------
# Floating bodies: FETI's natural coarse space in the multiplier space
# ---------------------------------------------------------------------------
@dataclass
class FloatingCoarseSpace:
    """The rigid modes ``R`` of bodies held only by contact (and weak springs) and
    ``G = R'B'``, FETI's natural coarse space (C. Farhat, J. Mandel, F.-X. Roux 1994;
    Z. Dostal et al. for contact).

    With ``u = u_perp + R alpha`` (``R'u_perp = 0``) the modes leave ``A``'s part:
    ``A-hat`` acts on the complement of ``R`` only (:func:`solvers.kernels.multigrid.scaled_vcycle`,
    ``near_kernel``), so ``S_in = B A-hat^{-1} B'`` and ``S-hat`` lose the one eigenvalue
    that the springs' ~1e-9 stiffness puts ~4e4 times above the rest of ``S``. The
    floating body's equilibrium ``R'(f - A u - B'p) = 0`` becomes the equality ``G p = e``
    (``e = R'(f - A u)``, the load on the modes; the springs' share of it is ~1e-5)
    imposed in every projection (8.24) (:func:`smalbe`), and its multiplier ``mu``
    moves the rigid part: ``alpha <- alpha - mu / tau`` (at the fixed point
    ``tau w_p = G'mu - nu``, so this choice of ``alpha`` makes the gap ``nu / tau >= 0``
    complementary to ``p``; ``mu = 0`` at the solution).
    """

    R: np.ndarray          # (n, k) orthonormal floating modes
    G: np.ndarray          # (k, m) = R'B'

    def balance(self, d_u: np.ndarray, p: np.ndarray) -> np.ndarray:
        """``e = R'(f - A u)`` from the residual ``d_u = f - A u - B'p``."""
        return self.R.T @ d_u + self.G @ p


def floating_coarse_space(qp: ContactQP) -> FloatingCoarseSpace | None:
    """The coarse space of ``qp``'s floating modes (None if it has none)."""
    R = floating_modes(qp)
    if R.shape[1] == 0:
        return None
    return FloatingCoarseSpace(R, np.asarray((qp.B @ R).T))


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


@dataclass
class Alg84:
    """The operators of Alg. 8.4 for ``A u + B'p = F``, ``B u - C p <= G``, ``p >= 0``.

    Attributes
    ----------
    A, B, C, F, G
        The contact problem (``C`` may be None).
    A_hat_inv : callable
        Scaled preconditioner, ``A_hat < A <= gamma_bar A_hat`` (8.18).
    S_hat : callable
        Product with the Schur-complement preconditioner (never its inverse).
    gamma_bar : float
    tau : float
        Relaxation parameter of the Richardson step.
    project : callable
        ``project(d, p_k) -> (p_{k+1}, n_inner)``: approximate minimiser of
        ``1/2 q'S_hat q - d'q`` over ``q >= 0`` ((8.24), Alg. 8.3 or MPRGP).
    coarse : FloatingCoarseSpace, optional
        Floating modes: ``A_hat_inv`` acts on their complement, and the projection is
        ``project_balanced(d, p_k, G, e) -> (p_{k+1}, mu, n_inner)`` onto ``q >= 0,
        G q = e`` (:func:`smalbe`).
    """

    A: object
    B: object
    C: object
    F: np.ndarray
    G: np.ndarray
    A_hat_inv: Callable
    S_hat: Callable
    gamma_bar: float
    tau: float
    project: Callable
    coarse: FloatingCoarseSpace | None = None
    project_balanced: Callable | None = None

    def Cp(self, p):
        return self.C @ p if self.C is not None else 0.0

    def step(self, u: np.ndarray, p: np.ndarray, update: str = "multiplicative",
             Au: np.ndarray | None = None, residual: tuple | None = None):
        """One step of Alg. 8.4, (8.23)-(8.25), line by line.

        ``Au``, if given, is ``A @ u``; ``residual``, if given, is ``(d_u, w_u)``
        of (8.23) at ``(u, p)`` (saves the products when the caller has them).

        Returns
        -------
        (u_new, p_new, eta, n_inner, t_proj, d_u, w_u, w_p)
            The new iterate, the (8.25) estimate ``eta`` and the quantities of
            (8.23) at ``(u, p)`` (for the transformed functional and Cor. 8.4).
        """
        A, B, tau, gamma = self.A, self.B, self.tau, self.gamma_bar
        if residual is None:
            d_u = self.F - (A @ u if Au is None else Au) - B.T @ p  # (8.23)
            w_u = self.A_hat_inv(d_u)                               # (8.23)
        else:
            d_u, w_u = residual
        w_p = B @ w_u - (self.G - B @ u + self.Cp(p))           # (8.23)
        t0 = time.perf_counter()
        if self.coarse is None:
            p_new, n_inner = self.project(self.S_hat(p) + tau * w_p, p)  # P~(S-hat p^k + tau w_p)
        else:   # the floating bodies' equilibrium G p = e as well; mu moves their rigid part
            cs = self.coarse
            p_new, mu, n_inner = self.project_balanced(self.S_hat(p) + tau * w_p, p, cs.G,
                                                       cs.balance(d_u, p))
        t_proj = time.perf_counter() - t0
        u_new = u + (tau / gamma) * w_u                         # additive update
        if update == "multiplicative":
            u_new = u_new + (tau / gamma) * self.A_hat_inv(B.T @ (p - p_new))
        if self.coarse is not None:
            u_new = u_new - self.coarse.R @ (mu / tau)
        eta = float(w_u @ d_u + (p_new - p) @ w_p)              # (8.25)
        return u_new, p_new, eta, n_inner, t_proj, d_u, w_u, w_p


def augmented_projection_algorithm(op: Alg84, u: np.ndarray, p: np.ndarray, eps: float,
                                   max_iter: int, update: str = "multiplicative",
                                   monitor: Callable[[OuterStep], bool] | None = None,
                                   corollary: bool = True):
    """Alg. 8.4 (approximate augmented projection): repeat :meth:`Alg84.step` until (8.25).

    Parameters
    ----------
    op : Alg84
    u, p : arrays
        Initial guess ``(u^0, p^0)``, ``p^0 >= 0``.
    eps : float
        Relative tolerance of the termination criterion (8.25).
    update : {"additive", "multiplicative"}
    monitor : callable, optional
        Called after each step with an :class:`OuterStep`; returning True
        stops the iteration (time limit, KKT-based stopping).
    corollary : bool
        Also evaluate Corollary 8.4's quantity (one more product with ``A`` per
        step; NaN otherwise). ``Jt(U^k)`` costs no product: the step shares ``A u``.

    Returns
    -------
    (u, p, k, reason) with ``reason`` in {"converged", "max_iter", "monitor"}.
    """
    z = op.A_hat_inv(op.F)                                      # for Jt(U^k) only
    Bz = op.B @ z
    eta_0 = None
    for k in range(max_iter):
        Au = op.A @ u
        u_new, p_new, eta, n_inner, t_proj, d_u, w_u, w_p = op.step(u, p, update, Au)
        Ft_U = Au @ z - op.F @ u + p @ Bz - p @ op.G
        J_t = -0.5 * Ft_U - 0.5 * (Au @ w_u - u @ d_u + p @ w_p)  # Jt(U^k) of (8.20)
        du = u_new - u
        cor = float(du @ (op.A @ w_u) - du @ d_u + (p_new - p) @ w_p) if corollary \
            else np.nan                                         # Corollary 8.4
        eta_0 = max(eta, 1e-300) if eta_0 is None else eta_0
        eta_rel = float(np.sqrt(max(eta, 0.0) / eta_0))
        u, p = u_new, p_new
        stop = monitor(OuterStep(k + 1, u, p, eta, eta_rel, cor, float(J_t), n_inner, t_proj)) \
            if monitor else False
        if eta_rel <= eps:                                      # termination (8.25)
            return u, p, k + 1, "converged"
        if stop:
            return u, p, k + 1, "monitor"
    return u, p, max_iter, "max_iter"


# ---------------------------------------------------------------------------
# Variant beyond the thesis: Krylov acceleration of the outer iteration
# ---------------------------------------------------------------------------
def face_cg_variant(op: Alg84, S_hat_columns: Callable, u: np.ndarray, p: np.ndarray,
                    eps: float, max_iter: int, Gamma: float = 1.0,
                    monitor: Callable[[OuterStep], bool] | None = None,
                    S_hat_diagonal: np.ndarray | None = None):
    """Alg. 8.4 accelerated by preconditioned CG on the face of the active set.

    *Not in the thesis* (option ``accelerate="face_cg"``). An MPRGP-like
    outer method for the transformed problem (8.20): after every multiplicative
    Alg. 8.4 step (:meth:`Alg84.step`, which plays the role of MPRGP's
    expansion and proportioning steps) Bramble-Pasciak CG for (8.20) with ``p``
    restricted to the face ``{p > 0}`` and the block preconditioner
    ``diag(gamma_bar (A - A_hat), S_hat_II)`` (8.22), one V-cycle per step
    (the ``u``-part of the residual stays of the form ``(A - A_hat) y``, so
    ``(A - A_hat)^{-1}`` is never needed). The CG phase ends at a step that
    would leave ``p >= 0`` (truncated, feasible step), or when the chopped
    gradient of the zero multipliers outgrows the face residual (factor
    ``Gamma``, MPRGP's proportioning test); the next Alg. 8.4 step then reuses
    the phase's last residual ``(d_u, A-hat^{-1} d_u)``, so a CG phase that ends
    at once costs no V-cycle. Both kinds of step decrease ``Jt`` monotonically.
    ``S_hat_II^{-1}`` is a dense Cholesky factor of the face block of
    ``S_hat`` (``S_hat_columns(I)``; size = number of active constraints);
    ``diag(S_hat)`` (proportioning test) is ``S_hat_diagonal`` or, if None,
    read off ``S_hat_columns`` entry by entry.

    Returns
    -------
    (u, p, k, reason, n_cg) as :func:`augmented_projection_algorithm` plus
    the number of CG steps among the ``k`` outer steps.
    """
    import scipy.linalg as sla
    A, B, F, G, gamma_bar = op.A, op.B, op.F, op.G, op.gamma_bar
    eta_0, k, n_cg = None, 0, 0
    S_diag = S_hat_diagonal
    residual = None     # (d, A-hat^-1 d) at (u, p), left by a CG phase for the next step

    def emit(eta, cor, n_inner, t_proj):
        eta_rel = float(np.sqrt(max(eta, 0.0) / eta_0))
        stop = monitor(OuterStep(k, u, p, eta, eta_rel, cor, np.nan, n_inner, t_proj)) \
            if monitor else False
        return eta_rel, stop

    while k < max_iter:
        # -- one multiplicative step of Alg. 8.4 ---------------------------
        u, p, eta, n_inner, t_proj, *_ = op.step(u, p, "multiplicative", residual=residual)
        eta_0 = max(eta, 1e-300) if eta_0 is None else eta_0
        k += 1
        eta_rel, stop = emit(eta, np.nan, n_inner, t_proj)
        if eta_rel <= eps:
            return u, p, k, "converged", n_cg
        if stop:
            return u, p, k, "monitor", n_cg
        face = p > 0
        residual = None
        if not face.any():
            continue
        # -- CG on the face {p > 0} ------------------------------------------
        I = np.flatnonzero(face)
        S_II = S_hat_columns(I)[I]
        chol = sla.cho_factor(0.5 * (S_II + S_II.T))
        if S_diag is None:
            S_diag = np.array([S_hat_columns(np.array([j]))[j, 0] for j in range(len(p))])
        d = F - A @ u - B.T @ p
        y = op.A_hat_inv(d)
        Ay = A @ y
        r_p = B @ y - (G - B @ u + op.Cp(p))
        P_u = AP_u = P_p = None
        rz_old = None
        while k < max_iter:
            residual = (d, y)
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
            v = op.A_hat_inv(q)
            BPv = B @ v - B @ P_u + op.Cp(P_p)
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
            residual = (d, y)
            k, n_cg = k + 1, n_cg + 1
            eta_rel, stop = emit(rz + eta_beta, step * rz, 0, 0.0)
            if eta_rel <= eps and eta_beta <= eps ** 2 * eta_0:
                return u, p, k, "converged", n_cg
            if stop:
                return u, p, k, "monitor", n_cg
            if alpha_f <= alpha:
                break                                    # the face shrinks: back to Alg. 8.4
    return u, p, max_iter, "max_iter", n_cg


# ---------------------------------------------------------------------------
# Infeasibility: the dual ray
# ---------------------------------------------------------------------------
#: A step's multiplier increment ``dp`` is a candidate Farkas direction when its forces
#: ``||B' dp^+||`` are at most this beside ``||B||_F ||dp^+||`` and its gap ``g' dp^+``
#: is negative: on an infeasible problem ``p^k`` runs off along a ray ``z >= 0`` with
#: ``B'z = 0``, ``g'z < 0`` (the dual is unbounded) and the increments line up with it.
FARKAS_RTOL = 1e-6

#: At most this many rows (the candidate's support) are put to the exact test, a dense
#: Gram matrix of the rows (:func:`solvers.kernels.cholesky.row_basis`).
FARKAS_ROWS = 2000


@dataclass
class DualRay:
    """The infeasibility test of :func:`solve`, fed each outer step's multipliers.

    A candidate (:data:`FARKAS_RTOL`) is put to the exact test of the direct solvers:
    :func:`solvers.kernels.cholesky.row_basis` on the Gram matrix of its support's rows
    with their gaps, which raises the Farkas certificate of rows no ``u`` satisfies. A
    candidate the test does not confirm raises the bar: the next must be twice as
    aligned, so a feasible problem pays for a few tests at most.
    """

    qp: ContactQP
    p: np.ndarray
    bar: float = FARKAS_RTOL

    def __post_init__(self):
        self.norm_B = float(np.sqrt(self.qp.B.multiply(self.qp.B).sum()))

    def certificate(self, p_new: np.ndarray) -> str | None:
        """The Farkas certificate (message) if the step from ``self.p`` to ``p_new``
        points along a confirmed ray of an infeasible problem, else None."""
        qp = self.qp
        z = np.maximum(p_new - self.p, 0.0)
        self.p = p_new
        if qp.C is not None or not z.any() or float(qp.g @ z) >= 0.0:
            return None
        alignment = float(np.linalg.norm(qp.B.T @ z)) / (self.norm_B * float(np.linalg.norm(z)))
        if alignment > self.bar:
            return None
        self.bar = 0.5 * alignment
        rows = np.flatnonzero(z > FARKAS_RTOL * z.max())
        if rows.size > FARKAS_ROWS:
            return None
        B_I = qp.B[rows]
        K = (B_I @ B_I.T).toarray()
        try:
            row_basis(0.5 * (K + K.T), np.asarray(qp.g)[rows], labels=rows)
        except InfeasibleError as err:
            return str(err)
        except RuntimeError:                # dependent rows whose exchanges cycle: no proof
            return None
        return None


# ---------------------------------------------------------------------------
# Setup and the registered solve()
# ---------------------------------------------------------------------------
def theorem_8_8_alpha(gamma_bar: float) -> tuple[float, float]:
    """Spectral constants of (8.22) vs (8.20) for ``S-hat = S_in`` (Theorem 8.8)."""
    r = np.sqrt(max(0.0, 1.0 - 1.0 / gamma_bar))
    return 1.0 - r, 1.0 + r


def make_projection(projection: Component, S_hat: SchurPreconditioner, tau_2_hat: float = 1.0):
    """The approximate projection ``project(d, p_k) -> (p_{k+1}, n_inner)``.

    ``richardson``: Alg. 8.3 with ``tau_2 = tau_2_hat / lambda_max(S-hat)`` and
    ``n_i = ceil(c 2 kappa(S-hat) / tau_2_hat)`` (8.15), ``c = n_i_factor``,
    i.e. ``rho_P <= exp(-c)``. ``mprgp``: MPRGP with ``alpha_bar = 1/lambda_max``
    stopped at the relative projected-gradient reduction ``rtol``.

    Returns
    -------
    (project, n_i) with ``n_i`` the fixed step count of Alg. 8.3 (None for MPRGP).
    """
    lam_max = S_hat.lam_max
    o = projection.options
    if projection.kind == "richardson":
        n_i = int(min(o["max_steps"], np.ceil(o["n_i_factor"] * 2.0 * S_hat.kappa / tau_2_hat)))
        tau_2 = tau_2_hat / lam_max
        return (lambda d, p: projected_richardson(S_hat, d, p, tau_2, n_i)), n_i
    if projection.kind == "mprgp":
        return (lambda d, p: mprgp(S_hat, d, p, 1.0 / lam_max, o["rtol"], o["max_steps"])), None
    raise ValueError(f"unknown projection {projection.kind!r}; allowed: mprgp, richardson")


def balanced_projection(projection: Component, S_hat: SchurPreconditioner) -> Callable:
    """``project_balanced(d, p_k, G, e) -> (p_{k+1}, mu, n_inner)``: (8.24) with the floating
    bodies' equilibrium ``G q = e`` (:func:`smalbe`, MPRGP inside with the ``mprgp``
    projection's ``rtol`` and ``max_steps``; Alg. 8.3 has no equality and is refused)."""
    o = projection.options
    return lambda d, p, G, e: smalbe(S_hat, G, e, d, p, S_hat.lam_max, o["rtol"], o["max_steps"])


#: ``schur="auto"`` keeps the multilevel ``S-hat`` while its measured
#: ``kappa(S-hat^{-1} S_in)`` is at most this, and takes ``S_in`` itself beyond. The
#: multilevel operator models ``S`` as an H^{-1/2} norm; a locking P1 material stiffens
#: ``S`` on the fine surface modes, and the ratio grows with nu. The V-cycles of a whole
#: solve cross over near 6 (``S_in`` costs an ``A-hat`` per inner step). The stabilised
#: problem's operator (:func:`solvers.kernels.schur.stabilised_schur_apply`) starts higher
#: at nu = 0.3 and still wins against the assembled ``S_in``, whose assembly grows like
#: m N, so its limit is twice the nodal one (the measurements:
#: docs/guide/measurements.md).
SCHUR_KAPPA_LIMIT = {"nodal": 6.0, "stabilised": 12.0}

#: ... and assembles ``S_in`` (``m`` products with ``A-hat``, then dense products) up to
#: this many constraints: a matrix-free ``S_in`` costs an ``A-hat`` per inner step, and a
#: solve takes hundreds to thousands of them (docs/guide/measurements.md).
ASSEMBLE_LIMIT = 400


def resolve_kinds(qp: ContactQP, ahat: Component, schur: Component) -> tuple[str, str]:
    """The A-hat and S-hat kinds ``auto`` stands for on this problem, before measuring
    (:func:`solve` may still replace an automatic multilevel ``S-hat`` by ``S_in``,
    :data:`SCHUR_KAPPA_LIMIT`)."""
    a = vcycle_kind(qp, ahat.kind)
    s = schur.kind
    if s == "auto":
        s = "multilevel" if (qp.multilevel.surface is not None and qp.m > 2) else "inexact"
    return a, s


def solve(qp: ContactQP, tol: float, max_iter: int, time_limit: float | None,
          u0: np.ndarray | None, p0: np.ndarray | None, opts: Options,
          callback: Callable | None = None) -> SolveResult:
    """Solve ``qp`` by Alg. 8.4 (see the module docstring and :data:`SOLVER` for ``opts``).

    ``callback(step: OuterStep) -> bool`` (Python only, not a registry option)
    is called after each outer step; True stops the run (status ``max_iter``
    unless (8.25) is met). Measurement scripts use it for error-vs-time curves.

    Returns
    -------
    SolveResult
        ``claimed_status`` ``converged`` when the verified KKT residual
        (``stop="kkt"``, the default) or (8.25) (``stop="estimate"``) meets the
        tolerance; ``stats`` has the columns of Table 9.1 and the setup
        details; ``history`` per outer step: ``energy`` J(u^k) (NaN with
        ``diagnostics=False``, as is ``corollary_8_4``),
        ``J_transformed``, ``kkt_max``, ``eta_rel``, ``corollary_8_4``,
        ``n_inner``, ``time``.
    """
    t_start = time.perf_counter()
    deadline = None if time_limit is None else t_start + time_limit
    if qp.m == 0:
        raise ValueError("augmented projection needs at least one constraint")
    ahat_kind, schur_kind = resolve_kinds(qp, opts.ahat, opts.schur)
    a, s = opts.ahat.options, opts.schur.options
    coarse = floating_coarse_space(qp)
    if coarse is not None and opts.projection.kind != "mprgp":
        raise ParameterError("parameter 'projection': 'richardson' (Alg. 8.3) is not allowed "
                             "on a problem with floating bodies (it has no equality "
                             "constraint); allowed: mprgp (SMALBE)")
    if coarse is not None and opts.accelerate == "face_cg":
        raise ParameterError("parameter 'accelerate': 'face_cg' is not allowed on a problem "
                             "with floating bodies (no coarse space in its CG phase); "
                             "allowed: none")
    A_hat_inv = scaled_vcycle(qp.A, ahat_kind, qp.multilevel, qp.dim, qp.free_dofs,
                              seed=opts.seed, near_kernel=None if coarse is None else coarse.R,
                              **a)
    gamma_bar = A_hat_inv.gamma_bar
    S_hat = build_schur(schur_kind, qp, A_hat_inv, s["lanczos_steps"], opts.seed)
    limit = SCHUR_KAPPA_LIMIT["nodal" if qp.stabilisation is None else "stabilised"]
    if opts.schur.kind == "auto" and S_hat.kappa_Sin > limit:
        # the sparse S-hat has lost its equivalence (locking, a poor surface hierarchy):
        # S_in itself, assembled once when that costs fewer A-hat products than the
        # inner steps would
        schur_kind = "inexact_assembled" if qp.m <= ASSEMBLE_LIMIT else "inexact"
        S_hat = build_schur(schur_kind, qp, A_hat_inv, s["lanczos_steps"], opts.seed)
    alpha_low, alpha_bar = theorem_8_8_alpha(gamma_bar)
    tau = opts.tau
    if tau <= 0.0:  # Sect. 8.5: tau = 1/alpha_bar; block Gauss-Seidel (multiplicative): 1
        tau = 1.0 / alpha_bar if opts.update == "additive" else 1.0
    project, n_i_fixed = make_projection(opts.projection, S_hat)
    # Theorem 8.2 rate (known rho_P only for Alg. 8.3, where rho_P <= exp(-c)).
    mu = S_hat.ritz_Sin[0] / S_hat.scale if S_hat.name in ("jacobi", "multilevel") else 1.0
    richardson = opts.projection.kind == "richardson"
    rho_P = np.exp(-opts.projection.options["n_i_factor"]) if richardson else np.nan
    rho = 1.0 - 0.5 * tau * alpha_low * mu * (1.0 - rho_P)
    if opts.accelerate == "face_cg" and opts.update != "multiplicative":
        raise ValueError("accelerate='face_cg' uses the multiplicative update")
    op = Alg84(qp.A, qp.B, qp.C, qp.f, qp.g, A_hat_inv, S_hat, gamma_bar, tau, project,
               coarse, None if coarse is None else balanced_projection(opts.projection, S_hat))
    setup_time = time.perf_counter() - t_start
    vcycles_setup = A_hat_inv.n_applications

    u = np.zeros(qp.n) if u0 is None else np.array(u0, dtype=float)
    p = np.zeros(qp.m) if p0 is None else np.maximum(np.asarray(p0, dtype=float), 0.0)
    eps_eff = opts.eps if opts.eps > 0 else tol
    history = {k: [] for k in ("energy", "J_transformed", "kkt_max", "eta_rel", "eta",
                               "corollary_8_4", "n_inner", "t_proj", "time")}
    t_solve = time.perf_counter()
    state = {"reason": None, "next_check": tol, "infeasible": None}
    stop_kkt = opts.stop == "kkt"
    ray = DualRay(qp, p)

    def monitor(step: OuterStep) -> bool:
        history["energy"].append(qp.energy(step.u) if opts.diagnostics else np.nan)
        history["J_transformed"].append(step.J_transformed)
        history["eta_rel"].append(step.eta_rel)
        history["eta"].append(step.eta)
        history["corollary_8_4"].append(step.corollary_8_4)
        history["n_inner"].append(step.n_inner)
        history["t_proj"].append(step.t_proj)
        kmax = kkt_residuals(qp, step.u, step.p).max if (opts.record_kkt or stop_kkt) else np.nan
        history["kkt_max"].append(kmax)
        history["time"].append(time.perf_counter() - t_solve)
        if callback is not None and callback(step):
            state["reason"] = "callback"
            return True
        state["infeasible"] = ray.certificate(step.p)
        if state["infeasible"] is not None:
            state["reason"] = "infeasible"
            return True
        if stop_kkt and kmax <= state["next_check"]:
            # the verification's own test: KKT and the certified energy bound (one to
            # three linear solves, so only when the residuals have fallen again)
            if certify(qp, step.u, step.p, tol).meets(tol):
                state["reason"] = "kkt"
                return True
            state["next_check"] = kmax / 4
        if deadline is not None and time.perf_counter() > deadline:
            state["reason"] = "time_limit"
            return True
        return False

    eps_run = 0.0 if stop_kkt else eps_eff
    n_cg = 0
    if opts.accelerate == "face_cg":
        # the sparse kinds know their diagonal; otherwise face_cg reads it off when needed
        cheap_diagonal = S_hat.diagonal() if S_hat.diagonal_unscaled is not None else None
        u, p, k, reason, n_cg = face_cg_variant(op, S_hat.columns, u, p, eps_run, max_iter,
                                                monitor=monitor,
                                                S_hat_diagonal=cheap_diagonal)
    else:
        u, p, k, reason = augmented_projection_algorithm(op, u, p, eps_run, max_iter,
                                                         opts.update, monitor, opts.diagnostics)
    solve_time = time.perf_counter() - t_solve
    if reason == "converged" or state["reason"] == "kkt":
        status = "converged"
        message = (f"(8.25) estimate reduced by {history['eta_rel'][-1]:.2e} <= eps {eps_eff:.1e}"
                   if reason == "converged" else f"verified KKT max and certified energy "
                   f"bound <= {tol:.1e}") \
            + f" after {k} outer steps"
    elif state["reason"] == "infeasible":
        status, message = "failed", f"outer step {k}: {state['infeasible']}"
    elif state["reason"] == "time_limit":
        status, message = "time_limit", f"time limit {time_limit:g} s reached after {k} outer steps"
    elif state["reason"] == "callback":
        status, message = "max_iter", f"stopped by the callback after {k} outer steps"
    else:
        status = "max_iter"
        message = (f"{'KKT max / certified bound' if stop_kkt else '(8.25)'} not met after "
                   f"{k} outer steps")
    n_vcycles, t_vcycle = A_hat_inv.n_applications - vcycles_setup, A_hat_inv.time
    kappa_SinvS = np.nan
    if opts.kappa_exact:  # diagnostic, after the timed solve (Sect. 8.6: kappa(S-hat^-1 S))
        kappa_SinvS = kappa_schur_exact(qp, A_hat_inv, S_hat, max(s["lanczos_steps"], 20))[0]
    n_inner = np.asarray(history["n_inner"], dtype=float)
    stats = {
        "N": qp.n_nodes, "NC": qp.m,
        "n_outer": k, "n_inner_mean": float(n_inner.mean()) if n_inner.size else 0.0,
        "n_inner_total": int(n_inner.sum()),
        "t_solve": solve_time, "t_setup": setup_time, "t_proj": float(np.sum(history["t_proj"])),
        "t_vcycle": t_vcycle, "n_vcycles": n_vcycles,
        "t_ahat_setup": A_hat_inv.setup_time, "t_ahat_lanczos": A_hat_inv.lanczos_time,
        "t_shat_setup": S_hat.setup_time,
        "ahat_kind": ahat_kind, "schur_kind": schur_kind,
        "tau": tau, "eps": eps_eff, "n_cg": n_cg,
        "gamma_bar": gamma_bar, "ritz_AhatA_min": A_hat_inv.ritz[0],
        "ritz_AhatA_max": A_hat_inv.ritz[1], "amg_levels": len(A_hat_inv.ml.levels),
        "ahat_degree": A_hat_inv.degree,
        "kappa_vcycle": A_hat_inv.ritz_vcycle[1] / A_hat_inv.ritz_vcycle[0],
        "operator_complexity": A_hat_inv.operator_complexity(),
        "smoothing_work": A_hat_inv.smoothing_work(), "deep_work": A_hat_inv.deep_work(),
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

    ``u0 = P u_{L-1} + P_D u_fixed`` (:func:`problems.qp.prolongate_displacement`: the
    coarse displacement interpolated with its prescribed values);
    ``p0 = M_L Prolongate(M_{L-1}^{-1} p_{L-1})``: the pressure
    ``p / contact mass`` is a grid function on the constrained surface,
    prolongated with the surface prolongation of the last mesh level and
    multiplied by the fine lumped mass, so ``p0 >= 0``; on the stabilised problem
    (Sect. 7.5) the reverse rows' pressure as well
    (:func:`problems.fem.adaptive.prolongate_solution`, which this is on uniform levels).

    Parameters
    ----------
    qp_coarse, qp_fine : ContactQP
        Consecutive levels of one scene (``qp_fine`` carries the prolongations).
    result_coarse : SolveResult or (u, p) tuple

    Returns
    -------
    (u0, p0)
    """
    u_c, p_c = (result_coarse.u, result_coarse.p) if hasattr(result_coarse, "u") else result_coarse
    return prolongate_solution(qp_coarse, u_c, p_c, qp_fine)


def supports(qp: ContactQP) -> tuple[bool, str]:
    """Floating bodies are treated by their coarse space (:class:`FloatingCoarseSpace`),
    which needs every floating mode to meet the contact: ``G = R'B'`` of full row rank.
    A mode no constraint touches is held by the springs alone, and Alg. 8.4 would
    iterate on a system ~1e9 times worse conditioned: refused at once. Two-pass rows
    (hard reverse rows) are refused too: where nodes of the two surfaces coincide they
    repeat constrained rows, so ``S = B A^-1 B'`` and its ``S-hat`` are singular, which
    the projected Richardson iteration on the transformed system needs definite."""
    if qp.stabilisation is not None and qp.stabilisation.hard:
        return False, ("two-pass constraints (hard reverse rows): S-hat over both surfaces' "
                       "rows is singular where their nodes coincide (dependent rows)")
    R = floating_modes(qp)
    k = R.shape[1]
    if k:
        sv = np.linalg.svd(np.asarray((qp.B @ R).T), compute_uv=False)
        scale = float(np.sqrt(qp.B.multiply(qp.B).sum()))          # ||B||_F
        if qp.m == 0 or sv.size < k or sv[-1] <= 1e-8 * max(scale, 1e-300):
            return False, (f"{k} floating rigid mode(s), and the contact constraints do "
                           "not hold all of them (R'B' rank-deficient)")
    return True, ""


SOLVER = SolverSpec(
    name="augmented_projection",
    summary="Hackl's augmented projection (Alg. 8.4): projected preconditioned Richardson on the "
            "Bramble-Pasciak-transformed problem, multigrid A-hat, sparse S-hat, MPRGP projection",
    solve=solve,
    parameters=(
        AHAT_SCALED,
        ComponentParameter(
            "schur", "auto", {k: (Parameter("lanczos_steps", 24, "Lanczos steps for the spectral bounds", low=5,
                                        kind=int),) for k in
                              ("auto", "multilevel", "inexact", "inexact_assembled", "jacobi")},
            "S-hat: multilevel surface operator (O(N^C)), inexact S_in (matrix-free), "
            "inexact_assembled (N^C V-cycles) or jacobi B diag(A)^-1 B'; auto = multilevel "
            "if the scene supplies its surface hierarchy and kappa(S-hat^-1 S_in) <= 6, "
            "else inexact (assembled up to 400 constraints)"),
        ComponentParameter(
            "projection", "mprgp",
            {"mprgp": (Parameter("rtol", 0.1, "relative projected-gradient reduction", low=0.0,
                                 high=1.0, low_open=True),
                       Parameter("max_steps", 2000, "cap on inner steps", low=1, kind=int)),
             "richardson": (Parameter("n_i_factor", 1.0, "c in n_i = c 2 kappa(S-hat) (8.15)",
                                      low=0.0, low_open=True),
                            Parameter("max_steps", 2000, "cap on inner steps", low=1, kind=int))},
            "approximate projection (8.24): MPRGP (Sect. 8.6) or projected Richardson "
            "(Alg. 8.3, n_i by (8.15))"),
        Parameter("update", "multiplicative", "u-update of Alg. 8.4",
                  choices=("multiplicative", "additive")),
        Parameter("stop", "kkt", "stop when the verification passes: KKT residuals and the "
                  "certified energy bound <= tol (kkt), or by the thesis's estimate (8.25) "
                  "<= eps (estimate)", choices=("kkt", "estimate")),
        Parameter("eps", 0.0, "relative tolerance of (8.25) for stop=estimate; 0 = tol",
                  low=0.0, high=1.0),
        Parameter("tau", 0.0, "relaxation; 0 = auto: 1/alpha_bar (Theorem 8.8) for the additive, "
                  "1 for the multiplicative update", low=0.0, high=2.0),
        Parameter("accelerate", "none", "beyond the thesis: 'face_cg' = Bramble-Pasciak CG on the "
                  "face of the active set between Alg. 8.4 steps", choices=("none", "face_cg")),
        Parameter("kappa_exact", False, "also estimate kappa(S-hat^-1 S), S = B A^-1 B' (costly)"),
        Parameter("record_kkt", True, "verified KKT residual in the history at every step"),
        Parameter("diagnostics", True, "J(u^k) and Corollary 8.4's quantity in the history at "
                  "every step (two products with A per step, not part of Alg. 8.4; timing "
                  "studies turn them off)"),
        Parameter("seed", 0, "Lanczos start vectors", low=0, kind=int),
    ),
    presets=preset_texts("stop when the verified KKT max <="),
    default_max_iter=2000,
    role=Role.THESIS,
    handles_C=True,
    supports=supports,
    friction_reason=(
        "not built: Tresca's tangential multipliers would join p in the dual as the box "
        "|lambda_t| <= s, still a trivial projection (Remark 8.5), but S-hat, its "
        "Lanczos bounds and the floating coarse space are built over the normal rows only"),
)


@dataclass(frozen=True)
class Variant:
    """A named configuration of this solver, as the studies run it.

    ``thesis`` tells whether it stays Alg. 8.4 (with the thesis's or another
    A-hat/S-hat pair) or goes beyond it (``face_cg``); ``nested`` adds the
    initial guess of Alg. 8.5 from the two coarser levels.
    """

    summary: str
    options: dict
    nested: bool = False
    thesis: bool = True


_BEST = {"ahat": "gmg", "schur": "multilevel", "projection": "mprgp", "update": "multiplicative"}

#: Named configurations of Alg. 8.4 (the augmented-projection study's ``configs``).
VARIANTS = {
    "alg84": Variant("Alg. 8.4 as written: geometric-multigrid A-hat, multilevel S-hat, "
                     "MPRGP projection, multiplicative update", _BEST),
    "additive": Variant("Alg. 8.4 with the additive update", {**_BEST, "update": "additive"}),
    "richardson": Variant("Alg. 8.4 with the projection of Alg. 8.3 (n_i by (8.15))",
                          {**_BEST, "projection": "richardson"}),
    "sa": Variant("Alg. 8.4 with pyamg SA as A-hat", {**_BEST, "ahat": "sa"}),
    "thesis_Sin": Variant("Alg. 8.4 with the thesis's inexact Schur complement S_in",
                          {**_BEST, "schur": "inexact"}),
    "jacobi": Variant("Alg. 8.4 with the Jacobi-type S-hat B diag(A)^-1 B'",
                      {**_BEST, "schur": "jacobi"}),
    "nested": Variant("Alg. 8.4 with the nested initial guess of Alg. 8.5", _BEST, nested=True),
    "face_cg": Variant("beyond the thesis: Alg. 8.4 steps + Krylov (CG) steps on the active face",
                       {**_BEST, "accelerate": "face_cg"}, thesis=False),
    "nested_face_cg": Variant("beyond the thesis: face_cg with the nested initial guess of "
                              "Alg. 8.5", {**_BEST, "accelerate": "face_cg"}, nested=True,
                              thesis=False),
}
