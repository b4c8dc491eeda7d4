"""TNNMG on one 2D Tresca step: the tangential rows become coordinates exactly, the node
block's nonsmooth minimiser is exact, and the solver's answers satisfy the friction KKT
conditions and agree with the exact reference (:func:`solvers.kernels.tresca.tresca_exact`) on
circle_square; its frictionless path is the one it was."""
import functools
from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp

from problems.friction.residuals import friction_residuals
from problems.kkt import energy_error
from problems.spec import problems
from solvers import tnnmg
from solvers.kernels.block_gs import (TRESCA, block_inverses, tresca_block_gauss_seidel,
                                      unsigned_index)
from solvers.certificate import certify
from solvers.kernels.contact_box import box_transformation
from solvers.kernels import tnnmg_system
from solvers.kernels.tnnmg_system import fine_system
from solvers.kernels.tnnmg_tresca import TrescaFace, TrescaFaceCG, kink_search, tresca_energy
from solvers.interface import solve
from solvers.kernels.tresca import TrescaSolution, friction_path, path_for_ratio
from agreement import within_certificate

SCENE = problems()["circle_square"]


def _frictional(level, **kw):
    return SCENE.make(level, **{"friction": "tresca", "mu": 0.5, "shift": 0.01, **kw})


@functools.lru_cache(maxsize=None)
def _exact_path(level, ratio):
    """The exact path at ``Q/(mu P) = ratio`` (its steps and answers), built once per
    module: several tests read level 2's."""
    return tuple(path_for_ratio(_frictional(level), ratio))


def _tnnmg(qp, tol=1e-10, **opts):
    """TNNMG's answer to one step, called directly (its stop is the suite's verification:
    the friction KKT residuals and the certified Tresca bound)."""
    res = tnnmg.solve(qp, tol, 500, None, None, None, tnnmg.SOLVER.options(**opts))
    assert res.claimed_status == "converged", res.message
    return res


