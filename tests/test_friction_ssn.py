"""The friction branch of semismooth_newton: the primal-dual active set method of Hüeber,
Stadler and Wohlmuth for 2D Tresca and Coulomb steps on circle_square (mu = 0.5,
elastically similar bodies), checked against the exact reference of a Tresca step
(solvers.kernels.tresca.tresca_exact) and against the frictionless PDAS."""
from __future__ import annotations

import numpy as np
import pytest

from problems.friction.residuals import friction_residuals
from problems.kkt import energy_error
from problems.spec import problems
from solvers import semismooth_newton
from solvers.interface import solve
from solvers.semismooth_newton import STICK, tangential_update
from solvers.kernels.tresca import TrescaSolution, friction_path, path_for_ratio, with_step

SCENE = problems()["circle_square"]
SPEC = semismooth_newton.SOLVER


def _frictional(level=1, **kw):
    return SCENE.make(level, **{"friction": "tresca", "mu": 0.5, "shift": 0.01, **kw})


def _ssn(step_qp, tol=1e-10, max_iter=100, **options):
    """The friction branch on one step, called directly (the registry's verification of a
    frictional answer is not this module's)."""
    return SPEC.solve(step_qp, tol, max_iter, None, None, None, SPEC.options(**options))


def _as_solution(step_qp, res) -> TrescaSolution:
    """A SolveResult of the branch as friction_path's TrescaSolution."""
    fr = step_qp.friction
    stick = (fr.slip_bound > 0) & (np.abs(res.tangential) < fr.slip_bound)
    return TrescaSolution(u=res.u, p=res.p, lam=res.tangential, stick=stick,
                          status=res.claimed_status, iterations=res.iterations,
                          kkt=friction_residuals(step_qp, res.u, res.p, res.tangential))


def _check_against_exact(steps):
    """Every step of an exact path solved again by the branch: converged, friction KKT
    <= 1e-10, within 1e-8 of the exact u in the energy norm; the Newton steps per step."""
    iterations = []
    for st in steps:
        res = _ssn(st.qp)
        assert res.claimed_status == "converged", res.message
        kkt = friction_residuals(st.qp, res.u, res.p, res.tangential)
        assert kkt.max <= 1e-10, kkt
        assert energy_error(st.qp, res.u, st.solution.u) <= 1e-8
        s = st.qp.friction.slip_bound
        assert np.max(np.abs(res.tangential - st.solution.lam)) <= 1e-8 * max(s.max(), 1e-300)
        assert len(res.history["n_stick"]) == res.iterations
        iterations.append(res.iterations)
    return iterations


@pytest.mark.parametrize("level", [1, 2])
@pytest.mark.parametrize("ratio", [0.3, 0.7])
def test_tresca_steps_agree_with_the_exact_reference(level, ratio):
    """Both steps of the Cattaneo-Mindlin path (the normal step, s = 0, and the tangential
    step scaled to Q/(mu P) = ratio). Measured Newton steps (normal, tangential) from an
    empty start: 4 and 4 at level 1, 7 and 6 at level 2, 7 and 7 at level 3; friction KKT
    <= 4e-13, energy error <= 1e-13."""
    steps = path_for_ratio(_frictional(level), ratio)
    last = steps[-1]
    contact = last.qp.friction.slip_bound > 0
    assert last.solution.stick.any() and (contact & ~last.solution.stick).any()   # partial slip
    iterations = _check_against_exact(steps)
    assert max(iterations) <= 10


@pytest.mark.slow
def test_tresca_steps_agree_with_the_exact_reference_level_3():
    qp = _frictional(3)
    for ratio in (0.3, 0.7):
        assert max(_check_against_exact(path_for_ratio(qp, ratio))) <= 10


def test_mu_zero_reproduces_the_frictionless_pdas():
    """With mu = 0 no row carries a friction force and each step is the frictionless
    problem: the same u and p as pdas to 1e-10."""
    qp = _frictional(1, mu=0.0)
    steps = friction_path(qp, solve=lambda step_qp: _as_solution(step_qp, _ssn(step_qp)))
    for step, shift in zip(steps, (0.0, 0.01)):
        plain = SCENE.make(1, shift=shift)
        ref = solve(plain, "pdas", tol=1e-12)
        assert ref.status == "converged" and step.solution.status == "converged"
        assert np.all(step.solution.lam == 0.0)
        assert energy_error(plain, step.solution.u, ref.u) <= 1e-10
        assert np.max(np.abs(step.solution.p - ref.p)) <= 1e-10 * np.max(ref.p)


def test_large_mu_sticks_everywhere():
    """mu = 1000: every row in contact sticks (its tangential multiplier strictly inside
    the bound) and its slip is zero to round-off."""
    qp = _frictional(1, mu=1e3)
    steps = friction_path(qp, solve=lambda step_qp: _as_solution(step_qp, _ssn(step_qp)))
    last = steps[-1]
    fr, sol = last.qp.friction, last.solution
    contact = fr.slip_bound > 0
    assert contact.sum() >= 5 and np.array_equal(sol.stick, contact)
    res = _ssn(last.qp)
    assert res.stats["n_stick"] == contact.sum() and res.stats["n_slip"] == 0
    slip = fr.slip(sol.u)
    assert np.max(np.abs(slip[contact])) <= 1e-10 * np.max(np.abs(fr.T @ sol.u))


