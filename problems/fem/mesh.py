"""Simplex meshes and nested uniform refinement hierarchies.

Meshes are plain arrays: ``points`` (n_nodes, d) and ``cells`` (n_cells, d+1),
tetrahedra positively oriented. Uniform (red) refinement returns the nodal
prolongation matrix with it, so a multilevel solver can use the hierarchy
(Sect. 8.6, Alg. 8.5): triangles via scikit-fem, tetrahedra by
:func:`red_refine_tets` (the inner octahedron split along its shortest
diagonal; scikit-fem 12 measures that diagonal in x and y only, which lets the
quality decay level by level, and its fine-mesh boundary search costs more than
the refinement). Curved boundaries are kept on the curve by projecting new
boundary nodes (``project``) after each refinement; the prolongation stays the
plain P1 one (midpoint averaging), which is what nested iteration needs.

Generators: structured squares and cubes (Kuhn/Freudenthal: 6 tetrahedra per
hexahedron sharing its main diagonal; the cube with 2n cells per edge is the
Freudenthal refinement of the one with n, so :func:`nested_prolongation` is the
exact P1 interpolation), netgen disks and balls (OCC geometry).

netgen's meshes may be kept between processes (:func:`keep_meshes`: the workflow's
scripts keep them in a directory, ``workflows.mesh_store``), as numba keeps its compiled
kernels: a study's processes (the test set's families, the contact levels, every study on
cube-sphere) each mesh the same ball, which takes netgen seconds. An entry is keyed by
the generator's name and source, netgen's version and the arguments, and holds exactly
the arrays netgen gave.
"""
from __future__ import annotations

import functools
import hashlib
import inspect
from dataclasses import dataclass, field
from importlib import metadata
from typing import Callable, Protocol

import numpy as np
import scipy.sparse as sp
from skfem import MeshTet, MeshTri

from problems.qp import Extrusion


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
    return structured_rectangle(n, n, x0, y0, size, size)


def structured_rectangle(nx: int, ny: int, x0: float = 0.0, y0: float = 0.0,
                         width: float = 1.0, height: float = 1.0):
    """Structured triangulation of a rectangle with nx x ny cells: ``(points, cells)``."""
    for name, n in (("nx", nx), ("ny", ny)):
        if n < 1:
            raise ValueError(f"parameter '{name}': {n!r} is not allowed; allowed: an integer >= 1")
    m = MeshTri.init_tensor(np.linspace(x0, x0 + width, nx + 1),
                            np.linspace(y0, y0 + height, ny + 1))
    return m.p.T.copy(), m.t.T.copy()


class MeshStore(Protocol):
    """Where generated meshes are kept between processes (``workflows.mesh_store``)."""

    def load(self, key: str) -> tuple[np.ndarray, np.ndarray] | None:
        """The ``(points, cells)`` kept under ``key``, or None."""

    def keep(self, key: str, points: np.ndarray, cells: np.ndarray) -> None:
        """Keep ``(points, cells)`` under ``key``."""


_STORE: list[MeshStore | None] = [None]


def keep_meshes(store: MeshStore | None) -> None:
    """Read netgen's meshes from ``store`` where an earlier process kept them, and keep
    the ones generated here in it (``None``: generate every mesh, keep none)."""
    _STORE[0] = store


@functools.lru_cache(maxsize=None)
def _identity(generate: Callable) -> str:
    """The generator's name, source and netgen's version, read once per process."""
    return repr((generate.__qualname__, inspect.getsource(generate),
                 metadata.version("netgen-mesher")))


def mesh_key(generate: Callable, center: tuple, numbers: tuple) -> str:
    """The key of ``generate(center, *numbers)``'s mesh: the generator's name and a SHA-256
    of its name, its source, netgen's version and the arguments (a changed generator or
    netgen meshes anew)."""
    digest = hashlib.sha256(repr((_identity(generate), tuple(center),
                                  tuple(numbers))).encode()).hexdigest()
    return f"{generate.__name__}-{digest[:32]}"


