"""The ad-hoc element error estimators of thesis Sect. 7.4 for P1 elasticity.

Both act on the stacked two-body mesh of a :class:`problems.qp.ContactQP`
(``qp.mesh``) and a full nodal displacement (``qp.full_displacement(u)``);
2D (triangles, plane strain) and 3D (tetrahedra).

* :func:`eta1_squared`, the residual part of (5.17b)::

      eta_T1^2 = h_T^2 ||div sigma(u_h) + f||_T^2
               + 1/2 sum_{E in E(T), interior} h_T ||[sigma(u_h) nu]||_E^2
               + sum_{E in E(T), Neumann}    h_T ||sigma(u_h) nu - L||_E^2

  For P1 ``sigma(u_h)`` is constant per cell, so ``div sigma(u_h) = 0`` and
  every norm is a constant times a measure. ``h_T`` is the longest edge of
  ``T``. Interior facets are those of two cells (of one body: the bodies share
  no nodes); Neumann facets are the boundary facets that are neither
  Dirichlet (every DOF of every vertex prescribed) nor on the constrained or
  the opposing contact surface (the thesis omits the contact terms).

* :func:`eta2_squared`, the penetration ("hanging node") term (7.9) and
  Fig. 7.1: ``eta_T2^2 = d_T^2 h_T^(d-2)`` on the constrained body's cells at
  the constrained surface (the thesis adds it on the master surface ``l``).
  ``d_i = max(0, -g_i)`` is the penetration of node ``i`` of the opposing
  surface into the constrained body in the deformed configuration, found by
  the reverse search of Alg. 7.1: :func:`problems.fem.contact.contact_constraints`
  on ``points + u`` with the opposing nodes as the constrained ones, the
  constrained surface's facets as the opposing ones and the direction ``-n``.
  Assignment: node ``i`` counts for the cell whose constrained-surface facet
  holds the foot point ``Q_i`` (the line through the deformed node along
  ``-n`` meets the deformed facet there); on a vertex or edge shared by
  several facets, the facet of smallest index (the search's tie rule).
  ``d_T^2`` is the sum of ``d_i^2`` over the nodes assigned to ``T``. The
  thesis's ``d_T^2`` sums over the patch ``omega(T)``; assigning each node to
  one facet counts every penetration once.

Pure functions of arrays: no files, no printing.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from problems.fem.contact import contact_constraints
from problems.fem.elasticity import barycentric_gradients, strain_stress
from problems.qp import ContactQP

VARIANTS = ("eta1", "eta1+eta2")


# --------------------------------------------------------------------------- geometry
def cell_diameters(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """``h_T``: the longest edge of each simplex."""
    x = np.asarray(points, dtype=float)[np.asarray(cells)]
    n = x.shape[1]
    return np.max([np.linalg.norm(x[:, i] - x[:, j], axis=1)
                   for i in range(n) for j in range(i + 1, n)], axis=0)


@dataclass
class Facets:
    """Every facet of a simplex mesh once, with the cells on either side.

    Attributes
    ----------
    nodes : (k, d) int array
        Facet vertices (sorted ids).
    cells : (k, 2) int array
        The two cells of an interior facet; ``cells[:, 1] == -1`` on the boundary.
    normal : (k, d) array
        Unit normal pointing out of ``cells[:, 0]``.
    measure : (k,) array
        Length (2D) or area (3D).
    """

    nodes: np.ndarray
    cells: np.ndarray
    normal: np.ndarray
    measure: np.ndarray

    @property
    def interior(self) -> np.ndarray:
        return self.cells[:, 1] >= 0


def mesh_facets(points: np.ndarray, cells: np.ndarray) -> Facets:
    """All facets of a conforming simplex mesh (2D segments, 3D triangles).

    Raises
    ------
    ValueError
        If a facet belongs to more than two cells.
    """
    pts = np.asarray(points, dtype=float)
    t = np.asarray(cells, dtype=np.int64)
    n_loc = t.shape[1]
    f = np.sort(np.stack([np.delete(t, k, axis=1) for k in range(n_loc)], axis=1)
                .reshape(-1, n_loc - 1), axis=1)
    owner = np.repeat(np.arange(len(t)), n_loc)
    opposite = t.ravel()                           # the vertex opposite each local facet
    uniq, inv, counts = np.unique(f, axis=0, return_inverse=True, return_counts=True)
    if counts.max() > 2:
        raise ValueError("parameter 'cells': a facet is shared by more than two cells; "
                         "allowed: a conforming simplex mesh")
    inv = inv.ravel()
    order = np.argsort(inv, kind="stable")
    first = np.full(len(uniq), -1)
    second = np.full(len(uniq), -1)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    first[:] = order[start]
    two = counts == 2
    second[two] = order[start[two] + 1]
    cell_pair = np.stack([owner[first], np.where(two, owner[np.maximum(second, 0)], -1)], axis=1)
    x = pts[uniq]
    if n_loc == 3:
        e = x[:, 1] - x[:, 0]
        normal = np.stack([e[:, 1], -e[:, 0]], axis=1)
    else:
        normal = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    size = np.linalg.norm(normal, axis=1)
    normal = normal / size[:, None]
    measure = size if n_loc == 3 else 0.5 * size
    inward = np.einsum("ij,ij->i", normal, pts[opposite[first]] - x[:, 0]) > 0
    normal[inward] *= -1.0
    return Facets(nodes=uniq, cells=cell_pair, normal=normal, measure=measure)


def _facet_rows(facets: Facets, query: np.ndarray) -> np.ndarray:
    """Row of each facet of ``query`` (any vertex order) in ``facets``; -1 if absent."""
    q = np.sort(np.asarray(query, dtype=np.int64).reshape(len(query), -1), axis=1)
    if not len(q):
        return np.zeros(0, dtype=np.int64)
    n = int(max(facets.nodes.max(), q.max())) + 1
    key = lambda a: np.ravel_multi_index(a.T, (n,) * a.shape[1])
    k_all = key(facets.nodes)
    order = np.argsort(k_all)
    kq = key(q)
    pos = np.clip(np.searchsorted(k_all[order], kq), 0, len(order) - 1)
    found = k_all[order][pos] == kq
    return np.where(found, order[pos], -1)


# --------------------------------------------------------------------------- eta_T1
def eta1_squared(points, cells, u, E, nu, *, body_force=None, neumann=None,
                 traction=None, facets: Facets | None = None) -> np.ndarray:
    """``eta_T1^2`` of Sect. 7.4 per cell (module docstring).

    Parameters
    ----------
    points : (n_nodes, d) array
    cells : (n_cells, d + 1) int array
    u : (n_nodes, d) or (n_nodes * d,) array
        Full nodal P1 displacement.
    E, nu : float or (n_cells,) array
    body_force : (d,) or (n_cells, d) array, optional
        ``f`` per cell (default zero).
    neumann : (k,) int or bool array, optional
        Rows of ``facets`` that are Neumann facets (default: none; boundary
        facets not listed carry no term).
    traction : (d,) or (k, d) array, optional
        ``L`` on the Neumann facets (default zero: traction-free).
    facets : Facets, optional
        :func:`mesh_facets` of the mesh, if already computed.

    Returns
    -------
    (n_cells,) array
    """
    pts = np.asarray(points, dtype=float)
    t = np.asarray(cells, dtype=np.int64)
    d = pts.shape[1]
    fc = mesh_facets(pts, t) if facets is None else facets
    _, sigma = strain_stress(pts, t, u, E, nu)
    _, vol = barycentric_gradients(pts, t)
    h = cell_diameters(pts, t)
    out = np.zeros(len(t))
    if body_force is not None:
        f = np.broadcast_to(np.asarray(body_force, dtype=float), (len(t), d))
        out += h ** 2 * np.einsum("ij,ij->i", f, f) * vol
    inner = np.flatnonzero(fc.interior)
    a, b = fc.cells[inner, 0], fc.cells[inner, 1]
    jump = np.einsum("fij,fj->fi", sigma[a] - sigma[b], fc.normal[inner])
    j2 = np.einsum("fi,fi->f", jump, jump) * fc.measure[inner]
    np.add.at(out, a, 0.5 * h[a] * j2)
    np.add.at(out, b, 0.5 * h[b] * j2)
    if neumann is not None:
        rows = np.asarray(neumann)
        rows = np.flatnonzero(rows) if rows.dtype == bool else rows.astype(np.int64)
        if np.any(fc.interior[rows]):
            raise ValueError("parameter 'neumann': interior facets are not allowed; "
                             "allowed: boundary facets")
        c = fc.cells[rows, 0]
        L = np.zeros((len(rows), d)) if traction is None else np.broadcast_to(
            np.asarray(traction, dtype=float), (len(rows), d))
        r = np.einsum("fij,fj->fi", sigma[c], fc.normal[rows]) - L
        np.add.at(out, c, h[c] * np.einsum("fi,fi->f", r, r) * fc.measure[rows])
    return out


# --------------------------------------------------------------------------- eta_T2
@dataclass
class Penetrations:
    """The reverse search behind ``eta_T2`` (module docstring).

    Attributes
    ----------
    nodes : (k,) int array
        Opposing-surface nodes whose line along ``-n`` met a constrained facet.
    depth : (k,) array
        ``d_i = max(0, -g_i)``, the penetration into the constrained body.
    cell : (k,) int array
        The constrained body's cell each node is assigned to.
    """

    nodes: np.ndarray
    depth: np.ndarray
    cell: np.ndarray


def penetrations(qp: ContactQP, u_full: np.ndarray, direction=None,
                 facets: Facets | None = None) -> Penetrations:
    """Penetration of the opposing surface's nodes into the constrained body, deformed.

    Parameters
    ----------
    qp : ContactQP
        With ``mesh`` and ``contact``.
    u_full : (n_nodes, d) array
        ``qp.full_displacement(u)``.
    direction : (d,) array, optional
        ``n`` (constrained towards opposing body); default the normalised mean
        of ``qp.contact.direction`` (exact for case b's constant ``n``).
    """
    if qp.mesh is None or qp.contact is None:
        raise ValueError("parameter 'qp': a ContactQP with mesh and contact is required")
    pts = qp.mesh.points
    x = pts + np.asarray(u_full, dtype=float).reshape(pts.shape)
    n = (np.asarray(qp.contact.direction, dtype=float).mean(axis=0) if direction is None
         else np.asarray(direction, dtype=float))
    n = n / np.linalg.norm(n)
    opp_nodes = np.unique(qp.contact.opposing_facets)
    cc = contact_constraints(x, opp_nodes, qp.contact.facets, direction=-n, search="along_direction")
    fc = mesh_facets(pts, qp.mesh.cells) if facets is None else facets
    rows = _facet_rows(fc, qp.contact.facets)
    if np.any(rows < 0) or np.any(fc.interior[rows]):
        raise ValueError("parameter 'qp': contact.facets are not boundary facets of qp.mesh")
    cell = fc.cells[rows[cc.facet], 0] if cc.m else np.zeros(0, dtype=np.int64)
    return Penetrations(nodes=cc.rows, depth=np.maximum(0.0, -cc.g), cell=cell)


def eta2_squared(qp: ContactQP, u_full: np.ndarray, direction=None,
                 facets: Facets | None = None) -> np.ndarray:
    """``eta_T2^2 = d_T^2 h_T^(d-2)``, (7.9), per cell of ``qp.mesh`` (zero off the
    constrained surface)."""
    pen = penetrations(qp, u_full, direction, facets)
    out = np.zeros(len(qp.mesh.cells))
    np.add.at(out, pen.cell, pen.depth ** 2)
    d = qp.dim
    if d != 2:
        out *= cell_diameters(qp.mesh.points, qp.mesh.cells) ** (d - 2)
    return out


# --------------------------------------------------------------------------- on a ContactQP
def neumann_facets(qp: ContactQP, facets: Facets) -> np.ndarray:
    """Rows of ``facets`` on the Neumann boundary of ``qp``: boundary facets neither
    Dirichlet (every DOF of every vertex prescribed) nor on a contact surface."""
    d = qp.dim
    fixed = np.ones(qp.n_nodes * d, dtype=bool)
    fixed[qp.free_dofs] = False
    node_fixed = fixed.reshape(-1, d).all(axis=1)
    boundary = ~facets.interior
    dirichlet = node_fixed[facets.nodes].all(axis=1)
    contact = np.zeros(len(facets.measure), dtype=bool)
    for f in (qp.contact.facets, qp.contact.opposing_facets):
        rows = _facet_rows(facets, f)
        contact[rows[rows >= 0]] = True
    return np.flatnonzero(boundary & ~dirichlet & ~contact)


def estimate(qp: ContactQP, u: np.ndarray, variant: str = "eta1+eta2", *, body_force=None,
             tractions=(), direction=None, eta2_weight: float = 1.0) -> dict:
    """Per-cell ``eta_T^2`` of ``qp`` at the free-DOF solution ``u`` (Sect. 7.4).

    Parameters
    ----------
    qp : ContactQP
        With ``mesh``, ``contact``, ``free_dofs`` and ``u_fixed``.
    u : (qp.n,) array
    variant : {"eta1", "eta1+eta2"}
        ``eta_T^2 = eta_T1^2`` or ``eta_T1^2 + eta2_weight * eta_T2^2``.
    body_force : (d,) or (n_cells, d) array, optional
    tractions : sequence of (body, selector, traction)
        Neumann loads ``L`` (e.g. a scene's :class:`problems.fem.two_body.Traction`
        list): on the Neumann facets of cells of ``body`` whose centroid the
        selector accepts; traction-free elsewhere.
    direction : (d,) array, optional
        ``n`` for the reverse search (see :func:`penetrations`).
    eta2_weight : float
        The thesis's "certain constant" in front of ``eta_T2`` (>= 0).

    Returns
    -------
    dict
        ``eta2`` (the total ``eta_T^2`` per cell), ``eta1_sq``, ``eta2_sq``.
    """
    if variant not in VARIANTS:
        raise ValueError(f"parameter 'variant': {variant!r} is not allowed; "
                         f"allowed: {', '.join(VARIANTS)}")
    if not eta2_weight >= 0:
        raise ValueError(f"parameter 'eta2_weight': {eta2_weight!r} is not allowed; "
                         "allowed: a number >= 0")
    mesh = qp.mesh
    u_full = qp.full_displacement(u)
    fc = mesh_facets(mesh.points, mesh.cells)
    rows = neumann_facets(qp, fc)
    d = qp.dim
    L = np.zeros((len(rows), d))
    if tractions:
        body_of_cell = mesh.body_of_node[mesh.cells[:, 0]]
        cen = mesh.points[fc.nodes[rows]].mean(axis=1)
        owner = body_of_cell[fc.cells[rows, 0]]
        for tr in tractions:
            body, on, value = ((tr.body, tr.on, tr.traction) if hasattr(tr, "on") else tr)
            sel = (owner == body) & np.asarray(on(cen), dtype=bool)
            L[sel] += np.asarray(value, dtype=float)
    e1 = eta1_squared(mesh.points, mesh.cells, u_full, mesh.E_cell, mesh.nu_cell,
                      body_force=body_force, neumann=rows, traction=L, facets=fc)
    e2 = (eta2_squared(qp, u_full, direction, fc) if variant == "eta1+eta2"
          else np.zeros(len(mesh.cells)))
    return {"eta2": e1 + eta2_weight * e2, "eta1_sq": e1, "eta2_sq": e2}
