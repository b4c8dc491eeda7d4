"""Nested iteration over a frictional load path
(:func:`solvers.kernels.tresca.run_nested_load_path`): each solve on a finer level starts
from its own last answer plus the coarser level's change over the same solve,
interpolated with its prescribed values; the answers are those of the plain path (only
the start differs); Coulomb's law is refused with the reason; the tangential step's scale is
recovered exactly (:func:`solvers.kernels.tresca.tangential_scale`)."""
from __future__ import annotations

import numpy as np
import pytest

from problems.kkt import energy_error
from problems.spec import problems
from solvers.interface import run_load_path, solve
from solvers.kernels.tresca import (NestedStart, run_nested_load_path, scaled_tangential_step,
                                    tangential_scale, warm_start)

SCENE = problems()["circle_square"]
TOL = 1e-9


def _levels(levels, law="tresca", factor=0.8):
    return [scaled_tangential_step(SCENE.make(k, friction=law, mu=0.5, shift=0.01), factor)
            for k in levels]


def test_the_tangential_scale_is_recovered_exactly():
    qp = SCENE.make(1, friction="tresca", mu=0.5, shift=0.01)
    for factor in (0.0, 0.37, 2.5):
        assert tangential_scale(scaled_tangential_step(qp, factor), qp) == \
            pytest.approx(factor, abs=1e-12)


def test_nested_path_starts_from_the_prolongated_change_and_reaches_the_same_answer():
    qps = _levels((0, 1))
    starts, results, step_qps = [], [], []

    def step(step_qp, start):
        starts.append(start)
        step_qps.append(step_qp)
        res = solve(step_qp, "tnnmg", tol="high", **warm_start(start))
        results.append(res)
        return res

    runs = run_nested_load_path(qps, step, TOL)
    assert [r.result.status for r in runs] == ["converged", "converged"]
    n = len(results) // 2                  # the same solves on both levels
    assert [r["tresca_solves"] for r in runs[0].records] == \
        [r["tresca_solves"] for r in runs[1].records]
    coarse, fine = results[:n], results[n:]
    P = qps[1].multilevel.prolongations[-1]
    P_D = qps[1].multilevel.prescribed_prolongation
    # the coarse steps' own prescribed values: the tangential step moves the held part
    fixed = [q.u_fixed for q in step_qps[:n]]
    assert np.abs(fixed[-1] - fixed[0]).max() > 0
    interpolate = lambda i: P @ coarse[i].u + P_D @ fixed[i]
    assert isinstance(starts[n], NestedStart)
    np.testing.assert_allclose(starts[n].u, interpolate(0), rtol=0, atol=1e-14)
    for i in range(1, n):                  # u0 = u_last + I(u_c,i) - I(u_c,i-1)
        expected = fine[i - 1].u + interpolate(i) - interpolate(i - 1)
        np.testing.assert_allclose(starts[n + i].u, expected, rtol=0, atol=1e-14)
        assert starts[n + i].p is fine[i - 1].p
    # the prescribed values' share is what brings the start near the answer
    first = fine[0].u
    assert energy_error(step_qps[n], starts[n].u, first) < \
        0.1 * energy_error(step_qps[n], P @ coarse[0].u, first)
    # the coarsest level runs as a warm path does
    assert starts[0] is None and all(s is r for s, r in zip(starts[1:n], coarse))
    plain = run_load_path(qps[1], lambda q, s: solve(q, "tnnmg", tol="high",
                                                     **warm_start(s)), TOL)
    assert plain.result.status == "converged"
    assert energy_error(qps[1], runs[1].result.u, plain.result.u) <= 1e-8


def test_a_coarser_level_stopping_short_leaves_the_finer_path_warm():
    qps = _levels((0, 1))
    calls = []

    def step(step_qp, start):
        calls.append(start)
        res = solve(step_qp, "tnnmg", tol="high", **warm_start(start))
        if step_qp.n == qps[0].n and len(calls) == 2:    # the coarse normal step stops
            res.status, res.message = "max_iter", "stopped short"
        return res

    runs = run_nested_load_path(qps, step, TOL)
    assert runs[0].result.status == "max_iter"
    assert runs[1].result.status == "converged", runs[1].result.message
    coarse_solves = sum(r["tresca_solves"] for r in runs[0].records)
    # the coarse path stopped at its second solve: the fine path's third starts warm
    assert coarse_solves == 2
    assert not isinstance(calls[coarse_solves + 2], NestedStart)


def test_coulomb_and_an_empty_chain_are_refused():
    with pytest.raises(ValueError, match="Coulomb's fixed point takes a different number"):
        run_nested_load_path(_levels((0, 1), law="coulomb"), None, TOL)
    with pytest.raises(ValueError, match="at least one level"):
        run_nested_load_path([], None, TOL)