def _kept(generate: Callable) -> Callable:
    """``generate(center, *numbers)``, read from the :func:`keep_meshes` store where it
    holds the mesh, else generated and kept there."""

    def kept(center, *numbers):
        store = _STORE[0]
        if store is None:
            return generate(np.array(center), *numbers)
        key = mesh_key(generate, center, numbers)
        found = store.load(key)
        if found is not None:
            return found
        points, cells = generate(np.array(center), *numbers)
        store.keep(key, points, cells)
        return points, cells

    return kept


def _generated_once(generate: Callable) -> Callable:
    """``generate(center, *numbers)`` run once per process and arguments, and once per
    store where meshes are kept (:func:`keep_meshes`): a scene builds its meshes at every
    level and coupling of a study, and netgen's meshing of the same geometry (seconds for
    the ball) gives the same mesh each time. Each caller gets its own copies of the
    arrays."""
    cached = functools.lru_cache(maxsize=32)(_kept(generate))

    @functools.wraps(generate)
    def once(center, *numbers):
        points, cells = cached(tuple(map(float, center)), *map(float, numbers))
        return points.copy(), cells.copy()

    return once


@_generated_once
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


def netgen_half_disk(center: tuple[float, float], radius: float, maxh: float,
                     side: str = "lower"):
    """Unstructured triangulation of a half disk by netgen (OCC geometry), the half below
    (``side="lower"``) or above (``"upper"``) the horizontal chord through ``center``:
    ``(points, cells)``."""
    if not (radius > 0 and maxh > 0):
        raise ValueError("parameters 'radius' and 'maxh' must be positive")
    if side not in ("lower", "upper"):
        raise ValueError(f"parameter 'side': {side!r} is not allowed; allowed: lower, upper")
    return _netgen_half_disk(center, radius, maxh, 1.0 if side == "upper" else -1.0)


