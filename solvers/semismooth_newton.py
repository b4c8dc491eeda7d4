"""Inexact semismooth Newton (primal-dual active set) with multigrid-preconditioned inner
solves: the method a contact-mechanics user would pick (deal.II step-41/42 style).

The PDAS / semismooth Newton iteration of Hintermüller, Ito and Kunisch (SIAM J.
Optim. 13, 2003) for ``min 1/2 u'Au - f'u  s.t.  Bu <= g``: with the active set
``I = {i : p_i + c (Bu - g)_i > 0}`` each step solves the equality-constrained
problem ``min 1/2 u'Au - f'u  s.t.  B_I u = g_I`` -- here *inexactly*, by
projected preconditioned CG (Gould, Hribar and Nocedal, SIAM J. Sci. Comput. 23,
2001): CG on the null space of ``B_I`` with a projector ``Pi`` onto it and the
preconditioner ``Pi M Pi'``, ``M`` one symmetric V-cycle (geometric multigrid on
the refinement hierarchy, pyamg SA without one). ``Pi`` removes the constraint
directions along their local A-harmonic extensions (``face="harmonic"``, beyond
Gould-Hribar-Nocedal; :func:`solvers.kernels.face.face_projector`), which
keeps the V-cycle's rate on the face, or orthogonally (``face="euclidean"``,
their ``I - B_I'(B_I B_I')^{-1} B_I``), which cuts the V-cycle's smooth correction
at the constrained DOFs and needs about twice the steps. The solve is warm
started from the previous iterate. The multipliers are those the projector defines,
``p_I = (W' B_I')^{-1} W' (f - A u)`` (least squares for ``euclidean``), ``p = 0`` off ``I``.
Linearly dependent active rows (LICQ fails; ``u`` is still unique) are reduced to a
basis consistent with their gaps (:func:`solvers.kernels.cholesky.row_basis`: rank-revealing
pivoted Cholesky of ``K = B_I W``); the multiplier is then the basic one, zero on the
dependent rows, as in :mod:`solvers.pdas`. Rows that no ``u`` satisfies end the run as
``failed`` ("the problem is infeasible", with a Farkas certificate).

Inexactness control: the inner relative tolerance starts at ``inner.rtol`` and
is tied to the outer residual (a forcing term ``min(rtol, forcing * KKT)``), so
early steps with a wrong active set are cheap and the last ones accurate; when
the active set repeats, the tolerance is tightened by ``tighten`` until the
verification passes. The inner PCG keeps its residual projected and stops at the
round-off level of the problem (:func:`projected_pcg`), so its result does not
depend on how a BLAS kernel rounds. A cycling active set is damped as in
:mod:`solvers.pdas`.

Globalisation: PDAS converges for M-matrix-like problems but may cycle otherwise
(with exact or inexact solves). When the Newton iteration stalls -- the active set
recurs even under single damped changes, or the best KKT residual has not halved for
``patience`` steps -- the monotone primal active-set method takes over from where
Newton stopped (:func:`_monotone`; Nocedal and Wright, Alg. 16.3): feasible iterates,
the same inexact face solves, a non-increasing energy, finite termination. The
message says that it ran and why; ``fallback="none"`` makes a stall a ``failed`` run
instead, and ``patience=0`` runs the monotone method from the start.

It stops when the suite's verification passes (KKT residuals and the certified
energy bound, :func:`solvers.interface.verify`), so its claims are never refuted.

Friction (2D or 3D, a ContactQP with ``qp.friction``; :func:`solve_friction`): the
primal-dual active set method of Hüeber, Stadler and Wohlmuth (SIAM J. Sci. Comput. 30,
2008) with the normal active set, the sticking nodes (``slip = 0``) and the slipping
nodes (2D: ``lam = s sign``; 3D: the linearised complementarity function
``max(s, |lam + c slip|) lam - s (lam + c slip) = 0``) as its sets. Each step is solved exactly: ``A`` factorised once and
the dense Schur complement of the normal and tangential rows, as the ``schur`` route of
:mod:`solvers.pdas` (the inner options ``ahat``, ``inner``, ``face``, ``forcing``,
``tighten`` and ``patience`` do not apply). Sets that cycle under single changes on a
Tresca step hand the step's dual, from the best Newton step, to a method that cannot
cycle (``fallback="monotone"``: the primal active-set method on the box in 2D, the
globalised Newton method of the projection equation in 3D). It takes one Tresca step, the
slip bound given; with ``coulomb="monolithic"`` a Coulomb problem is solved with
``s = mu p`` inside the Newton iteration. A frictionless problem never reaches it.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from problems.friction.residuals import friction_residuals, friction_row_residuals
from problems.kkt import kkt_residuals
from problems.qp import ContactQP
from problems.spec import ComponentParameter, Options, Parameter, ParameterError
from solvers.kernels.face import FACE_PROJECTION, FaceProjector, face_hops, face_projector
from solvers.kernels.multigrid import AHAT, component_vcycle
from solvers.base import VERIFIED_PRESETS, Role, SolveResult, SolverSpec
from solvers.certificate import certify
from solvers.kernels.cholesky import InfeasibleError, dense_schur, factorize, row_basis
from solvers.kernels.active_set import (check_positive_diagonal, damped_update, initial_active_set,
                                        pdas_update, stiffness_scale)


#: Round-off floor of the inner solve, relative to the energy norm of the iterate: below
#: it the projected residual is noise (measured ~1e-16 relative on the random two-body
#: family and on circle-square) and further CG steps only stir it.
ROUNDOFF_FLOOR = 1e3 * np.finfo(float).eps


def projected_pcg(A, face: FaceProjector, f, gI, M, x0, rtol: float, max_steps: int):
    """``min 1/2 x'Ax - f'x  s.t.  B_I x = g_I`` by projected PCG from ``x0``.

    ``face`` projects onto ``ker B_I`` (:func:`solvers.kernels.face.face_projector`);
    the preconditioner is ``Pi M Pi'``. The residual is kept projected,
    ``r <- Pi' r`` after every update (Gould, Hribar and Nocedal's *residual
    update*, their Sect. 6), so that ``r'z = r' M r`` is evaluated as a norm: the
    unprojected residual carries the constraint force ``B_I' p`` and ``r'z``
    computed from it is a difference of large numbers that rounding can make
    tiny, negative or wrong (CG then walks off the face and runs into ``max_steps``,
    seen on 90 unknowns under one OpenBLAS kernel). It stops when
    ``||r||_M <= max(rtol ||r_0||_M, ROUNDOFF_FLOOR ||x||_A)``: relative to the
    lifted start, but never below the round-off level of the problem, which a
    warm start that is already optimal on the face sits at. The iterate is
    lifted onto the face once more at the end (removes the drift of the updates).

    Returns
    -------
    (x, steps)
    """
    x = face.lift(np.array(x0, dtype=float), gI)           # a feasible start near x0
    Ax = A @ x
    r = face.project_T(f - Ax)
    y = M(r)
    rz = float(r @ y)
    floor = ROUNDOFF_FLOOR * np.sqrt(max(float(x @ Ax), 0.0))
    stop = max(rtol * np.sqrt(max(rz, 0.0)), floor)
    z = face.project(y)
    d = z
    steps = 0
    while steps < max_steps and rz > 0 and np.sqrt(rz) > stop:
        Ad = A @ d
        dAd = float(d @ Ad)
        if not dAd > 0:                                     # d is round-off: nothing to gain
            break
        alpha = rz / dAd
        x = x + alpha * d
        r = face.project_T(r - alpha * Ad)
        y = M(r)
        rz_new = float(r @ y)
        z = face.project(y)
        d = z + (rz_new / rz) * d
        rz = rz_new
        steps += 1
    return (face.lift(x, gI) if steps else x), steps


def solve(qp: ContactQP, tol: float, max_iter: int, time_limit: float | None,
          u0: np.ndarray | None, p0: np.ndarray | None, opts: Options) -> SolveResult:
    """Solve ``qp`` by the inexact semismooth Newton method (module docstring).

    ``max_iter`` caps the steps, Newton and fallback together; ``stats`` count the
    inner PCG steps and the V-cycles (one per inner step plus one per face solve for
    the initial residual) and those of the setup, and say whether the monotone
    fallback ran (``fallback``) and why (the message).
    """
    if qp.friction is not None:
        return solve_friction(qp, tol, max_iter, time_limit, u0, p0, opts)
    t_start = time.perf_counter()
    if qp.C is not None:
        raise ValueError("semismooth_newton solves Bu <= g only; the ContactQP has a "
                         "stabilisation block C (Sect. 7.5)")
    check_positive_diagonal(qp.A)
    if opts.patience == 0 and opts.fallback == "none":
        raise ParameterError("parameter 'patience': 0 (the fallback from the start) is not "
                             "allowed with fallback='none'; allowed: patience >= 1")
    vc = component_vcycle(qp, opts.ahat)   # unscaled: PCG needs no spectral bounds
    B = qp.B.tocsr()
    hops = face_hops(qp.dim, opts.face.options.get("hops", 0))
    faces = _FaceCache(qp.A, B, qp.g, opts.face.kind, hops)
    setup_time = time.perf_counter() - t_start
    vcycles_setup = vc.n_applications

    t_solve = time.perf_counter()
    run = _Run(qp, B, vc.raw, faces, tol, opts, t_solve,
               None if time_limit is None else t_start + time_limit)
    u = np.zeros(qp.n) if u0 is None else np.array(u0, dtype=float)
    p = None if p0 is None else np.maximum(np.asarray(p0, dtype=float), 0.0)
    active = initial_active_set(qp, u0, p, opts.c * stiffness_scale(qp))
    fallback = opts.fallback == "monotone"
    fell_back = opts.patience == 0
    if fell_back:
        out = _monotone(run, u, active, max_iter, 0)
        out.message = f"monotone primal active-set method (patience=0): {out.message}"
    else:
        out = _newton(run, u, active, max_iter, opts.patience)
    if out.status == "stalled" and fallback and run.out_of_time():
        out.status, out.message = "time_limit", out.message + "; time limit reached"
    elif out.status == "stalled" and fallback and out.steps < max_iter:
        stall, fell_back = out.message, True
        out = _monotone(run, out.u, out.active, max_iter - out.steps, out.steps)
        out.message = f"{stall}; fell back to the monotone primal active-set method: {out.message}"
    elif out.status == "stalled":
        out.status = "failed" if not fallback else "max_iter"
        out.message += "; no fallback" if not fallback else "; no steps left for the fallback"
    inner = int(np.sum(run.history["inner_steps"]))
    phases = run.history["phase"]
    stats = {"newton_steps": phases.count("newton"), "fallback_steps": phases.count("fallback"),
             "fallback": fell_back, "inner_steps": inner,
             "n_vcycles": vc.n_applications - vcycles_setup, "vcycles_setup": vcycles_setup,
             "n_active": int(np.count_nonzero(out.p > 0)), "ahat_kind": vc.kind,
             "face": opts.face.kind, "damped": run.damped}
    return SolveResult(u=out.u, p=out.p, claimed_status=out.status, message=out.message,
                       iterations=out.steps, setup_time=setup_time,
                       solve_time=time.perf_counter() - t_solve, history=run.history,
                       stats=stats)


class _FaceCache:
    """The face projector of the last active set (a repeated set keeps its factor).

    One set only: Newton repeats its last set when it tightens the inner tolerance,
    while the fallback changes its working set by a row at every step and so
    factorises every step (a factor update by rows would save that; not needed while
    the fallback is a safeguard)."""

    def __init__(self, A, B, g, kind: str, hops: int):
        self.A, self.B, self.g, self.kind, self.hops = A, B, g, kind, hops
        self.rows, self.face = None, None

    def __call__(self, idx: np.ndarray) -> FaceProjector:
        if self.face is None or not np.array_equal(idx, self.rows):
            self.face = face_projector(self.A, self.B[idx], self.kind, self.hops, self.g[idx], idx)
            self.rows = idx
        return self.face


@dataclass
class _Outcome:
    """Where a phase stopped: the iterate, its active set, the status and the steps so far."""

    u: np.ndarray
    p: np.ndarray
    active: np.ndarray
    status: str
    message: str
    steps: int


@dataclass
class _Run:
    """What both phases share: the problem, the V-cycle, the faces, the inexactness
    control (``rtol``), the clock and the history."""

    qp: ContactQP
    B: object
    M: object
    faces: _FaceCache
    tol: float
    opts: Options
    t_solve: float
    deadline: float | None
    rtol: float = 0.0
    damped: bool = False
    history: dict = field(default_factory=lambda: {
        "phase": [], "n_active": [], "inner_steps": [], "inner_rtol": [], "kkt_max": [],
        "energy": [], "time": []})

    def __post_init__(self):
        self.rtol = self.opts.inner.options["rtol"]

    def face_solve(self, u: np.ndarray, active: np.ndarray):
        """The face of ``active`` solved from ``u`` to ``rtol``: ``(u, face)``."""
        idx = np.flatnonzero(active)
        face = self.faces(idx)
        u, steps = projected_pcg(self.qp.A, face, self.qp.f, self.qp.g[idx], self.M, u,
                                 self.rtol, self.opts.inner.options["max_steps"])
        self.history["inner_steps"].append(steps)
        self.history["inner_rtol"].append(self.rtol)
        return u, face

    def multipliers(self, u: np.ndarray, active: np.ndarray, face) -> np.ndarray:
        p = np.zeros(self.qp.m)
        p[active] = face.multipliers(self.qp.f - self.qp.A @ u)
        return p

    def record(self, phase: str, active: np.ndarray, u: np.ndarray, kkt: float) -> None:
        h = self.history
        h["phase"].append(phase)
        h["n_active"].append(int(np.count_nonzero(active)))
        h["kkt_max"].append(kkt)
        # the energy is what the fallback must not raise; the Newton phase does not need it
        h["energy"].append(self.qp.energy(u) if phase == "fallback" else np.nan)
        h["time"].append(time.perf_counter() - self.t_solve)

    def verified(self, u: np.ndarray, p: np.ndarray, kkt: float) -> bool:
        """The suite's verification: KKT residuals and the certified energy bound."""
        return kkt <= self.tol and certify(self.qp, u, p, self.tol).meets(self.tol)

    def tighten(self) -> bool:
        """Tighten the inner tolerance; False when it is at its floor already."""
        floor = self.opts.inner.options["min_rtol"]
        if self.rtol <= floor:
            return False
        self.rtol = max(self.rtol * self.opts.tighten, floor)
        return True

    def out_of_time(self) -> bool:
        return self.deadline is not None and time.perf_counter() > self.deadline


