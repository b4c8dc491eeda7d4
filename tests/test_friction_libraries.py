"""The general QP and conic libraries on friction: one Tresca step as a QP (2D, the slip
split into two nonnegative parts) or as a second-order cone program (3D, isotropic; and
2D), the map of the libraries' multipliers back to ``(p, lam)``, the rescaling of the
frictional step, and every library's row on circle_square and cube_sphere level 0
(mu = 0.5; the tangential step, with sticking and slipping nodes) against the exact
reference ``tresca_exact``."""
from __future__ import annotations

import functools

import numpy as np
import pytest
import scipy.sparse as sp

from problems.friction.forms import (cone_program, contact_program, epigraph_program, lift,
                                     program_multipliers, split_program, step_multipliers,
                                     tresca_step)
from problems.friction.data import Friction
from problems.friction.residuals import tresca_energy
from problems.kkt import energy_error
from problems.qp import ContactQP
from problems.spec import problems
from solvers.kernels.scaling import scale_qp
from solvers.base import TOLERANCES
from solvers.kernels.cholesky import cholesky_factor
from solvers.interface import run_load_path, solve, solvers
from solvers.qp_libraries import LIBRARIES, clarabel_call
from solvers.kernels.tresca import friction_path, warm_start
from workflows.cli import main
from workflows.io import read_json
from agreement import within_certificate

#: the tangential step of each scene at level 0, with nodes that stick and nodes that slip
#: (measured: circle_square 1 of 3 bounded nodes sticks, cube_sphere 3 of 5)
SHIFT = {"circle_square": 0.03, "cube_sphere": 0.05}

#: the libraries with second-order cones (their own cone APIs) and the QP-only ones
CONIC = sorted(lib.name for lib in LIBRARIES if lib.cone_call is not None)
QP_ONLY = sorted(lib.name for lib in LIBRARIES if lib.cone_call is None)


@functools.lru_cache(maxsize=None)
def _exact(scene):
    """``(step_qp, solution)``: the tangential Tresca step of the scene's exact load path
    and its exact answer (:func:`solvers.kernels.tresca.tresca_exact`)."""
    qp = problems()[scene].make(0, friction="tresca", mu=0.5, shift=SHIFT[scene])
    last = friction_path(qp)[-1]
    fr = last.qp.friction
    stick = last.solution.stick.sum()
    assert 0 < stick < (fr.slip_bound > 0).sum() < qp.m       # stick, slip, and no contact
    return last.qp, last.solution


@pytest.fixture(scope="module", params=sorted(SHIFT))
def exact_step(request):
    """:func:`_exact` of each scene."""
    return _exact(request.param)


def _programs(step):
    return [split_program(step), cone_program(step)] if step.components == 1 else \
        [cone_program(step)]


def _form_residuals(step, program, u, p, lam):
    """At ``x = lift(u)`` and ``y = program_multipliers(p, lam)``: the stationarity
    ``Px + q + G'y``, the slack ``z = h - Gx`` and ``y`` of the friction rows per node."""
    x = lift(step, program, u)
    y = program_multipliers(step, program, p, lam)
    return x, y, program.P @ x + program.q + program.G.T @ y, program.h - program.G @ x


def test_the_forms_objective_is_the_tresca_energy(exact_step):
    """At ``(u, |T u - r|)`` every form's objective is the step's Tresca energy (the nodes
    without a bound have no ``t``), to round-off, at the exact answer and off it."""
    qp, sol = exact_step
    step = tresca_step(qp)
    off = sol.u * (1 + 1e-3 * np.random.default_rng(0).standard_normal(qp.n))
    for program in _programs(step):
        for u in (sol.u, off):
            x = lift(step, program, u)
            value = 0.5 * x @ (program.P @ x) + program.q @ x
            assert abs(value - tresca_energy(qp, u)) <= 1e-13 * abs(tresca_energy(qp, u))