@_generated_once
def _netgen_half_disk(center: tuple[float, float], radius: float, maxh: float,
                      sign: float):
    """:func:`netgen_half_disk` with ``sign`` +1 (upper) or -1 (lower)."""
    from netgen.occ import Circle, OCCGeometry, Rectangle

    cx, cy = map(float, center)
    r = float(radius)
    box = Rectangle(2.2 * r, 1.1 * r).Face()
    box = box.Move((cx - 1.1 * r, cy if sign > 0 else cy - 1.1 * r, 0))
    geo = OCCGeometry(Circle((cx, cy), r).Face() * box, dim=2)
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

    New nodes are edge midpoints (old nodes first, then one per edge);
    ``prolongation`` is the P1 interpolation from the old to the new nodes.
    ``project(points, is_boundary)`` may move new boundary nodes (e.g. onto a
    circle or a sphere) and returns the corrected points.
    """
    d = points.shape[1]
    if d == 3:
        new_pts, new_cells, edges = red_refine_tets(points, cells)
        n_old = len(points)
        prolongation = _edge_prolongation(n_old, edges)
        if project is not None:
            is_boundary = np.zeros(len(new_pts), dtype=bool)
            is_boundary[_refined_boundary_nodes(cells, n_old, edges)] = True
            new_pts = project(new_pts, is_boundary)
            new_cells = orient_positive(new_pts, new_cells)
        return new_pts, new_cells, prolongation
    mesh = MeshTri(np.ascontiguousarray(points.T), np.ascontiguousarray(cells.T))
    fine = mesh.refined()
    n_old = points.shape[0]
    edges = mesh.facets
    new_pts = fine.p.T.copy()
    n_new = new_pts.shape[0]
    n_edges = edges.shape[1]
    if n_new != n_old + n_edges:
        raise RuntimeError("unexpected node layout after refinement")
    mid = 0.5 * (points[edges[0]] + points[edges[1]])
    if not np.allclose(new_pts[n_old:], mid, atol=1e-12 * max(1.0, np.abs(points).max())):
        raise RuntimeError("scikit-fem's refined() no longer numbers midpoints by edge")
    prolongation = _edge_prolongation(n_old, edges.T)
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


def project_to_circle(center, radius: float):
    """A ``project`` callback for :func:`refine` that puts boundary nodes on a circle
    (2D) or a sphere (3D) about ``center``."""
    c = np.asarray(center, dtype=float)

    def project(points: np.ndarray, is_boundary: np.ndarray) -> np.ndarray:
        out = points.copy()
        v = out[is_boundary] - c
        r = np.linalg.norm(v, axis=1)
        out[is_boundary] = c + v * (radius / r)[:, None]
        return out

    return project


def project_to_arc(center, radius: float):
    """A ``project`` callback for :func:`refine` that puts the boundary nodes off the
    horizontal chord through ``center`` on the circle (a half disk's arc): the chord's
    nodes stay on it."""
    c = np.asarray(center, dtype=float)

    def project(points: np.ndarray, is_boundary: np.ndarray) -> np.ndarray:
        out = points.copy()
        on_arc = is_boundary & (np.abs(out[:, 1] - c[1]) > 1e-12 * radius)
        v = out[on_arc] - c
        out[on_arc] = c + v * (radius / np.linalg.norm(v, axis=1))[:, None]
        return out

    return project


def disk_hierarchy(center, radius: float, level: int, maxh: float) -> Hierarchy:
    """A netgen disk (:func:`netgen_disk`) refined ``level`` times, the new boundary nodes
    put on the circle (:func:`project_to_circle`): at every level the boundary nodes lie on
    the circle, and a node of a level is a node of every finer one."""
    return uniform_hierarchy(*netgen_disk(center, radius, maxh), level,
                             project_to_circle(center, radius))


def half_disk_hierarchy(center, radius: float, level: int, maxh: float,
                        side: str = "lower") -> Hierarchy:
    """A netgen half disk (:func:`netgen_half_disk`) refined ``level`` times, the new nodes
    of its arc put on the circle and those of its chord left on it (:func:`project_to_arc`)."""
    return uniform_hierarchy(*netgen_half_disk(center, radius, maxh, side), level,
                             project_to_arc(center, radius))


def dof_prolongation(node_prolongation: sp.spmatrix, dim: int, free_fine: np.ndarray,
                     free_coarse: np.ndarray) -> sp.csr_matrix:
    """Vector-valued P1 prolongation restricted to the free DOFs of both levels.

    DOFs are node-major (``node * dim + component``). Columns of prescribed
    coarse DOFs are dropped: corrections vanish there.
    """
    P = sp.kron(node_prolongation, sp.identity(dim), format="csr")
    return P[free_fine][:, free_coarse].tocsr()


def prescribed_dof_prolongation(node_prolongation: sp.spmatrix, dim: int,
                                free_fine: np.ndarray, free_coarse: np.ndarray,
                                ) -> sp.csr_matrix:
    """The columns :func:`dof_prolongation` drops: vector-valued P1 prolongation from
    the coarse prescribed DOFs (columns of the full coarse vector, zero at its free
    DOFs) to the fine free DOFs, so that ``P u + P_D u_fixed`` interpolates the coarse
    displacement with its prescribed values.
    """
    P = sp.kron(node_prolongation, sp.identity(dim), format="csr")[free_fine]
    keep = np.ones(P.shape[1])
    keep[free_coarse] = 0.0
    P_D = (P @ sp.diags(keep)).tocsr()
    P_D.eliminate_zeros()
    return P_D


def midpoint_anchors(points: np.ndarray, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The edges of a simplex mesh (sorted node pairs) and the places a red-type
    refinement puts its nodes: the nodes, then the edges' midpoints."""
    d = points.shape[1]
    pairs = np.vstack([cells[:, [i, j]] for i in range(d + 1) for j in range(i + 1, d + 1)])
    edges = np.unique(np.sort(pairs, axis=1), axis=0)
    return edges, np.vstack([points, 0.5 * (points[edges[:, 0]] + points[edges[:, 1]])])


def nested_prolongation(points: np.ndarray, cells: np.ndarray, fine_points: np.ndarray,
                        tol: float = 1e-9) -> sp.csr_matrix:
    """P1 prolongation to a nested refinement whose nodes are coarse nodes or
    coarse edge midpoints (any red-type refinement, any node numbering).

    Each fine node is matched (KD-tree, distance < ``tol`` times the mesh
    diameter) to a coarse node (weight 1) or to the midpoint of a coarse edge
    (weights 1/2, 1/2). A fine node matching neither raises ValueError.
    """
    from scipy.spatial import cKDTree

    edges, anchors = midpoint_anchors(points, cells)
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


# --------------------------------------------------------------------------- 3D
#: Local edges of a tetrahedron (scikit-fem's order) and the opposite-edge pairs of the
#: octahedron left after cutting off the four corner tetrahedra.
TET_EDGES = np.array([[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [2, 3]])
_OPPOSITE = np.array([[0, 5], [1, 3], [2, 4]])
_TET_FACES = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])


