"""Sparse Cholesky factorisation of the stiffness matrix, factorised once.

The exact solvers (``pdas`` with ``method="schur"``, the verification's duality
gap) need ``A^{-1}`` applied to a few hundred contact columns and to a handful of
vectors. What decides their cost is the factorisation's fill (a nested-dissection
ordering) and, for the dual problem (7.3), that only the components of
``A^{-1} B^T`` on the contact rows' support are needed.

Backends (:data:`BACKENDS`, picked by :func:`factorize` with ``backend="auto"``):

``pardiso``
    Intel MKL PARDISO through ``libmkl_rt`` (the ``mkl`` wheel; x86-64 only),
    called directly with ``ctypes``: symmetric positive definite (``mtype`` 2),
    METIS nested dissection (``iparm(2)`` = 2), no iterative refinement inside
    the solve (``iparm(8)`` = 0; the MKL default of two steps doubles a solve's
    cost, callers refine where they need to), and *partial solves*
    (``iparm(31)`` = 1) when ``components`` is given: the right-hand sides are
    nonzero only there and only those components of the solution are computed,
    which skips most of the elimination tree. One thread by default (measured
    timings and bitwise reproducible results; ``threads`` to change).
``splu``
    SciPy's SuperLU with the COLAMD ordering, the fallback where MKL is absent
    (e.g. on ARM). Competitive in 2D; in 3D its fill and its time are far above
    PARDISO's.

``tests/test_cholesky.py`` checks that the backends agree; what they cost, and what the
partial solves save, is in docs/guide/measurements.md.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import glob
import os
import sys
import time
import weakref
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.sparse as sp

#: Columns solved at once: the block size that measured best (larger blocks do
#: not lower the per-column cost).
BLOCK = 64


class FactorizationError(RuntimeError):
    """The factorisation failed (the message says why, e.g. not positive definite)."""


@dataclass
class Cholesky:
    """A factorised SPD matrix.

    Attributes
    ----------
    backend : str
        ``"pardiso"`` or ``"splu"``.
    n : int
        Order of the matrix.
    fill : int
        Nonzeros of the factor (``nnz(L)``; ``nnz(L + U)`` for ``splu``).
    factor_time : float
        Seconds spent in the ordering and the numerical factorisation.
    components : (k,) int array or None
        Components a :meth:`solve` with ``partial=True`` computes.
    """

    backend: str
    n: int
    fill: int
    factor_time: float
    components: np.ndarray | None
    _solve: Callable[[np.ndarray, bool], np.ndarray] = field(repr=False)

    def solve(self, b: np.ndarray, partial: bool = False) -> np.ndarray:
        """``A^{-1} b`` for a vector or the columns of a matrix (dense or sparse).

        With ``partial=True`` (requires ``components``) ``b`` must vanish off
        ``components`` and only those components of the result are valid (the
        others are zero for ``pardiso`` and exact for ``splu``).
        """
        if partial and self.components is None:
            raise ValueError("partial=True needs a factorisation with 'components'")
        vector = np.ndim(b) == 1
        if sp.issparse(b):
            b = b.tocsc()
        cols = 1 if vector else b.shape[1]
        if not vector and cols > BLOCK:
            return np.hstack([self.solve(b[:, s:s + BLOCK], partial)
                              for s in range(0, cols, BLOCK)])
        # column-major, as the backends take it: no copy of an n x BLOCK block on the way in
        dense = b.toarray(order="F") if sp.issparse(b) else np.asarray(b, dtype=float)
        x = self._solve(dense.reshape(self.n, cols), partial)
        return x[:, 0] if vector else x


def factorize(A: sp.spmatrix, backend: str = "auto", components: np.ndarray | None = None,
              threads: int = 1) -> Cholesky:
    """Factorise the symmetric positive definite ``A`` once.

    Parameters
    ----------
    A : sparse (n, n)
        Symmetric positive definite (both triangles stored).
    backend : {"auto", "pardiso", "splu"}
        ``auto``: ``pardiso`` if MKL loads, else ``splu``.
    components : int array, optional
        Indices for partial solves (e.g. the columns of ``B`` that hold nonzeros).
    threads : int
        Threads of the ``pardiso`` backend.

    Raises
    ------
    ValueError
        Unknown backend, or a backend that is not available.
    FactorizationError
        ``A`` is not positive definite (or the backend fails otherwise).
    """
    if backend not in ("auto", *BACKENDS):
        raise ValueError(f"backend={backend!r} is not allowed; allowed: auto, "
                         f"{', '.join(BACKENDS)}")
    if backend == "auto":
        backend = "pardiso" if _mkl() is not None else "splu"
    elif backend == "pardiso" and _mkl() is None:
        raise ValueError("backend='pardiso' needs Intel MKL (pip install mkl; x86-64 only); "
                         "use backend='splu'")
    if components is not None:
        components = np.unique(np.asarray(components, dtype=np.int64))
    return BACKENDS[backend](sp.csr_matrix(A), components, threads)


def dense_schur(chol: Cholesky, G: sp.spmatrix) -> np.ndarray:
    """``G A^{-1} G'`` dense, symmetric to round-off, ``A`` the matrix ``chol`` factorises
    (the dual operator of (7.3), the Delassus operator): ``A^{-1} G'`` :data:`BLOCK`
    columns at a time by partial solves, so ``chol.components`` must hold ``G``'s columns
    (:meth:`Cholesky.solve`)."""
    G = sp.csr_matrix(G)
    Gt = sp.csc_matrix(G.T)
    k = G.shape[0]
    S = np.empty((k, k))
    for start in range(0, k, BLOCK):
        cols = Gt[:, start:start + BLOCK]
        S[:, start:start + cols.shape[1]] = G @ chol.solve(cols, partial=True)
    return 0.5 * (S + S.T)


def available_backends() -> tuple[str, ...]:
    """The backends that work on this machine."""
    return tuple(b for b in BACKENDS if b != "pardiso" or _mkl() is not None)


# -- MKL PARDISO ---------------------------------------------------------------

_MKL: list = []          # [library or None], loaded once

#: PARDISO's error codes (MKL reference, "pardiso" error parameter).
_PARDISO_ERRORS = {
    -1: "input inconsistent", -2: "not enough memory", -3: "reordering problem",
    -4: "zero pivot, numerical factorisation or iterative refinement problem "
        "(the matrix is not positive definite?)",
    -5: "unclassified (internal) error", -6: "reordering failed", -7: "diagonal matrix is "
    "singular", -8: "32-bit integer overflow problem", -9: "not enough memory for OOC",
    -10: "error opening OOC files", -11: "read/write error with OOC files",
}


def _mkl():
    """MKL's single dynamic library (``libmkl_rt``), or None where it is not installed."""
    if not _MKL:
        lib = None
        candidates = sorted(glob.glob(os.path.join(sys.prefix, "lib", "libmkl_rt.so*")), key=len)
        found = ctypes.util.find_library("mkl_rt")
        for path in candidates + ([found] if found else []):
            try:
                lib = ctypes.CDLL(path)
                lib.pardiso  # noqa: B018 -- the symbol must exist
                break
            except (OSError, AttributeError):
                lib = None
        _MKL.append(lib)
    return _MKL[0]


