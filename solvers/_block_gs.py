"""Compiled node-block Gauss-Seidel sweeps for :mod:`solvers.tnnmg` (numba).

One kernel serves both smoothers of truncated nonsmooth Newton multigrid: the nonlinear
presmoother (exact minimisation of the energy over one node's unknowns with a bound on
its first unknown: the unconstrained block solve, or, when it crosses the bound, the
first unknown clamped to it and the others solved again) and the linear smoother of the
truncated correction (the bounded unknown of an active node held fixed). Blocks have at
most three unknowns; their inverses come from :func:`block_inverses`.

Compiled with numba (``cache=True``: compiled once per machine, then read from
numba's cache beside this file); no Python loop over nodes runs in a sweep.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numba import njit

#: Block modes of :func:`block_gauss_seidel`.
FREE, BOUNDED, FIXED = 0, 1, 2


def unsigned_index(a: np.ndarray) -> np.ndarray:
    """``a`` (non-negative indices) as ``uint32`` (``uint64`` if it does not fit): the
    compiled kernels index with it without numba's test for negative indices."""
    a = np.asarray(a)
    big = a.size and int(a.max()) >= np.iinfo(np.uint32).max
    return a.astype(np.uint64 if big else np.uint32)


def block_inverses(A: sp.csr_matrix, node_ptr: np.ndarray, node_dofs: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(diag, inv_full, inv_sub)``, each ``(n_blocks, 3, 3)``: the node blocks of ``A``,
    their inverses, and the inverses of the blocks without their first unknown (stored
    at ``[1:k, 1:k]``); padded with the identity. One compiled pass over ``A``'s rows."""
    A = sp.csr_matrix(A)
    nb = node_ptr.size - 1
    diag = np.empty((nb, 3, 3))
    inv_full = np.empty((nb, 3, 3))
    inv_sub = np.empty((nb, 3, 3))
    _block_inverses(A.indptr, A.indices, A.data, node_ptr, node_dofs, diag, inv_full, inv_sub)
    return diag, inv_full, inv_sub


@njit(cache=True, nogil=True)
def _inverse3(M, out):   # pragma: no cover (compiled)
    """``out = inv(M)`` for a 3 x 3 ``M`` by cofactors."""
    c00 = M[1, 1] * M[2, 2] - M[1, 2] * M[2, 1]
    c01 = M[1, 2] * M[2, 0] - M[1, 0] * M[2, 2]
    c02 = M[1, 0] * M[2, 1] - M[1, 1] * M[2, 0]
    det = M[0, 0] * c00 + M[0, 1] * c01 + M[0, 2] * c02
    out[0, 0] = c00 / det
    out[1, 0] = c01 / det
    out[2, 0] = c02 / det
    out[0, 1] = (M[0, 2] * M[2, 1] - M[0, 1] * M[2, 2]) / det
    out[1, 1] = (M[0, 0] * M[2, 2] - M[0, 2] * M[2, 0]) / det
    out[2, 1] = (M[0, 1] * M[2, 0] - M[0, 0] * M[2, 1]) / det
    out[0, 2] = (M[0, 1] * M[1, 2] - M[0, 2] * M[1, 1]) / det
    out[1, 2] = (M[0, 2] * M[1, 0] - M[0, 0] * M[1, 2]) / det
    out[2, 2] = (M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0]) / det


@njit(cache=True, nogil=True)
def _block_inverses(indptr, indices, data, node_ptr, node_dofs, diag, inv_full,
                    inv_sub):   # pragma: no cover (compiled)
    sub = np.empty((3, 3))
    for blk in range(node_ptr.size - 1):
        s = node_ptr[blk]
        k = node_ptr[blk + 1] - s
        for a in range(3):
            for c in range(3):
                diag[blk, a, c] = 1.0 if a == c and a >= k else 0.0
        for a in range(k):
            i = node_dofs[s + a]
            for q in range(indptr[i], indptr[i + 1]):
                j = indices[q]
                for c in range(k):
                    if node_dofs[s + c] == j:
                        diag[blk, a, c] += data[q]
        _inverse3(diag[blk], inv_full[blk])
        for a in range(3):
            for c in range(3):
                sub[a, c] = diag[blk, a, c] if a > 0 and c > 0 else (1.0 if a == c else 0.0)
        _inverse3(sub, inv_sub[blk])


@njit(cache=True, nogil=True)
def block_gauss_seidel(indptr, indices, data, x, b, node_ptr, node_dofs, diag, inv_full,
                       inv_sub, mode, upper, forward):   # pragma: no cover (compiled)
    """One sweep of node-block Gauss-Seidel for ``A x = b``, in place on ``x``.

    ``mode[k]``: FREE (the block solve), BOUNDED (exact minimisation with
    ``x[first] <= upper[k]``), FIXED (the first unknown kept, the others solved).
    ``forward`` False sweeps the blocks in reverse order (a symmetric pair of sweeps).
    """
    nb = node_ptr.size - 1
    r = np.zeros(3)
    dx = np.zeros(3)
    start, stop, stride = (0, nb, 1) if forward else (nb - 1, -1, -1)
    for blk in range(start, stop, stride):
        s = node_ptr[blk]
        k = node_ptr[blk + 1] - s
        for a in range(k):
            i = node_dofs[s + a]
            acc = b[i]
            for q in range(indptr[i], indptr[i + 1]):
                acc -= data[q] * x[indices[q]]
            r[a] = acc
        md = mode[blk]
        i0 = node_dofs[s]
        if md != FIXED:
            for a in range(k):
                acc = 0.0
                for c in range(k):
                    acc += inv_full[blk, a, c] * r[c]
                dx[a] = acc
            if md == BOUNDED and x[i0] + dx[0] > upper[blk]:
                md = 3
        if md == FIXED or md == 3:
            d0 = 0.0 if md == FIXED else upper[blk] - x[i0]
            dx[0] = d0
            for a in range(1, k):
                acc = 0.0
                for c in range(1, k):
                    acc += inv_sub[blk, a, c] * (r[c] - diag[blk, c, 0] * d0)
                dx[a] = acc
        for a in range(k):
            x[node_dofs[s + a]] += dx[a]
        if md == 3:
            x[i0] = upper[blk]
