"""Nested meshes of a constrained surface, for the multilevel S-hat (Sect. 8.6, Remark 8.15).

A scene's refinement hierarchy gives the constrained surface on every mesh
level (:func:`surface_levels`). Below the coarsest mesh the surface can be
coarsened further when it is a tensor-product grid in some parameter
coordinates (:func:`tensor_coarsening`): a straight edge (2D) or a structured
face (3D). Pure functions of arrays; nodal values on every level are ordered as
the nodes given.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from problems.qp import SurfaceHierarchy


def _line_interpolation(s_coarse: np.ndarray, s_fine: np.ndarray) -> sp.csr_matrix:
    """Piecewise-linear interpolation from sorted coarse to sorted fine 1D nodes."""
    if len(s_coarse) == 1:
        return sp.csr_matrix(np.ones((len(s_fine), 1)))
    j = np.clip(np.searchsorted(s_coarse, s_fine, side="right") - 1, 0, len(s_coarse) - 2)
    t = np.clip((s_fine - s_coarse[j]) / (s_coarse[j + 1] - s_coarse[j]), 0.0, 1.0)
    rows = np.repeat(np.arange(len(s_fine)), 2)
    P = sp.csr_matrix((np.column_stack([1 - t, t]).ravel(),
                       (rows, np.column_stack([j, j + 1]).ravel())),
                      shape=(len(s_fine), len(s_coarse)))
    P.eliminate_zeros()
    return P


def _line_mass(s: np.ndarray) -> np.ndarray:
    """Lumped 1D mass (half of each adjacent interval)."""
    if len(s) == 1:
        return np.ones(1)
    h = np.diff(s)
    return 0.5 * (np.concatenate([h, [0.0]]) + np.concatenate([[0.0], h]))


def _line_size(s: np.ndarray) -> np.ndarray:
    """Largest adjacent interval at each node of a sorted 1D grid."""
    if len(s) == 1:
        return np.ones(1)
    h = np.diff(s)
    return np.maximum(np.concatenate([h, [0.0]]), np.concatenate([[0.0], h]))


def facet_sizes(points: np.ndarray, facets: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """Local mesh size at ``nodes``: the largest adjacent facet's length (2D segments)
    or ``sqrt(2 area)`` (3D triangles; the leg of a right isosceles triangle).

    ``facets`` are ``(k, d)`` vertex facets or quadratic ones (the vertices first, then
    the edge midpoints, :func:`problems.fem.quadratic.quadratic_facets`)."""
    pts = np.asarray(points, dtype=float)
    verts = pts[facets[:, :pts.shape[1]]]
    if pts.shape[1] == 2:
        size = np.linalg.norm(verts[:, 1] - verts[:, 0], axis=1)
    else:
        area = 0.5 * np.linalg.norm(np.cross(verts[:, 1] - verts[:, 0], verts[:, 2] - verts[:, 0]),
                                    axis=1)
        size = np.sqrt(2.0 * area)
    out = np.zeros(len(pts))
    np.maximum.at(out, facets.ravel(), np.repeat(size, facets.shape[1]))
    return out[nodes]

def _halve(s: np.ndarray) -> np.ndarray:
    """Every other node of a sorted 1D grid, keeping both ends."""
    keep = np.arange(0, len(s), 2)
    if keep[-1] != len(s) - 1:
        keep = np.append(keep, len(s) - 1)
    return s[keep]


def tensor_coarsening(coords: np.ndarray, min_nodes: int = 2):
    """Coarser levels of a tensor-product surface grid, coarse to fine.

    Parameters
    ----------
    coords : (m, k) array
        Parameter coordinates of the surface nodes (k = 1 for a line, 2 for a
        face), e.g. ``x`` of a straight edge or ``(x, y)`` of a structured
        face. Every combination of the unique values per axis must be a node.
    min_nodes : int
        Stop when every axis has at most this many nodes.

    Returns
    -------
    prolongations, masses, sizes : lists
        ``prolongations[k]`` maps coarse level ``k`` to ``k + 1``; the last
        maps to the given nodes in their order. ``masses[k]`` and ``sizes[k]``
        are the lumped (tensor-product) masses and the local mesh sizes (largest
        adjacent interval along any axis) of the coarse levels only (the finest
        level's are the scene's own).

    Raises
    ------
    ValueError
        If the nodes are not a full tensor grid.
    """
    coords = np.asarray(coords, dtype=float).reshape(len(coords), -1)
    axes = [np.unique(coords[:, j]) for j in range(coords.shape[1])]
    if np.prod([len(a) for a in axes]) != len(coords):
        raise ValueError("tensor_coarsening: the surface nodes are not a full tensor grid "
                         f"({'x'.join(str(len(a)) for a in axes)} != {len(coords)} nodes)")
    # position of each node in the lexicographic tensor numbering (last axis fastest)
    index = np.zeros(len(coords), dtype=np.int64)
    for a, c in zip(axes, coords.T):
        index = index * len(a) + np.searchsorted(a, c)
    chain = [axes]
    while any(len(a) > min_nodes for a in chain[0]):
        chain.insert(0, [_halve(a) if len(a) > min_nodes else a for a in chain[0]])
    prolongations, masses, sizes = [], [], []
    for coarse, fine in zip(chain[:-1], chain[1:]):
        P = sp.csr_matrix(np.ones((1, 1)))
        for c, f in zip(coarse, fine):
            P = sp.kron(P, _line_interpolation(c, f), format="csr")
        prolongations.append(P)
        m, h = np.ones(1), np.zeros(1)
        for c in coarse:
            m = np.kron(m, _line_mass(c))
            h = np.maximum(np.kron(h, np.ones(len(c))), np.kron(np.ones(len(h)), _line_size(c)))
        masses.append(m)
        sizes.append(h)
    if prolongations:  # the last one lands on the given node order
        prolongations[-1] = prolongations[-1][index].tocsr()
    return prolongations, masses, sizes


def surface_levels(node_prolongations: list, surface_nodes: list, surface_masses: list,
                   surface_sizes: list, coarsening=None) -> SurfaceHierarchy:
    """The constrained surface on every mesh level, plus optional coarser levels.

    Parameters
    ----------
    node_prolongations : list of sparse
        Nodal prolongations of the stacked mesh, level ``k`` to ``k + 1``.
    surface_nodes : list of int arrays
        Constrained nodes on each mesh level (global ids of that level), in
        the order of that level's constraint rows.
    surface_masses, surface_sizes : lists of arrays
        Their lumped surface masses and local mesh sizes (:func:`facet_sizes`).
    coarsening : (prolongations, masses, sizes), optional
        Levels below the coarsest mesh, ending on ``surface_nodes[0]``
        (e.g. from :func:`tensor_coarsening`).

    Returns
    -------
    SurfaceHierarchy

    Raises
    ------
    ValueError
        If a fine surface node is interpolated from off-surface coarse nodes
        (the surfaces are not nested).
    """
    prolongations, masses, sizes = [], [], []
    if coarsening is not None:
        prolongations += list(coarsening[0])
        masses += list(coarsening[1])
        sizes += list(coarsening[2])
    for k, P in enumerate(node_prolongations):
        P = sp.csr_matrix(P)[surface_nodes[k + 1]]
        on = P[:, surface_nodes[k]]
        if abs(abs(P).sum() - abs(on).sum()) > 1e-12 * max(abs(P).sum(), 1.0):
            raise ValueError(f"surface levels {k} and {k + 1} are not nested: a fine surface "
                             "node is interpolated from nodes off the coarse surface")
        prolongations.append(on.tocsr())
    masses += [np.asarray(m, dtype=float) for m in surface_masses]
    sizes += [np.asarray(h, dtype=float) for h in surface_sizes]
    return SurfaceHierarchy(prolongations=prolongations, masses=masses, sizes=sizes)
