"""The general QP libraries, one row of a table each, run by one adapter.

Every library solves the same rescaled problem (:mod:`solvers.kernels.scaling`):
``min 1/2 x'Px + q'x  s.t.  Gx <= h`` with ``P = A~``, ``q = -f~``, ``G = B~``,
``h = g~``; its inequality multipliers are our ``p`` (``Px + q + G'z = 0``, ``z >= 0``)
without a sign change. :func:`run` does the steps every library shares, once: the
rescaling, the preset's settings, the limits, the timing, the call, the unscaling, the
mapping of the library's own status onto the suite's, the note on an initial guess the
library ignores, and the result. A row (:class:`Library`) says only what differs: how
a preset maps onto the library's options, its status strings, and how it is called.

Friction (one Tresca step, :mod:`problems.friction.forms`; the load path and Coulomb's
fixed point run around it, :func:`solvers.kernels.tresca.run_load_path`): a 2D step is handed to
every library as a QP in ``(u, t)``, the slip split into two nonnegative parts
(:func:`problems.friction.forms.split_program`); a 3D step, isotropic, as a second-order
cone program (:func:`problems.friction.forms.cone_program`) to the libraries whose own API
takes such cones, Clarabel (``SecondOrderConeT``), SCS and ECOS (the cone sizes ``q``,
called directly: qpsolvers passes no cones); the QP-only libraries skip it. A 3D step of
the faceted law (the disc replaced by a ``k``-gon) is a QP
(:func:`problems.friction.forms.facet_program`) handed to every library. ECOS minimises
a linear objective only: it is handed every form with the quadratic term as
second-order cones, one per row of ``F`` (:func:`problems.friction.forms.epigraph_program`,
``P = F'F`` with ``F`` the sparse Cholesky factor of ``A``), which leaves the multipliers
unchanged. The step is rescaled like the frictionless problem, the tangential rows by one
factor per node
(:mod:`solvers.kernels.scaling`), and the library's multipliers map back to ``p`` and the
tangential multipliers ``lam`` (``SolveResult.tangential``).

Presets: ``low/mid/high`` = ``tol`` 1e-3/1e-6/1e-9 set as the library's absolute
tolerances, as qpbenchmark maps them (its ``test_set.define_solver_settings``), with the
relative ones at ``tol`` too where a library's absolute test alone would be
dimension-bound (OSQP, ProxQP, QPALM; the problem is rescaled to O(1) first) and the
duality-gap checks switched on where the library has them off by default (ProxQP,
PIQP). ECOS: ``feastol``, ``abstol`` and ``reltol`` all at ``tol`` (its gap test passes
on either, as Clarabel's does); qpbenchmark sets ``feastol`` only and leaves the gap at
ECOS's default 1e-8 for every preset. The table of what each preset means to each library
is the report's ``solver_presets.csv`` (:func:`Library.describe`).

How each library is reached: through qpsolvers (``qpsolvers.solve_problem``), the layer
qpbenchmark itself runs, where it passes every option the presets need and the
library's own status and iteration count (``Solution.extras``) -- OSQP, ProxQP, PIQP,
QPALM, cvxopt, SCS. qpsolvers costs no time: the same solves, the same iterations, take
as long through it as direct (docs/guide/measurements.md). It loses options, though, and
there the call is direct: Clarabel's iteration count (not in ``extras``), HiGHS's status
(``extras`` is empty: its own "Solve error" / "Large nullspace" would read as a bare
failure) and ECOS's epigraph (qpsolvers's ``ecos_solve_problem`` builds it from a dense
``P`` and its dense Cholesky factor, ``n^2`` entries, and passes no cones).
qpsolvers also passes dual warm starts to no library and drops QPALM's primal one (PIQP,
Clarabel, HiGHS and ECOS take none either); the suite's studies start every library
cold, so nothing measured depends on it, and a run given a guess says in its message
whether the library used it.
"""
from __future__ import annotations

import contextlib
import os
import sys
import time
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
import scipy.sparse as sp

from problems.friction.forms import (ConeProgram, epigraph_program, lift, standard_program,
                                     step_multipliers)
from problems.qp import ContactQP
from problems.spec import Options, Parameter, resolve_parameters
from solvers.kernels.scaling import ADAPTER_PARAMETERS, scale_qp, upper_triangle
from solvers.kernels.cholesky import cholesky_factor
from solvers.base import TOLERANCES, Role, SolveResult, SolverSpec, guess_not_used


