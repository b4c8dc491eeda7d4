"""Compiled node-block Gauss-Seidel sweeps for :mod:`solvers.tnnmg` (numba).

One kernel serves both smoothers of truncated nonsmooth Newton multigrid: the nonlinear
presmoother (exact minimisation of the energy over one node's unknowns with a bound on
its first unknown: the unconstrained block solve, or, when it crosses the bound, the
first unknown clamped to it and the others solved again) and the linear smoother of the
truncated correction (the bounded unknown of an active node held fixed). Blocks have at
most three unknowns; their inverses come from :func:`block_inverses`. The sweep
:func:`tresca_block_gauss_seidel` adds Tresca friction: in 2D the exact block minimiser
with the normal bound and the term ``s |x_t - c|`` (:func:`_tresca_block`), in 3D, with
``x_t`` the node's two tangential unknowns and the Euclidean norm, the exact
disc-constrained block minimiser :func:`disc_block_minimiser`; and the linear smoother with
a sticking node's tangential unknowns held. :func:`block_gauss_seidel` is the same sweep
with the frictionless modes only.

Compiled with numba (``cache=True``: compiled once per machine, then read from
numba's cache beside this file); no Python loop over nodes runs in a sweep.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numba import njit

#: Block modes of :func:`block_gauss_seidel`.
FREE, BOUNDED, FIXED = 0, 1, 2
#: Further block modes of :func:`tresca_block_gauss_seidel` (2D blocks): the exact
#: minimiser with the normal bound and Tresca's term (TRESCA), the second unknown held
#: (TANGENT_FIXED), both held (BOTH_FIXED).
TRESCA, TANGENT_FIXED, BOTH_FIXED = 4, 5, 6


def unsigned_index(a: np.ndarray) -> np.ndarray:
    """``a`` (non-negative indices) as ``uint32``, a view of an ``int32`` array (no copy):
    the compiled kernels then index without numba's test for negative indices (a large
    share of a sweep: docs/guide/measurements.md). An index beyond ``uint32`` stays
    ``int64`` (correct, slower; numba would turn ``uint64 + int`` into a float)."""
    a = np.asarray(a)
    if a.dtype == np.int32:
        return a.view(np.uint32)
    if a.dtype == np.uint32 or (a.size and int(a.max()) >= np.iinfo(np.uint32).max):
        return a if a.dtype == np.uint32 else a.astype(np.int64)
    return a.astype(np.uint32)


def block_inverses(A: sp.csr_matrix, node_ptr: np.ndarray, node_dofs: np.ndarray,
                   C: sp.csr_matrix | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(diag0, inv_full, inv_sub)`` of ``A + C`` (``C`` an optional sparse update):
    the first column of each node block ``(n_blocks, w)``, the blocks' inverses and the
    inverses of the blocks without their first unknown (stored at ``[1:k, 1:k]``),
    ``(n_blocks, w, w)`` with ``w`` the largest block (2 in 2D, 3 in 3D), padded with the
    identity. One compiled pass over the rows."""
    A = sp.csr_matrix(A)
    C = sp.csr_matrix(A.shape) if C is None else sp.csr_matrix(C)
    nb = node_ptr.size - 1
    w = int(np.diff(node_ptr).max(initial=1))
    if w > 3:
        raise ValueError(f"node blocks of at most 3 unknowns, got {w}")
    diag0 = np.empty((nb, w))
    inv_full = np.empty((nb, w, w))
    inv_sub = np.empty((nb, w, w))
    _block_inverses(A.indptr, A.indices, A.data, C.indptr, C.indices, C.data, node_ptr,
                    node_dofs, diag0, inv_full, inv_sub)
    return diag0, inv_full, inv_sub


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
def _block_inverses(indptr, indices, data, c_indptr, c_indices, c_data, node_ptr, node_dofs,
                    diag0, inv_full, inv_sub):   # pragma: no cover (compiled)
    block = np.empty((3, 3))
    sub = np.empty((3, 3))
    inv = np.empty((3, 3))
    w = diag0.shape[1]
    for blk in range(node_ptr.size - 1):
        s = node_ptr[blk]
        k = node_ptr[blk + 1] - s
        for a in range(3):
            for c in range(3):
                block[a, c] = 1.0 if a == c and a >= k else 0.0
        for a in range(k):
            i = node_dofs[s + a]
            for q in range(indptr[i], indptr[i + 1]):
                j = indices[q]
                for c in range(k):
                    if node_dofs[s + c] == j:
                        block[a, c] += data[q]
            for q in range(c_indptr[i], c_indptr[i + 1]):
                j = c_indices[q]
                for c in range(k):
                    if node_dofs[s + c] == j:
                        block[a, c] += c_data[q]
        for a in range(w):
            diag0[blk, a] = block[a, 0]
        _inverse3(block, inv)
        for a in range(w):
            for c in range(w):
                inv_full[blk, a, c] = inv[a, c]
        for a in range(3):
            for c in range(3):
                sub[a, c] = block[a, c] if a > 0 and c > 0 else (1.0 if a == c else 0.0)
        _inverse3(sub, inv)
        for a in range(w):
            for c in range(w):
                inv_sub[blk, a, c] = inv[a, c]


