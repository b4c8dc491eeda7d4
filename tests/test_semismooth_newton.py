"""The inexact semismooth Newton solver: projected PCG on a known equality-constrained QP,
agreement with the exact PDAS in 2D and 3D, warm starts, and its honest status."""
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from problems.circle_square import PROBLEM as CIRCLE_SQUARE
from problems.cube_sphere import PROBLEM as CUBE_SPHERE
from problems.qp import energy_error
from solvers.augmented_projection import nested_initial_guess
from solvers.interface import solve
from solvers.semismooth_newton import projected_pcg


def test_projected_pcg_solves_the_equality_constrained_qp():
    """Against the KKT system solved directly: min 1/2 x'Ax - f'x s.t. Cx = d."""
    rng = np.random.default_rng(0)
    n, m = 60, 7
    R = sp.random(n, n, density=0.2, random_state=rng)
    A = sp.csr_matrix(R @ R.T + sp.eye(n))
    C = sp.csr_matrix(rng.normal(size=(m, n)) * (rng.random((m, n)) < 0.2) + np.eye(m, n))
    f, d = rng.normal(size=n), rng.normal(size=m)
    K = sp.bmat([[A, C.T], [C, None]], format="csc")
    exact = spla.spsolve(K, np.concatenate([f, d]))[:n]
    x, steps, lu = projected_pcg(A, C, f, d, lambda r: r / A.diagonal(), np.zeros(n), 1e-13, 500)
    np.testing.assert_allclose(x, exact, rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(C @ x, d, atol=1e-12)
    assert 0 < steps <= n - m


@pytest.mark.parametrize("problem", [CIRCLE_SQUARE, CUBE_SPHERE], ids=["2d", "3d"])
def test_agrees_with_the_exact_pdas(problem):
    qp = problem.make(1)
    ref = solve(qp, "pdas", tol=1e-12)
    res = solve(qp, "semismooth_newton", tol="high")
    assert res.claimed_status == res.status == "converged", res.message
    assert energy_error(qp, res.u, ref.u) < 1e-8
    np.testing.assert_allclose(res.p, ref.p, atol=1e-7 * ref.p.max())
    assert np.array_equal(res.p > 0, ref.p > 0)
    # one V-cycle per inner step and one per Newton step; far fewer than the unknowns
    assert res.stats["n_vcycles"] == res.stats["inner_steps"] + res.iterations < qp.n / 50


def test_a_nested_start_saves_newton_steps():
    coarse, fine = CIRCLE_SQUARE.make(1), CIRCLE_SQUARE.make(2)
    rc = solve(coarse, "semismooth_newton", tol="mid")
    u0, p0 = nested_initial_guess(coarse, rc, fine)
    cold = solve(fine, "semismooth_newton", tol="mid")
    warm = solve(fine, "semismooth_newton", tol="mid", u0=u0, p0=p0)
    assert cold.status == warm.status == "converged"
    assert warm.iterations < cold.iterations and warm.stats["inner_steps"] < cold.stats["inner_steps"]


def test_stops_short_honestly():
    qp = CIRCLE_SQUARE.make(1)
    res = solve(qp, "semismooth_newton", tol="high", max_iter=2)
    assert res.status == "max_iter" and res.iterations == 2
