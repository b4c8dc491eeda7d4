"""Conforming local refinement of simplex meshes by bisection (thesis Sect. 7.4).

The adaptive loop of Sect. 7.4 refines the marked elements and whatever else
keeps the mesh conforming. Two bisection rules share one closure loop
(:func:`bisect`):

* ``"newest_vertex"`` (2D): each triangle stores its refinement edge as the
  edge opposite its first vertex (the *newest* vertex); a bisection puts the new
  node first in both children. Angles stay bounded below independently of the
  number of refinements (Mitchell; Binev-Dahmen-DeVore). The initial labels are
  the longest edges (:func:`label_longest_edge`).
* ``"longest_edge"`` (2D and 3D, Rivara): every bisection splits the longest
  edge of the simplex (ties broken by the global edge key, so that neighbours
  agree).

Closure: after each sweep every simplex containing a bisected edge as a
whole (a hanging node) is bisected by its own rule, until none is left, so
the result is conforming without hanging nodes.

Nesting (Sect. 8.6, Alg. 8.5): old nodes keep their numbers, every new node
``k`` is the midpoint of its two ``parents[k - n_old]``, numbered before it
(they are old nodes or nodes made earlier in the same call), and the nodal P1
prolongation follows from the parents (:func:`parent_prolongation`). New nodes
on a curved boundary are moved onto it by ``project(points, is_boundary)``
(e.g. :func:`problems.fem.mesh.project_to_circle`) after the prolongation is
fixed, as :func:`problems.fem.mesh.refine` does for the uniform hierarchy.

Pure functions of numpy arrays: no files, no clocks.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.sparse as sp

from problems.fem.elasticity import boundary_facets
from problems.fem.mesh import TET_EDGES, Hierarchy, orient_positive, signed_volumes

RULES = ("newest_vertex", "longest_edge")
_TRI_EDGES = np.array([[0, 1], [1, 2], [0, 2]])
_KEY = np.int64(2 ** 31)              # edge key min * _KEY + max (node ids < 2**31)


@dataclass
class Refinement:
    """One local refinement step.

    Attributes
    ----------
    points : (n_fine, d) array
        Old nodes first (unchanged unless projected: they are not), then the new ones.
    cells : (n_cells, d + 1) int array
        The conforming fine mesh; with ``"newest_vertex"`` the first vertex of
        each triangle is its newest vertex.
    prolongation : (n_fine, n_old) sparse
        Nodal P1 prolongation (identity on old nodes, averages of the parents).
    parents : (n_fine - n_old, 2) int array
        The two nodes whose midpoint each new node is (before projection).
    """

    points: np.ndarray
    cells: np.ndarray
    prolongation: sp.csr_matrix
    parents: np.ndarray


def _local_edges(d: int) -> np.ndarray:
    return _TRI_EDGES if d == 2 else TET_EDGES


def _edge_keys(cells: np.ndarray, local: np.ndarray) -> np.ndarray:
    a, b = cells[:, local[:, 0]], cells[:, local[:, 1]]
    return np.minimum(a, b) * _KEY + np.maximum(a, b)


def label_longest_edge(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Triangles rotated cyclically so that the edge opposite vertex 0 is the longest.

    The initial labelling of newest-vertex bisection; a cyclic rotation keeps
    the orientation and the mesh.
    """
    pts = np.asarray(points, dtype=float)
    t = np.asarray(cells, dtype=np.int64)
    if t.ndim != 2 or t.shape[1] != 3:
        raise ValueError(f"parameter 'cells': shape {t.shape} is not allowed; "
                         "allowed: (n_cells, 3) triangles")
    opp = np.stack([np.sum((pts[t[:, (k + 1) % 3]] - pts[t[:, (k + 2) % 3]]) ** 2, axis=1)
                    for k in range(3)], axis=1)
    k = np.argmax(opp, axis=1)
    return t[np.arange(len(t))[:, None], (k[:, None] + np.arange(3)) % 3]


def parent_prolongation(n_old: int, parents: np.ndarray) -> sp.csr_matrix:
    """Nodal P1 prolongation ``(n_old + k, n_old)`` of nodes made by bisection.

    New node ``n_old + i`` takes the mean of its ``parents[i]``, which are
    numbered before it; a parent that is itself new contributes its own row,
    so the result interpolates every function linear on the coarse cells.
    """
    parents = np.asarray(parents, dtype=np.int64).reshape(-1, 2)
    n_new = len(parents)
    if n_new and (parents.max(axis=1) >= n_old + np.arange(n_new)).any():
        raise ValueError("parameter 'parents': a new node must be numbered after its parents")
    rows = [sp.identity(n_old, format="csr")]
    # generation of each new node: 1 + the larger generation of its parents
    gen = np.zeros(n_old + n_new, dtype=np.int64)
    while True:                                   # fixed point; as many sweeps as generations
        g = 1 + np.maximum(gen[parents[:, 0]], gen[parents[:, 1]])
        if np.array_equal(g, gen[n_old:]):
            break
        gen[n_old:] = g
    P = sp.vstack(rows + [sp.csr_matrix((n_new, n_old))], format="csr")
    for g in range(1, int(gen.max(initial=0)) + 1):
        idx = np.flatnonzero(gen[n_old:] == g)
        Pg = 0.5 * (P[parents[idx, 0]] + P[parents[idx, 1]])
        sel = sp.csr_matrix((np.ones(len(idx)), (n_old + idx, np.arange(len(idx)))),
                            shape=(n_old + n_new, len(idx)))
        P = P + sel @ Pg
    P = P.tocsr()
    P.eliminate_zeros()
    return P


