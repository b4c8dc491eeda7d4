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
from enum import StrEnum
from typing import Any, Callable

import numpy as np

from problems.kkt import KKTResiduals
from problems.spec import Options, Parameter, ParameterError, resolve_parameters

#: Tolerance presets; each solver maps them to its own options (``SolverSpec.presets``).
TOLERANCES = {"low": 1e-3, "mid": 1e-6, "high": 1e-9}


def preset_texts(stop: str) -> dict[str, str]:
    """``{preset: "<stop> <tolerance>"}`` for every preset of :data:`TOLERANCES`: the
    report's text of a solver whose stopping rule is the preset's tolerance itself."""
    return {name: f"{stop} {tol:.0e}".replace("e-0", "e-") for name, tol in TOLERANCES.items()}


#: The presets of a solver that stops on the suite's verification (semismooth Newton, TNNMG).
VERIFIED_PRESETS = preset_texts("stop when verified: KKT and certified energy bound <=")

#: Status values of a :class:`SolveResult`. ``skipped``: the solver declared at once that it
#: cannot take the problem (:meth:`SolverSpec.check`); the message says why.
STATUSES = ("converged", "inaccurate", "max_iter", "time_limit", "failed", "skipped")

#: ``stats["friction"]`` of an answer that solved a Coulomb step itself, monolithically
#: (``s = mu p`` of its own ``p`` inside its iteration), instead of the Tresca step of the
#: given ``slip_bound``: the verification judges it as the Tresca step of its own bound
#: ``mu p`` (:func:`solvers.certificate.verify`).
COULOMB_MONOLITHIC = "coulomb_monolithic"

#: The note a solver appends to its message when it was given an initial guess
#: (``u0``, ``p0``) and did not start from it (:func:`guess_not_used`); a run table reads
#: it as "ignores the guess" (``workflows.studies.test_set.run``).
GUESS_NOT_USED = "initial guess not used"


def guess_not_used(message: str, by: str) -> str:
    """``message`` with the note that the initial guess was not used ``by`` (the library,
    the method and why): :data:`GUESS_NOT_USED` after a semicolon."""
    return (message + "; " if message else "") + f"{GUESS_NOT_USED} by {by}"

#: The rules of a solver's answer, checked by :func:`contract_violation` before anything
#: uses it: ``{rule: what the solver must deliver}``. A broken rule makes the row
#: ``failed`` with ``failed_check = "contract:<rule>"``. A solver that stops without an
#: answer (any claim but ``converged``) may return NaN in ``u`` or ``p``: that row is
#: ``failed`` with ``failed_check = "no_answer"``.
CONTRACT = {
    "type": "solve(...) returns a solvers.base.SolveResult",
    "status": "claimed_status is one of " + ", ".join(STATUSES),
    "u_shape": "u is a 1-D float array of length qp.n",
    "u_finite": "every entry of u is finite when the solver claims converged",
    "p_shape": "p is a 1-D float array of length qp.m",
    "p_finite": "every entry of p is finite when the solver claims converged",
    "message": "message is a str",
    "iterations": "iterations is an int >= 0",
    "times": "setup_time and solve_time are finite numbers >= 0",
    "records": "history and stats are dicts",
    "tangential": "on a frictional problem (qp.friction), tangential is a 1-D float array of "
                  "length qp.m (the tangential multipliers)",
    "tangential_finite": "every entry of tangential is finite when the solver claims converged",
}


class Role(StrEnum):
    """What a solver is in the comparison (a string, so ``role == "exact"`` works)."""

    #: ground truth: an exact method (the PDAS with a factorised A)
    EXACT = "exact"
    #: the thesis's own solver (Alg. 8.4)
    THESIS = "thesis"
    #: a contact-mechanics method (semismooth Newton, TNNMG)
    NEWTON = "newton"
    #: a general QP library (OSQP, Clarabel, ...)
    LIBRARY = "library"
    #: anything else, e.g. a solver of another package (entry point contactbench.solvers)
    OTHER = "other"