@pytest.mark.parametrize("level", [1, 2])
def test_monolithic_coulomb_agrees_with_the_fixed_point(level):
    """Coulomb with s = mu p inside the Newton iteration against the fixed point over
    exact Tresca steps (solvers.kernels.tresca.coulomb_step), both steps of the path, to 1e-8 in
    energy; the monolithic answer verifies as the Tresca step of its own bound mu p.
    Measured: the fixed point takes 2 and 9 Tresca solves at level 1, 9 and 10 at level 2
    (each 4, resp. 6-7, Newton steps of the Tresca branch); the monolithic method 4 and 4
    Newton steps at level 1, 7 and 6 at level 2."""
    qp = _frictional(level, friction="coulomb", shift=0.02)
    fixed = friction_path(qp)
    previous = np.zeros(qp.m)
    for k, st in enumerate(fixed):
        step_qp = with_step(qp, k, np.zeros(qp.m), previous)
        res = _ssn(step_qp, coulomb="monolithic")
        assert res.claimed_status == "converged", res.message
        assert res.stats["friction"] == "coulomb_monolithic"
        own = with_step(qp, k, 0.5 * res.p, previous)
        assert friction_residuals(own, res.u, res.p, res.tangential).max <= 1e-10
        assert energy_error(st.qp, res.u, st.solution.u) <= 1e-8
        np.testing.assert_allclose(res.p, st.solution.p, rtol=0, atol=1e-8 * st.solution.p.max())
        assert res.iterations < 10 and st.tresca_solves >= 2
        previous = qp.friction.T @ res.u + qp.friction.path[k].offset
    last = fixed[-1].solution
    assert last.stick.any() and ((fixed[-1].qp.friction.slip_bound > 0) & ~last.stick).any()


def test_a_coulomb_problem_is_a_tresca_step_unless_asked_otherwise():
    """The registry's contract: solve takes one Tresca step with the given slip bound;
    only coulomb='monolithic' replaces it by mu p."""
    qp = _frictional(1, friction="coulomb", shift=0.02)
    steps = friction_path(qp)
    res = _ssn(steps[-1].qp)
    assert res.stats["friction"] == "tresca_step"
    assert energy_error(steps[-1].qp, res.u, steps[-1].solution.u) <= 1e-8


def test_stopping_short_says_so():
    st = path_for_ratio(_frictional(1), 0.7)[-1]
    res = _ssn(st.qp, max_iter=1)
    assert res.claimed_status == "max_iter" and "did not repeat within 1 steps" in res.message
    assert res.tangential is not None and res.iterations == 1


def test_tangential_sets_and_their_hysteresis():
    """Stick inside the bound, slip with the sign of v outside, no force where s = 0; a row
    on the boundary keeps its state within eps."""
    bound = np.array([1.0, 1.0, 1.0, 0.0, 1.0, 1.0])
    v = np.array([0.5, 1.5, -2.0, 0.3, 1.0 + 1e-14, 1.0 - 1e-14])
    fresh = tangential_update(np.zeros(6, dtype=int), v, bound, 1e-12)
    assert fresh.tolist() == [STICK, 1, -1, 0, 1, STICK]
    held = tangential_update(np.array([1, STICK, STICK, STICK, STICK, 1]), v, bound, 1e-12)
    assert held.tolist() == [STICK, 1, -1, 0, STICK, 1]


def test_frictionless_problems_take_the_unchanged_path(monkeypatch):
    """A frictionless problem never reaches the friction branch, and its answer is the
    exact PDAS's as the solver's own tests require."""
    def refuse(*args, **kwargs):
        raise AssertionError("the friction branch ran on a frictionless problem")

    monkeypatch.setattr(semismooth_newton, "solve_friction", refuse)
    qp = SCENE.make(1)
    res = solve(qp, "semismooth_newton", tol="high")
    ref = solve(qp, "pdas", tol="high")
    assert res.status == "converged" and res.tangential is None
    assert energy_error(qp, res.u, ref.u) < 1e-8


def test_a_cycling_coulomb_iteration_ends_with_an_honest_status():
    """With c_slip = 1 (100 times the default) a slipping row whose slip reverses jumps to
    the opposite slip instead of sticking, and the monolithic Coulomb sets of the
    tangential step at level 1 cycle: damped down to single changes, the run ends
    ``failed`` with the best step and says why; it never loops."""
    qp = _frictional(1, friction="coulomb", shift=0.02)
    normal = _ssn(with_step(qp, 0, np.zeros(qp.m), np.zeros(qp.m)), coulomb="monolithic")
    previous = qp.friction.T @ normal.u + qp.friction.path[0].offset
    res = _ssn(with_step(qp, 1, np.zeros(qp.m), previous), coulomb="monolithic", c_slip=1.0)
    assert res.claimed_status == "failed" and "cycle under single changes" in res.message
    assert res.stats["damped"] and res.iterations < 100
    assert min(res.history["kkt_max"]) > 1e-3             # no step came close


