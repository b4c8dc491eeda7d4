"""Non-matching Laplace problem (thesis Ch. 6): exactness, rates, definiteness."""
import numpy as np
import pytest

from problems import laplace_nonmatching as lap
from problems.spec import ParameterError
from report.rates import fitted_rate


def test_conforming_reproduces_linear_solution_to_roundoff():
    sol = lap.solve(3, case="linear", variant="conforming")
    assert sol.err_h1 < 1e-11 and sol.err_l2 < 1e-12


@pytest.mark.parametrize("side", ["coarse", "fine"])
def test_mortar_passes_the_patch_test(side):
    # the modified multiplier space holds the constants: no consistency error for linear u
    sol = lap.solve(3, case="linear", variant="mortar", constrained=side)
    assert sol.err_h1 < 1e-11 and sol.err_l2 < 1e-12


def test_mortar_coupling_reproduces_linear_traces():
    y_c, y_o = np.linspace(0, 1, 9), np.linspace(0, 1, 13)
    T_other, T_ends = lap.mortar_coupling(y_c, y_o)
    u = lambda y: 2.0 - 3.0 * y
    np.testing.assert_allclose(T_other @ u(y_o) + T_ends @ u(y_c[[0, -1]]), u(y_c[1:-1]), atol=1e-13)


def test_mortar_rates_are_optimal():
    r1, r0 = _rates("sin10x", "mortar", [2, 3, 4])
    assert r1 >= 0.95 and r0 >= 1.9


@pytest.mark.parametrize("variant", ["nodal", "stabilised_a0.5", "stabilised_a1"])
def test_nonmatching_variants_fail_the_patch_test(variant):
    # nodal constraints are not exact for linear u: the interface's own error
    sol = lap.solve(2, case="linear", variant=variant)
    assert sol.err_h1 > 1e-4


def test_linear_interpolation_of_the_trace_is_exact_for_linear_functions():
    y_from = np.linspace(0, 1, 7)
    y_to = np.linspace(0, 1, 11)[1:-1]
    T = lap.trace_interpolation(y_from, y_to)
    np.testing.assert_allclose(T @ (3 * y_from - 1), 3 * y_to - 1, atol=1e-14)
    np.testing.assert_allclose(T.sum(axis=1).A.ravel(), 1.0, atol=1e-14)


def test_lumped_interface_weights_for_uniform_mesh():
    y = np.linspace(0, 1, 9)  # h = 1/8
    w = lap.lumped_interface_weights(y, alpha=1.0)
    # interior: two half edges of h^(1-2) / 2 each = 1/h; end points half that
    np.testing.assert_allclose(w[1:-1], 8.0)
    np.testing.assert_allclose(w[[0, -1]], 4.0)


def _rates(case, variant, levels, side="coarse"):
    sols = [lap.solve(L, case=case, variant=variant, constrained=side) for L in levels]
    h = np.array([s.h for s in sols])
    return (fitted_rate(h, np.array([s.err_h1 for s in sols])),
            fitted_rate(h, np.array([s.err_l2 for s in sols])))


@pytest.mark.parametrize("case", ["sin10x", "linear"])
def test_stabilised_alpha1_is_optimal(case):
    r1, r0 = _rates(case, "stabilised_a1", [2, 3, 4])
    assert r1 >= 0.95, r1
    assert r0 >= 1.9, r0


def test_nodal_interface_error_is_order_half_in_h1():
    # Theorem 6.17 proves O(h^1/2); in the patch test the whole error is the interface's
    r1, _ = _rates("linear", "nodal", [2, 3, 4])
    assert 0.4 <= r1 <= 0.6, r1


def test_conforming_rates_on_smooth_case():
    r1, r0 = _rates("sin10x", "conforming", [2, 3, 4])
    assert abs(r1 - 1) < 0.05 and abs(r0 - 2) < 0.05


@pytest.mark.parametrize("side", ["coarse", "fine"])
@pytest.mark.parametrize("variant", lap.VARIANTS)
def test_reduced_operator_is_definite(variant, side):
    disc = lap.assemble(1, "sin10x", variant, (2, 3), side)
    K, *_ = lap.reduced_system(disc)
    assert abs(K - K.T).max() < 1e-12
    assert lap.smallest_eigenvalue(K) > 1e-3
    # the stabilisation itself is positive semidefinite
    if disc.penalty.nnz:
        assert np.linalg.eigvalsh(disc.penalty.toarray()).min() > -1e-10


def test_wrong_penalty_sign_is_caught_by_the_definiteness_check():
    # the check above can fail: flipping the sign of (6.18) makes the operator indefinite
    disc = lap.assemble(1, "sin10x", "stabilised_a1", (2, 3), "coarse")
    disc.penalty = -disc.penalty
    K, *_ = lap.reduced_system(disc)
    assert lap.smallest_eigenvalue(K) < 0


def test_elimination_satisfies_the_nodal_constraints():
    disc = lap.assemble(2, "sin10x", "nodal", (2, 3), "coarse")
    P, u0 = lap.elimination(disc)
    w = np.random.default_rng(0).normal(size=P.shape[1])
    u = P @ w + u0
    np.testing.assert_allclose(u[disc.constrained], disc.constraint @ u, atol=1e-13)
    np.testing.assert_allclose(u[disc.dirichlet], disc.dirichlet_values, atol=1e-13)


def test_errors_use_quadrature_not_nodal_values():
    # the nodal interpolant of sin(10x) has zero nodal error but a nonzero L2 error
    mesh = lap.subdomain_mesh(0, 1, 8)
    u = np.sin(10 * mesh.p[0])
    e1, e0 = lap.errors([mesh], [u], "sin10x")
    assert e0 > 1e-3 and e1 > 1e-1


@pytest.mark.parametrize("bad, message", [({"ratio": "3:2"}, "ratio"), ({"ratio": "x"}, "ratio"),
                                          ({"case": "cos"}, "case"), ({"variant": "mortar_dual"}, "variant"),
                                          ({"constrained": "left"}, "constrained")])
def test_bad_parameters_name_the_parameter(bad, message):
    with pytest.raises(ParameterError, match=message):
        lap.PROBLEM.make(1, **bad)


def test_bad_level_names_the_range():
    with pytest.raises(ParameterError, match=r"level.*\[0, 8\]"):
        lap.PROBLEM.make(9)
