"""The neutral core: ContactQP validation, KKT residuals on hand-built pairs with known
violations, the energy error, and the option machinery (Parameter, ComponentParameter)."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from problems.kkt import energy_error, kkt_residuals
from problems.qp import ContactQP, QPValidationError
from problems.spec import (Component, ComponentParameter, Options, Parameter, ParameterError,
                           resolve_parameters)
from agreement import within_certificate


def tiny_qp(C=None) -> ContactQP:
    """min 1/2 (u1^2 + u2^2) - u1 - u2  s.t.  u1 <= 0.5:  u = (0.5, 1), p = 0.5."""
    return ContactQP(A=sp.eye(2), f=np.array([1.0, 1.0]), B=sp.csr_matrix([[1.0, 0.0]]),
                     g=np.array([0.5]), C=C)


def test_kkt_residuals_vanish_at_the_exact_solution():
    r = kkt_residuals(tiny_qp(), np.array([0.5, 1.0]), np.array([0.5]))
    assert r.max == 0.0 and r.raw == {"stationarity": 0.0, "primal": 0.0, "dual": 0.0,
                                      "complementarity": 0.0}


@pytest.mark.parametrize("u, p, expected", [
    # stationarity: A u + B'p - f = (0.1, 0) against max(|f|, |Au|, |B'p|) = 1
    (np.array([0.6, 1.0]), np.array([0.5]),
     {"stationarity": 0.1, "primal": 0.1 / 0.6, "complementarity": 0.05 / (0.5 * 0.6)}),
    # primal: B u - g = 0.2 > 0 (and stationarity (0.2, 0) / 1.2)
    (np.array([0.7, 1.0]), np.array([0.5]),
     {"stationarity": 0.2 / 1.0, "primal": 0.2 / 0.7, "complementarity": 0.1 / (0.5 * 0.7)}),
    # dual: p = -0.5 < 0; stationarity |0.5 - 0.5 - 1| = 1 / max(1, 0.5, 0.5)
    (np.array([0.5, 1.0]), np.array([-0.5]), {"stationarity": 1.0, "dual": 1.0}),
    # complementarity: inactive constraint (slack 0.5) with p = 0.5
    (np.array([0.0, 1.0]), np.array([0.5]),
     {"stationarity": 0.5, "complementarity": 0.25 / (0.5 * 0.5)}),
])
def test_kkt_residuals_measure_known_violations(u, p, expected):
    r = kkt_residuals(tiny_qp(), u, p)
    got = {"stationarity": r.stationarity, "primal": r.primal, "dual": r.dual,
           "complementarity": r.complementarity}
    for key in got:
        assert got[key] == pytest.approx(expected.get(key, 0.0), abs=1e-15), key


def test_kkt_residuals_with_a_stabilisation_block():
    # B u - C p <= g with C = 0.2: u1 + p = 1 and u1 - 0.2 p = 0.5 give p = 0.5 / 1.2
    qp = tiny_qp(C=sp.csr_matrix([[0.2]]))
    p = 0.5 / 1.2
    r = kkt_residuals(qp, np.array([1 - p, 1.0]), np.array([p]))
    assert r.max < 1e-15
    r0 = kkt_residuals(tiny_qp(), np.array([1 - p, 1.0]), np.array([p]))   # without C: violated
    assert r0.primal == pytest.approx((1 - p - 0.5) / (1 - p))


def test_complementarity_does_not_cancel_between_rows():
    qp = ContactQP(A=sp.eye(2), f=np.zeros(2), B=sp.eye(2), g=np.array([1.0, -1.0]))
    # p * slack = (+1 * 1) and (+1 * -1): a signed sum would be zero
    r = kkt_residuals(qp, np.zeros(2), np.array([1.0, 1.0]))
    assert r.complementarity == pytest.approx(2.0 / (2.0 * 1.0))


def test_energy_error():
    qp = tiny_qp()
    ref = np.array([0.5, 1.0])
    assert energy_error(qp, ref, ref) == 0.0
    assert energy_error(qp, np.array([0.5, 0.0]), ref) == pytest.approx(1 / np.sqrt(1.25))
    assert energy_error(qp, np.array([np.nan, 0.0]), ref) == np.inf


@pytest.mark.parametrize("change, needle", [
    ({"A": sp.csr_matrix([[1.0, 1.0], [0.0, 1.0]])}, "not symmetric"),
    ({"f": np.ones(3)}, "f must have shape"),
    ({"B": sp.csr_matrix([[0.0, 0.0]])}, "empty rows"),
    ({"g": np.array([np.inf])}, "non-finite"),
    ({"C": sp.eye(2)}, "C must have shape"),
])
def test_validation_names_the_field(change, needle):
    data = dict(A=sp.eye(2), f=np.ones(2), B=sp.csr_matrix([[1.0, 0.0]]), g=np.zeros(1))
    with pytest.raises(QPValidationError, match=needle):
        ContactQP(**{**data, **change})


COMPONENT = ComponentParameter("ahat", "gmg", {
    "gmg": (Parameter("sweeps", 1, low=1, kind=int),),
    "sa": (Parameter("sweeps", 1, low=1, kind=int), Parameter("max_coarse", 500, low=10, kind=int)),
})


def test_component_options_resolve_from_python_and_the_command_line():
    decl = (COMPONENT, Parameter("update", "multiplicative", choices=("multiplicative", "additive")))
    opts = resolve_parameters(decl, {}, "solver 'x'")
    assert opts.ahat == Component("gmg", {"sweeps": 1}) and opts.update == "multiplicative"
    opts = resolve_parameters(decl, {"ahat": "sa", "ahat.max_coarse": "50", "update": "additive"},
                              "solver 'x'")
    assert opts.ahat == Component("sa", {"sweeps": 1, "max_coarse": 50})
    assert opts.update == "additive"                 # an option named like a dict method
    assert resolve_parameters(decl, {"ahat": ("sa", {"sweeps": 3})}, "x").ahat["sweeps"] == 3
    assert opts.flat() == {"ahat": "sa", "ahat.sweeps": 1, "ahat.max_coarse": 50,
                           "update": "additive"}
    assert isinstance(opts, Options) and set(opts) == {"ahat", "update"}


@pytest.mark.parametrize("given, needle", [
    ({"ahat": "amg"}, "parameter 'ahat': 'amg' is not allowed; allowed: one of gmg, sa"),
    ({"ahat.max_coarse": "5"}, "has no option 'ahat.max_coarse'"),        # gmg has none
    ({"ahat": "sa", "ahat.max_coarse": "5"}, "'ahat.max_coarse': 5 is out of range"),
    ({"sweeps": 2}, "has no parameter 'sweeps'"),
    ({"update.x": 1}, "has no parameter 'update.x'"),
])
def test_component_errors_name_the_option(given, needle):
    decl = (COMPONENT, Parameter("update", "multiplicative"))
    with pytest.raises(ParameterError, match=needle.replace("(", r"\(").replace(")", r"\)")):
        resolve_parameters(decl, given, "solver 'x'")


def _direct(qp):
    import scipy.sparse.linalg as spla
    lu = spla.splu(qp.A.tocsc())
    return lambda r, guess=None: lu.solve(r)


def test_duality_gap_is_exact_on_known_pairs():
    """tiny QP: u* = (0.5, 1), p* = 0.5, S = B A^-1 B' = 1."""
    from solvers.certificate import duality_gap
    qp, solve_A = tiny_qp(), None
    solve_A = _direct(qp)
    exact = duality_gap(qp, np.array([0.5, 1.0]), np.array([0.5]), solve_A)
    assert abs(exact.gap) < 1e-15 and exact.relative_energy_bound < 1e-7 and exact.meets(1e-9)
    # a wrong multiplier: gap = 1/2 dp' S dp = 0.02, the S-norm error bound is exact
    wrong_p = duality_gap(qp, np.array([0.5, 1.0]), np.array([0.7]), solve_A)
    assert wrong_p.pair_gap * abs(qp.energy(np.array([0.5, 1.0]))) == pytest.approx(0.02)
    # an infeasible u (u1 = 0.6 > 0.5): the correction moves it back, shift = ||du||_A = 0.1
    infeasible = duality_gap(qp, np.array([0.6, 1.0]), np.array([0.5]), solve_A)
    assert infeasible.shift == pytest.approx(0.1) and infeasible.gap == pytest.approx(0.0, abs=1e-15)
    assert infeasible.energy_bound == pytest.approx(0.1)        # = ||u - u*||_A exactly
    assert not infeasible.meets(1e-3)


