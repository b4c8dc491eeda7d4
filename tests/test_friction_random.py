"""The random frictional family (:mod:`problems.friction.random_family`): every frictional
solver the suite owns on every tangential step of :data:`DRAWS` seeded draws.

Each draw's load path is solved by the exact reference on the test set's rounded
definitions (:func:`workflows.problem_set.frictional_steps`: a Coulomb step is the fixed
point's final Tresca step, its bound given); each tangential step is then solved from zero
by ``tresca_exact``, ``tnnmg`` and ``semismooth_newton`` through the registry, verified at
``TOL`` (the friction KKT residuals and the certified energy bound). Every run must be
verified ``converged`` and agree with the exact reference to :data:`AGREEMENT` in the
relative energy norm. The draws that needed semismooth Newton's fallback (sets that
cycle) are counted and named, and the counts printed after the run. On the first draws
the QP and conic libraries too: none of their verified ``converged`` rows is farther from
the exact reference than its certified bound. The test runs again
under every other OpenBLAS kernel the CPU can run (the Makefile's solver tests).
"""
from __future__ import annotations

import os

import numpy as np
import pytest

from problems.friction.random_family import SHARE_3D, draw
from problems.kkt import energy_error
from solvers.interface import solve
from workflows.problem_set import frictional_steps

#: Draws of the family (seeds ``0 .. DRAWS - 1``).
DRAWS = 500

#: The verification's tolerance of every run.
TOL = 1e-10

#: Agreement with the exact reference, relative energy norm.
AGREEMENT = 1e-8

SOLVERS = ("tresca_exact", "tnnmg", "semismooth_newton")

#: The QP and conic libraries checked on the first :data:`LIBRARY_DRAWS` draws at ``mid``:
#: a row they end ``converged`` (verified) lies within its certified bound of the exact
#: reference; a claim the verification refutes is ``inaccurate``, never ``converged``.
LIBRARIES = ("osqp", "scs", "proxsuite", "clarabel", "qpalm", "piqp")
LIBRARY_DRAWS = 40


def run_draw(seed: int) -> dict:
    """Every solver on every tangential step of draw ``seed``: the first disagreement (or
    None) and whether semismooth Newton fell back."""
    member = draw(seed)
    steps = frictional_steps(member.problem, member.params, member.level)
    fell_back, problems = False, []
    for k, step in steps.items():
        for solver in SOLVERS:
            res = solve(step.qp, solver, tol=TOL)
            error = energy_error(step.qp, res.u, step.solution.u) \
                if res.status == "converged" else np.inf
            if not error <= AGREEMENT:
                problems.append(f"{member.name} step {k}: {solver} {res.status}, energy "
                                f"distance {error:.1e} ({res.message})")
            fell_back |= bool(res.stats.get("fallback", False)) and solver == "semismooth_newton"
    return {"name": member.name, "dim": 3 if member.problem == "cube_sphere" else 2,
            "steps": len(steps), "problems": problems, "fallback": fell_back}


@pytest.fixture(scope="module")
def outcomes() -> list[dict]:
    return [run_draw(seed) for seed in range(DRAWS)]


def test_the_family_is_seeded_and_spans_its_ranges():
    assert draw(7) == draw(7) and draw(7) != draw(8)
    members = [draw(seed) for seed in range(DRAWS)]
    share_3d = np.mean([m.problem == "cube_sphere" for m in members])
    assert abs(share_3d - SHARE_3D) < 0.06
    params = [dict(m.params) for m in members]
    assert {p["friction"] for p in params} == {"tresca", "coulomb"}
    mu = np.array([p["mu"] for p in params])
    assert mu.min() < 0.06 and mu.max() > 1.3
    assert {p["shift_steps"] for p in params} == {1, 2, 3}
    shift = np.array([p["shift"] for p in params])
    assert shift.min() < 0 < shift.max()
    with pytest.raises(ValueError, match="parameter 'seed'.*allowed: an integer >= 0"):
        draw(-1)
    assert draw(7, 1).level == 1 and draw(7, 1).params == draw(7).params
    with pytest.raises(ValueError, match="parameter 'level'.*allowed: an integer 0 .. 2"):
        draw(7, 3)


def test_every_solver_converges_and_agrees_on_every_draw(outcomes, record_property):
    bad = [line for out in outcomes for line in out["problems"]]
    fallbacks = [out["name"] for out in outcomes if out["fallback"]]
    steps = sum(out["steps"] for out in outcomes)
    dims = [out["dim"] for out in outcomes]
    kernel = os.environ.get("OPENBLAS_CORETYPE", "the machine's own")
    record_property("summary", f"random frictional family (OpenBLAS kernel {kernel}): "
                    f"{len(outcomes)} draws "
                    f"({dims.count(2)} 2D, {dims.count(3)} 3D), {steps} tangential steps, "
                    f"{len(SOLVERS)} solvers each; semismooth Newton's fallback on "
                    f"{len(fallbacks)} draws{': ' + ', '.join(fallbacks) if fallbacks else ''}")
    assert len(outcomes) >= 500 and steps > len(outcomes)
    assert not bad, f"{len(bad)} runs not verified or not agreeing:\n" + "\n".join(bad[:20])


def test_the_libraries_converged_never_contradicts_the_reference(record_property):
    refuted, verified = {}, {}
    for seed in range(LIBRARY_DRAWS):
        member = draw(seed)
        for k, step in frictional_steps(member.problem, member.params, member.level).items():
            for library in LIBRARIES:
                res = solve(step.qp, library, "mid", time_limit=20)
                if res.claimed_status == "converged" and res.status != "converged":
                    refuted[library] = refuted.get(library, 0) + 1
                if res.status != "converged":
                    continue
                verified[library] = verified.get(library, 0) + 1
                error = energy_error(step.qp, res.u, step.solution.u)
                assert error <= res.gap.certified_bound + 1e-12, (member.name, k, library)
    kernel = os.environ.get("OPENBLAS_CORETYPE", "the machine's own")
    record_property("summary", f"random frictional family (OpenBLAS kernel {kernel}), first "
                    f"{LIBRARY_DRAWS} draws at mid: verified converged {verified}; claims refuted (inaccurate) "
                    f"{refuted}")
    assert sum(verified.values()) > LIBRARY_DRAWS * len(LIBRARIES)
