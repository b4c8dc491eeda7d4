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
  ``S-hat`` for the order -1 operator ``S = B A^{-1} B^T`` on the nested
  constrained-surface meshes the scene supplies (a line in 2D, a triangulated
  face in 3D), whose product costs O(N^C).
* :func:`lanczos_extremes`: Ritz estimates of extreme eigenvalues of a
  symmetric pencil (Remark 8.14, kappa(S-hat) of Table 9.1).
"""
from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from problems.qp import ContactQP, Multilevel, SurfaceHierarchy
from problems.spec import ComponentParameter, Parameter

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
#: Smoothers of the V-cycle: pyamg name and settings per sweep.
SMOOTHERS = {
    "symmetric_gs": ("gauss_seidel", {"sweep": "symmetric"}),
    "block_gs": ("block_gauss_seidel", {"sweep": "symmetric"}),
    "jacobi": ("jacobi", {"omega": 0.6}),
}


def _smoother(name: str, sweeps: int, blocked: bool):
    """pyamg smoother spec ``(name, settings)`` with ``sweeps`` iterations.

    Block Gauss-Seidel needs a BSR operator; otherwise pointwise symmetric GS.
    """
    if name == "block_gs" and not blocked:
        name = "symmetric_gs"
    kind, settings = SMOOTHERS[name]
    return kind, {**settings, "iterations": int(sweeps) * (2 if kind == "jacobi" else 1)}


def _as_blocked(A: sp.spmatrix, dim: int, free_dofs: np.ndarray | None):
    """``A`` as BSR with node blocks when the free DOFs come in whole nodes."""
    n = A.shape[0]
    if free_dofs is None or n % dim:
        return sp.csr_matrix(A)
    fd = np.asarray(free_dofs).reshape(-1, dim)
    if np.all(fd[:, 0] % dim == 0) and np.all(np.diff(fd, axis=1) == 1):
        return sp.bsr_matrix(A, blocksize=(dim, dim))
    return sp.csr_matrix(A)


@contextmanager
def _seeded_global_rng(seed: int = 0):
    """pyamg estimates spectral radii (Jacobi weights, prolongation smoothing) from
    ``np.random.rand`` start vectors: seed the global generator while a hierarchy is
    set up, so that two runs give the same hierarchy, and restore it afterwards."""
    state = np.random.get_state()
    np.random.seed(seed)
    try:
        yield
    finally:
        np.random.set_state(state)


def sa_hierarchy(A: sp.spmatrix, near_null: np.ndarray | None, dim: int,
                 free_dofs: np.ndarray | None, smoother: str, sweeps: int, max_coarse: int):
    """pyamg smoothed aggregation with ``near_null`` (rigid-body modes per body).

    Node-blocked (BSR) when the free DOFs come in whole nodes; symmetric
    smoothing so that one V-cycle is an SPD operator.
    """
    import pyamg
    Ab = _as_blocked(A, dim, free_dofs)
    sm = _smoother(smoother, sweeps, sp.isspmatrix_bsr(Ab))
    B = None if near_null is None else np.asarray(near_null, dtype=float)
    with _seeded_global_rng():
        return pyamg.smoothed_aggregation_solver(
            Ab, B=B, max_coarse=max_coarse, presmoother=sm, postsmoother=sm,
            improve_candidates=None, coarse_solver="splu")


def geometric_hierarchy(A: sp.spmatrix, prolongations: list, smoother: str, sweeps: int):
    """Geometric multigrid on the refinement hierarchy, Galerkin coarse operators.

    Parameters
    ----------
    prolongations : list of sparse
        ``P_k`` maps level ``k`` to ``k+1`` on the free DOFs; ``P[-1]`` ends at
        ``A``. Without prolongations the "V-cycle" is a direct solve.
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
    sm = _smoother(smoother, sweeps, blocked=False)
    with _seeded_global_rng():
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
        """One unscaled V-cycle with zero start (symmetric smoothing)."""
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