def test_tangential_rows_become_coordinates_exactly():
    """u = T v with the tangential rows: T is invertible with the inverse it claims, each
    normal row bounds one unknown and each tangential row reads one (T_i u = theta_i v_t)."""
    qp = _frictional(1)
    fr = qp.friction
    box = box_transformation(qp, fr.T)
    n = qp.n
    assert abs(box.T @ box.T_inv - sp.identity(n)).max() <= 1e-12
    rows = np.arange(qp.m)
    BT = (qp.B @ box.T).tocsr()
    assert abs(BT - sp.csr_matrix((box.scale, (rows, box.pivot)), shape=BT.shape)).max() \
        <= 1e-12 * abs(qp.B).max()
    TT = (fr.T @ box.T).tocsr()
    target = sp.csr_matrix((box.tangential_scale, (rows, box.tangential_pivot)), shape=TT.shape)
    assert abs(TT - target).max() <= 1e-12 * abs(fr.T).max()
    assert np.all(np.abs(box.tangential_scale) > 0)
    # each constrained node's block: (normal, tangential)
    assert np.all(box.tangential_pivot != box.pivot)
    assert np.array_equal(box.pivot // 2, box.tangential_pivot // 2)
    u = np.random.default_rng(1).normal(size=n)
    np.testing.assert_allclose(box.to_u(box.to_v(u)), u, rtol=0, atol=1e-12 * np.abs(u).max())
    # without tangential rows the transformation is the frictionless one, unchanged
    plain = box_transformation(qp)
    assert plain.tangential_pivot.size == 0
    assert np.array_equal(plain.pivot, box.pivot) and np.array_equal(plain.upper, box.upper)
    assert abs((qp.B @ plain.T) - BT).max() <= 1e-12 * abs(qp.B).max()


def _random_block_system(rng, k: int, shift: float):
    """A random ``k x k`` SPD block ``M`` (smallest eigenvalue at least ``shift``), a right
    hand side ``b`` and a start ``x``."""
    L = rng.normal(size=(k, k))
    return L @ L.T + shift * np.eye(k), rng.normal(size=k), rng.normal(size=k)


def _one_block(M, b, x, upper, weight, centre, mode=TRESCA):
    """One sweep of the Tresca kernel on a single block system ``M`` (2x2, or 3x3 with
    ``centre`` a 2-vector)."""
    A = sp.csr_matrix(M)
    w = M.shape[0]
    C = sp.csr_matrix((w, w))
    node_ptr, node_dofs = np.array([0, w]), np.arange(w)
    diag0, inv_full, inv_sub = block_inverses(A, node_ptr, node_dofs, C)
    x = x.copy()
    tresca_block_gauss_seidel(*(unsigned_index(a) for a in (A.indptr, A.indices)), A.data,
                              *(unsigned_index(a) for a in (C.indptr, C.indices)), C.data,
                              x, b, node_ptr, unsigned_index(node_dofs), diag0, inv_full,
                              inv_sub, np.array([mode]), np.array([upper]),
                              np.array([weight]), np.atleast_1d(np.asarray(centre, float)),
                              True)
    return x


def test_the_block_minimiser_meets_the_blocks_optimality_conditions():
    """Random 2x2 blocks: the kernel's answer is feasible and optimal (a multiplier >= 0 for
    the bound, a subgradient |xi| <= 1 of the slip term) to round-off, in all six cases."""
    rng = np.random.default_rng(7)
    seen = set()
    for _ in range(400):
        M, b, x = _random_block_system(rng, 2, 0.2)
        upper, weight, centre = rng.normal(), abs(rng.normal()) * rng.choice([0.1, 1, 3]), \
            rng.normal()
        out = _one_block(M, b, x, upper, weight, centre)
        g = M @ out - b
        scale = np.abs(M).max() * (np.abs(out).max() + 1) + np.abs(b).max() + weight
        at_bound, stick = out[0] == upper, out[1] == centre
        assert out[0] <= upper
        if at_bound:
            assert -g[0] >= -1e-12 * scale              # the bound's multiplier
        else:
            assert abs(g[0]) <= 1e-12 * scale
        if stick:
            assert abs(g[1]) <= weight + 1e-12 * scale
        else:
            assert abs(g[1] + weight * np.sign(out[1] - centre)) <= 1e-12 * scale
        seen.add((bool(at_bound), "stick" if stick else np.sign(out[1] - centre)))
    assert len(seen) == 6, seen


def test_the_line_search_over_kinks_is_exact():
    """phi(a) = base a + curvature a^2/2 + sum_j jumps_j max(a - kinks_j, 0) on [0, longest]:
    the search's answer has the least phi of all candidates (0, the end, every kink, every
    piece's clipped stationary point), and meets the one-sided optimality conditions."""
    rng = np.random.default_rng(11)
    for trial in range(300):
        k = int(rng.integers(0, 6))
        kinks = np.sort(rng.uniform(0, 3, size=k))
        jumps = rng.uniform(0, 2, size=k)
        base, curvature = rng.normal() * 2, rng.uniform(0.05, 2)
        longest = np.inf if trial % 3 == 0 else rng.uniform(0.1, 4)
        phi = lambda a: base * a + 0.5 * curvature * a * a + jumps @ np.maximum(a - kinks, 0)
        dphi = lambda a, side: base + curvature * a + jumps @ (
            (kinks < a) if side < 0 else (kinks <= a))      # phi'(a-), phi'(a+)
        a = kink_search(base, curvature, kinks, jumps, longest)
        assert 0 <= a <= longest
        edges = np.r_[0.0, kinks[kinks < longest], min(longest, 1e6)]
        stationary = np.clip(-(base + np.r_[0.0, np.cumsum(jumps)][:edges.size - 1])
                             / curvature, edges[:-1], edges[1:])
        best = min(phi(c) for c in np.r_[edges, stationary])
        assert phi(a) <= best + 1e-13 * (1 + abs(best))
        if a > 0:
            assert dphi(a, -1) <= 1e-12
        if a < longest:
            assert dphi(a, +1) >= -1e-12


def test_a_frictionless_solve_never_enters_the_tresca_path(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("the Tresca path was entered on a frictionless problem")
    monkeypatch.setattr(tnnmg, "_tresca_solve", refuse)
    monkeypatch.setattr(tnnmg_system, "tresca_block_gauss_seidel", refuse)    # its sweeps
    for name in ("tresca_line_search_step", "tresca_stationarity", "tresca_energy"):
        monkeypatch.setattr(tnnmg, name, refuse)                              # its steps
    qp = SCENE.make(1)
    res = solve(qp, "tnnmg", tol=1e-8)
    ref = solve(qp, "pdas", tol=1e-10)
    assert res.status == "converged" and res.tangential is None
    assert energy_error(qp, res.u, ref.u) <= 1e-6


def _agrees_with_the_exact_reference(level, ratio):
    """Each step of the exact path at ``Q/(mu P) = ratio`` (the normal step with its slip
    bound, then the tangential one): friction KKT <= 1e-10 and the energy-norm distance to
    the exact answer <= 1e-8; the tangential step has stick and slip rows, and TNNMG's
    stick rows (slip exactly zero) are as many as the exact ones."""
    for st in _exact_path(level, ratio):
        step_qp, exact = st.qp, st.solution
        res = _tnnmg(step_qp)
        kkt = friction_residuals(step_qp, res.u, res.p, res.tangential)
        assert kkt.max <= 1e-10, kkt
        assert energy_error(step_qp, res.u, exact.u) <= 1e-8
        s = step_qp.friction.slip_bound
        np.testing.assert_allclose(res.tangential, exact.lam, rtol=0, atol=1e-6 * s.max())
    assert res.stats["n_stick"] > 0 and res.stats["n_slip"] > 0
    assert res.stats["n_stick"] == np.count_nonzero(exact.stick)


@pytest.mark.parametrize("level, ratio", [(1, 0.3), (1, 0.7), (2, 0.7)])
def test_tnnmg_agrees_with_the_exact_tresca_reference(level, ratio):
    _agrees_with_the_exact_reference(level, ratio)


@pytest.mark.slow
def test_tnnmg_agrees_with_the_exact_tresca_reference_level_3():
    """Level 3 (129 rows) at the larger slip zone (levels 2-4 at both ratios are measured
    in the friction guide)."""
    _agrees_with_the_exact_reference(3, 0.7)


@pytest.mark.parametrize("ratio", [0.3, 0.7])
def test_cg_on_a_tresca_face_keeps_the_answer_and_saves_steps(ratio):
    """Level 2's tangential step to tol 1e-10: with CG on the face (the default) the run has
    CG steps, its energy never rises, and its answer is the exact one as TNNMG steps alone
    give it (``krylov="none"``: no CG step); it needs at most 3/4 of their steps (measured:
    13 and 14 against 21 and 20)."""
    st = _exact_path(2, ratio)[-1]
    with_cg, without = _tnnmg(st.qp), _tnnmg(st.qp, krylov="none")
    assert with_cg.stats["n_cg"] > 0 and "cg" in with_cg.history["phase"]
    assert without.stats["n_cg"] == 0 and set(without.history["phase"]) == {"tnnmg"}
    J = np.asarray(with_cg.history["energy"])
    assert np.all(np.diff(J) <= 1e-12 * np.abs(J).max())
    for res in (with_cg, without):
        assert friction_residuals(st.qp, res.u, res.p, res.tangential).max <= 1e-10
        assert energy_error(st.qp, res.u, st.solution.u) <= 1e-8
    assert res.stats["n_stick"] == with_cg.stats["n_stick"] == np.count_nonzero(
        st.solution.stick)
    assert with_cg.iterations <= 0.75 * without.iterations, (with_cg.iterations,
                                                             without.iterations)


def test_a_face_cg_step_stops_at_a_kink_and_writes_it_exactly():
    """A CG step on a 2D Tresca face does not carry a slipping row past its kink: at the
    exact answer of level 1's tangential step, one sticking row moved off its centre by
    ``eps`` slips on the face; along the direction back to it (the preconditioner replaced
    by that direction) the face's quadratic would step past the centre, so the step is cut
    there (length ``eps``), the row is written at its centre exactly, the face is left, and
    the energy falls."""
    st = _exact_path(1, 0.7)[-1]
    fine = fine_system(st.qp, tresca=True)
    box, term = fine.box, fine.tresca
    v = box.to_v(st.solution.u)
    j = int(np.flatnonzero(st.solution.stick)[0])
    eps = 1e-3 * np.abs(term.centre).max()
    v[term.pivot] = np.where(st.solution.stick, term.centre, v[term.pivot])
    v[term.pivot[j]] = term.centre[j] + eps
    face = TrescaFace.of(fine, v)
    assert face.sign[j] == 1
    E = np.concatenate([box.pivot[face.active],
                        term.pivot[(face.sign == 0) & (term.weight > 0)]])
    back = np.zeros(st.qp.n)
    back[term.pivot[j]] = -1.0

    class Direction:                 # the preconditioner, replaced by the direction back
        def vcycle(self, g, sweeps=None):
            return back.copy()
    r = fine.f - fine.matvec(v)
    cg = TrescaFaceCG(E, sweeps=2, face=face)
    v2, r2, alpha, leave = cg.step(fine, Direction(), v, r, box.pivot, box.upper, face.active)
    assert cg.rz / float(back @ fine.matvec(back)) > 1.5 * eps     # uncut: past the kink
    assert leave and alpha == pytest.approx(eps, rel=1e-12)
    assert v2[term.pivot[j]] == term.centre[j]
    assert tresca_energy(fine, v2, r2) < tresca_energy(fine, v, r)
    np.testing.assert_allclose(r2, fine.f - fine.matvec(v2), rtol=0,
                               atol=1e-12 * np.abs(fine.f).max())


@pytest.mark.parametrize("ratio", [0.3, 0.7])
def test_the_certified_bound_of_a_tresca_answer_is_near_its_error(ratio):
    """The slipping rows' multipliers are ``s_i sign(slip_i)``, so the certificate at the
    stop weighs the iterate's error in second order: at tol 1e-6 (level 2's tangential
    step) the certified bound is at least the true energy error against the exact answer
    and at most twice it (measured: 1.1-1.4 times; with the clipped residual as the
    multipliers, over ten times)."""
    st = _exact_path(2, ratio)[-1]
    res = _tnnmg(st.qp, tol=1e-6)
    fr = st.qp.friction
    slip = fr.slip(res.u)
    slipping = (fr.slip_bound > 0) & (np.abs(slip) > 1e-8 * np.abs(slip).max())
    assert slipping.any()
    np.testing.assert_array_equal(res.tangential[slipping],
                                  fr.slip_bound[slipping] * np.sign(slip[slipping]))
    err = energy_error(st.qp, res.u, st.solution.u)
    gap = certify(st.qp, res.u, res.p, None, lam=res.tangential)
    bound = gap.relative_energy_bound
    assert 1e-9 < err and within_certificate(err, bound, gap.floor), (err, bound)
    assert bound <= min(max(2.0 * err, 4 * gap.floor), 1e-6), (err, bound, gap.floor)


def test_mu_zero_is_the_frictionless_answer():
    """Slip bounds zero: the Tresca path's answer is pdas's frictionless one to 1e-10."""
    for st in friction_path(_frictional(1, mu=0.0)):
        res = _tnnmg(st.qp, tol=1e-12)
        plain = replace(st.qp, friction=None)
        ref = solve(plain, "pdas", tol=1e-12)
        assert ref.status == "converged"
        assert energy_error(plain, res.u, ref.u) <= 1e-10
        assert np.max(np.abs(res.p - ref.p)) <= 1e-10 * np.max(ref.p)
        assert np.array_equal(res.tangential, np.zeros(st.qp.m))   # |lam| <= s = 0


def test_a_huge_mu_sticks_everywhere():
    steps = friction_path(_frictional(1, mu=1e3))
    st = steps[-1]
    res = _tnnmg(st.qp)
    fr = st.qp.friction
    contact = fr.slip_bound > 0
    assert contact.sum() >= 5 and res.stats["n_stick"] == contact.sum()
    slip = fr.slip(res.u)
    assert np.max(np.abs(slip[contact])) <= 1e-12 * np.max(np.abs(fr.T @ res.u))
    assert energy_error(st.qp, res.u, st.solution.u) <= 1e-8


@pytest.mark.parametrize("law", ["tresca", "coulomb"])
def test_the_load_path_run_by_tnnmg_is_the_exact_path(law):
    """friction_path with TNNMG's steps (each from TNNMG's previous state; Coulomb: the
    fixed point s = mu p over them) against the exact path."""
    qp = _frictional(1, friction=law)

    def by_tnnmg(step_qp):
        res = _tnnmg(step_qp)
        kkt = friction_residuals(step_qp, res.u, res.p, res.tangential)
        stick = (step_qp.friction.slip_bound > 0) & (step_qp.friction.slip(res.u) == 0)
        return TrescaSolution(res.u, res.p, res.tangential, stick, res.claimed_status,
                              res.iterations, kkt)
    for mine, exact in zip(friction_path(qp, by_tnnmg), friction_path(qp)):
        assert mine.solution.status == "converged"     # Coulomb: the fixed point too
        assert mine.solution.kkt.max <= 1e-10
        assert energy_error(exact.qp, mine.solution.u, exact.solution.u) <= 1e-8


def test_a_coulomb_step_is_the_tresca_step_of_its_bound():
    """The load path's fixed point hands over Coulomb steps with the bound given: TNNMG
    solves that Tresca step, the same iterates as with the law named tresca."""
    st = friction_path(_frictional(1))[-1]
    coulomb = replace(st.qp, friction=replace(st.qp.friction, law="coulomb"))
    assert tnnmg.supports(coulomb) == (True, "")
    a, b = _tnnmg(st.qp), _tnnmg(coulomb)
    assert np.array_equal(a.u, b.u) and np.array_equal(a.tangential, b.tangential)
    assert a.stats["friction"] == "tresca_step"


def test_a_run_stopped_short_says_so():
    """Two steps of a tangential step: max_iter with its message, the energy never rising,
    an answer of the right shape with its tangential multipliers inside their bounds."""
    st = friction_path(_frictional(1))[-1]
    res = tnnmg.solve(st.qp, 1e-10, 2, None, None, None, tnnmg.SOLVER.options())
    assert res.claimed_status == "max_iter" and "not verified after 2 steps" in res.message
    assert res.iterations == 2 and len(res.history["energy"]) == 2
    assert res.history["energy"][1] <= res.history["energy"][0]
    s = st.qp.friction.slip_bound
    assert res.u.shape == (st.qp.n,) and np.all(np.abs(res.tangential) <= s)
    assert friction_residuals(st.qp, res.u, res.p, res.tangential).max > 1e-10


def test_the_steps_split_at_the_last_change_of_the_face():
    """The tangential step from the normal step's answer (everything sticks there, the
    answer slips in an annulus): ``steps_to_face`` is the step at which the face last
    changed, at least the first, and from it on the stick set is the exact one;
    ``steps_on_face`` are the rest."""
    normal, tangential = _exact_path(1, 0.7)
    res = tnnmg.solve(tangential.qp, 1e-10, 500, None, normal.solution.u, None,
                      tnnmg.SOLVER.options())
    assert res.claimed_status == "converged", res.message
    to_face, on_face = res.stats["steps_to_face"], res.stats["steps_on_face"]
    assert to_face + on_face == res.iterations and to_face >= 1 and res.stats["n_slip"] > 0
    stuck = np.count_nonzero(tangential.solution.stick)
    assert res.history["n_stick"][to_face - 1:] == [stuck] * (on_face + 1)
    residual = res.history["residual"]
    rate = res.stats["contraction_on_face"]
    assert 0 < rate < 1
    assert rate ** on_face * residual[to_face - 1] == pytest.approx(residual[-1], rel=1e-9)
