"""The one interface between discrete contact problems and every solver.

Data flow (DESIGN.md): a scene builds a :class:`problems.qp.ContactQP`; any
registered solver turns it into a :class:`SolveResult`; :func:`solve` adds the
four verified KKT residuals (:func:`problems.qp.kkt_residuals`) so that no
solver is trusted on its own word.

A solver module under ``solvers/`` defines ``SOLVER = SolverSpec(...)``. Its
options are declared once, as the spec's ``parameters``; its
``solve(qp, tol, max_iter, time_limit, u0, p0, opts)`` receives them resolved
(defaults filled in, validated) as one :class:`problems.spec.Options` mapping
and returns a :class:`SolveResult` with ``claimed_status`` set; :func:`solve`
verifies it.
"""
from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from problems.qp import (ContactQP, DualityGap, KKTResiduals, duality_gap, kkt_residuals,
                        slack_form)
from problems.spec import (Options, Parameter, ParameterError, discover, lookup,
                           resolve_parameters)

#: Tolerance presets; each solver maps them to its own options (``SolverSpec.presets``).
TOLERANCES = {"low": 1e-3, "mid": 1e-6, "high": 1e-9}

#: Status values of a :class:`SolveResult`.
STATUSES = ("converged", "inaccurate", "max_iter", "time_limit", "failed")


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
        After verification (:func:`verify`): ``converged`` only if the solver
        claimed it *and* every verified KKT residual is <= tol *and* the
        certified duality gap is (relative gap <= tol); a claimed convergence
        that fails verification becomes ``inaccurate``.
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
    gap: DualityGap | None = None
    options: dict = field(default_factory=dict)

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
        if self.gap is not None:
            out.update(self.gap.as_dict())
        # solver statistics never overwrite the common columns above
        out.update({k: v for k, v in self.stats.items() if np.isscalar(v) and k not in out})
        return out


@dataclass(frozen=True)
class SolverSpec:
    """Entry point of one solver module.

    Attributes
    ----------
    name : str
    summary : str
    solve : callable
        ``solve(qp, tol, max_iter, time_limit, u0, p0, opts) -> SolveResult`` with
        ``opts`` the resolved :class:`problems.spec.Options`.
    parameters : tuple
        Solver options, declared here once (``Parameter`` or
        ``ComponentParameter``; ``--set`` on the CLI).
    presets : dict
        For the report: how the presets ``low/mid/high`` map to the solver's own
        options, e.g. ``{"low": "eps_abs=eps_rel=1e-3, polish", ...}``.
    default_max_iter : int
    role : str
        ``"reference"`` (general QP solvers), ``"exact"`` (ground truth) or
        ``"thesis"`` (the augmented projection of Alg. 8.4).
    handles_C : bool
        The solver takes a stabilisation block ``C`` (Sect. 7.5) as it is; for the
        others :func:`solve` hands over the equivalent slack form
        (:func:`problems.qp.slack_form`) and maps the answer back.
    """

    name: str
    summary: str
    solve: Callable[..., SolveResult]
    parameters: tuple[Parameter, ...] = ()
    presets: dict = field(default_factory=dict)
    default_max_iter: int = 10_000
    role: str = "reference"
    handles_C: bool = False

    def options(self, **given: Any) -> Options:
        """The resolved options: defaults overridden by ``given``, validated."""
        return resolve_parameters(self.parameters, given, f"solver '{self.name}'")


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
    opts = spec.options(**options)
    target = qp
    if qp.C is not None and not spec.handles_C:      # Sect. 7.5 through slack variables
        target = slack_form(qp)
        if u0 is not None:
            soft = qp.C.diagonal() > 0
            u0 = np.concatenate([u0, (qp.B @ u0 - qp.g)[soft]])
    t0 = time.perf_counter()
    try:
        result = spec.solve(target, tol, max_iter, time_limit, u0, p0, opts)
        if target is not qp:
            result.u = np.asarray(result.u)[:qp.n]
            result.message = (result.message + "; " if result.message else "") + "slack form"
    except (MemoryError, np.linalg.LinAlgError, RuntimeError, ValueError) as err:
        if isinstance(err, ParameterError):
            raise
        elapsed = time.perf_counter() - t0
        result = SolveResult(u=np.zeros(qp.n), p=np.zeros(qp.m), claimed_status="failed",
                             message=f"{type(err).__name__}: {err}", solve_time=elapsed)
    result.solver = spec.name
    result.tol = tol
    result.options = opts.flat()
    return verify(qp, result, tol)


#: Largest number of unknowns for which :func:`linear_solver` factorises A (per dimension);
#: beyond, multigrid-preconditioned CG.
DIRECT_LINEAR_LIMIT = {2: 2_500_000, 3: 150_000}


