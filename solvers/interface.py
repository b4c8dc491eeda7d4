"""The one interface between discrete contact problems and every solver.

Data flow (DESIGN.md): a scene builds a :class:`problems.qp.ContactQP`; any
registered solver turns it into a :class:`SolveResult`; :func:`solve` verifies it
(:func:`solvers.certificate.verify`: the four KKT residuals and a certified energy
bound) so that no solver is trusted on its own word.

The types live in :mod:`solvers.base`, the verification in :mod:`solvers.certificate`,
the reference policy in :mod:`solvers.reference`; the names a user needs are
re-exported here.
"""
from __future__ import annotations

import functools
import time
import traceback
from typing import Any

import numpy as np

from problems.qp import ContactQP, SharedWork
from problems.slack import slack_form
from problems.spec import (Parameter, ParameterError, discover, load_plugins, lookup,
                           with_plugins)
from solvers.base import (CONTRACT, STATUSES, TOLERANCES, Role, SolveResult, SolverSpec,
                          contract_violation, parse_tolerance, tangential_rows)
from solvers.certificate import broken_contract, certify, linear_solver, verify
from solvers.kernels.tresca import LoadPathRun, run_load_path

__all__ = ["CONTRACT", "ENTRY_POINT_GROUP", "STATUSES", "STOP_FACTOR", "TOLERANCES",
           "LoadPathRun", "Role", "SolveResult", "SolverSpec", "certify", "check_limits",
           "external_solvers",
           "linear_solver", "parse_tolerance", "run_load_path", "solve", "solver_set",
           "solvers", "verify"]


#: The entry-point group through which another installed package registers a solver: its
#: value names a :class:`SolverSpec` (``"package.module:SOLVER"``) or a module defining
#: ``SOLVER`` (docs/guide/add-a-solver.md).
ENTRY_POINT_GROUP = "contactbench.solvers"


def solvers() -> dict[str, SolverSpec]:
    """All registered solvers, ``{name: SolverSpec}``: the modules of ``solvers/`` that
    define ``SOLVER``, and the solvers other installed packages register under the
    entry-point group :data:`ENTRY_POINT_GROUP` (a built-in name wins a clash)."""
    return with_plugins(discover("solvers", "SOLVER"), external_solvers(), "solver")


@functools.lru_cache(maxsize=1)
def external_solvers() -> dict[str, SolverSpec]:
    """The solvers of other installed packages (entry points :data:`ENTRY_POINT_GROUP`),
    read once per process (:func:`problems.spec.load_plugins`: a broken plug-in is left
    out with a warning that says why, never breaking the suite)."""
    plugins = load_plugins(ENTRY_POINT_GROUP, "SOLVER", SolverSpec, "solver")
    _PLUGIN_PACKAGES.clear()
    _PLUGIN_PACKAGES.update(plugins.packages)
    return plugins.specs


#: ``{solver name: (package, version)}`` of the plug-ins :func:`external_solvers` loaded.
_PLUGIN_PACKAGES: dict[str, tuple[str, str | None]] = {}


def solver_set() -> dict[str, dict]:
    """The registered solvers and where each comes from, for a run's provenance:
    ``{name: {"role", "origin", "package", "version"}}`` with ``origin`` ``built-in``
    or ``plug-in`` (then the installed package and its version)."""
    out = {}
    for name, spec in solvers().items():
        if name in _PLUGIN_PACKAGES and external_solvers().get(name) is spec:
            package, version = _PLUGIN_PACKAGES[name]
            out[name] = {"role": str(spec.role), "origin": "plug-in", "package": package,
                         "version": version}
        else:
            out[name] = {"role": str(spec.role), "origin": "built-in",
                         "package": "contactbench", "version": None}
    return out