def test_the_forms_kkt_mapped_back_is_the_suites(exact_step):
    """The form's KKT conditions at ``(lift(u), y(p, lam))`` are the suite's: its
    stationarity in ``u`` is ``A u + B'p + T'lam - f`` and in ``t`` zero, its slack on the
    normal rows ``g - B u``, its complementarity on a node's friction rows
    ``s_i |slip_i| - lam_i . slip_i``, its dual cone ``|lam_i| <= s_i`` -- at any point
    (here a random one), all to round-off; and ``y`` maps back to ``(p, lam)``."""
    qp, sol = exact_step
    fr, step, n, m = qp.friction, tresca_step(qp), qp.n, qp.m
    rng = np.random.default_rng(1)
    u = sol.u + 1e-3 * np.abs(sol.u).max() * rng.standard_normal(n)
    p = np.abs(rng.standard_normal(m))
    lam = fr.clip(fr.slip_bound.repeat(fr.components) * rng.standard_normal(fr.T.shape[0]))
    slip = fr.slip(u)
    for program in _programs(step):
        x, y, stationarity, z = _form_residuals(step, program, u, p, lam)
        suite = qp.A @ u + qp.B.T @ p + fr.T.T @ lam - qp.f
        scale = np.abs(qp.f).max() + np.abs(qp.A @ u).max()
        assert np.abs(stationarity[:n] - suite).max() <= 1e-13 * scale, program.kind
        assert np.abs(stationarity[n:]).max() <= 1e-15 * fr.slip_bound.max(), program.kind
        np.testing.assert_array_equal(z[:m], qp.g - qp.B @ u)
        b = program.bounded
        products = z[m:] * y[m:]                     # split: rows T_b, then -T_b
        per_node = (products.reshape(2, b.size).sum(axis=0) if program.kind == "split"
                    else products.reshape(b.size, -1).sum(axis=1))
        target = (fr.slip_bound * fr.magnitude(slip) - fr.inner(lam, slip))[b]
        assert np.abs(per_node - target).max() <= 1e-14 * np.abs(slip).max() * \
            fr.slip_bound.max(), program.kind
        if program.kind == "split":                     # a, b >= 0, the cone of the QP
            assert y[m:].min() >= -1e-16 * fr.slip_bound.max()
            assert z[m:].min() >= -1e-15 * np.abs(slip).max()       # t = |slip| exactly
        else:                                           # both on their second-order cones
            cones_y, cones_z = y[m:].reshape(b.size, -1), z[m:].reshape(b.size, -1)
            for c in (cones_y, cones_z):
                assert np.all(np.linalg.norm(c[:, 1:], axis=1) <= c[:, 0] * (1 + 1e-15))
        p_back, lam_back = step_multipliers(step, program, y)
        np.testing.assert_array_equal(p_back, p)
        np.testing.assert_allclose(lam_back, lam, rtol=0, atol=1e-16 * fr.slip_bound.max())


def test_at_the_exact_answer_the_forms_kkt_hold(exact_step):
    """The exact answer lifted is a KKT point of every form: stationarity, primal and dual
    cones, and complementarity to round-off (relative)."""
    qp, sol = exact_step
    step, m = tresca_step(qp), qp.m
    for program in _programs(step):
        x, y, stationarity, z = _form_residuals(step, program, sol.u, sol.p, sol.lam)
        scale = np.abs(qp.f).max() + np.abs(qp.A @ sol.u).max()
        assert np.abs(stationarity).max() <= 1e-12 * scale, program.kind
        assert z[:m].min() >= -1e-13 * np.abs(qp.g).max()
        assert abs(z @ y) <= 1e-12 * np.abs(y).max() * np.abs(z).max() * len(z), program.kind