@dataclass
class Outcome:
    """What one call of a library returned, in the library's own words.

    ``x``, ``z``: its primal and inequality-dual (cone-dual) solution of the rescaled
    problem (None if it returned none); ``status``: its own status string;
    ``iterations``; ``stats``: its own residuals or timings worth a column;
    ``used_guess``: whether it started from the guess it was given."""

    x: np.ndarray | None
    z: np.ndarray | None
    status: str
    iterations: int
    stats: dict = field(default_factory=dict)
    used_guess: bool = False


#: Status strings of a qpsolvers call that never reached the library (qpsolvers solves an
#: unconstrained problem itself, by SciPy's LSQR, and then reports no library status).
FOUND = "solved by qpsolvers itself (no constraints)"
NOT_FOUND = "not solved by qpsolvers itself (no constraints)"

Call = Callable[[ConeProgram, dict, "np.ndarray | None", "np.ndarray | None"], Outcome]


@dataclass(frozen=True)
class Library:
    """One row of the table: a QP library as the suite runs it.

    Attributes
    ----------
    name, summary : str
        Registry name and one line for ``contactbench list``.
    package : str
        The distribution, whose version :data:`workflows.io.PACKAGES` records.
    settings : callable
        ``settings(tol, opts) -> dict``: the library's options for the target ``tol``
        (the preset table).
    statuses : dict
        The library's status strings -> the suite's (unknown ones are ``failed``).
    call : callable
        ``call(program, settings, x0, z0) -> Outcome`` on the rescaled problem
        (:class:`problems.friction.forms.ConeProgram` with a nonnegative cone only).
    cone_call : callable or None
        The same with second-order cones (a 3D Tresca step), through the library's own
        cone API; ``None``: a QP library, which skips such a step.
    max_iter_key, time_limit_key : str or None
        The library's names of the two limits (None: it has none; the time limit is
        then checked after the run, and a late run is ``time_limit``).
    parameters : tuple
        The library's own options beyond ``tol_factor`` and ``scale``.
    default_max_iter : int
    size_limit : str or dict, optional
        The name of an integer option among ``parameters`` that bounds the unknowns it
        is given, or one name per spatial dimension
        (:attr:`solvers.base.SolverSpec.size_limit`).
    """

    name: str
    summary: str
    package: str
    settings: Callable[[float, Options], dict]
    statuses: dict
    call: Call
    cone_call: Call | None = None
    max_iter_key: str | None = "max_iter"
    time_limit_key: str | None = None
    parameters: tuple = ()
    default_max_iter: int = 10_000
    size_limit: str | dict | None = None

    def describe(self, tol: float) -> str:
        """What the preset ``tol`` means to this library (the report's preset table)."""
        opts = resolve_parameters(ADAPTER_PARAMETERS + self.parameters, {}, self.name)
        shown = ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}"
                          for k, v in self.settings(tol, opts).items()
                          if k not in ("verbose", "log_to_console", "output_flag"))
        return f"{shown}; scale=true, tol_factor=1"


