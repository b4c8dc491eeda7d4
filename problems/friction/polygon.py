"""The faceted friction law's polygon: the regular ``k``-gon ``P_k`` inscribed in the unit
circle, one vertex along the first tangent, with which the faceted law (3D,
:class:`problems.friction.data.Friction`, ``facets = k``) replaces the disc
``|lam_i| <= s_i`` by ``lam_i in s_i P_k``: its vertices and facet normals, its support
function (the faceted dissipation), its gauge (the admissibility of ``lam_i``) and the
Euclidean projection onto ``s_i P_k`` with the region it lands in (facet interior or
vertex) and that region's affine projection, on which the exact reference's semismooth
Newton method is exact (:mod:`solvers.kernels.tresca`).
"""
from __future__ import annotations

import numpy as np


def polygon_vertices(k: int) -> np.ndarray:
    """The ``k`` vertices ``v_j = (cos 2 pi j / k, sin 2 pi j / k)`` of the regular
    ``k``-gon ``P_k`` inscribed in the unit circle, one vertex along the first tangent
    (``(k, 2)``, counter-clockwise)."""
    angle = 2.0 * np.pi * np.arange(k) / k
    return np.column_stack([np.cos(angle), np.sin(angle)])


def polygon_normals(k: int) -> np.ndarray:
    """The unit outward normals ``n_j`` of the facets ``[v_j, v_j+1]`` of ``P_k``
    (``(k, 2)``): ``P_k = {l : n_j . l <= cos(pi / k)}``, ``cos(pi / k)`` its apothem."""
    angle = np.pi * (2 * np.arange(k) + 1) / k
    return np.column_stack([np.cos(angle), np.sin(angle)])


def polygon_support(x: np.ndarray, k: int) -> np.ndarray:
    """``h_Pk(x_i) = max_{l in P_k} l . x_i = max_j v_j . x_i`` of each row of ``x``
    (``(N, 2)``): the faceted dissipation per unit slip bound."""
    return np.max(np.asarray(x, dtype=float) @ polygon_vertices(k).T, axis=1)


def polygon_gauge(x: np.ndarray, k: int) -> np.ndarray:
    """The gauge ``min {t >= 0 : x_i in t P_k} = max_j n_j . x_i / cos(pi / k)`` of each
    row of ``x`` (``(N, 2)``): ``x_i in s_i P_k`` exactly when it is ``<= s_i``."""
    return (np.max(np.asarray(x, dtype=float) @ polygon_normals(k).T, axis=1)
            / np.cos(np.pi / k))


#: Regions of a point ``z`` against ``s P_k`` (:func:`polygon_regions`): ``REGION_INSIDE``
#: (``z`` is its own projection), then per facet ``j`` the code ``REGION_FACET + 2 j``
#: (projected into the facet's interior) and ``REGION_FACET + 2 j + 1`` (projected onto
#: its first vertex ``s v_j``).
REGION_INSIDE, REGION_FACET = 1, 2


def polygon_regions(z: np.ndarray, s: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The Euclidean projection of each row of ``z`` (``(N, 2)``) onto ``s_i P_k`` and
    its region (:data:`REGION_INSIDE`, :data:`REGION_FACET`): outside, the nearest of
    the ``k`` facets' nearest points (each the segment's parameter clipped to
    ``[0, 1]``), exact to round-off; ``s_i = 0`` projects onto ``0``."""
    z, s = np.asarray(z, dtype=float), np.asarray(s, dtype=float)
    v = polygon_vertices(k)
    start = s[:, None, None] * v[None]                         # (N, k, 2): s v_j
    edge = s[:, None, None] * (np.roll(v, -1, axis=0) - v)[None]
    length2 = np.maximum(np.einsum("nkd,nkd->nk", edge, edge), 1e-300)
    t = np.einsum("nkd,nkd->nk", z[:, None, :] - start, edge) / length2
    at = np.clip(t, 0.0, 1.0)
    near = start + at[..., None] * edge
    dist = np.einsum("nkd,nkd->nk", z[:, None, :] - near, z[:, None, :] - near)
    j = np.argmin(dist, axis=1)
    rows = np.arange(len(z))
    inside = polygon_gauge(z, k) <= s
    projection = np.where(inside[:, None], z, near[rows, j])
    t_j = at[rows, j]
    facet = np.where(t_j >= 1.0, (j + 1) % k, j)       # the far vertex: the next facet's
    code = REGION_FACET + 2 * facet + ((t_j <= 0.0) | (t_j >= 1.0))
    return projection, np.where(inside, REGION_INSIDE, code)


def project_polygon(z: np.ndarray, s: np.ndarray, k: int) -> np.ndarray:
    """Each row of ``z`` (``(N, 2)``) projected onto ``s_i P_k`` (:func:`polygon_regions`)."""
    return polygon_regions(z, s, k)[0]


def region_projection(z: np.ndarray, s: np.ndarray, k: int,
                      code: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The affine projection of each row of ``z`` that its region ``code`` stands for, and
    its Jacobian (``(N, 2, 2)``): inside ``z`` and ``I``; in facet ``j``'s interior the
    projection onto the facet's line, ``I - n_j n_j'``; at vertex ``j`` ``s v_j`` and
    ``0``. On the right region it is :func:`project_polygon`."""
    z, s, code = np.asarray(z, dtype=float), np.asarray(s, dtype=float), np.asarray(code)
    facet = np.maximum(code - REGION_FACET, 0) // 2
    vertex = (code >= REGION_FACET) & ((code - REGION_FACET) % 2 == 1)
    on_facet = (code >= REGION_FACET) & ~vertex
    n = polygon_normals(k)[facet]
    apothem = np.cos(np.pi / k)
    out = z - (np.einsum("nd,nd->n", n, z) - s * apothem)[:, None] * n
    eye = np.broadcast_to(np.eye(2), (len(z), 2, 2))
    jac = eye - n[:, :, None] * n[:, None, :]
    out = np.where(on_facet[:, None], out, np.where(vertex[:, None],
                                                     s[:, None] * polygon_vertices(k)[facet], z))
    jac = np.where(on_facet[:, None, None], jac, np.where(vertex[:, None, None], 0.0, eye))
    return out, jac
