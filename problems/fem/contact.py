"""Nodal contact constraints ``B u <= g`` between two bodies (thesis Alg. 7.1).

The *constrained* surface (thesis: surface ``l``) carries one inequality per
node ``P``; the *opposing* surface (thesis: surface ``l-1``) is given by its
facets (segments in 2D, triangles in 3D).  For each constrained node the
procedure **Parametrisation** of Alg. 7.1 finds a facet ``Delta`` and a point
``Q`` on it,

* case b, ``search="along_direction"`` (7.13): ``Q = P + lambda n`` along a
  prescribed unit vector ``n``;
* case a, ``search="closest_point"`` (7.12): ``Q`` is the closest point of the
  opposing surface,

and **Barycentric** (7.14) gives the weights ``w_k`` of ``Q`` in ``Delta``, so
that ``u(Q) = sum_k w_k u(P_k)``.

Sign convention (documented once, used everywhere)
--------------------------------------------------
``n`` points from the constrained node ``P`` towards the opposing body.  The
row of ``P`` is the linearised Signorini condition (2.33)::

    n . (u(P) - u(Q)) <= g,        g = <Q - P, n>,

i.e. ``B[P, P-dofs] = n`` and ``B[P, P_k-dofs] = -w_k n``.  ``g`` is the signed
distance from ``P`` to ``Q`` along ``n``: positive when the bodies are apart,
negative when ``P`` has penetrated the opposing body in the reference
configuration.  After a displacement ``u`` the gap along ``n`` between the
material points ``P`` and ``Q`` is ``<Q + u(Q) - P - u(P), n> = g - (B u)_P``,
so ``B u <= g`` is exactly non-penetration along ``n`` (first order in ``u``,
Lemma 2.1).

Alg. 7.1 writes ``G_P = sign<nu(Delta), n> |P - Q|``.  With ``nu`` the outward
normal of the opposing body and ``n = (Q - P)/|Q - P|`` (case a) this is the
*negative* of the physical gap, and in case b it does not see on which side of
``Delta`` the node lies.  We therefore use ``g = <Q - P, n>`` in both cases,
which equals ``|P - Q|`` for a separated node and ``-|P - Q|`` for a
penetrating one.  In case b the sign comes from ``lambda`` alone (no facet
orientation is needed).  In case a the side is decided by the outward normal of
the chosen facet: ``P`` is inside iff ``<P - Q, nu> < 0``; then
``n = (P - Q)/|P - Q|`` (still pointing into the opposing body) and
``g = -|P - Q|``; when ``P`` lies on the surface, ``n = -nu`` and ``g = 0``.
Case a therefore needs *outward oriented* opposing facets (2D: segment
``(a, b)`` has normal ``(b - a)`` turned clockwise, outward for a
counter-clockwise boundary; 3D: ``(b - a) x (c - a)``); :func:`orient_facets`
orients boundary facets from the volume cells.  Caveat: when ``Q`` lies on the
rim of an *open* opposing surface (``P`` beside it, not above it) the side is
still that of the facet plane, as in Alg. 7.1; such nodes are better kept out
of ``constrained_nodes`` or handled with case b (whose line then misses and
the node is dropped).

Search: a ``scipy.spatial.cKDTree`` over facet centroids gives the candidate
facets per node and exact tests pick one (the same answer as testing all
pairs), replacing the ADT of Sect. 7.6: ``O(N^C log N^{C})`` in the mean when
the gaps are comparable to the facet size (see :func:`contact_constraints`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

#: Alg. 7.1's two ways to find the opposing point ``Q`` of a constrained node ``P``:
#: along a prescribed direction (its case b, (7.13)) or the closest point (case a, (7.12)).
SEARCHES = ("along_direction", "closest_point")

#: The names the searches had before (Alg. 7.1's case letters): refused, naming the new one.
RENAMED_SEARCHES = {"a": "closest_point", "b": "along_direction"}


@dataclass
class ContactConstraints:
    """The nodal constraints ``B u <= g`` of Alg. 7.1 (one row per found node).

    Attributes
    ----------
    rows : (m,) int array
        Global id of the constrained node ``P`` behind each row.
    B : (m, n_nodes*dim) scipy.sparse.csr_matrix
        Row ``i``: ``n_i`` at the DOFs of ``P``, ``-w_ik n_i`` at the DOFs of the
        facet's vertices; DOFs are node-major, ``dof = node*dim + component``.
    g : (m,) array
        Signed gap ``<Q - P, n>``: > 0 apart, < 0 penetrating (module docstring).
    direction : (m, dim) array
        Unit vectors ``n`` (from ``P`` towards the opposing body).
    facet : (m,) int array
        Row index into ``opposing_facets`` of the facet holding ``Q``.
    facet_nodes : (m, dim) int array
        Its vertices ``P_1, ..., P_dim`` (global node ids), in facet order.
    weights : (m, dim) array
        Barycentric weights (7.14) of ``Q`` w.r.t. the facet's vertices (sum 1).
    target : (m, dim) array
        The point ``Q`` (reference configuration).
    found : (k,) bool array
        Per candidate in ``constrained_nodes``: whether it got a row;
        ``rows == constrained_nodes[found]``.
    dim : int
    search : str
        ``"closest_point"`` (case a) or ``"along_direction"`` (case b).
    """

    rows: np.ndarray
    B: sp.csr_matrix
    g: np.ndarray
    direction: np.ndarray
    facet: np.ndarray
    facet_nodes: np.ndarray
    weights: np.ndarray
    target: np.ndarray
    found: np.ndarray
    dim: int
    search: str

    @property
    def m(self) -> int:
        """Number of constraints."""
        return self.rows.size


# --------------------------------------------------------------------------- geometry

def facet_normals(points: np.ndarray, facets: np.ndarray) -> np.ndarray:
    """Unit normals ``nu(Delta)`` of segments (2D) or triangles (3D), (7.14).

    2D: segment ``(a, b)`` -> ``(b - a)`` turned clockwise, ``(dy, -dx)/|.|``;
    3D: ``(b - a) x (c - a) / |.|``.  Outward for a counter-clockwise boundary
    (2D) or triangles counter-clockwise seen from outside (3D).

    Raises
    ------
    ValueError
        If a facet is degenerate (zero length or area).
    """
    verts = np.asarray(points, dtype=float)[np.asarray(facets)]
    nu = _raw_normals(verts)
    size = np.linalg.norm(nu, axis=1)
    scale = np.max(np.linalg.norm(verts[:, 1:] - verts[:, :1], axis=2), axis=1) ** (verts.shape[1] - 1)
    bad = np.flatnonzero(size <= 1e-14 * np.maximum(scale, 1e-300))
    if bad.size:
        raise ValueError(f"opposing_facets: {bad.size} degenerate facets (zero length/area), "
                         f"first: {bad[:5].tolist()}")
    return nu / size[:, None]


def _raw_normals(verts: np.ndarray) -> np.ndarray:
    """Unnormalised normals of facets given by vertex coordinates (f, dim, dim)."""
    r1 = verts[:, 1] - verts[:, 0]
    if verts.shape[2] == 2:
        return np.stack([r1[:, 1], -r1[:, 0]], axis=1)
    return np.cross(r1, verts[:, 2] - verts[:, 0])


def barycentric(verts: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Barycentric weights of ``x`` projected onto the facet plane, (7.14).

    Solves ``s R1 + t R2 = X - P1 - <X - P1, nu> nu`` in the least-squares
    (Gram) form ``R R^T c = R (X - P1)``, which is the same projection.

    Parameters
    ----------
    verts : (p, dim, dim) array
        Vertex coordinates ``P1, P2[, P3]`` of ``p`` facets.
    x : (p, dim) array
        One point per facet.

    Returns
    -------
    (p, dim) array
        ``(1 - s [- t], s [, t])``; they sum to one.
    """
    r = verts[:, 1:] - verts[:, :1]                      # (p, dim-1, dim)
    gram = np.einsum("pid,pjd->pij", r, r)
    rhs = np.einsum("pid,pd->pi", r, x - verts[:, 0])
    if r.shape[1] == 1:
        coef = rhs / gram[:, :, 0]
    else:
        det = gram[:, 0, 0] * gram[:, 1, 1] - gram[:, 0, 1] * gram[:, 1, 0]
        coef = np.stack([gram[:, 1, 1] * rhs[:, 0] - gram[:, 0, 1] * rhs[:, 1],
                         gram[:, 0, 0] * rhs[:, 1] - gram[:, 1, 0] * rhs[:, 0]], axis=1) / det[:, None]
    return np.concatenate([1.0 - coef.sum(axis=1, keepdims=True), coef], axis=1)


