"""Siconos's frictional-contact solvers as registered solvers (solvers/siconos.py): an
independent code, under the system Python, verified by the suite like every solver, on
the test set's Tresca steps and on Coulomb load paths in 2D and 3D; what it cannot take
skipped with the reason; its process's failures reported as rows (solvers/system_python.py)."""
from __future__ import annotations

import sys

import numpy as np
import pytest

from problems.friction.data import coulomb_step
from problems.kkt import energy_error
from problems.spec import problems
from solvers import siconos, system_python
from solvers.base import COULOMB_MONOLITHIC
from solvers.interface import run_load_path, solve, solvers
from solvers.kernels.tresca import warm_start
from workflows.problem_set import load

PYTHON, WHY = siconos.interpreter()
needs_siconos = pytest.mark.skipif(not PYTHON, reason=WHY)
#: agreement with the exact reference (relative energy norm) at the ``high`` preset
AGREEMENT = 1e-8


@pytest.fixture(scope="module")
def small_class():
    ts = load("contact-qp-5")
    return {item.name: item for item in ts.problems("small", None)}


def test_a_2d_problem_embeds_in_3d_with_its_extra_component_decoupled():
    rng = np.random.default_rng(0)
    X = rng.standard_normal((6, 6))
    W, q = X @ X.T + 6 * np.eye(6), rng.standard_normal(6)
    W3, q3, kept = siconos.embed_2d(W, q)
    assert W3.shape == (9, 9) and list(kept) == [0, 1, 3, 4, 6, 7]
    assert np.array_equal(W3[np.ix_(kept, kept)], W) and np.array_equal(q3[kept], q)
    extra = [2, 5, 8]
    assert np.allclose(np.diag(W3)[extra], np.mean(np.diag(W)))
    assert not W3[extra][:, kept].any() and not q3[extra].any()


@needs_siconos
@pytest.mark.parametrize("name", ["circle_square_tresca_q05_L0", "cube_sphere_tresca_q05_L0",
                                  "circle_square_coulomb_q05_L1",
                                  "cube_sphere_coulomb_q05_L0"])
def test_the_test_sets_tresca_steps_are_verified_and_agree_with_the_reference(small_class,
                                                                              name):
    """Siconos's Gauss-Seidel through its Tresca fixed point held to one step: verified
    ``converged`` on the small class's 2D and 3D Tresca steps (the Coulomb families' are
    Tresca steps of the bound ``mu p``), at the exact reference to ``AGREEMENT``; the
    Newton method skips them with its reason."""
    qp = small_class[name].build()
    ref = solve(qp, "tresca_exact", tol=1e-10)
    res = solve(qp, "siconos_nsgs", tol="high")
    assert res.status == "converged", res.message
    assert res.stats["friction"] == "tresca_step" and "FC3D_NSGS" in res.message
    assert energy_error(qp, res.u, ref.u) <= AGREEMENT
    assert np.abs(res.tangential - ref.tangential).max() <= 1e-6 * np.abs(ref.tangential).max()
    newton = solve(qp, "siconos_newton", tol="high")
    assert newton.status == "skipped" and "Coulomb's law only" in newton.message


#: The test set's Coulomb steps against their reference: the reference is the fixed
#: point's final Tresca step, its bounds mu p rounded to 8 significant digits.
COULOMB_AGREEMENT = 1e-8


@needs_siconos
@pytest.mark.parametrize("name", ["circle_square_coulomb_q05_L0", "circle_square_coulomb_q05_L1",
                                  "cube_sphere_coulomb_q05_L0", "circle_square_coulomb_mu1_L0"])
def test_the_test_sets_coulomb_steps_as_one_problem_by_three_codes(small_class, name):
    """The Coulomb step of a test-set Coulomb family (:func:`coulomb_step`), solved as one
    problem by Siconos's Gauss-Seidel and Newton methods and by semismooth Newton
    (``coulomb=monolithic``), each verified on its own bound ``mu p``: all three at the
    fixed point's exported reference, to the rounding of its bounds."""
    step = small_class[name].frictional_step()
    qp = coulomb_step(step.qp)
    for solver, options in (("siconos_nsgs", {}), ("siconos_newton", {}),
                            ("semismooth_newton", {"coulomb": "monolithic"})):
        res = solve(qp, solver, tol="high", **options)
        assert res.status == "converged", (solver, res.message)
        assert res.stats["friction"] == COULOMB_MONOLITHIC, solver
        assert energy_error(qp, res.u, step.solution.u) <= COULOMB_AGREEMENT, solver