def run(lib: Library, qp: ContactQP, tol: float, max_iter: int, time_limit: float | None,
        u0: np.ndarray | None, p0: np.ndarray | None, opts: Options) -> SolveResult:
    """Solve ``qp`` with the library ``lib`` (the steps every row shares, once)."""
    if qp.C is not None:          # solvers.interface.solve hands over the slack form
        raise ValueError(f"{lib.name} solves Bu <= g only; the ContactQP has a "
                         "stabilisation block C (Sect. 7.5)")
    t0 = time.perf_counter()
    data = scale_qp(qp, enabled=opts.scale)
    step = data.step()
    program = standard_program(step)
    call = lib.cone_call if program.cones else lib.call
    if call is None:
        raise ValueError(f"{lib.name} takes no second-order cones (a QP library)")
    settings = lib.settings(tol * opts.tol_factor, opts)
    if lib.max_iter_key:
        settings[lib.max_iter_key] = int(max_iter)
    if lib.time_limit_key and time_limit is not None:
        settings[lib.time_limit_key] = float(time_limit)
    x0, z0 = data.scale_guess(u0, p0)
    x0 = None if x0 is None else lift(step, program, x0)
    z0 = z0 if program.kind == "contact" else None        # no guess of lam is taken
    setup_time = time.perf_counter() - t0
    t1 = time.perf_counter()
    try:
        out = call(program, settings, x0, z0)
    except Exception as err:          # whatever the library raises is its failure, a row
        out = Outcome(None, None, f"raised {type(err).__name__}: {err}", 0)
    solve_time = time.perf_counter() - t1
    x = (np.full(program.P.shape[0], np.nan) if out.x is None
         else np.asarray(out.x, dtype=float))
    z = np.full(program.G.shape[0], np.nan) if out.z is None else np.asarray(out.z, dtype=float)
    p_s, lam_s = step_multipliers(step, program, z)
    u, p = data.unscale(x[:program.n], p_s)
    status = {FOUND: "converged", **lib.statuses}.get(out.status, "failed")
    if status == "inaccurate" and out.iterations >= max_iter:
        status = "max_iter"                  # "solved inaccurate" at the iteration limit
    message = f"{lib.name}: {out.status}"
    if time_limit is not None and not lib.time_limit_key and setup_time + solve_time > time_limit:
        status = "time_limit"
        message += (f"; run took {setup_time + solve_time:.3g} s > time_limit {time_limit:g} s "
                    f"({lib.name} cannot be interrupted)")
    if (u0 is not None or p0 is not None) and not out.used_guess:
        message = guess_not_used(message, "the library")
    stats = {**out.stats, "scaled": bool(opts.scale)}
    if lam_s is not None:
        stats["form"] = program.kind
    return SolveResult(u=u, p=p, claimed_status=status, message=message,
                       iterations=int(out.iterations), setup_time=setup_time,
                       solve_time=solve_time, stats=stats,
                       tangential=None if lam_s is None else data.unscale_tangential(lam_s))


# ----------------------------------------------------------------------------- the calls
def via_qpsolvers(solver: str, status_of: Callable[[dict], str],
                  iterations_of: Callable[[dict], int],
                  stats_of: Callable[[dict], dict] = lambda extras: {},
                  primal_guess: bool = True,
                  prepare: Callable[[dict], dict] = lambda settings: settings) -> Call:
    """A call through ``qpsolvers.solve_problem`` (the layer qpbenchmark runs);
    ``prepare`` turns option values into the library's own types."""

    def call(program: ConeProgram, settings: dict, x0, z0) -> Outcome:
        import qpsolvers

        settings = prepare(dict(settings))
        m = program.G.shape[0]
        problem = qpsolvers.Problem(program.P, program.q, program.G if m else None,
                                    program.h if m else None)
        with warnings.catch_warnings():       # its "exited with status ...": ours says it
            warnings.simplefilter("ignore", UserWarning)
            warnings.simplefilter("ignore", PendingDeprecationWarning)   # osqp's raise_error
            sol = qpsolvers.solve_problem(problem, solver=solver, initvals=x0, **settings)
        extras = sol.extras or {}
        z = sol.z if m else np.zeros(0)
        if not extras:       # qpsolvers solved it itself (no constraints: SciPy's LSQR)
            return Outcome(x=sol.x, z=z, status=FOUND if sol.found else NOT_FOUND,
                           iterations=0)
        return Outcome(x=sol.x, z=z, status=status_of(extras),
                       iterations=iterations_of(extras), stats=stats_of(extras),
                       used_guess=primal_guess and x0 is not None)

    return call


def _info(attr: str) -> Callable[[dict], Any]:
    """``extras["info"].<attr>`` (OSQP, ProxQP, PIQP, QPALM)."""
    return lambda extras: getattr(extras["info"], attr) if "info" in extras else None


def _enum_name(value) -> str:
    """``"Status.NAME"`` or ``NAME`` -> ``"NAME"``."""
    return str(value).rsplit(".", 1)[-1]


def clarabel_call(program: ConeProgram, settings: dict, x0, z0) -> Outcome:
    """Direct: qpsolvers does not pass Clarabel's iteration count, nor cones. The
    nonnegative rows, then a ``SecondOrderConeT`` per cone of the program."""
    import clarabel

    s = clarabel.DefaultSettings()
    for key, value in settings.items():
        setattr(s, key, value)
    m = program.nonnegative
    cones = (([clarabel.NonnegativeConeT(m)] if m else [])
             + [clarabel.SecondOrderConeT(size) for size in program.cones])
    sol = clarabel.DefaultSolver(upper_triangle(program.P), program.q, program.G, program.h,
                                 cones, s).solve()
    return Outcome(x=np.asarray(sol.x), z=np.asarray(sol.z), status=str(sol.status),
                   iterations=int(sol.iterations),
                   stats={"clarabel_r_prim": float(sol.r_prim),
                          "clarabel_r_dual": float(sol.r_dual)})


