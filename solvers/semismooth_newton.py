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
Gould-Hribar-Nocedal; :func:`solvers.preconditioners.face_projector`), which
keeps the V-cycle's rate on the face, or orthogonally (``face="euclidean"``,
their ``I - B_I'(B_I B_I')^{-1} B_I``), which cuts the V-cycle's smooth correction
at the constrained DOFs and needs about twice the steps. The solve is warm
started from the previous iterate. The multipliers are those the projector defines,
``p_I = (W' B_I')^{-1} W' (f - A u)`` (least squares for ``euclidean``), ``p = 0`` off ``I``.

Inexactness control: the inner relative tolerance starts at ``inner.rtol`` and
is tied to the outer residual (a forcing term ``min(rtol, forcing * KKT)``), so
early steps with a wrong active set are cheap and the last ones accurate; when
the active set repeats, the tolerance is tightened by ``tighten`` until the
verification passes. A cycling active set is damped as in :mod:`solvers.pdas`.
It stops when the suite's verification passes (KKT residuals and the certified
energy bound, :func:`solvers.interface.verify`), so its claims are never refuted.
"""
from __future__ import annotations

import time

import numpy as np

from problems.qp import ContactQP, kkt_residuals
from problems.spec import ComponentParameter, Options, Parameter
from solvers import preconditioners as pc
from solvers.interface import SolveResult, SolverSpec, certify
from solvers.pdas import _check_positive_diagonal, _damped_update, _pdas_update, _stiffness_scale


def projected_pcg(A, face: pc.FaceProjector, f, gI, M, x0, rtol: float, max_steps: int):
    """``min 1/2 x'Ax - f'x  s.t.  B_I x = g_I`` by projected PCG from ``x0``.

    ``face`` projects onto ``ker B_I`` (:func:`solvers.preconditioners.face_projector`);
    the preconditioner is ``Pi M Pi'``. ``rtol`` is relative to the projected
    preconditioned residual at ``x0`` lifted onto the face.

    Returns
    -------
    (x, steps)
    """
    x = face.lift(np.array(x0, dtype=float), gI)           # a feasible start near x0
    precondition = lambda r: face.project(M(face.project_T(r)))
    r = f - A @ x
    z = precondition(r)
    d = z.copy()
    rz = float(r @ z)
    r0 = np.sqrt(max(rz, 0.0))
    steps = 0
    while steps < max_steps and np.sqrt(max(rz, 0.0)) > rtol * r0 and rz > 0:
        Ad = A @ d
        alpha = rz / float(d @ Ad)
        x += alpha * d
        r = r - alpha * Ad
        z = precondition(r)
        rz_new = float(r @ z)
        d = z + (rz_new / rz) * d
        rz = rz_new
        steps += 1
    return x, steps


def solve(qp: ContactQP, tol: float, max_iter: int, time_limit: float | None,
          u0: np.ndarray | None, p0: np.ndarray | None, opts: Options) -> SolveResult:
    """Solve ``qp`` by the inexact semismooth Newton method (module docstring).

    ``max_iter`` caps the Newton (active-set) steps; ``stats`` count the inner
    PCG steps and the V-cycles (one per inner step plus one per Newton step for
    the initial residual) and those of the setup.
    """
    t_start = time.perf_counter()
    if qp.C is not None:
        raise ValueError("semismooth_newton solves Bu <= g only; the ContactQP has a "
                         "stabilisation block C (Sect. 7.5)")
    _check_positive_diagonal(qp.A)
    vc = pc.component_vcycle(qp, opts.ahat)   # unscaled: PCG needs no spectral bounds
    M = vc.raw
    c_eff = opts.c * _stiffness_scale(qp)
    B = qp.B.tocsr()
    hops = pc.face_hops(qp.dim, opts.face.options.get("hops", 0))
    setup_time = time.perf_counter() - t_start
    vcycles_setup = vc.n_applications

    t_solve = time.perf_counter()
    u = np.zeros(qp.n) if u0 is None else np.array(u0, dtype=float)
    p = np.zeros(qp.m) if p0 is None else np.maximum(np.asarray(p0, dtype=float), 0.0)
    if u0 is None and p0 is None:
        active = np.zeros(qp.m, dtype=bool)
    else:
        active = (p + c_eff * (B @ u - qp.g)) > 0
    rtol = opts.inner.options["rtol"]
    history = {"n_active": [], "inner_steps": [], "inner_rtol": [], "kkt_max": [], "time": []}
    seen: set[bytes] = set()
    face = face_rows = None
    limit: int | None = None
    status, message, k = "max_iter", f"not verified after {max_iter} Newton steps", 0
    for k in range(1, max_iter + 1):
        idx = np.flatnonzero(active)
        if face is None or not np.array_equal(idx, face_rows):   # a repeated set keeps its factor
            face, face_rows = pc.face_projector(qp.A, B[idx], opts.face.kind, hops), idx
        u, steps = projected_pcg(qp.A, face, qp.f, qp.g[idx], M, u, rtol,
                                 opts.inner.options["max_steps"])
        p = np.zeros(qp.m)
        p[idx] = face.multipliers(qp.f - qp.A @ u)
        kkt = kkt_residuals(qp, u, p).max
        history["n_active"].append(int(idx.size))
        history["inner_steps"].append(steps)
        history["inner_rtol"].append(rtol)
        history["kkt_max"].append(kkt)
        history["time"].append(time.perf_counter() - t_solve)
        proposed = _pdas_update(qp, active, u, p, opts.flip_tol)
        new = proposed if limit is None else _damped_update(qp, active, proposed, u, p, limit)
        if np.array_equal(new, active):
            if kkt <= tol and certify(qp, u, p, tol).meets(tol):
                status = "converged"
                message = (f"active set fixed after {k} Newton steps, verified (KKT "
                           f"{kkt:.1e}, certified bound <= {tol:.0e})")
                break
            if rtol <= opts.inner.options["min_rtol"]:
                status = "inaccurate"
                message = (f"active set fixed but not verified at the inner tolerance floor "
                           f"{rtol:.0e} (KKT {kkt:.1e})")
                break
            rtol = max(rtol * opts.tighten, opts.inner.options["min_rtol"])
        else:
            key = new.tobytes()
            if key in seen:                                   # cycling: damp the updates
                n_changes = int(np.count_nonzero(proposed != active))
                limit = max(1, n_changes // 2) if limit is None else max(1, limit // 2)
                seen = set()
                new = _damped_update(qp, active, proposed, u, p, limit)
            seen.add(new.tobytes())
            active = new
            rtol = max(min(rtol, opts.forcing * kkt), opts.inner.options["min_rtol"])
        if time_limit is not None and time.perf_counter() - t_start > time_limit:
            status, message = "time_limit", f"time limit {time_limit:g} s reached at step {k}"
            break
    inner = int(np.sum(history["inner_steps"]))
    stats = {"newton_steps": k, "inner_steps": inner, "n_vcycles": vc.n_applications - vcycles_setup,
             "vcycles_setup": vcycles_setup, "n_active": int(np.count_nonzero(p > 0)),
             "ahat_kind": vc.kind, "face": opts.face.kind, "damped": limit is not None}
    return SolveResult(u=u, p=p, claimed_status=status, message=message, iterations=k,
                       setup_time=setup_time, solve_time=time.perf_counter() - t_solve,
                       history=history, stats=stats)


def _ahat_parameter() -> ComponentParameter:
    """The V-cycle's options, shared with (declared once in) the augmented projection."""
    from solvers.augmented_projection import SOLVER as AP

    return next(p for p in AP.parameters if p.name == "ahat")


