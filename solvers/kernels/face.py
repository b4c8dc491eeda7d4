"""The face of an active set: projection onto ``ker B_I`` for projected PCG.

:func:`face_projector` builds the :class:`FaceProjector` of the rows of an active
set; :data:`FACE_PROJECTION` declares it as a solver option. Used by the semismooth
Newton solver (:mod:`solvers.semismooth_newton`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from problems.spec import ComponentParameter, Parameter
from solvers.kernels.cholesky import factorize, row_basis
from solvers.kernels.multigrid import Apply

# ---------------------------------------------------------------------------
# The face of an active set: projection for projected PCG
# ---------------------------------------------------------------------------
#: Face projections: the metric whose orthogonal complement of ``ker B_I`` is removed.
FACE_KINDS = ("harmonic", "euclidean")

#: Default patch width of the harmonic face projection per dimension: the fastest
#: semismooth Newton solves; in 3D the patch's factorisation grows faster than the steps
#: fall (docs/guide/measurements.md).
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
    smooth V-cycle correction at the constrained DOFs (it takes twice the
    projected-PCG steps: the solver comparison's page).

    Setup: a sparse Cholesky factor of ``G_pp`` (:func:`solvers.kernels.cholesky.factorize`)
    and the dense Cholesky factor of the small ``K = B_p G_pp^{-1} B_p'`` (partial
    solves on the constrained DOFs). Each operation below costs one solve with
    ``G_pp`` on the patch and one with ``K``.

    Linearly dependent rows: ``B_I`` holds only a basis of them (``kept``,
    :func:`solvers.kernels.cholesky.row_basis`), the face is the same, and the others get
    multiplier zero.
    """

    B_I: sp.csr_matrix          # the basis rows of the active set
    patch: np.ndarray
    B_p: sp.csr_matrix          # B_I[:, patch]
    solve_G: Apply | None
    K_factor: tuple | None
    kept: np.ndarray            # positions of the basis rows among the active rows
    n_rows: int                 # number of active rows

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
        """``x + W K^{-1} (g_I - B_I x)``: a point of the affine face ``B_I x = g_I``
        (``g_I`` of all active rows)."""
        return self._extend(x, np.asarray(g_I)[self.kept] - self.B_I @ x, 1.0)

    def multipliers(self, r: np.ndarray) -> np.ndarray:
        """``K^{-1} W' r``: the multipliers with ``r ~ B_I' p_I`` (exact when it is),
        one per active row, zero on the dependent ones."""
        p = np.zeros(self.n_rows)
        p[self.kept] = self._basis_multipliers(r)
        return p

    def _basis_multipliers(self, r: np.ndarray) -> np.ndarray:
        if self.K_factor is None:
            return np.zeros(0)
        Wr = self.B_p @ self.solve_G(np.asarray(r, dtype=float)[self.patch])
        return sla.cho_solve(self.K_factor, Wr)

    def project_T(self, r: np.ndarray) -> np.ndarray:
        """``Pi' r = r - B_I' (multipliers of r)``."""
        return np.array(r, dtype=float) - self.B_I.T @ self._basis_multipliers(r)


def face_projector(A: sp.spmatrix, B_I: sp.spmatrix, kind: str = "harmonic",
                   hops: int = 2, g_I: np.ndarray | None = None,
                   labels: np.ndarray | None = None) -> FaceProjector:
    """The :class:`FaceProjector` of the rows ``B_I`` (an active set).

    Parameters
    ----------
    A : sparse (n, n)
        Stiffness matrix (its graph defines the patch, its block the metric).
    B_I : sparse (m_I, n)
        Active constraint rows; linearly dependent ones are reduced to a basis
        (:func:`solvers.kernels.cholesky.row_basis`, from ``K``).
    kind : {"harmonic", "euclidean"}
    hops : int
        ``harmonic`` only: graph distance of the patch from the constrained DOFs.
    g_I : (m_I,) array, optional
        The rows' gaps: the basis of dependent rows is then consistent with them.
    labels : (m_I,) int array, optional
        Row numbers for messages.

    Raises
    ------
    ValueError
        For an unknown ``kind`` or ``hops < 0``.
    solvers.kernels.cholesky.InfeasibleError
        Dependent rows that no ``u`` satisfies (with ``g_I``).
    RuntimeError
        Dependent rows without a basis consistent with ``g_I``.
    """
    if kind not in FACE_KINDS:
        raise ValueError(f"unknown face projection {kind!r}; allowed: {', '.join(FACE_KINDS)}")
    if hops < 0:
        raise ValueError(f"hops must be >= 0, got {hops}")
    B_I = sp.csr_matrix(B_I)
    constrained = np.unique(B_I.indices)
    patch = constrained
    if B_I.shape[0] == 0:
        return FaceProjector(B_I, patch, B_I[:, patch], None, None, np.zeros(0, dtype=int), 0)
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
    basis = row_basis(0.5 * (K + K.T), g_I, labels)
    if basis.dropped.size:
        B_I, B_p = B_I[basis.kept], B_p[basis.kept]
    return FaceProjector(B_I, patch, B_p, solve_G, basis.factor, basis.kept, K.shape[0])
