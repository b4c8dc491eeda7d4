"""Dimension-generic linear elasticity with P1 vector Lagrange elements.

The small-deformation model of thesis Sect. 2.1: Hooke's tensor (2.22) of a
homogeneous isotropic body, Lamé parameters from Young's modulus and Poisson's
ratio (2.23), linearised stress (2.24) and strain (2.25).  The discrete space is
the conforming P1 space of Sect. 5.1 on simplex meshes (triangles in 2D,
tetrahedra in 3D); in 2D the model is plane strain.

Conventions (shared with ``solvers.interface.ContactQP``)
--------------------------------------------------------
* ``points`` is ``(n_nodes, d)`` with ``d`` in {2, 3}; ``cells`` is
  ``(n_cells, d + 1)`` integer node indices; boundary ``facets`` are
  ``(n_facets, d)`` (segments in 2D, triangles in 3D).
* DOFs are node-major interleaved: ``dof = node * d + component``, so a
  displacement vector reshapes to ``(n_nodes, d)``.
* Material data ``E``, ``nu`` are scalars or per-cell arrays; two bodies with
  disjoint node sets assembled together give a block-diagonal matrix.

Everything here is a pure function of numpy arrays: no file I/O, no clocks.
The stiffness matrix is the closed form ``K_e = |T| (lam g_a g_b^T +
mu (g_a . g_b) I + mu g_b g_a^T)`` per node pair ``(a, b)``, with ``g`` the
(constant) gradients of the barycentric coordinates, evaluated for all cells of
a chunk at once and assembled with one COO -> CSR conversion per chunk.
"""
from __future__ import annotations

from math import factorial

import numpy as np
import scipy.sparse as sp

__all__ = [
    "lame_parameters", "barycentric_gradients", "stiffness_matrix", "body_force_vector",
    "traction_vector", "facet_measures", "lumped_surface_mass", "boundary_facets", "strain_stress",
    "von_mises", "rigid_body_modes", "dirichlet_split",
]


# --------------------------------------------------------------------------- input checks
def _check_points(points) -> np.ndarray:
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] not in (2, 3) or pts.shape[0] == 0:
        raise ValueError(f"parameter 'points': shape {pts.shape} is not allowed; "
                         "allowed: (n_nodes, d) with n_nodes >= 1 and d in {2, 3}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("parameter 'points': non-finite coordinates; allowed: finite numbers")
    return pts


def _check_index_array(arr, name: str, n_cols: int, n_nodes: int, what: str) -> np.ndarray:
    a = np.asarray(arr)
    if a.ndim != 2 or a.shape[1] != n_cols:
        raise ValueError(f"parameter '{name}': shape {a.shape} is not allowed; "
                         f"allowed: (n_{what}, {n_cols})")
    if a.size and not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"parameter '{name}': dtype {a.dtype} is not allowed; allowed: integers")
    a = a.astype(np.int64, copy=False)
    if a.size and (a.min() < 0 or a.max() >= n_nodes):
        raise ValueError(f"parameter '{name}': node indices must lie in [0, {n_nodes - 1}], "
                         f"got [{a.min()}, {a.max()}]")
    return a


def _check_mesh(points, cells) -> tuple[np.ndarray, np.ndarray]:
    pts = _check_points(points)
    d = pts.shape[1]
    t = _check_index_array(cells, "cells", d + 1, pts.shape[0], "cells")
    if t.shape[0] == 0:
        raise ValueError("parameter 'cells': empty mesh; allowed: at least one cell")
    return pts, t


def _per_cell(value, name: str, n_cells: int) -> np.ndarray:
    """A scalar or an ``(n_cells,)`` array as a float array broadcastable per cell."""
    v = np.asarray(value, dtype=float)
    if v.ndim == 0:
        return v
    if v.shape != (n_cells,):
        raise ValueError(f"parameter '{name}': shape {v.shape} is not allowed; "
                         f"allowed: a scalar or ({n_cells},) (one value per cell)")
    return v