def test_the_epigraph_form_is_the_form(exact_step):
    """ECOS's form (:func:`epigraph_program`, ``F`` from the sparse Cholesky factor of
    ``A``): at ``x`` (off the answer) and ``w_j = 1/2 (F_j x)^2`` its linear objective is
    the form's objective, its rows' slack the form's, each epigraph cone's slack on the
    cone's boundary; with the form's multipliers and ``y_j = (z_j[0], -z_j[1:])`` its
    stationarity is the form's, and zero in ``w`` -- to round-off, for the frictionless
    form and every Tresca form. ``F`` of the wrong width is refused."""
    qp, sol = exact_step
    step = tresca_step(qp)
    rng = np.random.default_rng(2)
    u = sol.u * (1 + 1e-3 * rng.standard_normal(qp.n))
    for program in (contact_program(step), *_programs(step)):
        n, N, rows = program.n, len(program.q), len(program.h)
        F = sp.hstack([cholesky_factor(program.P[:n, :n]), sp.csr_matrix((n, N - n))],
                      format="csr")
        lifted = epigraph_program(program, F)
        assert lifted.nonnegative == program.nonnegative
        assert lifted.cones == (*program.cones, *(3,) * n) and lifted.P.nnz == 0
        x = lift(step, program, u)
        X = np.concatenate([x, 0.5 * (F @ x) ** 2])
        objective = 0.5 * x @ (program.P @ x) + program.q @ x
        assert abs(lifted.q @ X - objective) <= 1e-12 * abs(objective), program.kind
        z = lifted.h - lifted.G @ X
        slack = program.h - program.G @ x
        assert np.abs(z[:rows] - slack).max() <= 1e-15 * np.abs(slack).max(), program.kind
        cones = z[rows:].reshape(n, 3)
        boundary = cones[:, 0] ** 2 - cones[:, 1] ** 2 - cones[:, 2] ** 2
        assert np.abs(boundary).max() <= 1e-13 * (cones[:, 0] ** 2).max(), program.kind
        lam = None if program.kind == "contact" else sol.lam
        y = program_multipliers(step, program, sol.p, lam)
        Y = np.concatenate([y, (cones * [1.0, -1.0, -1.0]).ravel()])
        stationarity = lifted.q + lifted.G.T @ Y
        form = program.P @ x + program.q + program.G.T @ y
        scale = np.abs(program.q).max() + np.abs(program.P @ x).max()
        assert np.abs(stationarity[:N] - form).max() <= 1e-12 * scale, program.kind
        assert np.abs(stationarity[N:]).max() <= 1e-14, program.kind
    with pytest.raises(ValueError, match=f"F has {qp.n} columns; allowed: {len(program.q)}"):
        epigraph_program(program, F[:, :n])


#: ECOS's stationarity through the epigraph cones goes with the square root of its gap: at
#: the plain presets the suite refutes it on ``kkt_stationarity`` (at ``high`` too, the
#: every-library test above); with the library's tolerances at ``1e-4 tol`` it is verified
#: at ``low`` with a margin of 50 on every check (measured: KKT <= 7.9e-6, certified bound
#: <= 2.0e-5 on these problems)
ECOS_FACTOR = 1e-4


@pytest.mark.parametrize("scene", sorted(SHIFT))
def test_ecos_is_verified_on_every_form(scene):
    """ECOS, the quadratic term as an epigraph cone, on the frictionless level 0 and on its
    Tresca step (2D split, 3D cone) at ``low`` with ``tol_factor`` 1e-4: verified
    ``converged`` (the KKT residuals and the certified energy bound within 1e-3, checked by
    the suite, not by ECOS), within 1e-3 of the exact answer in the energy norm, and its
    energy within 1e-3 of Clarabel's (relative)."""
    tol = TOLERANCES["low"]
    frictionless = problems()[scene].make(0)
    exact = solve(frictionless, "pdas", tol="high")
    step_qp, step_exact = _exact(scene)
    for qp, ref in ((frictionless, exact), (step_qp, step_exact)):
        res = solve(qp, "ecos", tol="low", tol_factor=ECOS_FACTOR)
        assert res.status == "converged", (res.message, res.failed_check)
        assert res.iterations > 0 and res.message == "ecos: Optimal solution found"
        assert res.kkt.max <= tol and energy_error(qp, res.u, ref.u) <= tol
        other = solve(qp, "clarabel", tol="mid")     # (no friction: J = 1/2 u'Au - f'u)
        J, J_other = tresca_energy(qp, res.u), tresca_energy(qp, other.u)
        assert abs(J - J_other) <= tol * abs(J_other), scene
    assert res.stats["form"] == ("split" if scene == "circle_square" else "cone")


