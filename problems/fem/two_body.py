"""Two elastic bodies in contact: from meshes and supports to a :class:`ContactQP`.

Dimension-generic (2D plane strain, 3D), so a scene supplies only its geometry:
each body's nested meshes and material (:class:`Body`), its supports and loads,
which nodes form the constrained surface and which facets the opposing one
(:class:`TwoBodyScene`). :func:`assemble_two_body` then

1. stacks both bodies in one node numbering (the second body's ids offset),
2. assembles the P1 or P2 stiffness and the loads (Sect. 2.1, Sect. 5.1, Remark 7.11),
3. splits off the prescribed DOFs (Dirichlet lift),
4. builds the nodal contact constraints of Alg. 7.1 and the lumped contact mass,
5. restricts everything to the free DOFs,
6. collects the multilevel data: prolongations on the free DOFs of every
   level, rigid-body modes per body, the constrained surface on every level.

With ``degree=2`` (Remark 7.11) the finest level is the P2 space on the finest
mesh (:mod:`problems.fem.quadratic`): its constrained surface holds the
vertices and the edge midpoints, each opposing point is parametrised on the
flat facet through the opposing facet's vertices and weighted by the P2 shape
functions, and the hierarchy below it is P1 on every mesh level, so a
multilevel solver's first coarsening is a p-multigrid step (P2 -> P1 on the same
mesh, exact interpolation) and the geometric P1 hierarchy follows.

Pure functions: no files, no clocks.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.sparse as sp

from problems.fem.contact import contact_constraints, quadratic_constraints, tangential_rows
from problems.fem.elasticity import (body_force_vector, boundary_facets, dirichlet_split,
                                     lumped_surface_mass, rigid_body_modes, stiffness_matrix,
                                     traction_vector)
from problems.fem.mesh import Hierarchy, dof_prolongation, prescribed_dof_prolongation
from problems.fem.quadratic import (FACET_EDGES, body_force_vector_p2, edge_lookup, linear_to_quadratic,
                                    midpoint_supports, quadratic_facets, quadratic_mesh,
                                    stiffness_matrix_p2, surface_mass_p2, traction_vector_p2)
from problems.fem.surface import facet_sizes, surface_levels
from problems.spec import Options, Parameter, ParameterError
from problems.friction.data import FRICTION_LAWS, Friction, LoadStep, check_facets
from problems.qp import ContactQP, ContactSurface, HertzSetup, Mesh, Multilevel

#: The scenes' element order (one declaration, every two-body scene lists it).
ELEMENT_DEGREE = Parameter(
    "degree", 1, "Lagrange elements' order: 1 (P1) or 2 (P2, Remark 7.11: constraints at the "
    "vertices and edge midpoints of the constrained surface)", low=1, high=2)



def friction_parameters(held: str, dim: int = 2) -> tuple[Parameter, ...]:
    """The friction parameters of a contact scene (``friction``, ``mu``, ``shift``,
    ``shift_steps``, in 3D ``friction_facets``); ``held`` names the part of the loaded body
    the tangential ``shift`` moves, in ``shift_steps`` equal increments (1: one tangential
    step). In 2D the law is already polyhedral (an interval): no facets."""
    facets = (Parameter("friction_facets", 0, "3D friction law's shape: 0 = isotropic (the "
                        "disc |lam| <= s), k >= 3 = faceted (lam in the regular k-gon "
                        "inscribed in the disc, one vertex along the first tangent; a QP)",
                        low=0),) if dim == 3 else ()
    return (
        Parameter("friction", "none", "friction law on the contact (none: the thesis's "
                  "frictionless problem; tresca: slip bound mu p of the normal step; coulomb: "
                  "s = mu p by a fixed point)", choices=FRICTION_LAWS),
        Parameter("mu", 0.0, "friction coefficient", low=0.0),
        Parameter("shift", 0.0, f"tangential load: prescribed x-displacement of {held} after "
                  "the normal load", low=-0.2, high=0.2),
        Parameter("shift_steps", 1, "tangential load steps: the shift applied in this many "
                  "equal increments after the normal load (a quasi-static load path)", low=1,
                  high=20, kind=int),
        *facets,
    )


def friction_facets(p: Options, dim: int) -> int:
    """The scene's ``friction_facets`` (``0`` where it has none), checked: ``0`` or an
    integer ``>= 3`` in 3D, and only with a friction law.

    Raises
    ------
    ParameterError
        Naming the parameter and the allowed values.
    """
    facets = int(p.get("friction_facets", 0))
    check_facets(facets, dim, ParameterError, "parameter 'friction_facets'")
    if facets and p.friction == "none":
        raise ParameterError(f"parameter 'friction_facets': {facets} is not allowed with "
                             "friction='none'; allowed: 0 (the facets shape a friction law: "
                             "set friction=tresca or coulomb)")
    return facets


#: ``dirichlet(points, body_of_node) -> (fixed_dofs, values)`` on one level's stacked mesh.
Supports = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
#: ``selector(points) -> bool mask`` (nodes or facet centroids).
Selector = Callable[[np.ndarray], np.ndarray]


@dataclass
class Body:
    """One elastic body: its nested meshes (coarse to fine) and material.

    Attributes
    ----------
    name : str
    meshes : Hierarchy
        ``points[k], cells[k]`` on level ``k``; ``prolongations[k]`` the nodal
        P1 prolongation from level ``k`` to ``k + 1``.
    E, nu : float
        Young's modulus and Poisson's ratio.
    body_force : (d,) array
        Force per unit volume (area in 2D).
    """

    name: str
    meshes: Hierarchy
    E: float
    nu: float
    body_force: np.ndarray


@dataclass
class Traction:
    """A constant traction on the boundary facets of one body selected by centroid."""

    body: int
    on: Selector
    traction: np.ndarray


@dataclass
class Springs:
    """Weak grounded springs on selected nodes of one body (removing its rigid motion
    where only the contact holds it, e.g. the roll stack's work roll).

    ``stiffness`` is per node and component (force per length); the spring
    forces are reported by :func:`spring_forces`.
    """

    body: int
    on: Selector
    stiffness: np.ndarray


@dataclass
class TwoBodyScene:
    """What a scene supplies; :func:`assemble_two_body` does the rest.

    Attributes
    ----------
    bodies : (Body, Body)
        In memory order (a solution must not depend on it).
    constrained_body : int
        Index of the body whose surface carries one inequality per node
        (thesis: surface ``l``); the other body is the opposing one.
    supports : Supports
        Prescribed DOFs and values on a level's stacked mesh.
    on_constrained : Selector
        Boundary nodes of the constrained body that form the constrained surface.
    on_opposing : Selector
        Boundary facets (by centroid) of the opposing body that may come into contact.
    direction : (d,) array
        Contact direction ``n`` (case b), from the constrained towards the opposing body.
    search : {"along_direction", "closest_point"}
    surface_coarsening : callable, optional
        ``coarsening(points of the constrained nodes on level 0)`` returns
        coarser surface levels ``(prolongations, masses)`` below the coarsest
        mesh (e.g. :func:`problems.fem.surface.tensor_coarsening`).
    tractions : list of Traction
    springs : list of Springs
        Grounded springs, added to the stiffness (multigrid's Galerkin coarse
        operators inherit them).
    hertz : HertzSetup, optional
    units : str
    """

    bodies: tuple
    constrained_body: int
    supports: Supports
    on_constrained: Selector
    on_opposing: Selector
    direction: np.ndarray
    search: str = "along_direction"
    surface_coarsening: Callable | None = None
    tractions: list = field(default_factory=list)
    springs: list = field(default_factory=list)
    hertz: HertzSetup | None = None
    units: str = "dimensionless"


def stack(meshes: list[tuple[np.ndarray, np.ndarray]]):
    """One node numbering for several bodies: ``(points, cells, body_of_node, offsets)``."""
    points = np.vstack([p for p, _ in meshes])
    offsets = np.concatenate([[0], np.cumsum([len(p) for p, _ in meshes])])
    cells = np.vstack([c + off for (_, c), off in zip(meshes, offsets[:-1])])
    body_of_node = np.repeat(np.arange(len(meshes)), np.diff(offsets))
    return points, cells, body_of_node, offsets


def _level(scene: TwoBodyScene, k: int):
    """Stacked mesh of level ``k`` and its free DOFs."""
    points, cells, body_of_node, offsets = stack(
        [(b.meshes.points[k], b.meshes.cells[k]) for b in scene.bodies])
    dim = points.shape[1]
    fixed, values = scene.supports(points, body_of_node)
    free, u_fixed = dirichlet_split(dim * len(points), fixed, values)
    return points, cells, body_of_node, offsets, free, u_fixed


def _constrained_surface(scene: TwoBodyScene, points, cells, body_of_node):
    """Constrained nodes (sorted lexicographically), their facets, lumped mass and local
    mesh size."""
    body = scene.constrained_body
    facets = boundary_facets(cells[body_of_node[cells[:, 0]] == body], points)
    on = np.zeros(len(points), dtype=bool)
    cand = np.unique(facets)
    on[cand] = scene.on_constrained(points[cand])
    surface_facets = facets[np.all(on[facets], axis=1)]
    nodes = np.flatnonzero(on)
    nodes = nodes[np.lexsort(points[nodes].T[::-1])]       # sorted by x, then y (then z)
    mass = lumped_surface_mass(points, surface_facets, len(points))[nodes]
    if np.any(mass <= 0):
        raise ValueError("a constrained node lies on no constrained facet: on_constrained "
                         "must select whole boundary facets")
    return nodes, surface_facets, mass, facet_sizes(points, surface_facets, nodes)


def _quadratic_surface(quad, points, nodes, facets):
    """The P2 constrained surface on the vertex surface ``(nodes, facets)``: its vertices
    and edge midpoints (sorted lexicographically), their HRZ lumped mass
    (:func:`problems.fem.quadratic.surface_mass_p2`) and local node spacing (half the
    facet size: the multilevel S-hat treats the P2 surface as one level finer)."""
    qf = quadratic_facets(quad, facets)
    nodes = np.unique(qf)
    nodes = nodes[np.lexsort(points[nodes].T[::-1])]
    mass = surface_mass_p2(points, qf)[nodes]
    return nodes, mass, 0.5 * facet_sizes(points, qf, nodes)


def quadratic_pressure_map(surface) -> sp.csr_matrix:
    """Nodal pressure of P2 contact forces (Remark 7.11): restricted to the vertices by the
    p-multigrid prolongation's transpose, divided by the P1 lumped mass there and
    interpolated back to the midpoints, ``P diag(1 / m_1) P'``.

    P2's nodal forces alternate between vertices and midpoints (with the HRZ mass of
    :func:`problems.fem.quadratic.surface_mass_p2`: docs/guide/measurements.md; in 3D a
    vertex function integrates to zero, so ``p / mass`` is no pressure there).
    Aggregating each midpoint's force half onto each of its vertices is exact for a
    constant pressure in 2D and 3D and removes the alternation.

    Parameters
    ----------
    surface : SurfaceHierarchy
        Whose last level is the P2 surface and the one below it P1 on the same mesh.
    """
    P = sp.csr_matrix(surface.prolongations[-1])
    return (P @ sp.diags(1.0 / surface.masses[-2]) @ P.T).tocsr()


def _quadratic_level(scene: TwoBodyScene, linear):
    """The P2 level on the finest mesh level ``linear`` (:func:`_level`'s tuple): its
    stacked mesh, free DOFs, lifted prescribed values and the :class:`QuadraticMesh`.

    The vertices keep their ids; a boundary edge's midpoint is prescribed where both
    of its vertices are, to their mean (:func:`problems.fem.quadratic.midpoint_supports`).
    """
    points, cells, body_of_node, offsets, _free, _u = linear
    dim = points.shape[1]
    quad = quadratic_mesh(points, cells)
    body2 = np.concatenate([body_of_node, body_of_node[quad.edges[:, 0]]])
    fixed, values = scene.supports(points, body_of_node)
    facets = boundary_facets(cells)
    pairs = FACET_EDGES[dim]
    on_boundary = np.unique(np.concatenate(
        [edge_lookup(quad.edges, quad.n_vertices, facets[:, i], facets[:, j]) for i, j in pairs]))
    fixed2, values2 = midpoint_supports(quad.edges, quad.n_vertices, dim, fixed, values,
                                        on_boundary)
    free, u_fixed = dirichlet_split(dim * len(quad.points), fixed2, values2)
    return (quad.points, quad.cells, body2, offsets, free, u_fixed), quad


def _opposing_facets(scene: TwoBodyScene, points, cells, body_of_node):
    """Boundary facets of the opposing body selected by centroid, oriented outward
    (as case a of Alg. 7.1 needs)."""
    body = 1 - scene.constrained_body
    facets = boundary_facets(cells[body_of_node[cells[:, 0]] == body], points)
    return facets[scene.on_opposing(points[facets].mean(axis=1))]


def _body_modes(points: np.ndarray, on_body: np.ndarray) -> np.ndarray:
    """Rigid-body modes of the nodes ``on_body`` on all DOFs (zero elsewhere)."""
    dim = points.shape[1]
    idx = np.flatnonzero(on_body)
    modes = rigid_body_modes(points[idx])
    out = np.zeros((points.size, modes.shape[1]))
    out[(idx[:, None] * dim + np.arange(dim)).ravel()] = modes
    return out


def spring_matrix(scene: TwoBodyScene, points: np.ndarray, body_of_node: np.ndarray):
    """Diagonal stiffness of the scene's grounded springs on the full DOFs."""
    dim = points.shape[1]
    diag = np.zeros(points.size)
    for spring in scene.springs:
        nodes = np.flatnonzero((body_of_node == spring.body) & spring.on(points))
        k = np.broadcast_to(np.asarray(spring.stiffness, dtype=float), (dim,))
        diag[(nodes[:, None] * dim + np.arange(dim)).ravel()] += np.tile(k, len(nodes))
    return sp.diags(diag, format="csr")


def spring_forces(scene: TwoBodyScene, qp: ContactQP, u: np.ndarray) -> np.ndarray:
    """Total force ``(d,)`` the springs exert on the bodies for the displacement ``u``."""
    mesh = qp.mesh
    K = spring_matrix(scene, mesh.points, mesh.body_of_node)
    return -(K @ qp.full_displacement(u).ravel()).reshape(-1, qp.dim).sum(axis=0)


@dataclass(frozen=True)
class _LoadMap:
    """What maps a scene's prescribed values to a step's data, kept from one assembly: the
    full stiffness and load, the full contact (and tangential) rows and their gaps, and the
    finest level's geometry and free DOFs that the values must belong to."""

    A_full: sp.csr_matrix
    f_full: np.ndarray
    B_full: sp.csr_matrix
    g_full: np.ndarray
    T_full: sp.csr_matrix | None
    points: np.ndarray
    free: np.ndarray

    def load(self, u_fixed: np.ndarray) -> LoadStep:
        """The step's data for the prescribed values ``u_fixed``: the load with them lifted,
        the gaps they leave and their tangential offset (empty without tangential rows)."""
        f = self.f_full[self.free] - (self.A_full @ u_fixed)[self.free]
        g = self.g_full - self.B_full @ u_fixed
        offset = self.T_full @ u_fixed if self.T_full is not None else np.zeros(0)
        return LoadStep(f, g, offset, u_fixed)

    def step(self, scene: TwoBodyScene, level: int) -> LoadStep:
        """The step's data of ``scene``, whose meshes and supported DOFs must be this
        assembly's (only the prescribed values differ)."""
        points, _, _, _, free, u_fixed = _level(scene, level)
        if not (np.array_equal(points, self.points) and np.array_equal(free, self.free)):
            raise ValueError("the scene of a later load step has other meshes or supported "
                             "DOFs than the first: a load path may change prescribed values "
                             "only")
        return self.load(u_fixed)


def assemble_two_body(scene: TwoBodyScene, level: int, name: str = "",
                      degree: int = 1, tangential: bool = False) -> ContactQP:
    """The ContactQP of ``scene`` on mesh level ``level`` (see the module docstring).

    Parameters
    ----------
    scene : TwoBodyScene
    level : int
        The finest mesh level.
    name : str
    degree : {1, 2}
        Lagrange elements of first or second order (Remark 7.11).
    tangential : bool
        Also build the tangential rows (:func:`problems.fem.contact.tangential_rows`,
        P1; ``d - 1`` per constrained node) as a Tresca :class:`Friction` with zero slip bounds, which the scene
        completes; ``False`` leaves the frictionless ContactQP exactly as it is.

    Returns
    -------
    ContactQP
        With ``mesh``, ``contact``, ``multilevel`` (prolongations on the free
        DOFs from level 0 up, rigid-body modes per body, body of each DOF, the
        constrained surface on every level) and ``hertz``.
    """
    return _assemble(scene, level, name, degree, tangential)[0]


def _assemble(scene: TwoBodyScene, level: int, name: str, degree: int,
              tangential: bool) -> tuple[ContactQP, _LoadMap, LoadStep]:
    """:func:`assemble_two_body`'s ContactQP, what maps prescribed values to its data, and
    its own step's data (the ContactQP's load, gaps, offset and prescribed values)."""
    if degree not in (1, 2):
        raise ValueError(f"parameter 'degree': {degree!r} is not allowed; allowed: 1 (P1) or "
                         "2 (P2, Remark 7.11)")
    levels = [_level(scene, k) for k in range(level + 1)]
    vertex_points, vertex_cells, vertex_body = levels[-1][:3]
    quad = None
    if degree == 2:
        quadratic, quad = _quadratic_level(scene, levels[-1])
        levels.append(quadratic)
    points, cells, body_of_node, offsets, free, u_fixed = levels[-1]
    dim = points.shape[1]
    n_nodes = len(points)
    body_of_cell = body_of_node[cells[:, 0]]
    E_cell = np.array([scene.bodies[b].E for b in body_of_cell], dtype=float)
    nu_cell = np.array([scene.bodies[b].nu for b in body_of_cell], dtype=float)
    force = np.array([scene.bodies[b].body_force for b in range(len(scene.bodies))], dtype=float)
    if quad is None:
        A_full = stiffness_matrix(points, cells, E_cell, nu_cell)
        f_full = body_force_vector(points, cells, force[body_of_cell])
    else:
        A_full = stiffness_matrix_p2(quad, E_cell, nu_cell)
        f_full = body_force_vector_p2(points, cells, force[body_of_cell])
    A_full = A_full + spring_matrix(scene, points, body_of_node)
    for tr in scene.tractions:
        facets = boundary_facets(vertex_cells[body_of_cell == tr.body], vertex_points)
        facets = facets[tr.on(vertex_points[facets].mean(axis=1))]
        traction = np.asarray(tr.traction, dtype=float)
        f_full += (traction_vector(points, facets, traction) if quad is None else
                   traction_vector_p2(points, quadratic_facets(quad, facets), traction))

    nodes, surface_facets, mass, size = _constrained_surface(scene, vertex_points, vertex_cells,
                                                             vertex_body)
    if quad is not None:
        nodes, mass, size = _quadratic_surface(quad, points, nodes, surface_facets)
    opposing = _opposing_facets(scene, vertex_points, vertex_cells, vertex_body)
    cc = contact_constraints(points, nodes, opposing, direction=np.asarray(scene.direction, float),
                             search=scene.search, n_nodes=n_nodes)
    if quad is not None:
        cc = quadratic_constraints(cc, quadratic_facets(quad, cc.facet_nodes), n_nodes)
    if tangential and quad is not None:
        raise ValueError("tangential rows are built for P1 elements; allowed: degree=1")
    if cc.m == 0:
        raise ValueError("no constrained node finds an opposing facet: the bodies never face "
                         "each other along the contact direction (check on_opposing)")

    A = A_full[free][:, free].tocsr()
    B = cc.B[:, free].tocsr()
    T_full, tangent = tangential_rows(cc, n_nodes) if tangential else (None, None)
    load_map = _LoadMap(A_full=A_full, f_full=f_full, B_full=cc.B, g_full=cc.g,
                        T_full=T_full, points=points, free=free)
    data = load_map.load(u_fixed)
    f, g, offset = data.f, data.g, data.offset

    body_of_dof = np.repeat(body_of_node, dim)[free]
    rbm = np.hstack([_body_modes(points, body_of_node == b)[free]
                     for b in range(len(scene.bodies))])

    node_P = [sp.block_diag([b.meshes.prolongations[k] for b in scene.bodies], format="csr")
              for k in range(level)]
    if quad is not None:                    # the p-multigrid step: P1 -> P2 on the finest mesh
        node_P.append(linear_to_quadratic(quad.n_vertices, quad.edges))
    prolongations = [dof_prolongation(node_P[k], dim, levels[k + 1][4], levels[k][4])
                     for k in range(len(node_P))]
    prescribed = (prescribed_dof_prolongation(node_P[-1], dim, levels[-1][4], levels[-2][4])
                  if node_P else None)
    surf = [(nodes, None, mass, size) if k == len(levels) - 1 else
            _constrained_surface(scene, pts_k, cells_k, body_k)
            for k, (pts_k, cells_k, body_k, *_rest) in enumerate(levels)]
    coarsening = None
    if scene.surface_coarsening is not None:
        coarsening = scene.surface_coarsening(levels[0][0][surf[0][0]])
    surface = surface_levels(node_P, [s[0] for s in surf], [s[2] for s in surf],
                             [s[3] for s in surf], coarsening)
    # nodes whose ray misses the opposing surface (grazing contact) carry no constraint
    # (Alg. 7.1 drops them): the finest surface level keeps the rows that exist
    if surface.prolongations:            # (a single-level scene has no surface coarsening)
        surface.prolongations[-1] = surface.prolongations[-1][cc.found].tocsr()
    surface.masses[-1] = surface.masses[-1][cc.found]
    surface.sizes[-1] = surface.sizes[-1][cc.found]

    friction = None
    if tangential:
        friction = Friction(law="tresca", mu=0.0, T=T_full[:, free].tocsr(), tangent=tangent,
                            slip_bound=np.zeros(cc.m), offset=offset,
                            previous=np.zeros(T_full.shape[0]))

    qp = ContactQP(
        A=A, f=f, B=B, g=g, free_dofs=free, u_fixed=u_fixed, dim=dim, friction=friction,
        mesh=Mesh(points=points, cells=cells, body_of_node=body_of_node, E_cell=E_cell,
                  nu_cell=nu_cell, bodies=tuple(b.name for b in scene.bodies)),
        contact=ContactSurface(nodes=cc.rows, mass=mass[cc.found], direction=cc.direction,
                               facets=surface_facets, opposing_facets=opposing,
                               search=scene.search, dropped=int(nodes.size - cc.m),
                               pressure_map=None if quad is None else
                               quadratic_pressure_map(surface)),
        multilevel=Multilevel(prolongations=prolongations, rigid_body_modes=rbm,
                              body_of_dof=body_of_dof, surface=surface,
                              prescribed_prolongation=prescribed),
        hertz=scene.hertz, name=name, units=scene.units, level=level,
    )
    return qp, load_map, data


def frictional_two_body(scene: Callable[[int, Options], TwoBodyScene], level: int, p: Options,
                        name: str) -> ContactQP:
    """The frictional ContactQP of a scene with ``friction``, ``mu`` and ``shift``
    (:func:`friction_parameters`): its load path is the normal load (``shift`` = 0) and
    then the tangential steps (the held part moved along x to ``j shift / shift_steps``,
    ``j = 1 .. shift_steps``: :func:`shift_increments`); the ContactQP
    holds the first step's data, slip measured from the unloaded state, slip bounds zero
    (the path's driver sets them: :func:`solvers.kernels.tresca.friction_path`); in 3D the law's
    shape ``friction_facets`` (:func:`friction_facets`).

    ``scene(level, options)`` builds the scene with the held part's x-displacement set
    to ``options.shift``; the two steps differ only in their prescribed values, so the
    scene is assembled once and the shifted step's load, gaps and offset come from the same
    matrices (:class:`_LoadMap`: the same arithmetic as an assembly of the shifted scene).

    Raises
    ------
    ParameterError
        For a coupling other than ``nodal`` or elements other than P1 (the tangential
        rows are built for the nodal P1 constraints).
    ValueError
        If the shifted scene has other meshes or supported DOFs than the unshifted one.
    """
    # a scene that does not declare the parameter has only the allowed value
    for key, allowed in (("coupling", "nodal"), ("degree", 1)):
        value = p.get(key, allowed)
        if value != allowed:
            raise ParameterError(f"parameter '{key}': {value!r} is not allowed with "
                                 f"friction={p.friction!r}; allowed: {allowed!r} (the tangential "
                                 "rows are built for the nodal P1 constraints)")
    name = f"{name} level {level} {p.friction} mu={p.mu:g}"
    if p.get("friction_facets", 0):
        name += f" facets={p.friction_facets}"
    qp, load_map, normal = _assemble(scene(level, Options({**p, "shift": 0.0})), level, name,
                                     degree=1, tangential=True)
    qp.friction.law, qp.friction.mu = p.friction, float(p.mu)
    qp.friction.facets = friction_facets(p, qp.dim)
    full = load_map.step(scene(level, Options({**p, "shift": p.shift})), level)
    qp.friction.path = (normal, *shift_increments(normal, full, p.shift_steps))
    return qp


def shift_increments(normal: LoadStep, full: LoadStep, count: int) -> tuple[LoadStep, ...]:
    """The tangential steps of a path that applies the shift in ``count`` equal increments:
    step ``j`` the data at ``j / count`` of the way from ``normal`` to ``full`` (a step's
    data are affine in the prescribed shift, so this is exact: :meth:`LoadStep.toward`); the
    last step is ``full`` itself (``count = 1``: the two-step path as assembled)."""
    between = tuple(normal.toward(full, j / count) for j in range(1, count))
    return (*between, full)