def test_certified_bound_holds_for_perturbed_solutions():
    """On a random two-body QP, perturbed (u, p) pairs: the bound always exceeds the error."""
    from solvers.certificate import duality_gap
    from solvers.interface import solve
    rng = np.random.default_rng(5)
    n1, n2, m = 30, 40, 12
    M1, M2 = (sp.random(k, k, density=0.15, random_state=rng) for k in (n1, n2))
    A = sp.block_diag([M1 @ M1.T + sp.eye(n1), M2 @ M2.T + sp.eye(n2)], format="csr")
    B = np.zeros((m, n1 + n2))
    for i in range(m):
        B[i, i] = 1.0
        B[i, n1 + rng.choice(n2, 2, replace=False)] = -0.5
    f = rng.normal(size=n1 + n2)
    qp = ContactQP(A=A, f=f, B=sp.csr_matrix(B), g=np.full(m, -0.1))
    ref = solve(qp, "pdas", tol=1e-12)
    assert ref.status == "converged" and (ref.p > 0).sum() > 2
    solve_A = _direct(qp)
    for scale in (1e-8, 1e-5, 1e-2):
        for _ in range(5):
            u = ref.u + scale * rng.normal(size=qp.n)
            p = np.maximum(ref.p + scale * rng.normal(size=m), 0)
            b = duality_gap(qp, u, p, solve_A)
            assert b.certified
            assert within_certificate(energy_error(qp, u, ref.u), b.relative_energy_bound,
                                      b.floor)
