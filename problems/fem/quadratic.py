"""Second-order (P2) Lagrange elements on simplex meshes (thesis Remark 7.11).

The thesis "also used Lagrange elements of second order" with the nodal
constraints of Alg. 7.1 at every P2 node of the constrained surface and the
opposing point parametrised on the *flat* facet through the opposing facet's
vertices (Remark 7.11). This module holds what P2 adds to the P1 code of
:mod:`problems.fem.elasticity`; :func:`problems.fem.two_body.assemble_two_body`
uses it when a scene asks for ``degree=2``.

Conventions
-----------
* Nodes: the mesh's vertices keep their ids ``0..n_vertices-1``; the midpoint of
  edge ``e`` (of :func:`quadratic_mesh`'s ``edges``) is node ``n_vertices + e``.
  Edges are straight (subparametric: the geometry stays the P1 mesh's, as in
  Remark 7.11), so every midpoint is the mean of its edge's vertices.
* Cells: ``(n_cells, 6)`` triangles ``[v0, v1, v2, m01, m12, m02]`` and
  ``(n_cells, 10)`` tetrahedra ``[v0..v3, m01, m12, m02, m03, m13, m23]``
  (the local edge order of :data:`problems.fem.mesh.TET_EDGES`, scikit-fem's).
  Surface facets follow the same order: segments ``[v0, v1, m01]``, triangles
  ``[v0, v1, v2, m01, m12, m02]``.
* DOFs are node-major, ``node * d + component``, as for P1.

The stiffness matrix is assembled by scikit-fem (``ElementTriP2``,
``ElementTetP2``); loads of constant data and the surface masses are closed
forms (exact integrals of the P2 shape functions).

Pure functions of arrays: no files, no clocks.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from problems.fem.mesh import TET_EDGES, orient_positive, simplex_edges

__all__ = [
    "CELL_EDGES", "QuadraticMesh", "quadratic_mesh", "quadratic_mesh_of", "linear_to_quadratic",
    "quadratic_facets", "shape_functions", "facet_shape_functions", "stiffness_matrix_p2",
    "stiffness_matrix_p2_skfem", "body_force_vector_p2",
    "traction_vector_p2", "surface_mass_p2", "linear_subcells", "midpoint_supports",
]

#: Local edges of a cell, in the order of the midpoint columns (scikit-fem's).
CELL_EDGES = {2: np.array([[0, 1], [1, 2], [0, 2]]), 3: TET_EDGES}

#: Local edges of a facet (segment or triangle) with ``k`` vertices, in midpoint order.
FACET_EDGES = {2: np.array([[0, 1]]), 3: CELL_EDGES[2]}

#: The P2 lumped surface mass per unit facet measure: vertices, then midpoints
#: (Hinton-Rock-Zienkiewicz: the consistent mass's diagonal scaled to the facet's
#: measure). On segments it equals the row sums ``1/6, 1/6, 2/3``; on triangles the
#: row sums would be ``0`` at the vertices, HRZ gives ``3/57`` and ``16/57``.
HRZ_SHARE = {2: (np.full(2, 1 / 6), np.array([2 / 3])),
             3: (np.full(3, 3 / 57), np.full(3, 16 / 57))}


@dataclass
class QuadraticMesh:
    """A P2 mesh: nodes (vertices, then edge midpoints) and cells with their midpoints.

    Attributes
    ----------
    points : (n_vertices + n_edges, d) array
    cells : (n_cells, 6) or (n_cells, 10) int array
    edges : (n_edges, 2) int array
        Sorted vertex pairs; edge ``e`` has the midpoint node ``n_vertices + e``.
    n_vertices : int
    """

    points: np.ndarray
    cells: np.ndarray
    edges: np.ndarray
    n_vertices: int

    def midpoint(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Node ids of the midpoints of the edges ``(a, b)`` (vertex ids, any order).

        Raises
        ------
        ValueError
            If some ``(a, b)`` is not an edge of the mesh.
        """
        return edge_lookup(self.edges, self.n_vertices, a, b) + self.n_vertices


def edge_lookup(edges: np.ndarray, n_vertices: int, a, b) -> np.ndarray:
    """Index into ``edges`` (sorted pairs, lexicographic) of the edges ``(a, b)``."""
    a, b = np.asarray(a, dtype=np.int64), np.asarray(b, dtype=np.int64)
    key = np.minimum(a, b) * n_vertices + np.maximum(a, b)
    table = edges[:, 0] * n_vertices + edges[:, 1]
    idx = np.searchsorted(table, key)
    idx = np.minimum(idx, len(table) - 1)
    if key.size and not np.all(table[idx] == key):
        raise ValueError("an edge asked for is not an edge of the mesh")
    return idx