def test_a_coulomb_step_needs_friction_isotropic_and_mu():
    cube = problems()["cube_sphere"]
    with pytest.raises(ValueError, match="parameter 'qp': a frictionless problem"):
        coulomb_step(cube.make(0))
    with pytest.raises(ValueError, match="friction.facets = 6; allowed: 0"):
        coulomb_step(cube.make(0, friction="tresca", mu=0.5, shift=0.05, friction_facets=6))
    step = coulomb_step(cube.make(0, friction="tresca", mu=0.5, shift=0.05))
    assert step.friction.law == "coulomb" and step.friction.mu == 0.5


@needs_siconos
@pytest.mark.parametrize("solver", ["siconos_nsgs", "siconos_newton"])
def test_a_3d_coulomb_path_is_solved_monolithically_and_agrees_with_the_fixed_point(solver):
    """On cube-sphere's Coulomb load path Siconos solves each step's law itself (verified
    on its own bound ``mu p``, the fixed point ending at its confirming second solve), in
    agreement with the exact reference's fixed point over Tresca steps."""
    qp = problems()["cube_sphere"].make(0, friction="coulomb", mu=0.5, shift=0.05)
    exact = run_load_path(qp, lambda step, start: solve(step, "tresca_exact", tol=1e-10), 1e-10)
    run = run_load_path(qp, lambda step, start: solve(step, solver, tol="high",
                                                      **warm_start(start)), 1e-9)
    assert run.result.status == "converged", run.result.message
    assert run.result.stats["friction"] == COULOMB_MONOLITHIC
    assert [r["tresca_solves"] for r in run.records] == [2, 2]
    for mine, ref in zip(run.steps, exact.steps, strict=True):
        assert energy_error(qp, mine.solution.u, ref.solution.u) <= AGREEMENT


def test_what_it_cannot_take_is_skipped_with_the_reason(monkeypatch):
    circle = problems()["circle_square"]
    res = solve(circle.make(0), "siconos_nsgs")
    assert res.status == "skipped" and "a frictionless problem" in res.message
    faceted = problems()["cube_sphere"].make(0, friction="tresca", mu=0.5, shift=0.05,
                                             friction_facets=6)
    res = solve(faceted, "siconos_nsgs")
    assert res.status == "skipped" and "faceted" in res.message
    tresca = circle.make(0, friction="tresca", mu=0.5, shift=0.02)
    res = solve(tresca, "siconos_newton")
    assert res.status == "skipped" and "a Tresca step" in res.message
    monkeypatch.setattr(siconos, "LOCAL_MAX_ENTRIES", 10)
    res = solve(tresca, "siconos_nsgs")
    assert res.status == "skipped" and "dense Delassus operator" in res.message
    monkeypatch.undo()
    res = solve(tresca, "siconos_nsgs", max_unknowns_2d=1000)
    assert res.status == "skipped" and "unknowns > max_unknowns_2d = 1000" in res.message
    monkeypatch.setenv("CONTACTBENCH_SICONOS_PYTHON", "/nonexistent/python3")
    res = solve(tresca, "siconos_nsgs")
    assert res.status == "skipped" and siconos.INSTALL in res.message
    assert "CONTACTBENCH_SICONOS_PYTHON" in res.message


def test_a_job_past_its_limit_is_killed_and_one_that_dies_says_why():
    slow = system_python.run_job([sys.executable, "-c", "import time; time.sleep(30)"],
                                 system_python.clean_environment(), b"", 0.5, "tag", "the job")
    assert slow.record is None and slow.status == "time_limit"
    assert "the job killed: no answer within 0.5 s" in slow.message
    dies = system_python.run_job(
        [sys.executable, "-c", "import sys; sys.exit('Error: no such contact')"],
        system_python.clean_environment(), b"", 30, "tag", "the job")
    assert dies.record is None and dies.status == "failed"
    assert "exit status 1" in dies.message and "no such contact" in dies.message
    said = system_python.run_job(
        [sys.executable, "-c", "print('noise'); print('tag {\"x\": 1}')"],
        system_python.clean_environment(), b"", 30, "tag", "the job")
    assert said.record == {"x": 1}


@needs_siconos
def test_a_malformed_problem_is_a_failed_row_naming_the_sizes():
    stream = b'{"method": "nsgs", "contacts": 2, "tol": 1e-9, "max_iter": 10}\n' + bytes(8 * 5)
    job = system_python.run_job([PYTHON, "-I", str(siconos.WORKER)],
                                system_python.clean_environment(), stream, 60, siconos.TAG,
                                "Siconos's process")
    assert job.status == "failed" and "expected 50 doubles for 2 contacts, got 5" in job.message


def test_both_are_registered_as_frictional_solvers_of_their_own_process():
    registry = solvers()
    for name in ("siconos_nsgs", "siconos_newton"):
        spec = registry[name]
        assert spec.handles_friction and spec.role == "other"
        assert {p.name for p in spec.parameters} == {"tol_factor", "grace", "max_unknowns_2d",
                                                     "max_unknowns_3d"}