@dataclass
class SolveResult:
    """What every solver returns (DESIGN.md: status, residuals, history, statistics).

    Attributes
    ----------
    u, p : arrays
        Primal solution on the free DOFs and multipliers (``p >= 0``, ``Bu <= g``).
    claimed_status : str
        What the solver itself says: one of ``converged``, ``max_iter``,
        ``time_limit``, ``failed``, ``inaccurate`` when the solver itself
        knows it stopped short of its tolerance (e.g. Clarabel ``AlmostSolved``), or
        ``skipped`` when it cannot take the problem (:meth:`SolverSpec.check`).
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
    failed_check : str
        Filled in by the suite: why the verified status is not ``converged`` (empty if it
        is, or ``skipped``). ``contract:<rule>`` (the answer broke a rule of
        :data:`CONTRACT`), ``exception`` (the solver raised), ``process`` (its process
        died), ``hard_time_limit`` (killed past the hard wall-clock limit), ``claimed``
        (the solver itself claimed ``max_iter``, ``time_limit``, ``inaccurate`` or
        ``failed``), ``no_answer`` (it stopped short with non-finite ``u`` or ``p``),
        or, for a claimed convergence the verification did not confirm, the
        checks above ``tol`` joined by commas: ``kkt_stationarity``, ``kkt_primal``,
        ``kkt_dual``, ``kkt_complementarity``, on a frictional problem also ``kkt_bound``
        (``|lam_i| <= s_i``) and ``kkt_slip_complementarity``
        (``lam_i slip_i = s_i |slip_i|``), then ``energy_bound`` (or ``no_certificate``).
    traceback : str
        The traceback of an exception the solver raised (empty otherwise): kept with the
        row, never in its table columns.
    tangential : array or None
        On a frictional problem (``qp.friction``), the tangential multipliers (forces) of
        the constrained rows, ``|tangential_i| <= s_i``; ``None`` on a frictionless one.
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
    failed_check: str = ""
    traceback: str = ""
    tangential: np.ndarray | None = None

    @classmethod
    def without_answer(cls, n: int, m: int, solver: str, tol: float, status: str,
                       message: str, elapsed: float = 0.0, failed_check: str = "",
                       claimed_status: str | None = None,
                       traceback: str = "") -> "SolveResult":
        """A run that produced no answer (``skipped``, a broken contract, an exception, or
        killed / crashed in isolation): zeros for ``u`` and ``p``, no ``kkt``, the status
        already final (nothing to verify)."""
        res = cls(u=np.zeros(n), p=np.zeros(m),
                  claimed_status=status if claimed_status is None else claimed_status,
                  message=message, solve_time=elapsed, solver=solver, tol=tol,
                  failed_check=failed_check, traceback=traceback)
        res.status = status
        return res

    @property
    def total_time(self) -> float:
        return self.setup_time + self.solve_time

    def summary(self) -> dict:
        """Flat record for tables (no arrays)."""
        out = {"solver": self.solver, "tol": self.tol, "status": self.status,
               "claimed_status": self.claimed_status, "failed_check": self.failed_check,
               "message": self.message,
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
    role : Role
        What the solver is in the comparison (a :class:`Role` or its value).
    handles_C : bool
        The solver takes a stabilisation block ``C`` (Sect. 7.5) as it is; for the
        others :func:`solvers.interface.solve` hands over the equivalent slack form
        (:func:`problems.slack.slack_form`) and maps the answer back.
    supports : callable, optional
        ``supports(qp) -> (ok, reason)``, benchopt's ``skip``: called on the problem the
        solver would receive; ``(False, reason)`` makes the run ``skipped`` at once with
        that reason (a floating body, a size beyond a dense method, ...). It must be
        cheap (well under a second).
    handles_friction : bool
        The solver takes a ContactQP with friction (``qp.friction``, Tresca or Coulomb);
        every other solver refuses such a problem at once (``skipped``, with the reason)
        rather than solve it frictionless.
    friction_reason : str
        Why a solver without ``handles_friction`` does not take friction, added to its
        skip message (empty: it solves the frictionless problem only, nothing more).
    facets_reason : str
        Empty: a solver that handles friction takes the faceted law too
        (``friction.facets`` = k, :class:`problems.friction.data.Friction`); else why it does not,
        and it skips a faceted problem at once with this reason rather than solve the
        isotropic law.
    size_limit : str or dict, optional
        Name of an integer option in ``parameters`` that bounds the problem's unknowns
        ``qp.n``: a larger problem is ``skipped`` at once, the option's help giving the
        reason (a method whose cost grows too fast to finish in a study's time limit).
        Setting the option higher runs the solver anyway. A dict ``{dim: name}`` gives
        one option per spatial dimension (a sparse factor fills in faster in 3D than in
        2D); a dimension it leaves out has no bound.
    """

    name: str
    summary: str
    solve: Callable[..., SolveResult]
    parameters: tuple[Parameter, ...] = ()
    presets: dict = field(default_factory=dict)
    default_max_iter: int = 10_000
    role: Role = Role.OTHER
    handles_C: bool = False
    supports: Callable[[Any], tuple[bool, str]] | None = None
    handles_friction: bool = False
    friction_reason: str = ""
    facets_reason: str = ""
    size_limit: str | dict | None = None

    def __post_init__(self):
        try:
            object.__setattr__(self, "role", Role(self.role))
        except ValueError:
            raise ValueError(f"solver {self.name!r}: role {self.role!r} is not allowed; allowed: "
                             f"{', '.join(r.value for r in Role)}") from None
        named = {getattr(p, "name", None) for p in self.parameters}
        missing = [n for n in self.size_limit_names().values() if n not in named]
        if missing:
            raise ValueError(f"solver {self.name!r}: size_limit {missing[0]!r} is not one "
                             "of its parameters")

    def size_limit_names(self) -> dict:
        """``{dim: option name}`` of ``size_limit`` (key ``None``: every dimension)."""
        if self.size_limit is None:
            return {}
        if isinstance(self.size_limit, dict):
            return dict(self.size_limit)
        return {None: self.size_limit}

    def size_limit_name(self, dim: int) -> str | None:
        """The option that bounds the unknowns of a ``dim``-dimensional problem, if any."""
        names = self.size_limit_names()
        return names.get(dim, names.get(None))

    @property
    def size_parameters(self) -> dict:
        """``{dim: Parameter}`` of ``size_limit`` (their defaults and help, the reasons)."""
        by_name = {getattr(p, "name", None): p for p in self.parameters}
        return {dim: by_name[n] for dim, n in self.size_limit_names().items()}

    @property
    def size_parameter(self) -> Parameter | None:
        """The option named by a single ``size_limit`` (its default and help, the reason)."""
        return self.size_parameters.get(None)

    def options(self, **given: Any) -> Options:
        """The resolved options: defaults overridden by ``given``, validated."""
        return resolve_parameters(self.parameters, given, f"solver '{self.name}'")

    def check(self, qp, opts: Options | None = None) -> tuple[bool, str]:
        """``(True, "")`` if the solver with the options ``opts`` (default: its defaults)
        takes ``qp``, else ``(False, reason)``."""
        friction = getattr(qp, "friction", None)
        if friction is not None and not self.handles_friction:
            return False, (f"{friction.law} friction on the contact: this solver solves the "
                           "frictionless problem only"
                           + (f" ({self.friction_reason})" if self.friction_reason else ""))
        if friction is not None and getattr(friction, "facets", 0) and self.facets_reason:
            return False, (f"faceted friction (friction_facets = {friction.facets}): "
                           f"{self.facets_reason}")
        limit = self.size_limit_name(getattr(qp, "dim", None))
        if limit is not None:
            cap = (opts if opts is not None else self.options())[limit]
            if qp.n > cap:
                help_ = next(p.help for p in self.parameters if getattr(p, "name", None) == limit)
                return False, f"{qp.n} unknowns > {limit} = {cap}: {help_}"
        if self.supports is None:
            return True, ""
        ok, reason = self.supports(qp)
        return bool(ok), str(reason)