def quadratic_mesh(points: np.ndarray, cells: np.ndarray) -> QuadraticMesh:
    """The P2 nodes and cells of a P1 simplex mesh (see the module docstring)."""
    points = np.asarray(points, dtype=float)
    cells = np.asarray(cells, dtype=np.int64)
    d = points.shape[1]
    if cells.ndim != 2 or cells.shape[1] != d + 1:
        raise ValueError(f"parameter 'cells': shape {cells.shape} is not allowed; allowed: "
                         f"(n_cells, {d + 1}) vertex ids of {d}D simplices")
    n = len(points)
    edges, cell_edges = simplex_edges(cells, n, CELL_EDGES[d])
    mid = 0.5 * (points[edges[:, 0]] + points[edges[:, 1]])
    cells2 = np.hstack([cells, n + cell_edges])
    return QuadraticMesh(points=np.vstack([points, mid]), cells=cells2, edges=edges, n_vertices=n)


def quadratic_mesh_of(points: np.ndarray, cells: np.ndarray) -> QuadraticMesh:
    """The :class:`QuadraticMesh` of P2 nodes and cells made by :func:`quadratic_mesh`
    (a ContactQP's mesh at ``degree=2``): its edges read off the cells' vertex columns.

    Raises
    ------
    ValueError
        If ``cells`` are not P2 cells whose midpoint columns are ``n_vertices + edge``.
    """
    points = np.asarray(points, dtype=float)
    cells = np.asarray(cells, dtype=np.int64)
    d = points.shape[1]
    n_local = {2: 6, 3: 10}[d]
    if cells.ndim != 2 or cells.shape[1] != n_local:
        raise ValueError(f"parameter 'cells': shape {cells.shape} is not allowed; allowed: "
                         f"(n_cells, {n_local}) P2 cells of a {d}D mesh")
    n = int(cells[:, :d + 1].max()) + 1
    edges, cell_edges = simplex_edges(cells[:, :d + 1], n, CELL_EDGES[d])
    if not np.array_equal(cells[:, d + 1:], n + cell_edges):
        raise ValueError("parameter 'cells': the midpoint columns are not the nodes "
                         "n_vertices + edge of quadratic_mesh's numbering")
    return QuadraticMesh(points=points, cells=cells, edges=edges, n_vertices=n)


def linear_to_quadratic(n_vertices: int, edges: np.ndarray) -> sp.csr_matrix:
    """Nodal prolongation from P1 on the vertices to P2 on the same mesh: the identity
    at the vertices, the mean of the two vertices at a midpoint (exact interpolation)."""
    ne = len(edges)
    rows = np.concatenate([np.arange(n_vertices), np.repeat(n_vertices + np.arange(ne), 2)])
    cols = np.concatenate([np.arange(n_vertices), edges.ravel()])
    vals = np.concatenate([np.ones(n_vertices), np.full(2 * ne, 0.5)])
    return sp.csr_matrix((vals, (rows, cols)), shape=(n_vertices + ne, n_vertices))


def quadratic_facets(mesh: QuadraticMesh, facets: np.ndarray) -> np.ndarray:
    """Vertex facets ``(k, d)`` with their edges' midpoints appended (module docstring)."""
    facets = np.asarray(facets, dtype=np.int64)
    loc = FACET_EDGES[facets.shape[1]]
    mids = [mesh.midpoint(facets[:, i], facets[:, j]) for i, j in loc]
    return np.column_stack([facets, *mids]) if len(facets) else np.zeros(
        (0, facets.shape[1] + len(loc)), dtype=np.int64)


def shape_functions(bary: np.ndarray) -> np.ndarray:
    """P2 shape functions of a segment, triangle or tetrahedron (``bary`` ``(m, 2)``,
    ``(m, 3)``, ``(m, 4)``) at points given by their barycentric coordinates, in the
    node order of the module docstring: ``lam_i (2 lam_i - 1)`` at the vertices,
    ``4 lam_i lam_j`` at the midpoints. They sum to one and reproduce affine functions,
    so the opposing point ``Q`` of Alg. 7.1 is the same as with the P1 weights
    (Remark 7.11)."""
    lam = np.asarray(bary, dtype=float)
    vert = lam * (2.0 * lam - 1.0)
    loc = FACET_EDGES[2] if lam.shape[1] == 2 else CELL_EDGES[lam.shape[1] - 1]
    mids = 4.0 * lam[:, loc[:, 0]] * lam[:, loc[:, 1]]
    return np.hstack([vert, mids])