def _per_item_vector(value, name: str, n_items: int, d: int, what: str) -> np.ndarray:
    """A constant ``(d,)`` vector or ``(n_items, d)`` array, returned as ``(n_items, d)``."""
    v = np.asarray(value, dtype=float)
    if v.shape == (d,):
        v = np.broadcast_to(v, (n_items, d))
    elif v.shape != (n_items, d):
        raise ValueError(f"parameter '{name}': shape {v.shape} is not allowed; "
                         f"allowed: ({d},) or ({n_items}, {d}) (one vector per {what})")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"parameter '{name}': non-finite values; allowed: finite numbers")
    return v


# --------------------------------------------------------------------------- material
def _show_bad(arr: np.ndarray, bad: np.ndarray) -> str:
    if arr.ndim == 0:
        return repr(float(arr))
    first = int(np.flatnonzero(bad.ravel())[0])
    return f"{float(arr.ravel()[first])!r} (entry {first}, {int(bad.sum())} bad of {arr.size})"


def lame_parameters(E, nu, plane_strain: bool = True):
    """Lamé parameters ``(lam, mu)`` from Young's modulus and Poisson's ratio, (2.23).

    Parameters
    ----------
    E : float or array
        Young's modulus, ``E > 0`` (finite).
    nu : float or array
        Poisson's ratio, ``-1 < nu < 0.5``.  The thesis states ``nu in (0, 1/2)``
        below (2.23); the whole thermodynamically admissible range is accepted
        since (2.20) holds for ``-1 < nu < 1/2``.
    plane_strain : bool
        ``True`` (default): the 3D values (2.23), which are also those of the
        plane-strain model used in 2D throughout the suite.  ``False``: the
        plane-stress modification ``lam* = 2 lam mu / (lam + 2 mu) = E nu / (1 - nu^2)``.

    Returns
    -------
    lam, mu : float or array
        With the broadcast shape of ``E`` and ``nu``; ``mu > 0`` and
        ``lam + 2 mu / d > 0`` so that (2.22) is elliptic (2.20).

    Raises
    ------
    ValueError
        Naming ``E`` or ``nu`` if outside the allowed range.
    """
    E_arr = np.asarray(E, dtype=float)
    nu_arr = np.asarray(nu, dtype=float)
    bad_E = ~(np.isfinite(E_arr) & (E_arr > 0))
    if np.any(bad_E):
        raise ValueError(f"parameter 'E': {_show_bad(E_arr, bad_E)} is not allowed; "
                         "allowed: a number in (0, inf)")
    bad_nu = ~(np.isfinite(nu_arr) & (nu_arr > -1.0) & (nu_arr < 0.5))
    if np.any(bad_nu):
        raise ValueError(f"parameter 'nu': {_show_bad(nu_arr, bad_nu)} is not allowed; "
                         "allowed: a number in (-1, 0.5)")
    lam = E_arr * nu_arr / ((1.0 + nu_arr) * (1.0 - 2.0 * nu_arr))
    mu = E_arr / (2.0 * (1.0 + nu_arr))
    if not plane_strain:
        lam = 2.0 * lam * mu / (lam + 2.0 * mu)
    if lam.ndim == 0:
        return float(lam), float(mu)
    return lam, mu


# --------------------------------------------------------------------------- geometry
def barycentric_gradients(points, cells) -> tuple[np.ndarray, np.ndarray]:
    """Constant gradients of the P1 basis (barycentric coordinates) and cell measures.

    With ``J = [x_1 - x_0, ..., x_d - x_0]`` the gradients of ``lambda_1..lambda_d``
    are the rows of ``J^{-1} = adj(J) / det(J)`` (cofactors in closed form, all
    cells at once) and ``grad lambda_0 = -sum_k grad lambda_k`` (Sect. 5.1).

    Parameters
    ----------
    points : (n_nodes, d) array
    cells : (n_cells, d + 1) int array

    Returns
    -------
    grads : (n_cells, d + 1, d) array
        ``grads[c, a]`` is the gradient of the basis function of local vertex ``a``.
    volumes : (n_cells,) array
        Cell measures ``|det J| / d!`` (area in 2D, volume in 3D).

    Raises
    ------
    ValueError
        For malformed input or a degenerate cell (``det J == 0``).
    """
    pts, t = _check_mesh(points, cells)
    d = pts.shape[1]
    x0 = pts[t[:, 0]]
    J = np.stack([pts[t[:, k]] - x0 for k in range(1, d + 1)], axis=2)  # columns x_k - x_0
    if d == 2:
        a, b, c, e = J[:, 0, 0], J[:, 0, 1], J[:, 1, 0], J[:, 1, 1]
        det = a * e - b * c
        adj = np.stack([np.stack([e, -b], axis=1), np.stack([-c, a], axis=1)], axis=1)
    else:
        c0, c1, c2 = J[:, :, 0], J[:, :, 1], J[:, :, 2]
        # rows of adj(J) are the cross products of pairs of columns of J
        adj = np.stack([np.cross(c1, c2), np.cross(c2, c0), np.cross(c0, c1)], axis=1)
        det = np.einsum("ij,ij->i", c0, adj[:, 0, :])
    bad = np.flatnonzero(det == 0.0)
    if bad.size:
        raise ValueError(f"parameter 'cells': {bad.size} degenerate cell(s) with zero measure "
                         f"(first: {bad[:5].tolist()}); allowed: non-degenerate simplices")
    grads = np.empty((t.shape[0], d + 1, d))
    grads[:, 1:, :] = adj / det[:, None, None]
    grads[:, 0, :] = -grads[:, 1:, :].sum(axis=1)
    return grads, np.abs(det) / factorial(d)