class _PardisoHandle:
    """One PARDISO instance (its internal pointer ``pt``) for one sparsity pattern: the
    upper triangle's ``ia``/``ja`` (1-based), the settings of :func:`factorize`'s backend,
    and its memory freed when the handle is garbage collected."""

    def __init__(self, upper: sp.csr_matrix, components: np.ndarray | None, threads: int):
        if upper.nnz >= 2**31:
            raise FactorizationError(f"{upper.nnz} nonzeros exceed PARDISO's 32-bit indices")
        self.lib = _mkl()
        self.n = upper.shape[0]
        self.threads = threads
        self.ia = (upper.indptr + 1).astype(np.int32)
        self.ja = (upper.indices + 1).astype(np.int32)
        self.data = np.ascontiguousarray(upper.data, dtype=np.float64)
        self.pt = np.zeros(64, dtype=np.int64)          # PARDISO's internal pointer "pt"
        self.iparm = iparm = np.zeros(64, dtype=np.int32)
        iparm[0] = 1            # iparm(1): our own settings, not the defaults
        iparm[1] = 2            # iparm(2): METIS nested dissection
        iparm[7] = 0            # iparm(8): no iterative refinement inside the solve
        iparm[17] = -1          # iparm(18): report nnz of the factor
        self.perm = np.zeros(self.n, dtype=np.int32)
        if components is not None:
            iparm[30] = 1       # iparm(31): sparse right-hand sides, selected components
            self.perm[components] = 1
        self.analysed = False
        weakref.finalize(self, _pardiso_release, self.lib, self.pt, self.n, self.ia, self.ja,
                         self.perm, self.iparm)

    def call(self, phase: int, b: np.ndarray, x: np.ndarray) -> None:
        _pardiso_call(self.lib, self.pt, phase, self.n, self.data, self.ia, self.ja, self.perm,
                      self.iparm, b, x, self.threads)

    def factor(self, phase: int) -> float:
        """Phase 12 (ordering, symbolic and numerical factorisation) or 22 (numerical only,
        on the analysis kept from an earlier phase 12); its seconds."""
        t0 = time.perf_counter()
        self.call(phase, np.zeros(self.n), np.zeros(self.n))
        self.analysed = True
        return time.perf_counter() - t0

    def solve(self, b: np.ndarray, partial: bool) -> np.ndarray:
        self.iparm[30] = 1 if partial else 0
        rhs = np.asfortranarray(b)
        x = np.zeros_like(rhs)
        self.call(33, rhs, x)
        return np.ascontiguousarray(x)


