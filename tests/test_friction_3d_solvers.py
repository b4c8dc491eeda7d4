"""Friction in 3D: the exact reference of a Tresca step (the dual with a disc per node, by
semismooth Newton on the projection equation: solvers.kernels.tresca.disc_qp_newton) and the
semismooth Newton solver's 3D branch (Hüeber-Stadler-Wohlmuth), on small dual problems
with known optimality conditions and on cube_sphere (mu = 0.5, elastically similar
bodies: E1 = E2 = 1, nu1 = nu2 = 0.3, the scene's defaults)."""
from __future__ import annotations

import functools
from dataclasses import replace

import numpy as np
import pytest

from problems.friction.residuals import friction_residuals, tresca_energy
from problems.kkt import energy_error
from problems.spec import problems
from reference.cattaneo_mindlin import stick_zone_ratio, stick_zone_size
from solvers import semismooth_newton
from solvers.kernels import tresca
from solvers import tresca_exact as tresca_exact_solver
from solvers.interface import run_load_path, solve
from solvers.kernels.tresca import (DISC_EDGE, DISC_INSIDE, DISC_ZERO, TrescaSolution,
                                    box_qp_active_set, disc_qp_newton, friction_path,
                                    path_for_ratio, project_dual, tangential_ratio, with_step)


