"""The neutral core: the algebraic contact problem and how an answer is judged.

Both sides of the data flow import this module and nothing above it: a scene
(``problems/<name>.py``) builds a :class:`ContactQP`; every solver
(``solvers/<name>.py``) receives one; :func:`kkt_residuals` and
:func:`energy_error` judge any ``(u, p)`` the same way whoever produced it.

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
    cells : (n_cells, d + 1) int array
        Simplices (triangles in 2D, tetrahedra in 3D).
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
        ``"a"`` (closest point, (7.12)) or ``"b"`` (fixed direction, (7.13)).
    dropped : int
        Nodes of the constrained surface that found no opposing facet (e.g. beyond
        the opposing body's reach in grazing contact) and carry no constraint.
    """

    nodes: np.ndarray
    mass: np.ndarray
    direction: np.ndarray
    facets: np.ndarray
    opposing_facets: np.ndarray
    search: str = "b"
    dropped: int = 0


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
    """

    prolongations: list = field(default_factory=list)
    rigid_body_modes: np.ndarray | None = None
    body_of_dof: np.ndarray | None = None
    surface: SurfaceHierarchy | None = None


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
    """The reverse rows of the stabilised two-sided nodal constraints (Sect. 7.5).

    A stabilised ContactQP (:func:`problems.fem.stabilised.stabilise`) has the
    nodal constraints of the constrained surface first (``qp.contact`` describes
    them, ``C`` is zero there) and then one row per node of the opposing surface
    that finds the constrained surface along ``-n`` (the penetrations (7.9) of
    Fig. 7.1), penalised by ``C_ii = h_i^(2 alpha) / (k m_i)`` ((7.10)/(7.11)).

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
    alpha : float
        Exponent of ``h`` in (7.10).
    modulus : float
        ``k`` (force per area times length^(2 alpha - 1)).
    """

    nodes: np.ndarray
    mass: np.ndarray
    size: np.ndarray
    transfer: sp.spmatrix
    alpha: float
    modulus: float

    @property
    def n_rows(self) -> int:
        return len(self.nodes)


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
    stabilisation : Stabilisation, optional
        Set when the last ``stabilisation.n_rows`` rows of ``B`` are the reverse rows
        of Sect. 7.5; ``contact`` and ``multilevel.surface`` describe the first
        ``m_contact`` rows.
    name : str
        Scene and level, for reports.
    units : str
        Units of length and force, e.g. ``"dimensionless"`` or ``"m, N"``.
    level : int
        Refinement level the scene built it at.
    cache : dict
        Derived, solver-independent data computed on demand (e.g. the linear
        solver the verification's duality gap uses); not part of the problem.
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
    name: str = ""
    units: str = "dimensionless"
    level: int = 0
    cache: dict = field(default_factory=dict, repr=False, compare=False)

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
        """Rows of the constrained surface (all rows unless stabilised, Sect. 7.5)."""
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
            if self.C is None or np.any(self.C.diagonal()[m - r:] <= 0):
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


def surface_multipliers(qp: ContactQP, p: np.ndarray) -> np.ndarray:
    """The multipliers acting on the constrained surface's rows (``qp.m_contact`` of them).

    ``p`` itself without a stabilisation; with one (Sect. 7.5) the reverse rows'
    multipliers are spread onto the constrained nodes of the facet each one hits,
    ``p_c + T' p_r`` (``T = stabilisation.transfer``): the total force on the
    constrained surface. The pressure is this over ``contact.mass`` (Sect. 8.6).
    """
    p = np.asarray(p, dtype=float)
    if qp.stabilisation is None:
        return p
    mc = qp.m_contact
    return p[:mc] + qp.stabilisation.transfer.T @ p[mc:]


def slack_form(qp: ContactQP) -> ContactQP:
    """The equivalent QP without ``C``, for solvers that take ``Bu <= g`` only (Sect. 7.5).

    With ``C = diag(c)`` (``c_i >= 0``) and one slack ``s_i`` per row with ``c_i > 0``::

        min 1/2 u'Au - f'u + 1/2 s' diag(1/c) s   s.t.  B_h u <= g_h,  B_s u - s <= g_s

    has the same ``u`` and the same multipliers (stationarity in ``s`` gives
    ``s = c p``, so ``B_s u - c p <= g_s``): ``min_s`` of the slack term is the
    penalty ``1/2 (B_s u - g_s)_+^2 / c`` of (7.10). The unknowns are ``(u, s)``;
    ``u = x[:qp.n]``. Mesh and contact data are kept for output; the multilevel data
    are dropped (the slack unknowns are on no mesh).
    """
    if qp.C is None:
        return qp
    c = qp.C.diagonal()
    if abs(qp.C - sp.diags(c)).max() > 0 or np.any(c < 0):
        raise QPValidationError("slack_form needs a diagonal C >= 0")
    soft = np.flatnonzero(c > 0)
    k = soft.size
    A = sp.block_diag([qp.A, sp.diags(1.0 / c[soft])], format="csr")
    S = sp.csr_matrix((-np.ones(k), (soft, np.arange(k))), shape=(qp.m, k))
    return ContactQP(A=A, f=np.concatenate([qp.f, np.zeros(k)]), B=sp.hstack([qp.B, S]).tocsr(),
                     g=qp.g, dim=qp.dim, name=qp.name + " (slack form)", units=qp.units,
                     level=qp.level)


@dataclass
class KKTResiduals:
    """The four KKT residuals, scaled to be comparable across meshes and units.

    ``stationarity = ||Au + B'p - f||_inf / max(||f||_inf, ||Au||_inf, ||B'p||_inf)``,
    ``primal = max(Bu - Cp - g)_+ / max(||Bu||_inf, ||g||_inf)``,
    ``dual = max(-p)_+ / ||p||_inf``,
    ``complementarity = sum_i |p_i (g - Bu + Cp)_i| / (||p||_1 max(||Bu||_inf, ||g||_inf))``
    (entrywise, so that violations of opposite sign cannot cancel).
    Every denominator is floored at the tiny number ``1e-300``; ``raw`` holds the
    unscaled values.
    """

    stationarity: float
    primal: float
    dual: float
    complementarity: float
    raw: dict = field(default_factory=dict)

    @property
    def max(self) -> float:
        return max(self.stationarity, self.primal, self.dual, self.complementarity)

    def as_dict(self, prefix: str = "kkt_") -> dict:
        return {f"{prefix}stationarity": self.stationarity, f"{prefix}primal": self.primal,
                f"{prefix}dual": self.dual, f"{prefix}complementarity": self.complementarity}


def kkt_residuals(qp: ContactQP, u: np.ndarray, p: np.ndarray) -> KKTResiduals:
    """Verified KKT residuals of ``(u, p)`` for ``qp`` (same formula for every solver)."""
    tiny = 1e-300
    u = np.asarray(u, dtype=float)
    p = np.asarray(p, dtype=float)
    Au = qp.A @ u
    Btp = qp.B.T @ p
    Bu = qp.B @ u
    slack = qp.g - Bu + (qp.C @ p if qp.C is not None else 0.0)
    inf = lambda v: float(np.max(np.abs(v))) if np.size(v) else 0.0
    r_stat = inf(Au + Btp - qp.f)
    r_primal = max(0.0, float(np.max(-slack))) if slack.size else 0.0  # 0.0 first: never -0.0
    r_dual = max(0.0, float(np.max(-p))) if p.size else 0.0
    r_comp = float(np.sum(np.abs(p * slack)))
    disp_scale = max(inf(Bu), inf(qp.g), tiny)
    return KKTResiduals(
        stationarity=r_stat / max(inf(qp.f), inf(Au), inf(Btp), tiny),
        primal=r_primal / disp_scale,
        dual=r_dual / max(inf(p), tiny),
        complementarity=r_comp / max(float(np.sum(np.abs(p))) * disp_scale, tiny),
        raw={"stationarity": r_stat, "primal": r_primal, "dual": r_dual, "complementarity": r_comp},
    )


def energy_error(qp: ContactQP, u: np.ndarray, u_ref: np.ndarray) -> float:
    """Relative energy-norm error ``||u - u_ref||_A / ||u_ref||_A``.

    ``inf`` for a non-finite or mis-shaped ``u``; the absolute error if
    ``u_ref`` is zero.
    """
    u = np.asarray(u, dtype=float)
    if u.shape != (qp.n,) or not np.all(np.isfinite(u)):
        return float("inf")
    e = u - u_ref
    ref = float(u_ref @ (qp.A @ u_ref))
    err = max(float(e @ (qp.A @ e)), 0.0)
    return float(np.sqrt(err / ref)) if ref > 0 else float(np.sqrt(err))


@dataclass
class DualityGap:
    """A certified bound on the energy error of ``u`` by weak duality.

    For a feasible ``u_f`` (``B u_f <= g``) and any ``p~ >= 0`` the duality gap with
    the exact dual function ``q(p~) = min_v L(v, p~)`` bounds the energy error:
    ``J(u_f) - q(p~) >= J(u_f) - J(u*) >= 1/2 ||u_f - u*||_A^2``, so
    ``||u - u*||_A <= ||u - u_f||_A + sqrt(2 gap)``. :func:`duality_gap` tries a few
    pairs ``(u_f, p~)`` built from the solver's ``(u, p)`` and keeps the smallest
    bound (each is valid).

    Attributes
    ----------
    gap : float
        The duality gap of the best pair (>= 0 up to round-off).
    relative_gap : float
        ``gap / |J(u_f)|``: dimensionless.
    shift : float
        ``||u - u_f||_A``: the correction making ``u`` feasible.
    energy_bound : float
        Certified ``||u - u*||_A <= shift + sqrt(2 gap)``.
    relative_energy_bound : float
        ``energy_bound / (||u_f||_A - sqrt(2 gap))``: a certified bound on the
        relative energy error ``||u - u*||_A / ||u*||_A`` (inf if not positive).
    floor : float
        The bound's floating-point floor (relative): the gap is a sum of terms
        known to about machine precision, so bounds below ``~sqrt(eps)`` cannot be
        certified.
    pair_gap : float
        The relative gap of the solver's own pair ``(u_f, p)``: with its
        multipliers as they are (their complementarity and S-norm error,
        ``1/2 ||p - p*||_S^2 <= gap``).
    certified : bool
        False if no feasible ``u_f`` was found (then the bounds are inf).
    """

    gap: float
    relative_gap: float
    shift: float
    energy_bound: float
    relative_energy_bound: float
    floor: float
    pair_gap: float
    certified: bool

    def as_dict(self) -> dict:
        return {"energy_bound": self.relative_energy_bound, "energy_bound_floor": self.floor,
                "relative_gap": self.relative_gap, "pair_gap": self.pair_gap,
                "feasibility_shift": self.shift, "certified": self.certified}

    def meets(self, tol: float) -> bool:
        """The certified relative energy bound is <= ``tol`` (or at its floor)."""
        return self.certified and self.relative_energy_bound <= max(tol, 4.0 * self.floor)


def _pivots(qp: ContactQP, B: sp.csr_matrix) -> tuple[np.ndarray, np.ndarray]:
    """One unknown per row of ``B`` (the constrained surface's rows of ``qp``) to move it
    with: the constrained node's component along the row's direction if free (a
    contact code would move the constrained surface), else the row's largest entry.
    Returns ``(pivot, coefficient)``."""
    pivot = np.asarray(abs(B).argmax(axis=1)).ravel()
    if qp.contact is not None and qp.free_dofs is not None and qp.u_fixed is not None:
        pos = -np.ones(len(qp.u_fixed), dtype=np.int64)
        pos[qp.free_dofs] = np.arange(qp.n)
        comp = np.abs(qp.contact.direction).argmax(axis=1)
        own = pos[qp.contact.nodes * qp.dim + comp]
        pivot = np.where(own >= 0, own, pivot)
    return pivot, np.asarray(B[np.arange(B.shape[0]), pivot]).ravel()


def feasible_point(qp: ContactQP, u: np.ndarray, tight: np.ndarray | None = None,
                   sweeps: int = 3) -> tuple[np.ndarray, bool]:
    """``u_f = u + delta`` with ``B u_f <= g``, and ``B u_f = g`` on the rows ``tight``,
    on the constrained surface's rows (the first ``qp.m_contact``; a stabilised
    problem's reverse rows are penalised, not hard).

    Each violated (or, in ``tight``, slack) row is moved on its pivot unknown
    (:func:`_pivots`); rows sharing unknowns interact, so up to ``sweeps``
    passes. Returns ``(u_f, feasible)``.
    """
    u_f = np.array(u, dtype=float)
    mc = qp.m_contact
    if mc == 0:
        return u_f, True
    B, g = qp.B.tocsr()[:mc], qp.g[:mc]
    pivot, coef = _pivots(qp, B)
    tight = np.zeros(mc, dtype=bool) if tight is None else np.asarray(tight, dtype=bool)
    scale = max(float(np.max(np.abs(B @ u_f))), float(np.max(np.abs(g))), 1e-300)
    for _ in range(sweeps):
        res = B @ u_f - g
        move = (res > 0) | (tight & (res < 0))
        if not move.any():
            break
        np.subtract.at(u_f, pivot[move], res[move] / coef[move])
    return u_f, bool(np.all(B @ u_f - g <= 1e-14 * scale))


def duality_gap(qp: ContactQP, u: np.ndarray, p: np.ndarray,
                solve_A: Callable[..., np.ndarray],
                target: float | None = None) -> DualityGap:
    """The certified energy-error bound of ``u`` (:class:`DualityGap`).

    ``solve_A(r, guess=x0)`` returns ``A^{-1} r`` (the bound is certified up to that
    solve's accuracy, which the caller drives far below the gap); ``x0``, the feasible
    point of the pair (close to ``A^{-1} r`` for a good pair), is where an iterative
    solve may start: it changes the cost, not the accuracy asked for. For a pair
    ``(u_f, p~)`` with ``x = A^{-1}(f - B'p~)`` the gap is a sum of non-negative
    terms, computed without cancellation::

        J(u_f) - q(p~) = 1/2 ||u_f - x||_A^2 + p~'(g - B u_f)

    Pairs tried: the solver's ``(u, p_+)`` made feasible; and, for thresholds
    ``theta`` in (1e-8, 1e-4), ``u`` made feasible and tight on the rows with
    ``p > theta max p`` with ``p~`` = ``p`` there and 0 elsewhere (a solver's
    complementarity error would otherwise dominate the bound of its ``u``).
    Each pair costs one linear solve; with ``target`` the search stops at the
    first pair whose bound meets it. With a stabilisation block ``C`` (Sect. 7.5;
    diagonal, zero on the hard rows, which come first) the primal function is
    ``P(u) = J(u) + 1/2 v'C^{-1}v``, ``v = (Bu - g)_+`` on the rows with ``C > 0``;
    ``u`` is made feasible on the hard rows only:
    ``P(u) - q(p) = 1/2 ||u - x||_A^2 + p'(g - Bu) + 1/2 p'Cp + 1/2 v'C^{-1}v``.
    """
    eps = np.finfo(float).eps
    u = np.asarray(u, dtype=float)
    p_plus = np.maximum(np.asarray(p, dtype=float), 0.0)
    inf = float("inf")

    def pair(u_f, p_t, extra=0.0):
        x = solve_A(qp.f - qp.B.T @ p_t, guess=u_f)
        e = u_f - x
        slack = qp.g - qp.B @ u_f
        gap = 0.5 * float(e @ (qp.A @ e)) + float(p_t @ slack) + extra
        d = u_f - u
        shift = float(np.sqrt(max(d @ (qp.A @ d), 0.0)))
        norm = float(np.sqrt(max(u_f @ (qp.A @ u_f), 0.0)))
        root = np.sqrt(2.0 * max(gap, 0.0))
        noise = 8 * eps * (float(p_t @ (np.abs(qp.g) + abs(qp.B) @ np.abs(u_f))) + norm ** 2
                           + abs(float(qp.f @ u_f)))
        if norm > 0:
            rel = (shift + root) / (norm - root) if norm > root else inf
            floor = np.sqrt(2 * noise) / norm
        else:            # u_f = 0: certified exactly if the bound is zero (e.g. no load)
            rel, floor = (0.0 if shift + root == 0 else inf), 0.0
        return gap, shift, shift + root, rel, floor, gap / max(abs(qp.energy(u_f)), 1e-300)

    if qp.C is not None:
        c = qp.C.diagonal()
        soft = c > 0
        hard_rows = np.flatnonzero(~soft)
        if (abs(qp.C - sp.diags(c)).max() > 0 or np.any(c < 0)
                or np.any(hard_rows >= qp.m_contact)):
            return DualityGap(inf, inf, 0.0, inf, inf, inf, inf, False)
        u_f, feasible = feasible_point(qp, u) if hard_rows.size else (u, True)
        if not feasible:
            return DualityGap(inf, inf, inf, inf, inf, inf, inf, False)
        v = np.maximum(qp.B @ u_f - qp.g, 0.0)[soft]
        gap, shift, bound, rel, floor, relgap = pair(
            u_f, p_plus, 0.5 * float(p_plus[soft] @ (c[soft] * p_plus[soft]))
            + 0.5 * float(v @ (v / c[soft])))
        return DualityGap(gap, relgap, shift, bound, rel, floor, relgap, True)
    u_f, feasible = feasible_point(qp, u)
    if not feasible:
        return DualityGap(inf, inf, inf, inf, inf, inf, inf, False)
    best = pair(u_f, p_plus)
    pair_gap = best[5]
    top = float(p_plus.max()) if qp.m else 0.0
    for theta in (1e-8, 1e-4):
        if target is not None and best[3] <= max(target, 4.0 * best[4]):
            break
        active = p_plus > theta * top
        if top == 0 or active.all() and theta > 1e-8:
            continue
        u_t, ok = feasible_point(qp, u, tight=active)
        if ok:
            cand = pair(u_t, np.where(active, p_plus, 0.0))
            if cand[3] < best[3]:
                best = cand
    gap, shift, bound, rel, floor, relgap = best
    return DualityGap(gap=float(gap), relative_gap=float(relgap), shift=shift,
                      energy_bound=float(bound), relative_energy_bound=float(rel),
                      floor=float(floor), pair_gap=float(pair_gap), certified=True)


#: A rigid-body mode of one body counts as *floating* when its Rayleigh quotient
#: ``r'Ar / r'r`` is below this fraction of the mean diagonal of ``A`` over that body's
#: unknowns: the body is held in that direction only by weak springs (or not at all).
#: Held modes (a Dirichlet or symmetry condition acts on them) measure >= 1e-4 on the
#: roll stack and >= 3e-5 on every other scene and hard case of the suite (3.5e-3 with a
#: stiffness contrast of 1e4, each body against its own diagonal), the roll stack's
#: floating vertical translation 7e-10: the gap makes the test free of units and E.
FLOATING_THRESHOLD = 1e-6


def floating_modes(qp: ContactQP, threshold: float = FLOATING_THRESHOLD) -> np.ndarray:
    """The near-kernel of ``A``: rigid motions of a body that only weak springs hold.

    A body held only by the contact (the roll stack's work roll, thesis Sect. 9.3:
    "the eigenvalues of the problem may be very small") leaves ``A`` nearly
    singular: its stiffness in those directions is the springs' alone, ~1e-9 of the
    elastic stiffness. A factorisation of ``A`` then returns the huge rigid response
    ``A^{-1} f`` (metres where the answer is ~0.1 mm) and the contact solution is a
    difference of such numbers. Solvers that know these modes treat them exactly
    (:class:`solvers.cholesky.FloatingCholesky`).

    Parameters
    ----------
    qp : ContactQP
        With ``multilevel.rigid_body_modes`` and ``multilevel.body_of_dof``.
    threshold : float
        Largest Rayleigh quotient ``r'Ar / (r'r mean(diag A_bb))`` (dimensionless; ``A_bb``
        the body's block).

    Returns
    -------
    (n, k) array
        Orthonormal columns spanning the floating modes (k = 0: none, or no modes known).
        Cached in ``qp.cache``.
    """
    key = ("floating_modes", threshold)
    if key in qp.cache:
        return qp.cache[key]
    R = qp.multilevel.rigid_body_modes
    found = []
    if R is not None and qp.multilevel.body_of_dof is not None:
        diag = qp.A.diagonal()
        for b in np.unique(qp.multilevel.body_of_dof):
            scale = float(np.mean(diag[qp.multilevel.body_of_dof == b]))   # the body's own
            cols = R[:, np.any(R[qp.multilevel.body_of_dof == b] != 0, axis=0)]
            cols = cols * (qp.multilevel.body_of_dof == b)[:, None]
            if cols.shape[1] == 0:
                continue
            Q, s, _ = np.linalg.svd(cols, full_matrices=False)
            Q = Q[:, s > 1e-10 * s.max()]
            lam, V = np.linalg.eigh(Q.T @ (qp.A @ Q))
            keep = lam < threshold * scale
            found.append(Q @ V[:, keep])
    modes = np.hstack(found) if found else np.zeros((qp.n, 0))
    qp.cache[key] = modes
    return modes