def _scs_status(info: dict) -> str:
    return str(info.get("status", "no status"))


def _scs_iterations(info: dict) -> int:
    return int(info.get("iter", 0))


def _scs_stats(info: dict) -> dict:
    return {"scs_res_pri": float(info.get("res_pri", np.nan)),
            "scs_res_dual": float(info.get("res_dual", np.nan))}


def _scs_cone_call(program: ConeProgram, settings: dict, x0, z0) -> Outcome:
    """Direct (``scs.SCS``), with the cone sizes: ``l`` nonnegative rows, then the
    second-order cones ``q``; its ``y`` are the cone multipliers (``Px + c + A'y = 0``)."""
    import scs

    data = {"P": upper_triangle(program.P), "A": program.G, "b": program.h, "c": program.q}
    cone = {"l": program.nonnegative, "q": list(program.cones)}
    result = scs.SCS(data, cone, **settings).solve(warm_start=x0 is not None, x=x0)
    info = result["info"]
    return Outcome(x=np.asarray(result["x"]), z=np.asarray(result["y"]),
                   status=_scs_status(info), iterations=_scs_iterations(info),
                   stats=_scs_stats(info), used_guess=x0 is not None)


def _ecos_call(program: ConeProgram, settings: dict, x0, z0) -> Outcome:
    """Direct (``ecos.solve(c, G, h, dims)``): ECOS minimises a linear objective only, so
    it is handed the program's epigraph form
    (:func:`problems.friction.forms.epigraph_program`): ``1/2 (F_j x)^2 <= w_j``, a
    second-order cone of size 3 per row of ``F``, ``P = F'F``. ``P`` is ``A`` on ``u``
    and zero on ``t``, so ``F = (F_A, 0)`` with ``F_A`` the sparse Cholesky factor of
    ``A`` (:func:`solvers.kernels.cholesky.cholesky_factor`, a fill-reducing ordering): its
    nonzeros are the factorisation's fill, where a dense factor would put ``n^2/2`` into
    the KKT system ECOS factorises at each iteration. The nonnegative rows are
    ``dims["l"]``, the cones ``dims["q"]``, the epigraph cones last; its ``z`` of the
    program's rows are the program's multipliers (``c + G'z = 0``). ECOS takes no
    initial guess. Its answer's stationarity goes with the square root of its duality
    gap (the epigraph cones' multipliers off their central path), so the suite's
    verification refutes what it claims at a preset's own tolerance; ``tol_factor``
    tightens it."""
    import ecos

    n, N = program.n, len(program.q)
    F = sp.hstack([cholesky_factor(program.P[:n, :n]), sp.csr_matrix((n, N - n))])
    lifted = epigraph_program(program, F)
    dims = {"l": lifted.nonnegative, "q": list(lifted.cones)}
    sol = ecos.solve(lifted.q, lifted.G, lifted.h, dims, **settings)
    info = sol["info"]
    return Outcome(x=np.asarray(sol["x"])[:N], z=np.asarray(sol["z"])[:len(program.h)],
                   status=str(info["infostring"]), iterations=int(info["iter"]),
                   stats={"ecos_pres": float(info["pres"]), "ecos_dres": float(info["dres"]),
                          "ecos_gap": float(info["gap"])})