@njit(cache=True, nogil=True)
def block_gauss_seidel(indptr, indices, data, c_indptr, c_indices, c_data, x, b, node_ptr,
                       node_dofs, diag0, inv_full, inv_sub, mode, upper,
                       forward):   # pragma: no cover (compiled)
    """One sweep of node-block Gauss-Seidel for ``(A + C) x = b``, in place on ``x``
    (``A`` and the sparse update ``C`` as CSR triples, indices unsigned:
    :func:`unsigned_index`).

    ``mode[k]``: FREE (the block solve), BOUNDED (exact minimisation with
    ``x[first] <= upper[k]``), FIXED (the first unknown kept, the others solved).
    ``forward`` False sweeps the blocks in reverse order (a symmetric pair of sweeps).
    """
    none = np.zeros(0)
    tresca_block_gauss_seidel(indptr, indices, data, c_indptr, c_indices, c_data, x, b,
                              node_ptr, node_dofs, diag0, inv_full, inv_sub, mode, upper,
                              none, none, forward)


@njit(cache=True, nogil=True)
def tresca_block_gauss_seidel(indptr, indices, data, c_indptr, c_indices, c_data, x, b,
                              node_ptr, node_dofs, diag0, inv_full, inv_sub, mode, upper,
                              weight, centre, forward):   # pragma: no cover (compiled)
    """One sweep of node-block Gauss-Seidel for the energy ``1/2 x'(A + C)x - b'x +
    sum_k weight[k] |x_t,k - centre_k|`` (``x_t,k`` block ``k``'s unknowns after its first:
    one in 2D, two in 3D with the Euclidean norm), in place on ``x``; ``centre`` node-major,
    ``w - 1`` entries per block (``w = diag0.shape[1]``, the widest block).

    ``mode[k]``: as :func:`block_gauss_seidel`, and TRESCA (the exact minimiser over the
    block with ``x[first] <= upper[k]`` and the term: :func:`_tresca_block` in 2D,
    :func:`disc_block_minimiser` in 3D), TANGENT_FIXED (the tangential unknowns kept, the
    first solved), BOTH_FIXED (the block kept). With the modes of
    :func:`block_gauss_seidel` (``weight`` and ``centre`` then unread) it is that sweep.

    The loop body keeps a block's residual and update in scalars and hands arrays to no
    helper but :func:`_disc_block` (reached by the bounded blocks of a 3D Tresca step
    only): numba reference-counts every array a loop body passes through its branches,
    and where it cannot prune those counts each block pays several atomic operations,
    several times the sweep's arithmetic (docs/guide/measurements.md).
    """
    nb = node_ptr.size - 1
    nt = diag0.shape[1] - 1
    start, stop, stride = (0, nb, 1) if forward else (nb - 1, -1, -1)
    for blk in range(start, stop, stride):
        md = mode[blk]
        if md == BOTH_FIXED:
            continue
        s = node_ptr[blk]
        k = node_ptr[blk + 1] - s
        r0 = r1 = r2 = 0.0                     # b - (A + C) x on the block's unknowns
        for a in range(k):
            i = node_dofs[s + a]
            acc = b[i]
            for q in range(indptr[i], indptr[i + 1]):
                acc -= data[q] * x[indices[q]]
            for q in range(c_indptr[i], c_indptr[i + 1]):
                acc -= c_data[q] * x[c_indices[q]]
            if a == 0:
                r0 = acc
            elif a == 1:
                r1 = acc
            else:
                r2 = acc
        i0 = node_dofs[s]
        if md == TRESCA and k == 3:
            _disc_block(x, r0, r1, r2, blk, s, node_dofs, diag0, inv_sub, upper[blk],
                        weight[blk], centre, nt)
            continue
        if md == TRESCA:
            i1 = node_dofs[s + 1]
            x[i0], x[i1] = _tresca_block(x[i0], x[i1], r0, r1, diag0[blk, 0], diag0[blk, 1],
                                         1.0 / inv_sub[blk, 1, 1], inv_full[blk, 0, 0],
                                         inv_full[blk, 0, 1], inv_full[blk, 1, 0],
                                         inv_full[blk, 1, 1], upper[blk], weight[blk],
                                         centre[blk])
            continue
        if md == TANGENT_FIXED:
            x[i0] += r0 / diag0[blk, 0]
            continue
        # FREE, BOUNDED or FIXED: the block solve, clamped to the bound where it crosses
        # it (the first unknown at its bound and the others solved again), or the first
        # unknown kept
        d0 = d1 = d2 = 0.0
        clamp = False
        if md != FIXED:
            for a in range(k):
                acc = 0.0
                acc += inv_full[blk, a, 0] * r0
                if k > 1:
                    acc += inv_full[blk, a, 1] * r1
                if k > 2:
                    acc += inv_full[blk, a, 2] * r2
                if a == 0:
                    d0 = acc
                elif a == 1:
                    d1 = acc
                else:
                    d2 = acc
            clamp = md == BOUNDED and x[i0] + d0 > upper[blk]
        if md == FIXED or clamp:
            d0 = 0.0 if md == FIXED else upper[blk] - x[i0]
            q1 = r1 - diag0[blk, 1] * d0 if k > 1 else 0.0
            q2 = r2 - diag0[blk, 2] * d0 if k > 2 else 0.0
            for a in range(1, k):
                acc = 0.0
                acc += inv_sub[blk, a, 1] * q1
                if k > 2:
                    acc += inv_sub[blk, a, 2] * q2
                if a == 1:
                    d1 = acc
                else:
                    d2 = acc
        x[i0] += d0
        if k > 1:
            x[node_dofs[s + 1]] += d1
        if k > 2:
            x[node_dofs[s + 2]] += d2
        if clamp:
            x[i0] = upper[blk]