def test_ecos_presets_and_its_answer_to_a_guess():
    """The preset table (``Library.describe``) lists ECOS's three tolerances at ``tol``;
    ECOS takes no initial guess, and a run given one says so."""
    presets = solvers()["ecos"].presets
    for preset, tol in TOLERANCES.items():
        assert presets[preset] == (f"feastol={tol:g}, abstol={tol:g}, reltol={tol:g}; "
                                   "scale=true, tol_factor=1")
    qp = _small_tresca_step()
    res = solve(qp, "ecos", tol="mid", u0=np.zeros(qp.n))
    assert res.claimed_status == "converged"
    assert res.message.endswith("; initial guess not used by the library")


def test_the_split_form_is_for_one_tangential_row_per_node(exact_step):
    qp, _ = exact_step
    step = tresca_step(qp)
    if step.components == 1:
        cones = cone_program(step)
        assert split_program(step).cones == () and cones.cones == (2,) * len(cones.bounded)
    else:
        with pytest.raises(ValueError, match="2 tangential rows per node; allowed: 1"):
            split_program(step)


def test_the_rescaled_step_is_the_step(exact_step):
    """The rescaled Tresca step (:mod:`solvers.kernels.scaling`) has the exact answer mapped into
    it, ``u~ = u / (sigma d)``, ``p~ = p / (sigma r)``, ``lam~ = lam / (sigma rho)``: the
    stationarity residual is the original's times ``D / sigma``, ``|lam~_i| <= s~_i``
    exactly where ``|lam_i| <= s_i`` (the ratio is unchanged), the slip is ``rho slip /
    sigma`` and the energy ``J / sigma^2``; ``lam`` maps back."""
    qp, sol = exact_step
    fr, data = qp.friction, scale_qp(qp)
    step = data.step()
    k = fr.components
    rho = np.repeat(data.rho, k)
    u_s, p_s = sol.u / (data.sigma * data.d), sol.p / (data.sigma * data.r)
    lam_s = sol.lam / (data.sigma * rho)
    residual = data.A @ u_s + data.B.T @ p_s + step.T.T @ lam_s - data.f
    original = qp.A @ sol.u + qp.B.T @ sol.p + fr.T.T @ sol.lam - qp.f
    scale = np.abs(data.f).max() + np.abs(data.A @ u_s).max()
    assert np.abs(residual - data.d * original / data.sigma).max() <= 1e-13 * scale
    size = lambda v: np.linalg.norm(np.reshape(v, (-1, k)), axis=1)
    bounded = fr.slip_bound > 0
    np.testing.assert_allclose(size(lam_s)[bounded] / step.s[bounded],
                               size(sol.lam)[bounded] / fr.slip_bound[bounded], rtol=1e-14)
    np.testing.assert_allclose(step.T @ u_s - step.r, rho * fr.slip(sol.u) / data.sigma,
                               rtol=0, atol=1e-13 * np.abs(step.r).max())
    program = cone_program(step)
    x = lift(step, program, u_s)
    scaled_energy = 0.5 * x @ (program.P @ x) + program.q @ x
    assert abs(scaled_energy * data.sigma ** 2 - tresca_energy(qp, sol.u)) <= \
        1e-12 * abs(tresca_energy(qp, sol.u))
    np.testing.assert_allclose(data.unscale_tangential(lam_s), sol.lam, rtol=1e-15, atol=0)


