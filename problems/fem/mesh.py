"""Simplex meshes and nested uniform refinement hierarchies.

Meshes are plain arrays: ``points`` (n_nodes, d) and ``cells`` (n_cells, d+1).
Uniform refinement (red refinement via scikit-fem) returns the nodal
prolongation matrix with it, so a multilevel solver can use the hierarchy
(Sect. 8.6, Alg. 8.5). Curved boundaries are kept on the curve by projecting
new boundary nodes (``project``) after each refinement; the prolongation stays
the plain P1 one (midpoint averaging), which is what nested iteration needs.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.sparse as sp
from skfem import MeshTet, MeshTri


@dataclass
class Hierarchy:
    """A mesh and its uniform refinements.

    ``points[k]``, ``cells[k]`` is level k; ``prolongations[k]`` maps nodal values
    on level k to level k+1 (shape ``(n_{k+1}, n_k)``).
    """

    points: list = field(default_factory=list)
    cells: list = field(default_factory=list)
    prolongations: list = field(default_factory=list)


def structured_square(n: int, x0: float = 0.0, y0: float = 0.0, size: float = 1.0):
    """Structured triangulation of a square with n x n cells: ``(points, cells)``."""
    if n < 1:
        raise ValueError(f"parameter 'n': {n!r} is not allowed; allowed: an integer >= 1")
    m = MeshTri.init_tensor(np.linspace(x0, x0 + size, n + 1), np.linspace(y0, y0 + size, n + 1))
    return m.p.T.copy(), m.t.T.copy()


def netgen_disk(center: tuple[float, float], radius: float, maxh: float):
    """Unstructured triangulation of a disk by netgen (OCC geometry): ``(points, cells)``."""
    from netgen.occ import Circle, OCCGeometry

    if not (radius > 0 and maxh > 0):
        raise ValueError("parameters 'radius' and 'maxh' must be positive")
    geo = OCCGeometry(Circle(tuple(map(float, center)), float(radius)).Face(), dim=2)
    ngmesh = geo.GenerateMesh(maxh=maxh)
    points = np.array([p.p[:2] for p in ngmesh.Points()], dtype=float)
    cells = np.array([[v.nr - 1 for v in el.vertices] for el in ngmesh.Elements2D()], dtype=np.int64)
    return points, _counter_clockwise(points, cells)


def _counter_clockwise(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    a, b, c = (points[cells[:, i]] for i in range(3))
    det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    cells = cells.copy()
    cells[det < 0, 1], cells[det < 0, 2] = cells[det < 0, 2], cells[det < 0, 1].copy()
    return cells


def refine(points: np.ndarray, cells: np.ndarray,
           project: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None):
    """One uniform (red) refinement: ``(points, cells, prolongation)``.

    New nodes are edge midpoints (scikit-fem's ordering: old nodes first, then
    one per edge); ``prolongation`` is the P1 interpolation from the old to the
    new nodes. ``project(points, is_boundary)`` may move new boundary nodes
    (e.g. onto a circle) and returns the corrected points.
    """
    d = points.shape[1]
    mesh = (MeshTri if d == 2 else MeshTet)(np.ascontiguousarray(points.T), np.ascontiguousarray(cells.T))
    fine = mesh.refined()
    n_old = points.shape[0]
    edges = mesh.edges if d == 3 else mesh.facets
    new_pts = fine.p.T.copy()
    n_new = new_pts.shape[0]
    n_edges = edges.shape[1]
    if n_new != n_old + n_edges:
        raise RuntimeError("unexpected node layout after refinement")
    mid = 0.5 * (points[edges[0]] + points[edges[1]])
    if not np.allclose(new_pts[n_old:], mid, atol=1e-12 * max(1.0, np.abs(points).max())):
        raise RuntimeError("scikit-fem's refined() no longer numbers midpoints by edge")
    rows = np.concatenate([np.arange(n_old), np.repeat(np.arange(n_old, n_new), 2)])
    cols = np.concatenate([np.arange(n_old), edges.T.ravel()])
    vals = np.concatenate([np.ones(n_old), np.full(2 * n_edges, 0.5)])
    prolongation = sp.csr_matrix((vals, (rows, cols)), shape=(n_new, n_old))
    if project is not None:
        is_boundary = np.zeros(n_new, dtype=bool)
        is_boundary[fine.boundary_nodes()] = True
        new_pts = project(new_pts, is_boundary)
    return new_pts, fine.t.T.copy(), prolongation


def uniform_hierarchy(points: np.ndarray, cells: np.ndarray, levels: int,
                      project: Callable | None = None) -> Hierarchy:
    """The coarse mesh and ``levels`` uniform refinements of it."""
    h = Hierarchy([points], [cells], [])
    for _ in range(levels):
        p, c, P = refine(h.points[-1], h.cells[-1], project)
        h.points.append(p)
        h.cells.append(c)
        h.prolongations.append(P)
    return h


def project_to_circle(center, radius: float, only_outside_of: float | None = None):
    """A ``project`` callback for :func:`refine` that puts boundary nodes on a circle."""
    c = np.asarray(center, dtype=float)

    def project(points: np.ndarray, is_boundary: np.ndarray) -> np.ndarray:
        out = points.copy()
        v = out[is_boundary] - c
        r = np.linalg.norm(v, axis=1)
        out[is_boundary] = c + v * (radius / r)[:, None]
        return out

    return project


def dof_prolongation(node_prolongation: sp.spmatrix, dim: int, free_fine: np.ndarray,
                     free_coarse: np.ndarray) -> sp.csr_matrix:
    """Vector-valued P1 prolongation restricted to the free DOFs of both levels.

    DOFs are node-major (``node * dim + component``). Columns of prescribed
    coarse DOFs are dropped: corrections vanish there.
    """
    P = sp.kron(node_prolongation, sp.identity(dim), format="csr")
    return P[free_fine][:, free_coarse].tocsr()


def nested_prolongation(points: np.ndarray, cells: np.ndarray, fine_points: np.ndarray,
                        tol: float = 1e-9) -> sp.csr_matrix:
    """P1 prolongation to a nested refinement whose nodes are coarse nodes or
    coarse edge midpoints (any red-type refinement, any node numbering).

    Each fine node is matched (KD-tree, distance < ``tol`` times the mesh
    diameter) to a coarse node (weight 1) or to the midpoint of a coarse edge
    (weights 1/2, 1/2). A fine node matching neither raises ValueError.
    """
    from scipy.spatial import cKDTree

    d = points.shape[1]
    pairs = np.vstack([cells[:, [i, j]] for i in range(d + 1) for j in range(i + 1, d + 1)])
    edges = np.unique(np.sort(pairs, axis=1), axis=0)
    anchors = np.vstack([points, 0.5 * (points[edges[:, 0]] + points[edges[:, 1]])])
    scale = np.ptp(points, axis=0).max()
    dist, idx = cKDTree(anchors).query(fine_points)
    if np.any(dist > tol * scale):
        raise ValueError("the fine mesh is not a nested (midpoint) refinement of the coarse one")
    n = len(points)
    is_node = idx < n
    fine = np.arange(len(fine_points))
    e = edges[idx[~is_node] - n]
    rows = np.concatenate([fine[is_node], np.repeat(fine[~is_node], 2)])
    cols = np.concatenate([idx[is_node], e.ravel()])
    vals = np.concatenate([np.ones(is_node.sum()), np.full(2 * len(e), 0.5)])
    return sp.csr_matrix((vals, (rows, cols)), shape=(len(fine_points), n))