SOLVER = SolverSpec(
    name="semismooth_newton",
    summary="inexact semismooth Newton / primal-dual active set with warm-started "
            "projected multigrid-PCG inner solves and an inexactness control",
    solve=solve,
    parameters=(
        _ahat_parameter(),
        ComponentParameter(
            "inner", "ppcg",
            {"ppcg": (Parameter("rtol", 1e-2, "initial relative tolerance of the inner "
                                "projected PCG", low=0.0, high=1.0, low_open=True),
                      Parameter("min_rtol", 1e-13, "floor of the inner tolerance", low=0.0,
                                high=1e-3, low_open=True),
                      Parameter("max_steps", 500, "cap on inner PCG steps per Newton step",
                                low=1, kind=int))},
            "inner solver of a Newton step: projected PCG with one V-cycle"),
        pc.FACE_PROJECTION,
        Parameter("forcing", 0.1, "inner tolerance <= forcing * KKT residual (Eisenstat-Walker "
                  "type forcing term)", low=0.0, high=1.0, low_open=True),
        Parameter("tighten", 1e-2, "factor on the inner tolerance when the active set repeats "
                  "without verification", low=0.0, high=1.0, low_open=True),
        Parameter("c", 1.0, "PDAS parameter relative to the stiffness scale", low=0.0,
                  low_open=True),
        Parameter("flip_tol", 1e-13, "relative size below which a sign change does not "
                  "change the active set", low=0.0, high=1e-6),
    ),
    presets={"low": "stop when verified: KKT and certified energy bound <= 1e-3",
             "mid": "stop when verified: KKT and certified energy bound <= 1e-6",
             "high": "stop when verified: KKT and certified energy bound <= 1e-9"},
    default_max_iter=100,
    role="newton",
)