#: the bars of a library's answer at ``high`` (tol 1e-9), against the exact answer: the
#: libraries stop on their own gap and residual tests at tol, so the Tresca energy is
#: within ~tol of the least (bar 10 tol; measured <= 4e-11), and the energy-norm error,
#: which the energy gap bounds by its square root (J(u) - J* >= 1/2 ||u - u*||_A^2), within
#: sqrt(tol) (measured <= 1e-6: Clarabel on the circle_square step; the ADMM libraries
#: with polishing or many iterations ~1e-12)
ENERGY_BAR, NORM_BAR = 1e-8, np.sqrt(1e-9)


def _check_answer(qp, sol, res):
    """The honest row of a library: it claims converged (every one does on these steps),
    its answer is within the bars, and the suite's verdict is consistent -- verified
    ``converged`` with the true error under the certified bound, or ``inaccurate`` naming
    the checks that refuted it; either way the certified bound holds against the exact
    answer (weak duality)."""
    assert res.claimed_status == "converged", (res.solver, res.message)
    err = energy_error(qp, res.u, sol.u)
    J = tresca_energy(qp, sol.u)
    assert abs(tresca_energy(qp, res.u) - J) <= ENERGY_BAR * abs(J), res.solver
    assert err <= NORM_BAR, (res.solver, err)
    assert res.stats["form"] == ("split" if qp.friction.components == 1 else "cone")
    # err is relative: against the relative bound (the absolute one is ||u*||_A times it)
    assert res.gap.certified and within_certificate(err, res.gap.certified_bound, res.gap.floor)
    if res.status == "converged":
        assert res.failed_check == "" and res.kkt.max <= res.tol
    else:
        assert res.status == "inaccurate" and res.failed_check, res.solver
        assert not res.failed_check.startswith(("contract", "no_answer", "exception"))
    return err


def test_every_library_takes_a_2d_tresca_step_or_says_why(exact_step):
    """2D (circle_square): every library takes the step as a QP (HiGHS beyond its size
    limit is skipped with that reason); 3D (cube_sphere): Clarabel, SCS and ECOS take the
    cone program, the QP-only libraries are skipped with the reason."""
    qp, sol = exact_step
    errors = {}
    for lib in LIBRARIES:
        spec = solvers()[lib.name]
        assert spec.handles_friction
        res = solve(qp, lib.name, tol="high")
        if qp.dim == 3 and lib.cone_call is None:
            assert res.status == "skipped" and "no second-order cones" in res.message
            continue
        limit = spec.size_limit_name(qp.dim)
        if limit and qp.n > spec.options()[limit]:
            assert res.status == "skipped" and limit in res.message
            continue
        errors[lib.name] = _check_answer(qp, sol, res)
    if qp.dim == 2:
        assert set(errors) == set(QP_ONLY + CONIC) - {"highs"}
        # OSQP's polishing solves the KKT system of its final active sets: the exact answer
        assert errors["osqp"] <= 1e-12
        assert solve(qp, "osqp", tol="high").status == "converged"
    else:
        assert set(errors) == set(CONIC) == {"clarabel", "ecos", "scs"}


def _small_tresca_step(seed: int = 3) -> ContactQP:
    """A 2D Tresca step of 12 unknowns and 4 rows (one without a slip bound), small
    enough for HiGHS, whose dense null-space factor skips the scenes. Node ``i`` has the
    unknowns ``3i .. 3i+2``: its normal row ``(1, 0.2, 0)``, its tangential row
    ``(0, 1, -0.3)`` (contact-like: each row has an unknown of its own)."""
    rng = np.random.default_rng(seed)
    n, m = 12, 4
    M = rng.standard_normal((n, n))
    cols = 3 * np.arange(m)[:, None] + np.arange(3)
    row = lambda values: sp.csr_matrix((np.tile(values, m), (np.repeat(np.arange(m), 3),
                                                             cols.ravel())), shape=(m, n))
    fr = Friction(law="tresca", mu=0.5, T=row([0.0, 1.0, -0.3]),
                  tangent=np.tile([1.0, 0.0], (m, 1)), slip_bound=np.array([0.0, 0.5, 1.0, 2.0]),
                  offset=0.1 * rng.standard_normal(m), previous=np.zeros(m))
    return ContactQP(A=M @ M.T + n * np.eye(n), f=5 * rng.standard_normal(n),
                     B=row([1.0, 0.2, 0.0]), g=0.1 * np.abs(rng.standard_normal(m)), friction=fr)


