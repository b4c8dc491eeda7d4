"""The one interface between discrete contact problems and every solver.

Data flow (DESIGN.md): a scene builds a :class:`ContactQP`; any registered
solver turns it into a :class:`SolveResult`; :func:`solve` adds the four
verified KKT residuals (:func:`kkt_residuals`) so that no solver is trusted on
its own word.

Conventions (thesis Ch. 7-8, DESIGN.md)::

    minimise 1/2 u^T A u - f^T u   subject to   B u <= g
    KKT:  A u + B^T p = f,  B u <= g,  p >= 0,  p^T (g - B u) = 0

A solver module under ``solvers/`` defines ``SOLVER = SolverSpec(...)`` whose
``solve(qp, tol, max_iter, time_limit, u0, p0, **options)`` returns a
:class:`SolveResult` with ``claimed_status`` set; :func:`solve` verifies it.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
import scipy.sparse as sp

from problems.spec import Parameter, ParameterError, discover, lookup, resolve_parameters

#: Tolerance presets; each solver maps them to its own options (``SolverSpec.presets``).
TOLERANCES = {"low": 1e-3, "mid": 1e-6, "high": 1e-9}

#: Status values of a :class:`SolveResult`.
STATUSES = ("converged", "inaccurate", "max_iter", "time_limit", "failed")


class QPValidationError(ValueError):
    """A ContactQP failed its consistency checks (the message says which)."""


@dataclass
class ContactQP:
    """The algebraic contact problem ``min 1/2 u'Au - f'u  s.t.  Bu <= g``.

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
        Stabilisation block (Sect. 7.5): the constraint reads ``Bu - Cp <= g``.
        ``None`` (the default everywhere so far) means zero.
    free_dofs : (n,) int array, optional
        Position of each unknown in the full nodal vector ``u_full`` (node-major,
        ``node * dim + component``).
    u_fixed : (N_full,) array, optional
        Full nodal vector with the prescribed (Dirichlet) values, zero elsewhere;
        ``u_full = u_fixed; u_full[free_dofs] = u``.
    dim : int
        Spatial dimension (2 or 3).
    contact_nodes : (m,) int array, optional
        Global node index of the constrained node behind each row of ``B``.
    contact_mass : (m,) array, optional
        Lumped mass of the constrained surface at those nodes: the pressure is
        ``p / contact_mass`` (Sect. 8.6).
    contact_direction : (m, dim) array, optional
        Unit direction ``n`` of each constraint (case b) or the closest-point
        direction (case a).
    geometry : dict
        Anything the output needs (``points``, ``cells``, ``body_of_node``, ...).
    multilevel : dict
        Optional data for multilevel solvers: ``prolongations`` (list of sparse
        matrices, coarse -> fine, on the free DOFs), ``rigid_body_modes`` (n, k),
        ``body_of_dof`` (n,), ``hierarchy`` (coarser ContactQPs).
    name : str
        Scene and level, for reports.
    units : str
        Units of length and force, e.g. ``"dimensionless"`` or ``"m, N"``.
    """

    A: sp.spmatrix
    f: np.ndarray
    B: sp.spmatrix
    g: np.ndarray
    C: sp.spmatrix | None = None
    free_dofs: np.ndarray | None = None
    u_fixed: np.ndarray | None = None
    dim: int = 2
    contact_nodes: np.ndarray | None = None
    contact_mass: np.ndarray | None = None
    contact_direction: np.ndarray | None = None
    geometry: dict = field(default_factory=dict)
    multilevel: dict = field(default_factory=dict)
    name: str = ""
    units: str = "dimensionless"

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
        for name, shape in (("contact_nodes", (m,)), ("contact_mass", (m,)),
                            ("contact_direction", (m, self.dim))):
            val = getattr(self, name)
            if val is not None and np.shape(val) != shape:
                raise QPValidationError(f"{name} must have shape {shape}, got {np.shape(val)}")
        if self.contact_mass is not None and np.any(np.asarray(self.contact_mass) <= 0):
            raise QPValidationError("contact_mass must be positive")
        if self.free_dofs is not None and np.shape(self.free_dofs) != (n,):
            raise QPValidationError(f"free_dofs must have shape ({n},), got {np.shape(self.free_dofs)}")

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


@dataclass
class SolveResult:
    """What every solver returns (DESIGN.md: status, residuals, history, statistics).

    Attributes
    ----------
    u, p : arrays
        Primal solution on the free DOFs and multipliers (``p >= 0``, ``Bu <= g``).
    claimed_status : str
        What the solver itself says: one of ``converged``, ``max_iter``,
        ``time_limit``, ``failed``, or ``inaccurate`` when the solver itself
        knows it stopped short of its tolerance (e.g. Clarabel ``AlmostSolved``).
    status : str
        After verification (:func:`solve`): ``converged`` only if the solver
        claimed it *and* every verified KKT residual is <= tol; a claimed
        convergence that fails verification becomes ``inaccurate``.
    message : str
        Solver's own words (its status string, exception text, ...).
    iterations : int
    setup_time, solve_time : float
        Wall seconds: factorisations/setup vs. the iteration itself.
    history : dict of lists
        Per-iteration records where the solver has them (e.g. ``energy``,
        ``kkt_max``, ``time``).
    stats : dict
        Solver-specific statistics (e.g. ``n_inner_mean``, ``kappa_S``).
    """

    u: np.ndarray
    p: np.ndarray
    claimed_status: str
    message: str = ""
    iterations: int = 0
    setup_time: float = 0.0
    solve_time: float = 0.0
    history: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)
    solver: str = ""
    tol: float = float("nan")
    status: str = ""
    kkt: KKTResiduals | None = None

    @property
    def total_time(self) -> float:
        return self.setup_time + self.solve_time

    def summary(self) -> dict:
        """Flat record for tables (no arrays)."""
        out = {"solver": self.solver, "tol": self.tol, "status": self.status,
               "claimed_status": self.claimed_status, "message": self.message,
               "iterations": self.iterations, "setup_time": self.setup_time,
               "solve_time": self.solve_time, "total_time": self.total_time}
        if self.kkt is not None:
            out.update(self.kkt.as_dict())
            out["kkt_max"] = self.kkt.max
        out.update({k: v for k, v in self.stats.items() if np.isscalar(v)})
        return out


@dataclass(frozen=True)
class SolverSpec:
    """Entry point of one solver module.

    Attributes
    ----------
    name : str
    summary : str
    solve : callable
        ``solve(qp, tol, max_iter, time_limit, u0, p0, **options) -> SolveResult``.
    parameters : tuple[Parameter, ...]
        Solver options (``--set`` on the CLI).
    presets : dict
        For the report: how the presets ``low/mid/high`` map to the solver's own
        options, e.g. ``{"low": "eps_abs=eps_rel=1e-3, polish", ...}``.
    default_max_iter : int
    role : str
        ``"reference"`` (general QP solvers), ``"exact"`` (ground truth) or
        ``"thesis"`` (the augmented projection of Alg. 8.4).
    """

    name: str
    summary: str
    solve: Callable[..., SolveResult]
    parameters: tuple[Parameter, ...] = ()
    presets: dict = field(default_factory=dict)
    default_max_iter: int = 10_000
    role: str = "reference"


def solvers() -> dict[str, SolverSpec]:
    """All registered solvers, ``{name: SolverSpec}``."""
    return discover("solvers", "SOLVER")


def parse_tolerance(tol: Any) -> float:
    """A preset name (``low``/``mid``/``high``) or a number in (0, 1)."""
    if isinstance(tol, str) and tol in TOLERANCES:
        return TOLERANCES[tol]
    try:
        return Parameter("tol", 1e-6, low=0.0, high=1.0, low_open=True, high_open=True).validate(tol)
    except ParameterError:
        raise ParameterError(f"parameter 'tol': {tol!r} is not allowed; allowed: one of "
                             f"{', '.join(TOLERANCES)} or a number in (0, 1)") from None


def solve(qp: ContactQP, solver: str = "pdas", tol: float | str = "mid",
          max_iter: int | None = None, time_limit: float | None = None,
          u0: np.ndarray | None = None, p0: np.ndarray | None = None,
          **options: Any) -> SolveResult:
    """Run a registered solver and verify its answer.

    Parameters
    ----------
    qp : ContactQP
    solver : str
        Registry name (``contactbench list`` shows them).
    tol : float or {"low", "mid", "high"}
        Target for the verified scaled KKT residuals.
    max_iter : int, optional
        Defaults to the solver's own ``default_max_iter``.
    time_limit : float, optional
        Wall seconds; ``None`` means none.
    u0, p0 : arrays, optional
        Initial guess.
    **options
        Solver options, validated against its ``parameters``.

    Returns
    -------
    SolveResult
        With ``kkt`` and the verified ``status`` filled in.
    """
    spec = lookup(solvers(), solver, "solver")
    tol = parse_tolerance(tol)
    if max_iter is None:
        max_iter = spec.default_max_iter
    max_iter = Parameter("max_iter", 1, low=1, kind=int).validate(max_iter)
    if time_limit is not None:
        time_limit = Parameter("time_limit", 1.0, low=0.0, low_open=True).validate(time_limit)
    for name, guess, size in (("u0", u0, qp.n), ("p0", p0, qp.m)):
        if guess is not None and np.shape(guess) != (size,):
            raise ParameterError(f"parameter '{name}': shape {np.shape(guess)} is not allowed; "
                                 f"allowed: ({size},)")
    opts = resolve_parameters(spec.parameters, options, f"solver '{spec.name}'")
    t0 = time.perf_counter()
    try:
        result = spec.solve(qp, tol=tol, max_iter=max_iter, time_limit=time_limit,
                            u0=u0, p0=p0, **opts)
    except (MemoryError, np.linalg.LinAlgError, RuntimeError, ValueError) as err:
        if isinstance(err, ParameterError):
            raise
        elapsed = time.perf_counter() - t0
        result = SolveResult(u=np.zeros(qp.n), p=np.zeros(qp.m), claimed_status="failed",
                             message=f"{type(err).__name__}: {err}", solve_time=elapsed)
    result.solver = spec.name
    result.tol = tol
    return verify(qp, result, tol)


def verify(qp: ContactQP, result: SolveResult, tol: float) -> SolveResult:
    """Fill in ``kkt`` and the verified ``status`` (qpbenchmark's rule)."""
    if result.claimed_status not in STATUSES:
        raise ValueError(f"solver returned unknown status {result.claimed_status!r}")
    u_ok = np.shape(result.u) == (qp.n,) and np.all(np.isfinite(result.u))
    p_ok = np.shape(result.p) == (qp.m,) and np.all(np.isfinite(result.p))
    if not (u_ok and p_ok):
        result.kkt = KKTResiduals(*([float("inf")] * 4))
        result.status = "failed"
        result.message = (result.message + "; " if result.message else "") + "non-finite or mis-shaped result"
        return result
    result.kkt = kkt_residuals(qp, result.u, result.p)
    if result.claimed_status == "converged":
        result.status = "converged" if result.kkt.max <= tol else "inaccurate"
    else:
        result.status = result.claimed_status
    return result