def bisect(points: np.ndarray, cells: np.ndarray, marked, rule: str = "newest_vertex",
           project: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None) -> Refinement:
    """Bisect the ``marked`` cells and close the mesh conformingly (module docstring).

    Parameters
    ----------
    points : (n_nodes, d) array, d in {2, 3}
    cells : (n_cells, d + 1) int array
        With ``"newest_vertex"`` vertex 0 of each triangle is its newest vertex
        (label a mesh once with :func:`label_longest_edge`).
    marked : (n_cells,) bool array or int array of cell indices
    rule : {"newest_vertex", "longest_edge"}
        ``"newest_vertex"`` is 2D only.
    project : callable, optional
        ``project(points, is_boundary) -> points`` applied once at the end to
        the new boundary nodes.

    Returns
    -------
    Refinement

    Raises
    ------
    ValueError
        Naming the parameter for bad shapes, indices or ``rule``.
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise ValueError(f"parameter 'points': shape {pts.shape} is not allowed; "
                         "allowed: (n_nodes, d), d in {2, 3}")
    d, n_old = pts.shape[1], len(pts)
    t = np.array(cells, dtype=np.int64)
    if t.ndim != 2 or t.shape[1] != d + 1:
        raise ValueError(f"parameter 'cells': shape {t.shape} is not allowed; "
                         f"allowed: (n_cells, {d + 1})")
    if rule not in RULES:
        raise ValueError(f"parameter 'rule': {rule!r} is not allowed; allowed: {', '.join(RULES)}")
    if rule == "newest_vertex" and d != 2:
        raise ValueError("parameter 'rule': 'newest_vertex' is not allowed in 3D; "
                         "allowed: 'longest_edge'")
    m = np.asarray(marked)
    if m.dtype == bool:
        if m.shape != (len(t),):
            raise ValueError(f"parameter 'marked': shape {m.shape} is not allowed; "
                             f"allowed: ({len(t)},) booleans or cell indices")
        todo = np.flatnonzero(m)
    else:
        todo = np.unique(m.astype(np.int64).ravel())
        if todo.size and (todo[0] < 0 or todo[-1] >= len(t)):
            raise ValueError(f"parameter 'marked': cell indices must lie in [0, {len(t) - 1}]")
    local = _local_edges(d)
    new_pts: list[np.ndarray] = []
    parents: list[np.ndarray] = []
    split_keys = np.zeros(0, dtype=np.int64)        # sorted keys of bisected edges
    split_mid = np.zeros(0, dtype=np.int64)         # their midpoints, same order
    n_nodes = n_old
    all_pts = pts
    while todo.size:
        c = t[todo]
        if rule == "newest_vertex":
            li = np.full(len(c), 1)
            lj = np.full(len(c), 2)
        else:
            x = all_pts[c]
            length = np.sum((x[:, local[:, 0]] - x[:, local[:, 1]]) ** 2, axis=2)
            keys = _edge_keys(c, local)
            longest = length >= length.max(axis=1, keepdims=True) * (1.0 - 1e-12)
            e = np.argmax(np.where(longest, keys, -1), axis=1)
            li, lj = local[e, 0], local[e, 1]
        r = np.arange(len(c))
        a, b = c[r, li], c[r, lj]
        key = np.minimum(a, b) * _KEY + np.maximum(a, b)
        ukey, first = np.unique(key, return_index=True)
        fresh = ~np.isin(ukey, split_keys)
        k_new = ukey[fresh]
        ends = np.stack([a[first[fresh]], b[first[fresh]]], axis=1)
        ids = n_nodes + np.arange(len(k_new))
        mids = 0.5 * (all_pts[ends[:, 0]] + all_pts[ends[:, 1]])
        new_pts.append(mids)
        parents.append(np.sort(ends, axis=1))
        all_pts = np.vstack([all_pts, mids])
        n_nodes += len(k_new)
        split_keys = np.concatenate([split_keys, k_new])
        split_mid = np.concatenate([split_mid, ids])
        order = np.argsort(split_keys)
        split_keys, split_mid = split_keys[order], split_mid[order]
        mid = split_mid[np.searchsorted(split_keys, key)]
        child1, child2 = c.copy(), c.copy()
        child1[r, lj] = mid                         # keeps vertex a
        child2[r, li] = mid                         # keeps vertex b
        if rule == "newest_vertex":   # new node first: (m, t0, t1) and (m, t2, t0)
            child1 = child1[:, [2, 0, 1]]
            child2 = child2[:, [1, 2, 0]]
        t[todo] = child1
        t = np.vstack([t, child2])
        # closure: every cell that still holds a bisected edge as a whole
        todo = np.flatnonzero(np.isin(_edge_keys(t, local), split_keys).any(axis=1))
    parents_arr = np.vstack(parents) if parents else np.zeros((0, 2), dtype=np.int64)
    P = parent_prolongation(n_old, parents_arr)
    if project is not None and n_nodes > n_old:
        is_boundary = np.zeros(n_nodes, dtype=bool)
        is_boundary[np.unique(boundary_facets(t))] = True
        is_boundary[:n_old] = False
        all_pts = project(all_pts, is_boundary)
    if d == 3:
        t = orient_positive(all_pts, t)
    return Refinement(points=all_pts, cells=t, prolongation=P, parents=parents_arr)


def default_rule(dim: int) -> str:
    """The rule chosen per dimension (compared by
    ``workflows/scripts/bench_adaptive_refinement.py``): newest-vertex bisection in
    2D (angles bounded below by theory, fewest nodes for the same marking, as
    few as longest-edge bisection), longest-edge bisection in 3D (the same
    meshes as scikit-fem's ``MeshTet.refined(marked)`` at a similar time, with
    the parents recorded; netgen's bisection needed more nodes and reached smaller
    dihedral angles: docs/guide/measurements.md)."""
    return "newest_vertex" if dim == 2 else "longest_edge"


def grow(h: Hierarchy, marked, project: Callable | None = None, rule: str | None = None
         ) -> Hierarchy:
    """``h`` with one more level: its finest mesh with ``marked`` cells bisected.

    Without marked cells the new level is a copy of the finest one with the
    identity prolongation, so that bodies refined together keep equally many
    levels. The input hierarchy is not modified.
    """
    pts, cells = h.points[-1], h.cells[-1]
    m = np.asarray(marked)
    any_marked = m.any() if m.dtype == bool else m.size > 0
    if any_marked:
        ref = bisect(pts, cells, m, rule or default_rule(pts.shape[1]), project)
        new = (ref.points, ref.cells, ref.prolongation)
    else:
        new = (pts.copy(), cells.copy(), sp.identity(len(pts), format="csr"))
    return Hierarchy(h.points + [new[0]], h.cells + [new[1]], h.prolongations + [new[2]])


# --------------------------------------------------------------------------- checks
def facet_counts(cells: np.ndarray) -> np.ndarray:
    """How many cells share each facet (unique facets): 1 on the boundary, 2 inside."""
    t = np.asarray(cells, dtype=np.int64)
    n_loc = t.shape[1]
    f = np.sort(np.stack([np.delete(t, k, axis=1) for k in range(n_loc)], axis=1)
                .reshape(-1, n_loc - 1), axis=1)
    _, counts = np.unique(f, axis=0, return_counts=True)
    return counts


def boundary_measure(points: np.ndarray, cells: np.ndarray) -> float:
    """Total length (2D) or area (3D) of the facets that belong to one cell only.

    A hanging node leaves facets inside the domain that belong to one cell only,
    so a refinement is free of hanging nodes iff (with conformity of the rest)
    this measure is unchanged by it on a straight-sided domain.
    """
    f = boundary_facets(np.asarray(cells))
    x = np.asarray(points, dtype=float)[f]
    if x.shape[1] == 2:
        return float(np.linalg.norm(x[:, 1] - x[:, 0], axis=1).sum())
    return float(0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]),
                                      axis=1).sum())


def min_angle(points: np.ndarray, cells: np.ndarray) -> float:
    """Smallest interior angle (degrees) of a triangle mesh."""
    x = np.asarray(points, dtype=float)[np.asarray(cells)]
    out = np.inf
    for k in range(3):
        u = x[:, (k + 1) % 3] - x[:, k]
        v = x[:, (k + 2) % 3] - x[:, k]
        c = np.einsum("ij,ij->i", u, v) / (np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1))
        out = min(out, float(np.degrees(np.arccos(np.clip(c, -1, 1))).min()))
    return out


def min_measure(points: np.ndarray, cells: np.ndarray) -> float:
    """Smallest signed area (2D) or volume (3D): positive for a valid oriented mesh."""
    pts = np.asarray(points, dtype=float)
    t = np.asarray(cells)
    if pts.shape[1] == 3:
        return float(signed_volumes(pts, t).min())
    a, b, c = pts[t[:, 0]], pts[t[:, 1]], pts[t[:, 2]]
    return float((0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1])
                         - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))).min())