def _pardiso_call(lib, pt, phase, n, data, ia, ja, perm, iparm, b, x, threads) -> None:
    err = ctypes.c_int32(0)
    int_p = ctypes.POINTER(ctypes.c_int32)
    set_threads = getattr(lib, "MKL_Set_Num_Threads_Local", None)
    old = set_threads(ctypes.c_int(threads)) if set_threads else None
    try:
        lib.pardiso(pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)),
                    ctypes.byref(ctypes.c_int32(1)), ctypes.byref(ctypes.c_int32(1)),
                    ctypes.byref(ctypes.c_int32(2)), ctypes.byref(ctypes.c_int32(phase)),
                    ctypes.byref(ctypes.c_int32(n)), data.ctypes.data_as(ctypes.c_void_p),
                    ia.ctypes.data_as(int_p), ja.ctypes.data_as(int_p),
                    perm.ctypes.data_as(int_p),
                    ctypes.byref(ctypes.c_int32(1 if b.ndim == 1 else b.shape[1])),
                    iparm.ctypes.data_as(int_p), ctypes.byref(ctypes.c_int32(0)),
                    b.ctypes.data_as(ctypes.c_void_p), x.ctypes.data_as(ctypes.c_void_p),
                    ctypes.byref(err))
    finally:
        if set_threads:
            set_threads(old)
    if err.value:
        raise FactorizationError(f"PARDISO phase {phase}: error {err.value}, "
                                 f"{_PARDISO_ERRORS.get(err.value, 'unknown')}")


def _pardiso_release(lib, pt, n, ia, ja, perm, iparm) -> None:
    """Free PARDISO's memory (phase -1)."""
    _pardiso_call(lib, pt, -1, n, np.zeros(0), ia, ja, perm, iparm, np.zeros(0),
                  np.zeros(0), 1)


def canonical(M: sp.spmatrix) -> sp.csr_matrix:
    """``M`` as sorted CSR without duplicates; ``M`` itself where it is one already (a copy
    otherwise: the caller's arrays are never reordered)."""
    M = sp.csr_matrix(M)
    if M.has_canonical_format:
        return M
    M = M.copy()
    M.sum_duplicates()
    M.sort_indices()
    return M


def upper_triangle(A: sp.csr_matrix) -> tuple[sp.csr_matrix, np.ndarray]:
    """The upper triangle of the canonical ``A`` (explicit zeros kept) and the positions of
    its entries in ``A.data``."""
    rows = np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))
    places = np.flatnonzero(A.indices >= rows)
    counts = np.bincount(rows[places], minlength=A.shape[0])
    upper = sp.csr_matrix((A.data[places], A.indices[places], np.r_[0, np.cumsum(counts)]),
                          shape=A.shape)
    return upper, places


def _pardiso(A: sp.csr_matrix, components: np.ndarray | None, threads: int) -> Cholesky:
    handle = _PardisoHandle(upper_triangle(canonical(A))[0], components, threads)
    factor_time = handle.factor(12)
    return Cholesky(backend="pardiso", n=handle.n, fill=int(handle.iparm[17]),
                    factor_time=factor_time, components=components, _solve=handle.solve)


