"""Preconditioners for the augmented projection method (thesis Sects. 8.3-8.6).

Machinery only (no ``SOLVER``): :mod:`solvers.augmented_projection` builds on it.

* ``A-hat`` (8.18): one symmetric V-cycle per application, either pyamg smoothed
  aggregation with the rigid-body modes of each body as near-null space, or
  geometric multigrid on the refinement hierarchy (``qp.multilevel``) with
  Galerkin coarse operators. :func:`scaled_vcycle` scales it by Lanczos
  (Remark 8.14) so that ``A-hat < A <= gamma_bar A-hat``.
* ``S-hat`` (Sect. 8.5, Remarks 8.11, 8.12, 8.15): the inexact Schur complement
  ``S_in = B A-hat^{-1} B^T + C`` (matrix-free, one V-cycle per product, or
  assembled), the Jacobi-type ``B diag(A)^{-1} B^T + C`` and a multilevel
  ``S-hat`` for the order -1 operator ``S = B A^{-1} B^T`` on the 2D contact
  surface (1D surface mesh), whose product costs O(N^C).
* :func:`lanczos_extremes`: Ritz estimates of extreme eigenvalues of a
  symmetric pencil (Remark 8.14, kappa(S-hat) of Table 9.1).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

#: Safety factors applied to Ritz values (Ritz values lie inside the spectrum).
LOW_SAFETY = 0.9
HIGH_SAFETY = 1.05

Apply = Callable[[np.ndarray], np.ndarray]


# ---------------------------------------------------------------------------
# Lanczos (Remark 8.14)
# ---------------------------------------------------------------------------
def lanczos_extremes(apply_K: Apply, n: int, steps: int = 30, apply_Minv: Apply | None = None,
                     seed: int = 0, tol: float = 1e-10) -> tuple[float, float]:
    """Ritz estimates of the extreme eigenvalues of ``K x = lambda M x``.

    Preconditioned Lanczos in the ``M`` inner product (only ``M^{-1}`` is
    applied), without re-orthogonalisation (extreme Ritz values converge first;
    spurious copies do not matter for extremes).

    Parameters
    ----------
    apply_K, apply_Minv : callables
        Symmetric positive (semi)definite ``K`` and SPD ``M^{-1}`` (identity if None).
    n : int
        Dimension.
    steps : int
        Lanczos steps (one ``K`` and one ``M^{-1}`` product each).
    seed : int
        Random start vector.

    Returns
    -------
    (lambda_min, lambda_max) : floats
        Ritz values; ``lambda_min`` over-, ``lambda_max`` under-estimates.
    """
    Minv = apply_Minv or (lambda x: x)
    r = np.random.default_rng(seed).standard_normal(n)
    z = Minv(r)
    beta0 = np.sqrt(max(float(r @ z), 0.0))
    q, Mq = z / beta0, r / beta0
    Mq_prev, beta = np.zeros(n), 0.0
    alphas, betas = [], []
    for _ in range(min(steps, n)):
        w = apply_K(q)
        alpha = float(q @ w)
        alphas.append(alpha)
        w = w - alpha * Mq - beta * Mq_prev
        z = Minv(w)
        beta_new = np.sqrt(max(float(w @ z), 0.0))
        if beta_new <= tol * max(abs(alpha), 1e-300):
            break
        betas.append(beta_new)
        Mq_prev = Mq
        q, Mq, beta = z / beta_new, w / beta_new, beta_new
    k = len(alphas)
    ritz = sla.eigvalsh_tridiagonal(np.array(alphas), np.array(betas[:k - 1])) if k > 1 \
        else np.array(alphas)
    return float(ritz[0]), float(ritz[-1])


# ---------------------------------------------------------------------------
# A-hat: one symmetric V-cycle (8.18)
# ---------------------------------------------------------------------------
_SMOOTHERS = {
    "symmetric_gs": ("gauss_seidel", {"sweep": "symmetric", "iterations": 1}),
    "block_gs": ("block_gauss_seidel", {"sweep": "symmetric", "iterations": 1}),
    "jacobi": ("jacobi", {"omega": 0.6, "iterations": 2}),
}


def _as_blocked(A: sp.spmatrix, dim: int, free_dofs: np.ndarray | None):
    """``A`` as BSR with node blocks when the free DOFs come in whole nodes."""
    n = A.shape[0]
    if free_dofs is None or n % dim:
        return sp.csr_matrix(A)
    fd = np.asarray(free_dofs).reshape(-1, dim)
    if np.all(fd[:, 0] % dim == 0) and np.all(np.diff(fd, axis=1) == 1):
        return sp.bsr_matrix(A, blocksize=(dim, dim))
    return sp.csr_matrix(A)


def sa_hierarchy(A: sp.spmatrix, near_null: np.ndarray | None, dim: int = 2,
                 free_dofs: np.ndarray | None = None, smoother: str = "symmetric_gs",
                 max_coarse: int = 500):
    """pyamg smoothed aggregation with ``near_null`` (rigid-body modes per body).

    Node-blocked (BSR) when the free DOFs come in whole nodes; symmetric
    smoothing so that one V-cycle is an SPD operator.
    """
    import pyamg
    Ab = _as_blocked(A, dim, free_dofs)
    sm = _SMOOTHERS[smoother]
    if sm[0] == "block_gauss_seidel" and not sp.isspmatrix_bsr(Ab):
        sm = _SMOOTHERS["symmetric_gs"]
    B = None if near_null is None else np.asarray(near_null, dtype=float)
    return pyamg.smoothed_aggregation_solver(
        Ab, B=B, max_coarse=max_coarse, presmoother=sm, postsmoother=sm,
        improve_candidates=None, coarse_solver="splu")


def geometric_hierarchy(A: sp.spmatrix, prolongations: list, smoother: str = "symmetric_gs"):
    """Geometric multigrid on the refinement hierarchy, Galerkin coarse operators.

    Parameters
    ----------
    prolongations : list of sparse
        ``P_k`` maps level ``k`` to ``k+1`` on the free DOFs; ``P[-1]`` ends at ``A``.
    """
    from pyamg.multilevel import MultilevelSolver
    from pyamg.relaxation.smoothing import change_smoothers
    levels = []
    A_k = sp.csr_matrix(A)
    for P in reversed(prolongations):
        lvl = MultilevelSolver.Level()
        lvl.A, lvl.P, lvl.R = A_k, sp.csr_matrix(P), sp.csr_matrix(P.T)
        levels.append(lvl)
        A_k = sp.csr_matrix(lvl.R @ A_k @ lvl.P)
    coarse = MultilevelSolver.Level()
    coarse.A = A_k
    levels.append(coarse)
    ml = MultilevelSolver(levels, coarse_solver="splu")
    sm = _SMOOTHERS[smoother]
    if sm[0] == "block_gauss_seidel":
        sm = _SMOOTHERS["symmetric_gs"]
    change_smoothers(ml, presmoother=sm, postsmoother=sm)
    return ml


def _vcycle(ml, lvl: int, b: np.ndarray) -> np.ndarray:
    """One V-cycle on level ``lvl`` of a pyamg hierarchy, zero initial guess.

    Same operations as pyamg's cycle, without its residual norms (which cost
    as much as a smoothing sweep here).
    """
    levels = ml.levels
    if len(levels) == 1:
        return ml.coarse_solver(levels[0].A, b)
    level = levels[lvl]
    x = np.zeros_like(b)
    level.presmoother(level.A, x, b)
    coarse_b = level.R @ (b - level.A @ x)
    if lvl == len(levels) - 2:
        coarse_x = ml.coarse_solver(levels[-1].A, coarse_b)
    else:
        coarse_x = _vcycle(ml, lvl + 1, coarse_b)
    x += level.P @ coarse_x
    level.postsmoother(level.A, x, b)
    return x


@dataclass
class ScaledVCycle:
    """``A-hat^{-1}`` = one V-cycle divided by ``gamma_low`` (Remark 8.14).

    After scaling ``A-hat < A <= gamma_bar A-hat`` (8.18) with
    ``gamma_bar = gamma_high / gamma_low``.
    """

    kind: str
    ml: object
    gamma_low: float
    gamma_high: float
    ritz: tuple
    setup_time: float
    lanczos_time: float
    n_applications: int = 0
    time: float = 0.0

    @property
    def gamma_bar(self) -> float:
        return self.gamma_high / self.gamma_low

    def raw(self, r: np.ndarray) -> np.ndarray:
        """One unscaled V-cycle with zero start (V(1,1), symmetric smoothing)."""
        t0 = time.perf_counter()
        x = _vcycle(self.ml, 0, np.asarray(r, dtype=float))
        self.time += time.perf_counter() - t0
        self.n_applications += 1
        return x

    def __call__(self, r: np.ndarray) -> np.ndarray:
        """``A-hat^{-1} r`` (scaled)."""
        return self.raw(r) / self.gamma_low

    def operator_complexity(self) -> float:
        return float(self.ml.operator_complexity())


def scaled_vcycle(A: sp.spmatrix, kind: str = "sa", multilevel: dict | None = None, dim: int = 2,
                  free_dofs: np.ndarray | None = None, smoother: str = "symmetric_gs",
                  max_coarse: int = 500, lanczos_steps: int = 20, seed: int = 0) -> ScaledVCycle:
    """Build ``A-hat`` and scale it by Lanczos so that (8.18) holds.

    Parameters
    ----------
    kind : {"sa", "gmg"}
        pyamg smoothed aggregation (rigid-body modes as near-null space) or
        geometric multigrid on ``multilevel['prolongations']``.
    multilevel : dict
        ``qp.multilevel``.
    lanczos_steps : int
        Steps of preconditioned Lanczos for ``lambda(A-hat^{-1} A)``.

    Returns
    -------
    ScaledVCycle
        With ``gamma_low = LOW_SAFETY * ritz_min`` and
        ``gamma_high = HIGH_SAFETY * ritz_max``.
    """
    multilevel = multilevel or {}
    t0 = time.perf_counter()
    if kind == "sa":
        ml = sa_hierarchy(A, multilevel.get("rigid_body_modes"), dim, free_dofs, smoother, max_coarse)
    elif kind == "gmg":
        ml = geometric_hierarchy(A, list(multilevel.get("prolongations") or []), smoother)
    else:
        raise ValueError(f"unknown A-hat kind {kind!r}; allowed: sa, gmg")
    setup = time.perf_counter() - t0
    vc = ScaledVCycle(kind, ml, 1.0, 1.0, (np.nan, np.nan), setup, 0.0)
    t0 = time.perf_counter()
    lo, hi = lanczos_extremes(lambda x: A @ x, A.shape[0], lanczos_steps, vc.raw, seed)
    vc.lanczos_time = time.perf_counter() - t0
    vc.ritz = (lo, hi)
    vc.gamma_low, vc.gamma_high = LOW_SAFETY * lo, HIGH_SAFETY * hi
    return vc


# ---------------------------------------------------------------------------
# S-hat: Schur-complement preconditioners
# ---------------------------------------------------------------------------
@dataclass
class SchurPreconditioner:
    """``S-hat`` as a product ``q -> S-hat q`` (never its inverse in Alg. 8.4).

    Attributes
    ----------
    name : str
    apply_unscaled : callable
    scale : float
        ``S-hat = scale * apply_unscaled``; chosen so that ``S_in <= S-hat``.
    lam_min, lam_max : float
        Ritz values of ``S-hat`` (Euclidean), for (8.15) and MPRGP's step.
    kappa_Sin : float
        ``kappa(S-hat^{-1} S_in)`` (1 for ``S-hat = S_in``).
    """

    name: str
    apply_unscaled: Apply
    m: int
    scale: float = 1.0
    lam_min: float = np.nan
    lam_max: float = np.nan
    kappa_Sin: float = 1.0
    ritz_Sin: tuple = (1.0, 1.0)
    setup_time: float = 0.0
    n_applications: int = 0
    info: dict = field(default_factory=dict)

    def __call__(self, q: np.ndarray) -> np.ndarray:
        self.n_applications += 1
        return self.scale * self.apply_unscaled(q)

    @property
    def kappa(self) -> float:
        """kappa(S-hat) of Table 9.1 (Euclidean, Lanczos)."""
        return self.lam_max / self.lam_min

    def dense(self) -> np.ndarray:
        """Explicit ``S-hat`` (m products; for setup and tests, small m)."""
        I = np.eye(self.m)
        M = np.column_stack([self.scale * self.apply_unscaled(I[:, j]) for j in range(self.m)])
        return 0.5 * (M + M.T)


def surface_order(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Order the constrained nodes along a (2D) contact surface.

    Projects the coordinates on their principal axis; fine for a surface that
    is a graph over a line (both 2D scenes here).

    Returns
    -------
    order : int array
        ``points[order]`` runs along the surface.
    s : float array
        Arc length of the ordered nodes, starting at 0.
    """
    pts = np.asarray(points, dtype=float)
    c = pts - pts.mean(axis=0)
    axis = np.linalg.svd(c, full_matrices=False)[2][0]
    order = np.argsort(c @ axis, kind="stable")
    seg = np.linalg.norm(np.diff(pts[order], axis=0), axis=1)
    return order, np.concatenate([[0.0], np.cumsum(seg)])