def _line_facet(p: np.ndarray, n: np.ndarray, verts: np.ndarray, nu: np.ndarray, tol: float):
    """Case b of Alg. 7.1: intersect the lines ``P + lambda n`` with facet planes.

    Returns ``lam (p,)``, ``w (p, dim)`` and ``ok (p,)`` (line not parallel and
    ``Q`` inside the closed facet up to ``tol`` in barycentric coordinates).
    """
    denom = np.einsum("pd,pd->p", n, nu)
    parallel = np.abs(denom) <= 1e-12
    lam = np.einsum("pd,pd->p", verts[:, 0] - p, nu) / np.where(parallel, 1.0, denom)
    w = barycentric(verts, p + lam[:, None] * n)
    ok = ~parallel & np.all(w >= -tol, axis=1)
    return lam, w, ok


def _closest_on_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray):
    """Closest point parameter ``s`` in [0, 1] and squared distance, vectorised."""
    r = b - a
    s = np.clip(np.einsum("pd,pd->p", p - a, r) / np.einsum("pd,pd->p", r, r), 0.0, 1.0)
    d = p - (a + s[:, None] * r)
    return s, np.einsum("pd,pd->p", d, d)


def _closest_point(p: np.ndarray, verts: np.ndarray):
    """Case a of Alg. 7.1: closest point of each facet to ``p``; returns weights (p, dim)."""
    npair, dim = p.shape
    if dim == 2:
        s, _ = _closest_on_segment(p, verts[:, 0], verts[:, 1])
        return np.stack([1.0 - s, s], axis=1)
    w_in = barycentric(verts, p)
    inside = np.all(w_in >= 0.0, axis=1)
    best_d = np.full(npair, np.inf)
    w = np.zeros((npair, 3))
    for i, j in ((0, 1), (1, 2), (2, 0)):
        s, d2 = _closest_on_segment(p, verts[:, i], verts[:, j])
        better = d2 < best_d
        best_d = np.where(better, d2, best_d)
        w_edge = np.zeros((npair, 3))
        w_edge[:, i] = 1.0 - s
        w_edge[:, j] = s
        w[better] = w_edge[better]
    w[inside] = w_in[inside]
    return w