def vcycle(A: sp.spmatrix, kind: str, multilevel: Multilevel | None, dim: int,
           free_dofs: np.ndarray | None, *, smoother: str, sweeps: int,
           max_coarse: int = 0) -> ScaledVCycle:
    """One symmetric V-cycle as a preconditioner, unscaled (``gamma_low = 1``).

    ``kind`` {"gmg", "sa"}: geometric multigrid on ``multilevel.prolongations``
    or pyamg smoothed aggregation (rigid-body modes as near-null space);
    V(sweeps, sweeps) with the named symmetric smoother; ``max_coarse`` (SA
    only) the largest coarsest level. What a multigrid-PCG linear solve needs;
    :func:`scaled_vcycle` adds the scaling of (8.18).
    """
    multilevel = multilevel or Multilevel()
    t0 = time.perf_counter()
    if kind == "sa":
        ml = sa_hierarchy(A, multilevel.rigid_body_modes, dim, free_dofs, smoother, sweeps,
                          max_coarse)
    elif kind == "gmg":
        ml = geometric_hierarchy(A, list(multilevel.prolongations), smoother, sweeps)
    else:
        raise ValueError(f"unknown A-hat kind {kind!r}; allowed: gmg, sa")
    return ScaledVCycle(kind, ml, 1.0, 1.0, (np.nan, np.nan), time.perf_counter() - t0, 0.0)


def vcycle_kind(qp: ContactQP, kind: str) -> str:
    """``kind``, with ``auto`` resolved: gmg when ``qp`` has a refinement hierarchy, else sa."""
    return kind if kind != "auto" else ("gmg" if qp.multilevel.prolongations else "sa")


def component_vcycle(qp: ContactQP, ahat) -> ScaledVCycle:
    """The unscaled V-cycle an ``ahat`` component (:class:`problems.spec.Component`, as the
    augmented projection declares it) describes on ``qp.A``: what a PCG solve needs.

    Kind ``auto`` as :func:`vcycle_kind`; a Lanczos step count among the options is
    not used.
    """
    o = ahat.options
    return vcycle(qp.A, vcycle_kind(qp, ahat.kind), qp.multilevel, qp.dim, qp.free_dofs,
                  smoother=o["smoother"], sweeps=o["sweeps"], max_coarse=o.get("max_coarse", 0))


def scaled_vcycle(A: sp.spmatrix, kind: str, multilevel: Multilevel | None, dim: int,
                  free_dofs: np.ndarray | None, *, smoother: str, sweeps: int,
                  lanczos_steps: int, max_coarse: int = 0, seed: int = 0) -> ScaledVCycle:
    """Build ``A-hat`` (:func:`vcycle`) and scale it by Lanczos so that (8.18) holds.

    Parameters
    ----------
    kind, multilevel, smoother, sweeps, max_coarse
        As :func:`vcycle`.
    lanczos_steps : int
        Steps of preconditioned Lanczos for ``lambda(A-hat^{-1} A)``.

    The defaults of these options are declared once, in
    :data:`solvers.augmented_projection.SOLVER` (``ahat``).

    Returns
    -------
    ScaledVCycle
        With ``gamma_low = LOW_SAFETY * ritz_min`` and
        ``gamma_high = HIGH_SAFETY * ritz_max``.
    """
    vc = vcycle(A, kind, multilevel, dim, free_dofs, smoother=smoother, sweeps=sweeps,
                max_coarse=max_coarse)
    t0 = time.perf_counter()
    lo, hi = lanczos_extremes(lambda x: A @ x, A.shape[0], lanczos_steps, vc.raw, seed)
    vc.lanczos_time = time.perf_counter() - t0
    vc.ritz = (lo, hi)
    vc.gamma_low, vc.gamma_high = LOW_SAFETY * lo, HIGH_SAFETY * hi
    return vc


# ---------------------------------------------------------------------------
# The face of an active set: projection for projected PCG
# ---------------------------------------------------------------------------
#: Face projections: the metric whose orthogonal complement of ``ker B_I`` is removed.
FACE_KINDS = ("harmonic", "euclidean")