def _linear_interpolation(s_coarse: np.ndarray, s_fine: np.ndarray) -> sp.csr_matrix:
    """Piecewise-linear prolongation on a 1D mesh (coarse nodes are fine nodes)."""
    j = np.clip(np.searchsorted(s_coarse, s_fine, side="right") - 1, 0, len(s_coarse) - 2)
    t = (s_fine - s_coarse[j]) / (s_coarse[j + 1] - s_coarse[j])
    t = np.clip(t, 0.0, 1.0)
    rows = np.repeat(np.arange(len(s_fine)), 2)
    cols = np.column_stack([j, j + 1]).ravel()
    vals = np.column_stack([1 - t, t]).ravel()
    P = sp.csr_matrix((vals, (rows, cols)), shape=(len(s_fine), len(s_coarse)))
    P.eliminate_zeros()
    return P


def _lumped_mass_1d(s: np.ndarray) -> np.ndarray:
    h = np.diff(s)
    return 0.5 * (np.concatenate([h, [0.0]]) + np.concatenate([[0.0], h]))


@dataclass
class SurfaceHierarchy:
    """Nested 1D meshes of the contact surface (every other node dropped per level).

    ``P[k]`` maps level ``k`` to ``k+1``; level ``len(s)-1`` is the constrained
    surface itself (in surface order).
    """

    order: np.ndarray
    s: list
    P: list
    mass: list

    @property
    def h(self) -> np.ndarray:
        return np.array([float(np.max(np.diff(sk))) for sk in self.s])


