"""TNNMG on one 3D Tresca step: the node block's exact disc-constrained minimiser and the
line search on the nonsmooth energy, each against an independent brute-force minimiser;
the tangential rows as coordinates; the solver's answers on cube_sphere verified (friction
KKT and certificate)."""
from dataclasses import replace

import clarabel
import numpy as np
import pytest
import scipy.sparse as sp
from scipy.optimize import minimize_scalar

from problems.friction.residuals import friction_residuals
from problems.kkt import energy_error
from problems.spec import problems
from solvers import tnnmg
from solvers.kernels.block_gs import disc_block_minimiser
from solvers.certificate import certify
from solvers.kernels.contact_box import box_transformation
from solvers.kernels.tnnmg_tresca import disc_line_search
from solvers.interface import solve
from solvers.kernels.tresca import as_tresca_solution, friction_path, tangential_ratio
from test_friction_tnnmg import _one_block, _random_block_system
from agreement import within_certificate


def _block_energy(M, r, weight, e, d):
    return 0.5 * d @ M @ d - r @ d + weight * np.linalg.norm(d[1:] - e)


def _brute_block(M, r, h, weight, e):
    """The block's minimiser by nested 1D minimisations: the normal unknown by a bounded
    scalar search on ``(-inf, h]``; for each, the tangential part over directions (a grid
    of angles, then a bounded scalar search), the length along each in closed form."""
    angles = np.linspace(0.0, 2.0 * np.pi, 361)[:-1]
    Mtt = M[1:, 1:]

    def along(g, phi):
        u = np.array([np.cos(phi), np.sin(phi)])
        q = u @ Mtt @ u
        rho = max(g @ u - weight, 0.0) / q
        return 0.5 * rho * rho * q - rho * (g @ u - weight), rho * u

    def tangential(d0):
        g = r[1:] - M[1:, 0] * d0 - Mtt @ e
        j = int(np.argmin([along(g, phi)[0] for phi in angles]))
        phi = minimize_scalar(lambda t: along(g, t)[0], bounds=(angles[j] - 0.02, angles[j] + 0.02),
                              method="bounded", options={"xatol": 1e-13}).x
        d = np.r_[d0, e + along(g, phi)[1]]
        return _block_energy(M, r, weight, e, d), d

    span = 10.0 * (abs(h) + np.abs(r).sum() / M[0, 0] + np.abs(e).sum() + weight)
    d0 = minimize_scalar(lambda t: tangential(t)[0], bounds=(h - span, h), method="bounded",
                         options={"xatol": 1e-12}).x
    return min(tangential(d0), tangential(h), key=lambda c: c[0])


def test_the_disc_block_minimiser_is_the_brute_force_minimiser():
    """Random SPD 3x3 blocks: the minimiser's energy is the brute-force one's to round-off
    (never above it by more than 1e-11 relative), the points agree to 1e-6 (the brute
    force's own accuracy), and all four cases (normal free/at its bound x stick/slip)
    occur."""
    rng = np.random.default_rng(3)
    seen = set()
    for _ in range(24):
        L = rng.normal(size=(3, 3))
        M = L @ L.T + rng.choice([0.05, 0.5]) * np.eye(3)
        r, e = rng.normal(size=3), rng.normal(size=2)
        h, weight = rng.normal(), abs(rng.normal()) * rng.choice([0.1, 1.0, 3.0])
        d = np.zeros(3)
        case = disc_block_minimiser(M, r, h, weight, e, d)
        seen.add(case)
        brute_energy, brute = _brute_block(M, r, h, weight, e)
        energy = _block_energy(M, r, weight, e, d)
        assert energy <= brute_energy + 1e-11 * (1.0 + abs(brute_energy))
        assert np.max(np.abs(d - brute)) <= 1e-6 * (1.0 + np.max(np.abs(brute)))
    assert seen == {0, 1, 2, 3}, seen