def signed_volumes(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Signed volume of each tetrahedron (positive: (x1-x0, x2-x0, x3-x0) right-handed)."""
    a = points[cells[:, 0]]
    return np.einsum("ij,ij->i", np.cross(points[cells[:, 1]] - a, points[cells[:, 2]] - a),
                     points[cells[:, 3]] - a) / 6.0


def orient_positive(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Tetrahedra with vertices 2 and 3 swapped where the volume is negative."""
    cells = np.array(cells, dtype=np.int64)
    neg = signed_volumes(points, cells) < 0
    cells[neg, 2], cells[neg, 3] = cells[neg, 3], cells[neg, 2].copy()
    return cells


def simplex_edges(cells: np.ndarray, n_nodes: int, local_edges: np.ndarray):
    """Unique edges ``(n_edges, 2)`` (sorted pairs, lexicographic) and each cell's edges
    ``(n_cells, len(local_edges))`` in the local order ``local_edges``."""
    a = cells[:, local_edges[:, 0]].astype(np.int64)
    b = cells[:, local_edges[:, 1]].astype(np.int64)
    key = np.minimum(a, b) * n_nodes + np.maximum(a, b)
    del a, b
    uniq, inv = np.unique(key.ravel(), return_inverse=True)
    return (np.stack([uniq // n_nodes, uniq % n_nodes], axis=1),
            inv.reshape(cells.shape[0], len(local_edges)))


def tet_edges(cells: np.ndarray, n_nodes: int):
    """Unique edges and each tetrahedron's six in the local order :data:`TET_EDGES`
    (:func:`simplex_edges`)."""
    return simplex_edges(cells, n_nodes, TET_EDGES)


def boundary_triangles(cells: np.ndarray, n_nodes: int) -> np.ndarray:
    """Boundary faces ``(n_faces, 3)`` of a tetrahedral mesh (faces of one cell; unoriented)."""
    f = np.sort(cells[:, _TET_FACES].reshape(-1, 3).astype(np.int64), axis=1)
    key = (f[:, 0] * n_nodes + f[:, 1]) * n_nodes + f[:, 2]
    _, idx, cnt = np.unique(key, return_index=True, return_counts=True)
    return f[idx[cnt == 1]]


def red_refine_tets(points: np.ndarray, cells: np.ndarray):
    """One red refinement of a tetrahedral mesh (Bey): ``(points, cells, edges)``.

    Fine nodes: the old nodes, then the midpoint of ``edges[k]`` as node
    ``n_old + k``. Each tetrahedron gives its four corner tetrahedra and four
    around the shortest diagonal of the inner octahedron (which keeps the
    quality bounded under repeated refinement). Cells positively oriented.
    """
    n_old = points.shape[0]
    edges, ce = tet_edges(cells, n_old)
    new_points = np.vstack([points, 0.5 * (points[edges[:, 0]] + points[edges[:, 1]])])
    e = ce + n_old                                     # global ids of the six midpoints
    d2 = np.empty((cells.shape[0], 3))
    for k, (i, j) in enumerate(_OPPOSITE):
        diff = new_points[e[:, i]] - new_points[e[:, j]]
        d2[:, k] = np.einsum("ij,ij->i", diff, diff)
    choice = np.argmin(d2, axis=1)
    nc = cells.shape[0]
    out = np.empty((8, nc, 4), dtype=np.int64)
    out[0] = np.stack([cells[:, 0], e[:, 0], e[:, 2], e[:, 3]], axis=1)
    out[1] = np.stack([cells[:, 1], e[:, 0], e[:, 1], e[:, 4]], axis=1)
    out[2] = np.stack([cells[:, 2], e[:, 1], e[:, 2], e[:, 5]], axis=1)
    out[3] = np.stack([cells[:, 3], e[:, 3], e[:, 4], e[:, 5]], axis=1)
    for k in range(3):
        sel = choice == k
        d0, d1 = e[sel][:, _OPPOSITE[k, 0]], e[sel][:, _OPPOSITE[k, 1]]
        (p0, p1), (q0, q1) = (e[sel][:, _OPPOSITE[m]].T for m in range(3) if m != k)
        ring = [p0, q0, p1, q1]                        # the equator: opposite pairs alternate
        for r in range(4):
            out[4 + r, sel] = np.stack([d0, d1, ring[r], ring[(r + 1) % 4]], axis=1)
    return new_points, orient_positive(new_points, out.reshape(8 * nc, 4)), edges


def _refined_boundary_nodes(cells: np.ndarray, n_old: int, edges: np.ndarray) -> np.ndarray:
    """Boundary nodes of the red refinement, from the coarse boundary faces: their
    vertices and the midpoints (``n_old + k``) of their edges."""
    bf = boundary_triangles(cells, n_old)
    pairs = np.sort(bf[:, [[0, 1], [1, 2], [0, 2]]].reshape(-1, 2), axis=1)
    key = np.unique(pairs[:, 0] * n_old + pairs[:, 1])
    new = n_old + np.searchsorted(edges[:, 0] * n_old + edges[:, 1], key)
    return np.concatenate([np.unique(bf), new])


def _edge_prolongation(n_old: int, edges: np.ndarray) -> sp.csr_matrix:
    """P1 prolongation for old nodes followed by one midpoint per edge ``(n_edges, 2)``."""
    ne = edges.shape[0]
    rows = np.concatenate([np.arange(n_old), np.repeat(np.arange(n_old, n_old + ne), 2)])
    cols = np.concatenate([np.arange(n_old), np.asarray(edges).ravel()])
    vals = np.concatenate([np.ones(n_old), np.full(2 * ne, 0.5)])
    return sp.csr_matrix((vals, (rows, cols)), shape=(n_old + ne, n_old))


def structured_cube(n: int, origin=(0.0, 0.0, 0.0), size: float = 1.0):
    """Cube ``origin + [0, size]^3`` with n^3 hexahedra, 6 Kuhn tetrahedra each.

    Returns ``(points, cells)``; cells positively oriented.
    """
    if n < 1:
        raise ValueError(f"parameter 'n': {n!r} is not allowed; allowed: an integer >= 1")
    m = MeshTet.init_tensor(*(np.linspace(o, o + size, n + 1) for o in origin))
    pts = m.p.T.copy()
    return pts, orient_positive(pts, m.t.T)


@_generated_once
def netgen_ball(center, radius: float, maxh: float, grading: float = 0.3):
    """Unstructured tetrahedra of a ball by netgen (OCC geometry): ``(points, cells)``.

    The OCC sphere has its poles on the z axis, so a node sits at the ball's
    lowest point at every refinement level.
    """
    from netgen.meshing import MeshingParameters
    from netgen.occ import OCCGeometry, Pnt, Sphere

    if not (radius > 0 and maxh > 0):
        raise ValueError("parameters 'radius' and 'maxh' must be positive")
    geo = OCCGeometry(Sphere(Pnt(*map(float, center)), float(radius)))
    ngmesh = geo.GenerateMesh(MeshingParameters(maxh=float(maxh), grading=float(grading)))
    points = np.array(ngmesh.Coordinates(), dtype=float)
    cells = ngmesh.Elements3D().NumPy()["nodes"][:, :4].astype(np.int64) - 1
    return points, orient_positive(points, cells)


def tet_quality(points: np.ndarray, cells: np.ndarray) -> dict:
    """Smallest signed volume and smallest/largest dihedral angle (degrees)."""
    x = points[cells]
    J = (x[:, 1:] - x[:, :1]).transpose(0, 2, 1)
    G = np.linalg.inv(J)
    g = np.concatenate([-G.sum(axis=1, keepdims=True), G], axis=1)
    gn = g / np.linalg.norm(g, axis=2, keepdims=True)
    angles = []
    for i, j in TET_EDGES:
        k, m = (r for r in range(4) if r not in (i, j))
        angles.append(np.degrees(np.arccos(np.clip(-np.einsum("ij,ij->i", gn[:, k], gn[:, m]),
                                                   -1, 1))))
    angles = np.concatenate(angles)
    return {"min_volume": float(signed_volumes(points, cells).min()),
            "min_dihedral": float(angles.min()), "max_dihedral": float(angles.max())}


def extrusion_layers(points: np.ndarray, body_of_node: np.ndarray, free_dofs: np.ndarray,
                     dim: int, axis: int = 0) -> Extrusion:
    """The layers of a mesh whose bodies are each one section extruded along ``axis``,
    numbered layer by layer (every layer's nodes contiguous and in the section's order, as
    :func:`problems.roll_stack.extrude` numbers them).

    Parameters
    ----------
    points : (N, dim) array
    body_of_node : (N,) int array
        Bodies numbered ``0, 1, ...``, each body's nodes contiguous or not.
    free_dofs : (n,) int array
        The unknowns (node-major DOF numbers ``dim * node + component``).
    dim, axis : int

    Returns
    -------
    Extrusion

    Raises
    ------
    ValueError
        If a body is not numbered layer by layer along ``axis``.
    """
    n_nodes = len(points)
    layer_of_node = np.empty(n_nodes, dtype=int)
    section_of_node = np.empty(n_nodes, dtype=int)
    coordinates, body_layers, n_layers, n_section = [], [], 0, 0
    for b in np.unique(body_of_node):
        nodes = np.flatnonzero(body_of_node == b)
        at = points[nodes, axis]
        tol = 1e-9 * max(np.ptp(at), 1e-300)
        size = int(np.count_nonzero(np.abs(at - at[0]) <= tol))     # the first layer's nodes
        k = len(nodes) // size
        grid = at[:k * size].reshape(k, size)
        if (k * size != len(nodes) or np.any(np.abs(grid - grid[:, :1]) > tol)
                or np.any(np.diff(grid[:, 0]) <= tol)):
            raise ValueError(f"body {b} is not numbered layer by layer along axis {axis}")
        layer_of_node[nodes] = n_layers + np.repeat(np.arange(k), size)
        section_of_node[nodes] = n_section + np.tile(np.arange(size), k)
        coordinates.append(grid[:, 0])
        body_layers.append(n_layers + np.arange(k))
        n_layers, n_section = n_layers + k, n_section + size
    free_dofs = np.asarray(free_dofs)
    node = free_dofs // dim
    return Extrusion(layer_of_dof=layer_of_node[node],
                     section_dof=section_of_node[node] * dim + free_dofs % dim,
                     layer_coordinate=np.concatenate(coordinates),
                     body_layers=tuple(body_layers))
