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


def block_inverses(A: sp.csr_matrix, node_ptr: np.ndarray, node_dofs: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(diag, inv_full, inv_sub)``, each ``(n_blocks, 3, 3)``: the node blocks of ``A``,
    their inverses, and the inverses of the blocks without their first unknown (stored
    at ``[1:k, 1:k]``); padded with the identity."""
    nb = node_ptr.size - 1
    k = np.diff(node_ptr)
    diag = np.tile(np.eye(3), (nb, 1, 1))
    for a in range(3):
        for c in range(3):
            has = (k > a) & (k > c)
            if has.any():
                blocks = np.flatnonzero(has)
                diag[blocks, a, c] = np.asarray(
                    A[node_dofs[node_ptr[blocks] + a], node_dofs[node_ptr[blocks] + c]]).ravel()
    inv_full = np.linalg.inv(diag)
    sub = diag.copy()
    sub[:, 0, :] = 0.0
    sub[:, :, 0] = 0.0
    sub[:, 0, 0] = 1.0
    inv_sub = np.linalg.inv(sub)
    return diag, inv_full, inv_sub


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
    for t in range(nb):
        blk = t if forward else nb - 1 - t
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