#: Default patch width of the harmonic face projection per dimension. Measured with the
#: semismooth Newton solver to 1e-6: at circle-square level 4 hops 1/2/3/5 took
#: 9.3/8.0/6.2/5.9 s (Euclidean 16.3 s), at cube-sphere level 3 18.1/15.7/19.1/22.7 s
#: (Euclidean 22.7 s): in 3D the patch's factorisation grows faster than the steps fall.
AUTO_HOPS = {2: 5, 3: 2}

#: The face projection as a solver option (declared once; :func:`face_projector`).
FACE_PROJECTION = ComponentParameter(
    "face", "harmonic",
    {"harmonic": (Parameter("hops", 0, "patch width in graph steps around the constrained "
                            "DOFs; 0 = by dimension (AUTO_HOPS: 5 in 2D, 2 in 3D)",
                            low=0, high=50, kind=int),),
     "euclidean": ()},
    "projection onto the face B_I u = g_I in projected PCG: along local A-harmonic "
    "extensions of the constraint directions (harmonic) or orthogonal (euclidean, Gould-"
    "Hribar-Nocedal)")


def face_hops(dim: int, hops: int) -> int:
    """``hops``, or the measured default of the dimension when it is 0."""
    return int(hops) if hops else AUTO_HOPS.get(dim, 2)


@dataclass
class FaceProjector:
    """Projector onto the face ``ker B_I`` of an active set, along ``W = E B_I'``.

    ``Pi = I - W (B_I W)^{-1} B_I`` with ``E`` the zero-extended inverse of a
    metric ``G`` on a patch of DOFs around the constrained ones: ``G = I`` on the
    constrained DOFs (``euclidean``: the orthogonal projector of Gould, Hribar
    and Nocedal) or ``G = A`` restricted to the DOFs within ``hops`` graph steps
    of them (``harmonic``: ``W`` is the local discrete harmonic extension of the
    constraint directions, a cheap stand-in for the A-orthogonal projector
    ``W = A^{-1} B_I'``). With the multigrid V-cycle ``M`` the projected
    preconditioner is ``Pi M Pi'``: exact on the face when ``W = A^{-1} B_I'``,
    it inherits the V-cycle's rate, whereas the Euclidean projector cuts the
    smooth V-cycle correction at the constrained DOFs (measured at circle-square
    level 4 on the solution's face: 12 projected-PCG steps to energy error 1e-6
    with ``hops=5``, 24 with the Euclidean projector, 7 without constraints).

    Setup: a sparse Cholesky factor of ``G_pp`` (:func:`solvers.cholesky.factorize`)
    and the dense Cholesky factor of the small ``K = B_p G_pp^{-1} B_p'`` (partial
    solves on the constrained DOFs). Each operation below costs one solve with
    ``G_pp`` on the patch and one with ``K``.
    """

    B_I: sp.csr_matrix
    patch: np.ndarray
    B_p: sp.csr_matrix          # B_I[:, patch]
    solve_G: Apply | None
    K_factor: tuple | None

    def _extend(self, v: np.ndarray, c: np.ndarray, sign: float) -> np.ndarray:
        """``v + sign * W K^{-1} c``."""
        out = np.array(v, dtype=float)
        if self.K_factor is not None:
            mu = sla.cho_solve(self.K_factor, c)
            out[self.patch] += sign * self.solve_G(self.B_p.T @ mu)
        return out

    def project(self, v: np.ndarray) -> np.ndarray:
        """``Pi v`` (in ``ker B_I``)."""
        return self._extend(v, self.B_I @ v, -1.0)

    def lift(self, x: np.ndarray, g_I: np.ndarray) -> np.ndarray:
        """``x + W K^{-1} (g_I - B_I x)``: a point of the affine face ``B_I x = g_I``."""
        return self._extend(x, g_I - self.B_I @ x, 1.0)

    def multipliers(self, r: np.ndarray) -> np.ndarray:
        """``K^{-1} W' r``: the multipliers with ``r ~ B_I' p_I`` (exact when it is)."""
        if self.K_factor is None:
            return np.zeros(0)
        Wr = self.B_p @ self.solve_G(np.asarray(r, dtype=float)[self.patch])
        return sla.cho_solve(self.K_factor, Wr)

    def project_T(self, r: np.ndarray) -> np.ndarray:
        """``Pi' r = r - B_I' (multipliers of r)``."""
        return np.array(r, dtype=float) - self.B_I.T @ self.multipliers(r)