@contextlib.contextmanager
def _banner_silenced():
    """Standard output (file descriptor 1) closed to the C library for a moment: the first
    ``highspy.Highs()`` of a process prints HiGHS's banner there before any option can
    be set, which would land in the output of ``contactbench solve``."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 1)
        os.close(null)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def _highs_call(program: ConeProgram, settings: dict, x0, z0) -> Outcome:
    """Direct: qpsolvers returns none of HiGHS's status (``extras`` is empty), which would
    turn its own "Solve error" into a bare failure. ``min 1/2 x'Px + q'x`` with the rows
    ``-inf <= Gx <= h``; HiGHS's row duals are ``-z`` (minimisation, upper bounds)."""
    import highspy

    with _banner_silenced():
        h = highspy.Highs()
    for key, value in settings.items():
        h.setOptionValue(key, value)
    n, m = program.P.shape[0], program.G.shape[0]
    inf = highspy.kHighsInf
    lp = highspy.HighsLp()
    lp.num_col_, lp.num_row_ = n, m
    lp.col_cost_ = program.q
    lp.col_lower_, lp.col_upper_ = np.full(n, -inf), np.full(n, inf)
    lp.row_lower_, lp.row_upper_ = np.full(m, -inf), program.h
    G = sp.csc_matrix(program.G)
    lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
    lp.a_matrix_.start_, lp.a_matrix_.index_, lp.a_matrix_.value_ = G.indptr, G.indices, G.data
    lower = sp.csc_matrix(sp.tril(program.P))         # HiGHS takes the lower triangle
    model = highspy.HighsModel()
    model.lp_ = lp
    model.hessian_.dim_ = n
    model.hessian_.format_ = highspy.HessianFormat.kTriangular
    model.hessian_.start_, model.hessian_.index_ = lower.indptr, lower.indices
    model.hessian_.value_ = lower.data
    h.passModel(model)
    h.run()
    status = h.modelStatusToString(h.getModelStatus())
    sol = h.getSolution()
    info = h.getInfo()
    ok = sol.value_valid and sol.dual_valid
    return Outcome(x=np.asarray(sol.col_value) if ok else None,
                   z=-np.asarray(sol.row_dual) if ok else None, status=status,
                   iterations=max(int(info.qp_iteration_count), 0),
                   stats={"highs_qp_iterations": int(info.qp_iteration_count)})