def _random_dual(seed: int, m: int, k: int):
    """A dual problem of ``m`` nodes with ``k`` tangential rows each: ``S`` symmetric
    positive definite, a third of the bounds zero (nodes out of contact)."""
    rng = np.random.default_rng(seed)
    size = m * (1 + k)
    M = rng.standard_normal((size, size))
    S = M @ M.T / size + 0.05 * np.eye(size)
    bound = 0.5 * np.abs(rng.standard_normal(m))
    bound[: m // 3] = 0.0
    return S, rng.standard_normal(size), bound


def _dual_kkt(S, c, m, bound, y) -> float:
    """The largest violation of the dual problem's optimality conditions, relative to
    ``max(|c|)``: ``p >= 0``, ``grad_p >= 0``, ``p grad_p = 0``; per node ``|lam_i| <=
    s_i`` and, with ``grad = S y - c``, ``grad_i = 0`` inside the disc and
    ``grad_i = -t lam_i`` with ``t >= 0`` on its edge."""
    grad = S @ y - c
    p, gp = y[:m], grad[:m]
    worst = [max(0.0, -p.min()), max(0.0, -gp.min()), np.max(np.abs(p * gp))]
    lam, gl = y[m:].reshape(m, -1), grad[m:].reshape(m, -1)
    size = np.sqrt(np.sum(lam * lam, axis=1))
    worst.append(max(0.0, np.max(size - bound)))
    on_edge = (bound > 0) & (size >= bound * (1 - 1e-9))
    inside = (bound > 0) & ~on_edge
    worst.append(np.max(np.abs(gl[inside]), initial=0.0))
    if on_edge.any():
        n = lam[on_edge] / size[on_edge, None]
        along = np.sum(gl[on_edge] * n, axis=1)               # -t |lam|: must be <= 0
        worst.append(max(0.0, along.max()))
        worst.append(np.max(np.abs(gl[on_edge] - along[:, None] * n)))
    return max(worst) / np.max(np.abs(c))


@pytest.mark.parametrize("seed", range(6))
def test_disc_newton_in_one_dimension_is_the_box_active_set(seed):
    """With one tangential row per node the disc is the box ``[-s_i, s_i]``: the
    semismooth Newton method and the primal active-set method (finite, exact on its
    active sets) agree to 1e-12."""
    m = 20
    S, c, bound = _random_dual(seed, m, 1)
    y, (free, disc), _, ok = disc_qp_newton(S, c, m, bound)
    lo = np.concatenate([np.zeros(m), -bound])
    hi = np.concatenate([np.full(m, np.inf), bound])
    y_box, at, _, ok_box = box_qp_active_set(S, c, lo, hi)
    assert ok and ok_box
    assert np.max(np.abs(y - y_box)) <= 1e-12 * np.max(np.abs(y_box))
    assert np.array_equal(free, at[:m] == 0)
    assert np.array_equal(disc == DISC_INSIDE, (bound > 0) & (at[m:] == 0))


@pytest.mark.parametrize("seed", range(6))
def test_disc_newton_meets_the_optimality_conditions(seed):
    """Two tangential rows per node: the answer meets the dual optimality conditions to
    1e-12 (relative to ``max |c|``), agrees with the projected gradient method run to
    a contraction of e^-40 (an independent method) to 1e-12, has nodes of every kind,
    and a warm start from it ends at once on the same point. Measured: 7-9 Newton
    steps."""
    m = 30
    S, c, bound = _random_dual(seed, m, 2)
    y, (free, disc), iterations, ok = disc_qp_newton(S, c, m, bound)
    assert ok and iterations <= 20
    assert _dual_kkt(S, c, m, bound, y) <= 1e-12
    assert {DISC_ZERO, DISC_EDGE} <= set(disc.tolist()) and not free.all()
    eig = np.linalg.eigvalsh(S)
    x = np.zeros_like(c)                 # projected gradient: contracts by 1 - eig[0]/eig[-1]
    for _ in range(int(40 * eig[-1] / eig[0])):
        x = project_dual(x - (S @ x - c) / eig[-1], m, bound)
    assert np.max(np.abs(y - x)) <= 1e-12 * np.max(np.abs(y))
    y_warm, _, warm_iterations, ok_warm = disc_qp_newton(S, c, m, bound, start=y)
    assert ok_warm and warm_iterations <= 2
    assert np.max(np.abs(y_warm - y)) <= 1e-12 * np.max(np.abs(y))


def test_disc_newton_that_stops_short_says_so():
    m = 30
    S, c, bound = _random_dual(0, m, 2)
    _, _, iterations, ok = disc_qp_newton(S, c, m, bound, max_iter=1)
    assert not ok and iterations == 1


# --- cube_sphere ------------------------------------------------------------------------

SCENE = problems()["cube_sphere"]
TIGHT = 1e-10


def _frictional(level, **kw):
    return SCENE.make(level, **{"friction": "tresca", "mu": 0.5, "shift": 0.01, **kw})


@functools.cache
def _shared(level, law="tresca"):
    """The scene of :func:`_frictional` under ``law``, one object per level and law in
    this module: the tests that only solve it share the exact reference's dense dual and
    semismooth Newton's Schur complement, each formed once per problem and kept in
    ``qp.cache`` (the tests that change a limit or count the cache's work build their
    own). Coulomb's problem is Tresca's with the law changed, as the friction study
    makes it: the same A, B and T, so the same dual and Schur complement."""
    if law == "tresca":
        return _frictional(level)
    tresca_qp = _shared(level)
    return replace(tresca_qp, friction=replace(tresca_qp.friction, law=law))


def _registered_path(qp, solver, **options):
    """The load path through the registry: every Tresca solve verified (the friction KKT
    residuals and the certified Tresca energy bound) at 1e-10."""
    return run_load_path(qp, lambda step, start: solve(step, solver, tol=TIGHT, **options),
                         TIGHT)


@functools.cache
def _exact_path(level, law="tresca"):
    """``tresca_exact``'s load path on :func:`_shared` ``(level, law)``, once per module:
    the ``paths`` fixture and the TNNMG comparison use the same run."""
    return _registered_path(_shared(level, law), "tresca_exact")


@pytest.fixture(scope="module", params=[
    (1, "tresca"), (1, "coulomb"),
    pytest.param((2, "tresca"), marks=pytest.mark.slow),       # ~45 s
    pytest.param((2, "coulomb"), marks=pytest.mark.slow)],     # ~90 s: 15 verified solves
    ids=lambda p: f"{p[1]}-{p[0]}")
def paths(request):
    """Both load paths of one scene: ``tresca_exact`` (Coulomb: its fixed point over
    exact Tresca steps; measured 8 and 6-7 Tresca solves, contraction 0.03-0.05) and
    ``semismooth_newton`` (Coulomb: monolithic)."""
    level, law = request.param
    qp = _shared(level, law)
    options = {"coulomb": "monolithic"} if law == "coulomb" else {}
    return (qp, _exact_path(level, law),
            _registered_path(qp, "semismooth_newton", **options))


def test_both_load_paths_are_verified_with_partial_slip(paths):
    """Every step of both paths verified ``converged``; the tangential step sticks at the
    centre and slips at the rim (measured at level 1: 13 nodes stick, 4 slip; level 2:
    56 and 5)."""
    qp, exact, ssn = paths
    for run in (exact, ssn):
        assert run.result.status == "converged", run.result.message
        assert [r["status"] for r in run.records] == ["converged"] * len(qp.friction.path)
        last = run.steps[-1]
        states = last.qp.friction.states(last.solution.lam, TIGHT)
        assert (states == "stick").sum() >= 5 and (states == "slip").sum() >= 3


def test_the_exact_reference_and_semismooth_newton_agree(paths):
    """Two formulations (the dual's projection equation; the primal-dual active sets) give
    the same answer in every step: 1e-8 in the energy norm and in the relative Tresca
    energy (measured: 7e-13 and below)."""
    qp, exact, ssn = paths
    assert len(exact.steps) == len(ssn.steps) == len(qp.friction.path)
    for a, b in zip(exact.steps, ssn.steps):
        assert energy_error(a.qp, b.solution.u, a.solution.u) <= 1e-8
        energy = tresca_energy(a.qp, a.solution.u)
        assert abs(tresca_energy(a.qp, b.solution.u) - energy) <= 1e-8 * abs(energy)


def _as_solution(step_qp, res) -> TrescaSolution:
    """The friction branch's answer as friction_path's TrescaSolution."""
    fr = step_qp.friction
    return TrescaSolution(u=res.u, p=res.p, lam=res.tangential,
                          stick=fr.states(res.tangential, TIGHT) == "stick",
                          status=res.claimed_status, iterations=res.iterations,
                          kkt=friction_residuals(step_qp, res.u, res.p, res.tangential))


def _ssn(step_qp):
    spec = semismooth_newton.SOLVER
    return _as_solution(step_qp, spec.solve(step_qp, TIGHT, 100, None, None, None,
                                            spec.options()))


def test_mu_zero_reproduces_the_frictionless_pdas():
    """With mu = 0 no node carries a friction force and each step is the frictionless
    problem of its shift: both methods give pdas's u and p to 1e-10."""
    qp = _frictional(1, mu=0.0)
    plain = [SCENE.make(1, shift=shift) for shift in (0.0, 0.01)]
    refs = [solve(q, "pdas", tol=1e-12) for q in plain]
    for method in (None, _ssn):                          # None: the exact reference
        steps = friction_path(qp, solve=method)
        for step, q, ref in zip(steps, plain, refs):
            assert ref.status == "converged" and step.solution.status == "converged"
            assert np.all(step.solution.lam == 0.0)
            assert energy_error(q, step.solution.u, ref.u) <= 1e-10
            assert np.max(np.abs(step.solution.p - ref.p)) <= 1e-10 * np.max(ref.p)


def test_a_huge_mu_sticks_everywhere():
    """mu = 1000: every node in contact sticks (its tangential force strictly inside its
    disc) and its slip is zero to round-off, by both methods."""
    qp = _frictional(1, mu=1e3)
    for method in (None, _ssn):
        steps = friction_path(qp, solve=method)
        fr, sol = steps[-1].qp.friction, steps[-1].solution
        contact = fr.slip_bound > 0
        assert contact.sum() >= 10 and np.array_equal(sol.stick, contact)
        slip = fr.magnitude(fr.slip(sol.u))
        assert np.max(slip[contact]) <= 1e-12 * np.max(np.abs(fr.T @ sol.u))
        assert tangential_ratio(steps) < 0.01


def _stick_zone_deviation(level: int, ratio: float) -> float:
    """``(c/a) / (1 - Q/(mu P))^(1/3) - 1`` of the exact path scaled to ``ratio``; ``a``
    and ``c`` from the moments of ``p`` and of ``s - |lam|``
    (:func:`reference.cattaneo_mindlin.stick_zone_size`)."""
    qp = _shared(level)
    steps = path_for_ratio(qp, ratio)
    assert tangential_ratio(steps) == pytest.approx(ratio, rel=1e-6)
    sol, fr = steps[-1].solution, steps[-1].qp.friction
    assert sol.status == "converged" and sol.kkt.max <= 1e-12
    x = qp.mesh.points[qp.contact.nodes][:, :2]
    a, c = stick_zone_size(x, sol.p, fr.magnitude(sol.lam), fr.slip_bound, kind="point")
    return (c / a) / stick_zone_ratio(ratio, "point") - 1.0


@pytest.mark.parametrize("level", [1, pytest.param(2, marks=pytest.mark.slow)])
@pytest.mark.parametrize("ratio", [0.3, 0.7])
def test_cattaneo_mindlin_stick_radius(level, ratio):
    """The sphere's stick radius c = a (1 - Q/(mu P))^(1/3) (Johnson Sect. 7.2), within
    10 %. Measured deviations at levels 1, 2: -0.8 %, -1.9 % (0.3) and -0.9 %, -6.3 %
    (0.7); at level 3 (beyond the exact reference's dense A^-1 G', by semismooth_newton,
    measured once) -1.1 % and -3.1 %."""
    assert abs(_stick_zone_deviation(level, ratio)) <= 0.10


def test_a_dense_dual_beyond_its_size_is_refused_with_the_reason(monkeypatch):
    """tresca_exact forms A^-1 G' densely (cube_sphere level 3: 391,011 x 3,267 entries,
    10 GB): beyond TRESCA_EXACT_MAX_ENTRIES it is skipped with the reason, and
    dual_operators refuses it naming the limit."""
    qp = _frictional(0)
    assert tresca_exact_solver.supports(qp) == (True, "")
    size = qp.n * 3 * qp.m
    monkeypatch.setattr(tresca_exact_solver, "TRESCA_EXACT_MAX_ENTRIES", size - 1)
    ok, why = tresca_exact_solver.supports(qp)
    assert not ok and "A^-1 G' is dense" in why
    monkeypatch.setattr(tresca, "TRESCA_EXACT_MAX_ENTRIES", size - 1)
    with pytest.raises(ValueError, match="not allowed; allowed: at most"):
        tresca.dual_operators(qp)


@pytest.mark.parametrize("level", [1, pytest.param(2, marks=pytest.mark.slow)])
def test_tnnmg_agrees_with_the_exact_reference(level):
    """The third frictional solver on the same Tresca load path: verified, and within
    1e-8 of tresca_exact in the energy norm and the relative Tresca energy (measured at
    level 1: 1.7e-10 and 4e-16, 13 TNNMG steps per load step)."""
    qp = _shared(level)
    exact, multigrid = _exact_path(level), _registered_path(qp, "tnnmg")
    assert multigrid.result.status == "converged", multigrid.result.message
    for a, b in zip(exact.steps, multigrid.steps, strict=True):
        assert energy_error(a.qp, b.solution.u, a.solution.u) <= 1e-8
        energy = tresca_energy(a.qp, a.solution.u)
        assert abs(tresca_energy(a.qp, b.solution.u) - energy) <= 1e-8 * abs(energy)


def test_the_steps_of_a_load_path_share_one_schur_complement():
    """semismooth_newton forms A's factor and S once per problem: the load path's steps
    (ContactQPs made from it) find it in the shared cache."""
    qp = _frictional(0)
    first = semismooth_newton.contact_schur(qp)
    step = with_step(qp, 1, np.zeros(qp.m), np.zeros(qp.friction.T.shape[0]))
    assert semismooth_newton.contact_schur(step) is first
    assert first.S.shape == (3 * qp.m, 3 * qp.m)


def test_the_displacement_formed_at_the_end_agrees(paths):
    """3D: semismooth Newton with displacement='at_end' (the steps judged on the rows,
    u formed once) on the path's last Tresca step (level 2): verified, within 1e-12 of
    the default's u in the energy norm and 1e-10 of its multipliers; its Newton steps on
    fixed sets stop at round-off as the default's do (within the stall count)."""
    qp, _, ssn = paths
    last = ssn.steps[-1]
    spec = semismooth_newton.SOLVER
    every, end = (spec.solve(last.qp, TIGHT, 100, None, None, None,
                             spec.options(displacement=kind))
                  for kind in ("every_step", "at_end"))
    assert every.claimed_status == end.claimed_status == "converged", end.message
    assert friction_residuals(last.qp, end.u, end.p, end.tangential).max <= TIGHT
    assert energy_error(last.qp, end.u, every.u) <= 1e-12
    scale = max(np.max(np.abs(every.tangential)), np.max(every.p))
    assert np.max(np.abs(end.tangential - every.tangential)) <= 1e-10 * scale
    assert abs(end.iterations - every.iterations) <= semismooth_newton.FRICTION_STALL