@njit(cache=True, nogil=True)
def _tresca_block(x0, x1, r0, r1, m00, m01, m11, inv00, inv01, inv10, inv11, upper, weight,
                  centre):   # pragma: no cover (compiled)
    """The exact minimiser of one 2D block's energy in its update ``d``::

        1/2 d'Md - r'd + weight |x1 + d1 - centre|   subject to   x0 + d0 <= upper

    (``M = [[m00, m01], [m01, m11]]``, ``M^-1`` by its entries ``inv..``): the block's new
    ``(x0, x1)``. The minimiser is one of six points: the normal unknown free or at its
    bound, times the tangential one sticking (``x1 = centre``) or slipping either way (the
    term linear); each such point solves its case's stationarity by a 2x2 or 1x1 solve.
    Of those that keep the bound, the one with the least energy is the minimiser (it is
    among them, and every one is feasible); the bound and the stick point are returned
    exactly.
    """
    h = upper - x0
    e = centre - x1
    best, best0, best1, at_bound, stick = np.inf, 0.0, 0.0, False, False
    for case in range(6):
        normal_bound = case < 3
        side = case % 3                        # 0: stick, 1: slip +, 2: slip -
        sign = 1.0 if side == 1 else -1.0
        if normal_bound:
            d0 = h
            d1 = e if side == 0 else (r1 - m01 * h - sign * weight) / m11
        elif side == 0:
            d1 = e
            d0 = (r0 - m01 * e) / m00
        else:
            d0 = inv00 * r0 + inv01 * (r1 - sign * weight)
            d1 = inv10 * r0 + inv11 * (r1 - sign * weight)
        if not normal_bound and d0 > h:
            continue
        energy = (0.5 * (m00 * d0 * d0 + 2.0 * m01 * d0 * d1 + m11 * d1 * d1)
                  - r0 * d0 - r1 * d1 + weight * abs(d1 - e))
        if energy < best:
            best, best0, best1, at_bound, stick = energy, d0, d1, normal_bound, side == 0
    return (upper if at_bound else x0 + best0), (centre if stick else x1 + best1)