def test_the_disc_block_minimiser_meets_the_optimality_conditions():
    """Random blocks, ill-conditioned ones among them (tangential eigenvalues 1e-6 apart
    to 1e6): feasibility, the bound's multiplier >= 0, and a subgradient of the disc term
    (|g_t| <= weight at stick, g_t = -weight z/|z| at slip), to 1e-12 relative; the bound
    and the stick point are exact."""
    rng = np.random.default_rng(5)
    for trial in range(2000):
        Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        M = Q @ np.diag(10.0 ** rng.uniform(-3, 3, size=3)) @ Q.T
        r, e = rng.normal(size=3) * 10.0 ** rng.uniform(-2, 2), rng.normal(size=2)
        h, weight = rng.normal(), abs(rng.normal()) * 10.0 ** rng.uniform(-3, 1)
        d = np.zeros(3)
        case = disc_block_minimiser(M, r, h, weight, e, d)
        g = M @ d - r
        scale = np.abs(M).max() * (np.abs(d).max() + 1.0) + np.abs(r).max() + weight
        at_bound, stick = case >= 2, case % 2 == 1
        assert d[0] <= h and (d[0] == h) == at_bound or (not at_bound and d[0] < h)
        if at_bound:
            assert d[0] == h and -g[0] >= -1e-12 * scale
        else:
            assert abs(g[0]) <= 1e-12 * scale, (trial, g)
        z = d[1:] - e
        if stick:
            assert np.array_equal(d[1:], e) and np.linalg.norm(g[1:]) <= weight * (1 + 1e-15)
        else:
            assert np.linalg.norm(g[1:] + weight * z / np.linalg.norm(z)) <= 1e-12 * scale, \
                (trial, g, z)


def _phi(base, curvature, z, dt, weight, a):
    return base * a + 0.5 * curvature * a * a + weight @ np.linalg.norm(z + a * dt, axis=1)


def test_the_disc_line_search_is_the_minimiser_along_the_segment():
    """phi(a) = base a + curvature a^2/2 + sum_i weight_i |z_i + a dt_i| (2-vectors) on
    [0, longest]: the search's answer has phi no larger than a dense grid's best refined by
    a bounded scalar search, to round-off; rows with z_i antiparallel to dt_i (kinks) are
    among them, and a kink taken is reported exactly."""
    rng = np.random.default_rng(13)
    kinks_taken = 0
    for trial in range(300):
        m = int(rng.integers(1, 8))
        z, dt = rng.normal(size=(m, 2)), rng.normal(size=(m, 2))
        turn = rng.uniform(size=m) < 0.4               # antiparallel: a kink ahead
        z[turn] = -rng.uniform(0.1, 2.0, size=(turn.sum(), 1)) * dt[turn]
        weight = rng.uniform(0, 2, size=m) * (rng.uniform(size=m) < 0.9)
        dt[rng.uniform(size=m) < 0.1] = 0.0
        base, curvature = rng.normal() * 3, rng.uniform(0.05, 2)
        longest = np.inf if trial % 3 == 0 else rng.uniform(0.1, 4)
        a, reached, short = disc_line_search(base, curvature, z, dt, weight, longest)
        assert 0.0 <= a <= longest
        end = min(longest, 50.0)
        grid = np.linspace(0.0, end, 4001)
        vals = base * grid + 0.5 * curvature * grid ** 2 + np.linalg.norm(
            z[None] + grid[:, None, None] * dt[None], axis=2) @ weight
        j = int(np.argmin(vals))
        ref = minimize_scalar(lambda t: _phi(base, curvature, z, dt, weight, t),
                              bounds=(grid[max(j - 1, 0)], grid[min(j + 1, grid.size - 1)]),
                              method="bounded", options={"xatol": 1e-14}).fun
        best = min(ref, vals.min())
        assert _phi(base, curvature, z, dt, weight, a) <= best + 1e-13 * (1 + abs(best))
        if reached.any():
            kinks_taken += 1
            assert np.allclose(z[reached] + a * dt[reached], 0.0, atol=1e-14)
        assert short == (a == longest and np.isfinite(longest) and a > 0)
    assert kinks_taken > 0