def test_a_tresca_step_whose_sets_cycle_falls_back_to_a_method_that_cannot():
    """The test set's hard_friction_stiff step (contrast 1e4, level 0): from zero the
    Newton sets cycle under single changes at step 8. The step's dual goes on from the
    best Newton step by the primal active-set method on the box and ends at the exact
    reference's answer, saying so; without the fallback the run is ``failed``, and warm
    started it converges in two Newton steps without one."""
    from workflows.problem_set import frictional_steps

    params = (("friction", "coulomb"), ("mu", 0.3), ("shift", 0.011), ("E2", 1.0e4))
    step = frictional_steps("circle_square", params, 0)[1]
    qp, exact = step.qp, step.solution
    res = solve(qp, "semismooth_newton", "mid")
    assert res.status == "converged" and res.stats["fallback"], res.message
    assert "cycle under single changes" in res.message and "fell back to the primal" \
        in res.message
    assert energy_error(qp, res.u, exact.u) <= 1e-10
    bare = solve(qp, "semismooth_newton", "mid", fallback="none")
    assert bare.status == "failed" and not bare.stats["fallback"], bare.message
    assert "cycle under single changes" in bare.message
    warm = solve(qp, "semismooth_newton", "mid", u0=step.warm.u, p0=step.warm.p)
    assert warm.status == "converged" and not warm.stats["fallback"] and warm.iterations <= 3


def test_the_dual_fallback_solves_a_3d_tresca_step_from_an_empty_start():
    """In 3D the fallback is the globalised Newton method of the projection equation
    (``tresca_exact``'s): from ``y = 0`` and empty sets it reaches the exact answer of the
    test set's hard 3D step (Q/(mu P) ~ 0.98, cube_sphere level 0)."""
    from workflows.problem_set import frictional_steps

    params = (("friction", "tresca"), ("mu", 0.3), ("shift", 0.075))
    step = frictional_steps("cube_sphere", params, 0)[1]
    qp, fr, m = step.qp, step.qp.friction, step.qp.m
    ops = semismooth_newton.contact_schur(qp)
    rhs = ops.G @ ops.solve_A(qp.f) - np.concatenate([qp.g, fr.previous - fr.offset])
    y, (steps, ok, name) = semismooth_newton._dual_fallback(
        ops, rhs, m, fr, np.zeros(m), np.zeros(fr.T.shape[0]), np.zeros(m, dtype=bool),
        np.zeros(m, dtype=int))
    assert ok and steps > 1 and "projection equation" in name
    u = ops.solve_A(qp.f - ops.G.T @ y)
    assert energy_error(qp, u, step.solution.u) <= 1e-10
    assert friction_residuals(qp, u, y[:m], y[m:]).max <= 1e-10


def _counting_solves(monkeypatch) -> list:
    """Count the solves with A's factor (``ContactSchur.solve_A``) from now on."""
    calls = []
    plain = semismooth_newton.ContactSchur.solve_A

    def counted(self, rhs):
        calls.append(1)
        return plain(self, rhs)

    monkeypatch.setattr(semismooth_newton.ContactSchur, "solve_A", counted)
    return calls


@pytest.mark.parametrize("law", ["tresca", "coulomb"])
def test_the_displacement_formed_at_the_end_takes_the_same_steps(law, monkeypatch):
    """displacement='at_end' judges the Newton steps on the rows (G u = G A^-1 f - S y)
    and forms u once: the same sets, hence the same steps and, in 2D, the same
    multipliers, with two solves with A's factor per run (A^-1 f and u) instead of one
    per step and one for A^-1 f. Both steps of a Tresca path and of a monolithic
    Coulomb one (level 1, the second step at Q/(mu P) = 0.7 resp. with the Coulomb
    shift)."""
    if law == "tresca":
        steps = [st.qp for st in path_for_ratio(_frictional(1), 0.7)]
        options = {}
    else:
        qp = _frictional(1, friction="coulomb", shift=0.02)
        steps = [with_step(qp, k, np.zeros(qp.m), np.zeros(qp.m)) for k in range(2)]
        options = {"coulomb": "monolithic"}
    calls = _counting_solves(monkeypatch)
    for step_qp in steps:
        every = _ssn(step_qp, **options)
        n_every, calls[:] = len(calls), []
        end = _ssn(step_qp, displacement="at_end", **options)
        n_end, calls[:] = len(calls), []
        assert every.claimed_status == end.claimed_status == "converged", end.message
        assert end.iterations == every.iterations
        assert (n_every, n_end) == (1 + every.iterations, 2)
        np.testing.assert_array_equal(end.p, every.p)
        np.testing.assert_array_equal(end.tangential, every.tangential)
        assert energy_error(step_qp, end.u, every.u) <= 1e-14
        assert "u formed at the end" in end.message
