"""Alg. 8.4 on the stabilised two-sided formulation (Sect. 7.5, (7.10)/(7.11)): the
multilevel ``S-hat`` over both surfaces' rows
(:func:`solvers.kernels.schur.stabilised_schur_apply`), the scene parameter ``coupling``
and the nested initial guess of the reverse rows."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from problems import circle_square, cube_sphere
from problems.spec import ParameterError
from solvers import augmented_projection as ap
from solvers.interface import solve
from solvers.kernels.multigrid import lanczos_extremes
from solvers.reference import reference_solve
from solvers.kernels.schur import multilevel_schur_apply, stabilised_schur_apply

SCENES = {"circle_square": circle_square.PROBLEM, "cube_sphere": cube_sphere.PROBLEM}


def _kappa(qp, apply, size):
    """``kappa(S-hat^{-1} S)`` with the exact ``S = B A^{-1} B' + C`` (sparse LU) and
    ``S-hat^{-1}`` by CG; 40 Lanczos steps (the operators are small)."""
    lu = spla.splu(sp.csc_matrix(qp.A))
    Bt = sp.csr_matrix(qp.B.T)
    c = qp.C.diagonal() if qp.C is not None else 0.0
    S = lambda q: qp.B @ lu.solve(Bt @ q) + c * q
    K = spla.LinearOperator((size, size), matvec=apply)
    inv = lambda b: spla.cg(K, b, rtol=1e-11, atol=0.0, maxiter=20 * size)[0]
    lo, hi = lanczos_extremes(S, size, min(40, size), inv, seed=3)
    return hi / lo


@pytest.mark.parametrize("scene, levels", [("circle_square", (1, 2)), ("cube_sphere", (0, 1))])
def test_stabilised_multilevel_schur_is_spectrally_equivalent(scene, levels):
    """kappa(S-hat^{-1} S) of the stabilised operator stays below 10 on two levels (measured:
    2D 5.8, 6.9; 3D 4.9, 6.3; the nodal operator 2.7-4.6), where the constrained surface's
    operator alone (the reverse rows left to ``C``) grows like h^-1 (measured 2D 29, 56)."""
    for level in levels:
        qp = SCENES[scene].make(level, coupling="stabilised")
        apply, diag = stabilised_schur_apply(qp)
        c = qp.C.diagonal()
        kappa = _kappa(qp, lambda q: apply(q) + c * q, qp.m)
        assert kappa < 10.0, (scene, level, kappa)
        if scene == "circle_square":
            # without the mismatch term: the multilevel operator of the constrained rows
            # embedded by [I; T] plus C is far from S (its kappa grows with 1/h)
            K = sp.vstack([sp.identity(qp.m_contact), qp.stabilisation.transfer]).tocsr()
            base = multilevel_schur_apply(qp.multilevel.surface, embedding=K)[0]
            assert _kappa(qp, lambda q: base(q) + c * q, qp.m) > 2.5 * kappa


def test_stabilised_schur_diagonal_and_symmetry():
    """The diagonal the operator reports is its dense matrix's, and the matrix is
    symmetric positive definite with ``C`` added."""
    qp = circle_square.PROBLEM.make(0, coupling="stabilised")
    apply, diag = stabilised_schur_apply(qp)
    dense = np.column_stack([apply(e) for e in np.eye(qp.m)])
    np.testing.assert_allclose(dense, dense.T, rtol=1e-12, atol=1e-14 * np.abs(dense).max())
    np.testing.assert_allclose(np.diag(dense), diag, rtol=1e-12)
    assert np.linalg.eigvalsh(dense + qp.C.toarray()).min() > 0


def test_alg84_on_the_stabilised_problem_takes_the_multilevel_schur():
    """``schur=auto`` keeps the stabilised multilevel S-hat (its kappa(S-hat^-1 S_in) is
    under the stabilised limit) and Alg. 8.4 converges, verified, to the exact solution."""
    qp = circle_square.PROBLEM.make(2, coupling="stabilised")
    res = solve(qp, solver="augmented_projection", tol="mid")
    assert res.status == "converged", res.message
    assert res.stats["schur_kind"] == "multilevel"
    assert res.stats["kappa_SinvSin"] <= ap.SCHUR_KAPPA_LIMIT["stabilised"]
    ref = reference_solve(qp, tol=1e-10)
    e = res.u - ref.u
    assert np.sqrt(e @ (qp.A @ e) / (ref.u @ (qp.A @ ref.u))) < 1e-5


def test_nested_guess_carries_the_reverse_pressure():
    """Alg. 8.5 on the stabilised problem: the reverse rows' pressure is prolongated along
    with the displacement (measured relative errors against the fine solution: u 0.045,
    reverse multipliers 0.46; zero would be 1), nonnegative; mixed couplings refused."""
    coarse = circle_square.PROBLEM.make(1, coupling="stabilised")
    fine = circle_square.PROBLEM.make(2, coupling="stabilised")
    rc, rf = reference_solve(coarse, tol=1e-10), reference_solve(fine, tol=1e-10)
    u0, p0 = ap.nested_initial_guess(coarse, rc, fine)
    mc = fine.m_contact
    assert p0.shape == (fine.m,) and (p0 >= 0).all()
    assert np.linalg.norm(u0 - rf.u) < 0.1 * np.linalg.norm(rf.u)
    assert np.linalg.norm(p0[mc:] - rf.p[mc:]) < 0.6 * np.linalg.norm(rf.p[mc:])
    with pytest.raises(ValueError, match="both levels nodal or both stabilised"):
        ap.nested_initial_guess(circle_square.PROBLEM.make(1), rc, fine)


def test_coupling_parameter():
    """The scenes take ``coupling=stabilised`` (with alpha, penalty) and refuse it with P2."""
    qp = cube_sphere.PROBLEM.make(0, coupling="stabilised", alpha=0.5, penalty=2.0)
    assert qp.stabilisation is not None and qp.stabilisation.alpha == 0.5
    assert circle_square.PROBLEM.make(0).stabilisation is None
    with pytest.raises(ParameterError, match="parameter 'degree'"):
        circle_square.PROBLEM.make(0, coupling="stabilised", degree=2)
    with pytest.raises(ParameterError, match="parameter 'degree'"):
        cube_sphere.PROBLEM.make(0, coupling="two_pass", degree=2)
