"""Accuracy of a contact discretisation against a common finer reference (Sects. 7.3, 7.4).

The adaptive meshes of Sect. 7.4 are newest-vertex bisections of one start mesh, so
every mesh of every run is a node of one binary *bisection forest*: two meshes are
nested exactly when every leaf of the finer lies inside a leaf of the coarser. Here:

* :func:`cell_depth` - the number of bisections between a cell and its start-mesh
  ancestor (its measure halves with each bisection);
* :func:`refine_to_depth` - every cell bisected until it has at least a given depth
  ("uniform" refinement by bisection: depth ``2 L`` has exactly the nodes of the red
  level ``L``, only the diagonals differ);
* :func:`common_refinement` - the coarsest mesh of the forest that contains several
  meshes (their overlay), then every cell bisected ``extra`` more times: a reference
  finer than every compared mesh everywhere and nested with all of them;
* :func:`locate` and :func:`interpolation_matrix` - point location in a simplex mesh
  (any dimension) and the P1 interpolation matrix between nested meshes (per body,
  exact on nested meshes; nodes that projection moved outside a curved boundary get
  the linear extension of their nearest cell);
* :func:`energy_norm_by_cell` - ``a(e, e)`` split by cells, for region budgets;
* contact-surface measures: :func:`surface_interpolate` (a P1 pressure on another
  surface mesh), :func:`zigzag` (node-to-node oscillation of a nodal pressure),
  :func:`pileup` (nodes of both contact surfaces inside the contact zone).

Why the reference is a common refinement: for conforming nested spaces ``V_h`` in
``V_ref`` Galerkin orthogonality gives ``||u - u_h||^2 = ||u - u_ref||^2 +
||u_ref - u_h||^2`` (exactly for linear problems; for the contact problem up to
the difference of the discrete constraint sets). One number, ``||u - u_ref||``,
then separates the measured difference from the true error for every compared
mesh alike, so "mesh A reaches the error of mesh B" reads off the measured
differences without knowing it. Energies ``J(u_h)`` are not compared: the polygonal
circle and the discrete Dirichlet arc change with the mesh, which shifts ``J`` by
as much as ``||u - u_h||^2`` (docs/guide/measurements.md).

Pure functions of arrays: no files, no clocks.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from problems.fem.bisection import grow
from problems.fem.elasticity import barycentric_gradients, strain_stress
from problems.fem.mesh import Hierarchy


# --------------------------------------------------------------------------- location
def locate(points: np.ndarray, cells: np.ndarray, targets: np.ndarray, k: int = 10,
           tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """Cell of ``cells`` holding each target point and its barycentric coordinates.

    Candidates are the ``k`` cells with the nearest centroids (KD-tree), widened to
    ``8 k`` and then to all cells for targets still unplaced; among the candidates
    the cell whose smallest barycentric coordinate is largest wins. A target
    outside the mesh (a node moved onto a curved boundary) gets its best cell and
    barycentric coordinates slightly below zero: the linear extension. Such a target
    is settled once widening the candidates to ``8 k`` finds no better cell than the
    ``k`` nearest did (the cells next to a curved boundary are among its nearest); only
    a target whose best cell still improves goes on to the scan of all cells. (On a
    sphere refined uniformly a quarter of the fine surface nodes lie outside the coarse
    mesh, thousands at 18k nodes: one scan of all cells each would dominate the study.)

    Returns
    -------
    cell : (n_targets,) int array
    bary : (n_targets, d + 1) array
    """
    pts = np.asarray(points, dtype=float)
    t = np.asarray(cells, dtype=np.int64)
    x = np.asarray(targets, dtype=float)
    if x.size == 0:
        return np.zeros(0, dtype=np.int64), np.zeros((0, t.shape[1]))
    grads, _ = barycentric_gradients(pts, t)          # lambda(x) = e_0 + G (x - x_0)
    x0 = pts[t[:, 0]]
    tree = cKDTree(pts[t].mean(axis=1))

    def bary(c, xs):
        lam = np.einsum("kad,kd->ka", grads[c], xs - x0[c])
        lam[:, 0] += 1.0
        return lam

    cell = np.full(len(x), -1, dtype=np.int64)
    best = np.full(len(x), -np.inf)
    todo = np.arange(len(x))
    for kk in (k, 8 * k, len(t)):
        kk = min(kk, len(t))
        if kk > 512:              # the rare stragglers: all cells, one target at a time
            for i in todo:
                score = bary(np.arange(len(t)), np.repeat(x[i][None], len(t), axis=0)).min(axis=1)
                cell[i] = int(np.argmax(score))
                best[i] = score[cell[i]]
            break
        _, cand = tree.query(x[todo], k=kk)
        cand = cand.reshape(len(todo), kk)
        score = bary(cand.ravel(), np.repeat(x[todo], kk, axis=0)).min(axis=1)
        score = score.reshape(len(todo), kk)
        j = np.argmax(score, axis=1)
        before = best[todo]
        cell[todo] = cand[np.arange(len(todo)), j]
        best[todo] = score[np.arange(len(todo)), j]
        todo = todo[(best[todo] < -tol) & (best[todo] > before + tol)]
        if not todo.size:
            break
    return cell, bary(cell, x)


def interpolation_matrix(points: np.ndarray, cells: np.ndarray, targets: np.ndarray,
                         cell_group: np.ndarray | None = None,
                         target_group: np.ndarray | None = None) -> sp.csr_matrix:
    """``(n_targets, n_nodes)`` P1 or P2 interpolation from a simplex mesh to points.

    ``cells`` with ``d + 1`` columns are P1; with 6 (triangles) or 10 (tetrahedra) P2
    (:mod:`problems.fem.quadratic`: located by their vertices, weighted by the P2 shape
    functions; exact on nested meshes, whose P2 nodes are then points of the coarse
    cells). With groups (e.g. the body of each cell and of each target), a target is only
    located among the cells of its own group, so that two bodies touching at a
    point never exchange values.
    """
    from problems.fem.quadratic import shape_functions

    x = np.asarray(targets, dtype=float)
    t = np.asarray(cells, dtype=np.int64)
    d = np.asarray(points).shape[1]
    quadratic = t.shape[1] > d + 1
    if cell_group is None:
        cell_group, target_group = np.zeros(len(t), int), np.zeros(len(x), int)
    rows, cols, vals = [], [], []
    for g in np.unique(target_group):
        sel_x = np.flatnonzero(target_group == g)
        sel_c = np.flatnonzero(cell_group == g)
        if not sel_c.size:
            raise ValueError(f"parameter 'cell_group': no cell in group {g} for its targets")
        c, lam = locate(points, t[sel_c][:, :d + 1], x[sel_x])
        rows.append(np.repeat(sel_x, t.shape[1]))
        cols.append(t[sel_c][c].ravel())
        vals.append((shape_functions(lam) if quadratic else lam).ravel())
    P = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(len(x), len(points)))
    P.eliminate_zeros()
    return P


# --------------------------------------------------------------------------- the forest
def cell_depth(start_points: np.ndarray, start_cells: np.ndarray, points: np.ndarray,
               cells: np.ndarray) -> np.ndarray:
    """Bisections between each cell and its start-mesh ancestor: ``log2(|T_0| / |T|)``
    (rounded: projection onto a curved boundary changes measures by far less than 2x)."""
    _, vol0 = barycentric_gradients(start_points, start_cells)
    _, vol = barycentric_gradients(points, cells)
    anc, _ = locate(start_points, start_cells, np.asarray(points)[np.asarray(cells)].mean(axis=1))
    return np.rint(np.log2(vol0[anc] / vol)).astype(np.int64)


def _depths(meshes, start) -> list[np.ndarray]:
    return [cell_depth(s.points[-1], s.cells[-1], h.points[-1], h.cells[-1])
            for s, h in zip(start, meshes)]


def refine_to_depth(meshes, start, depth: int, project=None, rule: str | None = None):
    """Each body's hierarchy grown until every finest cell has depth ``>= depth``
    relative to ``start`` (the bodies' start hierarchies; their finest level is depth 0)."""
    project = project or (None,) * len(meshes)
    while True:
        marks = [d < depth for d in _depths(meshes, start)]
        if not any(m.any() for m in marks):
            return tuple(meshes)
        meshes = tuple(grow(h, m, pr, rule) for h, m, pr in zip(meshes, marks, project))


def common_refinement(start, targets, project=None, extra: int = 2, rule: str | None = None):
    """The overlay of ``targets`` (each a tuple of per-body hierarchies grown from
    ``start`` by bisection), every cell then bisected ``extra`` more times.

    A cell of the growing reference is bisected while a target cell of greater depth
    has its centroid inside it (forest cells are nested or disjoint, so the target
    cell lies inside it). Returns per-body hierarchies (many levels: one per sweep).
    """
    project = project or (None,) * len(start)
    ref = tuple(start)
    want = []                   # per body: (centroids, depth) of every target cell
    for b, s in enumerate(start):
        cen = np.vstack([tg[b].points[-1][tg[b].cells[-1]].mean(axis=1) for tg in targets])
        dep = np.concatenate([cell_depth(s.points[-1], s.cells[-1], tg[b].points[-1],
                                         tg[b].cells[-1]) for tg in targets])
        want.append((cen, dep))
    while True:
        depth = _depths(ref, start)
        marks = []
        for b, (cen, dep) in enumerate(want):
            h = ref[b]
            cell, _ = locate(h.points[-1], h.cells[-1], cen)
            need = dep > depth[b][cell]
            mark = np.zeros(len(h.cells[-1]), dtype=bool)
            mark[cell[need]] = True
            keep = need                      # satisfied target cells need no more location
            want[b] = (cen[keep], dep[keep])
            marks.append(mark)
        if not any(m.any() for m in marks):
            break
        ref = tuple(grow(h, m, pr, rule) for h, m, pr in zip(ref, marks, project))
    for _ in range(extra):
        ref = tuple(grow(h, np.ones(len(h.cells[-1]), dtype=bool), pr, rule)
                    for h, pr in zip(ref, project))
    return ref


def is_nested(coarse: Hierarchy, fine: Hierarchy, start: Hierarchy) -> bool:
    """Whether every finest cell of ``fine`` lies in a finest cell of ``coarse`` of at
    most its depth (the forest test, by centroids)."""
    dc = cell_depth(start.points[-1], start.cells[-1], coarse.points[-1], coarse.cells[-1])
    df = cell_depth(start.points[-1], start.cells[-1], fine.points[-1], fine.cells[-1])
    cell, _ = locate(coarse.points[-1], coarse.cells[-1],
                     fine.points[-1][fine.cells[-1]].mean(axis=1))
    return bool(np.all(dc[cell] <= df))


# --------------------------------------------------------------------------- norms
def energy_norm_by_cell(points, cells, u, E, nu, geometry=None) -> np.ndarray:
    """``int_T sigma(u) : eps(u)`` per cell (sums to ``u' A u`` for the P1 stiffness);
    ``geometry``: the mesh's ``barycentric_gradients(points, cells)``, where one mesh
    measures many fields."""
    g, vol = barycentric_gradients(points, cells) if geometry is None else geometry
    eps, sigma = strain_stress(points, cells, u, E, nu, gradients=g)
    return np.einsum("cij,cij->c", sigma, eps) * vol


# --------------------------------------------------------------------------- surfaces
def surface_interpolate(s_from: np.ndarray, values: np.ndarray, s_to: np.ndarray,
                        facets_from: np.ndarray | None = None) -> np.ndarray:
    """A nodal P1 function on one surface mesh evaluated at other surface points.

    ``s_*`` are in-plane coordinates (``(m,)`` or ``(m, 1)`` for a line: linear
    interpolation between the sorted nodes; ``(m, 2)`` for a face: ``facets_from``
    are its triangles in the numbering of ``s_from``).
    """
    s_from = np.asarray(s_from, dtype=float)
    s_to = np.asarray(s_to, dtype=float)
    v = np.asarray(values, dtype=float)
    if s_from.ndim == 1 or s_from.shape[1] == 1:
        a, b = s_from.reshape(-1), s_to.reshape(-1)
        order = np.argsort(a)
        return np.interp(b, a[order], v[order])
    if facets_from is None:
        raise ValueError("parameter 'facets_from': required for a 2D surface")
    cell, lam = locate(s_from, facets_from, s_to)
    return np.einsum("ij,ij->i", lam, v[np.asarray(facets_from)[cell]])


def zigzag(s: np.ndarray, pressure: np.ndarray, active: np.ndarray) -> np.ndarray:
    """Node-to-node oscillation of a nodal pressure along a line: at every active node
    between two active neighbours, the pressure minus the linear interpolation of its
    neighbours' (zero for any pressure linear between nodes, ~ h^2 p'' for a smooth
    one; the odd-even pattern of non-matching nodal constraints shows as O(p))."""
    s = np.asarray(s, dtype=float).reshape(-1)
    order = np.argsort(s)
    x, p, a = s[order], np.asarray(pressure, float)[order], np.asarray(active, bool)[order]
    i = np.flatnonzero(a[1:-1] & a[:-2] & a[2:]) + 1
    w = (x[i] - x[i - 1]) / (x[i + 1] - x[i - 1])
    return p[i] - ((1 - w) * p[i - 1] + w * p[i + 1])


def pileup(constrained_s: np.ndarray, opposing_s: np.ndarray, center: np.ndarray,
           radius: float) -> dict:
    """Nodes of the constrained and the opposing surface inside the contact zone
    (in-plane distance <= ``radius`` from ``center``) and their ratio
    (Fig. 7.3: > 1 when the opposing surface's hanging nodes pile up)."""
    def inside(s):
        s = np.asarray(s, dtype=float).reshape(len(s), -1)
        return int(np.sum(np.linalg.norm(s - np.asarray(center).reshape(1, -1), axis=1)
                          <= radius))
    nc, no = inside(constrained_s), inside(opposing_s)
    return {"zone_constrained": nc, "zone_opposing": no,
            "zone_ratio": no / nc if nc else float("nan")}