@njit(cache=True, nogil=True)
def _disc_block(x, r0, r1, r2, blk, s, node_dofs, diag0, inv_sub, upper, weight, centre,
                nt):   # pragma: no cover (compiled)
    """One 3D block of :func:`tresca_block_gauss_seidel` in mode TRESCA, from its residual
    ``(r0, r1, r2)``: the block matrix from its first column and the inverse of its
    tangential part, the exact minimiser (:func:`disc_block_minimiser`), the bound and the
    stick point written exactly."""
    r = np.empty(3)
    d = np.empty(3)
    M = np.empty((3, 3))
    e = np.empty(2)
    r[0], r[1], r[2] = r0, r1, r2
    i0 = node_dofs[s]
    a11, a12, a22 = inv_sub[blk, 1, 1], inv_sub[blk, 1, 2], inv_sub[blk, 2, 2]
    det = a11 * a22 - a12 * a12
    M[0, 0], M[1, 0], M[2, 0] = diag0[blk, 0], diag0[blk, 1], diag0[blk, 2]
    M[0, 1], M[0, 2] = diag0[blk, 1], diag0[blk, 2]
    M[1, 1], M[1, 2], M[2, 1], M[2, 2] = a22 / det, -a12 / det, -a12 / det, a11 / det
    for j in range(2):
        e[j] = centre[blk * nt + j] - x[node_dofs[s + 1 + j]]
    case = disc_block_minimiser(M, r, upper - x[i0], weight, e, d)
    x[i0] = upper if case >= 2 else x[i0] + d[0]
    for j in range(2):
        i = node_dofs[s + 1 + j]
        x[i] = centre[blk * nt + j] if case % 2 == 1 else x[i] + d[1 + j]


@njit(cache=True, nogil=True)
def disc_block_minimiser(M, r, h, weight, e, d):   # pragma: no cover (compiled)
    """The exact minimiser ``d`` of one 3D block's energy::

        1/2 d'Md - r'd + weight |d_t - e|   subject to   d_0 <= h

    (``M`` 3 x 3 SPD, ``d_t = d[1:3]``, ``|.|`` Euclidean): the node block of a Tresca step
    after the box transformation (:mod:`solvers.kernels.contact_box`), written into ``d``. Returns
    the case: ``2 * at_bound + stick`` (``d_0 = h`` exactly; ``d_t = e`` exactly).

    The normal unknown free: eliminated, the tangential part minimises
    ``1/2 z'Sz - g'z + weight |z|`` (``z = d_t - e``, ``S`` the Schur complement
    ``M_tt - M_t0 M_0t / M_00``; :func:`_disc_prox`); if that point keeps ``d_0 <= h`` it is
    the minimiser (the problem is convex). Otherwise ``d_0 = h`` and the same with
    ``S = M_tt``. Stick (``z = 0``) where ``|g| <= weight``.
    """
    m00 = M[0, 0]
    S = np.empty((2, 2))
    g = np.empty(2)
    z = np.empty(2)
    for a in range(2):
        for c in range(2):
            S[a, c] = M[1 + a, 1 + c] - M[1 + a, 0] * M[0, 1 + c] / m00
    for a in range(2):
        g[a] = (r[1 + a] - M[1 + a, 0] * r[0] / m00) - (S[a, 0] * e[0] + S[a, 1] * e[1])
    stick = _disc_prox(S, g, weight, z)
    d[1], d[2] = e[0] + z[0], e[1] + z[1]
    d[0] = (r[0] - M[0, 1] * d[1] - M[0, 2] * d[2]) / m00
    if d[0] <= h:
        return 1 if stick else 0
    d[0] = h
    for a in range(2):
        for c in range(2):
            S[a, c] = M[1 + a, 1 + c]
    for a in range(2):
        g[a] = r[1 + a] - M[1 + a, 0] * h - (S[a, 0] * e[0] + S[a, 1] * e[1])
    stick = _disc_prox(S, g, weight, z)
    d[1], d[2] = e[0] + z[0], e[1] + z[1]
    return 3 if stick else 2


