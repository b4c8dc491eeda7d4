"""The stabilised two-sided formulation of Sect. 7.5, (7.10)/(7.11), and its slack form."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

from problems import circle_square, flat_blocks
from problems.fem.adaptive import adaptive_loop, adaptive_start
from problems.fem.estimators import penetrations
from problems.fem.mesh import project_to_circle
from problems.fem.stabilised import effective_modulus, stabilise
from problems.kkt import kkt_residuals
from problems.qp import ContactQP, QPValidationError, surface_multipliers
from problems.slack import slack_form
from solvers.interface import certify, solve
from agreement import within_certificate


@pytest.fixture(scope="module")
def cs1():
    qp = circle_square.PROBLEM.make(1)
    return qp, solve(qp, "pdas", tol=1e-10)


def _energy_diff(qp, u, v):
    e = u - v
    return float(np.sqrt(e @ (qp.A @ e) / (v @ (qp.A @ v))))


def test_reverse_rows_are_the_penetrations_of_fig_7_1(cs1):
    """Each reverse row's value at the nodal solution is minus the penetration that eta_2
    measures (7.9), to first order (the rows are linearised in the reference configuration,
    eta_2 searches the deformed one); C is zero on the nodal rows and h^(2 alpha) / (k m)
    on the others."""
    qp, res = cs1
    sq = stabilise(qp, alpha=1.0, penalty=1.0)
    st = sq.stabilisation
    assert sq.m == qp.m + st.n_rows and sq.m_contact == qp.m
    c = sq.C.diagonal()
    assert np.all(c[:qp.m] == 0) and np.all(c[qp.m:] > 0)
    k = effective_modulus(qp)
    assert k == pytest.approx(qp.hertz.E_star, rel=1e-12)          # same pair, same formula
    np.testing.assert_allclose(c[qp.m:], st.size ** 2 / (st.modulus * st.mass))
    pen = penetrations(qp, qp.full_displacement(res.u))
    slack = (sq.g - sq.B @ res.u)[qp.m:]
    depth = dict(zip(pen.nodes, pen.depth))
    deep = np.array([depth[n] for n in st.nodes])
    np.testing.assert_allclose(np.maximum(-slack, 0.0), deep, rtol=0, atol=0.03 * deep.max())
    assert np.any(slack < 0)                      # the nodal solution lets hanging nodes in
    # the transfer spreads each reverse row onto the constrained facet it hits (weights sum 1)
    np.testing.assert_allclose(np.asarray(st.transfer.sum(axis=1)).ravel(), 1.0)


def test_bad_parameters_are_named():
    qp = flat_blocks.PROBLEM.make(0)
    with pytest.raises(ValueError, match="'alpha'"):
        stabilise(qp, alpha=-1.0)
    with pytest.raises(ValueError, match="'penalty'"):
        stabilise(qp, penalty=0.0)
    with pytest.raises(ValueError, match="'qp'"):
        stabilise(stabilise(qp))
    sq = stabilise(qp)
    with pytest.raises(QPValidationError, match="C > 0"):
        ContactQP(A=sq.A, f=sq.f, B=sq.B, g=sq.g, C=None, stabilisation=sq.stabilisation)


def test_stabilised_operator_is_spd():
    """The penalised primal Hessian ``A + B_r' C_r^-1 B_r`` (every reverse row active) and
    the slack form's matrix are symmetric positive definite."""
    sq = stabilise(flat_blocks.PROBLEM.make(0))
    mc = sq.m_contact
    B_r, c_r = sq.B[mc:], sq.C.diagonal()[mc:]
    H = (sq.A + B_r.T @ sp.diags(1.0 / c_r) @ B_r).toarray()
    np.testing.assert_allclose(H, H.T, rtol=0, atol=1e-12 * np.abs(H).max())
    assert np.linalg.eigvalsh(H).min() > 0
    sf = slack_form(sq)
    sla.cholesky(sf.A.toarray())                   # raises unless SPD
    assert sf.n == sq.n + sq.stabilisation.n_rows and sf.C is None