# ------------------------------------------------------------------------------ the table
LIBRARIES = (
    Library(
        "osqp", "OSQP 1.x (ADMM + solution polishing), general convex QP solver", "osqp",
        settings=lambda tol, o: {
            "eps_abs": tol, "eps_rel": tol, "polishing": bool(o.polish),
            "polish_refine_iter": 3 if tol >= 1e-6 else 10, "adaptive_rho": bool(o.adaptive_rho),
            "rho": float(o.rho), "check_dualgap": True, "scaled_termination": False,
            "verbose": False},
        statuses={"solved": "converged", "solved inaccurate": "inaccurate",
                  "maximum iterations reached": "max_iter",
                  "run time limit reached": "time_limit"},
        call=via_qpsolvers("osqp", _info("status"), lambda e: _info("iter")(e) or 0,
                           lambda e: {"status_polish": int(_info("status_polish")(e)),
                                      "osqp_prim_res": float(_info("prim_res")(e)),
                                      "osqp_dual_res": float(_info("dual_res")(e))}),
        time_limit_key="time_limit", default_max_iter=100_000,
        parameters=(Parameter("polish", True, "OSQP solution polishing (the source of its "
                              "accuracy)"),
                    Parameter("adaptive_rho", True, "OSQP adaptive ADMM step size"),
                    Parameter("rho", 0.1, "initial ADMM step size", low=0.0, low_open=True))),
    Library(
        "proxsuite", "ProxSuite ProxQP (proximal augmented Lagrangian), sparse Cholesky "
        "backend", "proxsuite",
        settings=lambda tol, o: {
            "eps_abs": tol, "eps_rel": tol, "check_duality_gap": bool(o.check_duality_gap),
            "eps_duality_gap_abs": tol, "eps_duality_gap_rel": tol, "verbose": False,
            "backend": "sparse", "sparse_backend": o.backend},
        statuses={"PROXQP_SOLVED": "converged", "PROXQP_MAX_ITER_REACHED": "max_iter"},
        call=via_qpsolvers("proxqp", lambda e: _enum_name(_info("status")(e)),
                           lambda e: _info("iter")(e) or 0,
                           lambda e: {"backend": _enum_name(_info("sparse_backend")(e)),
                                      "proxqp_pri_res": float(_info("pri_res")(e)),
                                      "proxqp_dua_res": float(_info("dua_res")(e)),
                                      "proxqp_duality_gap": float(_info("duality_gap")(e))},
                           prepare=lambda s: {**s, "sparse_backend":
                                              _proxqp_backend(s["sparse_backend"])}),
        parameters=(Parameter("check_duality_gap", True, "also stop on the duality gap "
                              "(ProxQP's default is off, which stops with complementarity "
                              "unresolved)"),
                    Parameter("backend", "sparse_cholesky", "ProxQP sparse backend (automatic "
                              "may switch to the ~27x slower matrix-free mode)",
                              choices=("sparse_cholesky", "automatic", "matrix_free")))),
    Library(
        "clarabel", "Clarabel (interior point, homogeneous embedding), general conic solver",
        "clarabel",
        settings=lambda tol, o: {"tol_gap_abs": tol, "tol_gap_rel": tol, "tol_feas": tol,
                                 "equilibrate_enable": bool(o.equilibrate), "verbose": False},
        statuses={"Solved": "converged", "AlmostSolved": "inaccurate",
                  "MaxIterations": "max_iter", "MaxTime": "time_limit"},
        call=clarabel_call, cone_call=clarabel_call, time_limit_key="time_limit",
        default_max_iter=200,
        parameters=(Parameter("equilibrate", True, "Clarabel's Ruiz equilibration"),)),
    Library(
        "piqp", "PIQP (proximal interior point), sparse KKT backend", "piqp",
        settings=lambda tol, o: {
            "eps_abs": tol, "eps_rel": 0.0, "check_duality_gap": bool(o.check_duality_gap),
            "eps_duality_gap_abs": tol, "eps_duality_gap_rel": 0.0, "verbose": False,
            "backend": "sparse", "kkt_solver": o.kkt_solver},
        statuses={"PIQP_SOLVED": "converged", "PIQP_MAX_ITER_REACHED": "max_iter"},
        call=via_qpsolvers("piqp", lambda e: _enum_name(_info("status")(e)),
                           lambda e: _info("iter")(e) or 0, primal_guess=False,
                           prepare=lambda s: {**s, "kkt_solver": _piqp_kkt(s["kkt_solver"])}),
        default_max_iter=250,
        parameters=(Parameter("check_duality_gap", True, "also stop on the duality gap"),
                    Parameter("kkt_solver", "sparse_ldlt", "PIQP sparse KKT backend",
                              choices=("sparse_ldlt", "sparse_ldlt_ineq_cond",
                                       "sparse_ldlt_eq_cond", "sparse_ldlt_cond")))),
    Library(
        "qpalm", "QPALM (proximal augmented Lagrangian for nonconvex QPs)", "qpalm",
        settings=lambda tol, o: {"eps_abs": tol, "eps_rel": tol, "scaling": int(o.scaling),
                                 "verbose": 0},
        statuses={"solved": "converged", "maximum iterations reached": "max_iter",
                  "time limit exceeded": "time_limit"},
        call=via_qpsolvers("qpalm", _info("status"),
                           lambda e: _info("iter")(e) or 0, primal_guess=False),
        time_limit_key="time_limit",
        parameters=(Parameter("scaling", 10, "QPALM's Ruiz scaling iterations", low=0,
                              kind=int),)),
    Library(
        "cvxopt", "CVXOPT (primal-dual interior point, coneqp), sparse KKT", "cvxopt",
        settings=lambda tol, o: {"feastol": tol, "abstol": tol, "reltol": 0.0},
        statuses={"optimal": "converged", "unknown": "inaccurate"},   # unknown: stopped short
        call=via_qpsolvers("cvxopt", lambda e: str(e.get("status", "no status")),
                           lambda e: int(e.get("iterations", 0)),
                           lambda e: {"cvxopt_gap": float(e.get("gap") or np.nan)}),
        max_iter_key="maxiters", default_max_iter=100),
    Library(
        "highs", "HiGHS (active-set QP solver of the HiGHS MIP/LP suite)", "highspy",
        settings=lambda tol, o: {"primal_feasibility_tolerance": tol,
                                 "dual_feasibility_tolerance": tol, "output_flag": False,
                                 "log_to_console": False},
        statuses={"Optimal": "converged", "Iteration limit reached": "max_iter",
                  "Time limit reached": "time_limit"},
        call=_highs_call, max_iter_key="qp_iteration_limit", time_limit_key="time_limit",
        default_max_iter=100_000, size_limit="max_unknowns",
        parameters=(Parameter(
            "max_unknowns", 2000, "HiGHS's active-set QP solver keeps a dense factor of the "
            "reduced Hessian on the null space of the active rows (on a contact problem "
            "nearly all n unknowns; beyond its qp_nullspace_limit of 4000 it stops with "
            "'Solve error'), so its time grows like n^3 here: 5 s at 1,600 unknowns, 18 s at "
            "2,104", low=1, kind=int),)),
    Library(
        "scs", "SCS (splitting conic solver, ADMM on the homogeneous embedding)", "scs",
        settings=lambda tol, o: {"eps_abs": tol, "eps_rel": 0.0, "verbose": False},
        statuses={"solved": "converged", "solved (inaccurate - reached max_iters)": "max_iter",
                  "solved (inaccurate - reached time_limit_secs)": "time_limit"},
        call=via_qpsolvers("scs", _scs_status, _scs_iterations, _scs_stats),
        cone_call=_scs_cone_call,
        max_iter_key="max_iters", time_limit_key="time_limit_secs", default_max_iter=100_000),
    Library(
        "ecos", "ECOS (primal-dual interior point for second-order cone programs), the "
        "quadratic term as an epigraph cone", "ecos",
        settings=lambda tol, o: {"feastol": tol, "abstol": tol, "reltol": tol,
                                 "verbose": False},
        statuses={"Optimal solution found": "converged",
                  "Close to optimal solution found": "inaccurate",
                  "Maximum number of iterations reached": "max_iter"},  # the rest: failed
        call=_ecos_call, cone_call=_ecos_call, max_iter_key="max_iters",
        default_max_iter=100,
        size_limit={2: "max_unknowns_2d", 3: "max_unknowns_3d"},
        parameters=(
            Parameter("max_unknowns_2d", 10_000, "ECOS factorises its KKT system, which holds "
                      "the epigraph's Cholesky factor of the stiffness matrix, at every "
                      "iteration, and it has no time limit of its own: in 2D 8,288 unknowns "
                      "take seconds, 32,904 over two minutes", low=1, kind=int),
            Parameter("max_unknowns_3d", 4_000, "ECOS factorises its KKT system, which holds "
                      "the epigraph's Cholesky factor of the stiffness matrix, at every "
                      "iteration, and it has no time limit of its own: a 3D factor fills in "
                      "faster, so 1,104 unknowns take a third of a second and 7,137 over a "
                      "minute", low=1, kind=int),
        )),
)


