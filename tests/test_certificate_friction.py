"""The certificate of a Tresca step (:func:`solvers.certificate.duality_gap` with the
tangential multipliers): the stick pairs (zero slip on the stick nodes, tight on the
active rows, :func:`solvers.certificate.stick_point`) make the bound of an answer with a
small residual slip of the size of its true error where the other pairs are orders of
magnitude above it; the bound stays above the true error; frictionless problems never
try them."""
from __future__ import annotations

import functools

import numpy as np
import pytest
import scipy.sparse as sp

from problems.kkt import energy_error
from problems.spec import problems
from solvers import certificate
from solvers.certificate import duality_gap, linear_solver
from solvers.kernels.tresca import dual_operators, friction_path
from agreement import within_certificate

#: the tangential step of each scene at level 0, with nodes that stick and nodes that slip
SHIFT = {"circle_square": 0.03, "cube_sphere": 0.05}
#: the steps tested: each scene's, and cube_sphere's with the octagon law (its slipping
#: nodes' multipliers on facets and at vertices)
STEPS = [("circle_square", 0), ("cube_sphere", 0), ("cube_sphere", 8)]


@functools.lru_cache(maxsize=None)
def _step(scene, facets=0):
    """``(step_qp, solution)``: the last Tresca step of the scene's exact load path
    (``facets``: the faceted law's ``k``, 0 isotropic)."""
    extra = {"friction_facets": facets} if facets else {}
    qp = problems()[scene].make(0, friction="tresca", mu=0.5, shift=SHIFT[scene], **extra)
    last = friction_path(qp)[-1]
    assert 0 < last.solution.stick.sum() < (last.qp.friction.slip_bound > 0).sum()
    last.qp.cache.dual_operators.clear()        # the verification as a library's row sees it
    return last.qp, last.solution


@pytest.fixture(scope="module", params=STEPS, ids=[f"{s}-k{k}" for s, k in STEPS])
def step(request):
    return _step(*request.param)


def _without_stick_pairs(monkeypatch):
    monkeypatch.setattr(certificate, "stick_point",
                        lambda *args: None)


def _residual_slip(qp, sol, size):
    """``u*`` plus a correction that slips the stick nodes by ``size`` times the largest
    slip: ``A^{-1} T_s' w`` (an answer's typical error there), with its energy error."""
    fr = qp.friction
    k = fr.components
    rows = (np.flatnonzero(sol.stick)[:, None] * k + np.arange(k)).ravel()
    w = np.zeros(fr.T.shape[0])
    w[rows] = np.random.default_rng(1).standard_normal(rows.size)
    d = linear_solver(qp)(fr.T.T @ w)
    slip = fr.magnitude(fr.slip(sol.u)).max()
    d *= size * slip / np.abs(fr.T @ d)[rows].max()
    return sol.u + d


def test_a_residual_slip_at_the_stick_nodes_gets_a_bound_of_its_true_error(step, monkeypatch):
    """An exact answer with a residual slip (1e-4 of the largest slip) at its stick nodes:
    the other pairs' bound is >= 100 times its true energy error (the friction term is
    linear in the slip), the stick pairs' within 10 times, and above it."""
    qp, sol = step
    u = _residual_slip(qp, sol, 1e-4)
    err = energy_error(qp, u, sol.u)
    solve_A = linear_solver(qp)
    new = duality_gap(qp, u, sol.p, solve_A, lam=sol.lam)
    with monkeypatch.context() as m:
        _without_stick_pairs(m)
        old = duality_gap(qp, u, sol.p, solve_A, lam=sol.lam)
    assert err > 10 * new.floor                          # a measurable error
    assert old.relative_energy_bound >= 100 * err, (old.relative_energy_bound, err)
    assert within_certificate(err, new.relative_energy_bound, new.floor)
    assert new.relative_energy_bound <= 10 * err, (new.relative_energy_bound, err)