@njit(cache=True, nogil=True)
def _disc_prox(S, g, weight, z):   # pragma: no cover (compiled)
    """``z = argmin 1/2 z'Sz - g'z + weight |z|`` (``S`` 2 x 2 SPD), written into ``z``;
    True where ``z = 0`` (``|g| <= weight``).

    Else ``(S + weight / rho I) z = g`` with ``rho = |z|``: in the eigenbasis ``S = Q
    diag(l) Q'`` (``gq = Q'g``) ``rho`` is the root of the secular equation
    ``psi(rho) = 1 / phi(rho) - 1``, ``phi(rho) = (sum_k gq_k^2 / (l_k rho + weight)^2)^(1/2)``
    (``|z| / rho``), increasing (linear for one eigenvalue), between ``(|g| - weight) / l_max``
    and ``(|g| - weight) / l_min``; Newton's method on it, safeguarded by bisection of that
    bracket, to round-off.
    """
    norm_g = np.sqrt(g[0] * g[0] + g[1] * g[1])
    if norm_g <= weight:
        z[0], z[1] = 0.0, 0.0
        return True
    a, b, c = S[0, 0], S[0, 1], S[1, 1]
    half = 0.5 * (a - c)
    rad = np.sqrt(half * half + b * b)
    l1 = 0.5 * (a + c) + rad                      # the larger eigenvalue
    l2 = (a * c - b * b) / l1
    if rad == 0.0:
        q0, q1 = 1.0, 0.0
    elif half >= 0.0:                             # eigenvector of l1, the stabler form
        q0, q1 = half + rad, b
    else:
        q0, q1 = b, rad - half
    qn = np.sqrt(q0 * q0 + q1 * q1)
    q0, q1 = q0 / qn, q1 / qn
    g1 = q0 * g[0] + q1 * g[1]                    # components along (q0, q1), (-q1, q0)
    g2 = -q1 * g[0] + q0 * g[1]
    lo = (norm_g - weight) / l1
    hi = (norm_g - weight) / l2
    rho = lo
    for _ in range(200):
        s1, s2 = l1 * rho + weight, l2 * rho + weight
        t1, t2 = g1 / s1, g2 / s2
        phi = np.sqrt(t1 * t1 + t2 * t2)
        psi = 1.0 / phi - 1.0
        if psi == 0.0:
            break
        if psi < 0.0:
            lo = rho
        else:
            hi = rho
        if hi - lo <= 4e-16 * hi:
            break
        dphi = -(t1 * t1 * l1 / s1 + t2 * t2 * l2 / s2) / phi
        nxt = rho + psi * phi * phi / dphi        # rho - psi / psi', psi' = -dphi / phi^2
        if not (lo < nxt < hi):
            nxt = 0.5 * (lo + hi)
        if abs(nxt - rho) <= 2e-16 * rho:
            break
        rho = nxt
    w1 = rho * g1 / (l1 * rho + weight)
    w2 = rho * g2 / (l2 * rho + weight)
    z[0] = q0 * w1 - q1 * w2
    z[1] = q1 * w1 + q0 * w2
    return False


def with_pattern(A: sp.csr_matrix, pattern: sp.csr_matrix) -> sp.csr_matrix:
    """``A`` with explicit zeros added where ``pattern`` has entries and ``A`` has none
    (both sorted canonical CSR); two compiled passes, no temporaries of ``A``'s size."""
    counts = np.zeros(A.shape[0], dtype=np.int64)
    _merge_rows(A.indptr, A.indices, A.data, pattern.indptr, pattern.indices, counts,
                np.zeros(0, A.indices.dtype), np.zeros(0), np.zeros(1, np.int64), False)
    indptr = np.zeros(A.shape[0] + 1, dtype=np.int64)
    np.cumsum(counts, out=indptr[1:])
    dtype = np.int32 if indptr[-1] < np.iinfo(np.int32).max else np.int64
    indices = np.empty(int(indptr[-1]), dtype=dtype)
    data = np.empty(int(indptr[-1]))
    _merge_rows(A.indptr, A.indices, A.data, pattern.indptr, pattern.indices, counts,
                indices, data, indptr, True)
    return sp.csr_matrix((data, indices, indptr.astype(dtype)), shape=A.shape)


@njit(cache=True, nogil=True)
def _merge_rows(indptr, indices, data, p_indptr, p_indices, counts, out_indices, out_data,
                out_indptr, fill):   # pragma: no cover (compiled)
    """Per row, the union of two sorted index lists: counted (``fill`` False) or written
    with ``A``'s values and zeros (``fill`` True)."""
    for i in range(indptr.size - 1):
        a, a_end = indptr[i], indptr[i + 1]
        b, b_end = p_indptr[i], p_indptr[i + 1]
        w = out_indptr[i] if fill else 0
        n = 0
        while a < a_end or b < b_end:
            if b >= b_end or (a < a_end and indices[a] < p_indices[b]):
                j, v = indices[a], data[a]
                a += 1
            elif a >= a_end or p_indices[b] < indices[a]:
                j, v = p_indices[b], 0.0
                b += 1
            else:
                j, v = indices[a], data[a]
                a += 1
                b += 1
            if fill:
                out_indices[w + n] = j
                out_data[w + n] = v
            n += 1
        counts[i] = n

