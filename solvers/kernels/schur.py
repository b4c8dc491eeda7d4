"""``S-hat``: preconditioners of the Schur complement ``S = B A^{-1} B^T`` (thesis
Sect. 8.5, Remarks 8.11, 8.12, 8.15), for the augmented projection (Alg. 8.4).

The inexact Schur complement ``S_in = B A-hat^{-1} B^T + C`` (matrix-free, one V-cycle
per product, or assembled), the Jacobi-type ``B diag(A)^{-1} B^T + C`` and a
multilevel ``S-hat`` for the order -1 operator ``S`` on the nested constrained-surface
meshes the scene supplies (a line in 2D, a triangulated face in 3D), whose product
costs O(N^C); on the stabilised problem (Sect. 7.5) it covers both surfaces' rows.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from problems.qp import ContactQP, SurfaceHierarchy
from solvers.kernels.multigrid import HIGH_SAFETY, Apply, ScaledVCycle, lanczos_extremes

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
    inverse_unscaled : callable or None
        An SPD approximate inverse of ``apply_unscaled`` (exact for the nodal
        multilevel kind, :func:`multilevel_schur_inverse`): the preconditioner of
        :meth:`solve_unscaled` in place of Jacobi.
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
    inverse_unscaled: Apply | None = None
    setup_time: float = 0.0
    n_applications: int = 0
    info: dict = field(default_factory=dict)

    def __call__(self, q: np.ndarray) -> np.ndarray:
        self.n_applications += 1
        return self.scale * self.apply_unscaled(q)

    @property
    def kappa(self) -> float:
        """kappa(S-hat) of Table 9.1 (Euclidean, Lanczos); ``inf`` for a singular ``S-hat``
        (linearly dependent rows of ``B``: ``lam_min = 0``)."""
        return self.lam_max / self.lam_min if self.lam_min > 0 else float("inf")

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
        """``x = apply_unscaled^{-1} b`` by PCG, preconditioned by ``inverse_unscaled``
        where the kind has one (one or two steps), else by Jacobi (needs
        ``diagonal_unscaled``; ~sqrt(kappa(S-hat)) steps)."""
        if self.inverse_unscaled is None and self.diagonal_unscaled is None:
            raise ValueError(f"S-hat '{self.name}' has no cheap diagonal for its inverse")
        K = spla.LinearOperator((self.m, self.m), matvec=self.apply_unscaled)
        M = spla.LinearOperator((self.m, self.m), matvec=(
            self.inverse_unscaled or (lambda x: x / self.diagonal_unscaled)))

        def solve(b: np.ndarray) -> np.ndarray:
            x, info = spla.cg(K, b, M=M, rtol=1e-11, atol=0.0, maxiter=10 * self.m + 100)
            if info != 0:
                raise RuntimeError(f"CG on S-hat '{self.name}' did not converge (info {info})")
            return x

        return solve


def multilevel_schur_apply(surface: SurfaceHierarchy, embedding: sp.spmatrix | None = None
                           ) -> tuple[Apply, np.ndarray]:
    """``S-hat q = K (sum_k I_k W_k M_k^{-1} I_k^T) K^T q`` (a multilevel H^{-1/2} norm) and
    its diagonal.

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

    ``embedding`` ``K`` (``(m, m_surface)``, default the identity) maps the surface's
    rows into a larger multiplier space; the stabilised problem's reverse rows act
    on the constrained surface through their ``transfer`` (:func:`stabilised_schur_apply`).
    """
    L = surface.n_levels - 1
    scale = _level_scales(surface)
    P = [sp.csr_matrix(p) for p in surface.prolongations]
    Pt = [p.T.tocsr() for p in P]
    K = None if embedding is None else sp.csr_matrix(embedding)
    Kt = None if K is None else K.T.tocsr()

    def apply(q: np.ndarray) -> np.ndarray:
        r = [None] * (L + 1)
        r[L] = np.asarray(q, dtype=float) if Kt is None else Kt @ q
        for k in range(L - 1, -1, -1):
            r[k] = Pt[k] @ r[k + 1]
        y = scale[0] * r[0]
        for k in range(1, L + 1):
            y = P[k - 1] @ y + scale[k] * r[k]
        return y if K is None else K @ y

    # diag(K I_k D_k I_k^T K^T) = (K I_k o K I_k) diag(D_k), I_k the composite interpolation
    I = sp.identity(len(scale[L]), format="csr") if K is None else K
    diag = I.multiply(I) @ scale[L]
    for k in range(L - 1, -1, -1):
        I = (I @ P[k]).tocsr()
        diag += I.multiply(I) @ scale[k]
    return apply, diag


def multilevel_schur_inverse(surface: SurfaceHierarchy) -> Apply:
    """The exact inverse of the multilevel ``S-hat`` of :func:`multilevel_schur_apply`
    (no embedding), by one sparse factorisation of O(sum_k m_k) unknowns.

    ``S-hat = sum_k I_k D_k I_k^T`` (``D_k = W_k M_k^{-1}``) is the finest block of
    ``H = G^{-T} D G^{-1}``, where ``G`` (unit block lower bidiagonal) maps the level
    vectors ``r = (r_L, ..., r_0)`` to ``(r_L, r_{L-1} - P_{L-1}^T r_L, ...)``, so that
    ``G^{-1}`` takes ``x`` to its restrictions ``r_k = I_k^T x``. The inverse of a
    block is the Schur complement of the inverse matrix ``K = H^{-1} = G D^{-1} G^T``,
    which is sparse (the levels' prolongations and their products):

        ``S-hat^{-1} = K_LL - K_Lc K_cc^{-1} K_cL``,

    ``c`` the coarse levels. ``K_cc`` is a sparse SPD matrix over the coarse levels'
    nodes, which a sparse LU factorises with little fill (a line or a face mesh).
    Setup scaling (:func:`_scale_against_Sin`) preconditions its PCG with it: one
    or two steps where Jacobi took ~sqrt(kappa(S-hat)), hundreds on graded surfaces.
    """
    L = surface.n_levels - 1
    scale = _level_scales(surface)
    order = list(range(L, -1, -1))                   # r_L first: G is lower triangular
    start = dict(zip(order, np.cumsum([0] + [len(scale[k]) for k in order[:-1]])))
    total = sum(len(d) for d in scale)
    rows, cols, vals = [np.arange(total)], [np.arange(total)], [np.ones(total)]
    for k in range(L):
        Pt = sp.coo_matrix(surface.prolongations[k].T)           # m_k x m_{k+1}
        rows.append(Pt.row + start[k])
        cols.append(Pt.col + start[k + 1])
        vals.append(-Pt.data)
    G = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(total, total))
    K = (G @ sp.diags(np.concatenate([1.0 / scale[k] for k in order])) @ G.T).tocsr()
    m = len(scale[L])
    K_LL, K_Lc = K[:m, :m], K[:m, m:]
    if total == m:
        return lambda b: K_LL @ b
    lu = spla.splu(K[m:, m:].tocsc())
    K_cL = K_Lc.T.tocsr()
    return lambda b: K_LL @ b - K_Lc @ lu.solve(K_cL @ b)


def _level_scales(surface: SurfaceHierarchy) -> list:
    """``D_k = W_k M_k^{-1}`` of :func:`multilevel_schur_apply`, per surface level."""
    L = surface.n_levels - 1
    h = [np.asarray(s, dtype=float) for s in surface.sizes]
    return [(0.5 * h[k] if k < L else h[k]) / surface.masses[k] for k in range(L + 1)]


def jacobi_product(B: sp.spmatrix, A: sp.spmatrix) -> sp.csr_matrix:
    """``B diag(A)^{-1} B^T``, sparse (the Jacobi-type Schur complement)."""
    return sp.csr_matrix(B @ sp.diags(1.0 / A.diagonal()) @ B.T)


def stabilised_schur_apply(qp: ContactQP) -> tuple[Apply, np.ndarray]:
    """A multilevel ``S-hat`` over both surfaces' rows of the stabilised problem
    (Sect. 7.5, (7.10)/(7.11)) and its diagonal, without ``C``.

    A reverse row ``r`` measures the same gap as the constrained rows around the
    point it hits, so ``B_r ~ T B_c`` with ``T`` the barycentric ``transfer``
    (exact for fields linear along the surface). With ``K = [I; T]`` and the
    mismatch ``E = B - K B_c`` (zero on the constrained rows)::

        S = B A^{-1} B^T = (K B_c + E) A^{-1} (K B_c + E)^T
        S-hat = K S-hat_c K^T + E diag(A)^{-1} E^T

    ``S-hat_c`` is the multilevel operator of the constrained surface
    (:func:`multilevel_schur_apply`), which matches ``B_c A^{-1} B_c^T`` on every
    frequency; ``E`` annihilates the smooth multipliers (a force ``q_r`` and its
    transfer ``T' q_r`` to the constrained nodes cancel to second order), and on
    what is left, the high frequencies, ``A`` is spectrally its diagonal. The
    mismatch term is sparse (``r x r``), assembled once; one product costs O(N^C).
    ``kappa(S-hat^{-1} S)`` stays bounded under refinement
    (``tests/test_stabilised_schur.py``; the augmented projection study's page).
    """
    st, m_c = qp.stabilisation, qp.m_contact
    T = sp.csr_matrix(st.transfer)
    K = sp.vstack([sp.identity(m_c, format="csr"), T]).tocsr()
    B = sp.csr_matrix(qp.B)
    E = (B - K @ B[:m_c]).tocsr()
    E.eliminate_zeros()
    EDE = jacobi_product(E, qp.A)
    base, diag = multilevel_schur_apply(qp.multilevel.surface, embedding=K)
    return (lambda q: base(q) + EDE @ q), diag + EDE.diagonal()


def build_schur(kind: str, qp: ContactQP, Ainv: ScaledVCycle, lanczos_steps: int,
                seed: int = 0) -> SchurPreconditioner:
    """Build ``S-hat`` of the given kind, scaled so that ``S_in <= S-hat``.

    Parameters
    ----------
    kind : {"inexact", "inexact_assembled", "multilevel", "jacobi"}
        ``S_in = B A-hat^{-1} B^T + C`` (8.22) matrix-free or assembled
        (N^C V-cycles), the multilevel surface operator
        (:func:`multilevel_schur_apply`; on a stabilised problem over both surfaces'
        rows, :func:`stabilised_schur_apply`) or ``B diag(A)^{-1} B^T + C``.
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
        Sj = jacobi_product(B, qp.A)
        if C is not None:
            Sj = Sj + C
        sh = SchurPreconditioner("jacobi", lambda q: Sj @ q, m, Sj.diagonal().copy())
    elif kind == "multilevel":
        surface = qp.multilevel.surface
        if surface is None:
            raise ValueError("schur=multilevel needs the nested constrained-surface meshes "
                             "(qp.multilevel.surface), which this problem does not supply; "
                             "use schur=inexact")
        base, diag = (multilevel_schur_apply(surface) if qp.stabilisation is None
                      else stabilised_schur_apply(qp))
        apply = (lambda q: base(q) + C @ q) if C is not None else base
        sh = SchurPreconditioner("multilevel", apply, m, diag + diagC)
        if qp.stabilisation is None:
            sh.inverse_unscaled = multilevel_schur_inverse(surface)
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