# --------------------------------------------------------------------------- stiffness
def stiffness_matrix(points, cells, E, nu, chunk: int = 400_000) -> sp.csr_matrix:
    """Stiffness matrix of ``a(u, v) = int sigma(u) : epsilon(v)``, (2.22)-(2.25), P1.

    For local vertices ``a, b`` with basis gradients ``g_a, g_b`` and components
    ``i, j`` the element matrix is the closed form

        K[(a, i), (b, j)] = |T| (lam g_ai g_bj + mu (g_a . g_b) delta_ij + mu g_aj g_bi),

    i.e. ``lam div u div v + 2 mu epsilon(u) : epsilon(v)``; in 2D this is plane
    strain.  Only the upper triangle of each element matrix is evaluated (its
    diagonal halved), for all cells of a chunk at once, and assembled into ``S``
    by one COO -> CSR conversion per chunk; then ``K = S + S^T``, which is *exactly* symmetric
    in floating point (``S_rc + S_cr`` is commutative; the duplicate summation
    order of the conversion itself is unspecified) and scatters half as many
    entries as the full element matrices would.

    Parameters
    ----------
    points : (n_nodes, d) array, d in {2, 3}
    cells : (n_cells, d + 1) int array
    E, nu : float or (n_cells,) array
        Young's modulus and Poisson's ratio per cell (validated by
        :func:`lame_parameters`).
    chunk : int
        Cells per assembly pass; the partial sums are added as CSR, which bounds
        the memory (about 0.8 kB per cell of a chunk in 3D, against ~2.7 kB per
        cell of the whole mesh in one pass).

    Returns
    -------
    (n_nodes * d, n_nodes * d) scipy.sparse.csr_matrix
        DOF ``node * d + component``; symmetric positive semi-definite, with the
        rigid body modes (:func:`rigid_body_modes`) of every connected body in
        its kernel.  Nodes not used by any cell give empty rows.
    """
    pts, t = _check_mesh(points, cells)
    n_cells, d = t.shape[0], pts.shape[1]
    lam, mu = lame_parameters(_per_cell(E, "E", n_cells), _per_cell(nu, "nu", n_cells))
    lam = np.broadcast_to(lam, (n_cells,))
    mu = np.broadcast_to(mu, (n_cells,))
    n_dofs = pts.shape[0] * d
    S = None
    for start in range(0, n_cells, chunk):        # bounded memory: ~0.8 kB per cell of a chunk
        part = slice(start, min(start + chunk, n_cells))
        S_part = _upper_element_sum(pts, t[part], lam[part], mu[part], n_dofs)
        S = S_part if S is None else S + S_part
        del S_part
    K = S + S.T.tocsr()      # K_rc = S_rc + S_cr: exactly symmetric in floating point
    K.sort_indices()
    return K