class SamePatternCholesky:
    """Factorisations of a sequence of SPD matrices that share one sparsity pattern, each
    replacing the one before: PARDISO's ordering and symbolic analysis once per pattern,
    then only the numerical factorisation (phase 22) of each new matrix's values.

    Made for the truncated coarsest operator of TNNMG
    (:class:`solvers.kernels.tnnmg_correction.TruncatedHierarchy`), whose values change
    at every change of the truncation and whose pattern does not
    (:class:`~solvers.kernels.tnnmg_correction.UpdatedOperator` keeps explicit zeros
    where updates go). A matrix of another pattern is analysed anew. Needs MKL
    (:func:`available_backends`); one thread (bitwise reproducible).
    """

    def __init__(self):
        if _mkl() is None:
            raise ValueError("SamePatternCholesky needs Intel MKL (pip install mkl; x86-64 "
                             "only); use factorize(A, backend='splu')")
        self.handle: _PardisoHandle | None = None
        self.pattern: tuple[np.ndarray, np.ndarray] | None = None
        self.upper: np.ndarray | None = None        # positions of A's upper triangle
        self.analyses = 0                            # patterns analysed so far

    def factorize(self, A: sp.spmatrix) -> Cholesky:
        """The factorisation of ``A`` (both triangles stored); the previous one's solve is
        no longer valid.

        Raises
        ------
        FactorizationError
            ``A`` is not positive definite; the next call may try again.
        """
        A = canonical(A)
        same = (self.pattern is not None and self.handle is not None and self.handle.analysed
                and np.array_equal(A.indptr, self.pattern[0])
                and np.array_equal(A.indices, self.pattern[1]))
        if same:
            self.handle.data[:] = A.data[self.upper]
            phase = 22
        else:
            upper, self.upper = upper_triangle(A)
            self.pattern = (A.indptr.copy(), A.indices.copy())
            self.handle = _PardisoHandle(upper, None, 1)
            self.analyses += 1
            phase = 12
        factor_time = self.handle.factor(phase)
        return Cholesky(backend="pardiso", n=self.handle.n, fill=int(self.handle.iparm[17]),
                        factor_time=factor_time, components=None, _solve=self.handle.solve)


# -- SciPy SuperLU -------------------------------------------------------------

def _splu(A: sp.csr_matrix, components: np.ndarray | None, threads: int) -> Cholesky:
    import scipy.sparse.linalg as spla

    t0 = time.perf_counter()
    try:
        lu = spla.splu(A.tocsc(), permc_spec="COLAMD")
    except RuntimeError as err:                     # exactly singular
        raise FactorizationError(f"SuperLU: {err}") from None
    factor_time = time.perf_counter() - t0
    return Cholesky(backend="splu", n=A.shape[0], fill=int(lu.L.nnz + lu.U.nnz),
                    factor_time=factor_time, components=components,
                    _solve=lambda b, partial: lu.solve(b))


#: Backend name -> factorising function ``(A, components, threads) -> Cholesky``.
BACKENDS = {"pardiso": _pardiso, "splu": _splu}


def cholesky_factor(A: sp.spmatrix) -> sp.csc_matrix:
    """A sparse ``F`` with ``F'F = A`` for a symmetric positive definite ``A``: the
    Cholesky factor itself, where :func:`factorize` only hands out solves.

    SciPy's SuperLU in symmetric mode (``MMD_AT_PLUS_A``, a fill-reducing ordering of
    ``A + A'``; diagonal pivots only, so the row permutation is ``Pc'``) gives
    ``A_pp = Pc' A Pc = L U`` with ``L`` unit lower triangular; ``A_pp`` symmetric makes
    ``U = D L'`` (``D`` the pivots), so ``A_pp = U' D^-1 U`` and ``F = D^-1/2 U Pc'``
    (upper triangular in the ordering).
    Its nonzeros are the factorisation's fill, not the ``n^2`` of a dense Cholesky.

    Raises
    ------
    FactorizationError
        A pivot that is not positive (``A`` is not positive definite), or SuperLU left
        the diagonal (then ``U`` is no Cholesky factor).
    """
    import scipy.sparse.linalg as spla

    A = sp.csc_matrix(A)
    try:
        lu = spla.splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True})
    except RuntimeError as err:                     # exactly singular
        raise FactorizationError(f"SuperLU: {err}") from None
    order = lu.perm_c                       # A_pp[order[i], order[j]] = A[i, j]
    if not np.array_equal(lu.perm_r, order):
        raise FactorizationError("SuperLU pivoted off the diagonal: the matrix is not "
                                 "symmetric positive definite")
    pivots = lu.U.diagonal()
    if not np.all(pivots > 0):
        bad = np.flatnonzero(~(pivots > 0))
        raise FactorizationError(f"{bad.size} pivots <= 0 (first: {pivots[bad[0]]:.3g}): "
                                 "the matrix is not positive definite")
    factor = sp.diags(1.0 / np.sqrt(pivots)) @ sp.csc_matrix(lu.U)
    return sp.csc_matrix(factor[:, order])