def test_every_library_on_a_small_tresca_step():
    """Every library, HiGHS included, on a small step with a node in contact (``p > 0``)
    that slips, one that sticks and one without a bound: within the bars of the exact
    answer (measured: HiGHS 1.8e-7 in the energy norm, the others <= 7e-9)."""
    qp = _small_tresca_step()
    exact = solve(qp, "tresca_exact", tol=1e-12)
    assert exact.status == "converged"
    states = qp.friction.states(exact.tangential, 1e-12)
    assert {"free", "stick", "slip"} <= set(states)
    for lib in LIBRARIES:
        _check_answer(qp, exact, solve(qp, lib.name, tol="high"))


def test_the_cone_program_in_2d_is_the_split_qp():
    """Clarabel on the 2D step's cone program (cones of size 2) and on its split QP: the
    same answer, within the bars, as the exact reference."""
    qp, sol = _exact("circle_square")
    data = scale_qp(qp)
    step = data.step()
    settings = {"tol_gap_abs": 1e-10, "tol_gap_rel": 1e-10, "tol_feas": 1e-10,
                "verbose": False}
    for program in (split_program(step), cone_program(step)):
        out = clarabel_call(program, settings, None, None)
        assert out.status == "Solved", program.kind
        u, _ = data.unscale(out.x[:program.n], out.z[:qp.m])
        assert energy_error(qp, u, sol.u) <= NORM_BAR, program.kind


@pytest.mark.parametrize("scene, name", [("circle_square", "osqp"),
                                         ("circle_square", "clarabel"),
                                         ("cube_sphere", "clarabel"),
                                         ("cube_sphere", "ecos")])
def test_a_library_that_stops_short_says_so(scene, name):
    qp, _ = _exact(scene)
    res = solve(qp, name, tol="high", max_iter=2)
    assert res.claimed_status == res.status == "max_iter" and res.failed_check == "claimed"
    assert res.tangential.shape == (qp.friction.T.shape[0],)


def test_coulomb_load_path_with_a_qp_library():
    """Coulomb friction through the load path: the fixed point ``s = mu p`` runs around
    OSQP's Tresca steps (warm-started, a guess OSQP takes), every step verified, and the path agrees with the exact
    reference's (registered ``tresca_exact``) to 1e-10 in the energy norm, with the same
    number of Tresca solves within one."""
    qp = problems()["circle_square"].make(0, friction="coulomb", mu=0.5, shift=0.02)
    exact = run_load_path(qp, lambda step, start: solve(step, "tresca_exact", tol=1e-10),
                          1e-10)
    run = run_load_path(qp, lambda step, start: solve(step, "osqp", tol="high",
                                                      **warm_start(start)), 1e-9)
    assert run.result.status == "converged", run.result.message
    assert [r["status"] for r in run.records] == ["converged", "converged"]
    assert run.records[1]["tresca_solves"] >= 2
    for mine, ref, a, b in zip(run.steps, exact.steps, run.records, exact.records, strict=True):
        assert energy_error(qp, mine.solution.u, ref.solution.u) <= 1e-10
        assert abs(a["tresca_solves"] - b["tresca_solves"]) <= 1


def test_cli_solves_a_coulomb_scene_with_a_qp_library(tmp_path):
    out = tmp_path / "run.json"
    assert main(["solve", "--problem", "circle_square", "--level", "0", "--solver", "osqp",
                 "--tol", "high", "--out", str(out), "--force", "--set", "friction=coulomb",
                 "--set", "mu=0.5", "--set", "shift=0.02"]) == 0
    data = read_json(out)
    assert data["status"] == "converged" and data["form"] == "split"
    assert [s["status"] for s in data["friction"]["load_path"]] == ["converged", "converged"]
    states = set(data["friction"]["state"])
    assert "stick" in states