def check_limits(spec: SolverSpec, tol: float | str, max_iter: int | None,
                 time_limit: float | None) -> tuple[float, int, float | None]:
    """The validated ``(tol, max_iter, time_limit)`` of a run of ``spec`` (``max_iter``
    defaults to the solver's ``default_max_iter``; ``time_limit`` None means none).

    Raises
    ------
    ParameterError
        Naming the parameter and the allowed range.
    """
    tol = parse_tolerance(tol)
    if max_iter is None:
        max_iter = spec.default_max_iter
    max_iter = Parameter("max_iter", 1, low=1, kind=int).validate(max_iter)
    if time_limit is not None:
        time_limit = Parameter("time_limit", 1.0, low=0.0, low_open=True).validate(time_limit)
    return tol, max_iter, time_limit


#: The range of ``stop_factor`` (:func:`solve`): a tolerance ladder's rungs, from a
#: hundred times looser than the target to a thousand times tighter (the comparison's
#: ladder, :mod:`workflows.ladder`) and a decade beyond either way.
STOP_FACTOR = Parameter("stop_factor", 1.0, "the solver's own tolerance = tol * stop_factor "
                        "(the verification judges at tol)", low=1e-4, high=1e3)


def solve(qp: ContactQP, solver: str = "pdas", tol: float | str = "mid",
          max_iter: int | None = None, time_limit: float | None = None,
          u0: np.ndarray | None = None, p0: np.ndarray | None = None,
          stop_factor: float = 1.0, verification_work: SharedWork | None = None,
          **options: Any) -> SolveResult:
    """Run a registered solver, check its answer against the contract and verify it.

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
    stop_factor : float
        The solver is asked for ``tol * stop_factor`` (its own stopping rule, a library's
        mapping of it), the verification judges at ``tol``: a rung of a tolerance ladder
        (:mod:`workflows.ladder`). 1 (the default) is the plain run.
    verification_work : SharedWork, optional
        What earlier verifications of ``qp`` computed (factorisations, the last
        certificate), taken into ``qp.cache`` after the solver's run and before its
        verification: a benchmark that starts each timed run without the work of the runs
        before it (``qp.cache`` emptied) verifies without redoing it.
    **options
        Solver options, validated against its ``parameters``.

    Returns
    -------
    SolveResult
        With ``kkt``, the verified ``status`` and ``failed_check`` filled in. Whatever
        the solver does becomes a row: an exception it raises is a ``failed`` row
        (``failed_check = "exception"``, the traceback in ``traceback``); an answer
        that breaks :data:`solvers.base.CONTRACT` is a ``failed`` row naming the rule
        (:func:`solvers.certificate.verify`).
    """
    spec = lookup(solvers(), solver, "solver")
    tol, max_iter, time_limit = check_limits(spec, tol, max_iter, time_limit)
    stop_factor = STOP_FACTOR.validate(stop_factor)
    if tol * stop_factor >= 1.0:
        raise ParameterError(f"parameter 'stop_factor': {stop_factor!r} makes the solver's "
                             f"tolerance {tol * stop_factor:g}; allowed: tol * stop_factor < 1")
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
    ok, reason = spec.check(target, opts)
    if not ok:                                        # benchopt's skip: at once, with why
        result = SolveResult.without_answer(qp.n, qp.m, spec.name, tol, "skipped",
                                            f"skipped: {reason}", time.perf_counter() - t0)
        result.options = opts.flat()
        return result
    try:
        result = spec.solve(target, tol * stop_factor, max_iter, time_limit, u0, p0, opts)
    except ParameterError:
        raise
    except Exception as err:       # noqa: BLE001 -- whatever a solver raises is its row
        result = SolveResult.without_answer(
            qp.n, qp.m, spec.name, tol, "failed", f"{type(err).__name__}: {err}",
            time.perf_counter() - t0, failed_check="exception",
            traceback=traceback.format_exc())
        result.options = opts.flat()
        return result
    broken = contract_violation(result, target.n, target.m, tangential_rows(target))
    if broken is not None:
        row = broken_contract(qp, result, tol, *broken)
        row.solver, row.options = spec.name, opts.flat()
        return row
    if target is not qp:
        result.u = np.asarray(result.u, dtype=float)[:qp.n]
        result.message = (result.message + "; " if result.message else "") + "slack form"
    result.solver = spec.name
    result.tol = tol
    result.options = opts.flat()
    if verification_work is not None:
        qp.cache.fill_from(verification_work)
    return verify(qp, result, tol)