class FloatingCholesky:
    """``A^{-1}`` for an SPD ``A`` with a known near-kernel (floating bodies), stably.

    A body held only by contact and weak springs (the roll stack's work roll,
    thesis Sect. 9.3) gives ``A = A_0 + K`` with ``A_0 R = 0`` for its rigid modes
    ``R`` and ``K`` the springs, ~1e-9 of the elastic stiffness. A Cholesky of ``A``
    itself is backward stable, but the answer's rigid part is ``~1/K`` times the
    unbalanced load: metres where the contact solution is 0.1 mm, so every contact
    quantity becomes a difference of huge numbers (the dual route's KKT residuals
    stalled at ~1e-4). This class removes the near-kernel exactly, as FETI does for
    floating subdomains (C. Farhat, F.-X. Roux 1991; Z. Dostal et al. for contact):
    ``k`` *fixing* DOFs ``D`` are chosen where the modes are largest (pivoted QR of
    ``R'``), the modes are normalised to ``R_D = I`` and the unknowns change basis,
    ``x = x_r (on the rest r) + R y_d``. In that basis

        T'AT = [[A_rr, C], [C', Sigma]],   C = (A R)_r = (K R)_r,  Sigma = R'AR = R'KR,

    where ``A_rr`` (``A`` without the fixing DOFs) is an ordinary well-conditioned
    elasticity matrix and ``C``, ``Sigma`` are the springs' small terms, computed
    without cancellation (``A_0 R = 0``). A solve is one solve with ``A_rr`` and a
    ``k x k`` system with ``Sigma~ = Sigma - C' A_rr^{-1} C``.

    Parameters
    ----------
    A : sparse (n, n)
        Symmetric positive definite.
    modes : (n, k) array
        Basis of the near-kernel (:func:`problems.floating.floating_modes`), k >= 1.
    backend, components, threads
        As :func:`factorize` (``components`` in the numbering of ``A``).

    Attributes
    ----------
    fixing : (k,) int array
        The fixing DOFs ``D``.
    rest : (n - k,) int array
        The other DOFs ``r``, in order.
    R : (n, k) array
        The modes normalised to ``R[fixing] = I``.
    chol : Cholesky
        Of ``A_rr``.
    """

    def __init__(self, A: sp.spmatrix, modes: np.ndarray, backend: str = "auto",
                 components: np.ndarray | None = None, threads: int = 1):
        import scipy.linalg as sla

        A = sp.csr_matrix(A)
        n, k = A.shape[0], modes.shape[1]
        if k == 0:
            raise ValueError("FloatingCholesky needs at least one mode; use factorize()")
        _, _, piv = sla.qr(modes.T, mode="economic", pivoting=True)
        self.fixing = np.sort(piv[:k])
        mask = np.ones(n, dtype=bool)
        mask[self.fixing] = False
        self.rest = np.flatnonzero(mask)
        self.n, self.k = n, k
        self.R = modes @ np.linalg.inv(modes[self.fixing])
        self.R[self.fixing] = np.eye(k)
        t0 = time.perf_counter()
        comp_r = None
        if components is not None:
            pos = -np.ones(n, dtype=np.int64)
            pos[self.rest] = np.arange(len(self.rest))
            comp_r = pos[np.asarray(components, dtype=np.int64)]
            comp_r = comp_r[comp_r >= 0]
        self.A = A
        self._Arr = A[self.rest][:, self.rest].tocsr()
        self.chol = factorize(self._Arr, backend, comp_r, threads)
        AR = A @ self.R
        self.C = AR[self.rest]
        sigma = self.R.T @ AR
        self.W = self.rest_solve(self.C)
        self.sigma = 0.5 * (sigma + sigma.T) - self.C.T @ self.W
        self.sigma = 0.5 * (self.sigma + self.sigma.T)
        self.backend, self.fill = self.chol.backend, self.chol.fill
        self.factor_time = time.perf_counter() - t0
        if not np.all(np.linalg.eigvalsh(self.sigma) > 0):
            raise FactorizationError("the floating modes' spring stiffness Sigma~ is not "
                                     "positive definite (a mode that nothing holds)")

    def rest_solve(self, b: np.ndarray, refine: bool = True) -> np.ndarray:
        """``A_rr^{-1} b``, with one step of iterative refinement unless ``refine=False``."""
        x = self.chol.solve(b)
        return x + self.chol.solve(b - self._Arr @ x) if refine else x

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``A^{-1} b`` (a vector or the columns of a matrix)."""
        b = np.asarray(b, dtype=float)
        z = self.rest_solve(b[self.rest])
        y_d = np.linalg.solve(self.sigma, self.R.T @ b - self.C.T @ z)
        x = self.R @ y_d
        x[self.rest] += z - self.W @ y_d
        return x


def shared_floating_factor(qp, modes: np.ndarray, backend: str = "auto") -> FloatingCholesky:
    """The :class:`FloatingCholesky` of ``qp.A`` (partial solves on ``B``'s support),
    factorised once per problem and kept in ``qp.cache.floating_factor``: the exact solver and the
    verification's duality gap need the same ``A^{-1}`` (a factorisation of a large
    problem is too slow to repeat), and sharing it changes no number."""
    cached = qp.cache.floating_factor
    if cached is not None and backend in ("auto", cached.backend):
        return cached
    fl = FloatingCholesky(qp.A, modes, backend, components=sp.csr_matrix(qp.B).indices)
    qp.cache.floating_factor = fl
    return fl


# -- linearly dependent constraint rows ------------------------------------------

#: Relative pivot below which a constraint row counts as linearly dependent on the rows
#: before it: ``pivot^2 <= DEPENDENT_RTOL * K_ii`` in the Cholesky factor of a Gram matrix
#: ``K`` of the rows, i.e. the row's angle to the span of the others is below ~1e-6 (far
#: above the ~1e-16 at which round-off leaves an exactly dependent row).
DEPENDENT_RTOL = 1e-12

#: Relative violation ``(B_D u - g_D)_i`` of a dropped row, beside ``|M_i| |g_J| + |g_i|
#: + max |g_I|``, above which the dependent rows are inconsistent at equality (the rows are
#: satisfied to round-off when the gaps are consistent). The largest gap of the rows is
#: in the scale because a gap is computed from coordinates of that size: two coincident
#: nodes' gaps (1e-17 and 0, say) agree to round-off of the geometry, not of themselves,
#: and judged by their own size their exchanges would cycle.
CONSISTENT_RTOL = 1e-10


class InfeasibleError(RuntimeError):
    """Constraint rows that no ``u`` satisfies: a Farkas certificate ``z >= 0`` with
    ``B_I' z = 0`` and ``g_I' z < 0`` (the message gives the rows and ``g_I' z``)."""


@dataclass
class RowBasis:
    """A basis of linearly dependent constraint rows, chosen from their Gram matrix.

    Attributes
    ----------
    kept : (r,) int array
        Positions of the basis rows ``J`` (sorted; all rows when they are independent).
    dropped : (k,) int array
        Positions of the other rows ``D``: ``B_D = M B_J`` to round-off; their
        multipliers are set to zero.
    factor : tuple
        :func:`scipy.linalg.cho_factor` of ``K[J][:, J]``.
    """

    kept: np.ndarray
    dropped: np.ndarray
    factor: tuple


def row_basis(K: np.ndarray, g: np.ndarray | None = None, labels: np.ndarray | None = None,
              rtol: float = DEPENDENT_RTOL) -> RowBasis:
    """A basis of the rows whose Gram matrix is ``K`` (``K = B_I W`` for any SPD metric,
    e.g. the Schur complement ``B_I A^{-1} B_I'``), consistent with the gaps ``g``.

    Independent rows (the Cholesky factor of ``K`` has no relative pivot below ``rtol``)
    give all rows and exactly :func:`scipy.linalg.cho_factor` of ``K``. Otherwise a
    rank-revealing pivoted Cholesky (LAPACK ``dpstrf``, largest remaining diagonal first)
    of ``K`` scaled to unit diagonal picks the basis ``J``; the step's multipliers are
    then those supported on ``J`` (zero on the dropped rows ``D``). With ``g`` the basis
    must also be consistent: on the face ``B_J u = g_J`` the dropped rows hold
    ``B_D u = M g_J <= g_D`` (``M = K_DJ K_JJ^{-1}``, since ``B_D = M B_J``), i.e. ``u``
    sits at a vertex of ``{B_I u <= g_I}`` in the row space. A violated dropped row ``i``
    enters the basis in exchange for the row ``j`` of largest ``M_ij > 0``, which then
    has slack ``r_i / M_ij``; without such a row, ``z = e_i - M_i >= 0`` has
    ``B_I' z = 0`` and ``g_I' z = -r_i < 0``: the rows are infeasible.

    Parameters
    ----------
    K : (k, k) array
        Symmetric positive semidefinite Gram matrix of the rows.
    g : (k,) array, optional
        The rows' gaps; without them the basis is not checked for consistency.
    labels : (k,) int array, optional
        Row numbers for messages (default: positions).
    rtol : float
        Relative pivot of a dependent row (:data:`DEPENDENT_RTOL`).

    Raises
    ------
    InfeasibleError
        The rows admit no ``u`` with ``B_I u <= g_I`` (Farkas certificate in the message).
    RuntimeError
        No consistent basis within ``2 k`` exchanges (a cycle of exchanges).
    """
    import scipy.linalg as sla
    from scipy.linalg.lapack import dpstrf

    K = np.asarray(K, dtype=float)
    k = K.shape[0]
    if k == 0:
        return RowBasis(np.zeros(0, dtype=int), np.zeros(0, dtype=int), None)
    labels = np.arange(k) if labels is None else np.asarray(labels)
    diag = np.diag(K).copy()
    try:
        factor = sla.cho_factor(K)
        if np.all(np.diag(factor[0]) ** 2 > rtol * diag):
            return RowBasis(np.arange(k), np.zeros(0, dtype=int), factor)
    except np.linalg.LinAlgError:
        pass
    nonzero = np.flatnonzero(diag > rtol * max(float(diag.max(initial=0.0)), 1e-300))
    s = 1.0 / np.sqrt(diag[nonzero])
    scaled = 0.5 * (K[np.ix_(nonzero, nonzero)] + K[np.ix_(nonzero, nonzero)].T) * np.outer(s, s)
    _, piv, rank, info = dpstrf(scaled, tol=rtol)
    if info < 0:
        raise RuntimeError(f"LAPACK dpstrf: argument {-info} is invalid")
    kept = np.sort(nonzero[piv[:rank] - 1])
    seen: set[bytes] = set()
    for _ in range(2 * k + 1):
        dropped = np.setdiff1d(np.arange(k), kept)
        factor = sla.cho_factor(K[np.ix_(kept, kept)])
        if g is None or dropped.size == 0:
            return RowBasis(kept, dropped, factor)
        M = sla.cho_solve(factor, K[np.ix_(kept, dropped)]).T
        gJ = g[kept]
        r = M @ gJ - g[dropped]
        scale = np.abs(M) @ np.abs(gJ) + np.abs(g[dropped]) + np.abs(g).max()
        violation = r / np.maximum(scale, 1e-300)
        i = int(np.argmax(violation))
        if violation[i] <= CONSISTENT_RTOL:
            return RowBasis(kept, dropped, factor)
        seen.add(kept.tobytes())
        coeff = M[i]
        if not np.any(coeff > rtol * np.abs(coeff).max()):
            z = np.concatenate([[1.0], -coeff])
            rows = np.concatenate([[labels[dropped[i]]], labels[kept]])
            support = np.abs(z) > rtol * np.abs(z).max()
            order = np.argsort(rows[support])
            rows, z = rows[support][order], z[support][order]
            raise InfeasibleError(
                f"the problem is infeasible: constraint rows {rows.tolist()} with "
                f"weights z = {np.round(z, 6).tolist()} >= 0 give B'z = 0 but "
                f"g'z = {-r[i]:.3e} < 0 (a Farkas certificate: no u has Bu <= g)")
        j = int(np.argmax(coeff))
        kept = np.sort(np.append(np.delete(kept, j), dropped[i]))
        if kept.tobytes() in seen:
            break
    raise RuntimeError(f"{k} linearly dependent constraint rows: no basis consistent with "
                       f"their gaps found by exchanges (the exchanges cycle)")