def surface_hierarchy(points: np.ndarray, n_coarse: int = 2) -> SurfaceHierarchy:
    """Build the nested surface meshes down to ``n_coarse`` nodes."""
    order, s = surface_order(points)
    levels = [s]
    while len(levels[0]) > n_coarse:
        fine = levels[0]
        keep = np.arange(0, len(fine), 2)
        if keep[-1] != len(fine) - 1:
            keep = np.append(keep, len(fine) - 1)
        if len(keep) == len(fine):
            break
        levels.insert(0, fine[keep])
    P = [_linear_interpolation(levels[k], levels[k + 1]) for k in range(len(levels) - 1)]
    return SurfaceHierarchy(order, levels, P, [_lumped_mass_1d(sk) for sk in levels])


def multilevel_schur_apply(hier: SurfaceHierarchy, m: int) -> Apply:
    """``S-hat q = sum_k w_k I_k M_k^{-1} I_k^T q`` (a multilevel H^{-1/2} norm).

    With ``lambda = M^{-1} q`` the pressure, ``q^T S-hat q`` is
    ``sum_k w_k ||Q_k lambda||^2`` with quasi-L2 projections ``Q_k`` (lumped
    masses) and ``w_k = h_k - h_{k+1}`` (``w_L = h_L``), i.e. the multilevel
    norm ``sum_k h_k ||(Q_k - Q_{k-1}) lambda||^2 ~ ||lambda||^2_{H^{-1/2}}``,
    which matches ``S = B A^{-1} B^T`` (order -1, Lemma 8.13). One product costs
    O(N^C) (Remark 8.12): restrictions down, diagonal scalings, prolongations up.
    """
    h = hier.h
    L = len(hier.s) - 1
    w = np.append(h[:-1] - h[1:], h[-1])
    w = np.maximum(w, 0.25 * h)  # non-uniform surfaces: keep every level positive
    Pt = [P.T.tocsr() for P in hier.P]
    order = hier.order

    def apply(q: np.ndarray) -> np.ndarray:
        r = [None] * (L + 1)
        r[L] = q[order]
        for k in range(L - 1, -1, -1):
            r[k] = Pt[k] @ r[k + 1]
        y = w[0] * r[0] / hier.mass[0]
        for k in range(1, L + 1):
            y = hier.P[k - 1] @ y + w[k] * r[k] / hier.mass[k]
        out = np.empty(m)
        out[order] = y
        return out

    return apply


