"""Friction through the registry: ``tresca_exact`` as a registered solver, the suite's
verification of a frictional answer (the friction KKT residuals and the certified Tresca
energy bound), and ``contactbench solve`` on a frictional scene (the whole load path,
the stick/slip state per constrained node in its JSON)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp

from problems.kkt import energy_error
from problems.qp import ContactQP
from problems.spec import problems
from solvers.base import CONTRACT, SolveResult, contract_violation
from solvers.certificate import verify
from solvers.kernels.cholesky import FactorizationError
from solvers.interface import run_load_path, solve, solvers
from solvers.kernels.tresca import friction_path, warm_start
from workflows.cli import main
from workflows.io import read_json
from agreement import within_certificate

SCENE = problems()["circle_square"]
TIGHT = 1e-10


def _scene(level, law, mu=0.5, shift=0.02):
    return SCENE.make(level, friction=law, mu=mu, shift=shift)


def _registered_path(qp, tol=TIGHT):
    return run_load_path(qp, lambda step, start: solve(step, "tresca_exact", tol=tol), tol)


def _a_norm(qp, v):
    return float(np.sqrt(v @ (qp.A @ v)))


@pytest.fixture(scope="module")
def tresca_run():
    qp = _scene(1, "tresca")
    return qp, _registered_path(qp)


def test_tresca_exact_is_registered_for_friction():
    spec = solvers()["tresca_exact"]
    assert spec.handles_friction and spec.role == "exact"
    qp = _scene(1, "tresca")
    assert spec.check(qp) == (True, "")
    # a solver without friction is skipped on a frictional step at once, with the reason
    res = solve(qp, "pdas")
    assert res.status == "skipped" and "frictionless problem only" in res.message
    # the thesis's solver says what extending it would take
    res = solve(qp, "augmented_projection")
    assert res.status == "skipped" and "frictionless problem only (not built: " in res.message
    assert "Remark 8.5" in res.message


def test_without_friction_it_is_skipped_with_the_reason():
    """A frictionless problem is pdas's: the dense dual would only add a slower second
    exact route to every frictionless study."""
    res = solve(SCENE.make(1), "tresca_exact", tol=TIGHT)
    assert res.status == "skipped" and "frictionless problem" in res.message


def test_its_limits_and_failures_are_reported():
    """The active-set cap is a ``max_iter`` row; no rows is the linear solve; rows that no
    ``u`` satisfies (a singular dual Hessian) a ``failed`` answer saying so; an indefinite
    ``A`` an error naming it, which the registry makes a ``failed`` row as it does every
    solver's exception (the last three on the method itself, which the registry gives
    frictional problems only)."""
    res = solve(_scene(1, "tresca"), "tresca_exact", "mid", max_iter=1)
    assert res.claimed_status == res.status == "max_iter" and "stopped after 1" in res.message
    method = lambda qp: solvers()["tresca_exact"].solve(qp, 1e-8, 100, None, None, None, {})
    free = ContactQP(A=2 * sp.eye(3), f=np.ones(3), B=sp.csr_matrix((0, 3)), g=np.zeros(0))
    res = method(free)
    assert res.claimed_status == "converged" and np.allclose(res.u, 0.5, rtol=1e-14)
    infeasible = ContactQP(A=2 * sp.eye(2), f=np.ones(2), g=[-1.0, -1.0],
                           B=sp.csr_matrix([[1.0, 0.0], [-1.0, 0.0]]))
    res = method(infeasible)
    assert res.claimed_status == "failed" and "dual Hessian is singular" in res.message
    indefinite = ContactQP(A=sp.diags([1.0, -1.0]), f=np.ones(2), g=[0.0],
                           B=sp.csr_matrix([[1.0, 0.0]]))
    with pytest.raises(FactorizationError, match="not positive definite"):
        method(indefinite)


@pytest.mark.parametrize("level", [1, pytest.param(2, marks=pytest.mark.slow)])
@pytest.mark.parametrize("law", ["tresca", "coulomb"])
def test_the_registered_reference_verifies_every_step(level, law):
    qp = _scene(level, law)
    run = _registered_path(qp)
    res = run.result
    assert res.status == "converged" and res.failed_check == "", res.message
    assert {"bound", "slip_complementarity"} <= set(res.kkt.names)
    assert res.kkt.max <= TIGHT and res.gap.certified and res.gap.meets(TIGHT)
    assert [r["status"] for r in run.records] == ["converged", "converged"]
    # the same path as the exact reference called directly, without the registry
    ref = friction_path(qp, tol=TIGHT)
    assert len(run.steps) == len(ref) == 2
    for mine, theirs in zip(run.steps, ref):
        assert energy_error(qp, mine.solution.u, theirs.solution.u) <= 1e-12
        lam = theirs.solution.lam
        assert np.max(np.abs(mine.solution.lam - lam)) <= 1e-10 * np.max(np.abs(lam))
    last = run.steps[-1]
    assert 0 < last.solution.stick.sum() < (last.qp.friction.slip_bound > 0).sum()
    if law == "coulomb":             # the fixed point s = mu p works in the tangential step
        assert run.records[1]["tresca_solves"] >= 3
        assert 0 < run.records[1]["contraction"] < 1
        np.testing.assert_allclose(last.qp.friction.slip_bound, 0.5 * res.p, rtol=0,
                                   atol=1e-9 * res.p.max())


@pytest.mark.parametrize("tangential, rule", [
    (None, "tangential"), (np.zeros(3), "tangential"), ("ab", "tangential"),
    (np.array([0.0, np.nan]), "tangential_finite")])
def test_the_tangential_rules_of_the_contract(tangential, rule):
    res = SolveResult(u=np.zeros(4), p=np.zeros(2), claimed_status="converged",
                      tangential=tangential)
    assert rule in CONTRACT and contract_violation(res, 4, 2, 2)[0] == rule
    assert contract_violation(res, 4, 2) is None          # frictionless: not asked for
    ok = SolveResult(u=np.zeros(4), p=np.zeros(2), claimed_status="converged",
                     tangential=np.zeros(2))
    assert contract_violation(ok, 4, 2, 2) is None


#: every registered contact solver that takes friction (each Tresca step through the
#: registry); the general QP libraries stop at their own tolerances and may honestly fall
#: short of the verification, which tests/test_friction_libraries.py checks instead
FRICTIONAL = sorted(name for name, spec in solvers().items()
                    if spec.handles_friction and spec.role != "library")
#: the frictional solvers that take one law only, and the reason they give for the other
ONE_LAW = {("siconos_newton", "tresca"): "Siconos's nonsmooth Newton methods solve Coulomb's "
                                         "law only"}


@pytest.mark.parametrize("law", ["tresca", "coulomb"])
@pytest.mark.parametrize("name", FRICTIONAL)
def test_every_frictional_solver_verifies_along_the_path_and_agrees(name, law):
    """Each frictional solver, run along the load path through the registry at ``high``,
    is verified ``converged`` on every step and agrees with the exact reference to 1e-8
    in the relative energy norm (both steps)."""
    assert "tresca_exact" in FRICTIONAL and len(FRICTIONAL) >= 2
    qp = _scene(1, law)
    ok, why = solvers()[name].check(qp)
    if not ok and "install" in why:
        pytest.skip(why)                   # a solver of another interpreter, not installed
    ref = _registered_path(qp)
    run = run_load_path(qp, lambda step, start: solve(step, name, tol="high", **warm_start(start)),
                        1e-9)
    if (name, law) in ONE_LAW:
        assert run.result.status == "skipped" and ONE_LAW[name, law] in run.result.message
        return
    assert run.result.status == "converged", run.result.message
    assert [r["status"] for r in run.records] == ["converged", "converged"]
    for mine, exact in zip(run.steps, ref.steps, strict=True):
        assert energy_error(qp, mine.solution.u, exact.solution.u) <= 1e-8, name


def test_warm_started_load_path_agrees_with_the_cold_one_in_fewer_steps():
    """Started from the path's last answer (the default, as a quasi-static computation
    runs), TNNMG's Coulomb path reaches the same verified answer as from zero, in well
    under the steps: each fixed-point solve starts next to its answer."""
    qp = _scene(1, "coulomb")
    ref = _registered_path(qp)
    runs = {}
    for warm in (True, False):
        steps = []

        def tnnmg(step, start):
            res = solve(step, "tnnmg", tol="high", **warm_start(start))
            steps.append(res.iterations)
            return res

        run = run_load_path(qp, tnnmg, 1e-9, warm=warm)
        assert run.result.status == "converged", run.result.message
        assert [r["warm_start"] for r in run.records] == [warm, warm]
        assert energy_error(qp, run.result.u, ref.result.u) <= 1e-8
        runs[warm] = sum(steps)
    assert runs[True] <= 0.7 * runs[False], runs


def test_a_coulomb_step_solved_monolithically_is_judged_on_its_own_bound():
    """semismooth_newton with coulomb='monolithic' answers the Coulomb step itself
    (s = mu p inside its iteration): verified on the Tresca step of its own bound mu p,
    not on the slip bound it was handed, and the path's fixed point then stops at its
    second solve (s = mu p holds at once)."""
    qp = _scene(1, "coulomb")
    ref = _registered_path(qp)
    run = run_load_path(qp, lambda step, start: solve(step, "semismooth_newton", tol="high",
                                                      coulomb="monolithic"), 1e-9)
    assert run.result.status == "converged", run.result.message
    assert run.result.stats["friction"] == "coulomb_monolithic"
    assert [r["tresca_solves"] for r in run.records] == [2, 2]
    assert energy_error(qp, run.result.u, ref.result.u) <= 1e-8
    # handed a slip bound far from mu p, the answer is still judged on its own
    handed = replace(run.qp, friction=replace(run.qp.friction,
                                              slip_bound=2 * run.qp.friction.slip_bound))
    res = solve(handed, "semismooth_newton", tol="high", coulomb="monolithic")
    assert res.status == "converged" and res.kkt.bound <= 1e-9
    tresca = solve(handed, "semismooth_newton", tol="high")     # the handed Tresca step
    assert tresca.status == "converged" and energy_error(qp, tresca.u, res.u) > 1e-6


def _answer(u, p, lam):
    return SolveResult(u=np.array(u), p=np.array(p), claimed_status="converged",
                       tangential=None if lam is None else np.array(lam))


def test_a_perturbed_answer_fails_with_the_right_check(tresca_run):
    _, run = tresca_run
    step, sol = run.qp, run.steps[-1].solution
    tol = 1e-6
    assert verify(step, _answer(sol.u, sol.p, sol.lam), tol).status == "converged"
    # slipping rows' multipliers 1 % beyond their bound
    s = step.friction.slip_bound
    slipping = (s > 0) & ~sol.stick
    assert slipping.sum() >= 2
    beyond = np.where(slipping, 1.01 * sol.lam, sol.lam)
    bad = verify(step, _answer(sol.u, sol.p, beyond), tol)
    assert bad.status == "inaccurate" and "kkt_bound" in bad.failed_check.split(",")
    assert bad.kkt.bound == pytest.approx(0.01 * np.max(s[slipping]) / max(
        np.max(np.abs(beyond)), np.max(s)), rel=1e-6)
    # u off by 1e-3 in the energy norm
    d = np.random.default_rng(4).standard_normal(step.n)
    d *= 1e-3 * _a_norm(step, sol.u) / _a_norm(step, d)
    off = verify(step, _answer(sol.u + d, sol.p, sol.lam), tol)
    assert off.status == "inaccurate" and "energy_bound" in off.failed_check.split(",")
    err = energy_error(step, sol.u + d, sol.u)
    assert err >= 0.99e-3 and within_certificate(err, off.gap.relative_energy_bound,
                                                 off.gap.floor)
    # no tangential multipliers at all: the contract, by name
    none = verify(step, _answer(sol.u, sol.p, None), tol)
    assert none.status == "failed" and none.failed_check == "contract:tangential"
    assert "tangential" in none.message and none.kkt is None


def test_slipping_against_the_multiplier_fails_the_slip_complementarity(tresca_run):
    """Slipping rows given their multiplier with the wrong sign: the bound holds, the slip
    complementarity does not (the friction force would push along the slip)."""
    _, run = tresca_run
    step, sol = run.qp, run.steps[-1].solution
    fr = step.friction
    slip = fr.slip(sol.u)
    slipping = (fr.slip_bound > 0) & ~sol.stick & (np.abs(slip) > 1e-3 * np.abs(slip).max())
    lam = np.where(slipping, -sol.lam, sol.lam)
    res = verify(step, _answer(sol.u, sol.p, lam), 1e-6)
    assert res.kkt.bound == 0 and res.kkt.slip_complementarity > 100 * 1e-6
    assert "kkt_slip_complementarity" in res.failed_check.split(",")


@pytest.mark.parametrize("size", [1e-9, 1e-6, 1e-3])
def test_the_certified_bound_holds_and_is_small_at_the_solution(tresca_run, size):
    """The Tresca bound is >= the true energy error (against the exact reference at a
    tight tolerance) for perturbed u and multipliers, and small at the solution."""
    _, run = tresca_run
    step, sol = run.qp, run.steps[-1].solution
    exact = verify(step, _answer(sol.u, sol.p, sol.lam), TIGHT)
    assert exact.gap.relative_energy_bound <= max(1e-7, 4 * exact.gap.floor)
    rng = np.random.default_rng(int(-np.log10(size)))
    norm = _a_norm(step, sol.u)
    for trial in range(4):
        d = rng.standard_normal(step.n)
        u = sol.u + size * norm * d / _a_norm(step, d)
        p = sol.p * (1 + size * rng.standard_normal(step.m))
        lam = sol.lam * (1 + size * rng.standard_normal(step.m))
        res = verify(step, _answer(u, p, lam), TIGHT)
        error = energy_error(step, u, sol.u)
        assert res.gap.certified
        assert within_certificate(error, res.gap.relative_energy_bound, res.gap.floor), \
            (trial, error)
        assert res.gap.relative_energy_bound <= 1e3 * error + 4 * res.gap.floor, trial


# ---------------------------------------------------------------- the command line
def _cli(tmp_path, *sets, solver="tresca_exact", level=1, tol="1e-10", extra=()):
    out = tmp_path / "run.json"
    argv = ["solve", "--problem", "circle_square", "--level", str(level), "--solver", solver,
            "--tol", tol, "--out", str(out), "--force", *extra]
    for s in sets:
        argv += ["--set", s]
    assert main(argv) == 0
    return read_json(out)


def test_cli_runs_the_load_path_and_writes_the_frictional_state(tmp_path):
    data = _cli(tmp_path, "friction=tresca", "mu=0.5", "shift=0.02")
    assert data["status"] == "converged" and data["solver"] == "tresca_exact"
    assert data["kkt"]["bound"] <= 1e-10 and data["kkt"]["slip_complementarity"] <= 1e-10
    fr = data["friction"]
    assert [r["load"] for r in fr["load_path"]] == ["normal", "tangential"]
    assert [r["status"] for r in fr["load_path"]] == ["converged", "converged"]
    assert [r["tresca_solves"] for r in fr["load_path"]] == [2, 1]
    # the last step against the exact reference called directly
    qp = _scene(1, "tresca")
    ref = friction_path(qp, tol=1e-10)[-1]
    lam, s = np.array(fr["tangential"]), np.array(fr["slip_bound"])
    assert len(lam) == len(fr["state"]) == len(fr["slip"]) == qp.m
    np.testing.assert_allclose(lam, ref.solution.lam, rtol=0, atol=1e-10 * np.abs(lam).max())
    np.testing.assert_allclose(fr["traction"], lam / qp.contact.mass, rtol=1e-14)
    np.testing.assert_allclose(data["contact"]["pressure"], ref.solution.p / qp.contact.mass,
                               rtol=0, atol=1e-10 * np.max(data["contact"]["pressure"]))
    state, slip = np.array(fr["state"]), np.array(fr["slip"])
    assert np.array_equal(state == "stick", ref.solution.stick)
    assert (state == "stick").sum() >= 2 and (state == "slip").sum() >= 2
    assert np.all(np.abs(slip[state == "stick"]) <= 1e-10 * np.abs(slip).max())
    np.testing.assert_allclose(np.abs(lam[state == "slip"]), s[state == "slip"], rtol=1e-12)
    assert fr["tangential_force"][0] == pytest.approx(lam.sum(), rel=1e-12)
    assert 0.3 < fr["load_ratio"] < 0.8


def test_cli_cold_starts_every_load_step_from_zero(tmp_path):
    warm = _cli(tmp_path, "friction=tresca", "mu=0.5", "shift=0.02", solver="tnnmg",
                tol="high")
    cold = _cli(tmp_path, "friction=tresca", "mu=0.5", "shift=0.02", solver="tnnmg",
                tol="high", extra=["--cold"])
    assert warm["status"] == cold["status"] == "converged"
    assert [r["warm_start"] for r in warm["friction"]["load_path"]] == [True, True]
    assert [r["warm_start"] for r in cold["friction"]["load_path"]] == [False, False]
    np.testing.assert_allclose(warm["friction"]["tangential"], cold["friction"]["tangential"],
                               rtol=0, atol=1e-6 * np.abs(cold["friction"]["tangential"]).max())


def test_cli_coulomb_reports_the_fixed_point(tmp_path):
    data = _cli(tmp_path, "friction=coulomb", "mu=0.5", "shift=0.02")
    assert data["status"] == "converged", data["message"]
    tangential = data["friction"]["load_path"][1]
    assert tangential["tresca_solves"] >= 3 and 0 < tangential["contraction"] < 1
    np.testing.assert_allclose(data["friction"]["slip_bound"], 0.5 * np.array(data["contact"]["p"]),
                               rtol=0, atol=1e-9 * np.max(data["contact"]["p"]))


def test_cli_mu_zero_is_the_frictionless_answer(tmp_path):
    data = _cli(tmp_path, "friction=tresca", "mu=0", "shift=0.02")
    assert data["status"] == "converged"
    plain = SCENE.make(1, shift=0.02)
    ref = solve(plain, "pdas", tol=1e-12)
    p = np.array(data["contact"]["p"])
    assert np.max(np.abs(p - ref.p)) <= 1e-10 * np.max(ref.p)
    gap = np.array(data["contact"]["gap"])
    assert np.max(np.abs(gap - (plain.g - plain.B @ ref.u))) <= 1e-10 * np.max(np.abs(plain.g))
    assert set(data["friction"]["state"]) == {"free"}
    assert np.all(np.array(data["friction"]["tangential"]) == 0)


def test_cli_a_frictionless_solver_is_skipped_with_the_reason(tmp_path):
    data = _cli(tmp_path, "friction=coulomb", "mu=0.5", "shift=0.02", solver="pdas",
                tol="mid")
    assert data["status"] == "skipped" and "frictionless problem only" in data["message"]
    assert data["kkt"] is None and data["friction"]["load_path"][0]["status"] == "skipped"
    assert len(data["friction"]["load_path"]) == 1


@pytest.mark.parametrize("law", ["tresca", "coulomb"])
def test_cli_gross_sliding_is_a_verified_state(tmp_path, law):
    """A prescribed tangential displacement that carries the whole contact to mu P: every
    node slips, no partial slip is left. That state is the static equilibrium under the
    displacement, solved and verified like any other; the row says it is gross sliding."""
    data = _cli(tmp_path, f"friction={law}", "mu=0.05", "shift=0.2")
    assert data["status"] == "converged" and not data["failed_check"]
    assert data["message"].startswith("gross sliding")
    assert "stick" not in data["friction"]["state"]
    assert "slip" in data["friction"]["state"]
    # Q = mu P: exactly for Coulomb (s = mu p of the step itself), for Tresca up to the
    # change of the normal force since the normal step (its s = mu p0)
    assert data["friction"]["load_ratio"] == pytest.approx(1.0, abs=1e-6 if law == "coulomb"
                                                           else 0.05)
    assert data["kkt"]["bound"] <= 1e-10          # the answer itself is verified
