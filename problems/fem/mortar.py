"""Mortar coupling of two non-matching 2D contact surfaces: segment-based integration,
standard and dual Lagrange multipliers (thesis Sect. 6.1, Remark 6.8; Wohlmuth 2000;
Hueber and Wohlmuth 2005).

The nodal constraints of Alg. 7.1 ask each constrained node to stay out of the
opposing body. The mortar method asks it in the mean instead: row ``i`` is the
weighted gap

    (1/m_i) int_Gamma psi_i n.(u_c - u_o) ds  <=  (1/m_i) int_Gamma psi_i gap ds,
    m_i = int_Gamma phi_i ds,

with ``Gamma`` the constrained surface, ``phi_i`` its P1 hats, ``u_c`` the constrained
body's and ``u_o`` the opposing body's displacement at the opposing point, ``gap``
the distance from ``Gamma`` to the opposing surface along ``n``, and ``psi_i`` the
multiplier basis:

* ``mortar``: the standard basis ``psi_i = phi_i``. Its constrained block
  ``D_ij = int phi_i phi_j`` is the surface mass matrix: each row reaches its node's
  neighbours, so the rows are not node-wise.
* ``mortar_dual``: Wohlmuth's dual basis (Wohlmuth 2000), on each segment
  ``psi_a = 2 phi_a - phi_b``: biorthogonal, ``int psi_i phi_j = delta_ij m_i``, so
  ``D = diag(m)``, and row ``i`` moves its constrained node by exactly ``n``: each row
  owns one constrained node, as nodal rows do (the box transformation of
  :mod:`solvers.contact_box` applies).

Both bases sum to 1 on each segment, so a uniform pressure is transmitted exactly (the
contact patch test); the multiplier over ``m_i`` is the nodal pressure (Sect. 8.6), as
for flat_blocks' mortar rows.

What is approximated, and how:

* the surfaces are the meshes' polygons (the circle of circle_square by its chords);
* the normal field is the constant contact direction ``n`` of the scene (Alg. 7.1
  case b), which is the constrained surface's normal where that surface is straight
  (circle_square's and flat_blocks' constrained edges): the opposing segments are
  projected onto ``Gamma`` along ``n``. A curved constrained surface would need a
  continuous nodal normal field (averaged normals) and is refused;
* the integrals: the projected opposing nodes split ``Gamma`` into pieces on which
  both surfaces are straight and the projection is affine, so every integrand is a
  polynomial of degree <= 2 in the piece's parameter, integrated exactly by 3-point
  Gauss quadrature (segment-based integration);
* linearisation: the weighted gaps are taken in the reference configuration (small
  displacements, as the nodal rows of Alg. 7.1).

Pure functions: no files, no printing.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from problems.qp import ContactQP, SharedWork

#: The mortar couplings: standard and dual multipliers (module docstring).
MORTAR_COUPLINGS = ("mortar", "mortar_dual")

#: Gauss points per piece: exact for the degree-2 integrands of the module docstring.
GAUSS_POINTS = 3


@dataclass(frozen=True)
class MortarIntegrals:
    """The segment-based mortar integrals on a 2D constrained surface.

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
        ``m_i = int phi_i``.
    """

    nodes: np.ndarray
    D: sp.csr_matrix
    M: sp.csr_matrix
    weighted_gap: np.ndarray
    mass: np.ndarray


def _graph(points: np.ndarray, facets: np.ndarray, tangent: np.ndarray, which: str):
    """Segments of a polygon that is a graph over the tangent coordinate: their end
    parameters ``(t0 < t1)`` and end nodes sorted by ``t0``; refuses overlapping ones."""
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
    return t, ends


def _locate(t_segments: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Index of the segment (sorted, non-overlapping) containing each parameter."""
    return np.clip(np.searchsorted(t_segments[:, 0], at, side="right") - 1, 0,
                   len(t_segments) - 1)