def orient_facets(points: np.ndarray, facets: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Boundary facets reordered so that :func:`facet_normals` points out of the body.

    Parameters
    ----------
    points : (n_nodes, dim) array
    facets : (f, dim) int array
        Boundary facets of the body made of ``cells``, in any orientation.
    cells : (c, dim+1) int array
        Its simplices (triangles in 2D, tetrahedra in 3D).

    Returns
    -------
    (f, dim) int array
        ``facets`` with two vertices swapped where the normal pointed inwards.

    Raises
    ------
    ValueError
        If a facet is not a face of any cell.
    """
    points = np.asarray(points, dtype=float)
    facets = np.asarray(facets)
    cells = np.asarray(cells)
    dim = points.shape[1]
    if facets.ndim != 2 or facets.shape[1] != dim:
        raise ValueError(f"facets: shape {facets.shape} not allowed; allowed: (f, {dim})")
    if cells.ndim != 2 or cells.shape[1] != dim + 1:
        raise ValueError(f"cells: shape {cells.shape} not allowed; allowed: (c, {dim + 1})")
    # every face of every cell, with the opposite vertex
    faces = np.concatenate([np.delete(cells, i, axis=1) for i in range(dim + 1)])
    opposite = np.concatenate([cells[:, i] for i in range(dim + 1)])
    keys = np.sort(np.concatenate([facets, faces]), axis=1)
    _, inv = np.unique(keys, axis=0, return_inverse=True)
    inv = inv.ravel()
    f = facets.shape[0]
    owner = np.full(inv.max() + 1, -1)
    owner[inv[f:]] = opposite                      # any cell having the face
    opp = owner[inv[:f]]
    missing = np.flatnonzero(opp < 0)
    if missing.size:
        raise ValueError(f"facets: {missing.size} facets are no face of any cell, "
                         f"first: {missing[:5].tolist()}")
    nu = _raw_normals(points[facets])
    inward = np.einsum("fd,fd->f", nu, points[opp] - points[facets[:, 0]]) > 0
    out = facets.copy()
    out[inward, 0], out[inward, 1] = facets[inward, 1], facets[inward, 0]
    return out


# --------------------------------------------------------------------------- validation

def _check_inputs(points, constrained_nodes, opposing_facets, dim, direction, search,
                  max_distance, n_nodes, tol):
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise ValueError(f"points: shape {points.shape} not allowed; allowed: (n_nodes, 2) or (n_nodes, 3)")
    if dim is None:
        dim = points.shape[1]
    if dim not in (2, 3) or dim != points.shape[1]:
        raise ValueError(f"dim: {dim!r} not allowed; allowed: points.shape[1] = {points.shape[1]}")
    if not np.all(np.isfinite(points)):
        raise ValueError("points: non-finite coordinates; allowed: finite numbers")
    if n_nodes is None:
        n_nodes = points.shape[0]
    if not isinstance(n_nodes, (int, np.integer)) or n_nodes < points.shape[0]:
        raise ValueError(f"n_nodes: {n_nodes!r} not allowed; allowed: an integer >= len(points) "
                         f"= {points.shape[0]}")
    n_nodes = int(n_nodes)
    if search in RENAMED_SEARCHES:
        raise ValueError(f"search: {search!r} was renamed to {RENAMED_SEARCHES[search]!r}; "
                         f"allowed: one of {', '.join(SEARCHES)}")
    if search not in SEARCHES:
        raise ValueError(f"search: {search!r} not allowed; allowed: one of {', '.join(SEARCHES)}")
    nodes = np.asarray(constrained_nodes)
    if nodes.ndim != 1 or (nodes.size and not np.issubdtype(nodes.dtype, np.integer)):
        raise ValueError(f"constrained_nodes: shape {nodes.shape}, dtype {nodes.dtype} not allowed; "
                         f"allowed: a 1-D integer array")
    nodes = nodes.astype(np.int64)
    if nodes.size and (nodes.min() < 0 or nodes.max() >= points.shape[0]):
        raise ValueError(f"constrained_nodes: ids must lie in [0, {points.shape[0]})")
    if np.unique(nodes).size != nodes.size:
        raise ValueError("constrained_nodes: repeated node ids not allowed; allowed: distinct ids")
    facets = np.asarray(opposing_facets)
    if facets.size == 0:
        facets = facets.reshape(0, dim)
    not_int = facets.size and not np.issubdtype(facets.dtype, np.integer)
    if facets.ndim != 2 or facets.shape[1] != dim or not_int:
        raise ValueError(f"opposing_facets: shape {facets.shape} not allowed; allowed: an integer "
                         f"array (f, {dim}) ({'segments' if dim == 2 else 'triangles'})")
    facets = facets.astype(np.int64)
    if facets.size and (facets.min() < 0 or facets.max() >= points.shape[0]):
        raise ValueError(f"opposing_facets: ids must lie in [0, {points.shape[0]})")
    max_distance = float(max_distance)
    if not max_distance >= 0:
        raise ValueError(f"max_distance: {max_distance!r} not allowed; allowed: a number >= 0 or inf")
    if not (0 <= tol < 0.5):
        raise ValueError(f"tol: {tol!r} not allowed; allowed: a number in [0, 0.5)")
    if search == "closest_point":
        dirs = None                     # n is the closest-point direction; direction is ignored
    else:
        if direction is None:
            raise ValueError("direction: required for search='along_direction'; allowed: a (dim,) vector "
                             "or a (len(constrained_nodes), dim) array")
        dirs = np.asarray(direction, dtype=float)
        if dirs.shape == (dim,):
            dirs = np.broadcast_to(dirs, (nodes.size, dim))
        if dirs.shape != (nodes.size, dim):
            raise ValueError(f"direction: shape {dirs.shape} not allowed; allowed: ({dim},) or "
                             f"({nodes.size}, {dim})")
        size = np.linalg.norm(dirs, axis=1)
        if not np.all(np.isfinite(dirs)) or np.any(size == 0):
            raise ValueError("direction: zero or non-finite vectors not allowed; allowed: finite, non-zero")
        dirs = dirs / size[:, None]
    return points, dim, n_nodes, nodes, facets, dirs, max_distance


# --------------------------------------------------------------------------- search

#: Constrained nodes handled per block (bounds the candidate-pair arrays' memory).
BLOCK = 1024


@dataclass(frozen=True)
class _Opposing:
    """The opposing surface prepared for the search (centroid KD-tree, normals)."""

    facets: np.ndarray        # (f, dim) node ids
    verts: np.ndarray         # (f, dim, dim) vertex coordinates
    nu: np.ndarray            # (f, dim) unit normals
    centroids: np.ndarray     # (f, dim)
    radii: np.ndarray         # (f,) distance centroid -> farthest own vertex
    radius: float             # max of radii
    tree: cKDTree             # over the centroids
    max_distance: float
    tol: float                # barycentric slack
    tol_len: float            # length tolerance (tol * diameter)


def _flatten(lists) -> tuple[np.ndarray, np.ndarray]:
    """Pairs ``(i, j)`` from a list (object array) of candidate lists."""
    counts = np.fromiter((len(c) for c in lists), dtype=np.int64, count=len(lists))
    owner = np.repeat(np.arange(len(lists)), counts)
    cand = (np.concatenate([np.asarray(c, dtype=np.int64) for c in lists]) if counts.sum()
            else np.zeros(0, dtype=np.int64))
    return owner, cand


def _pick(owner, key, second, facet, valid, k, tol_len):
    """Per owner ``0..k-1`` the valid pair with the smallest ``key``; ties within
    ``tol_len`` go to the smallest ``second``, then the smallest facet id.
    Returns a pair index per owner, -1 where none is valid."""
    best = np.full(k, np.inf)
    np.minimum.at(best, owner[valid], key[valid])
    idx = np.flatnonzero(valid)
    idx = idx[key[idx] <= best[owner[idx]] + tol_len]
    idx = idx[np.lexsort((facet[idx], second[idx], owner[idx]))]
    first_owner, first = np.unique(owner[idx], return_index=True)
    choice = np.full(k, -1, dtype=np.int64)
    choice[first_owner] = idx[first]
    return choice


def _not_own_facet(op: _Opposing, node_ids, cand):
    """Facets having the constrained node itself as a vertex are no candidates."""
    return ~np.any(op.facets[cand] == node_ids[:, None], axis=1)


def _upper_bound_a(op: _Opposing, p, node_ids):
    """Exact distance to the nearest of the few facets with the nearest centroids
    (own facets skipped): an upper bound of the case-a distance, inf if none."""
    kq = min(4 * p.shape[1], op.facets.shape[0])
    _, near = op.tree.query(p, k=kq)
    near = near.reshape(len(p), kq)
    owner = np.repeat(np.arange(len(p)), kq)
    cand = near.ravel()
    w = _closest_point(p[owner], op.verts[cand])
    dist = np.linalg.norm(p[owner] - np.einsum("pk,pkd->pd", w, op.verts[cand]), axis=1)
    dist[~_not_own_facet(op, node_ids[owner], cand)] = np.inf
    return dist.reshape(len(p), kq).min(axis=1)


def _search_a(op: _Opposing, points, nodes):
    """Case a (7.12): closest point, exact.

    Every facet within distance ``d`` of ``P`` has its centroid within ``d + R``;
    ``d`` is bounded by :func:`_upper_bound_a` (and ``max_distance``).  A cheap
    lower bound (distance to the facet plane and, in the plane, to the facet's
    circumscribing ball) prunes the candidates before the exact test.
    """
    k = nodes.size
    p_all = points[nodes]
    bound = np.minimum(_upper_bound_a(op, p_all, nodes), op.max_distance) + op.tol_len
    finite = np.isfinite(bound)
    radius = np.where(finite, bound + op.radius, np.inf)
    owner, cand = _flatten(op.tree.query_ball_point(p_all, r=radius))
    keep = _not_own_facet(op, nodes[owner], cand)
    owner, cand = owner[keep], cand[keep]
    rel = p_all[owner] - op.centroids[cand]
    plane = np.einsum("pd,pd->p", rel, op.nu[cand])
    lateral = np.maximum(np.linalg.norm(rel - plane[:, None] * op.nu[cand], axis=1)
                         - op.radii[cand], 0.0)
    keep = plane ** 2 + lateral ** 2 <= bound[owner] ** 2
    owner, cand = owner[keep], cand[keep]
    p = p_all[owner]
    w = _closest_point(p, op.verts[cand])
    q = np.einsum("pk,pkd->pd", w, op.verts[cand])
    diff = p - q
    dist = np.linalg.norm(diff, axis=1)
    side = np.einsum("pd,pd->p", diff, op.nu[cand])
    on_surface = dist <= op.tol_len
    align = np.where(on_surface, 1.0, np.abs(side) / np.where(on_surface, 1.0, dist))
    valid = dist <= op.max_distance + op.tol_len
    choice = _pick(owner, dist, -np.round(align, 8), cand, valid, k, op.tol_len)
    found = choice >= 0
    c = choice[found]
    on = on_surface[c]
    inside = side[c] < -op.tol_len
    direction = np.where(inside[:, None], diff[c], -diff[c]) / np.where(on, 1.0, dist[c])[:, None]
    direction[on] = -op.nu[cand[c][on]]
    g = np.where(inside, -dist[c], dist[c])
    g[on] = 0.0
    return found, cand[c], w[c], q[c], direction, g


def _test_b(op: _Opposing, p, n, nodes, owner, cand):
    """Exact line-facet tests for candidate pairs (owner indexes p, n, nodes)."""
    keep = _not_own_facet(op, nodes[owner], cand)
    owner, cand = owner[keep], cand[keep]
    lam, w, ok = _line_facet(p[owner], n[owner], op.verts[cand], op.nu[cand], op.tol)
    ok &= np.abs(lam) <= op.max_distance + op.tol_len
    return owner, cand, lam, w, ok


def _finish_b(op: _Opposing, p, n, k, owner, cand, lam, w, ok):
    """Pick the hit with the smallest ``|lambda|`` per node (ties: in front of P, lowest id)."""
    behind = (lam < -op.tol_len).astype(float)
    choice = _pick(owner, np.abs(lam), behind, cand, ok, k, op.tol_len)
    found = choice >= 0
    c = choice[found]
    return found, cand[c], w[c], p[found] + lam[c][:, None] * n[found], n[found].copy(), lam[c]


def _orthonormal_complement(n: np.ndarray) -> np.ndarray:
    """(dim, dim-1) orthonormal basis of the plane orthogonal to the unit vector n."""
    _, _, vt = np.linalg.svd(n[None, :])
    return vt[1:].T


def _search_b_constant(op: _Opposing, points, nodes, n, basis, proj_tree):
    """Case b (7.13), one direction: the line meets a facet only if the facet's
    projection onto ``n^perp`` contains P's: an exact (dim-1)-D ball search."""
    p = points[nodes]
    dirs = np.broadcast_to(n, p.shape)
    owner, cand = _flatten(proj_tree.query_ball_point(p @ basis, r=op.radius + op.tol_len))
    return _finish_b(op, p, dirs, nodes.size, *_test_b(op, p, dirs, nodes, owner, cand))


def _line_box(p, n, lo, hi, max_distance):
    """Parameter interval ``[a, b]`` of ``P + lambda n`` inside the box, |lambda| <= max_distance."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (lo - p) / n, (hi - p) / n
    zero = n == 0
    inside = (p >= lo) & (p <= hi)
    a_c = np.where(zero, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2))
    b_c = np.where(zero, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2))
    return (np.maximum(a_c.max(axis=1), -max_distance), np.minimum(b_c.min(axis=1), max_distance))


def _sample_intervals(alpha, beta, spacing):
    """Points covering each interval ``[alpha_i, beta_i]`` (empty if alpha > beta) with
    gaps <= spacing; returns (interval index, parameter)."""
    nonempty = alpha <= beta
    idx = np.flatnonzero(nonempty)
    length = beta[idx] - alpha[idx]
    count = np.ceil(length / spacing).astype(np.int64) + 1
    step = np.where(count > 1, length / np.maximum(count - 1, 1), 0.0)
    owner = np.repeat(idx, count)
    j = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    return owner, alpha[owner] + j * np.repeat(step, count)


def _search_b_lines(op: _Opposing, points, nodes, dirs):
    """Case b (7.13), one direction per node: exact search along each line.

    A facet hit at ``lambda`` has its centroid within ``R`` (max facet radius) of
    ``P + lambda n``, so sample points at spacing <= 2R with balls of radius 2R
    find every hit.  The samples start at ``|lambda| = d0 - R`` (no facet is
    nearer), stay inside the centroids' bounding box (+R) and grow outwards in
    annuli of doubling width until the best hit lies inside the covered range.
    """
    k = nodes.size
    p = points[nodes]
    R, tl = op.radius, op.tol_len
    lo, hi = op.centroids.min(axis=0) - R - tl, op.centroids.max(axis=0) + R + tl
    a, b = _line_box(p, dirs, lo, hi, op.max_distance + tl)
    reach = np.where(a <= b, np.maximum(np.abs(a), np.abs(b)), -np.inf)
    d0, _ = op.tree.query(p)
    inner = np.maximum(d0 - R - tl, 0.0)
    width = np.full(k, 4.0 * R)
    best = np.full(k, np.inf)
    todo = np.flatnonzero(inner <= reach)
    parts = []
    while todo.size:
        r_in, r_out = inner[todo], inner[todo] + width[todo]
        alpha = np.concatenate([np.maximum(a[todo], r_in), np.maximum(a[todo], -r_out)])
        beta = np.concatenate([np.minimum(b[todo], r_out), np.minimum(b[todo], -r_in)])
        which, lam_s = _sample_intervals(alpha, beta, 2.0 * R)
        owner_s = todo[which % todo.size]
        samples = p[owner_s] + lam_s[:, None] * dirs[owner_s]
        so, cand = _flatten(op.tree.query_ball_point(samples, r=2.0 * R + tl))
        key = np.unique(owner_s[so] * op.facets.shape[0] + cand)
        owner, cand = key // op.facets.shape[0], key % op.facets.shape[0]
        res = _test_b(op, p, dirs, nodes, owner, cand)
        ok = res[4]
        np.minimum.at(best, res[0][ok], np.abs(res[2][ok]))
        parts.append(tuple(x[ok] for x in res))
        final = (best[todo] + tl <= r_out) | (r_out >= reach[todo])
        todo = todo[~final]
        inner[todo] += width[todo]
        width[todo] *= 2.0
    if parts:
        owner, cand, lam, w, ok = (np.concatenate(x) for x in zip(*parts))
    else:
        owner, cand, lam, w, ok = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64),
                                   np.zeros(0), np.zeros((0, p.shape[1])), np.zeros(0, dtype=bool))
    return _finish_b(op, p, dirs, k, owner, cand, lam, w, ok)


# --------------------------------------------------------------------------- public API

def contact_constraints(points, constrained_nodes, opposing_facets, *, dim=None, direction=None,
                        search="along_direction", max_distance=np.inf, n_nodes=None,
                        tol=1e-10) -> ContactConstraints:
    """Matrix ``B`` and gap ``g`` of the nodal contact constraints, Alg. 7.1.

    Parameters
    ----------
    points : (n_nodes, dim) array
        Reference coordinates of both bodies' nodes (global numbering).
    constrained_nodes : (k,) int array
        Distinct node ids of the constrained surface (thesis surface ``l``).
    opposing_facets : (f, dim) int array
        Facets of the opposing surface (surface ``l-1``): segments (2D) or
        triangles (3D).  Case a needs them outward oriented
        (:func:`orient_facets`); case b does not.  Give only the part that
        may come into contact (``Gamma_C``): case b takes the hit closest
        to ``P`` along the line.  Facets having ``P`` as a vertex are skipped.
    dim : {2, 3}, optional
        Defaults to ``points.shape[1]`` (must agree with it).
    direction : (dim,) or (k, dim) array, optional
        Required for case b: ``n`` per node or one constant vector,
        pointing from the constrained towards the opposing body; normalised
        here.  Ignored by case a (``n`` is then the closest-point
        direction), so a scene can switch ``search`` without other changes.
    search : {"along_direction", "closest_point"}
        ``"along_direction"`` (Alg. 7.1 case b): ``Q = P + lambda n`` inside a facet (7.13),
        smallest ``|lambda|`` wins; ``"closest_point"`` (case a): ``Q`` closest point of the
        opposing surface (7.12).
    max_distance : float
        Nodes with no facet within this distance (``|lambda|`` in case b,
        ``|P - Q|`` in case a), or whose line misses every facet, get no row.
    n_nodes : int, optional
        Number of nodes for the columns of ``B`` (default ``len(points)``).
    tol : float
        Relative tolerance: barycentric slack for "``Q`` inside the facet" and
        ties (``tol * diameter`` of the whole configuration); ``Q`` on a shared
        vertex/edge gives one row, from the facet with the smallest index
        (case a: the facet whose normal is best aligned with ``P - Q`` first).

    Returns
    -------
    ContactConstraints
        ``B u <= g`` means ``n . (u(P) - u(Q)) <= <Q - P, n>``, i.e.
        non-penetration along ``n``; ``g < 0`` for initial penetration.

    Raises
    ------
    ValueError
        Naming the parameter, for shapes, ids, ``search``, ``direction``, ...

    Notes
    -----
    A KD-tree over facet centroids replaces the ADT of Sect. 7.6: case a and
    case b with one direction query a ball per node (case b in the projection
    onto ``n^perp``); case b with per-node directions samples the line outwards
    from the nearest possible ``|lambda|``.  All searches are exact (the same
    answer as testing all pairs), mean cost ``O(N^C log N^{C})`` when gaps are
    of the order of the facet size, growing with ``gap / facet size``
    otherwise; ``max_distance`` bounds it.
    """
    points, dim, n_nodes, nodes, facets, dirs, max_distance = _check_inputs(
        points, constrained_nodes, opposing_facets, dim, direction, search, max_distance,
        n_nodes, tol)
    k = nodes.size
    found = np.zeros(k, dtype=bool)
    fac, w, q, n, g = (np.zeros(0, dtype=np.int64), np.zeros((0, dim)), np.zeros((0, dim)),
                       np.zeros((0, dim)), np.zeros(0))
    if k and facets.shape[0]:
        verts = points[facets]
        nu = facet_normals(points, facets)
        centroids = verts.mean(axis=1)
        extent = np.ptp(np.concatenate([verts.reshape(-1, dim), points[nodes]]), axis=0)
        radii = np.max(np.linalg.norm(verts - centroids[:, None], axis=2), axis=1)
        op = _Opposing(facets=facets, verts=verts, nu=nu, centroids=centroids, radii=radii,
                       radius=float(radii.max()),
                       tree=cKDTree(centroids), max_distance=max_distance, tol=tol,
                       tol_len=tol * max(float(np.linalg.norm(extent)), 1e-300))
        if search == "closest_point":
            run = lambda sel: _search_a(op, points, nodes[sel])
        elif np.all(dirs == dirs[0]):
            basis = _orthonormal_complement(dirs[0])
            proj_tree = cKDTree(centroids @ basis)
            run = lambda sel: _search_b_constant(op, points, nodes[sel], dirs[0], basis, proj_tree)
        else:
            run = lambda sel: _search_b_lines(op, points, nodes[sel], dirs[sel])
        blocks = [run(np.arange(s, min(s + BLOCK, k))) for s in range(0, k, BLOCK)]
        found = np.concatenate([blk[0] for blk in blocks])
        fac, w, q, n, g = (np.concatenate([blk[i] for blk in blocks]) for i in range(1, 6))
    rows = nodes[found]
    facet_nodes = facets[fac] if fac.size else np.zeros((0, dim), dtype=np.int64)
    B = _assemble(rows, facet_nodes, w, n, n_nodes, dim)
    return ContactConstraints(rows=rows, B=B, g=g, direction=n, facet=fac, facet_nodes=facet_nodes,
                              weights=w, target=q, found=found, dim=dim, search=search)


def _assemble(rows, facet_nodes, w, n, n_nodes, dim) -> sp.csr_matrix:
    """``B[i, P-dofs] = n_i``, ``B[i, P_k-dofs] = -w_ik n_i`` (Alg. 7.1)."""
    m = rows.size
    comp = np.arange(dim)
    nodes = np.concatenate([rows[:, None], facet_nodes], axis=1)          # (m, 1+dim)
    coef = np.concatenate([np.ones((m, 1)), -w], axis=1)                  # (m, 1+dim)
    cols = nodes[:, :, None] * dim + comp                                 # (m, 1+dim, dim)
    vals = coef[:, :, None] * n[:, None, :]
    r = np.broadcast_to(np.arange(m)[:, None, None], cols.shape)
    B = sp.coo_matrix((vals.ravel(), (r.ravel(), cols.ravel())), shape=(m, n_nodes * dim)).tocsr()
    B.sum_duplicates()
    return B


def tangent_directions(direction: np.ndarray) -> np.ndarray:
    """Unit tangents of each row direction ``n``, node-major ``(m k, d)``, ``k = d - 1``.

    2D: ``t = (n_y, -n_x)`` (``n`` turned clockwise: ``n = (0, 1)`` gives ``t = (1, 0)``).
    3D: ``t_1``, the x axis projected onto the plane orthogonal to ``n`` and normalised
    (the y axis where ``n`` lies within 45 degrees of x), and ``t_2 = n x t_1``: an
    orthonormal right-handed frame ``(t_1, t_2, n)``; ``n = (0, 0, 1)`` gives the x and
    y axes.

    Raises
    ------
    ValueError
        For directions that are neither 2D nor 3D.
    """
    n = np.asarray(direction, dtype=float)
    if n.ndim != 2 or n.shape[1] not in (2, 3):
        raise ValueError(f"direction: shape {n.shape} is not allowed; allowed: (m, 2) or (m, 3)")
    if n.shape[1] == 2:
        return np.stack([n[:, 1], -n[:, 0]], axis=1)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    axis = np.where((np.abs(n[:, 0]) > np.sqrt(0.5))[:, None], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0])
    t1 = axis - np.sum(axis * n, axis=1, keepdims=True) * n
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(n, t1)
    return np.stack([t1, t2], axis=1).reshape(-1, 3)


def tangential_rows(cc: ContactConstraints, n_nodes: int) -> tuple[sp.csr_matrix, np.ndarray]:
    """The tangential rows of the constraints ``cc``: ``t_ij . (u(P) - sum_k w_k u(P_k))``.

    The same interpolation (Alg. 7.1, (7.14)) as the normal rows of ``cc.B`` with the
    unit tangents ``t_ij`` (:func:`tangent_directions`) in place of ``n_i``; ``d - 1``
    rows per constrained node, node-major (row ``i (d - 1) + j``).

    Returns
    -------
    T : (m (d-1), n_nodes*dim) csr_matrix
    tangent : (m (d-1), dim) array
    """
    t = tangent_directions(cc.direction)
    k = cc.dim - 1
    rep = lambda a: np.repeat(a, k, axis=0)
    return _assemble(rep(cc.rows), rep(cc.facet_nodes), rep(cc.weights), t, n_nodes,
                     cc.dim), t


def quadratic_constraints(cc: ContactConstraints, facet_nodes: np.ndarray,
                          n_nodes: int) -> ContactConstraints:
    """The constraints ``cc`` for P2 elements (Remark 7.11).

    The opposing point ``Q`` stays the one found on the flat facet through the
    opposing facet's vertices; ``u(Q)`` is interpolated by the facet's P2 shape
    functions (:func:`problems.fem.quadratic.facet_shape_functions`) instead of the
    barycentric weights (7.14). The P2 weights reproduce affine functions, so the
    gap ``g`` and :func:`gap_after` are unchanged.

    Parameters
    ----------
    cc : ContactConstraints
        Found on the vertex facets (``cc.facet_nodes`` ``(m, dim)``).
    facet_nodes : (m, 3) or (m, 6) int array
        The same facets with their edges' midpoints
        (:func:`problems.fem.quadratic.quadratic_facets`).
    n_nodes : int
        Number of P2 nodes (columns of ``B`` over ``dim``).
    """
    from problems.fem.quadratic import facet_shape_functions

    w = facet_shape_functions(cc.weights)
    if facet_nodes.shape != w.shape:
        raise ValueError(f"parameter 'facet_nodes': shape {facet_nodes.shape} is not allowed; "
                         f"allowed: {w.shape} (the facets' vertices, then their midpoints)")
    return replace(cc, B=_assemble(cc.rows, facet_nodes, w, cc.direction, n_nodes, cc.dim),
                   facet_nodes=facet_nodes, weights=w)


def restrict_to_free(B, free_dofs) -> sp.csr_matrix:
    """Columns ``free_dofs`` of ``B`` (full nodal DOFs -> unknowns), as CSR.

    Raises
    ------
    ValueError
        If ``free_dofs`` is not a 1-D integer array of column indices of ``B``.
    """
    B = sp.csr_matrix(B)
    free = np.asarray(free_dofs)
    if free.ndim != 1 or (free.size and not np.issubdtype(free.dtype, np.integer)):
        raise ValueError(f"free_dofs: shape {free.shape}, dtype {free.dtype} not allowed; "
                         f"allowed: a 1-D integer array")
    if free.size and (free.min() < 0 or free.max() >= B.shape[1]):
        raise ValueError(f"free_dofs: indices must lie in [0, {B.shape[1]})")
    return sp.csr_matrix(B[:, free])


def gap_after(points, cc: ContactConstraints, u_full) -> np.ndarray:
    """Gap along ``n`` between the material points ``P`` and ``Q`` after displacement.

    ``<(Q + u(Q)) - (P + u(P)), n>`` with ``u(Q) = sum_k w_k u(P_k)`` and the
    reference pairing; equals ``g - B u_full`` (< 0 means penetration).  For a
    new pairing on the deformed configuration call :func:`contact_constraints`
    with ``points + u``.

    Parameters
    ----------
    points : (n_nodes, dim) array
        The reference coordinates used to build ``cc``.
    cc : ContactConstraints
    u_full : (n_nodes*dim,) or (n_nodes, dim) array
        Full nodal displacement, node-major.
    """
    points = np.asarray(points, dtype=float)
    u = np.asarray(u_full, dtype=float)
    if u.size != points.size:
        raise ValueError(f"u_full: size {u.size} not allowed; allowed: points.size = {points.size}")
    if cc.m == 0:
        return np.zeros(0)
    x = points + u.reshape(points.shape)
    xq = np.einsum("mk,mkd->md", cc.weights, x[cc.facet_nodes])
    return np.einsum("md,md->m", xq - x[cc.rows], cc.direction)
