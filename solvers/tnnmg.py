"""Truncated nonsmooth Newton multigrid (TNNMG): the contact community's fastest method.

Gräser and Kornhuber (J. Comput. Math. 27, 2009), Gräser and Sander (IMA J. Numer. Anal.
39, 2019; the dune-tnnmg module). The nodal constraints become bounds on single unknowns
by the change of variables of Krause and Wohlmuth (:mod:`solvers.kernels.contact_box`:
``u = T v``, ``A~ = T' A T``, ``v[pivot] <= upper``). One step from ``v``:

1. nonlinear presmoothing: ``presmoothing`` node-block Gauss-Seidel sweeps, each block
   minimised exactly (a bound crossed is clamped and the rest of the block solved
   again; :mod:`solvers.kernels.block_gs`), alternating direction;
2. the active set ``E = {pivot : v = upper}`` and the truncated linear correction: one
   V-cycle for ``A~ c = r`` on the unknowns off ``E`` (``c = 0`` on ``E``), with the
   truncated prolongation ``D_I T^{-1} P`` at the finest transfer and the Galerkin
   coarse operators of the truncated space; these differ from the untruncated ones by
   a low-rank term on the rows of ``E``, so only that term is recomputed when ``E``
   changes (``A_c,t = A_c - Y'X - X'Y + Y'A~_EE Y``, ``Y = P~[E]``, ``X = A~[E] P~``,
   passed down by Galerkin products of the difference and added in place:
   :class:`~solvers.kernels.tnnmg_correction.UpdatedOperator`; the untruncated ones are
   the scene's own ``P'AP``, since ``P~'A~P~ = P'T'A T T^{-1} P``);
3. projection of the correction onto the feasible set (``c <= upper - v`` at the
   pivots) and the exact line search on the energy over the feasible segment; beside it
   before it, points on the projection arc (``min(v + a c, upper)``, ``a = 1, 1/4,
   ...``), the first with a lower energy taken
   (:func:`~solvers.kernels.tnnmg_line_search.line_search_step`: the arc takes all
   bounds a correction crosses at once, where the projected line search crawls when a
   soft body meets a stiff one);
4. once a step leaves the active set as the previous one left it, conjugate gradients on
   that face (:class:`~solvers.kernels.tnnmg_correction.FaceCG`; Dostal's MPRGP with the
   truncated V-cycle as the preconditioner) until a free pivot meets its bound or the
   negative multipliers outweigh the free residual; then TNNMG steps again. A TNNMG step
   is a preconditioned steepest descent on the face; CG is what the linear floor
   (multigrid-PCG) does, and towards incompressibility, where one V-cycle contracts
   slowly, it cuts the steps by two to three times.

Every part decreases the energy, so the iteration is monotone and converges globally
for any number of smoothing sweeps. The geometric hierarchy is the scene's refinement
hierarchy (``qp.multilevel``); without one (the roll stack) the correction is a direct
solve of the truncated system, refactorised when the active set changes (exact
truncated Newton; :func:`solvers.kernels.cholesky.factorize`). It stops when the suite's
verification passes: the four KKT residuals and the certified energy bound (:func:`certify`).

Memory: ``A~`` is the scene's ``A`` (not copied) plus the transformation's update on the
rows near the contact, which the compiled sweep reads beside it; ``T`` and ``T^{-1}`` are
kept as their changed rows; each coarse operator is held once (with explicit zeros where
the truncation's term goes). Its peak memory is about the multigrid-PCG linear
solve's (the solver comparison's page).

Nested iteration from the coarsest level is the caller's: the scene's coarser problems,
solved in turn, give ``u0`` (the augmented-projection study does this for every
nested row). Floating bodies are handled as they come: the truncation fixes the active
normal unknowns, which hold a body that only contact holds. The stabilised problem
(Sect. 7.5) is ``skipped``: its reverse rows do not have the one-row-per-node structure;
so are mortar rows with standard multipliers (a non-diagonal ``D``), while mortar rows
with dual multipliers (``D`` diagonal, :mod:`problems.fem.mortar`) are one row per
constrained node and are taken.

Tresca friction (one step of a load path, :class:`problems.friction.data.Friction`;
Gräser and Kornhuber's setting of a block-separable nonsmooth energy). The tangential
rows become coordinates too (:mod:`solvers.kernels.contact_box`:
``T_i u = theta_i R_i v_t,i``, ``v_t,i`` the node's one (2D) or two (3D) unknowns after
``v_s[0]``, ``R_i`` orthogonal), so the energy ``J~(v) + sum_i weight_i |v_t,i -
centre_i|`` (:class:`~solvers.kernels.tnnmg_system.TrescaTerm`; in 3D the Euclidean
norm, the isotropic disc) is separable by node blocks with the normal bound on
``v_s[0]``. The step is the one above with (:mod:`solvers.kernels.tnnmg_tresca`):

1. the node block's exact minimiser of the normal bound and the term (the normal unknown
   free or at its bound, times stick or slip; 2D:
   :func:`solvers.kernels.block_gs._tresca_block`, 3D:
   :func:`solvers.kernels.block_gs.disc_block_minimiser`, a secular equation solved to
   round-off);
2. the truncation of the normal-active pivots and of the sticking nodes' tangential
   unknowns (slip exactly zero); a slipping node's term enters the correction's
   right-hand side by its derivative (``weight sign(slip)``; 3D: ``weight slip/|slip|``;
   in 2D the term is linear near the iterate, in 3D its curvature across the slip
   direction goes into the correction's operator,
   :class:`~solvers.kernels.tnnmg_tresca.SlipCurvature`);
3. the line search on the nonsmooth energy: in 2D exact over its kinks
   (:func:`~solvers.kernels.tnnmg_tresca.tresca_line_search_step`), in 3D a safeguarded
   Newton search on its nondecreasing derivative to round-off
   (:func:`~solvers.kernels.tnnmg_tresca.disc_line_search`);
4. in 2D, conjugate gradients on a face (option ``krylov="cg"``,
   :class:`~solvers.kernels.tnnmg_tresca.TrescaFaceCG`): once a step leaves the normal
   active set, the stick set and the slip signs as the previous one left them
   (:class:`~solvers.kernels.tnnmg_tresca.TrescaFace`), the energy is quadratic there (each
   slipping row's ``weight_i |v_t,i - centre_i|`` is linear with its sign fixed), and CG
   preconditioned by the truncated V-cycle (V(2,2), :data:`TRESCA_FACE_SWEEPS`) runs on it
   until a free pivot meets its bound, a slipping row reaches its kink, or the negative
   normal multipliers and the sticking rows' excess ``|r| - weight`` outweigh the free
   gradient; then TNNMG steps again. In 3D each step is a TNNMG step: with slipping
   nodes the energy on a face is not quadratic (``|z|`` of a 2-vector is curved across
   the slip direction), so CG's conjugacy does not hold there.

It stops when the suite's verification passes: the friction KKT residuals
(:func:`problems.friction.residuals.friction_residuals`) and the certified energy bound of
the Tresca step (:func:`certify` with ``lam``) meet tol, with the tangential multipliers
``lam_i = R_i r[v_t,i] / theta_i`` from the stationarity of the tangential unknowns, in
the disc ``|lam_i| <= s_i`` (2D: ``[-s_i, s_i]``, and ``s_i sign(slip_i)`` where the row
slips, so that the certified bound follows the energy error closely;
``SolveResult.tangential``; :meth:`~solvers.kernels.tnnmg_system.TrescaTerm.multipliers`).
A Coulomb problem is solved as the Tresca step of its given slip bound (the fixed point
``s = mu p`` over Tresca steps is the load path's). The solve's ``stats`` split its steps
at the last change of its face (``steps_to_face``, ``steps_on_face``;
:func:`~solvers.kernels.tnnmg_tresca.tresca_face_state`): the steps that find the normal
active set and the stick set, and the multigrid steps on the face found.

This module is the solver: its options and their defaults, the driver of the steps and
the gate of the suite's verification. The steps' pieces are kernels:
:mod:`solvers.kernels.tnnmg_system` (the transformed system, its smoother, the Tresca
term; step 1), :mod:`solvers.kernels.tnnmg_correction` (the truncated V-cycle and CG on a
face; steps 2 and 4), :mod:`solvers.kernels.tnnmg_line_search` (projection and line
search; step 3) and :mod:`solvers.kernels.tnnmg_tresca` (what a Tresca step does
differently).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from problems.friction.residuals import friction_residuals
from problems.kkt import kkt_residuals
from problems.qp import ContactQP
from problems.spec import Options, Parameter
from solvers.base import VERIFIED_PRESETS, Role, SolveResult, SolverSpec
from solvers.certificate import certify
from solvers.kernels.block_gs import BOTH_FIXED, BOUNDED, FIXED, FREE, TANGENT_FIXED, TRESCA
from solvers.kernels.contact_box import TransformationError, box_transformation, check_structure
from solvers.kernels.tnnmg_correction import FaceCG, hierarchy
from solvers.kernels.tnnmg_line_search import line_search_step
from solvers.kernels.tnnmg_system import energy, fine_system, presmooth, stationarity
from solvers.kernels.tnnmg_tresca import (SlipCurvature, TrescaFace, TrescaFaceCG,
                                          contraction_on_face, tresca_energy, tresca_face_state,
                                          tresca_line_search_step, tresca_stationarity)


#: The suite's KKT check (and the certificate) runs once the transformed problem's own
#: stationarity residual is within this factor of tol
#: (:func:`solvers.kernels.tnnmg_system.stationarity`; the two scalings differ by the
#: transformation's norm, O(1)).
CHECK_FACTOR = 10.0

#: V-cycle sweeps by dimension (option ``sweeps=0``): in 2D V(1,1) keeps the steps
#: level-independent at the lower time; in 3D one node-block sweep a side smooths too
#: little for that, V(2,2) keeps it at the same time to the target
#: (docs/guide/measurements.md).
AUTO_SWEEPS = {2: 1, 3: 2}

#: Nonlinear presmoothing sweeps per step (option ``presmoothing=0``): one without
#: friction; two on a Tresca step, where the sweeps alone move the slip front (the
#: truncated correction holds every sticking node): on the nested load paths of
#: :mod:`workflows.studies.friction.run`'s scenes never more steps, for one sweep more
#: per step (docs/guide/friction.md).
AUTO_PRESMOOTHING = {False: 1, True: 2}

#: V-cycle sweeps of a 3D Tresca step's TNNMG steps (option ``sweeps=0``; 2D as
#: :data:`AUTO_SWEEPS`). A 3D step takes no CG on its face, so each V-cycle's contraction
#: is the step's: with V(2,2) it falls with the level (in the normal step too, where no
#: stick set is found); four sweeps a side, each a compiled pass over the mesh, take the
#: fewest steps on the nested load paths (docs/guide/friction.md).
TRESCA_3D_SWEEPS = 4

#: V-cycle sweeps of the preconditioner of CG on a face of a 2D Tresca step (option
#: ``sweeps=0``): two a side, as the linear floor's V-cycle smooths (a symmetric
#: Gauss-Seidel sweep, forward and back, before and after): with one a side CG takes as
#: many steps as TNNMG steps alone do (docs/guide/friction.md).
TRESCA_FACE_SWEEPS = 2


@dataclass
class _StepLog:
    """A TNNMG solve's per-step history, its phases' times and its end (:func:`solve`)."""

    t_solve: float
    deadline: float | None
    history: dict = field(default_factory=lambda: {
        key: [] for key in ("energy", "residual", "kkt_max", "n_active", "step", "phase",
                            "time", "t_verify")})
    timing: dict = field(default_factory=lambda: dict.fromkeys(
        ("t_smoother", "t_truncation", "t_vcycle", "t_check", "t_verify"), 0.0))

    def record(self, **values) -> None:
        """Append the step's ``values`` (a new name starts its list), its time and the time
        the verification has taken so far (``t_verify``, part of ``time``)."""
        for key, value in values.items():
            self.history.setdefault(key, []).append(value)
        self.history["time"].append(time.perf_counter() - self.t_solve)
        self.history["t_verify"].append(self.timing["t_verify"])

    def verified(self, qp: ContactQP, u: np.ndarray, p: np.ndarray, tol: float, stop: str,
                 lam: np.ndarray | None = None) -> tuple[float, bool]:
        """:func:`_verified`, its time added to ``timing["t_verify"]`` (a part of
        ``t_check``): the suite's verification inside the solve, the certificate's first
        factorisation of ``A`` included, which a time to a target keeps apart
        (:func:`workflows.measure.tnnmg_run`)."""
        t0 = time.perf_counter()
        try:
            return _verified(qp, u, p, tol, stop, lam)
        finally:
            self.timing["t_verify"] += time.perf_counter() - t0

    def close(self, k: int, times: tuple, kkt_max: float, verified: bool, converged: str,
              stop: Callable[[], bool]) -> tuple[str, str] | None:
        """Record the check and the phases' times ``(t0, t1, t2, t3)`` of step ``k``, then
        ask ``stop`` (the caller's callback); ``(status, message)`` if the solve ends here."""
        t0, t1, t2, t3 = times
        self.history["kkt_max"].append(kkt_max)
        self.timing["t_smoother"] += t1 - t0
        self.timing["t_truncation"] += t2 - t1
        self.timing["t_vcycle"] += t3 - t2
        self.timing["t_check"] += time.perf_counter() - t3
        stopped = stop()
        if verified:
            return "converged", converged
        if stopped:
            return "max_iter", f"stopped by the caller after {k} steps"
        if self.deadline is not None and time.perf_counter() > self.deadline:
            return "time_limit", f"time limit reached after {k} steps"
        return None


def _verified(qp: ContactQP, u: np.ndarray, p: np.ndarray, tol: float, stop: str,
              lam: np.ndarray | None = None) -> tuple[float, bool]:
    """``(kkt_max, verified)`` of an iterate, judged as the suite's verification judges
    it: the KKT residuals (the friction ones with the tangential multipliers ``lam``)
    within ``tol`` and, unless ``stop`` is ``"kkt"``, the certified bound too."""
    kkt_max = (kkt_residuals(qp, u, p) if lam is None
               else friction_residuals(qp, u, p, lam)).max
    return kkt_max, kkt_max <= tol and (stop == "kkt"
                                        or certify(qp, u, p, tol, lam=lam).meets(tol))


def _tresca_solve(qp: ContactQP, tol: float, max_iter: int, time_limit: float | None,
                  u0: np.ndarray | None, opts: Options, callback: Callable | None
                  ) -> SolveResult:
    """One Tresca step (``qp.friction``, 2D or 3D) by TNNMG (module docstring, Tresca
    friction)."""
    t_start = time.perf_counter()
    fine = fine_system(qp, tresca=True)
    box, term = fine.box, fine.tresca
    piv, upper, tpiv = box.pivot, box.upper, term.pivot
    curvature = SlipCurvature.build(fine) if term.k > 1 else None
    presmoothing = opts.presmoothing or AUTO_PRESMOOTHING[True]
    sweeps = opts.sweeps or (TRESCA_3D_SWEEPS if qp.dim == 3 else AUTO_SWEEPS.get(qp.dim, 2))
    ml = hierarchy(qp, fine if curvature is None else curvature.fine, sweeps,
                   opts.coarse == "truncated", opts.patch, np.concatenate([piv, tpiv]),
                   None if curvature is None else curvature.places)
    nb = box.node_ptr.size - 1
    mode_nonlinear = np.full(nb, FREE, dtype=np.int64)
    mode_nonlinear[fine.bounded_blocks] = TRESCA
    block_of_row = np.empty(qp.m, dtype=np.int64)
    block_of_row[box.block_row[fine.bounded_blocks]] = fine.bounded_blocks
    v = np.zeros(qp.n) if u0 is None else box.to_v(np.asarray(u0, dtype=float))
    v[piv] = np.minimum(v[piv], upper)
    setup_time = time.perf_counter() - t_start
    deadline = None if time_limit is None else t_start + time_limit

    log = _StepLog(time.perf_counter(), deadline)
    status, message, k = "max_iter", f"not verified after {max_iter} steps", 0
    forward = True
    face_cg = opts.krylov == "cg" and term.k == 1   # 3D: TNNMG steps only (docstring)
    cg, n_cg, previous = None, 0, None
    face_state, to_face = tresca_face_state(fine, v), 0
    for k in range(1, max_iter + 1):
        t0 = t1 = time.perf_counter()
        if cg is None:                            # a TNNMG step
            forward = presmooth(fine, v, mode_nonlinear, forward, presmoothing)
            t1 = time.perf_counter()
            face = TrescaFace.of(fine, v) if face_cg else None
            r = fine.f - fine.matvec(v)
            active, stick = v[piv] >= upper, term.stick(v)
            mode = np.full(nb, FREE, dtype=np.int64)
            mode[block_of_row[active]] = FIXED
            mode[block_of_row[stick]] = TANGENT_FIXED
            mode[block_of_row[active & stick]] = BOTH_FIXED
            E = np.concatenate([piv[active], tpiv.reshape(-1, term.k)[stick].ravel()])
            ml.truncate(E, mode, None if curvature is None else curvature.set(v, stick))
            t2 = time.perf_counter()
            g = r.copy()
            g[tpiv] -= term.gradient(v)
            g[E] = 0.0
            c = ml.vcycle(g)
            v, r, step = tresca_line_search_step(fine, v, r, c, piv, upper)
            if face_cg:                           # the face is stable: CG on it
                if previous == face and TrescaFace.of(fine, v) == face:
                    cg = TrescaFaceCG(E, sweeps=opts.sweeps or TRESCA_FACE_SWEEPS, face=face)
                previous = face
            phase = "tnnmg"
        else:                                     # a CG step on the face (TrescaFaceCG)
            t2 = t1
            v, r, step, leave = cg.step(fine, ml, v, r, piv, upper, cg.face.active)
            n_cg += 1
            phase = "cg"
            if leave:
                cg = None
        t3 = time.perf_counter()
        state = tresca_face_state(fine, v)
        if not np.array_equal(state, face_state):
            face_state, to_face = state, k
        bound = v[piv] >= upper
        residual = tresca_stationarity(fine, r, piv[bound], v)
        log.record(energy=tresca_energy(fine, v, r), residual=residual,
                   n_active=int(np.count_nonzero(bound)), step=step, phase=phase,
                   n_stick=int(np.count_nonzero(term.stick(v))))
        verified, kkt_max = False, np.nan
        if residual <= CHECK_FACTOR * tol or callback is not None:
            u, p = box.to_u(v), box.multipliers(r, bound)
            lam = term.multipliers(r, qp.friction, v)
        if residual <= CHECK_FACTOR * tol:         # the suite's verification decides
            kkt_max, verified = log.verified(qp, u, p, tol, opts.stop, lam)
        end = log.close(k, (t0, t1, t2, t3), kkt_max, verified,
                        f"verified after {k} steps" + (f" ({n_cg} of them CG)" if face_cg
                                                       else ""),
                        lambda: callback is not None and callback(u, p))
        if end is not None:
            status, message = end
            break
    if k == 0:
        r = fine.f - fine.matvec(v)
    bound = v[piv] >= upper
    u, p = box.to_u(v), box.multipliers(r, bound)
    lam = term.multipliers(r, qp.friction, v)
    stick = term.stick(v)
    stats = {"friction": "tresca_step", "n_steps": k, "n_cg": n_cg, "n_vcycles": k,
             "steps_to_face": to_face, "steps_on_face": k - to_face,
             "contraction_on_face": contraction_on_face(log.history["residual"], to_face),
             "presmoothing": presmoothing,
             "truncation_updates": ml.updates, "coarse_analyses": ml.coarse_factor.analyses,
             "n_active": int(np.count_nonzero(p > 0)),
             "n_stick": int(np.count_nonzero(stick)),
             "n_slip": int(np.count_nonzero(~stick & (term.weight > 0))),
             "n_levels": len(ml.coarse_ops) + 1, **log.timing}
    return SolveResult(u=u, p=p, claimed_status=status, message=message, iterations=k,
                       setup_time=setup_time, solve_time=time.perf_counter() - log.t_solve,
                       history=log.history, stats=stats, tangential=lam)


def supports(qp: ContactQP) -> tuple[bool, str]:
    """Nodal constraints with one row per constrained node (:mod:`solvers.kernels.contact_box`);
    with friction, one Tresca step (2D or 3D) whose tangential rows become coordinates too
    (a Coulomb problem's step at its given slip bound: the fixed point ``s = mu p`` is the
    load path's)."""
    fr = qp.friction
    if fr is not None:
        try:
            box_transformation(qp, fr.T)
        except TransformationError as err:
            return False, f"the constraints cannot be turned into bounds: {err}"
        return True, ""
    ok, reason = check_structure(qp)
    return ok, (f"the constraints cannot be turned into bounds: {reason}" if not ok else "")


def solve(qp: ContactQP, tol: float, max_iter: int, time_limit: float | None,
          u0: np.ndarray | None, p0: np.ndarray | None, opts: Options,
          callback: Callable | None = None) -> SolveResult:
    """Solve ``qp`` by TNNMG (module docstring). ``p0`` is not used (a primal method).

    ``callback(u, p)``, if given, is called after every step, after ``history["time"]``
    is stamped (its cost is the caller's to subtract), and stops an unverified run by
    returning True (status ``max_iter``). A Tresca step (``qp.friction``) goes to
    :func:`_tresca_solve`.
    """
    if qp.friction is not None:
        return _tresca_solve(qp, tol, max_iter, time_limit, u0, opts, callback)
    t_start = time.perf_counter()
    fine = fine_system(qp)
    presmoothing = opts.presmoothing or AUTO_PRESMOOTHING[False]
    ml = hierarchy(qp, fine, opts.sweeps or AUTO_SWEEPS.get(qp.dim, 2),
                   opts.coarse == "truncated", opts.patch)
    box = fine.box
    piv, upper = box.pivot, box.upper
    mode_nonlinear = np.full(box.node_ptr.size - 1, FREE, dtype=np.int64)
    mode_nonlinear[fine.bounded_blocks] = BOUNDED
    v = np.zeros(qp.n) if u0 is None else box.to_v(np.asarray(u0, dtype=float))
    v[piv] = np.minimum(v[piv], upper)
    setup_time = time.perf_counter() - t_start
    deadline = None if time_limit is None else t_start + time_limit

    log = _StepLog(time.perf_counter(), deadline)
    status, message, k = "max_iter", f"not verified after {max_iter} steps", 0
    forward, cg, n_cg, previous = True, None, 0, None
    for k in range(1, max_iter + 1):
        t0 = t1 = time.perf_counter()
        if cg is None:                            # a TNNMG step
            forward = presmooth(fine, v, mode_nonlinear, forward, presmoothing)
            t1 = time.perf_counter()
            r = fine.f - fine.matvec(v)
            active = v[piv] >= upper
            ml.update(active)
            t2 = time.perf_counter()
            r_t = r.copy()
            r_t[piv[active]] = 0.0
            c = ml.vcycle(r_t)
            v, r, step = line_search_step(fine, v, r, c, piv, upper)
            bound = v[piv] >= upper
            if (opts.krylov == "cg" and previous is not None
                    and np.array_equal(active, previous) and np.array_equal(bound, active)):
                cg = FaceCG(piv[active])         # the face is stable: CG on it
            previous = active
            phase = "tnnmg"
        else:                                     # a CG step on the face (FaceCG)
            t2 = t1
            v, r, step, leave = cg.step(fine, ml, v, r, piv, upper, active)
            bound = v[piv] >= upper
            n_cg += 1
            phase = "cg"
            if leave:
                cg = None
        t3 = time.perf_counter()
        residual = stationarity(fine, r, piv[bound])
        log.record(energy=energy(fine, v, r), residual=residual,
                   n_active=int(np.count_nonzero(bound)), step=step, phase=phase)
        verified, kkt_max = False, np.nan
        if residual <= CHECK_FACTOR * tol or callback is not None:
            u, p = box.to_u(v), box.multipliers(r, bound)
        if residual <= CHECK_FACTOR * tol:         # the suite's verification decides
            kkt_max, verified = log.verified(qp, u, p, tol, opts.stop)
        end = log.close(k, (t0, t1, t2, t3), kkt_max, verified,
                        f"verified after {k} steps ({n_cg} of them CG)",
                        lambda: callback is not None and callback(u, p))
        if end is not None:
            status, message = end
            break
    if k == 0:
        r = fine.f - fine.matvec(v)
    u, p = box.to_u(v), box.multipliers(r, v[piv] >= upper)
    stats = {"n_steps": k, "n_cg": n_cg, "n_vcycles": k, "presmoothing": presmoothing,
             "truncation_updates": ml.updates, "coarse_analyses": ml.coarse_factor.analyses,
             "n_active": int(np.count_nonzero(p > 0)),
             "n_levels": len(ml.coarse_ops) + 1, **log.timing}
    return SolveResult(u=u, p=p, claimed_status=status, message=message, iterations=k,
                       setup_time=setup_time, solve_time=time.perf_counter() - log.t_solve,
                       history=log.history, stats=stats)


SOLVER = SolverSpec(
    name="tnnmg",
    summary="truncated nonsmooth Newton multigrid (Gräser-Kornhuber): nonlinear block "
            "Gauss-Seidel, a truncated geometric-multigrid V-cycle, projection and an exact "
            "line search on the Krause-Wohlmuth box-transformed problem",
    solve=solve,
    parameters=(
        Parameter("presmoothing", 0, "nonlinear node-block Gauss-Seidel sweeps per step "
                  "(alternating direction); 0: one, two on a Tresca step "
                  "(AUTO_PRESMOOTHING)", low=0, high=10, kind=int),
        Parameter("sweeps", 0, "smoothing sweeps of the linear V-cycle: V(sweeps, sweeps); "
                  "0: by dimension (AUTO_SWEEPS: 1 in 2D, 2 in 3D; a 3D Tresca step: 4, "
                  "TRESCA_3D_SWEEPS; CG on a 2D Tresca step's face: 2, TRESCA_FACE_SWEEPS)",
                  low=0, high=10, kind=int),
        Parameter("patch", 0, "graph layers of the contact patch around the constraint "
                  "rows' unknowns, solved exactly in each V-cycle after pre- and before "
                  "post-smoothing (0: none; each change of the active set refactorises it, "
                  "which costs more than it saves once CG runs on the face)",
                  low=0, high=20, kind=int),
        Parameter("stop", "verified", "verified: stop when the KKT residuals and the "
                  "certified energy bound meet tol; kkt: the KKT residuals alone (nested "
                  "iteration's coarse levels; the interface still certifies the answer)",
                  choices=("verified", "kkt")),
        Parameter("krylov", "cg", "cg: once a TNNMG step leaves the active set as it found "
                  "it (twice in a row), conjugate gradients on that face, preconditioned by "
                  "the truncated V-cycle, until a bound or a negative multiplier ends it "
                  "(MPRGP's expansion and proportioning; a 2D Tresca step's face also fixes "
                  "the stick set and the slip signs, and a kink ends it too; 3D Tresca "
                  "steps: TNNMG steps only); none: TNNMG steps only",
                  choices=("cg", "none")),
        Parameter("coarse", "truncated", "coarse operators: Galerkin products of the truncated "
                  "space (truncated) or the untruncated ones (untruncated; still monotone by "
                  "the projection and line search, fewer updates, more steps)",
                  choices=("truncated", "untruncated")),
    ),
    presets=VERIFIED_PRESETS,
    default_max_iter=500,
    role=Role.NEWTON,
    handles_friction=True,
    facets_reason=("its nonlinear smoother and truncation are built for the isotropic law "
                   "(discs); the faceted law is a QP, taken by the QP libraries and "
                   "tresca_exact"),
    # not that it solves the stabilised problem: handed over as it is, ``supports`` sees
    # its C block and names it as the reason to skip (its slack form would hide why)
    handles_C=True,
    supports=supports,
)