def face_projector(A: sp.spmatrix, B_I: sp.spmatrix, kind: str = "harmonic",
                   hops: int = 2) -> FaceProjector:
    """The :class:`FaceProjector` of the rows ``B_I`` (an active set).

    Parameters
    ----------
    A : sparse (n, n)
        Stiffness matrix (its graph defines the patch, its block the metric).
    B_I : sparse (m_I, n)
        Active constraint rows, linearly independent.
    kind : {"harmonic", "euclidean"}
    hops : int
        ``harmonic`` only: graph distance of the patch from the constrained DOFs.

    Raises
    ------
    ValueError
        For an unknown ``kind``, ``hops < 0`` or linearly dependent rows.
    """
    from solvers.cholesky import factorize
    if kind not in FACE_KINDS:
        raise ValueError(f"unknown face projection {kind!r}; allowed: {', '.join(FACE_KINDS)}")
    if hops < 0:
        raise ValueError(f"hops must be >= 0, got {hops}")
    B_I = sp.csr_matrix(B_I)
    constrained = np.unique(B_I.indices)
    patch = constrained
    if B_I.shape[0] == 0:
        return FaceProjector(B_I, patch, B_I[:, patch], None, None)
    if kind == "harmonic":
        A = sp.csr_matrix(A)
        for _ in range(hops):
            patch = np.union1d(patch, A[patch].indices)
    B_p = B_I[:, patch]
    if kind == "harmonic":
        G = factorize(A[patch][:, patch], components=np.searchsorted(patch, constrained))
        solve_G, X = G.solve, G.solve(B_p.T, partial=True)
    else:
        solve_G, X = (lambda r: np.asarray(r, dtype=float)), B_p.T.toarray()
    K = np.asarray(B_p @ X)
    try:
        K_factor = sla.cho_factor(0.5 * (K + K.T))
        dependent = np.diag(K_factor[0]).min() ** 2 <= 1e-12 * np.diag(K).max()
    except np.linalg.LinAlgError:
        dependent = True
    if dependent:
        raise ValueError("the active constraint rows B_I are linearly dependent")
    return FaceProjector(B_I, patch, B_p, solve_G, K_factor)


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
    m : int
    diagonal_unscaled : (m,) array or None
        Diagonal of ``apply_unscaled`` when it is cheap (sparse kinds).
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
    diagonal_unscaled: np.ndarray | None = None
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

    def columns(self, idx: np.ndarray) -> np.ndarray:
        """``S-hat[:, idx]`` (one product per column)."""
        out = np.empty((self.m, len(idx)))
        e = np.zeros(self.m)
        for c, j in enumerate(idx):
            e[j] = 1.0
            out[:, c] = self.scale * self.apply_unscaled(e)
            e[j] = 0.0
        return out

    def diagonal(self) -> np.ndarray:
        """``diag(S-hat)``: from ``diagonal_unscaled`` when the kind has it, else one
        product per entry."""
        if self.diagonal_unscaled is not None:
            return self.scale * np.asarray(self.diagonal_unscaled, dtype=float)
        return np.array([self.columns(np.array([j]))[j, 0] for j in range(self.m)])

    def dense(self) -> np.ndarray:
        """Explicit, symmetrised ``S-hat`` (m products; for tests and small m)."""
        M = self.columns(np.arange(self.m))
        return 0.5 * (M + M.T)

    def solve_unscaled(self) -> Apply:
        """``x = apply_unscaled^{-1} b`` by Jacobi-PCG (needs ``diagonal_unscaled``)."""
        if self.diagonal_unscaled is None:
            raise ValueError(f"S-hat '{self.name}' has no cheap diagonal for its inverse")
        K = spla.LinearOperator((self.m, self.m), matvec=self.apply_unscaled)
        M = spla.LinearOperator((self.m, self.m), matvec=lambda x: x / self.diagonal_unscaled)

        def solve(b: np.ndarray) -> np.ndarray:
            x, info = spla.cg(K, b, M=M, rtol=1e-11, atol=0.0, maxiter=10 * self.m + 100)
            if info != 0:
                raise RuntimeError(f"CG on S-hat '{self.name}' did not converge (info {info})")
            return x

        return solve


