"""The neutral core: the algebraic contact problem and its typed data.

Both sides of the data flow import this module and nothing above it: a scene
(``problems/<name>.py``) builds a :class:`ContactQP`; every solver
(``solvers/<name>.py``) receives one; :mod:`problems.kkt` judges any ``(u, p)`` the
same way whoever produced it. Beside it, one job each: :mod:`problems.kkt` (KKT
residuals, energy error), :mod:`problems.slack` (the slack form of the stabilised
problem), :mod:`problems.floating` (floating bodies' rigid modes). Friction (the
:class:`problems.friction.data.Friction` a ContactQP may carry, its program forms and
its KKT residuals) is gathered in :mod:`problems.friction`.

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

from problems.friction.data import FRICTION_LAWS, Friction, check_facets


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
    (:func:`solvers.kernels.multigrid.layered_hierarchy`).

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
    prescribed_prolongation : sparse or None
        ``(n, N_c dim)``: the last prolongation's share of the coarser level's
        prescribed values, from its full nodal vector (``u_fixed``, node-major) to
        the free DOFs; zero columns at its free DOFs. The free nodes next to the
        Dirichlet boundary take part of their interpolated value from it
        (:func:`prolongate_displacement`).
    """

    prolongations: list = field(default_factory=list)
    rigid_body_modes: np.ndarray | None = None
    body_of_dof: np.ndarray | None = None
    surface: SurfaceHierarchy | None = None
    extrusion: Extrusion | None = None
    prescribed_prolongation: sp.spmatrix | None = None


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


@dataclass
class SharedWork:
    """What is computed once per :class:`ContactQP` and shared, typed (``qp.cache``).

    Attributes
    ----------
    floating_modes : dict
        ``{threshold: (n, k) array}`` (:func:`problems.floating.floating_modes`).
    floating_factor : object or None
        ``A^{-1}`` with the floating modes removed
        (:func:`solvers.kernels.cholesky.shared_floating_factor`), shared by the exact
        solver and the verification's linear solver (a factorisation of a large problem
        is too slow to repeat).
    linear_solver : callable or None
        ``(r, guess=None) -> A^{-1} r`` of the verification
        (:func:`solvers.certificate.linear_solver`).
    certificate : tuple or None
        ``(digest of (u, p, tol), DualityGap)``: the last certificate
        (:func:`solvers.certificate.certify`).
    dual_operators : dict
        ``{frictional: DualOperators}`` (:func:`solvers.kernels.tresca.dual_operators`): ``A``
        factorised and the dense dual Hessian, shared by the steps of a load path (with
        and without the tangential rows).
    contact_schur : dict
        ``{factorization: ContactSchur}`` (:func:`solvers.semismooth_newton.contact_schur`):
        ``A`` factorised and the dense Schur complement of the normal and tangential rows,
        shared by the Tresca solves of a load path (forming it is too slow to repeat
        for each).
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
        _check_symmetric(self.A, symmetry_tol)
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
        if ml.prescribed_prolongation is not None and ml.prescribed_prolongation.shape[0] != n:
            raise QPValidationError(f"multilevel.prescribed_prolongation must end on the {n} "
                                    f"unknowns, got shape {ml.prescribed_prolongation.shape}")
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


def _check_symmetric(A: sp.csr_matrix, symmetry_tol: float) -> None:
    """Raise :class:`QPValidationError` unless ``max |A - A^T| <= symmetry_tol max |A|``.

    A canonical ``A`` whose pattern is symmetric (a stiffness matrix) is compared entry by
    entry with its transpose (its sorted CSC arrays are the CSR arrays of ``A^T``) without
    forming ``A - A^T``: the same differences, so the same maximum; any other ``A`` through
    the sparse difference.
    """
    At = A.tocsc() if A.has_canonical_format and A.nnz else None
    if At is not None and np.array_equal(At.indptr, A.indptr) and np.array_equal(At.indices,
                                                                                 A.indices):
        worst, scale = float(np.abs(A.data - At.data).max()), float(np.abs(A.data).max())
    else:
        asym = abs(A - A.T)
        worst, scale = (asym.max() if asym.nnz else 0.0), (abs(A).max() if A.nnz else 1.0)
    if worst != 0 and worst > symmetry_tol * scale:
        raise QPValidationError(f"A is not symmetric: max |A - A^T| = {worst:.3e} "
                                f"(scale {scale:.3e})")


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


def prolongate_displacement(qp_coarse: ContactQP, u: np.ndarray, qp_fine: ContactQP,
                            ) -> np.ndarray:
    """The coarser level's displacement ``u`` interpolated on ``qp_fine``'s free DOFs,
    prescribed values included: ``P u + P_D u_fixed`` (the start of nested iteration,
    Alg. 8.5).

    ``P = qp_fine.multilevel.prolongations[-1]`` carries the coarse free DOFs and
    ``P_D = qp_fine.multilevel.prescribed_prolongation`` the coarse prescribed values
    (``qp_coarse.u_fixed``): a fine free node on an edge with one Dirichlet end takes
    half its value from that end. Without ``P_D`` the start would carry the Dirichlet
    lift's layer along the boundary as error, the same at every level. A fine problem
    without ``P_D`` (built elsewhere, or loaded from an export) gets ``P u``.

    Raises
    ------
    ValueError
        ``qp_fine`` has no prolongations, or they do not start on ``qp_coarse``'s
        unknowns and prescribed values.
    """
    ml = qp_fine.multilevel
    if not ml.prolongations:
        raise ValueError("parameter 'qp_fine': multilevel.prolongations are required")
    P = ml.prolongations[-1]
    if P.shape != (qp_fine.n, qp_coarse.n):
        raise ValueError(f"prolongation has shape {P.shape}, expected "
                         f"{(qp_fine.n, qp_coarse.n)}: not consecutive levels of one scene")
    u0 = P @ np.asarray(u, dtype=float)
    P_D = ml.prescribed_prolongation
    if P_D is None:
        return u0
    if qp_coarse.u_fixed is None or P_D.shape[1] != np.size(qp_coarse.u_fixed):
        raise ValueError(f"prescribed prolongation has shape {P_D.shape}, expected "
                         f"{qp_fine.n} x {np.size(qp_coarse.u_fixed)} (the coarser level's "
                         "u_fixed): not consecutive levels of one scene")
    return u0 + P_D @ qp_coarse.u_fixed