#: Alg. 7.1's weights on a facet (Remark 7.11) are the P2 shape functions.
facet_shape_functions = shape_functions


def stiffness_matrix_p2_skfem(mesh: QuadraticMesh, E, nu) -> sp.csr_matrix:
    """P2 stiffness matrix of ``a(u, v) = int lam div u div v + 2 mu eps(u) : eps(v)``
    (plane strain in 2D), assembled by scikit-fem (the cross-check of
    :func:`stiffness_matrix_p2`).

    Parameters
    ----------
    mesh : QuadraticMesh
    E, nu : float or (n_cells,) array

    Returns
    -------
    (N d, N d) scipy.sparse.csr_matrix
        Node-major DOFs in the numbering of ``mesh``; exactly symmetric.
    """
    from skfem import (Basis, BilinearForm, ElementTetP2, ElementTriP2, ElementVector, MeshTet,
                       MeshTri, asm)
    from skfem.helpers import ddot, sym_grad, trace

    from problems.fem.elasticity import lame_parameters

    d = mesh.points.shape[1]
    n_cells, n_v = len(mesh.cells), mesh.n_vertices
    lam, mu = lame_parameters(np.broadcast_to(np.asarray(E, float), (n_cells,)),
                              np.broadcast_to(np.asarray(nu, float), (n_cells,)))
    verts = mesh.cells[:, :d + 1]
    if d == 2:
        sk = MeshTri(np.ascontiguousarray(mesh.points[:n_v].T), np.ascontiguousarray(verts.T), sort_t=False, validate=False)
        basis = Basis(sk, ElementVector(ElementTriP2()))
        sk_edges, edge_dofs = sk.facets.T, basis.facet_dofs
    else:
        sk = MeshTet(np.ascontiguousarray(mesh.points[:n_v].T),
                     np.ascontiguousarray(orient_positive(mesh.points, verts).T), sort_t=False,
                     validate=False)
        basis = Basis(sk, ElementVector(ElementTetP2()))
        sk_edges, edge_dofs = sk.edges.T, basis.edge_dofs

    @BilinearForm
    def elasticity(u, v, w):
        eu, ev = sym_grad(u), sym_grad(v)
        return w["lam"] * trace(eu) * trace(ev) + 2.0 * w["mu"] * ddot(eu, ev)

    nqp = basis.X.shape[1]
    K = asm(elasticity, basis, lam=np.repeat(lam[:, None], nqp, axis=1),
            mu=np.repeat(mu[:, None], nqp, axis=1)).tocsr()
    # scikit-fem numbers the vertices' DOFs node-major, then its edges': map both to ours
    comp = np.arange(d)
    perm = np.empty(basis.N, dtype=np.int64)
    perm[basis.nodal_dofs.T.ravel()] = (np.arange(n_v)[:, None] * d + comp).ravel()
    mid = n_v + edge_lookup(mesh.edges, n_v, sk_edges[:, 0], sk_edges[:, 1])
    perm[edge_dofs.T.ravel()] = (mid[:, None] * d + comp).ravel()
    n = len(mesh.points) * d
    P = sp.csr_matrix((np.ones(basis.N), (perm, np.arange(basis.N))), shape=(n, basis.N))
    K = P @ K @ P.T
    K = (0.5 * (K + K.T)).tocsr()
    K.sort_indices()
    return K


#: Degree-2 quadrature on the reference simplex in barycentric coordinates (weights sum
#: to one): exact for the products of P2 gradients (Strang-Fix 3- and 4-point rules).
_QUADRATURE = {2: (np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]]),
                   np.full(3, 1 / 3)),
               3: ((lambda a, b: np.array([[a, b, b, b], [b, a, b, b], [b, b, a, b],
                                           [b, b, b, a]]))(0.5854101966249685, 0.1381966011250105),
                   np.full(4, 1 / 4))}