def linear_solver(qp: ContactQP) -> Callable[..., np.ndarray]:
    """``(r, guess=None) -> A^{-1} r`` for the verification's duality gap, built once
    per problem (``qp.cache``).

    A sparse Cholesky of ``A`` (:func:`solvers.cholesky.factorize`) up to
    :data:`DIRECT_LINEAR_LIMIT` or where a solver has factorised it already (with the
    floating bodies' near-kernel removed, :class:`solvers.cholesky.FloatingCholesky`: a
    multigrid PCG on such a nearly singular ``A`` needs thousands of steps); else CG
    preconditioned by one V-cycle (geometric multigrid on the problem's hierarchy, pyamg
    SA without one) to a residual of 1e-14 ||r||, started from ``guess`` (the direct
    route ignores it): a guess close to the solution saves steps, never accuracy.
    """
    if "linear_solver" in qp.cache:
        return qp.cache["linear_solver"]
    import scipy.sparse.linalg as spla

    if qp.n <= DIRECT_LINEAR_LIMIT.get(qp.dim, 0) or "floating_cholesky" in qp.cache:
        from problems.qp import floating_modes
        from solvers.cholesky import factorize, shared_floating_factor
        modes = floating_modes(qp)
        # a body held only by weak springs: its rigid part solved apart (no 1/spring-sized
        # intermediate results; see FloatingCholesky)
        chol = shared_floating_factor(qp, modes) if modes.shape[1] else factorize(qp.A)

        def solve_A(r, guess=None):
            x = chol.solve(r)
            return x + chol.solve(r - qp.A @ x)        # one step of iterative refinement
    else:
        from solvers import preconditioners as pc
        from solvers.augmented_projection import SOLVER as AP
        vc = pc.component_vcycle(qp, AP.options().ahat)
        M = spla.LinearOperator(qp.A.shape, matvec=vc.raw)

        def solve_A(r, guess=None):
            x, info = spla.cg(qp.A, r, x0=guess, M=M, rtol=1e-14, atol=0.0, maxiter=3000)
            if info != 0:
                raise RuntimeError("multigrid PCG for the duality gap did not converge")
            return x
    qp.cache["linear_solver"] = solve_A
    return solve_A


def certify(qp: ContactQP, u: np.ndarray, p: np.ndarray, tol: float | None = None) -> DualityGap:
    """The certified bound of ``(u, p)`` (one to three linear solves with A; with
    ``tol``, as few as meet it).

    The last certificate is kept in ``qp.cache`` under the digest of ``(u, p, tol)``:
    a solver that certifies its own stop and :func:`verify` after it pay for one.
    """
    u, p = np.ascontiguousarray(u, dtype=float), np.ascontiguousarray(p, dtype=float)
    key = hashlib.blake2b(u.tobytes() + p.tobytes() + repr(tol).encode(),
                          digest_size=16).digest()
    last = qp.cache.get("certificate")
    if last is not None and last[0] == key:
        return last[1]
    gap = duality_gap(qp, u, p, linear_solver(qp), target=tol)
    qp.cache["certificate"] = (key, gap)
    return gap


def verify(qp: ContactQP, result: SolveResult, tol: float) -> SolveResult:
    """Fill in ``kkt``, ``gap`` and the verified ``status``.

    qpbenchmark's rule, strengthened: ``converged`` only if the solver claims it,
    every scaled KKT residual is <= ``tol`` and the certified bound on the relative
    energy error (from the duality gap, :func:`problems.qp.duality_gap`) is <=
    ``tol`` (or at the bound's floating-point floor, ~1e-8: below it the KKT
    residuals decide). A scaled residual alone can pass a wrong answer when A is
    ill-conditioned; the certified bound cannot.
    """
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
    from solvers.cholesky import FactorizationError
    try:
        result.gap = certify(qp, result.u, result.p, tol)
    except FactorizationError as err:          # A not positive definite: no certificate
        inf = float("inf")
        result.gap = DualityGap(inf, inf, inf, inf, inf, inf, inf, False)
        result.message = (result.message + "; " if result.message else "") + (
            f"no certificate: {err}")
    if result.claimed_status == "converged":
        accurate = result.kkt.max <= tol and result.gap.meets(tol)
        result.status = "converged" if accurate else "inaccurate"
    else:
        result.status = result.claimed_status
    return result


#: Largest number of unknowns for which the exact reference factorises ``A`` (PDAS through
#: the dual problem on the contact rows), per dimension. Measured with one thread: 2D
#: level 4 (523k unknowns) factorises in ~3 s; in 3D, 104k unknowns take ~7 s and
#: 1 GB, 346k ~90 s and 4-5 GB (nested-dissection fill grows like N^(4/3) in 3D), where
#: the iterative reference takes ~9 s.
DIRECT_REFERENCE_LIMIT = {2: 2_500_000, 3: 150_000}


def reference_solve(qp: ContactQP, tol: float = 1e-10,
                    time_limit: float | None = None) -> SolveResult:
    """The suite's reference solution of ``qp`` (DESIGN.md, performance conventions).

    The exact PDAS (``A`` factorised once, the dual problem on the contact rows solved
    by active sets; :mod:`solvers.pdas`) where a factorisation is affordable
    (:data:`DIRECT_REFERENCE_LIMIT`); otherwise an iterative solve to verified KKT
    residuals ``<= tol``: the augmented projection with face-CG acceleration. The
    result's ``solver`` says which; its ``status`` is verified against ``tol`` either way.
    """
    from solvers.pdas import SCHUR_MAX_M

    if qp.n <= DIRECT_REFERENCE_LIMIT.get(qp.dim, 0) and qp.m <= SCHUR_MAX_M:
        return solve(qp, "pdas", tol=tol, time_limit=time_limit, method="schur")
    return solve(qp, "augmented_projection", tol=tol, time_limit=time_limit, max_iter=5000,
                 accelerate="face_cg")