def multilevel_schur_apply(surface: SurfaceHierarchy) -> tuple[Apply, np.ndarray]:
    """``S-hat q = sum_k I_k W_k M_k^{-1} I_k^T q`` (a multilevel H^{-1/2} norm) and its diagonal.

    ``I_k`` interpolates surface level ``k`` to the finest, ``M_k`` is the
    lumped surface mass and ``W_k`` the local mesh size (``surface.sizes``),
    halved below the finest level (``h_k - h_{k+1}`` on uniform levels). With
    ``lambda = M^{-1} q`` the pressure, ``q^T S-hat q`` is
    ``sum_k ||Q_k lambda||^2_{W_k}`` with quasi-L2 projections ``Q_k``, i.e. the
    multilevel norm ``sum_k h_k ||(Q_k - Q_{k-1}) lambda||^2 ~
    ||lambda||^2_{H^{-1/2}}``, which matches ``S = B A^{-1} B^T`` (order -1,
    Lemma 8.13). One product costs O(N^C) (Remark 8.12): restrictions down,
    diagonal scalings, prolongations up. Dimension-generic: the surface is a
    line (2D) or a triangulated face (3D), nested as the scene supplies it.
    """
    L = surface.n_levels - 1
    h = [np.asarray(s, dtype=float) for s in surface.sizes]
    scale = [(0.5 * h[k] if k < L else h[k]) / surface.masses[k] for k in range(L + 1)]
    P = [sp.csr_matrix(p) for p in surface.prolongations]
    Pt = [p.T.tocsr() for p in P]

    def apply(q: np.ndarray) -> np.ndarray:
        r = [None] * (L + 1)
        r[L] = np.asarray(q, dtype=float)
        for k in range(L - 1, -1, -1):
            r[k] = Pt[k] @ r[k + 1]
        y = scale[0] * r[0]
        for k in range(1, L + 1):
            y = P[k - 1] @ y + scale[k] * r[k]
        return y

    # diag(I_k D_k I_k^T) = (I_k o I_k) diag(D_k), with I_k the composite interpolation
    diag = scale[L].copy()
    I = sp.identity(len(scale[L]), format="csr")
    for k in range(L - 1, -1, -1):
        I = (I @ P[k]).tocsr()
        diag += I.multiply(I) @ scale[k]
    return apply, diag