def _proxqp_backend(name: str):
    from proxsuite import proxqp

    return {"sparse_cholesky": proxqp.SparseBackend.SparseCholesky,
            "automatic": proxqp.SparseBackend.Automatic,
            "matrix_free": proxqp.SparseBackend.MatrixFree}[name]


def _piqp_kkt(name: str):
    import piqp

    return getattr(piqp.KKTSolver, name)


def cone_support(lib: Library) -> Callable[[ContactQP], tuple[bool, str]]:
    """``supports(qp)`` of a row: a QP library (no ``cone_call``) skips an isotropic 3D
    Tresca step and takes a faceted one (a QP)."""

    def supports(qp: ContactQP) -> tuple[bool, str]:
        """A 2D Tresca step is handed over as a QP (the slip split into two nonnegative
        parts), a 3D one, isotropic, as a second-order cone program; a library without
        second-order cones skips a 3D Tresca step (or Coulomb, run as Tresca steps). A
        faceted step (``friction_facets`` = k) is a QP every library takes."""
        fr = qp.friction
        if lib.cone_call is None and fr is not None and fr.components > 1 and not fr.facets:
            return False, (f"{fr.law} friction in {qp.dim}D: isotropic friction is a "
                           f"second-order cone program, and {lib.name} is a QP solver (no "
                           "second-order cones)")
        return True, ""

    return supports


def solver_spec(lib: Library) -> SolverSpec:
    """The registry entry of a row."""
    return SolverSpec(
        name=lib.name, summary=lib.summary,
        solve=lambda qp, tol, max_iter, time_limit, u0, p0, opts: run(
            lib, qp, tol, max_iter, time_limit, u0, p0, opts),
        parameters=ADAPTER_PARAMETERS + lib.parameters,
        presets={name: lib.describe(tol) for name, tol in TOLERANCES.items()},
        default_max_iter=lib.default_max_iter, role=Role.LIBRARY, size_limit=lib.size_limit,
        supports=cone_support(lib), handles_friction=True)


#: Every row as a registered solver (:func:`problems.spec.discover` reads ``SOLVERS``).
SOLVERS = tuple(solver_spec(lib) for lib in LIBRARIES)
