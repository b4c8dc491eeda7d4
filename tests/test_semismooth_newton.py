"""The inexact semismooth Newton solver: projected PCG on a known equality-constrained QP,
agreement with the exact PDAS in 2D and 3D, warm starts, and its honest status."""
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from problems.circle_square import PROBLEM as CIRCLE_SQUARE
from problems.cube_sphere import PROBLEM as CUBE_SPHERE
from problems.kkt import energy_error
from problems.qp import ContactQP
from solvers.augmented_projection import nested_initial_guess
from solvers.interface import solve
from solvers.kernels.face import face_projector
from solvers.kernels.multigrid import vcycle
from solvers.semismooth_newton import projected_pcg
from test_solvers import cycling_qp


@pytest.mark.parametrize("kind", ["harmonic", "euclidean"])
def test_projected_pcg_solves_the_equality_constrained_qp(kind):
    """Against the KKT system solved directly: min 1/2 x'Ax - f'x s.t. Cx = d."""
    rng = np.random.default_rng(0)
    n, m = 60, 7
    R = sp.random(n, n, density=0.2, random_state=rng)
    A = sp.csr_matrix(R @ R.T + sp.eye(n))
    C = sp.csr_matrix(rng.normal(size=(m, n)) * (rng.random((m, n)) < 0.2) + np.eye(m, n))
    f, d = rng.normal(size=n), rng.normal(size=m)
    K = sp.bmat([[A, C.T], [C, None]], format="csc")
    exact = spla.spsolve(K, np.concatenate([f, d]))
    face = face_projector(A, C, kind, hops=1)
    x, steps = projected_pcg(A, face, f, d, lambda r: r / A.diagonal(), np.zeros(n), 1e-13, 500)
    np.testing.assert_allclose(x, exact[:n], rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(C @ x, d, atol=1e-12)
    assert 0 < steps <= n - m
    # the projector's multipliers are the KKT system's at the solution
    np.testing.assert_allclose(face.multipliers(f - A @ x), exact[n:], rtol=1e-8, atol=1e-10)


@pytest.mark.parametrize("kind", ["harmonic", "euclidean"])
def test_face_projector_is_a_projector_onto_the_face(kind):
    rng = np.random.default_rng(1)
    qp = CIRCLE_SQUARE.make(1)
    B_I = qp.B.tocsr()[: max(3, qp.m // 3)]
    face = face_projector(qp.A, B_I, kind, hops=2)
    v, w = rng.normal(size=qp.n), rng.normal(size=qp.n)
    Pv = face.project(v)
    np.testing.assert_allclose(B_I @ Pv, 0.0, atol=1e-12 * np.abs(B_I @ v).max())
    np.testing.assert_allclose(face.project(Pv), Pv, rtol=1e-12, atol=1e-14 * np.abs(v).max())
    # Pi' is the adjoint of Pi: the preconditioner Pi M Pi' is symmetric
    assert abs(w @ face.project(v) - face.project_T(w) @ v) <= 1e-12 * np.abs(w).sum() * np.abs(v).max()
    g = rng.normal(size=B_I.shape[0])
    np.testing.assert_allclose(B_I @ face.lift(v, g), g, atol=1e-12 * np.abs(g).max())
    if kind == "euclidean":  # the orthogonal projector of Gould, Hribar and Nocedal
        BBt = (B_I @ B_I.T).toarray()
        np.testing.assert_allclose(Pv, v - B_I.T @ np.linalg.solve(BBt, B_I @ v), atol=1e-12)


def test_harmonic_projection_keeps_the_vcycle_rate_on_the_face():
    """The same face, the same V-cycle: projected PCG along local harmonic extensions
    needs fewer steps to the same error than the orthogonal projection."""
    qp = CIRCLE_SQUARE.make(3)
    ref = solve(qp, "pdas", tol=1e-12)
    idx = np.flatnonzero(ref.p > 0)
    B_I = qp.B.tocsr()[idx]
    M = vcycle(qp.A, "gmg", qp.multilevel, qp.dim, qp.free_dofs, smoother="symmetric_gs",
               sweeps=1).raw
    errors = {}
    for kind in ("harmonic", "euclidean"):
        face = face_projector(qp.A, B_I, kind, hops=2)
        x, steps = projected_pcg(qp.A, face, qp.f, qp.g[idx], M, np.zeros(qp.n), 1e-30, 8)
        errors[kind] = energy_error(qp, x, ref.u)
    assert errors["harmonic"] < 0.2 * errors["euclidean"], errors


@pytest.mark.parametrize("face", ["harmonic", "euclidean"])
@pytest.mark.parametrize("problem", [CIRCLE_SQUARE, CUBE_SPHERE], ids=["2d", "3d"])
def test_agrees_with_the_exact_pdas(problem, face):
    qp = problem.make(1)
    ref = solve(qp, "pdas", tol=1e-12)
    res = solve(qp, "semismooth_newton", tol="high", face=face)
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


def test_face_projector_refuses_bad_input():
    qp = CIRCLE_SQUARE.make(0)
    B = qp.B.tocsr()
    with pytest.raises(ValueError, match="allowed: harmonic, euclidean"):
        face_projector(qp.A, B[:2], "oblique")
    with pytest.raises(ValueError, match="hops must be >= 0"):
        face_projector(qp.A, B[:2], "harmonic", hops=-1)
    empty = face_projector(qp.A, B[:0])          # no active constraint: the identity
    v = np.arange(qp.n, dtype=float)
    assert np.array_equal(empty.project(v), v) and np.array_equal(empty.project_T(v), v)


@pytest.mark.parametrize("kind", ["harmonic", "euclidean"])
def test_face_projector_of_dependent_rows_keeps_a_basis(kind):
    """A duplicated row and a row that is the sum of two others: the projector keeps a
    basis of the rows (the same face), the dependent rows get multiplier zero, and the
    multipliers still reproduce a force ``B_I' p`` exactly."""
    qp = CIRCLE_SQUARE.make(0)
    B = qp.B.tocsr()
    B_I = sp.vstack([B[:3], B[1:2], B[0:1] + B[2:3]], format="csr")
    g_I = B_I @ np.linspace(0.1, 0.2, qp.n)                      # consistent gaps
    face = face_projector(qp.A, B_I, kind, hops=2, g_I=g_I)
    assert face.kept.size == 3 and face.n_rows == 5
    v = np.random.default_rng(3).normal(size=qp.n)
    assert np.max(np.abs(B_I @ face.project(v))) <= 1e-12 * np.max(np.abs(B_I @ v))
    x = face.lift(v, g_I)
    assert np.max(np.abs(B_I @ x - g_I)) <= 1e-12 * np.max(np.abs(g_I))
    p = face.multipliers(B_I.T @ np.array([1.0, 2.0, 3.0, 0.0, 0.0]))
    assert np.count_nonzero(p) == 3
    np.testing.assert_allclose(B_I.T @ p, B_I.T @ np.array([1.0, 2.0, 3.0, 0.0, 0.0]),
                               rtol=0, atol=1e-12)


# --------------------------------------------------------------------- the fallback
def _fallback_energies(res) -> np.ndarray:
    phase = np.array(res.history["phase"])
    return np.array(res.history["energy"])[phase == "fallback"]


def test_a_stalled_newton_iteration_falls_back_and_says_so():
    """From a guess on which the PDAS update cycles (tests.test_solvers.cycling_qp), with
    the patience cut to one step: the monotone fallback takes over, lowers the energy at
    every step and ends on the exact solution; the message names the fallback."""
    qp, p0 = cycling_qp()
    ref = solve(qp, "pdas", tol="high")
    res = solve(qp, "semismooth_newton", tol="high", u0=np.zeros(4), p0=p0,
                patience=1)
    assert res.status == "converged" and res.stats["fallback"], res.message
    assert "fell back to the monotone primal active-set method" in res.message
    energies = _fallback_energies(res)
    assert energies.size == res.stats["fallback_steps"] >= 2
    assert np.all(np.diff(energies) <= 1e-14 * np.abs(energies).max())
    assert energy_error(qp, res.u, ref.u) < 1e-10
    # without a fallback the same stall is an honest failure, at once
    none = solve(qp, "semismooth_newton", tol="high", u0=np.zeros(4), p0=p0,
                 patience=1, fallback="none", max_iter=50)
    assert none.status == "failed" and "no fallback" in none.message
    assert none.iterations < 50


@pytest.mark.parametrize("problem", [CIRCLE_SQUARE, CUBE_SPHERE], ids=["2d", "3d"])
def test_the_monotone_method_alone_solves_a_scene(problem):
    """``patience=0``: the primal feasible active-set method from the start;
    feasible and energy-monotone at every step, verified at the end like Newton."""
    qp = problem.make(1)
    ref = solve(qp, "pdas", tol=1e-12)
    res = solve(qp, "semismooth_newton", tol="mid", patience=0)
    assert res.status == "converged", res.message
    assert res.stats["newton_steps"] == 0 and res.stats["fallback_steps"] == res.iterations
    energies = _fallback_energies(res)
    assert np.all(np.diff(energies) <= 1e-12 * np.abs(energies).max())
    assert energy_error(qp, res.u, ref.u) < 1e-5
    assert np.max(qp.B @ res.u - qp.g) <= 1e-12 * np.abs(qp.g).max()


def test_no_fallback_from_the_start_is_refused():
    from problems.spec import ParameterError
    with pytest.raises(ParameterError, match="parameter 'patience'"):
        solve(CIRCLE_SQUARE.make(0), "semismooth_newton", patience=0, fallback="none")


def test_the_monotone_method_on_a_problem_without_constraints():
    """No rows: the feasible start is the start itself (no max over an empty set)."""
    qp = ContactQP(A=2 * sp.eye(4), f=np.ones(4), B=sp.csr_matrix((0, 4)), g=np.zeros(0))
    res = solve(qp, "semismooth_newton", tol="high", patience=0)
    assert res.status == "converged", res.message
    np.testing.assert_allclose(res.u, 0.5, rtol=1e-12)