def build_schur(kind: str, qp: ContactQP, Ainv: ScaledVCycle, lanczos_steps: int,
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
    lanczos_steps : int
        Lanczos steps for the extreme eigenvalues of ``S-hat`` (kappa, MPRGP's
        step); sparse kinds scale against ``S_in`` with a third of them (at
        least 6), one V-cycle per step.

    Returns
    -------
    SchurPreconditioner
        With Lanczos estimates of ``lambda(S-hat)`` and, for sparse kinds,
        of ``lambda(S-hat^{-1} S_in)`` (setup inverts the sparse ``S-hat`` by
        PCG; the iteration never does).
    """
    t0 = time.perf_counter()
    B, C, m = qp.B, qp.C, qp.m
    Bt = sp.csr_matrix(B.T)
    plusC = (lambda q: C @ q) if C is not None else (lambda q: 0.0)
    diagC = C.diagonal() if C is not None else 0.0

    def S_in(q):
        return B @ Ainv(Bt @ q) + plusC(q)

    info = {}
    if kind == "inexact":
        sh = SchurPreconditioner("inexact", S_in, m)
    elif kind == "inexact_assembled":
        I = np.eye(m)
        Sd = np.column_stack([S_in(I[:, j]) for j in range(m)])
        Sd = 0.5 * (Sd + Sd.T)
        sh = SchurPreconditioner("inexact_assembled", lambda q: Sd @ q, m, np.diag(Sd).copy())
    elif kind == "jacobi":
        Sj = sp.csr_matrix(B @ sp.diags(1.0 / qp.A.diagonal()) @ Bt)
        if C is not None:
            Sj = Sj + C
        sh = SchurPreconditioner("jacobi", lambda q: Sj @ q, m, Sj.diagonal().copy())
    elif kind == "multilevel":
        surface = qp.multilevel.surface
        if qp.stabilisation is not None:
            raise ValueError("schur=multilevel covers the constrained surface's rows only; the "
                             "stabilised problem (Sect. 7.5) has reverse rows too: use "
                             "schur=inexact or jacobi")
        if surface is None:
            raise ValueError("schur=multilevel needs the nested constrained-surface meshes "
                             "(qp.multilevel.surface), which this problem does not supply; "
                             "use schur=inexact")
        base, diag = multilevel_schur_apply(surface)
        apply = (lambda q: base(q) + C @ q) if C is not None else base
        sh = SchurPreconditioner("multilevel", apply, m, diag + diagC)
        info["surface_levels"] = surface.n_levels
    else:
        raise ValueError(f"unknown S-hat kind {kind!r}")
    sh.info = info
    if kind in ("jacobi", "multilevel"):
        # lambda_max first; one V-cycle per step, and the largest Ritz value of the pencil has
        # settled to 0.3% by 8 steps (circle-square, cube-sphere), inside HIGH_SAFETY
        _scale_against_Sin(sh, S_in, max(6, lanczos_steps // 3), seed)
    lo, hi = lanczos_extremes(sh, m, min(lanczos_steps * 2, m), seed=seed + 1)
    sh.lam_min, sh.lam_max = lo, HIGH_SAFETY * hi
    sh.n_applications = 0
    sh.setup_time = time.perf_counter() - t0
    return sh


def _scale_against_Sin(sh: SchurPreconditioner, S_in: Apply, steps: int, seed: int) -> None:
    """Scale ``S-hat`` so that ``S_in <= S-hat`` (so the bound alpha_bar <= 2 holds).

    Lanczos for the pencil ``(S_in, S-hat)`` with ``S-hat^{-1}`` by PCG; also
    records ``kappa(S-hat^{-1} S_in)``.
    """
    lo, hi = lanczos_extremes(S_in, sh.m, min(steps, sh.m), sh.solve_unscaled(), seed=seed + 2)
    sh.ritz_Sin = (lo, hi)
    sh.scale = HIGH_SAFETY * hi
    sh.kappa_Sin = hi / lo


def kappa_schur_exact(qp: ContactQP, Ainv: ScaledVCycle, sh: SchurPreconditioner,
                      steps: int = 30, cg_tol: float = 1e-10,
                      seed: int = 3) -> tuple[float, float, float]:
    """``kappa(S-hat^{-1} S)`` with ``S = B A^{-1} B^T + C`` (costly: PCG per product).

    ``S-hat^{-1}`` by PCG on the sparse ``S-hat``, or a dense Cholesky factor
    for a kind without a cheap diagonal (small ``m``).

    Returns
    -------
    (kappa, lambda_min, lambda_max)
    """
    Bt = sp.csr_matrix(qp.B.T)
    M = spla.LinearOperator(qp.A.shape, matvec=Ainv)

    def S(q):
        x, info = spla.cg(qp.A, Bt @ q, M=M, rtol=cg_tol, atol=0.0, maxiter=500)
        return qp.B @ x + (qp.C @ q if qp.C is not None else 0.0)

    if sh.diagonal_unscaled is not None:
        inv_unscaled = sh.solve_unscaled()
        inv = lambda x: inv_unscaled(x) / sh.scale
    else:
        factor = sla.cho_factor(sh.dense())
        inv = lambda x: sla.cho_solve(factor, x)
    lo, hi = lanczos_extremes(S, sh.m, min(steps, sh.m), inv, seed=seed)
    return hi / lo, lo, hi
