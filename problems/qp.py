"""The neutral core: the algebraic contact problem and its typed data.

Both sides of the data flow import this module and nothing above it: a scene
(``problems/<name>.py``) builds a :class:`ContactQP`; every solver
(``solvers/<name>.py``) receives one; :mod:`problems.kkt` judges any ``(u, p)`` the
same way whoever produced it. Beside it, one job each: :mod:`problems.kkt` (KKT
residuals, energy error), :mod:`problems.slack` (the slack form of the stabilised
problem), :mod:`problems.floating` (floating bodies' rigid modes).

Conventions (thesis Ch. 7-8, DESIGN.md)::

    minimise 1/2 u^T A u - f^T u   subject to   B u - C p <= g,   p >= 0
    KKT:  A u + B^T p = f,  B u - C p <= g,  p >= 0,  p^T (g - B u + C p) = 0

``C`` is the stabilisation block of Sect. 7.5 (``None``: zero). Everything a
multilevel solver or the output needs from the discretisation travels inside
the ContactQP as typed, optional data (:class:`Mesh`, :class:`ContactSurface`,
:class:`Multilevel`, :class:`HertzSetup`); a solver never knows which scene it
solves.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.sparse as sp


class QPValidationError(ValueError):
    """A ContactQP failed its consistency checks (the message says which)."""


@dataclass
class Mesh:
    """The discretisation behind a ContactQP (for output and estimators).

    Attributes
    ----------
    points : (N, d) array
        Node coordinates of both bodies (one global numbering).
    cells : (n_cells, d + 1) or P2 (n_cells, 6 or 10) int array
        Simplices (triangles in 2D, tetrahedra in 3D); P2 cells list the vertices,
        then the edge midpoints (:mod:`problems.fem.quadratic`).
    body_of_node : (N,) int array
        Index into ``bodies`` of each node.
    E_cell, nu_cell : (n_cells,) arrays
        Young's modulus and Poisson's ratio per cell.
    bodies : tuple of str
        Body names, e.g. ``("square", "circle")``.
    """

    points: np.ndarray
    cells: np.ndarray
    body_of_node: np.ndarray
    E_cell: np.ndarray
    nu_cell: np.ndarray
    bodies: tuple = ()

    @property
    def n_nodes(self) -> int:
        return len(self.points)

    @property
    def dim(self) -> int:
        return self.points.shape[1]

    @property
    def degree(self) -> int:
        """Lagrange order of the cells: 1 (``d + 1`` nodes each) or 2 (vertices first,
        then edge midpoints; :mod:`problems.fem.quadratic`)."""
        return 1 if self.cells.shape[1] == self.dim + 1 else 2


@dataclass
class ContactSurface:
    """The constrained surface (thesis: surface ``l``) and its constraints' geometry.

    Attributes
    ----------
    nodes : (m,) int array
        Global node behind each row of ``B`` (the constrained nodes).
    mass : (m,) array
        Lumped surface mass at those nodes: the pressure is ``p / mass`` (Sect. 8.6).
    direction : (m, d) array
        Unit direction ``n`` of each constraint (case b) or the closest-point
        direction (case a), pointing from the constrained towards the opposing body.
    facets : (k, d) int array
        Facets of the constrained surface (segments in 2D, triangles in 3D).
    opposing_facets : (k', d) int array
        Facets of the opposing surface (thesis: surface ``l-1``) the search used.
    search : str
        ``"closest_point"`` (Alg. 7.1 case a, (7.12)) or ``"along_direction"`` (case b, (7.13)).
    dropped : int
        Nodes of the constrained surface that found no opposing facet (e.g. beyond
        the opposing body's reach in grazing contact) and carry no constraint.
    pressure_map : (m, m) sparse, optional
        The nodal pressure of the multipliers, ``pressure = pressure_map @ p``, where
        ``p / mass`` is not it (P2: :func:`problems.fem.two_body.quadratic_pressure_map`);
        ``None``: ``p / mass`` (Sect. 8.6).
    """

    nodes: np.ndarray
    mass: np.ndarray
    direction: np.ndarray
    facets: np.ndarray
    opposing_facets: np.ndarray
    search: str = "along_direction"
    dropped: int = 0
    pressure_map: sp.spmatrix | None = None

    def pressure(self, p: np.ndarray) -> np.ndarray:
        """Nodal contact pressure of the multipliers ``p`` on these rows (Sect. 8.6)."""
        p = np.asarray(p, dtype=float)
        return p / self.mass if self.pressure_map is None else self.pressure_map @ p


@dataclass
class SurfaceHierarchy:
    """Nested meshes of the constrained surface, coarse to fine (for a multilevel S-hat).

    Attributes
    ----------
    prolongations : list of sparse
        ``prolongations[k]`` maps nodal values on surface level ``k`` to level
        ``k+1`` (P1/Q1 interpolation); the last ends on the ContactQP's rows,
        in their order.
    masses : list of arrays
        Lumped surface masses per level; ``masses[-1]`` is the contact mass.
    sizes : list of arrays
        Local mesh size at each node per level: the largest adjacent facet
        (its length in 2D, ``sqrt(2 area)`` in 3D).
    """

    prolongations: list
    masses: list
    sizes: list

    @property
    def n_levels(self) -> int:
        return len(self.masses)


@dataclass(frozen=True)
class Extrusion:
    """The layers of an extruded mesh: each body is one section copied at a sequence of
    positions along an axis (the roll stack's rolls), so each unknown lies on one layer
    and is the copy of one unknown of its body's section.

    What a semicoarsening multigrid needs when the levels are separate meshes
    (:func:`solvers.multigrid.layered_hierarchy`).

    Attributes
    ----------
    layer_of_dof : (n,) int array
        Layer of each unknown, numbered over all bodies.
    section_dof : (n,) int array
        The section unknown (body, section node, component) each unknown copies,
        numbered over all bodies.
    layer_coordinate : (n_layers,) array
        Position of each layer along the axis.
    body_layers : tuple of int arrays
        Each body's layers, in order along the axis.
    """

    layer_of_dof: np.ndarray
    section_dof: np.ndarray
    layer_coordinate: np.ndarray
    body_layers: tuple


@dataclass
class Multilevel:
    """What a multilevel solver needs from the refinement hierarchy.

    Attributes
    ----------
    prolongations : list of sparse
        ``prolongations[k]`` maps level ``k`` to ``k+1`` on the free DOFs; the
        last ends on the ContactQP's unknowns.
    rigid_body_modes : (n, r) array
        Rigid-body motions of each body restricted to the free DOFs (near-null
        space for algebraic multigrid).
    body_of_dof : (n,) int array
        Body of each unknown.
    surface : SurfaceHierarchy or None
        Nested constrained-surface meshes, supplied by the scene.
    extrusion : Extrusion or None
        The layers of an extruded mesh, supplied by the scene (semicoarsening
        multigrid where there is no refinement hierarchy).
    """

    prolongations: list = field(default_factory=list)
    rigid_body_modes: np.ndarray | None = None
    body_of_dof: np.ndarray | None = None
    surface: SurfaceHierarchy | None = None
    extrusion: Extrusion | None = None


@dataclass(frozen=True)
class HertzSetup:
    """The analytic Hertz reference of a scene (K. L. Johnson, Contact Mechanics, Ch. 4).

    Attributes
    ----------
    kind : {"line", "point"}
        Plane-strain cylinder contact (2D) or sphere contact (3D).
    radius : float
        Effective radius ``R`` of the contacting curvature.
    E_star : float
        Effective modulus ``1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2``.
    """

    kind: str
    radius: float
    E_star: float


@dataclass
class Stabilisation:
    """The reverse rows of two-sided nodal constraints: stabilised (Sect. 7.5) or two-pass.

    A stabilised ContactQP (:func:`problems.fem.stabilised.stabilise`) has the
    nodal constraints of the constrained surface first (``qp.contact`` describes
    them, ``C`` is zero there) and then one row per node of the opposing surface
    that finds the constrained surface along ``-n`` (the penetrations (7.9) of
    Fig. 7.1), penalised by ``C_ii = h_i^(2 alpha) / (k m_i)`` ((7.10)/(7.11)).
    A two-pass ContactQP (:func:`problems.fem.stabilised.two_pass`) has the same
    rows hard: ``C`` is ``None``, ``alpha`` and ``modulus`` are ``None``.

    Attributes
    ----------
    nodes : (r,) int array
        Opposing-surface node behind each reverse row.
    mass : (r,) array
        Its lumped mass on the opposing surface.
    size : (r,) array
        Local mesh size ``h_i`` of the opposing surface there.
    transfer : (r, m_c) sparse
        Barycentric weights of the constrained facet each reverse row hits, on the
        constrained rows: the reverse multipliers act on the constrained surface as
        ``transfer' p_r`` (:func:`surface_multipliers`).
    alpha : float or None
        Exponent of ``h`` in (7.10); ``None`` for hard (two-pass) rows.
    modulus : float or None
        ``k`` (force per area times length^(2 alpha - 1)); ``None`` for hard rows.
    """

    nodes: np.ndarray
    mass: np.ndarray
    size: np.ndarray
    transfer: sp.spmatrix
    alpha: float | None
    modulus: float | None

    @property
    def hard(self) -> bool:
        """Two-pass rows (no penalty), not the penalised rows of Sect. 7.5."""
        return self.alpha is None

    @property
    def n_rows(self) -> int:
        return len(self.nodes)


#: The friction laws a ContactQP can carry (``none``: the thesis's frictionless problem).
FRICTION_LAWS = ("none", "tresca", "coulomb")

#: The fewest facets of a faceted friction law (a polygon needs three); ``0``: isotropic.
MIN_FRICTION_FACETS = 3


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


@dataclass
class LoadStep:
    """One step of a quasi-static load path: the ContactQP's data of that step.

    Attributes
    ----------
    f : (n,) array
        Load vector of the step (with the step's prescribed displacements lifted).
    g : (m,) array
        Gaps of the step.
    offset : (m_contact k,) array
        Tangential relative displacement of the step's prescribed values
        (``T_full @ u_fixed``): the step's relative tangential displacement is
        ``T u + offset``.
    """

    f: np.ndarray
    g: np.ndarray
    offset: np.ndarray


@dataclass
class Friction:
    """Tresca or Coulomb friction on the constrained rows: ``k = d - 1`` tangential rows
    per constrained node (2D: one, 3D: two).

    The tangential rows of constrained node ``i`` are ``t_ij . (u(P) - sum_k w_k u(P_k))``,
    the same interpolation (Alg. 7.1, (7.14)) as its normal row with the unit tangents
    ``t_ij`` orthogonal to the row's direction ``n_i`` (and, in 3D, to each other). Rows
    and every tangential vector are node-major: entry ``i k + j`` belongs to node ``i``,
    tangent ``j``. The slip of ``u`` is measured from the previous state of the load
    path::

        slip(u) = T u + offset - previous

    and one step is the Tresca problem (isotropic: ``|.|`` is the Euclidean norm of a
    node's ``k``-vector, the absolute value in 2D)::

        minimise 1/2 u'Au - f'u + sum_i s_i |slip_i(u)|   subject to   B u <= g

    with KKT conditions ``A u + B'p + T'lam = f``, ``|lam_i| <= s_i``,
    ``lam_i . slip_i = s_i |slip_i|`` (and the normal ones). Coulomb friction sets
    ``s_i = mu p_i`` by a fixed point over Tresca problems.

    The faceted law (3D, ``facets = k >= 3``) replaces the disc ``|lam_i| <= s_i`` by
    ``s_i P_k``, ``P_k`` the regular ``k``-gon inscribed in the unit circle with one vertex
    along the first tangent (:func:`polygon_vertices`): inscribed, as the pyramid
    approximations of engineering codes are, so that ``P_k`` lies inside the disc, its
    dissipation is a lower bound of the isotropic one and it grows to it as ``k`` grows
    (the gap is ``1 - cos(pi / k)`` relative, ``O(k^-2)``). Its primal term is the
    support function of ``s_i P_k``::

        s_i h_Pk(slip_i) = max_{l in s_i P_k} l . slip_i = s_i max_j v_j . slip_i

    (a linear function is largest at a vertex ``v_j``), so the step is

        minimise 1/2 u'Au - f'u + sum_i s_i h_Pk(slip_i(u))   subject to   B u <= g

    and, as ``s_i h_Pk`` is the support function of ``s_i P_k`` (its subdifferential at
    ``x`` is the face of ``s_i P_k`` where ``l . x`` is largest), its KKT conditions are
    ``A u + B'p + T'lam = f``, ``lam_i in s_i P_k`` (:meth:`gauge` ``<= s_i``),
    ``lam_i . slip_i = s_i h_Pk(slip_i)``. The dual is the isotropic one with the discs
    replaced by ``s_i P_k`` (``min 1/2 y'Sy - c'y``, ``p >= 0``, ``lam_i in s_i P_k``,
    :mod:`solvers.tresca`). In 2D the law is already polyhedral (the disc is the
    interval ``[-s_i, s_i]``): ``facets`` is ``0`` there.

    Attributes
    ----------
    law : {"tresca", "coulomb"}
    mu : float
        Friction coefficient (Coulomb; for Tresca it documents how ``slip_bound`` was made).
    T : (m_contact k, n) sparse
        Tangential rows on the free DOFs (node-major).
    tangent : (m_contact k, d) array
        Unit tangent of each tangential row.
    slip_bound : (m_contact,) array
        ``s_i >= 0``, a force (the bound on ``|lam_i|``).
    offset : (m_contact k,) array
        ``T_full @ u_fixed`` of this step's prescribed values.
    previous : (m_contact k,) array
        Relative tangential displacement ``T u_prev + offset_prev`` of the previous state.
    path : tuple of LoadStep
        The scene's load path (normal load first, then the tangential step); the
        ContactQP's ``f``, ``g`` and ``offset`` are those of one of its steps.
    facets : int
        ``0``: isotropic (the disc); ``k >= 3`` (3D only): the faceted law, ``lam_i`` in
        the inscribed regular ``k``-gon ``s_i P_k``.
    """

    law: str
    mu: float
    T: sp.spmatrix
    tangent: np.ndarray
    slip_bound: np.ndarray
    offset: np.ndarray
    previous: np.ndarray
    path: tuple = ()
    facets: int = 0

    @property
    def components(self) -> int:
        """``k``: tangential rows per constrained node (``d - 1``)."""
        return self.T.shape[0] // max(len(self.slip_bound), 1)

    def blocks(self, v: np.ndarray) -> np.ndarray:
        """The node-major vector ``v`` (``m_contact k`` entries) as ``(m_contact, k)``."""
        return np.asarray(v, dtype=float).reshape(-1, self.components)

    def magnitude(self, v: np.ndarray) -> np.ndarray:
        """Euclidean norm of each node's ``k``-vector of ``v`` (2D: ``|v_i|``)."""
        v = np.asarray(v, dtype=float)
        return np.abs(v) if self.components == 1 else np.linalg.norm(self.blocks(v), axis=1)

    def inner(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Per node ``a_i . b_i`` of two node-major vectors (2D: ``a_i b_i``)."""
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        return a * b if self.components == 1 else np.einsum("ij,ij->i", self.blocks(a),
                                                             self.blocks(b))

    def dissipation(self, slip: np.ndarray) -> np.ndarray:
        """Per node the dissipation per unit slip bound of the slip ``slip``: ``|slip_i|``
        (isotropic), ``h_Pk(slip_i) = max_j v_j . slip_i`` (faceted)."""
        if not self.facets:
            return self.magnitude(slip)
        return polygon_support(self.blocks(slip), self.facets)

    def gauge(self, lam: np.ndarray) -> np.ndarray:
        """Per node the size of ``lam_i`` the slip bound limits: ``|lam_i|`` (isotropic),
        the gauge of ``P_k`` (faceted, :func:`polygon_gauge`): ``lam_i`` is admissible
        exactly when it is ``<= s_i``."""
        if not self.facets:
            return self.magnitude(lam)
        return polygon_gauge(self.blocks(lam), self.facets)

    def clip(self, lam: np.ndarray) -> np.ndarray:
        """``lam`` projected onto the friction discs ``|lam_i| <= s_i`` (2D: the box
        ``[-s_i, s_i]``; 3D: each node's vector scaled back radially; faceted: the
        Euclidean projection onto ``s_i P_k``, :func:`project_polygon`)."""
        lam, s = np.asarray(lam, dtype=float), self.slip_bound
        if self.components == 1:
            return np.clip(lam, -s, s)
        if self.facets:
            return project_polygon(self.blocks(lam), s, self.facets).ravel()
        size = self.magnitude(lam)
        scale = np.where(size > s, s / np.where(size > 0, size, 1.0), 1.0)
        return (self.blocks(lam) * scale[:, None]).ravel()

    def tangential_force(self, lam: np.ndarray) -> np.ndarray:
        """The total tangential force ``sum_ij lam_ij t_ij`` (``(d,)``) of the multipliers
        ``lam``."""
        return (np.asarray(lam, dtype=float)[:, None] * self.tangent).sum(axis=0)

    def total_force(self, lam: np.ndarray) -> float:
        """``Q``: the size of the total tangential force of the multipliers ``lam``
        (2D: ``|sum_i lam_i|``; 3D: the norm of :meth:`tangential_force`)."""
        if self.components == 1:
            return abs(float(np.asarray(lam, dtype=float).sum()))
        return float(np.linalg.norm(self.tangential_force(lam)))

    def slip(self, u: np.ndarray) -> np.ndarray:
        """Tangential slip ``T u + offset - previous`` of ``u`` in this step."""
        return self.T @ np.asarray(u, dtype=float) + self.offset - self.previous

    def states(self, lam: np.ndarray, tol: float) -> np.ndarray:
        """Stick/slip state of each constrained node from its tangential multiplier
        ``lam``: ``free`` where ``s_i = 0`` (no tangential force can act: out of contact
        under Coulomb friction), ``stick`` where ``|lam_i|`` lies inside its bound by more
        than ``tol max(s)`` (the slip is then zero), ``slip`` where it is at the bound.
        """
        s = self.slip_bound
        margin = tol * (float(s.max()) if s.size else 0.0)
        inside = s - self.gauge(lam) > margin
        return np.where(s > 0, np.where(inside, "stick", "slip"), "free")


@dataclass
class SharedWork:
    """What is computed once per :class:`ContactQP` and shared, typed (``qp.cache``).

    Attributes
    ----------
    floating_modes : dict
        ``{threshold: (n, k) array}`` (:func:`problems.floating.floating_modes`).
    floating_factor : object or None
        ``A^{-1}`` with the floating modes removed
        (:func:`solvers.cholesky.shared_floating_factor`), shared by the exact solver and
        the verification's linear solver (a factorisation of the roll stack's level 3
        takes ~25 s).
    linear_solver : callable or None
        ``(r, guess=None) -> A^{-1} r`` of the verification
        (:func:`solvers.certificate.linear_solver`).
    certificate : tuple or None
        ``(digest of (u, p, tol), DualityGap)``: the last certificate
        (:func:`solvers.certificate.certify`).
    dual_operators : dict
        ``{frictional: DualOperators}`` (:func:`solvers.tresca.dual_operators`): ``A``
        factorised and the dense dual Hessian, shared by the steps of a load path (with
        and without the tangential rows).
    contact_schur : dict
        ``{factorization: ContactSchur}`` (:func:`solvers.semismooth_newton.contact_schur`):
        ``A`` factorised and the dense Schur complement of the normal and tangential rows,
        shared by the Tresca solves of a load path (at cube-sphere level 3 forming it
        costs minutes).
    """

    floating_modes: dict = field(default_factory=dict)
    floating_factor: object | None = None
    linear_solver: Callable | None = None
    certificate: tuple | None = None
    dual_operators: dict = field(default_factory=dict)
    contact_schur: dict = field(default_factory=dict)

    def problem_only(self) -> "SharedWork":
        """The problem's own data (its floating modes) without any solver's work: what a
        timed run starts from, so that it pays its own factorisations."""
        return SharedWork(floating_modes=dict(self.floating_modes))

    def fill_from(self, other: "SharedWork") -> None:
        """Take ``other``'s work wherever this holds none (after a timed run: the
        verification reuses what earlier verifications of the problem computed)."""
        for name in ("floating_modes", "dual_operators", "contact_schur"):
            mine = getattr(self, name)
            for key, value in getattr(other, name).items():
                mine.setdefault(key, value)
        for name in ("floating_factor", "linear_solver", "certificate"):
            if getattr(self, name) is None:
                setattr(self, name, getattr(other, name))


@dataclass
class ContactQP:
    """The algebraic contact problem ``min 1/2 u'Au - f'u  s.t.  Bu - Cp <= g``.

    Attributes
    ----------
    A : (n, n) sparse, symmetric positive definite
        Stiffness of both bodies on the free DOFs (block diagonal for two bodies).
    f : (n,) array
        Load vector (body force, tractions, minus the Dirichlet lift).
    B : (m, n) sparse
        One row per constrained node (Alg. 7.1, (7.14)).
    g : (m,) array
        Gaps along the contact direction, same units as ``u``.
    C : (m, m) sparse, optional
        Stabilisation block (Sect. 7.5); ``None`` means zero.
    free_dofs : (n,) int array, optional
        Position of each unknown in the full nodal vector (node-major,
        ``node * dim + component``).
    u_fixed : (N * dim,) array, optional
        Full nodal vector with the prescribed values, zero elsewhere;
        ``u_full = u_fixed; u_full[free_dofs] = u``.
    dim : int
        Spatial dimension (2 or 3).
    mesh : Mesh, optional
    contact : ContactSurface, optional
    multilevel : Multilevel
    hertz : HertzSetup, optional
    friction : Friction, optional
        Tresca or Coulomb friction on the constrained rows; ``None``: frictionless (the
        thesis's problem). Solvers that do not declare ``handles_friction`` refuse it.
    stabilisation : Stabilisation, optional
        Set when the last ``stabilisation.n_rows`` rows of ``B`` are reverse rows
        (penalised, Sect. 7.5, or hard, two-pass); ``contact`` and
        ``multilevel.surface`` describe the first ``m_contact`` rows.
    name : str
        Scene and level, for reports.
    units : str
        Units of length and force, e.g. ``"dimensionless"`` or ``"m, N"``.
    level : int
        Refinement level the scene built it at.
    cache : SharedWork
        Work computed once per problem and shared by whoever needs it (the floating
        modes, a factorisation of ``A``, the verification's linear solver, the last
        certificate); not part of the problem (not compared, not printed).
    """

    A: sp.spmatrix
    f: np.ndarray
    B: sp.spmatrix
    g: np.ndarray
    C: sp.spmatrix | None = None
    free_dofs: np.ndarray | None = None
    u_fixed: np.ndarray | None = None
    dim: int = 2
    mesh: Mesh | None = None
    contact: ContactSurface | None = None
    multilevel: Multilevel = field(default_factory=Multilevel)
    hertz: HertzSetup | None = None
    stabilisation: Stabilisation | None = None
    friction: Friction | None = None
    name: str = ""
    units: str = "dimensionless"
    level: int = 0
    cache: SharedWork = field(default_factory=lambda: SharedWork(), repr=False,
                              compare=False)

    def __post_init__(self):
        self.A = sp.csr_matrix(self.A, dtype=float)
        self.B = sp.csr_matrix(self.B, dtype=float)
        self.f = np.asarray(self.f, dtype=float).ravel()
        self.g = np.asarray(self.g, dtype=float).ravel()
        if self.C is not None:
            self.C = sp.csr_matrix(self.C, dtype=float)
        self.validate()

    @property
    def n(self) -> int:
        """Number of unknowns (free DOFs)."""
        return self.A.shape[0]

    @property
    def m(self) -> int:
        """Number of constraints (constrained nodes, N^C)."""
        return self.B.shape[0]

    @property
    def m_contact(self) -> int:
        """Rows of the constrained surface (all rows unless there are reverse rows: the
        stabilised coupling of Sect. 7.5 or two-pass)."""
        return self.m - (self.stabilisation.n_rows if self.stabilisation is not None else 0)

    @property
    def n_nodes(self) -> int:
        """Number of mesh nodes N (``n / dim`` without a mesh)."""
        return self.mesh.n_nodes if self.mesh is not None else self.n // self.dim

    def validate(self, symmetry_tol: float = 1e-10) -> None:
        """Check shapes, finiteness, symmetry of A and non-empty rows of B.

        Raises
        ------
        QPValidationError
            Naming the offending field.
        """
        n, m = self.A.shape[0], self.B.shape[0]
        if self.A.shape != (n, n) or n == 0:
            raise QPValidationError(f"A must be square and non-empty, got shape {self.A.shape}")
        if self.f.shape != (n,):
            raise QPValidationError(f"f must have shape ({n},), got {self.f.shape}")
        if self.B.shape[1] != n:
            raise QPValidationError(f"B must have {n} columns (one per unknown), got {self.B.shape[1]}")
        if self.g.shape != (m,):
            raise QPValidationError(f"g must have shape ({m},), got {self.g.shape}")
        for name in ("A", "B", "C"):
            mat = getattr(self, name)
            if mat is not None and not np.all(np.isfinite(mat.data)):
                raise QPValidationError(f"{name} has non-finite entries")
        for name in ("f", "g"):
            if not np.all(np.isfinite(getattr(self, name))):
                raise QPValidationError(f"{name} has non-finite entries")
        asym = abs(self.A - self.A.T)
        scale = abs(self.A).max() if self.A.nnz else 1.0
        if asym.nnz and asym.max() > symmetry_tol * scale:
            raise QPValidationError(f"A is not symmetric: max |A - A^T| = {asym.max():.3e} "
                                    f"(scale {scale:.3e})")
        if m:
            row_nnz = np.diff(self.B.indptr)
            rownorm = np.sqrt(np.asarray(self.B.multiply(self.B).sum(axis=1)).ravel())
            empty = np.flatnonzero((row_nnz == 0) | (rownorm == 0))
            if empty.size:
                raise QPValidationError(f"B has {empty.size} empty rows (first: {empty[:5].tolist()})")
        if self.C is not None and self.C.shape != (m, m):
            raise QPValidationError(f"C must have shape ({m}, {m}), got {self.C.shape}")
        if self.free_dofs is not None and np.shape(self.free_dofs) != (n,):
            raise QPValidationError(f"free_dofs must have shape ({n},), got {np.shape(self.free_dofs)}")
        st = self.stabilisation
        if st is not None:
            r = st.n_rows
            if not 0 < r < m:
                raise QPValidationError(f"stabilisation has {r} reverse rows; allowed: 1..{m - 1} "
                                        f"(B has {m} rows)")
            if st.hard and self.C is not None:
                raise QPValidationError("hard reverse rows (two-pass, alpha None) take no C")
            if not st.hard and (self.C is None or np.any(self.C.diagonal()[m - r:] <= 0)):
                raise QPValidationError("stabilisation needs C > 0 on its reverse rows")
            for name in ("mass", "size"):
                if np.shape(getattr(st, name)) != (r,) or np.any(getattr(st, name) <= 0):
                    raise QPValidationError(f"stabilisation.{name} must be {r} positive numbers")
            if st.transfer.shape != (r, m - r):
                raise QPValidationError(f"stabilisation.transfer must have shape {(r, m - r)}, "
                                        f"got {st.transfer.shape}")
        mc = self.m_contact
        if self.contact is not None:
            c = self.contact
            for name, shape in (("nodes", (mc,)), ("mass", (mc,)), ("direction", (mc, self.dim))):
                if np.shape(getattr(c, name)) != shape:
                    raise QPValidationError(f"contact.{name} must have shape {shape}, "
                                            f"got {np.shape(getattr(c, name))}")
            if np.any(np.asarray(c.mass) <= 0):
                raise QPValidationError("contact.mass must be positive")
        if self.mesh is not None and self.mesh.dim != self.dim:
            raise QPValidationError(f"mesh.points is {self.mesh.dim}D but dim = {self.dim}")
        ml = self.multilevel
        if ml.prolongations and ml.prolongations[-1].shape[0] != n:
            raise QPValidationError(f"multilevel.prolongations[-1] must end on the {n} unknowns, "
                                    f"got shape {ml.prolongations[-1].shape}")
        if ml.surface is not None:
            s = ml.surface
            if len(s.masses) != len(s.sizes) or len(s.prolongations) != len(s.masses) - 1:
                raise QPValidationError("multilevel.surface: masses, sizes and prolongations "
                                        "do not describe the same levels")
            if len(s.masses[-1]) != mc or len(s.sizes[-1]) != mc:
                raise QPValidationError(f"multilevel.surface must end on the {mc} constraints, "
                                        f"got {len(s.masses[-1])}")

        if self.friction is not None:
            _validate_friction(self.friction, n, self.m_contact, self.dim)

    def full_displacement(self, u: np.ndarray) -> np.ndarray:
        """Nodal displacement array ``(n_nodes, dim)`` including prescribed values."""
        if self.free_dofs is None or self.u_fixed is None:
            raise QPValidationError("this ContactQP has no free_dofs/u_fixed to expand u")
        full = np.array(self.u_fixed, dtype=float, copy=True)
        full[self.free_dofs] = u
        return full.reshape(-1, self.dim)

    def energy(self, u: np.ndarray) -> float:
        """J(u) = 1/2 u'Au - f'u."""
        return 0.5 * float(u @ (self.A @ u)) - float(self.f @ u)

    def constrained_points(self) -> np.ndarray:
        """Coordinates of the constrained nodes, one row per constraint."""
        if self.mesh is None or self.contact is None:
            raise QPValidationError("this ContactQP has no mesh/contact surface")
        return self.mesh.points[self.contact.nodes]


def check_facets(facets, dim: int, error: type = QPValidationError,
                 name: str = "friction.facets") -> None:
    """Raise ``error`` naming ``name`` unless ``facets`` is an allowed facet count in
    ``dim`` dimensions: ``0`` (isotropic), or in 3D an integer ``>= 3``
    (:data:`MIN_FRICTION_FACETS`); in 2D the law is already polyhedral (an interval)."""
    whole = isinstance(facets, (int, np.integer)) and not isinstance(facets, bool)
    if whole and (facets == 0 or (dim == 3 and facets >= MIN_FRICTION_FACETS)):
        return
    allowed = (f"0 (isotropic) or an integer >= {MIN_FRICTION_FACETS} (the inscribed regular "
               "k-gon)" if dim == 3 else
               "0 (in 2D the friction law is already polyhedral: the interval [-s, s])")
    raise error(f"{name} = {facets!r} is not allowed in {dim}D; allowed: {allowed}")


def _validate_friction(fr: Friction, n: int, mc: int, dim: int) -> None:
    """Shapes and ranges of a ContactQP's friction data (the message names the field)."""
    if fr.law not in FRICTION_LAWS[1:]:
        raise QPValidationError(f"friction.law {fr.law!r} is not allowed; allowed: "
                                f"{', '.join(FRICTION_LAWS[1:])}")
    fr.T = sp.csr_matrix(fr.T, dtype=float)
    mt = mc * (dim - 1)                     # tangential rows: d - 1 per constrained row
    if fr.T.shape != (mt, n):
        raise QPValidationError(f"friction.T must have shape ({mt}, {n}) ({dim - 1} tangential "
                                f"row(s) per constrained row in {dim}D), got {fr.T.shape}")
    for name, size in (("slip_bound", mc), ("offset", mt), ("previous", mt)):
        v = np.asarray(getattr(fr, name), dtype=float).ravel()
        if v.shape != (size,) or not np.all(np.isfinite(v)):
            raise QPValidationError(f"friction.{name} must be {size} finite values, got shape "
                                    f"{v.shape}")
        setattr(fr, name, v)
    fr.tangent = np.asarray(fr.tangent, dtype=float)
    if fr.tangent.shape != (mt, dim):
        raise QPValidationError(f"friction.tangent must have shape ({mt}, {dim}), got "
                                f"{fr.tangent.shape}")
    if np.any(fr.slip_bound < 0) or not fr.mu >= 0:
        raise QPValidationError("friction.slip_bound and friction.mu must be >= 0")
    check_facets(fr.facets, dim, QPValidationError, "friction.facets")
    for k, step in enumerate(fr.path):
        for name, size in (("f", n), ("offset", mt)):
            if np.shape(getattr(step, name)) != (size,):
                raise QPValidationError(f"friction.path[{k}].{name} must have shape ({size},), "
                                        f"got {np.shape(getattr(step, name))}")


def surface_multipliers(qp: ContactQP, p: np.ndarray) -> np.ndarray:
    """The multipliers acting on the constrained surface's rows (``qp.m_contact`` of them).

    ``p`` itself without a stabilisation; with one (Sect. 7.5) the reverse rows'
    multipliers are spread onto the constrained nodes of the facet each one hits,
    ``p_c + T' p_r`` (``T = stabilisation.transfer``): the total force on the
    constrained surface. The pressure is :func:`surface_pressure`.
    """
    p = np.asarray(p, dtype=float)
    if qp.stabilisation is None:
        return p
    mc = qp.m_contact
    return p[:mc] + qp.stabilisation.transfer.T @ p[mc:]


def surface_pressure(qp: ContactQP, p: np.ndarray) -> np.ndarray:
    """Nodal contact pressure at the constrained nodes: :func:`surface_multipliers`
    turned into a pressure by :meth:`ContactSurface.pressure`."""
    return qp.contact.pressure(surface_multipliers(qp, p))
