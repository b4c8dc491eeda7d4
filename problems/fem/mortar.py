"""Mortar coupling of two non-matching contact surfaces, 2D and 3D: segment-based
integration and clipping of projected triangles, standard and dual Lagrange multipliers
(thesis Sect. 6.1, Remark 6.8; Wohlmuth 2000; Hueber and Wohlmuth 2005).

The nodal constraints of Alg. 7.1 ask each constrained node to stay out of the
opposing body. The mortar method asks it in the mean instead: row ``i`` is the
weighted gap

    (1/m_i) int_Gamma psi_i n.(u_c - u_o) ds  <=  (1/m_i) int_Gamma psi_i gap ds,
    m_i = int_Gamma psi_i ds,

with ``Gamma`` the constrained surface, ``phi_i`` its P1 or P2 hats (the trace of the
scene's elements: one row per vertex, and per edge midpoint at P2), ``u_c`` the constrained
body's and ``u_o`` the opposing body's displacement at the opposing point, ``gap``
the distance from ``Gamma`` to the opposing surface along ``n``, and ``psi_i`` the
multiplier basis:

* ``mortar``: the standard basis ``psi_i = phi_i`` (on P2 triangles a modified basis of
  the same space, below). Its constrained block
  ``D_ij = int phi_i phi_j`` is the surface mass matrix: each row reaches its node's
  neighbours, so the rows are not node-wise.
* ``mortar_dual``: Wohlmuth's dual basis (Wohlmuth 2000), on each facet with ``k``
  vertices (a segment, ``k = 2``; a triangle, ``k = 3``) ``psi_a = (k + 1) phi_a - 1``:
  biorthogonal, ``int psi_i phi_j = delta_ij m_i``, so ``D = diag(m)``, and row ``i``
  moves its constrained node by exactly ``n``: each row owns one constrained node, as
  nodal rows do (the box transformation of :mod:`solvers.kernels.contact_box` applies).
  (With ``psi_a = alpha phi_a + beta`` on a simplex of dimension ``s = k - 1``,
  ``int phi_a phi_b = |T| (1 + delta_ab) / ((s + 1)(s + 2))`` and
  ``int phi_b = |T| / (s + 1)`` make biorthogonality read ``beta = -alpha / (s + 2)``
  and ``alpha / (s + 2) = 1``: ``alpha = k + 1``, ``beta = -1``. In 2D this is
  ``2 phi_a - phi_b``.)

Both bases sum to 1 on each facet, so a uniform pressure is transmitted exactly (the
contact patch test); the multiplier over ``m_i`` is the nodal pressure (Sect. 8.6), as
for the nodal rows.

P2 (Remark 7.11's elements; :func:`multiplier_basis`, :func:`dual_coefficients`):

* ``mortar``: on a segment ``psi_i`` the P2 trace hats (3-node), each row scaled by
  ``1/s_i`` with ``s_i`` the HRZ lumped surface mass
  (:func:`problems.fem.quadratic.surface_mass_p2`, which is ``m_i`` itself there). On a
  6-node triangle the vertex hats integrate to zero: a vertex row weighted by its hat
  would not see a rigid translation along ``n`` and would bound only the gap's variation
  over the vertex's patch (the ball of cube_sphere then penetrates the cube). The
  multipliers there take the modified basis of the same P2 space (Popp, Wohlmuth, Gee
  and Wall 2012; :func:`modified_coefficients`): ``psi_v = phi_v + alpha sum_m phi_m``
  over the midpoints of the vertex's edges, ``psi_m = (1 - 2 alpha) phi_m``, with
  ``alpha = 1/5``; it sums to one, and every weight ``m_i = int psi_i`` is positive
  (``2 |T| / 15`` per triangle at a vertex, ``|T| / 5`` at a midpoint), so the rows are
  scaled by ``1/m_i`` as at P1 and a rigid translation by ``d`` moves every row by
  ``d``. Scaling a row changes neither the feasible set nor the displacement: the
  multiplier over the row's scale is the coefficient ``c_i`` of ``psi_i`` in the
  multiplier field (a uniform pressure ``q`` has every ``c_i = q``, the contact patch
  test);
* the nodal pressure at P2 is therefore recovered from the forces, as for the nodal P2
  rows (:func:`problems.fem.two_body.quadratic_pressure_map`): the constrained nodes'
  forces ``F = D' diag(1/s) p`` aggregated onto the vertices (each midpoint's half to
  each of its vertices), divided by the P1 lumped mass there and interpolated back to
  the midpoints, ``pressure = P diag(1/m_P1) P' F`` (:func:`force_pressure_map`; exact
  for a uniform pressure: ``F_j = q m_j`` aggregates to ``q m_P1``);
* ``mortar_dual`` in 2D: the dual basis of the P2 segment, ``psi = A phi`` with
  ``A = diag(m) M^-1`` from the local mass matrix ``M`` and ``m = M 1 = |T| (1/6, 1/6,
  2/3)``, i.e. ``psi_0 = (6 phi_0 + 2 phi_1 - phi_m) / 4`` at a vertex and
  ``psi_m = (-2 phi_0 - 2 phi_1 + 3 phi_m) / 2`` at the midpoint; its columns sum to
  one (``m' M^-1 = 1'``), so the patch test holds, and ``D = diag(m)``;
* ``mortar_dual`` in 3D is refused: ``A = diag(m) M^-1`` needs ``m_i > 0``, and the P2
  vertex hats of a triangle integrate to zero, so no dual basis of the P2 trace exists
  (the literature modifies the displacements' basis as well and builds the dual basis on
  it: Lamichhane, Stevenson and Wohlmuth 2005; Popp et al. 2012; not built here).

What is approximated, and how:

* the surfaces are the meshes' polygons and triangulations (the circle of circle_square
  by its chords, the sphere of cube_sphere by its flat triangles), at P2 too: the P2
  meshes are subparametric (:mod:`problems.fem.quadratic`), each midpoint on its
  straight edge, so the P2 fields live on the P1 geometry and the curved surfaces'
  approximation is not improved by the higher degree;
* the normal field is the constant contact direction ``n`` of the scene (Alg. 7.1
  case b), which is the constrained surface's normal where that surface is flat
  (the straight edges of circle_square and flat_blocks, the top face of cube_sphere):
  the opposing facets are projected onto ``Gamma`` along ``n``. A curved constrained
  surface would need a continuous nodal normal field (averaged normals) and is refused;
* the integrals: ``Gamma`` is split into pieces on which both surfaces are flat and the
  projection is affine, so every integrand is a polynomial of degree <= 2 (P1) or
  <= 4 (P2: a product of two quadratics; the gap is affine, ``psi_i gap`` of degree
  3) on each piece, integrated exactly. In 2D the projected opposing nodes split the
  segments (segment-based integration, 3-point Gauss per piece, exact for degree 5,
  :func:`segment_quadrature`); in 3D each projected opposing triangle is clipped
  against each constrained triangle it overlaps, the convex intersection triangulated
  and integrated by a rule of the integrands' degree, :data:`TRIANGLE_RULES`: the
  3-point Strang-Fix rule (degree 2) at P1, the 6-point Strang-Fix/Dunavant rule
  (degree 4) at P2 (:func:`clipped_quadrature`). Both backends give the same
  :class:`SurfaceQuadrature` (P1 hats), which :func:`quadratic_quadrature` lifts to the
  P2 hats, and from which :func:`mortar_integrals` assembles the rows;
* linearisation: the weighted gaps are taken in the reference configuration (small
  displacements, as the nodal rows of Alg. 7.1).

Pure functions: no files, no printing.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from problems.fem.elasticity import lumped_surface_mass
from problems.fem.quadratic import (FACET_EDGES, QuadraticMesh, quadratic_facets,
                                    quadratic_mesh_of, shape_functions, surface_mass_p2)
from problems.qp import ContactQP, SharedWork

#: The mortar couplings: standard and dual multipliers (module docstring).
MORTAR_COUPLINGS = ("mortar", "mortar_dual")

#: Gauss points per piece in 2D: exact for degree 5, so for the P1 (degree 2) and the P2
#: (degree 4) integrands of the module docstring.
GAUSS_POINTS = 3


def _symmetric_points(a: np.ndarray) -> np.ndarray:
    """The barycentric points ``(a, a, 1 - 2a)`` for each ``a`` and their rotations:
    ``(3 len(a), 3)``, rotation-major."""
    base = np.column_stack([a, a, 1.0 - 2.0 * a])
    return np.concatenate([np.roll(base, shift, axis=1) for shift in range(3)])


def _strang_fix_6() -> tuple[np.ndarray, np.ndarray]:
    """The 6-point rule of degree 4 on a triangle (Strang and Fix; Dunavant's degree-4
    rule) in closed form: points ``(a, a, 1 - 2a)`` with weights ``w`` (summing to 1/3)."""
    r10, root = np.sqrt(10.0), np.sqrt(38.0 - 44.0 * np.sqrt(0.4))
    a = np.array([8.0 - r10 + root, 8.0 - r10 - root]) / 18.0
    s = np.sqrt(213125.0 - 53320.0 * r10)
    w = np.array([620.0 + s, 620.0 - s]) / 3720.0
    return _symmetric_points(a), np.tile(w, 3)


#: Rules on the reference triangle by the degree they integrate exactly: barycentric
#: points and weights (summing to 1, times the piece's area); the 3-point Strang-Fix
#: rule of degree 2 for the P1 integrands, the 6-point one of degree 4 for P2's.
TRIANGLE_RULES = {
    2: (np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]]),
        np.full(3, 1 / 3)),
    4: _strang_fix_6(),
}

#: The polynomial degree of the mortar integrands by element degree (module docstring).
INTEGRAND_DEGREE = {1: 2, 2: 4}

#: Relative bar of the geometric tests (a point on an edge, parallel edges): far above
#: round-off, far below any mesh feature.
GEOMETRY_TOL = 1e-12

#: Relative bar of the coverage test (each constrained triangle's area, covered once).
COVERAGE_TOL = 1e-10


@dataclass(frozen=True)
class SurfaceQuadrature:
    """A quadrature on the constrained surface, split into pieces on which both surfaces
    are flat and the projection along ``n`` is affine, with both facets' hats at each point.

    Attributes
    ----------
    weight : (q,) array
        Weights (``ds``: the pieces' measure on ``Gamma``).
    facet : (q,) int array
        The constrained facet (a row of ``facets``) of each point.
    constrained, opposing : (q, k) int arrays
        The nodes of the constrained facet and of the opposing facet at each point.
    phi, phi_opposing : (q, k) arrays
        Their hats there (the opposing ones at the point's projection onto the opposing
        facet along ``n``).
    """

    weight: np.ndarray
    facet: np.ndarray
    constrained: np.ndarray
    opposing: np.ndarray
    phi: np.ndarray
    phi_opposing: np.ndarray


@dataclass(frozen=True)
class MortarIntegrals:
    """The mortar integrals on a flat constrained surface.

    Attributes
    ----------
    nodes : (m,) int array
        The constrained nodes (one row each), in the order of the rows.
    D : (m, m) csr
        ``int psi_i phi_j`` over the constrained hats (diagonal ``m`` for the dual basis).
    M : (m, n_nodes) csr
        ``int psi_i phi_k^o`` over the opposing hats (global node numbers).
    weighted_gap : (m,) array
        ``int psi_i gap``.
    mass : (m,) array
        The rows' weights ``m_i = int psi_i`` (``int phi_i`` for the dual basis, equal).
    """

    nodes: np.ndarray
    D: sp.csr_matrix
    M: sp.csr_matrix
    weighted_gap: np.ndarray
    mass: np.ndarray


def _not_covered(which: str) -> ValueError:
    return ValueError(f"the opposing surface does not cover the constrained surface along the "
                      f"contact direction n: the mortar integrals need it {which}")


def _graph(points: np.ndarray, facets: np.ndarray, tangent: np.ndarray, which: str):
    """Segments of a polygon that is a graph over the tangent coordinate: their end
    parameters ``(t0 < t1)``, end nodes and original indices, sorted by ``t0``; refuses
    overlapping ones."""
    t = points[facets] @ tangent                                  # (k, 2)
    swap = t[:, 0] > t[:, 1]
    ends = np.where(swap[:, None], facets[:, ::-1], facets)
    t = np.sort(t, axis=1)
    order = np.argsort(t[:, 0])
    t, ends = t[order], ends[order]
    scale = max(float(np.ptp(t)), 1e-300)
    if np.any(t[:, 1] - t[:, 0] <= 1e-12 * scale) or np.any(t[1:, 0] < t[:-1, 1] - 1e-12 * scale):
        raise ValueError(f"the {which} surface is not a graph over the tangent of the contact "
                         "direction n: its segments cannot be projected one-to-one along n")
    return t, ends, order


def _locate(t_segments: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Index of the segment (sorted, non-overlapping) containing each parameter."""
    return np.clip(np.searchsorted(t_segments[:, 0], at, side="right") - 1, 0,
                   len(t_segments) - 1)


def segment_quadrature(points: np.ndarray, facets: np.ndarray, opposing_facets: np.ndarray,
                       normal: np.ndarray) -> SurfaceQuadrature:
    """Segment-based integration on a straight 2D constrained surface (module docstring):
    the projected nodes of both surfaces split it into pieces, 3-point Gauss on each.

    Raises
    ------
    ValueError
        If a surface is not a graph over the tangent, or the opposing surface does not
        cover the constrained one along ``n``.
    """
    tangent = np.array([normal[1], -normal[0]])
    t_c, ends_c, order_c = _graph(points, facets, tangent, "constrained")
    t_o, ends_o, _ = _graph(points, opposing_facets, tangent, "opposing")
    lo, hi = t_c[0, 0], t_c[-1, 1]
    tol = 1e-12 * max(hi - lo, 1e-300)
    covered = np.all(t_o[1:, 0] <= t_o[:-1, 1] + tol) and t_o[0, 0] <= lo + tol \
        and t_o[-1, 1] >= hi - tol
    if not covered:
        raise _not_covered("over every constrained segment")
    breaks = np.unique(np.concatenate([t_c.ravel(), t_o.ravel()]))
    breaks = breaks[(breaks >= lo) & (breaks <= hi)]
    g, w = np.polynomial.legendre.leggauss(GAUSS_POINTS)
    a, b = breaks[:-1, None], breaks[1:, None]
    tq = (0.5 * (a + b) + 0.5 * (b - a) * g).ravel()
    wq = (0.5 * (b - a) * w).ravel()                    # ds = dt on a surface normal to n
    kc, ko = _locate(t_c, tq), _locate(t_o, tq)
    sc = (tq - t_c[kc, 0]) / (t_c[kc, 1] - t_c[kc, 0])
    so = (tq - t_o[ko, 0]) / (t_o[ko, 1] - t_o[ko, 0])
    return SurfaceQuadrature(weight=wq, facet=order_c[kc], constrained=ends_c[kc],
                             opposing=ends_o[ko], phi=np.stack([1 - sc, sc], axis=1),
                             phi_opposing=np.stack([1 - so, so], axis=1))


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The z component of the cross product of 2D vectors (last axis)."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _barycentric_2d(tri: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Barycentric coordinates of points ``x (..., 2)`` in triangles ``tri (..., 3, 2)``."""
    e1, e2, r = tri[..., 1, :] - tri[..., 0, :], tri[..., 2, :] - tri[..., 0, :], \
        x - tri[..., 0, :]
    det = _cross(e1, e2)
    l1, l2 = _cross(r, e2) / det, _cross(e1, r) / det
    return np.stack([1.0 - l1 - l2, l1, l2], axis=-1)


def _counter_clockwise(tri: np.ndarray, nodes: np.ndarray):
    """Triangles (and their nodes) reordered counter-clockwise, with their areas."""
    area = 0.5 * _cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    flip = area < 0
    tri, nodes = tri.copy(), nodes.copy()
    tri[flip] = tri[flip][:, ::-1]
    nodes[flip] = nodes[flip][:, ::-1]
    return tri, nodes, np.abs(area)


def _overlapping_pairs(tri_c: np.ndarray, tri_o: np.ndarray, tol: float):
    """Pairs ``(c, o)`` of triangles whose bounding boxes overlap: a KD-tree of the opposing
    centroids, searched within each constrained triangle's reach plus the largest
    opposing one's, then the boxes compared."""
    cent_c, cent_o = tri_c.mean(axis=1), tri_o.mean(axis=1)
    reach_c = np.linalg.norm(tri_c - cent_c[:, None], axis=2).max(axis=1)
    reach_o = np.linalg.norm(tri_o - cent_o[:, None], axis=2).max(axis=1)
    found = cKDTree(cent_o).query_ball_point(cent_c, r=reach_c + reach_o.max() + tol)
    c = np.repeat(np.arange(len(tri_c)), [len(f) for f in found])
    o = np.fromiter((j for f in found for j in f), dtype=np.int64, count=len(c))
    lo_c, hi_c, lo_o, hi_o = tri_c.min(axis=1), tri_c.max(axis=1), tri_o.min(axis=1), \
        tri_o.max(axis=1)
    keep = np.all((lo_c[c] <= hi_o[o] + tol) & (lo_o[o] <= hi_c[c] + tol), axis=1)
    return c[keep], o[keep]


def _inside(tri: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Points ``x (p, j, 2)`` in the closed triangles ``tri (p, 3, 2)``, up to
    :data:`GEOMETRY_TOL` in barycentric coordinates."""
    lam = _barycentric_2d(tri[:, None], x)
    return np.all(lam >= -GEOMETRY_TOL, axis=-1)


def convex_intersections(a: np.ndarray, b: np.ndarray):
    """The intersections of counter-clockwise triangles ``a[p]`` and ``b[p]``: the convex
    polygons spanned by the vertices of each inside the other and the crossings of
    their edges, sorted counter-clockwise.

    Parameters
    ----------
    a, b : (p, 3, 2) arrays

    Returns
    -------
    vertices : (p, 15, 2) array
        The polygon's vertices first (counter-clockwise about their mean), unused slots
        after them; a vertex may repeat (a corner on an edge).
    count : (p,) int array
        The number of vertices (fewer than 3: the triangles touch at most).
    centre : (p, 2) array
        The mean of the vertices (inside the polygon: it is convex).
    """
    ea = np.roll(a, -1, axis=1) - a                             # edges a_i -> a_i+1
    eb = np.roll(b, -1, axis=1) - b
    den = _cross(ea[:, :, None], eb[:, None, :])                # (p, 3, 3)
    d = b[:, None, :, :] - a[:, :, None, :]
    scale = np.linalg.norm(ea, axis=2)[:, :, None] * np.linalg.norm(eb, axis=2)[:, None, :]
    crossing = np.abs(den) > GEOMETRY_TOL * scale               # parallel edges: the
    safe = np.where(crossing, den, 1.0)                         # corners inside give them
    s, t = _cross(d, eb[:, None, :]) / safe, _cross(d, ea[:, :, None]) / safe
    crossing &= (s >= -GEOMETRY_TOL) & (s <= 1 + GEOMETRY_TOL) & (t >= -GEOMETRY_TOL) \
        & (t <= 1 + GEOMETRY_TOL)
    points = np.concatenate([a, b, (a[:, :, None, :] + s[..., None] * ea[:, :, None, :])
                             .reshape(-1, 9, 2)], axis=1)
    valid = np.concatenate([_inside(b, a), _inside(a, b), crossing.reshape(-1, 9)], axis=1)
    count = valid.sum(axis=1)
    mean = (points * valid[..., None]).sum(axis=1) / np.maximum(count, 1)[:, None]
    angle = np.where(valid, np.arctan2(points[..., 1] - mean[:, None, 1],
                                       points[..., 0] - mean[:, None, 0]), np.inf)
    order = np.argsort(angle, axis=1, kind="stable")
    return np.take_along_axis(points, order[..., None], axis=1), count, mean


def clipped_quadrature(points: np.ndarray, facets: np.ndarray, opposing_facets: np.ndarray,
                       normal: np.ndarray, exact_degree: int = 2) -> SurfaceQuadrature:
    """Integration on a flat 3D constrained surface by clipping (module docstring): each
    opposing triangle projected along ``n`` onto the constrained plane is intersected with
    each constrained triangle it overlaps (candidates from :func:`_overlapping_pairs`),
    each convex intersection (:func:`convex_intersections`) split into triangles from its
    vertices' mean, and the rule of :data:`TRIANGLE_RULES` exact for ``exact_degree``
    (2 or 4) applied on each.

    Raises
    ------
    ValueError
        If the projected opposing triangles do not cover every constrained triangle exactly
        once (a gap, the surface's edge, or a fold of the opposing surface over the plane).
    """
    _, _, vt = np.linalg.svd(normal[None, :])
    plane = vt[1:].T                                            # (3, 2) basis of n-perp
    tri_c, nodes_c, area_c = _counter_clockwise(points[facets] @ plane, facets)
    tri_o, nodes_o, area_o = _counter_clockwise(points[opposing_facets] @ plane,
                                                opposing_facets)
    extent = float(np.ptp(tri_c.reshape(-1, 2), axis=0).max())
    seen = area_o > GEOMETRY_TOL * extent ** 2           # edge-on: no area along n
    tri_o, nodes_o = tri_o[seen], nodes_o[seen]
    c, o = _overlapping_pairs(tri_c, tri_o, GEOMETRY_TOL * extent)
    poly, count, centre = convex_intersections(tri_c[c], tri_o[o])
    j = np.arange(int(count.max(initial=0)))
    nxt = np.where(j[None, :] + 1 < count[:, None], j[None, :] + 1, 0)
    first = poly[:, :j.size]
    second = np.take_along_axis(poly, nxt[..., None], axis=1)
    use = (j[None, :] < count[:, None]) & (count[:, None] >= 3)
    pair, _ = np.nonzero(use)
    pieces = np.stack([centre[pair], first[use], second[use]], axis=1)   # (pieces, 3, 2)
    piece_area = 0.5 * _cross(pieces[:, 1] - pieces[:, 0], pieces[:, 2] - pieces[:, 0])
    lam, w = TRIANGLE_RULES[exact_degree]
    x = np.einsum("qk,pkd->pqd", lam, pieces).reshape(-1, 2)
    weight = (piece_area[:, None] * w[None, :]).ravel()
    pair = np.repeat(pair, len(w))
    covered = np.bincount(c[pair], weight, minlength=len(tri_c))
    if np.any(np.abs(covered - area_c) > COVERAGE_TOL * area_c):
        raise _not_covered("over every constrained triangle, once")
    return SurfaceQuadrature(weight=weight, facet=c[pair], constrained=nodes_c[c[pair]],
                             opposing=nodes_o[o[pair]],
                             phi=_barycentric_2d(tri_c[c[pair]], x),
                             phi_opposing=_barycentric_2d(tri_o[o[pair]], x))


def surface_quadrature(points: np.ndarray, facets: np.ndarray, opposing_facets: np.ndarray,
                       normal: np.ndarray, exact_degree: int = 2) -> SurfaceQuadrature:
    """The quadrature of the mortar integrals on a flat constrained surface normal to
    ``normal``: :func:`segment_quadrature` in 2D (exact for degree 5), :func:`clipped_quadrature`
    in 3D (exact for ``exact_degree``, 2 or 4: :data:`TRIANGLE_RULES`).

    Raises
    ------
    ValueError
        If the constrained surface is not flat and normal to ``n``, or the opposing surface
        does not cover it along ``n``.
    """
    n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    c_nodes = np.unique(facets)
    height = points[c_nodes] @ n
    extent = float(np.ptp(points[c_nodes] - np.outer(height, n), axis=0).max())
    if np.ptp(height) > 1e-10 * max(extent, 1e-300):
        raise ValueError("the constrained surface is not flat and normal to the contact "
                         "direction n: the mortar coupling here projects along a constant n")
    if points.shape[1] == 2:
        return segment_quadrature(points, facets, opposing_facets, n)
    return clipped_quadrature(points, facets, opposing_facets, n, exact_degree)


#: The weight ``alpha`` of the modified P2 basis on a triangle (module docstring): any
#: ``0 < alpha < 1/2`` keeps it a basis of the same space with every weight positive.
MODIFIED_ALPHA = 0.2


def modified_coefficients(alpha: float = MODIFIED_ALPHA) -> np.ndarray:
    """The modified P2 basis of a triangle, ``psi_a = sum_c T_ac phi_c`` (Popp, Wohlmuth,
    Gee and Wall 2012): at a vertex ``phi_a + alpha (phi_m + phi_m')`` over the midpoints
    of its two edges, at a midpoint ``(1 - 2 alpha) phi_m``. The columns of ``T`` sum to
    one (the basis sums to one) and the weights are ``int psi_a = 2 alpha |T| / 3`` at a
    vertex and ``(1 - 2 alpha) |T| / 3`` at a midpoint (``int phi_a = 0`` at a vertex)."""
    if not 0.0 < alpha < 0.5:
        raise ValueError(f"parameter 'alpha': {alpha!r} is not allowed; allowed: 0 < alpha "
                         "< 1/2")
    T = np.zeros((6, 6))
    for e, ends in enumerate(FACET_EDGES[3]):
        T[3 + e, 3 + e] = 1.0 - 2.0 * alpha
        T[ends, 3 + e] = alpha
    T[:3, :3] = np.eye(3)
    return T


def multiplier_basis(phi: np.ndarray, dual: bool, degree: int = 1) -> np.ndarray:
    """The multipliers ``psi`` at the quadrature points from the constrained hats
    ``phi (q, k)`` of a P1 or P2 facet: ``phi`` itself (standard; on a P2 triangle the
    modified basis of :func:`modified_coefficients`, whose vertex hats do not integrate
    to zero) or the dual basis (module docstring): at P1 Wohlmuth's ``(k + 1) phi_a - 1``,
    written ``k phi_a - sum_{b != a} phi_b``; at P2 ``A phi`` with
    :func:`dual_coefficients`.

    Raises
    ------
    ValueError
        For a dual basis that does not exist (P2 triangles: :func:`dual_coefficients`).
    """
    if not dual:
        return phi @ modified_coefficients().T if phi.shape[1] == 6 else phi
    if degree == 2:
        vertices = {3: 2, 6: 3}[phi.shape[1]]
        return phi @ dual_coefficients(vertices, degree).T
    k = phi.shape[1]
    return k * phi - sum(np.roll(phi, shift, axis=1) for shift in range(1, k))


def reference_rule(vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """A rule on the reference facet with ``vertices`` vertices (a segment, 2; a triangle,
    3), exact for degree 4: barycentric points and weights summing to 1 (3-point Gauss;
    :data:`TRIANGLE_RULES`)."""
    if vertices == 2:
        g, w = np.polynomial.legendre.leggauss(GAUSS_POINTS)
        s = 0.5 * (1.0 + g)
        return np.column_stack([1.0 - s, s]), 0.5 * w
    return TRIANGLE_RULES[4]


def dual_coefficients(vertices: int, degree: int) -> np.ndarray:
    """The dual basis ``psi_a = sum_c A_ac phi_c`` on a facet with ``vertices`` vertices
    and P``degree`` hats ``phi``: ``A = diag(m) M^-1`` with the local mass matrix ``M``
    and ``m = M 1`` (module docstring), so ``int psi_a phi_b = delta_ab m_a``. Scale-free:
    computed on the reference facet.

    Raises
    ------
    ValueError
        If some ``m_a <= 0``: the P2 triangle, whose vertex hats integrate to zero, has no
        dual basis (the multiplier of a vertex row would vanish).
    """
    bary, w = reference_rule(vertices)
    phi = bary if degree == 1 else shape_functions(bary)
    mass_matrix = np.einsum("q,qa,qb->ab", w, phi, phi)
    m = mass_matrix.sum(axis=1)
    if np.any(m <= 1e-12):
        facet = {2: "segment", 3: "triangle"}[vertices]
        raise ValueError(f"the dual multipliers of the P{degree} trace on a {facet} do not exist "
                         f"(its vertex hats integrate to zero, int phi_i = 0, and the dual basis "
                         f"needs int phi_i > 0); allowed: coupling='mortar' at degree={degree}, "
                         "or coupling='mortar_dual' at degree=1")
    return np.linalg.solve(mass_matrix, np.diag(m)).T


def quadratic_quadrature(quad: SurfaceQuadrature, mesh: QuadraticMesh) -> SurfaceQuadrature:
    """``quad`` with the P2 hats of both facets at its points: the facets' vertices
    followed by their edges' midpoints (:func:`problems.fem.quadratic.quadratic_facets`'
    order) and :func:`problems.fem.quadratic.shape_functions` of the P1 hats (the
    barycentric coordinates)."""
    def lift(nodes):
        return np.column_stack([nodes] + [mesh.midpoint(nodes[:, i], nodes[:, j])
                                          for i, j in FACET_EDGES[nodes.shape[1]]])
    return replace(quad, constrained=lift(quad.constrained), opposing=lift(quad.opposing),
                   phi=shape_functions(quad.phi), phi_opposing=shape_functions(quad.phi_opposing))


def mortar_integrals(points: np.ndarray, facets: np.ndarray, opposing_facets: np.ndarray,
                     normal: np.ndarray, dual: bool,
                     quadratic: QuadraticMesh | None = None) -> MortarIntegrals:
    """The mortar integrals (module docstring) of a flat constrained surface.

    Parameters
    ----------
    points : (N, d) array
        All nodes (both bodies), d = 2 or 3.
    facets, opposing_facets : (k, d), (k', d) int arrays
        Facets (segments, triangles) of the constrained and of the opposing surface.
    normal : (d,) array
        Unit contact direction ``n``, from the constrained towards the opposing body.
    dual : bool
        Dual (Wohlmuth) instead of standard multipliers.
    quadratic : QuadraticMesh, optional
        The P2 mesh of ``points`` (:func:`problems.fem.quadratic.quadratic_mesh_of`): P2
        hats and multipliers, ``facets`` and ``opposing_facets`` still given by their
        vertices. ``None``: P1.

    Returns
    -------
    MortarIntegrals
        Rows for every node of ``facets`` (and every midpoint of their edges at P2),
        sorted by x, then y (then z): the nodal rows' order.

    Raises
    ------
    ValueError
        As :func:`surface_quadrature` and :func:`dual_coefficients`.
    """
    degree = 1 if quadratic is None else 2
    n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    quad = surface_quadrature(points, facets, opposing_facets, n, INTEGRAND_DEGREE[degree])
    # the gap from the P1 geometry (the P2 meshes are subparametric: the same points)
    x_o = np.einsum("qk,qkd->qd", quad.phi_opposing, points[quad.opposing])
    x_c = np.einsum("qk,qkd->qd", quad.phi, points[quad.constrained])
    gap = (x_o - x_c) @ n
    if quadratic is not None:
        quad = quadratic_quadrature(quad, quadratic)
        facets = quadratic_facets(quadratic, facets)
    wq, phi_c, phi_o = quad.weight, quad.phi, quad.phi_opposing
    psi = multiplier_basis(phi_c, dual, degree)
    c_nodes = np.unique(facets)
    c_nodes = c_nodes[np.lexsort(points[c_nodes].T[::-1])]   # as the nodal rows' order
    row_of = -np.ones(len(points), dtype=np.int64)
    row_of[c_nodes] = np.arange(len(c_nodes))
    rows_c = row_of[quad.constrained]                     # (q, k)
    m = len(c_nodes)

    def assemble(test, trial, cols):
        vals = wq[:, None, None] * test[:, :, None] * trial[:, None, :]
        r = np.broadcast_to(rows_c[:, :, None], vals.shape)
        c = np.broadcast_to(cols[:, None, :], vals.shape)
        return r.ravel(), c.ravel(), vals.ravel()

    # the rows' weights int psi_i (int phi_i for the dual basis, where they are equal)
    mass = np.bincount(rows_c.ravel(), (wq[:, None] * (phi_c if dual else psi)).ravel(),
                       minlength=m)
    if dual:                                              # biorthogonality: D = diag(m) exactly
        D = sp.diags(mass, format="csr")
    else:
        r, c, v = assemble(psi, phi_c, rows_c)
        D = sp.csr_matrix((v, (r, c)), shape=(m, m))
    r, c, v = assemble(psi, phi_o, quad.opposing)
    M = sp.csr_matrix((v, (r, c)), shape=(m, len(points)))
    weighted_gap = np.bincount(rows_c.ravel(), (wq[:, None] * psi * gap[:, None]).ravel(),
                               minlength=m)
    return MortarIntegrals(nodes=c_nodes, D=D, M=M, weighted_gap=weighted_gap, mass=mass)


def force_pressure_map(points: np.ndarray, facets: np.ndarray, nodes: np.ndarray,
                       quadratic: QuadraticMesh, forces: sp.spmatrix) -> sp.csr_matrix:
    """The P2 nodal pressure of row multipliers (module docstring): ``P diag(1/m_P1) P'
    forces``, with ``forces`` the map from the multipliers to the normal forces on the
    constrained P2 ``nodes``, ``P`` the P1-to-P2 interpolation on the surface (a vertex
    itself, a midpoint the mean of its edge's vertices) and ``m_P1`` the vertices' P1
    lumped mass on the vertex ``facets``."""
    vertices = np.unique(facets)
    col_of = -np.ones(len(points), dtype=np.int64)
    col_of[vertices] = np.arange(len(vertices))
    is_vertex = nodes < quadratic.n_vertices
    ends = quadratic.edges[np.where(is_vertex, 0, nodes - quadratic.n_vertices)]
    rows = np.concatenate([np.flatnonzero(is_vertex), np.repeat(np.flatnonzero(~is_vertex), 2)])
    cols = np.concatenate([col_of[nodes[is_vertex]], col_of[ends[~is_vertex]].ravel()])
    vals = np.concatenate([np.ones(is_vertex.sum()), np.full(2 * (~is_vertex).sum(), 0.5)])
    P = sp.csr_matrix((vals, (rows, cols)), shape=(len(nodes), len(vertices)))
    m_p1 = lumped_surface_mass(points, facets)[vertices]
    return (P @ sp.diags(1.0 / m_p1) @ P.T @ forces).tocsr()


def mortar(qp: ContactQP, dual: bool = False) -> ContactQP:
    """``qp`` with its nodal rows replaced by the mortar weighted gaps (module docstring).

    Parameters
    ----------
    qp : ContactQP
        The nodal P1 or P2 constraints of a 2D or 3D two-body scene, searched along a
        constant ``n`` (Alg. 7.1 case b), without reverse rows.
    dual : bool
        Dual multipliers (``mortar_dual``) instead of standard ones (``mortar``).

    Returns
    -------
    ContactQP
        One row per node of the constrained surface (vertices, and edge midpoints at P2),
        scaled by ``1/s_i``: ``s_i = m_i`` at P1 and on P2 triangles, the HRZ lumped mass
        on P2 segments (module docstring); ``contact`` keeps its facets and opposing facets, with those nodes,
        ``mass = s``, the direction ``n`` and, at P2, the pressure recovered from the
        forces (:func:`force_pressure_map`; at P1 the pressure is the multiplier over
        ``m_i``).

    Raises
    ------
    ValueError
        For a ContactQP the mortar coupling does not take (naming the parameter), a dual
        basis that does not exist (P2 in 3D, :func:`dual_coefficients`) or a surface
        :func:`surface_quadrature` refuses.
    """
    c = qp.contact
    if qp.mesh is None or c is None or qp.stabilisation is not None or qp.C is not None:
        raise ValueError("parameter 'qp': a nodal ContactQP with mesh and contact is required")
    degree, dim = qp.mesh.degree, qp.dim
    if dual:
        dual_coefficients(dim, degree)                # refuses a basis that does not exist
    if c.search != "along_direction":
        raise ValueError(f"parameter 'search': {c.search!r} is not allowed with the mortar "
                         "coupling; allowed: along_direction (projection along a constant n)")
    n = c.direction.mean(axis=0)
    n = n / np.linalg.norm(n)
    pts = qp.mesh.points
    quadratic = quadratic_mesh_of(pts, qp.mesh.cells) if degree == 2 else None
    mi = mortar_integrals(pts, c.facets, c.opposing_facets, n, dual, quadratic)
    # P2 segments: the HRZ mass (m_i itself, computed as the nodal P2 rows' contact mass)
    scale = surface_mass_p2(pts, quadratic_facets(quadratic, c.facets))[mi.nodes] \
        if quadratic is not None and dim == 2 else mi.mass
    m = len(mi.nodes)
    D, M = mi.D.tocoo(), mi.M.tocoo()
    rows = [np.concatenate([D.row, M.row])] * dim
    full = sp.csr_matrix(
        (np.concatenate([np.concatenate([D.data, -M.data]) * n[k] for k in range(dim)]),
         (np.concatenate(rows), np.concatenate([np.concatenate([dim * mi.nodes[D.col] + k,
                                                                dim * M.col + k])
                                                for k in range(dim)]))),
        shape=(m, dim * len(pts)))
    full = sp.diags(1.0 / scale) @ full
    full.eliminate_zeros()
    pressure_map = None if quadratic is None else force_pressure_map(
        pts, c.facets, mi.nodes, quadratic, mi.D.T @ sp.diags(1.0 / scale))
    contact = replace(c, nodes=mi.nodes, mass=scale, direction=np.tile(n, (m, 1)), dropped=0,
                      pressure_map=pressure_map)
    kind = "mortar, dual multipliers" if dual else "mortar"
    return replace(qp, B=full[:, qp.free_dofs].tocsr(),
                   g=mi.weighted_gap / scale - full @ qp.u_fixed, contact=contact,
                   name=f"{qp.name} ({kind})", cache=SharedWork())