def mortar_integrals(points: np.ndarray, facets: np.ndarray, opposing_facets: np.ndarray,
                     normal: np.ndarray, dual: bool) -> MortarIntegrals:
    """The mortar integrals (module docstring) of a straight 2D constrained surface.

    Parameters
    ----------
    points : (N, 2) array
        All nodes (both bodies).
    facets, opposing_facets : (k, 2), (k', 2) int arrays
        Segments of the constrained and of the opposing surface.
    normal : (2,) array
        Unit contact direction ``n``, from the constrained towards the opposing body.
    dual : bool
        Dual (Wohlmuth) instead of standard multipliers.

    Returns
    -------
    MortarIntegrals
        Rows for every node of ``facets``, sorted by x, then y (the nodal rows' order).

    Raises
    ------
    ValueError
        If the constrained surface is not straight and normal to ``n``, or the opposing
        surface does not cover it along ``n``.
    """
    n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    tangent = np.array([n[1], -n[0]])
    c_nodes = np.unique(facets)
    height = points[c_nodes] @ n
    extent = float(np.ptp(points[c_nodes] @ tangent))
    if np.ptp(height) > 1e-10 * max(extent, 1e-300):
        raise ValueError("the constrained surface is not straight and normal to the contact "
                         "direction n: the mortar coupling here projects along a constant n")
    t_c, ends_c = _graph(points, facets, tangent, "constrained")
    t_o, ends_o = _graph(points, opposing_facets, tangent, "opposing")
    lo, hi = t_c[0, 0], t_c[-1, 1]
    tol = 1e-12 * max(extent, 1e-300)
    covered = np.all(t_o[1:, 0] <= t_o[:-1, 1] + tol) and t_o[0, 0] <= lo + tol \
        and t_o[-1, 1] >= hi - tol
    if not covered:
        raise ValueError("the opposing surface does not cover the constrained surface along "
                         "the contact direction n: the mortar integrals need it over every "
                         "constrained segment")
    breaks = np.unique(np.concatenate([t_c.ravel(), t_o.ravel()]))
    breaks = breaks[(breaks >= lo) & (breaks <= hi)]
    g, w = np.polynomial.legendre.leggauss(GAUSS_POINTS)
    a, b = breaks[:-1, None], breaks[1:, None]
    tq = (0.5 * (a + b) + 0.5 * (b - a) * g).ravel()
    wq = (0.5 * (b - a) * w).ravel()                    # ds = dt on a surface normal to n
    kc, ko = _locate(t_c, tq), _locate(t_o, tq)
    sc = (tq - t_c[kc, 0]) / (t_c[kc, 1] - t_c[kc, 0])
    so = (tq - t_o[ko, 0]) / (t_o[ko, 1] - t_o[ko, 0])
    phi_c = np.stack([1 - sc, sc], axis=1)               # hats of the constrained ends
    phi_o = np.stack([1 - so, so], axis=1)
    psi = np.stack([2 * phi_c[:, 0] - phi_c[:, 1], 2 * phi_c[:, 1] - phi_c[:, 0]],
                   axis=1) if dual else phi_c
    x_o = (phi_o[:, :1] * points[ends_o[ko, 0]] + phi_o[:, 1:] * points[ends_o[ko, 1]])
    x_c = (phi_c[:, :1] * points[ends_c[kc, 0]] + phi_c[:, 1:] * points[ends_c[kc, 1]])
    gap = (x_o - x_c) @ n
    row_of = -np.ones(len(points), dtype=np.int64)
    c_nodes = c_nodes[np.lexsort(points[c_nodes].T[::-1])]   # as the nodal rows' order
    row_of[c_nodes] = np.arange(len(c_nodes))
    rows_c = row_of[ends_c[kc]]                           # (q, 2)
    m = len(c_nodes)

    def assemble(test, trial, cols):
        vals = wq[:, None, None] * test[:, :, None] * trial[:, None, :]
        r = np.broadcast_to(rows_c[:, :, None], vals.shape)
        c = np.broadcast_to(cols[:, None, :], vals.shape)
        return r.ravel(), c.ravel(), vals.ravel()

    mass = np.bincount(rows_c.ravel(), (wq[:, None] * phi_c).ravel(), minlength=m)
    if dual:                                              # biorthogonality: D = diag(m) exactly
        D = sp.diags(mass, format="csr")
    else:
        r, c, v = assemble(psi, phi_c, rows_c)
        D = sp.csr_matrix((v, (r, c)), shape=(m, m))
    r, c, v = assemble(psi, phi_o, ends_o[ko])
    M = sp.csr_matrix((v, (r, c)), shape=(m, len(points)))
    weighted_gap = np.bincount(rows_c.ravel(), (wq[:, None] * psi * gap[:, None]).ravel(),
                               minlength=m)
    return MortarIntegrals(nodes=c_nodes, D=D, M=M, weighted_gap=weighted_gap, mass=mass)


def mortar(qp: ContactQP, dual: bool = False) -> ContactQP:
    """``qp`` with its nodal rows replaced by the mortar weighted gaps (module docstring).

    Parameters
    ----------
    qp : ContactQP
        The nodal constraints of a 2D two-body scene, searched along a constant ``n``
        (Alg. 7.1 case b), without reverse rows.
    dual : bool
        Dual multipliers (``mortar_dual``) instead of standard ones (``mortar``).

    Returns
    -------
    ContactQP
        One row per node of the constrained surface; ``contact`` keeps its facets and
        opposing facets, with those nodes, their masses and the direction ``n``.
    """
    c = qp.contact
    if qp.mesh is None or c is None or qp.stabilisation is not None or qp.C is not None:
        raise ValueError("parameter 'qp': a nodal ContactQP with mesh and contact is required")
    if qp.dim != 2:
        raise ValueError(f"parameter 'dim': {qp.dim} is not allowed; allowed: 2 (the mortar "
                         "coupling integrates on segments)")
    if c.search != "along_direction":
        raise ValueError(f"parameter 'search': {c.search!r} is not allowed with the mortar "
                         "coupling; allowed: along_direction (projection along a constant n)")
    n = c.direction.mean(axis=0)
    n = n / np.linalg.norm(n)
    pts = qp.mesh.points
    mi = mortar_integrals(pts, c.facets, c.opposing_facets, n, dual)
    m = len(mi.nodes)
    D, M = mi.D.tocoo(), mi.M.tocoo()
    rows = [np.concatenate([D.row, M.row])] * 2
    full = sp.csr_matrix(
        (np.concatenate([np.concatenate([D.data, -M.data]) * n[k] for k in range(2)]),
         (np.concatenate(rows), np.concatenate([np.concatenate([2 * mi.nodes[D.col] + k,
                                                                2 * M.col + k])
                                                for k in range(2)]))),
        shape=(m, 2 * len(pts)))
    full = sp.diags(1.0 / mi.mass) @ full
    full.eliminate_zeros()
    contact = replace(c, nodes=mi.nodes, mass=mi.mass, direction=np.tile(n, (m, 1)), dropped=0)
    kind = "mortar, dual multipliers" if dual else "mortar"
    return replace(qp, B=full[:, qp.free_dofs].tocsr(),
                   g=mi.weighted_gap / mi.mass - full @ qp.u_fixed, contact=contact,
                   name=f"{qp.name} ({kind})", cache=SharedWork())