def test_the_sweep_takes_a_3d_block_to_the_disc_minimiser():
    """One sweep of the Tresca kernel on a single 3x3 block system is the block minimiser
    applied to its residual (the kernel rebuilds the block from its first column and the
    inverse of its tangential part: equal to round-off), the bound and the stick point
    written exactly."""
    rng = np.random.default_rng(17)
    cases = set()
    for _ in range(200):
        M, b, x = _random_block_system(rng, 3, 0.1)
        upper, weight, centre = rng.normal(), abs(rng.normal()), rng.normal(size=2)
        out = _one_block(M, b, x, upper, weight, centre)
        d = np.zeros(3)
        case = disc_block_minimiser(M, b - M @ x, upper - x[0], weight, centre - x[1:], d)
        cases.add(case)
        np.testing.assert_allclose(out, x + d, rtol=0, atol=1e-12 * (1 + np.abs(x + d).max()))
        assert (out[0] == upper) == (case >= 2)
        assert np.array_equal(out[1:], centre) == (case % 2 == 1)
    assert cases == {0, 1, 2, 3}


# --- TNNMG on cube_sphere's Tresca steps ----------------------------------------------

CUBE = problems()["cube_sphere"]

#: The held cap's shift along x that gives Q/(mu P) about 0.3 and 0.7 at mu = 0.5 on levels
#: 1 and 2 (found by solvers.kernels.tresca.path_for_ratio with TNNMG; the tests measure the ratio).
SHIFT_FOR_RATIO = {0.3: 0.035, 0.7: 0.088}


def _cube(level, **kw):
    return CUBE.make(level, **{"friction": "tresca", "mu": 0.5, **kw})


def _verified_tnnmg(step_qp, tol=1e-10, u0=None):
    """TNNMG's answer to one Tresca step through the suite's interface (``converged`` only
    when verified), checked again here: the friction KKT residuals and the certified
    Tresca bound meet ``tol``."""
    res = solve(step_qp, "tnnmg", tol=tol, u0=u0)
    assert res.status == "converged", res.message
    assert res.stats["n_cg"] == 0          # 3D: TNNMG steps only (no CG on a face)
    assert friction_residuals(step_qp, res.u, res.p, res.tangential).max <= tol
    assert certify(step_qp, res.u, res.p, tol, lam=res.tangential).meets(tol)
    return res


def _socp_answer(step_qp):
    """The Tresca step as a second-order cone program solved by an interior-point method
    (Clarabel): ``min 1/2 u'Au - f'u + s't`` with ``B u <= g`` and ``|T_i u - r_i| <= t_i``
    (one 3-dimensional cone per constrained node): an answer independent of TNNMG's
    transformation, smoother and line search."""
    fr = step_qp.friction
    n, m, k = step_qp.n, step_qp.m, fr.components
    P = sp.block_diag([sp.csc_matrix(step_qp.A), sp.csc_matrix((m, m))]).tocsc()
    cost = np.r_[-step_qp.f, fr.slip_bound]
    # cone rows: (t_i, T_i u + offset_i - previous_i) = b - G x
    T = sp.csr_matrix(fr.T)
    order = np.arange(m * (k + 1)).reshape(m, k + 1)
    t_rows = sp.csr_matrix((-np.ones(m), (order[:, 0], n + np.arange(m))),
                           shape=(m * (k + 1), n + m))
    slip_rows = sp.csr_matrix(sp.csr_matrix(-T).tocoo(), copy=True).tocoo()
    slip_rows = sp.csr_matrix((slip_rows.data, (order[:, 1:].ravel()[slip_rows.row],
                                                slip_rows.col)), shape=(m * (k + 1), n + m))
    G = sp.vstack([sp.hstack([step_qp.B, sp.csr_matrix((m, m))]), t_rows + slip_rows]).tocsc()
    rhs = np.zeros(m * (k + 1))
    rhs[order[:, 1:].ravel()] = fr.offset - fr.previous
    cones = [clarabel.NonnegativeConeT(m)] + [clarabel.SecondOrderConeT(k + 1)] * m
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = 1e-13
    settings.max_iter = 400
    out = clarabel.DefaultSolver(P, cost, G, np.r_[step_qp.g, rhs], cones, settings).solve()
    assert str(out.status) == "Solved", out.status
    return np.asarray(out.x[:n])