def test_errors_at_the_slipping_nodes_get_a_bound_of_their_true_error(step, monkeypatch):
    """An exact answer moved at its slipping nodes (1e-4 of the largest slip) with its
    tangential multipliers off their bounds (1e-4 of the largest): the other pairs pay
    the multipliers' distance to the bound times the slip (linear), the stick pairs with
    the aligned multipliers only its square: within 10 times the true error, and at least
    10 times sharper than the others."""
    qp, sol = step
    fr = qp.friction
    k = fr.components
    slipping = (fr.slip_bound > 0) & ~sol.stick
    rows = (np.flatnonzero(slipping)[:, None] * k + np.arange(k)).ravel()
    rng = np.random.default_rng(2)
    w = np.zeros(fr.T.shape[0])
    w[rows] = rng.standard_normal(rows.size)
    d = linear_solver(qp)(fr.T.T @ w)
    u = sol.u + d * 1e-4 * fr.magnitude(fr.slip(sol.u)).max() / np.abs(fr.T @ d)[rows].max()
    lam = sol.lam + 1e-4 * np.abs(sol.lam).max() * rng.standard_normal(sol.lam.shape)
    err = energy_error(qp, u, sol.u)
    solve_A = linear_solver(qp)
    new = duality_gap(qp, u, sol.p, solve_A, lam=lam)
    with monkeypatch.context() as m:
        _without_stick_pairs(m)
        old = duality_gap(qp, u, sol.p, solve_A, lam=lam)
    assert err > 10 * new.floor
    assert within_certificate(err, new.relative_energy_bound, new.floor)
    assert new.relative_energy_bound <= 10 * err, (new.relative_energy_bound, err)
    assert old.relative_energy_bound >= 10 * new.relative_energy_bound


def test_a_faceted_slip_on_a_facet_gets_the_facets_multiplier():
    """The octagon law's exact answer: of its two slipping nodes one slips along a
    facet's normal (its multiplier inside the facet) and one at a vertex;
    :func:`solvers.certificate.facet_slips` finds the facet node alone and the aligned
    multipliers are the exact ones (to round-off), in the octagons."""
    qp, sol = _step("cube_sphere", 8)
    fr = qp.friction
    s, slip = fr.slip_bound, fr.slip(sol.u)
    lam_t = fr.clip(sol.lam)
    stick = certificate.stick_nodes(fr, sol.u, lam_t)
    assert np.array_equal(stick, sol.stick)
    facets = certificate.facet_slips(fr, slip, stick)
    on = np.any(facets != 0, axis=1)
    slipping = (s > 0) & ~stick
    assert 0 < on.sum() < slipping.sum() and not np.any(on & ~slipping)
    aligned = certificate.aligned_multipliers(fr, lam_t, slip, stick, facets)
    assert np.abs(aligned - sol.lam).max() <= 1e-12 * s.max()
    assert np.all(fr.gauge(aligned) <= s * (1 + 1e-12))


def test_the_active_rows_by_complementarity_ignore_an_interior_point_tail(step):
    """An interior point's multipliers ``p* + mu / slack`` on the inactive rows (``mu``
    with the largest tail entry 1e-3 of the largest ``p``): a threshold of 1e-4 of the
    largest ``p`` takes rows that are not in contact, the comparison with the slack
    (:func:`solvers.certificate.complementary_active`) the exact active rows."""
    qp, sol = step
    slack = qp.g - qp.B @ sol.u
    exact = sol.p > 0
    assert np.all(slack[~exact] > 0)
    tail = np.where(exact, 0.0, 1.0 / np.where(exact, 1.0, slack))
    p = sol.p + 1e-3 * sol.p.max() * tail / tail.max()
    assert not np.array_equal(p > 1e-4 * p.max(), exact)
    assert np.array_equal(certificate.complementary_active(qp, sol.u, p), exact)


def _held(qp, sol):
    """``(u, active, stick, facets)``: the answer with a residual slip of 1e-4 and what the
    stick point holds of it (:func:`certificate.stick_point`'s arguments)."""
    fr = qp.friction
    u = _residual_slip(qp, sol, 1e-4)
    stick = certificate.stick_nodes(fr, u, fr.clip(sol.lam))
    return (u, certificate.complementary_active(qp, u, sol.p), stick,
            certificate.facet_slips(fr, fr.slip(u), stick))