def contract_violation(result: Any, n: int, m: int,
                       m_tangential: int | None = None) -> tuple[str, str] | None:
    """The first rule of :data:`CONTRACT` that a solver's answer breaks, as
    ``(rule, what is wrong)``, or None if it keeps them all.

    Parameters
    ----------
    result : object
        What the solver's ``solve`` returned.
    n, m : int
        The size of the problem the solver received (``qp.n``, ``qp.m``).
    m_tangential : int, optional
        On a frictional problem, its number of tangential rows (``qp.friction.T``):
        ``tangential`` must then be an array of that length; ``None``: frictionless,
        ``tangential`` is not checked.

    A ``skipped`` answer carries nothing to use: only its type, status and message are
    checked.
    """
    if not isinstance(result, SolveResult):
        return "type", f"it returned a {type(result).__name__}"
    status = result.claimed_status
    if not isinstance(status, str) or status not in STATUSES:
        return "status", f"claimed_status is {status!r}"
    if not isinstance(result.message, str):
        return "message", f"message is a {type(result.message).__name__}"
    if status == "skipped":
        return None
    for name, size in (("u", n), ("p", m)):
        value = getattr(result, name)
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            return f"{name}_shape", f"{name} is a {type(value).__name__}, not numbers"
        if arr.shape != (size,):
            return f"{name}_shape", f"{name} has shape {arr.shape}, not ({size},)"
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            return f"{name}_finite", (f"{name} has {bad.size} non-finite entries (first at "
                                      f"index {bad[0]}: {arr[bad[0]]})")
    its = result.iterations
    if isinstance(its, (bool, np.bool_)) or not isinstance(its, (int, np.integer)) or its < 0:
        return "iterations", f"iterations is {its!r}"
    for name in ("setup_time", "solve_time"):
        t = getattr(result, name)
        if (isinstance(t, (bool, np.bool_)) or not isinstance(t, (int, float, np.number))
                or not np.isfinite(t) or t < 0):
            return "times", f"{name} is {t!r}"
    for name in ("history", "stats"):
        if not isinstance(getattr(result, name), dict):
            return "records", f"{name} is a {type(getattr(result, name)).__name__}"
    if m_tangential is not None:
        value = result.tangential
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            return "tangential", f"tangential is a {type(value).__name__}, not numbers"
        if value is None or arr.shape != (m_tangential,):
            return "tangential", ("tangential is None" if value is None else
                                  f"tangential has shape {arr.shape}, not ({m_tangential},)")
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            return "tangential_finite", (f"tangential has {bad.size} non-finite entries "
                                         f"(first at index {bad[0]}: {arr[bad[0]]})")
    return None


def tangential_rows(qp) -> int | None:
    """The number of tangential rows of a frictional ``qp`` (``None`` if frictionless):
    the length :func:`contract_violation` asks of ``SolveResult.tangential``."""
    friction = getattr(qp, "friction", None)
    return None if friction is None else friction.T.shape[0]


def parse_tolerance(tol: Any) -> float:
    """A preset name (``low``/``mid``/``high``) or a number in (0, 1)."""
    if isinstance(tol, str) and tol in TOLERANCES:
        return TOLERANCES[tol]
    try:
        return Parameter("tol", 1e-6, low=0.0, high=1.0, low_open=True, high_open=True).validate(tol)
    except ParameterError:
        raise ParameterError(f"parameter 'tol': {tol!r} is not allowed; allowed: one of "
                             f"{', '.join(TOLERANCES)} or a number in (0, 1)") from None