def _shape_gradients(grad_lam: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """Gradients ``(n_cells, n_local, d)`` of the P2 functions at barycentric point ``lam``:
    ``(4 lam_i - 1) grad lam_i`` at the vertices, ``4 (lam_j grad lam_i + lam_i grad lam_j)``
    at the midpoints."""
    d = grad_lam.shape[2]
    loc = CELL_EDGES[d]
    vert = (4.0 * lam - 1.0)[None, :, None] * grad_lam
    mids = 4.0 * (lam[loc[:, 1]][None, :, None] * grad_lam[:, loc[:, 0]]
                  + lam[loc[:, 0]][None, :, None] * grad_lam[:, loc[:, 1]])
    return np.concatenate([vert, mids], axis=1)


def stiffness_matrix_p2(mesh: QuadraticMesh, E, nu, chunk: int = 50_000) -> sp.csr_matrix:
    """P2 stiffness matrix of ``a(u, v) = int lam div u div v + 2 mu eps(u) : eps(v)``
    (plane strain in 2D), a vectorised closed form.

    The element matrix is ``sum_q w_q |T| (lam g_ai g_bj + mu (g_a . g_b) delta_ij +
    mu g_aj g_bi)`` with the P2 gradients ``g`` at the points of a degree-2 rule (exact:
    the gradients are affine), for all cells of a chunk at once. It equals scikit-fem's
    assembly (:func:`stiffness_matrix_p2_skfem`, a test) and is much faster than it
    (docs/guide/measurements.md).

    Parameters
    ----------
    mesh : QuadraticMesh
    E, nu : float or (n_cells,) array
    chunk : int
        Cells per pass (bounds the memory: ~15 kB per cell of a chunk in 3D).

    Returns
    -------
    (N d, N d) scipy.sparse.csr_matrix
        Node-major DOFs in the numbering of ``mesh``; exactly symmetric.
    """
    from problems.fem.elasticity import barycentric_gradients, lame_parameters

    d = mesh.points.shape[1]
    cells = mesh.cells
    n_cells, n_loc = cells.shape
    lam, mu = lame_parameters(np.broadcast_to(np.asarray(E, float), (n_cells,)),
                              np.broadcast_to(np.asarray(nu, float), (n_cells,)))
    lam, mu = np.broadcast_to(lam, (n_cells,)), np.broadcast_to(mu, (n_cells,))
    points_q, weights_q = _QUADRATURE[d]
    n_dofs = len(mesh.points) * d
    dofs_local = (cells[:, :, None] * d + np.arange(d)).reshape(n_cells, n_loc * d)
    K = sp.csr_matrix((n_dofs, n_dofs))
    eye = np.eye(d)
    for start in range(0, n_cells, chunk):
        part = slice(start, min(start + chunk, n_cells))
        grad_lam, vol = barycentric_gradients(mesh.points, cells[part, :d + 1])
        Ke = np.zeros((len(vol), n_loc, d, n_loc, d))
        for lam_q, w_q in zip(points_q, weights_q):
            g = _shape_gradients(grad_lam, lam_q)                        # (c, a, i)
            gg = np.einsum("cai,cbi->cab", g, g)
            Ke += (w_q * lam[part])[:, None, None, None, None] * np.einsum("cai,cbj->caibj", g, g)
            Ke += (w_q * mu[part])[:, None, None, None, None] * (
                gg[:, :, None, :, None] * eye[None, None, :, None, :]
                + np.einsum("caj,cbi->caibj", g, g))
        Ke *= vol[:, None, None, None, None]
        Ke = Ke.reshape(len(vol), n_loc * d, n_loc * d)
        rows = np.repeat(dofs_local[part], n_loc * d, axis=1).ravel()
        cols = np.tile(dofs_local[part], (1, n_loc * d)).ravel()
        K = K + sp.csr_matrix((Ke.ravel(), (rows, cols)), shape=(n_dofs, n_dofs))
    K = (0.5 * (K + K.T)).tocsr()
    K.sort_indices()
    return K


def _simplex_measures(points: np.ndarray, verts: np.ndarray) -> np.ndarray:
    """Measures of cells (``d + 1`` vertices) or facets (``d`` vertices)."""
    from problems.fem.elasticity import facet_measures, barycentric_gradients

    if verts.shape[1] == points.shape[1] + 1:
        return barycentric_gradients(points, verts)[1]
    return facet_measures(points, verts)


def _scatter(elems: np.ndarray, share: np.ndarray, n_nodes: int) -> np.ndarray:
    """``share`` ``(k, n_local, d)`` added to the nodes ``elems`` ``(k, n_local)``."""
    d = share.shape[2]
    out = np.empty((n_nodes, d))
    for c in range(d):
        out[:, c] = np.bincount(elems.ravel(), weights=share[:, :, c].ravel(), minlength=n_nodes)
    return out.ravel()


#: ``int_T phi_i / |T|`` of the P2 functions: triangles (vertices 0, midpoints 1/3),
#: tetrahedra (vertices -1/20, midpoints 1/5).
CELL_INTEGRALS = {2: np.r_[np.zeros(3), np.full(3, 1 / 3)],
                  3: np.r_[np.full(4, -1 / 20), np.full(6, 1 / 5)]}
#: The same on facets: segments (1/6, 1/6, 2/3), triangles (0, 0, 0, 1/3, 1/3, 1/3).
FACET_INTEGRALS = {2: np.array([1 / 6, 1 / 6, 2 / 3]), 3: CELL_INTEGRALS[2]}


def body_force_vector_p2(points: np.ndarray, cells: np.ndarray, force: np.ndarray) -> np.ndarray:
    """Consistent load ``int f . v`` of a cell-wise constant force density ``(n_cells, d)``."""
    d = points.shape[1]
    vol = _simplex_measures(points, cells[:, :d + 1])
    share = vol[:, None, None] * CELL_INTEGRALS[d][None, :, None] * force[:, None, :]
    return _scatter(cells, share, len(points))


def traction_vector_p2(points: np.ndarray, facets: np.ndarray, traction) -> np.ndarray:
    """Consistent load of a constant traction ``(d,)`` on quadratic facets
    (:func:`quadratic_facets`)."""
    d = points.shape[1]
    meas = _simplex_measures(points, facets[:, :d])
    tr = np.broadcast_to(np.asarray(traction, float), (len(facets), d))
    share = meas[:, None, None] * FACET_INTEGRALS[d][None, :, None] * tr[:, None, :]
    return _scatter(facets, share, len(points))


def surface_mass_p2(points: np.ndarray, facets: np.ndarray, n_nodes: int | None = None) -> np.ndarray:
    """Lumped P2 surface mass on quadratic facets: HRZ lumping (:data:`HRZ_SHARE`), positive
    at every node of a facet; sums to the surface's measure."""
    d = points.shape[1]
    n_nodes = len(points) if n_nodes is None else n_nodes
    meas = _simplex_measures(points, facets[:, :d])
    share = np.concatenate(HRZ_SHARE[d])
    return np.bincount(facets.ravel(), weights=(meas[:, None] * share).ravel(), minlength=n_nodes)


#: Sub-simplices of a P2 cell on its nodes (local columns): 4 triangles, or the 4 corner
#: tetrahedra and the inner octahedron split along the diagonal m02-m13.
_SUBCELLS = {2: np.array([[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]]),
             3: np.array([[0, 4, 6, 7], [4, 1, 5, 8], [6, 5, 2, 9], [7, 8, 9, 3],
                          [6, 8, 4, 5], [6, 8, 5, 9], [6, 8, 9, 7], [6, 8, 7, 4]])}


def linear_subcells(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """The P1 simplices on a P2 mesh's nodes (each cell split into 4 triangles or 8
    tetrahedra): for plots and cell-wise output, with positively oriented tetrahedra."""
    d = points.shape[1]
    sub = cells[:, _SUBCELLS[d]].reshape(-1, d + 1)
    return orient_positive(points, sub) if d == 3 else sub


def midpoint_supports(edges: np.ndarray, n_vertices: int, dim: int, fixed: np.ndarray,
                      values: np.ndarray, boundary_edges: np.ndarray):
    """Prescribed P2 DOFs from the vertices' ones: a boundary edge's midpoint component is
    prescribed where both its vertices' are, to their mean (exact for affine data).

    Parameters
    ----------
    edges : (n_edges, 2) int array
        The mesh's edges (:class:`QuadraticMesh`); midpoint of edge ``e`` is node
        ``n_vertices + e``.
    fixed, values : arrays
        Prescribed DOFs ``vertex * dim + component`` and their values.
    boundary_edges : (k,) int array
        Indices into ``edges`` of the edges on the boundary (an interior edge between two
        supported vertices stays free).

    Returns
    -------
    fixed, values
        The vertices' and the midpoints' prescribed DOFs (P2 node numbering).
    """
    fixed = np.asarray(fixed, dtype=np.int64)
    prescribed = np.full(n_vertices * dim, np.nan)
    prescribed[fixed] = values
    e = edges[boundary_edges]
    comp = np.arange(dim)
    va = prescribed[(e[:, :1] * dim + comp)]
    vb = prescribed[(e[:, 1:] * dim + comp)]
    both = ~np.isnan(va) & ~np.isnan(vb)
    rows, cols = np.nonzero(both)
    mid_dofs = (n_vertices + boundary_edges[rows]) * dim + cols
    return (np.concatenate([fixed, mid_dofs]),
            np.concatenate([np.asarray(values, float), 0.5 * (va + vb)[rows, cols]]))