def _path_by_tnnmg(qp, tol=1e-10):
    """The load path with TNNMG's verified steps (each from its previous state)."""
    return friction_path(qp, lambda step_qp: as_tresca_solution(
        step_qp, _verified_tnnmg(step_qp, tol)))


def test_cube_sphere_tangential_rows_become_coordinates_exactly():
    """u = T v with two tangential rows per constrained node: T is invertible with the
    inverse it claims, each normal row bounds one unknown, each node's tangential rows
    read its two other unknowns through theta_i R_i with R_i orthogonal."""
    qp = _cube(1, shift=0.035)
    fr = qp.friction
    box = box_transformation(qp, fr.T)
    m = qp.m
    assert abs(box.T @ box.T_inv - sp.identity(qp.n)).max() <= 1e-12
    BT = (qp.B @ box.T).tocsr()
    target = sp.csr_matrix((box.scale, (np.arange(m), box.pivot)), shape=BT.shape)
    assert abs(BT - target).max() <= 1e-12 * abs(qp.B).max()
    R, theta = box.tangential_frame, box.tangential_scale
    assert R.shape == (m, 2, 2) and np.all(theta > 0)
    assert np.abs(np.einsum("ijl,ihl->ijh", R, R) - np.eye(2)).max() <= 1e-12
    pivots = box.tangential_pivot.reshape(m, 2)
    rows = np.repeat(np.arange(2 * m), 2)
    cols = pivots[np.repeat(np.arange(m), 2)].ravel()
    target = sp.csr_matrix(((theta[:, None, None] * R).ravel(), (rows, cols)),
                           shape=fr.T.shape)
    assert abs((fr.T @ box.T).tocsr() - target).max() <= 1e-12 * abs(fr.T).max()
    blocks = np.repeat(np.arange(box.node_ptr.size - 1), np.diff(box.node_ptr))
    block_of = np.empty(qp.n, dtype=np.int64)
    block_of[box.node_dofs] = blocks
    assert np.all(block_of[pivots] == block_of[box.pivot][:, None])     # the node's own
    u = np.random.default_rng(1).normal(size=qp.n)
    np.testing.assert_allclose(box.to_u(box.to_v(u)), u, rtol=0, atol=1e-12 * np.abs(u).max())


@pytest.mark.parametrize("ratio", [0.3, 0.7])
def test_tnnmg_on_a_cube_sphere_tresca_path_level_1(ratio):
    """Level 1 (81 constrained nodes), mu = 0.5: the normal step and the tangential step,
    each verified (friction KKT and certificate, 1e-10) and within 1e-8 (relative energy
    norm) of the cone program's answer; the tangential step at Q/(mu P) = ratio +- 0.03
    with sticking and slipping nodes."""
    steps = _path_by_tnnmg(_cube(1, shift=SHIFT_FOR_RATIO[ratio]))
    for st in steps:
        assert energy_error(st.qp, st.solution.u, _socp_answer(st.qp)) <= 1e-8
    assert abs(tangential_ratio(steps) - ratio) <= 0.03
    res = _verified_tnnmg(steps[-1].qp)
    assert res.stats["n_stick"] > 0 and res.stats["n_slip"] > 0


def test_the_certified_bound_of_a_3d_tresca_answer_is_near_its_error():
    """A slipping node's multiplier is ``s_i slip_i / |slip_i|``, so the certificate at the
    stop weighs the iterate's error in second order: at tol 1e-6 on the tangential step
    of level 1 (Q/(mu P) ~ 0.7) the certified bound is at least the true energy error
    against the cone program's answer and at most three times it (measured: 2.1 times;
    with the clipped residual as the multipliers, 170 times)."""
    st = _path_by_tnnmg(_cube(1, shift=SHIFT_FOR_RATIO[0.7]))[-1]
    res = solve(st.qp, "tnnmg", tol=1e-6)
    assert res.status == "converged", res.message
    fr = st.qp.friction
    slip = fr.blocks(fr.slip(res.u))
    length = np.linalg.norm(slip, axis=1)
    slipping = (fr.slip_bound > 0) & (length > 1e-8 * length.max())
    assert slipping.sum() >= 5
    np.testing.assert_allclose(
        fr.blocks(res.tangential)[slipping],
        fr.slip_bound[slipping, None] * slip[slipping] / length[slipping, None],
        rtol=0, atol=1e-12 * fr.slip_bound.max())
    err = energy_error(st.qp, res.u, _socp_answer(st.qp))
    gap = certify(st.qp, res.u, res.p, None, lam=res.tangential)
    bound = gap.relative_energy_bound
    assert 1e-9 < err and within_certificate(err, bound, gap.floor), (err, bound)
    assert bound <= min(max(3.0 * err, 4 * gap.floor), 1e-6), (err, bound, gap.floor)