def build_schur(kind: str, qp, Ainv: ScaledVCycle, lanczos_steps: int = 30,
                seed: int = 0) -> SchurPreconditioner:
    """Build ``S-hat`` of the given kind, scaled so that ``S_in <= S-hat``.

    Parameters
    ----------
    kind : {"inexact", "inexact_assembled", "multilevel", "jacobi"}
        ``S_in = B A-hat^{-1} B^T + C`` (8.22) matrix-free or assembled
        (N^C V-cycles), the multilevel surface operator
        (:func:`multilevel_schur_apply`) or ``B diag(A)^{-1} B^T + C``.
    qp : ContactQP
    Ainv : ScaledVCycle
        The scaled ``A-hat^{-1}``.

    Returns
    -------
    SchurPreconditioner
        With Lanczos estimates of ``lambda(S-hat)`` and, for sparse kinds,
        of ``lambda(S-hat^{-1} S_in)`` (setup uses a dense Cholesky of the
        small ``S-hat``; the iteration never inverts it).
    """
    t0 = time.perf_counter()
    B, C, m = qp.B, qp.C, qp.m
    Bt = sp.csr_matrix(B.T)
    plusC = (lambda q: C @ q) if C is not None else (lambda q: 0.0)

    def S_in(q):
        return B @ Ainv(Bt @ q) + plusC(q)

    info = {}
    if kind == "inexact":
        sh = SchurPreconditioner("inexact", S_in, m)
    elif kind == "inexact_assembled":
        I = np.eye(m)
        Sd = np.column_stack([S_in(I[:, j]) for j in range(m)])
        Sd = 0.5 * (Sd + Sd.T)
        sh = SchurPreconditioner("inexact_assembled", lambda q: Sd @ q, m)
    elif kind == "jacobi":
        Sj = sp.csr_matrix(B @ sp.diags(1.0 / qp.A.diagonal()) @ Bt)
        if C is not None:
            Sj = Sj + C
        sh = SchurPreconditioner("jacobi", lambda q: Sj @ q, m)
    elif kind == "multilevel":
        if qp.dim != 2 or qp.contact_nodes is None or "points" not in qp.geometry:
            raise ValueError("S-hat 'multilevel' needs a 2D ContactQP with contact_nodes and "
                             "geometry['points'] (1D contact surface)")
        hier = surface_hierarchy(np.asarray(qp.geometry["points"])[qp.contact_nodes])
        base = multilevel_schur_apply(hier, m)
        apply = (lambda q: base(q) + C @ q) if C is not None else base
        sh = SchurPreconditioner("multilevel", apply, m)
        info["surface_levels"] = len(hier.s)
    else:
        raise ValueError(f"unknown S-hat kind {kind!r}")
    sh.info = info
    if kind in ("jacobi", "multilevel"):
        _scale_against_Sin(sh, S_in, max(6, (2 * lanczos_steps) // 3), seed)  # lambda_max converges first
    lo, hi = lanczos_extremes(sh, m, min(lanczos_steps * 2, m), seed=seed + 1)
    sh.lam_min, sh.lam_max = lo, HIGH_SAFETY * hi
    sh.n_applications = 0
    sh.setup_time = time.perf_counter() - t0
    return sh


def _scale_against_Sin(sh: SchurPreconditioner, S_in: Apply, steps: int, seed: int) -> None:
    """Scale ``S-hat`` so that ``S_in <= S-hat`` (so the bound alpha_bar <= 2 holds).

    Lanczos on ``L^{-1} S_in L^{-T}`` with the Cholesky factor of the (small,
    dense) unscaled ``S-hat``; also records ``kappa(S-hat^{-1} S_in)``.
    """
    Sd = sh.dense()
    Lc = sla.cholesky(Sd, lower=True)

    def op(x):
        y = sla.solve_triangular(Lc, x, lower=True, trans="T")
        return sla.solve_triangular(Lc, S_in(y), lower=True)

    lo, hi = lanczos_extremes(op, sh.m, min(steps, sh.m), seed=seed + 2)
    sh.ritz_Sin = (lo, hi)
    sh.scale = HIGH_SAFETY * hi
    sh.kappa_Sin = hi / lo


def kappa_schur_exact(qp, Ainv: ScaledVCycle, sh: SchurPreconditioner, steps: int = 30,
                      cg_tol: float = 1e-10, seed: int = 3) -> tuple[float, float, float]:
    """``kappa(S-hat^{-1} S)`` with ``S = B A^{-1} B^T + C`` (costly: PCG per product).

    Returns
    -------
    (kappa, lambda_min, lambda_max)
    """
    import scipy.sparse.linalg as spla
    Bt = sp.csr_matrix(qp.B.T)
    M = spla.LinearOperator(qp.A.shape, matvec=Ainv)

    def S(q):
        x, info = spla.cg(qp.A, Bt @ q, M=M, rtol=cg_tol, atol=0.0, maxiter=500)
        return qp.B @ x + (qp.C @ q if qp.C is not None else 0.0)

    Lc = sla.cholesky(sh.dense(), lower=True)

    def op(x):
        y = sla.solve_triangular(Lc, x, lower=True, trans="T")
        return sla.solve_triangular(Lc, S(y), lower=True)

    lo, hi = lanczos_extremes(op, sh.m, min(steps, sh.m), seed=seed)
    return hi / lo, lo, hi
