"""TNNMG on one 3D Tresca step: the node block's exact disc-constrained minimiser and the
line search on the nonsmooth energy, each against an independent brute-force minimiser;
the tangential rows as coordinates; the solver's answers on cube_sphere verified (friction
KKT and certificate)."""
import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from solvers import tnnmg
from solvers._block_gs import disc_block_minimiser
from test_friction_tnnmg import _one_block


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
        a, reached, short = tnnmg._disc_line_search(base, curvature, z, dt, weight, longest)
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
        L = rng.normal(size=(3, 3))
        M = L @ L.T + 0.1 * np.eye(3)
        b, x = rng.normal(size=3), rng.normal(size=3)
        upper, weight, centre = rng.normal(), abs(rng.normal()), rng.normal(size=2)
        out = _one_block(M, b, x, upper, weight, centre)
        d = np.zeros(3)
        case = disc_block_minimiser(M, b - M @ x, upper - x[0], weight, centre - x[1:], d)
        cases.add(case)
        np.testing.assert_allclose(out, x + d, rtol=0, atol=1e-12 * (1 + np.abs(x + d).max()))
        assert (out[0] == upper) == (case >= 2)
        assert np.array_equal(out[1:], centre) == (case % 2 == 1)
    assert cases == {0, 1, 2, 3}