def test_mu_zero_is_the_frictionless_tnnmg_answer():
    """Slip bounds zero: each step's answer is TNNMG's frictionless one to 1e-10."""
    for st in friction_path(_cube(1, mu=0.0, shift=0.035),
                            lambda q: as_tresca_solution(q, _verified_tnnmg(q, 1e-12))):
        plain = replace(st.qp, friction=None)
        ref = solve(plain, "tnnmg", tol=1e-12)
        assert ref.status == "converged", ref.message
        assert energy_error(plain, st.solution.u, ref.u) <= 1e-10
        assert np.max(np.abs(st.solution.p - ref.p)) <= 1e-10 * np.max(ref.p)
        assert np.array_equal(st.solution.lam, np.zeros(2 * st.qp.m))


def test_a_3d_run_stopped_short_says_so():
    """Two steps of a tangential step: max_iter with its message, the energy never rising,
    the tangential multipliers inside their discs (to the radial clip's round-off)."""
    st = _path_by_tnnmg(_cube(1, shift=0.035))[-1]
    res = tnnmg.solve(st.qp, 1e-10, 2, None, None, None, tnnmg.SOLVER.options())
    assert res.claimed_status == "max_iter" and "not verified after 2 steps" in res.message
    assert res.history["energy"][1] <= res.history["energy"][0]
    fr = st.qp.friction
    assert np.all(fr.magnitude(res.tangential) <= fr.slip_bound * (1 + 1e-15))
    assert friction_residuals(st.qp, res.u, res.p, res.tangential).max > 1e-10


@pytest.mark.slow
@pytest.mark.parametrize("ratio", [0.3, 0.7])
def test_tnnmg_on_a_cube_sphere_tresca_path_level_2(ratio):
    """Level 2 (289 constrained nodes): each step verified, and within 1e-8 of a second
    TNNMG run started elsewhere (from the frictionless answer of the step) and verified
    to 1e-12; Q/(mu P) = ratio +- 0.03 with sticking and slipping nodes."""
    steps = _path_by_tnnmg(_cube(2, shift=SHIFT_FOR_RATIO[ratio]))
    for st in steps:
        start = solve(replace(st.qp, friction=None), "tnnmg", tol=1e-8).u
        other = _verified_tnnmg(st.qp, 1e-12, u0=start)
        assert energy_error(st.qp, st.solution.u, other.u) <= 1e-8
    assert abs(tangential_ratio(steps) - ratio) <= 0.03
    res = _verified_tnnmg(steps[-1].qp)
    assert res.stats["n_stick"] > 0 and res.stats["n_slip"] > 0


def test_a_huge_mu_sticks_everywhere_in_3d():
    """mu = 1000: in the tangential step every node in contact sticks, its slip (both
    components) exactly zero in TNNMG's coordinates, to round-off in u's."""
    st = _path_by_tnnmg(_cube(1, mu=1e3, shift=0.035))[-1]
    res = _verified_tnnmg(st.qp)
    fr = st.qp.friction
    contact = fr.slip_bound > 0
    assert contact.sum() >= 10 and res.stats["n_stick"] == contact.sum()
    assert res.stats["n_slip"] == 0
    slip = fr.magnitude(fr.slip(res.u))
    assert np.max(slip[contact]) <= 1e-12 * np.max(np.abs(fr.T @ res.u))