def _upper_element_sum(pts: np.ndarray, t: np.ndarray, lam: np.ndarray, mu: np.ndarray,
                       n_dofs: int) -> sp.csr_matrix:
    """``S`` of :func:`stiffness_matrix` for the cells ``t`` (upper triangles of the
    element matrices, diagonals halved), assembled by one COO -> CSR conversion."""
    n_cells, d = t.shape[0], pts.shape[1]
    g, vol = barycentric_gradients(pts, t)
    m = (d + 1) * d                                   # local DOFs (a, i) -> a * d + i
    p, q = np.triu_indices(m)                         # upper triangle of the element matrix
    a, i, b, j = p // d, p % d, q // d, q % d
    # entry-major layout (one row per local entry, one column per cell); the loop over
    # the m (m + 1) / 2 entries writes into one preallocated array (no big temporaries)
    gf = np.ascontiguousarray(g.reshape(n_cells, m).T)            # gf[a * d + i] = g_ai
    lam_v = lam * vol
    mu_v = mu * vol
    del g, vol
    ke = np.empty((p.size, n_cells))
    tmp = np.empty(n_cells)
    for k in range(p.size):
        row = ke[k]
        np.multiply(gf[p[k]], gf[q[k]], out=row)                  # lam g_ai g_bj
        row *= lam_v
        np.multiply(gf[a[k] * d + j[k]], gf[b[k] * d + i[k]], out=tmp)   # mu g_aj g_bi
        if i[k] == j[k]:                                          # mu (g_a . g_b) delta_ij
            for comp in range(d):
                tmp += gf[a[k] * d + comp] * gf[b[k] * d + comp]
        tmp *= mu_v
        row += tmp
        if p[k] == q[k]:
            row *= 0.5                                # K = S + S^T counts the diagonal twice
    del gf
    itype = np.int32 if n_dofs < np.iinfo(np.int32).max else np.int64
    dofs = (t.T.astype(itype)[:, None, :] * d
            + np.arange(d, dtype=itype)[None, :, None]).reshape(m, n_cells)
    return sp.coo_matrix((ke.ravel(), (dofs[p].ravel(), dofs[q].ravel())),
                         shape=(n_dofs, n_dofs)).tocsr()


# --------------------------------------------------------------------------- loads
def body_force_vector(points, cells, force) -> np.ndarray:
    """Consistent load ``int f . v`` of a cell-wise constant body force density.

    For P1 each of the ``d + 1`` vertices of cell ``T`` receives ``|T| f_T / (d + 1)``.

    Parameters
    ----------
    points : (n_nodes, d) array
    cells : (n_cells, d + 1) int array
    force : (d,) or (n_cells, d) array
        Force per unit volume (area in 2D), e.g. gravity ``(0, -rho g)``.

    Returns
    -------
    (n_nodes * d,) array
        Node-major interleaved.
    """
    pts, t = _check_mesh(points, cells)
    d = pts.shape[1]
    f = _per_item_vector(force, "force", t.shape[0], d, "cell")
    _, vol = barycentric_gradients(pts, t)
    return _scatter_vertex_loads(t, (vol / (d + 1))[:, None] * f, pts.shape[0])


def _scatter_vertex_loads(elems: np.ndarray, share: np.ndarray, n_nodes: int) -> np.ndarray:
    """Add ``share[e]`` (a ``(d,)`` vector) to every vertex of element ``e``."""
    d = share.shape[1]
    nodes = elems.ravel()
    out = np.empty((n_nodes, d))
    for comp in range(d):
        w = np.repeat(share[:, comp], elems.shape[1])
        out[:, comp] = np.bincount(nodes, weights=w, minlength=n_nodes)
    return out.ravel()