def test_limits_of_the_penalty(cs1):
    """penalty -> 0: the nodal solution (the reverse rows let everything through);
    penalty -> inf: the two-pass solution with the reverse rows hard."""
    qp, res = cs1
    weak = [_energy_diff(qp, solve(stabilise(qp, 1.0, k), "pdas", tol=1e-10).u, res.u)
            for k in (1e-2, 1e-4, 1e-6)]
    assert weak[0] > 10 * weak[1] > 100 * weak[2] and weak[2] < 1e-6
    sq = stabilise(qp, 1.0, 1.0)
    hard = ContactQP(A=sq.A, f=sq.f, B=sq.B, g=sq.g)              # both surfaces hard
    two_pass = solve(hard, "pdas", tol=1e-10)
    assert two_pass.status == "converged"
    strong = [_energy_diff(qp, solve(stabilise(qp, 1.0, k), "pdas", tol=1e-10).u, two_pass.u)
              for k in (1e2, 1e4, 1e6)]
    assert strong[0] > 10 * strong[1] > 100 * strong[2] and strong[2] < 1e-5
    assert _energy_diff(qp, two_pass.u, res.u) > 1e-3             # the limits differ


@pytest.mark.parametrize("solver", ["augmented_projection", "osqp", "semismooth_newton",
                                    "clarabel"])
def test_native_and_slack_form_solvers_agree(cs1, solver):
    """Alg. 8.4 with C != 0 and the QP solvers through the slack form give PDAS's answer;
    each is verified on the stabilised problem itself."""
    qp, _ = cs1
    sq = stabilise(qp)
    exact = solve(sq, "pdas", tol=1e-10)
    assert exact.status == "converged" and exact.gap.certified
    r = solve(sq, solver, tol=1e-8)
    assert np.shape(r.u) == (sq.n,) and np.shape(r.p) == (sq.m,)
    assert kkt_residuals(sq, r.u, r.p).max == r.kkt.max
    assert _energy_diff(sq, r.u, exact.u) < 1e-5
    if solver != "augmented_projection":
        assert "slack form" in r.message


def test_certificate_bounds_the_energy_error_with_mixed_c(cs1):
    """With hard nodal rows (C = 0) and penalised reverse rows the duality gap still bounds
    the true energy error of a perturbed u, and is tight at the solution."""
    qp, _ = cs1
    sq = stabilise(qp)
    exact = solve(sq, "pdas", tol=1e-10)
    gap = certify(sq, exact.u, exact.p)
    assert gap.certified and gap.relative_energy_bound < 1e-6
    rng = np.random.default_rng(0)
    for scale in (1e-4, 1e-2):
        u = exact.u * (1 + scale * rng.standard_normal(sq.n))
        g = certify(sq, u, exact.p)
        err = _energy_diff(sq, u, exact.u)
        assert g.certified and within_certificate(err, g.relative_energy_bound, g.floor)


def test_surface_multipliers_carry_the_whole_force():
    """Patch test: the constrained surface's force (nodal plus transferred reverse
    multipliers) equals the uniform pressure times the width, and the stabilised pressure
    deviates less from uniform than the nodal one."""
    q = flat_blocks.exact_pressure(flat_blocks.PROBLEM.options())
    dev = {}
    for coupling in ("nodal", "stabilised"):
        qp = flat_blocks.PROBLEM.make(2, coupling=coupling)
        r = solve(qp, "pdas", tol=1e-10)
        force = surface_multipliers(qp, r.p)
        assert force.shape == (qp.m_contact,)
        assert force.sum() == pytest.approx(r.p.sum(), rel=1e-12)
        assert force.sum() == pytest.approx(q, rel=2e-3)
        dev[coupling] = np.abs(force / qp.contact.mass / q - 1).max()
    assert dev["stabilised"] < 0.5 * dev["nodal"]


def test_adaptive_loop_with_the_stabilisation_and_nested_start():
    """The loop solves the stabilised problem on every step, starts each from the previous
    step (the reverse rows' pressure carried too), and the nested start cuts the
    augmented projection's outer steps."""
    opts = circle_square.PROBLEM.options()
    make, meshes = adaptive_start(circle_square.scene(0, opts), 0)
    proj = (None, project_to_circle(np.array([0.5, 1.0 + opts.radius]), opts.radius))
    starts = []

    def solver(qp, u0, p0):
        starts.append((qp, p0))
        return solve(qp, "augmented_projection", tol=1e-8, u0=u0, p0=p0)

    run = adaptive_loop(make, meshes, solver, estimator="eta1", max_steps=2, project=proj,
                        discretise=lambda qp: stabilise(qp, 1.0, 1.0))
    assert all(q.stabilisation is not None for q in run.qps)
    assert all(r.status == "converged" for r in run.results)
    for qp, p0 in starts[1:]:
        assert p0.shape == (qp.m,) and (p0 >= 0).all() and p0[qp.m_contact:].sum() > 0
    assert [r.NC for r in run.records] == [q.m_contact for q in run.qps]
    cold = solve(run.qps[-1], "augmented_projection", tol=1e-8)
    assert run.results[-1].iterations < cold.iterations