def test_the_stick_point_from_the_cached_dual_operators_is_the_one_it_forms(step):
    """The stick point from the exact route's cached ``A^{-1} [B; T]'`` and ``S``
    (:func:`solvers.kernels.tresca.dual_operators`) is the one formed with the verification's
    factor of ``A``, to round-off; it has zero slip at the stick nodes and is tight on
    the active rows."""
    qp, sol = step
    fr = qp.friction
    u, active, stick, facets = _held(qp, sol)
    args = (qp, u, active, stick, facets, linear_solver(qp))
    assert not qp.cache.dual_operators
    formed = certificate.stick_point(*args)
    dual_operators(qp)
    try:
        cached = certificate.stick_point(*args)
    finally:
        qp.cache.dual_operators.clear()
    scale = np.abs(sol.u).max()
    assert np.abs(cached - formed).max() <= 1e-10 * scale
    slip = fr.magnitude(fr.slip(formed))
    assert slip[stick].max() <= 1e-12 * slip.max()
    assert np.abs((qp.B @ formed - qp.g)[active]).max() <= 1e-12 * np.abs(qp.g).max()


def test_the_held_rows_of_the_cached_operators_are_read_bit_for_bit(step):
    """The stick point's columns of ``A^{-1} [B; T]'`` (:func:`certificate.times_transpose`,
    which reads only the held rows' columns) are ``(R @ W.T).T`` bit for bit: the held
    rows of each step (a faceted step's rows with a weight per tangential unknown among
    them), and a row with several entries in an unsorted order."""
    qp, sol = step
    u, active, stick, facets = _held(qp, sol)
    R = certificate.held_rows(qp, active, stick, facets)
    try:
        W = dual_operators(qp).W
    finally:
        qp.cache.dual_operators.clear()
    assert 0 < np.unique(R.indices).size < W.shape[1]
    assert np.array_equal(certificate.times_transpose(W, R), (R @ W.T).T)
    mixed = sp.csr_matrix((np.array([0.3, -1.7, 2.1, 1.0]), np.array([5, 1, 3, 0]),
                           np.array([0, 3, 3, 4])), shape=(3, W.shape[1]))
    assert np.array_equal(certificate.times_transpose(W, mixed), (mixed @ W.T).T)


def test_the_bound_stays_above_the_true_error(step):
    """Random perturbations of the exact answer (of ``u`` at several sizes, of the
    multipliers, of the slip at the stick nodes): the certified relative bound is never
    below the true energy error (up to the bound's floor)."""
    qp, sol = step
    fr = qp.friction
    rng = np.random.default_rng(7)
    solve_A = linear_solver(qp)
    scale = np.abs(sol.u).max()
    for size in (1e-2, 1e-4, 1e-6, 1e-8):
        for _ in range(3):
            u = sol.u + size * scale * rng.standard_normal(qp.n)
            u = _residual_slip(qp, sol, size) + (u - sol.u) * rng.uniform()
            p = sol.p * (1 + size * rng.standard_normal(qp.m))
            lam = fr.clip(sol.lam + size * np.abs(sol.lam).max()
                          * rng.standard_normal(sol.lam.shape))
            gap = duality_gap(qp, u, p, solve_A, lam=lam)
            err = energy_error(qp, u, sol.u)
            assert gap.certified
            assert within_certificate(err, gap.relative_energy_bound, gap.floor), (size, err, gap)


def test_frictionless_certificates_never_try_the_stick_pairs(monkeypatch):
    """Without friction (a frictionless problem; a frictional one with ``lam`` None) the
    stick pairs are never formed and every number of the certificate is as before."""
    qp_free = problems()["circle_square"].make(0)
    step_qp, sol = _step("circle_square")
    rng = np.random.default_rng(3)
    cases = []
    for qp, u, p in ((qp_free, None, None), (step_qp, sol.u, sol.p)):
        if u is None:
            from solvers.kernels.tresca import tresca_exact
            exact = tresca_exact(qp)
            u, p = exact.u, exact.p
        cases.append((qp, u + 1e-6 * np.abs(u).max() * rng.standard_normal(qp.n), p))
    before = [duality_gap(qp, u, p, linear_solver(qp)) for qp, u, p in cases]

    def refuse(*args):
        raise AssertionError("stick pairs tried without friction")
    monkeypatch.setattr(certificate, "stick_point", refuse)
    for (qp, u, p), b in zip(cases, before):
        a = duality_gap(qp, u, p, linear_solver(qp))
        assert a == b                                 # bitwise, every field