def facet_measures(pts: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Length (2D segments) or area (3D triangles) of each boundary facet."""
    if pts.shape[1] == 2:
        return np.linalg.norm(pts[f[:, 1]] - pts[f[:, 0]], axis=1)
    return 0.5 * np.linalg.norm(np.cross(pts[f[:, 1]] - pts[f[:, 0]],
                                         pts[f[:, 2]] - pts[f[:, 0]]), axis=1)


def traction_vector(points, facets, traction) -> np.ndarray:
    """Consistent load ``int_{Gamma_N} l . v`` of a facet-wise constant traction (2.26).

    Each of the ``d`` vertices of facet ``F`` receives ``|F| l_F / d``.

    Parameters
    ----------
    points : (n_nodes, d) array
    facets : (n_facets, d) int array
        Segments in 2D, triangles in 3D (e.g. from :func:`boundary_facets`).
    traction : (d,) or (n_facets, d) array
        Surface load ``l`` per unit length (2D) or area (3D).

    Returns
    -------
    (n_nodes * d,) array
        Node-major interleaved.
    """
    pts = _check_points(points)
    d = pts.shape[1]
    f = _check_index_array(facets, "facets", d, pts.shape[0], "facets")
    tr = _per_item_vector(traction, "traction", f.shape[0], d, "facet")
    return _scatter_vertex_loads(f, (facet_measures(pts, f) / d)[:, None] * tr, pts.shape[0])


def lumped_surface_mass(points, facets, n_nodes: int | None = None) -> np.ndarray:
    """Row-sum lumped boundary mass ``int_Gamma phi_i ds`` (Sect. 6.5, Sect. 8.6).

    The diagonal matrix ``M-bar`` that replaces the surface mass matrix: each
    facet's measure is split equally among its ``d`` vertices.  The contact
    pressure at a constrained node is the multiplier divided by this mass.

    Parameters
    ----------
    points : (n_nodes, d) array
    facets : (n_facets, d) int array
    n_nodes : int, optional
        Length of the result (default ``len(points)``); must be at least
        ``max(facets) + 1``.

    Returns
    -------
    (n_nodes,) array
        Zero at nodes that lie on no facet; sums to the measure of the surface.
    """
    pts = _check_points(points)
    d = pts.shape[1]
    if n_nodes is None:
        n_nodes = pts.shape[0]
    if isinstance(n_nodes, bool) or not isinstance(n_nodes, (int, np.integer)) or n_nodes < 1:
        raise ValueError(f"parameter 'n_nodes': {n_nodes!r} is not allowed; allowed: a positive integer")
    f = _check_index_array(facets, "facets", d, min(int(n_nodes), pts.shape[0]), "facets")
    w = np.repeat(facet_measures(pts, f) / d, d)
    return np.bincount(f.ravel(), weights=w, minlength=int(n_nodes)).astype(float)


def boundary_facets(cells, points=None) -> np.ndarray:
    """Boundary facets of a conforming simplex mesh (Def. 5.1): those of exactly one cell.

    Parameters
    ----------
    cells : (n_cells, d + 1) int array, d in {2, 3}
    points : (n_nodes, d) array, optional
        If given, every facet is oriented with its normal pointing out of its
        cell: in 2D ``(t_y, -t_x)`` for the tangent ``t = x_1 - x_0``, in 3D
        ``(x_1 - x_0) x (x_2 - x_0)``.  Without ``points`` the orientation is
        that of the facet inside its cell's vertex list (not necessarily outward).

    Returns
    -------
    (n_facets, d) int array
        In the order (cell, local facet), usable with :func:`traction_vector`
        and :func:`lumped_surface_mass`.
    """
    t = np.asarray(cells)
    if t.ndim != 2 or t.shape[1] not in (3, 4) or t.shape[0] == 0:
        raise ValueError(f"parameter 'cells': shape {t.shape} is not allowed; "
                         "allowed: (n_cells, 3) triangles or (n_cells, 4) tetrahedra")
    if not np.issubdtype(t.dtype, np.integer):
        raise ValueError(f"parameter 'cells': dtype {t.dtype} is not allowed; allowed: integers")
    t = t.astype(np.int64, copy=False)
    if t.min() < 0:
        raise ValueError("parameter 'cells': negative node index; allowed: indices >= 0")
    n_loc = t.shape[1]
    # facet k is opposite local vertex k; its vertices in cyclic order
    local = [[(k + j) % n_loc for j in range(1, n_loc)] for k in range(n_loc)]
    facets = t[:, local].reshape(-1, n_loc - 1)            # order (cell, k)
    key = np.sort(facets, axis=1)
    order = np.lexsort(key.T[::-1])
    sk = key[order]
    new = np.ones(len(sk), dtype=bool)
    new[1:] = np.any(sk[1:] != sk[:-1], axis=1)
    starts = np.flatnonzero(new)
    counts = np.diff(np.append(starts, len(sk)))
    if counts.max() > 2:
        raise ValueError("parameter 'cells': a facet is shared by more than two cells; "
                         "allowed: a conforming simplex mesh")
    single = np.sort(order[starts[counts == 1]])
    out = facets[single]
    if points is not None:
        pts = _check_points(points)
        d = n_loc - 1
        if pts.shape[1] != d:
            raise ValueError(f"parameter 'points': dimension {pts.shape[1]} does not match "
                             f"{d}D cells; allowed: (n_nodes, {d})")
        if t.max() >= pts.shape[0]:
            raise ValueError(f"parameter 'cells': node index {t.max()} out of range for "
                             f"{pts.shape[0]} points")
        opposite = t[single // n_loc, single % n_loc]
        e1 = pts[out[:, 1]] - pts[out[:, 0]]
        if d == 2:
            normal = np.stack([e1[:, 1], -e1[:, 0]], axis=1)
        else:
            normal = np.cross(e1, pts[out[:, 2]] - pts[out[:, 0]])
        inward = np.einsum("ij,ij->i", normal, pts[opposite] - pts[out[:, 0]]) > 0
        out[inward] = out[inward][:, ::-1]
    return out


# --------------------------------------------------------------------------- post-processing
def _displacement(u, n_nodes: int, d: int) -> np.ndarray:
    arr = np.asarray(u, dtype=float)
    if arr.shape == (n_nodes * d,):
        return arr.reshape(n_nodes, d)
    if arr.shape == (n_nodes, d):
        return arr
    raise ValueError(f"parameter 'u': shape {arr.shape} is not allowed; "
                     f"allowed: ({n_nodes * d},) or ({n_nodes}, {d})")


def strain_stress(points, cells, u, E, nu,
                  gradients: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Cell-wise constant linearised strain (2.25) and stress (2.24) of a P1 field.

    Parameters
    ----------
    points : (n_nodes, d) array
    cells : (n_cells, d + 1) int array
    u : (n_nodes * d,) or (n_nodes, d) array
        Full nodal displacement (node-major).
    E, nu : float or (n_cells,) array
    gradients : (n_cells, d + 1, d) array, optional
        The mesh's :func:`barycentric_gradients`, where one mesh is measured many times.

    Returns
    -------
    strain, stress : (n_cells, d, d) arrays
        ``stress = lam tr(eps) I + 2 mu eps``.  In 2D (plane strain) the
        out-of-plane stress ``sigma_zz = lam tr(eps)`` is not included; see
        :func:`von_mises`.
    """
    pts, t = _check_mesh(points, cells)
    n_cells, d = t.shape[0], pts.shape[1]
    lam, mu = lame_parameters(_per_cell(E, "E", n_cells), _per_cell(nu, "nu", n_cells))
    U = _displacement(u, pts.shape[0], d)
    g = barycentric_gradients(pts, t)[0] if gradients is None else gradients
    grad_u = np.einsum("cai,cak->cik", U[t], g)               # d u_i / d x_k
    eps = 0.5 * (grad_u + grad_u.transpose(0, 2, 1))
    tr = np.trace(eps, axis1=1, axis2=2)
    sigma = 2.0 * np.asarray(mu)[..., None, None] * eps
    sigma += (np.asarray(lam) * tr)[:, None, None] * np.eye(d)
    return eps, sigma


def von_mises(points, cells, u, E, nu) -> np.ndarray:
    """Cell-wise von Mises stress ``sqrt(3/2 s : s)``, ``s`` the stress deviator.

    In 2D the plane-strain out-of-plane stress ``sigma_zz = lam (eps_xx + eps_yy)``
    enters the deviator.

    Parameters
    ----------
    points, cells, u, E, nu
        As for :func:`strain_stress`.

    Returns
    -------
    (n_cells,) array
    """
    eps, sigma = strain_stress(points, cells, u, E, nu)
    n_cells, d = sigma.shape[0], sigma.shape[1]
    s3 = np.zeros((n_cells, 3, 3))
    s3[:, :d, :d] = sigma
    if d == 2:
        lam, _ = lame_parameters(_per_cell(E, "E", n_cells), _per_cell(nu, "nu", n_cells))
        s3[:, 2, 2] = lam * np.trace(eps, axis1=1, axis2=2)
    dev = s3 - (np.trace(s3, axis1=1, axis2=2) / 3.0)[:, None, None] * np.eye(3)
    return np.sqrt(1.5 * np.einsum("cij,cij->c", dev, dev))


# --------------------------------------------------------------------------- kernels, BCs
def rigid_body_modes(points) -> np.ndarray:
    """Rigid body motions: the kernel of the unconstrained stiffness of one body.

    Translations and infinitesimal rotations ``omega x (x - x_c)`` about the
    centroid ``x_c`` (centring improves their conditioning as an AMG near-null
    space, e.g. pyamg's ``B``).

    Parameters
    ----------
    points : (n_nodes, d) array

    Returns
    -------
    (n_nodes * d, 3) array in 2D or (n_nodes * d, 6) in 3D
        Columns: the ``d`` translations, then the rotations (2D: about z;
        3D: about x, y, z).  Node-major interleaved.
    """
    pts = _check_points(points)
    n, d = pts.shape
    x = pts - pts.mean(axis=0)
    if d == 2:
        modes = np.zeros((n, 2, 3))
        modes[:, 0, 0] = 1.0
        modes[:, 1, 1] = 1.0
        modes[:, 0, 2] = -x[:, 1]
        modes[:, 1, 2] = x[:, 0]
    else:
        modes = np.zeros((n, 3, 6))
        modes[:, [0, 1, 2], [0, 1, 2]] = 1.0
        for k in range(3):
            modes[:, :, 3 + k] = np.cross(np.eye(3)[k], x)
    return modes.reshape(n * d, -1)


def dirichlet_split(n_dofs, fixed_dofs, fixed_values=0.0) -> tuple[np.ndarray, np.ndarray]:
    """Free DOFs and the lifted prescribed values (``ContactQP.free_dofs``/``u_fixed``).

    The reduced problem on the free DOFs is ``A[free][:, free] u = f[free] - (A u_fixed)[free]``
    and ``u_full = u_fixed; u_full[free] = u`` (Dirichlet part of (2.26)).

    Parameters
    ----------
    n_dofs : int
        Total number of DOFs, ``> 0``.
    fixed_dofs : int array
        Prescribed DOF indices in ``[0, n_dofs)``; repeats are allowed if their
        values agree.
    fixed_values : float or array like ``fixed_dofs``
        Prescribed values (default 0).

    Returns
    -------
    free_dofs : (n_free,) int64 array
        Sorted complement of ``fixed_dofs``.
    u_fixed : (n_dofs,) array
        Prescribed values at ``fixed_dofs``, zero elsewhere.
    """
    if isinstance(n_dofs, bool) or not isinstance(n_dofs, (int, np.integer)) or n_dofs < 1:
        raise ValueError(f"parameter 'n_dofs': {n_dofs!r} is not allowed; allowed: a positive integer")
    fixed = np.asarray(fixed_dofs).ravel()
    if fixed.size and not np.issubdtype(fixed.dtype, np.integer):
        raise ValueError(f"parameter 'fixed_dofs': dtype {fixed.dtype} is not allowed; allowed: integers")
    fixed = fixed.astype(np.int64)
    if fixed.size and (fixed.min() < 0 or fixed.max() >= n_dofs):
        raise ValueError(f"parameter 'fixed_dofs': indices must lie in [0, {n_dofs - 1}], "
                         f"got [{fixed.min()}, {fixed.max()}]")
    vals = np.asarray(fixed_values, dtype=float)
    if vals.ndim == 0:
        vals = np.full(fixed.shape, float(vals))
    else:
        vals = vals.ravel()
        if vals.shape != fixed.shape:
            raise ValueError(f"parameter 'fixed_values': shape {np.shape(fixed_values)} is not allowed; "
                             f"allowed: a scalar or one value per fixed DOF ({fixed.size},)")
    if not np.all(np.isfinite(vals)):
        raise ValueError("parameter 'fixed_values': non-finite values; allowed: finite numbers")
    u_fixed = np.zeros(int(n_dofs))
    u_fixed[fixed] = vals
    if not np.array_equal(u_fixed[fixed], vals):
        raise ValueError("parameter 'fixed_values': a DOF repeated in fixed_dofs has conflicting "
                         "values; allowed: equal values for repeated DOFs")
    mask = np.ones(int(n_dofs), dtype=bool)
    mask[fixed] = False
    return np.flatnonzero(mask), u_fixed
