"""The types every solver shares: the result, the spec of a solver module, the statuses
and the tolerance presets (DESIGN.md: one interface for all solvers).

A solver module under ``solvers/`` defines ``SOLVER = SolverSpec(...)``. Its options
are declared once, as the spec's ``parameters``; its
``solve(qp, tol, max_iter, time_limit, u0, p0, opts)`` receives them resolved (defaults
filled in, validated) as one :class:`problems.spec.Options` mapping and returns a
:class:`SolveResult` with ``claimed_status`` set; :func:`solvers.interface.solve`
verifies it (:func:`solvers.certificate.verify`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from problems.kkt import KKTResiduals
from problems.spec import Options, Parameter, ParameterError, resolve_parameters

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
    gap: Any = None   # solvers.certificate.DualityGap
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
        (:func:`problems.slack.slack_form`) and maps the answer back.
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



def parse_tolerance(tol: Any) -> float:
    """A preset name (``low``/``mid``/``high``) or a number in (0, 1)."""
    if isinstance(tol, str) and tol in TOLERANCES:
        return TOLERANCES[tol]
    try:
        return Parameter("tol", 1e-6, low=0.0, high=1.0, low_open=True, high_open=True).validate(tol)
    except ParameterError:
        raise ParameterError(f"parameter 'tol': {tol!r} is not allowed; allowed: one of "
                             f"{', '.join(TOLERANCES)} or a number in (0, 1)") from None