def _newton(run: _Run, u: np.ndarray, active: np.ndarray, max_iter: int,
            patience: int) -> _Outcome:
    """The semismooth Newton (PDAS) steps with inexact face solves.

    Ends ``converged`` (verified), ``inaccurate`` (the active set is fixed but the
    inner tolerance is at its floor), ``max_iter``, ``time_limit``, ``failed`` (rows that
    no ``u`` satisfies, with a Farkas certificate), or ``stalled``: the active set recurs
    even under single damped changes, the best KKT residual has not halved for
    ``patience`` steps, or linearly dependent active rows have no basis consistent with
    their gaps (:func:`solvers.kernels.face.face_projector`). A stalled run goes on in
    :func:`_monotone` (option ``fallback``).
    """
    qp, opts, tol = run.qp, run.opts, run.tol
    seen: set[bytes] = set()
    limit: int | None = None
    best, since_best = np.inf, 0
    p = np.zeros(qp.m)
    for k in range(1, max_iter + 1):
        try:
            u, face = run.face_solve(u, active)
        except InfeasibleError as err:
            return _Outcome(u, p, active, "failed", f"Newton step {k}: {err}", k - 1)
        except RuntimeError as err:                  # dependent rows without a basis
            return _Outcome(u, p, active, "stalled", f"no face for the active set of Newton "
                            f"step {k} ({err})", k - 1)
        p = run.multipliers(u, active, face)
        kkt = kkt_residuals(qp, u, p).max
        run.record("newton", active, u, kkt)
        best, since_best = (kkt, 0) if kkt < 0.5 * best else (best, since_best + 1)
        proposed = pdas_update(qp, active, u, p, opts.flip_tol)
        new = proposed if limit is None else damped_update(qp, active, proposed, u, p, limit)
        if np.array_equal(new, active):
            if run.verified(u, p, kkt):
                return _Outcome(u, p, active, "converged",
                                f"active set fixed after {k} Newton steps, verified (KKT "
                                f"{kkt:.1e}, certified bound <= {tol:.0e})", k)
            if not run.tighten():
                return _Outcome(u, p, active, "inaccurate",
                                f"active set fixed but not verified at the inner tolerance "
                                f"floor {run.rtol:.0e} (KKT {kkt:.1e})", k)
        else:
            key = new.tobytes()
            if key in seen:                                   # cycling: damp the updates
                if limit == 1:
                    return _Outcome(u, p, active, "stalled",
                                    f"the active set cycles under single changes at Newton "
                                    f"step {k} (KKT {kkt:.1e})", k)
                n_changes = int(np.count_nonzero(proposed != active))
                limit = max(1, n_changes // 2) if limit is None else max(1, limit // 2)
                run.damped = True
                seen = set()
                new = damped_update(qp, active, proposed, u, p, limit)
            if since_best >= patience:
                return _Outcome(u, p, active, "stalled",
                                f"no progress in {since_best} Newton steps (best KKT "
                                f"{best:.1e}, now {kkt:.1e})", k)
            seen.add(new.tobytes())
            active = new
            run.rtol = max(min(run.rtol, opts.forcing * kkt), opts.inner.options["min_rtol"])
        if run.out_of_time():
            return _Outcome(u, p, active, "time_limit", f"time limit reached at step {k}", k)
    return _Outcome(u, p, active, "max_iter", f"not verified after {max_iter} Newton steps",
                    max_iter)


def _feasible_start(run: _Run, u: np.ndarray, active: np.ndarray):
    """A point with ``Bu <= g`` on the face of a working set that contains ``active``:
    the violated rows join the working set and ``u`` is lifted onto its face, until
    no row is violated (at most ``m`` rounds; the lift moves ``u`` only on a patch
    around the constrained DOFs)."""
    qp, B = run.qp, run.B
    work = active.copy()
    for _ in range(qp.m + 1):
        if run.out_of_time():
            raise RuntimeError("time limit reached while looking for a feasible start")
        idx = np.flatnonzero(work)
        u = run.faces(idx).lift(u, qp.g[idx])
        Bu = B @ u
        scale = max(float(np.max(np.abs(Bu), initial=0.0)),
                    float(np.max(np.abs(qp.g), initial=0.0)), 1e-300)
        violated = ~work & (Bu - qp.g > run.opts.flip_tol * scale)
        if not violated.any():
            return u, work
        work |= violated
    raise RuntimeError("no feasible point found on the faces of the violated rows")


def _monotone(run: _Run, u: np.ndarray, active: np.ndarray, budget: int,
              done: int) -> _Outcome:
    """The fallback: a primal feasible active-set method (Nocedal and Wright, Numerical
    Optimization, Alg. 16.3; Hungerländer and Rendl, SIAM J. Optim. 25, 2015, for
    the same safeguard of a PDAS method) with the same inexact face solves.

    From a feasible point (:func:`_feasible_start`) each step solves the face of the
    working set by projected PCG (monotone in the energy, since CG is), moves
    towards it as far as the inactive rows allow and adds the blocking row, or,
    at the face's minimum, drops the row with the most negative multiplier. Every
    step keeps ``Bu <= g`` and does not raise the energy ``J``, so no working set
    recurs while ``J`` falls: with exact face solves the method terminates. With
    inexact ones a multiplier may have the wrong sign; a dropped row that blocks the
    very next step at once is taken as that, and the faces are solved tighter from
    then on. It stops when the verification passes.
    """
    qp, B, opts, tol = run.qp, run.B, run.opts, run.tol
    try:
        u, work = _feasible_start(run, u, active)
    except (RuntimeError, ValueError) as err:
        return _Outcome(u, np.zeros(qp.m), active, "failed",
                        f"no feasible start for the fallback: {err}", done)
    p = np.zeros(qp.m)
    dropped = -1
    for k in range(1, budget + 1):
        try:
            x, face = run.face_solve(u, work)
        except RuntimeError as err:                  # dependent rows without a basis
            return _Outcome(u, np.maximum(p, 0.0), work, "failed",
                            f"no face for the working set of fallback step {k}: {err}",
                            done + k - 1)
        d = x - u
        Bd, slack = B @ d, qp.g - B @ u
        blocking = np.flatnonzero(~work & (Bd > 0) & (Bd > slack))
        if blocking.size:                                  # a row stops the step short
            t = np.maximum(slack[blocking], 0.0) / Bd[blocking]
            j = blocking[np.argmin(t)]
            if j == dropped and t.min() <= 0.0:   # dropped on an inexact multiplier
                run.tighten()
            u = u + float(t.min()) * d
            work[j] = True
            p = np.zeros(qp.m)
            dropped = -1
            run.record("fallback", work, u, np.nan)       # no multipliers mid-step
        else:
            u = x
            p = run.multipliers(u, work, face)
            kkt = kkt_residuals(qp, u, np.maximum(p, 0.0)).max
            run.record("fallback", work, u, kkt)
            p_scale = float(np.max(np.abs(p))) if p.size else 0.0
            i = int(np.argmin(np.where(work, p, np.inf))) if work.any() else -1
            if i >= 0 and p[i] < -opts.flip_tol * p_scale:
                work[i] = False                            # leave the most negative row
                dropped = i
            elif run.verified(u, np.maximum(p, 0.0), kkt):
                return _Outcome(u, np.maximum(p, 0.0), work, "converged",
                                f"verified after {k} steps (KKT {kkt:.1e}, certified "
                                f"bound <= {tol:.0e})", done + k)
            elif not run.tighten():
                return _Outcome(u, np.maximum(p, 0.0), work, "inaccurate",
                                f"not verified at the inner tolerance floor {run.rtol:.0e} "
                                f"after {k} steps (KKT {kkt:.1e})", done + k)
        if run.out_of_time():
            return _Outcome(u, np.maximum(p, 0.0), work, "time_limit",
                            f"time limit reached at fallback step {k}", done + k)
    return _Outcome(u, np.maximum(p, 0.0), work, "max_iter",
                    f"not verified after {budget} steps", done + budget)


# ---------------------------------------------------------------------------------------
# Friction: the primal-dual active set method of Hüeber, Stadler and Wohlmuth (2D, 3D)
# ---------------------------------------------------------------------------------------

#: Tangential state of a row whose tangential multiplier is free (stick: ``slip = 0``);
#: ``+1``/``-1`` slip with ``lam = +-s``, ``0``: no friction force (``s = 0``).
STICK = 2

#: Iterative refinement steps after each solve with the factorised ``A``.
FRICTION_REFINE = 3

#: 3D: the friction KKT residual at which the Newton steps on fixed sets stop; they also
#: stop after :data:`FRICTION_STALL` such steps in a row that do not halve the best
#: residual on these sets (round-off). 2D ends on the fixed sets themselves.
FRICTION_ROUNDOFF = 1e-14
FRICTION_STALL = 3

#: Largest number of constrained rows of a frictional solve: the Schur complement of the
#: ``dim * m`` normal and tangential rows is dense.
FRICTION_MAX_M = 2500


def supports(qp: ContactQP) -> tuple[bool, str]:
    """Every frictionless problem; a frictional one with nodal rows (2D or 3D) and at most
    :data:`FRICTION_MAX_M` of them (the dense Schur complement of the friction branch)."""
    fr = qp.friction
    if fr is None:
        return True, ""
    if qp.C is not None or qp.stabilisation is not None:
        return False, "friction is solved for nodal rows only (no reverse or stabilised rows)"
    if fr.T.shape[0] != qp.m * (qp.dim - 1):
        return False, (f"friction is solved with dim - 1 tangential rows per constrained "
                       f"row; this problem has {fr.T.shape[0]} tangential rows for {qp.m}")
    if qp.m > FRICTION_MAX_M:
        return False, (f"{qp.m} constrained rows: the friction branch forms the dense Schur "
                       f"complement of dim * m rows, for at most {FRICTION_MAX_M} rows")
    return True, ""


@dataclass
class ContactSchur:
    """``A`` factorised once and the dense Schur complement ``S = G A^-1 G'`` of the
    normal and tangential rows ``G = [B; T]`` (formed by partial solves on the support
    of ``G``, as :mod:`solvers.pdas` forms ``B A^-1 B'``).

    Attributes
    ----------
    chol : solvers.kernels.cholesky.Cholesky
    A : sparse
    G : ((1 + k) m, n) sparse
        ``k = dim - 1`` tangential rows per constrained node.
    S : ((1 + k) m, (1 + k) m) array
    """

    chol: object
    A: object
    G: object
    S: np.ndarray

    def solve_A(self, rhs: np.ndarray) -> np.ndarray:
        """``A^-1 rhs``, iteratively refined (:data:`FRICTION_REFINE` steps)."""
        x = self.chol.solve(rhs)
        for _ in range(FRICTION_REFINE):
            x = x + self.chol.solve(rhs - self.A @ x)
        return x


def contact_schur(qp: ContactQP, factorization: str = "auto") -> ContactSchur:
    """:class:`ContactSchur` of the frictional ``qp``, computed once per problem and kept
    in ``qp.cache.contact_schur`` (the steps of a load path share ``A``, ``B`` and ``T``)."""
    kept = qp.cache.contact_schur.get(factorization)
    if kept is not None:
        return kept
    G = sp.vstack([qp.B, qp.friction.T]).tocsr()
    chol = factorize(qp.A, factorization, components=G.indices)
    ops = ContactSchur(chol, sp.csr_matrix(qp.A), G, dense_schur(chol, G))
    qp.cache.contact_schur[factorization] = ops
    return ops


def tangential_update(state: np.ndarray, v: np.ndarray, bound: np.ndarray,
                      eps: float) -> np.ndarray:
    """The stick/slip sets of Hüeber, Stadler and Wohlmuth (2008, Alg. 2 in 2D) from
    ``v = lam + c slip``: stick where ``|v_i| <= s_i``, slip with ``lam_i = s_i sign(v_i)``
    elsewhere, no force where ``s_i = 0``.

    Round-off hysteresis (as :func:`solvers.kernels.active_set.pdas_update`): a sticking row stays
    while ``|v_i| <= s_i + eps``, a slipping one keeps its sign while
    ``sign_i v_i >= s_i - eps``, so that a row on the stick/slip boundary (a weakly
    slipping node) cannot flip forever on rounding.

    3D: called with the per-node norm ``|v_i|`` (:meth:`problems.friction.data.Friction.magnitude`)
    as ``v``; a slipping node is then ``+1``.
    """
    new = np.where(np.abs(v) <= bound, STICK, np.sign(v)).astype(int)
    new = np.where((state == STICK) & (np.abs(v) <= bound + eps), STICK, new)
    new = np.where((np.abs(state) == 1) & (state * v >= bound - eps), state, new)
    new[bound <= 0] = 0
    return new


def _damped_tangential(state: np.ndarray, proposed: np.ndarray, v: np.ndarray,
                       bound: np.ndarray, limit: int) -> np.ndarray:
    """Only the ``limit`` largest proposed stick/slip changes, ranked by how far
    ``|v_i|`` is from ``s_i`` relative to the largest bound."""
    changes = np.flatnonzero(proposed != state)
    if changes.size <= limit:
        return proposed
    scale = max(float(np.max(bound, initial=0.0)), 1e-300)
    score = np.abs(np.abs(v[changes]) - bound[changes]) / scale
    chosen = changes[np.argsort(-score, kind="stable")[:limit]]
    new = state.copy()
    new[chosen] = proposed[chosen]
    return new


def _damped_sets(qp: ContactQP, sets: tuple, proposed: tuple, Bu, p, v, bound, limit: int,
                 mu: float | None) -> tuple[np.ndarray, np.ndarray]:
    """The normal and stick/slip sets with only the ``limit`` largest proposed changes of
    each (:func:`solvers.kernels.active_set.damped_update`, :func:`_damped_tangential`); Coulomb
    (``mu``): no friction force off the normal set."""
    normal = damped_update(qp, sets[0], proposed[0], None, p, limit, Bu=Bu)
    state = _damped_tangential(sets[1], proposed[1], v, bound, limit)
    if mu is not None:
        state = np.where(normal, state, 0)
    return normal, state


def _friction_step(ops: ContactSchur, rhs: np.ndarray, h: np.ndarray, m: int,
                   normal: np.ndarray, state: np.ndarray, s: np.ndarray,
                   mu: float | None) -> tuple[np.ndarray, int]:
    """The Newton step of the sets: ``y = (p, lam)`` with ``B_i u = g_i`` on the normal
    active rows (``p_i = 0`` off them), ``slip_i = 0`` on the sticking rows and
    ``lam_i = s_i sign_i`` on the slipping ones, ``u = A^-1 (f - G'y)``; eliminating
    ``u`` leaves the rows' block of ``S`` (``rhs = G A^-1 f - h``).

    Tresca (``mu`` None): ``S`` on the normal active and sticking rows is symmetric
    positive definite; dependent rows are reduced to a basis consistent with ``h``
    (:func:`solvers.kernels.cholesky.row_basis`, their multipliers zero). Coulomb
    (``mu``): ``lam_i = mu sign_i p_i`` on the slipping rows couples ``lam`` to ``p``
    and the block is not symmetric (a dense LU).

    Returns
    -------
    (y, n_dependent)
    """
    J_p = np.flatnonzero(normal)
    J_t = np.flatnonzero(state == STICK)
    slip = np.flatnonzero(np.abs(state) == 1)
    rows = np.concatenate([J_p, m + J_t])
    y = np.zeros(2 * m)
    if mu is None:
        y[m + slip] = s[slip] * state[slip]
        b = rhs[rows] - ops.S[np.ix_(rows, m + slip)] @ y[m + slip]
        if not rows.size:
            return y, 0
        basis = row_basis(ops.S[np.ix_(rows, rows)], h[rows], labels=rows)
        y[rows[basis.kept]] = sla.cho_solve(basis.factor, b[basis.kept])
        return y, int(basis.dropped.size)
    if not rows.size:
        return y, 0
    K = ops.S[np.ix_(rows, rows)].copy()
    where = np.searchsorted(J_p, slip)                # slipping rows lie in the normal set
    K[:, where] += ops.S[np.ix_(rows, m + slip)] * (mu * state[slip])
    try:
        x = sla.lu_solve(sla.lu_factor(K, check_finite=True), rhs[rows])
    except (sla.LinAlgError, ValueError) as err:
        raise RuntimeError(f"singular Coulomb step system: {err}") from None
    y[rows] = x
    y[m + slip] = mu * state[slip] * y[slip]
    return y, 0


def _friction_step_discs(ops: ContactSchur, rhs: np.ndarray, m: int, normal: np.ndarray,
                         state: np.ndarray, s: np.ndarray, lam: np.ndarray, v: np.ndarray,
                         c: float, mu: float | None) -> np.ndarray:
    """The 3D Newton step of the sets (Hüeber, Stadler and Wohlmuth 2008): ``y = (p, lam)``
    with ``B_i u = g_i`` on the normal active rows (``p_i = 0`` off them), ``slip_i = 0``
    on the sticking nodes, ``lam_i = 0`` where no friction force acts, and on the slipping
    nodes the linearisation at ``(lam, v = lam + c slip)`` of the complementarity function

        C_i = max(s_i, |v_i|) lam_i - s_i v_i = 0,

    whose generalised derivative where ``|v_i| > s_i`` gives, with ``n_i = v_i / |v_i|``
    and ``lam_i`` replaced by its projection ``l_i = s_i lam_i / max(s_i, |lam_i|)`` onto
    the disc (their globalising modification)::

        ((|v_i| - s_i) I + l_i n_i') lam_i+ + c (l_i n_i' - s_i I) slip_i+ = |v_i| l_i.

    ``u = A^-1 (f - G'y)`` is eliminated (``slip+ = rhs_T - (S y+)_T``, ``rhs = G A^-1 f
    - h``), leaving the rows' block of ``S`` with the slipping nodes' rows replaced: one
    dense LU (the block is not symmetric). Coulomb (``mu``; ``s = mu p`` of the iterate):
    ``s_i`` varies with ``p_i``, adding ``-mu v_i p_i+`` on the left and ``-s_i v_i`` on
    the right.
    """
    k = lam.size // m
    nodes_rows = lambda nodes: (m + k * nodes[:, None] + np.arange(k)).ravel()
    J_p = np.flatnonzero(normal)
    stick, slip = np.flatnonzero(state == STICK), np.flatnonzero(state == 1)
    rows = np.concatenate([J_p, nodes_rows(stick), nodes_rows(slip)])
    y = np.zeros(m + lam.size)
    if not rows.size:
        return y
    K, b = ops.S[np.ix_(rows, rows)].copy(), rhs[rows].copy()
    first = J_p.size + k * stick.size
    V, s_q = v.reshape(m, k)[slip], s[slip]
    size = np.sqrt(np.sum(V * V, axis=1))
    n = V / np.maximum(size, 1e-300)[:, None]
    held = lam.reshape(m, k)[slip]
    held_size = np.sqrt(np.sum(held * held, axis=1))
    l = held * (s_q / np.maximum(np.maximum(s_q, held_size), 1e-300))[:, None]
    outer = l[:, :, None] * n[:, None, :]
    eye = np.eye(k)[None]
    M = (size - s_q)[:, None, None] * eye + outer
    N = outer - s_q[:, None, None] * eye
    block = -c * np.einsum("qij,qjr->qir", N, K[first:].reshape(slip.size, k, rows.size))
    right = size[:, None] * l - c * np.einsum("qij,qj->qi", N, b[first:].reshape(slip.size, k))
    for q in range(slip.size):
        block[q, :, first + k * q:first + k * (q + 1)] += M[q]
    if mu is not None:
        block[np.arange(slip.size), :, np.searchsorted(J_p, slip)] -= mu * V
        right -= s_q[:, None] * V
    K[first:], b[first:] = block.reshape(-1, rows.size), right.ravel()
    try:
        y[rows] = sla.lu_solve(sla.lu_factor(K, check_finite=True), b)
    except (sla.LinAlgError, ValueError) as err:
        raise RuntimeError(f"singular 3D friction step system: {err}") from None
    return y


def solve_friction(qp: ContactQP, tol: float, max_iter: int, time_limit: float | None,
                   u0: np.ndarray | None, p0: np.ndarray | None,
                   opts: Options) -> SolveResult:
    """A Tresca step (or, with ``coulomb="monolithic"``, a Coulomb step) by the
    primal-dual active set method of Hüeber, Stadler and Wohlmuth (SIAM J. Sci. Comput.
    30, 2008; in 2D Kunisch and Stadler, M2AN 39, 2005, where it is the semismooth
    Newton method of the max/sign formulation).

    The sets, from ``(u, p, lam)`` and ``c`` (relative to the stiffness scale):
    normal active ``N = {p_i + c (B_i u - g_i) > 0}``
    (:func:`solvers.kernels.active_set.pdas_update`); stick ``{|lam_i + c slip_i| <= s_i}``
    (3D: the norm of the node's 2-vector), slip
    elsewhere (:func:`tangential_update`). Each step solves the sets' linear system
    exactly (2D :func:`_friction_step`, 3D :func:`_friction_step_discs`: ``A`` factorised
    once, the dense Schur complement of the normal and tangential rows,
    :func:`contact_schur`). 2D: it stops when the sets repeat; the answer is then exact to
    round-off. 3D: the slipping nodes' condition is not linear (the disc's edge is
    curved), so on repeated sets the Newton steps go on until the friction KKT residual is
    at :data:`FRICTION_ROUNDOFF` or stalls (:data:`FRICTION_STALL`). The answer is judged by
    :func:`problems.friction.residuals.friction_residuals`.

    Tresca: ``s = qp.friction.slip_bound``. Coulomb, monolithic (the quasi-variational
    inequality, ``s = mu p`` of the iterate): the stick/slip sets use the bound
    ``mu (p_i + c (B_i u - g_i))_+`` on the normal active rows and the slipping rows
    carry ``lam_i = mu sign_i p_i`` in the step (3D: the linearisation in ``p_i`` too,
    :func:`_friction_step_discs`). Its convergence is shown for small
    ``mu`` only; a run that does not converge says so.

    A set pair that recurs is damped: only the ``k`` largest changes apply (``k`` halved
    at each further recurrence, down to one). Recurring under single changes, a Tresca
    step goes on from its best iterate by a method that cannot cycle (:func:`_dual_fallback`,
    ``fallback="monotone"``; ``stats["fallback"]`` says it ran); a monolithic Coulomb run,
    or ``fallback="none"``, ends ``failed`` with the best iterate.
    """
    t_start = time.perf_counter()
    check_positive_diagonal(qp.A)
    ok, reason = supports(qp)
    if not ok:
        raise ValueError(f"semismooth_newton: {reason}")
    fr, m = qp.friction, qp.m
    monolithic = fr.law == "coulomb" and opts.coulomb == "monolithic"
    mu = fr.mu if monolithic else None
    c_eff = opts.c * stiffness_scale(qp)
    c_slip = opts.c_slip * stiffness_scale(qp)
    ops = contact_schur(qp)
    w = ops.solve_A(qp.f)
    r = fr.previous - fr.offset                              # slip = T u - r
    h = np.concatenate([qp.g, r])
    Gw = ops.G @ w
    rhs = Gw - h
    every_step = opts.displacement == "every_step"
    setup_time = time.perf_counter() - t_start

    t_solve = time.perf_counter()
    u = np.zeros(qp.n) if u0 is None else np.array(u0, dtype=float)
    p = np.zeros(m) if p0 is None else np.maximum(np.asarray(p0, dtype=float), 0.0)
    discs = fr.components > 1
    lam = np.zeros(fr.T.shape[0])
    normal = initial_active_set(qp, u0, p0, c_eff)

    def bound_of(normal, Bu, p):
        if mu is None:
            return fr.slip_bound
        return np.where(normal, mu * np.maximum(p + c_eff * (Bu - qp.g), 0.0), 0.0)

    def sets_of(state, normal, Gu, p, lam):
        """The stick/slip sets from the rows' values ``Gu = (B u, T u)``."""
        s_hat = bound_of(normal, Gu[0], p)
        v = lam + c_slip * (Gu[1] - r)
        eps = opts.flip_tol * max(float(np.max(np.abs(v), initial=0.0)),
                                  float(np.max(s_hat, initial=0.0)), 1e-300)
        return tangential_update(state, fr.magnitude(v) if discs else v, s_hat, eps), v, s_hat

    state, v, s_hat = sets_of(np.zeros(m, dtype=int), normal, (qp.B @ u, fr.T @ u), p, lam)
    history = {"n_active": [], "n_stick": [], "n_slip": [], "kkt_max": [], "time": []}
    seen = {normal.tobytes() + state.tobytes()}
    limit: int | None = None
    best = None
    status, message = "max_iter", f"the sets did not repeat within {max_iter} steps"
    n_dependent, k = 0, 0
    fixed_best, stalled = np.inf, 0                  # 3D: the Newton steps on fixed sets
    fallback_steps = None                            # the dual fallback's steps, if it ran
    law = "Coulomb (monolithic)" if monolithic else "Tresca"
    for k in range(1, max_iter + 1):
        try:
            if discs:
                y = _friction_step_discs(ops, rhs, m, normal, state,
                                         fr.slip_bound if mu is None else s_hat, lam, v,
                                         c_slip, mu)
            else:
                y, n_dependent = _friction_step(ops, rhs, h, m, normal, state, fr.slip_bound,
                                                mu)
        except InfeasibleError as err:
            status, message = "failed", f"{law} step {k}: {err}"
            break
        except RuntimeError as err:
            status, message = "failed", f"{law} step {k}: {err}"
            break
        p, lam = y[:m], y[m:]
        if every_step:
            u = ops.solve_A(qp.f - ops.G.T @ y)
            Gu = (qp.B @ u, fr.T @ u)
            kkt = _friction_kkt(qp, u, p, lam, mu)
        else:                                      # the rows only: G u = G A^-1 f - S y
            Gy = Gw - ops.S @ y
            Gu = (Gy[:m], Gy[m:])
            kkt = _friction_row_kkt(qp, Gu[0], Gu[1] - r, p, lam, mu)
        history["n_active"].append(int(normal.sum()))
        history["n_stick"].append(int(np.count_nonzero(state == STICK)))
        history["n_slip"].append(int(np.count_nonzero(np.abs(state) == 1)))
        history["kkt_max"].append(kkt)
        history["time"].append(time.perf_counter() - t_solve)
        if best is None or kkt < best[0]:
            best = (kkt, u, p, lam, normal, state)
        proposed_normal = pdas_update(qp, normal, u, p, opts.flip_tol, Bu=Gu[0])
        proposed_state, v, s_hat = sets_of(state, proposed_normal, Gu, p, lam)
        new_normal, new_state = proposed_normal, proposed_state
        if limit is not None:
            new_normal, new_state = _damped_sets(qp, (normal, state), (proposed_normal,
                                                 proposed_state), Gu[0], p, fr.magnitude(v),
                                                 s_hat, limit, mu)
        if np.array_equal(new_normal, normal) and np.array_equal(new_state, state):
            stalled = stalled + 1 if kkt > 0.5 * fixed_best else 0
            fixed_best = min(fixed_best, kkt)
            if not discs or kkt <= FRICTION_ROUNDOFF or stalled >= FRICTION_STALL:
                if kkt <= tol:
                    status, message = "converged", (f"{law}: sets fixed after {k} steps, "
                                                    f"friction KKT max {kkt:.1e}")
                else:
                    status, message = "inaccurate", (f"{law}: sets fixed after {k} steps but "
                                                     f"friction KKT max {kkt:.1e} > tol "
                                                     f"{tol:.0e}")
                break
            # 3D: the same sets, the Newton steps go on to round-off
        else:
            fixed_best, stalled = np.inf, 0
            key = new_normal.tobytes() + new_state.tobytes()
            if key in seen:                                     # cycling: damp the updates
                if limit == 1:
                    kkt, u, p, lam, normal, state = best
                    status = "converged" if kkt <= tol else "failed"
                    message = (f"{law}: the sets cycle under single changes at step {k}; best "
                               f"step has friction KKT max {kkt:.1e}")
                    if status == "failed" and mu is None and opts.fallback == "monotone":
                        y, (fallback_steps, ok, method) = _dual_fallback(
                            ops, rhs, m, fr, p, lam, normal, state)
                        p, lam = y[:m], y[m:]
                        u = ops.solve_A(qp.f - ops.G.T @ y)
                        kkt = _friction_kkt(qp, u, p, lam, None)
                        status = ("converged" if kkt <= tol else "inaccurate") if ok \
                            else "max_iter"
                        message += (f"; fell back to {method} on the dual from the best "
                                    f"step: {fallback_steps} steps, friction KKT max {kkt:.1e}")
                    break
                n_changes = int(np.count_nonzero(proposed_normal != normal)
                                + np.count_nonzero(proposed_state != state))
                limit = max(1, n_changes // 2) if limit is None else max(1, limit // 2)
                seen = set()
                new_normal, new_state = _damped_sets(qp, (normal, state), (proposed_normal,
                                                     proposed_state), Gu[0], p,
                                                     fr.magnitude(v), s_hat, limit, mu)
                key = new_normal.tobytes() + new_state.tobytes()
            seen.add(key)
            normal, state = new_normal, new_state
        if time_limit is not None and time.perf_counter() - t_start > time_limit:
            status, message = "time_limit", f"time limit {time_limit:g} s reached at step {k}"
            break
    if not every_step and best is not None and fallback_steps is None:
        u = ops.solve_A(qp.f - ops.G.T @ np.concatenate([p, lam]))
        rows_kkt, kkt = kkt, _friction_kkt(qp, u, p, lam, mu)
        message += (f"; the steps judged on the rows (friction KKT max {rows_kkt:.1e}), u "
                    f"formed at the end: friction KKT max {kkt:.1e}")
        if status == "converged" and kkt > tol:
            status = "inaccurate"
    if limit is not None:
        message += f"; damped (at most {limit} set changes per step)"
    if n_dependent:
        message += f"; {n_dependent} linearly dependent row(s) carry a zero multiplier"
    stats = {"friction": "coulomb_monolithic" if monolithic else "tresca_step",
             "newton_steps": k, "n_active": int(np.count_nonzero(p > 0)),
             "n_stick": int(np.count_nonzero(state == STICK)),
             "n_slip": int(np.count_nonzero(np.abs(state) == 1)),
             "n_dependent": n_dependent, "damped": limit is not None,
             "fallback": fallback_steps is not None,
             "fallback_steps": 0 if fallback_steps is None else fallback_steps,
             "factorization": ops.chol.backend, "c_eff": c_eff}
    return SolveResult(u=u, p=p, claimed_status=status, message=message, iterations=k,
                       setup_time=setup_time, solve_time=time.perf_counter() - t_solve,
                       history=history, stats=stats, tangential=lam)


def _dual_fallback(ops: ContactSchur, rhs: np.ndarray, m: int, fr, p, lam, normal,
                   state) -> tuple[np.ndarray, tuple]:
    """A Tresca step's dual ``min 1/2 y'Sy - rhs'y`` over ``p >= 0``, ``|lam_i| <= s_i``
    (the same ``S`` and ``rhs`` as the Newton steps) by a method that cannot cycle,
    started from the best Newton step: 2D, the primal active-set method on the box
    (:func:`solvers.kernels.tresca.box_qp_active_set`, finite, its sets from the step's);
    3D, the semismooth Newton method on the projection equation, globalised on the dual
    objective (:func:`solvers.kernels.tresca.disc_qp_newton`, from the step's ``y``).

    Returns
    -------
    (y, (steps, converged, name))
    """
    from solvers.kernels.tresca import box_qp_active_set, disc_qp_newton, dual_box

    bound = fr.slip_bound
    if fr.components > 1:
        y, _, steps, ok = disc_qp_newton(ops.S, rhs, m, bound,
                                         start=np.concatenate([p, lam]))
        return y, (steps, ok, "the globalised Newton method of the projection equation")
    lo, hi = dual_box(m, bound)
    start = np.concatenate([np.where(normal, 0, -1),
                            np.where(np.abs(state) == 1, state, 0)])
    y, _, steps, ok = box_qp_active_set(ops.S, rhs, lo, hi, start=start)
    return y, (steps, ok, "the primal active-set method")


def _friction_kkt(qp: ContactQP, u, p, lam, mu: float | None) -> float:
    """The friction KKT residual (:func:`problems.friction.residuals.friction_residuals`) of the step;
    Coulomb (``mu``): of the Tresca step with ``s = mu p``."""
    return friction_residuals(_with_bound(qp, p, mu), u, p, lam).max


def _friction_row_kkt(qp: ContactQP, Bu, slip, p, lam, mu: float | None) -> float:
    """The rows' part of :func:`_friction_kkt` (every residual but the stationarity,
    :func:`problems.friction.residuals.friction_row_residuals`) from ``Bu`` and ``slip``."""
    return max(friction_row_residuals(_with_bound(qp, p, mu), Bu, slip, p, lam)[0].values())


def _with_bound(qp: ContactQP, p, mu: float | None) -> ContactQP:
    """``qp``; Coulomb (``mu``): its Tresca step with ``s = mu p``."""
    if mu is None:
        return qp
    return replace(qp, friction=replace(qp.friction, slip_bound=mu * np.maximum(p, 0.0)))


SOLVER = SolverSpec(
    name="semismooth_newton",
    summary="inexact semismooth Newton / primal-dual active set with warm-started "
            "projected multigrid-PCG inner solves and an inexactness control",
    solve=solve,
    parameters=(
        AHAT,
        ComponentParameter(
            "inner", "ppcg",
            {"ppcg": (Parameter("rtol", 1e-2, "initial relative tolerance of the inner "
                                "projected PCG", low=0.0, high=1.0, low_open=True),
                      Parameter("min_rtol", 1e-13, "floor of the inner tolerance", low=0.0,
                                high=1e-3, low_open=True),
                      Parameter("max_steps", 500, "cap on inner PCG steps per Newton step",
                                low=1, kind=int))},
            "inner solver of a Newton step: projected PCG with one V-cycle"),
        FACE_PROJECTION,
        Parameter("forcing", 0.1, "inner tolerance <= forcing * KKT residual (Eisenstat-Walker "
                  "type forcing term)", low=0.0, high=1.0, low_open=True),
        Parameter("tighten", 1e-2, "factor on the inner tolerance when the active set repeats "
                  "without verification", low=0.0, high=1.0, low_open=True),
        Parameter("patience", 10, "Newton steps without halving the best KKT residual "
                  "before the Newton iteration counts as stalled (0: the fallback from the "
                  "start)", low=0, kind=int),
        Parameter("fallback", "monotone", "what runs when the Newton iteration stalls (the "
                  "active set cycles under single changes, or 'patience' steps without "
                  "progress): the monotone primal active-set method, or nothing (status "
                  "'failed'); on a Tresca step whose sets cycle under single changes, the "
                  "step's dual by the primal active-set method (2D) or the globalised Newton "
                  "method of the projection equation (3D)", choices=("monotone", "none")),
        Parameter("c", 1.0, "PDAS parameter relative to the stiffness scale", low=0.0,
                  low_open=True),
        Parameter("flip_tol", 1e-13, "relative size below which a sign change does not "
                  "change the active set", low=0.0, high=1e-6),
        Parameter("c_slip", 0.01, "parameter of the stick/slip sets (lam + c slip) relative "
                  "to the stiffness scale (friction only)", low=0.0, low_open=True),
        Parameter("displacement", "every_step", "friction only: when the displacement u = "
                  "A^-1 (f - G'y) is formed, at every Newton step (the sets and the stop judged "
                  "on u's residuals) or once at the end (judged on the rows G u = G A^-1 f - "
                  "S y; one solve with A's factor per run instead of one per step)",
                  choices=("every_step", "at_end")),
        Parameter("coulomb", "tresca_step", "on a Coulomb problem: solve the Tresca step of "
                  "its given slip bound (a fixed point s = mu p runs around it), or Coulomb "
                  "monolithically with s = mu p inside the Newton iteration (Hueber-Stadler-"
                  "Wohlmuth)", choices=("tresca_step", "monolithic")),
    ),
    presets=VERIFIED_PRESETS,
    default_max_iter=100,
    role=Role.NEWTON,
    supports=supports,
    handles_friction=True,
    facets_reason=("its friction branch is the isotropic law (the Newton step differentiates "
                   "the projection onto discs); the faceted law is a QP, taken by the QP "
                   "libraries and tresca_exact"),
)
