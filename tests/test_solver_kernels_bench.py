"""Benchmarks of the kernels of Alg. 8.4: V-cycle (A-hat^{-1}), S-hat product, projection.

Run the timings with ``pytest tests/test_solver_kernels_bench.py --benchmark-enable``;
with the default ``--benchmark-disable`` each kernel runs once as a plain test and
its result is checked.
"""
from __future__ import annotations

import numpy as np
import pytest

from problems.circle_square import PROBLEM
from solvers.kernels import multigrid as mg
from solvers.kernels.schur import build_schur
from solvers.augmented_projection import SOLVER, make_projection

LEVEL = 2


@pytest.fixture(scope="module")
def setup():
    qp = PROBLEM.make(LEVEL)
    vcycles = {kind: mg.scaled_vcycle(qp.A, kind, qp.multilevel, 2, qp.free_dofs,
                                      **{**SOLVER.options(ahat=kind).ahat.options,
                                         "lanczos_steps": 10}) for kind in ("gmg", "sa")}
    schur = {kind: build_schur(kind, qp, vcycles["gmg"], lanczos_steps=20)
             for kind in ("multilevel", "inexact", "jacobi")}
    rng = np.random.default_rng(0)
    return qp, vcycles, schur, rng.standard_normal(qp.n), rng.standard_normal(qp.m)


@pytest.mark.parametrize("kind", ["gmg", "sa"])
def test_vcycle(benchmark, setup, kind):
    qp, vcycles, _, r, _ = setup
    x = benchmark(vcycles[kind], r)
    y = vcycles[kind](np.roll(r, 1))
    assert np.isfinite(x).all() and x @ r > 0
    assert abs(y @ r - x @ np.roll(r, 1)) < 1e-8 * np.linalg.norm(x) * np.linalg.norm(r)  # symmetric


def test_matvec(benchmark, setup):
    qp, _, _, r, _ = setup
    y = benchmark(qp.A.dot, r)
    coo = qp.A.tocoo()  # the same product, summed entry by entry
    expected = np.bincount(coo.row, weights=coo.data * r[coo.col], minlength=qp.n)
    np.testing.assert_allclose(y, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())


@pytest.mark.parametrize("kind", ["multilevel", "inexact", "jacobi"])
def test_schur_product(benchmark, setup, kind):
    qp, vcycles, schur, _, q = setup
    y = benchmark(schur[kind], q)
    assert q @ y > 0
    # against an independent product: the dense S-hat (column by column), and for the
    # Jacobi-type S-hat the explicit scale * B diag(A)^-1 B^T
    np.testing.assert_allclose(y, schur[kind].dense() @ q, rtol=1e-10, atol=1e-12 * np.abs(y).max())
    if kind == "jacobi":
        S = (qp.B @ (qp.B.T / qp.A.diagonal()[:, None])) * schur[kind].scale
        np.testing.assert_allclose(y, S @ q, rtol=1e-10, atol=1e-12 * np.abs(y).max())


@pytest.mark.parametrize("projection", ["mprgp", "richardson"])
def test_projection(benchmark, setup, projection):
    qp, _, schur, _, q = setup
    S_hat = schur["multilevel"]
    project, _ = make_projection(SOLVER.options(projection=projection).projection, S_hat)
    p_k = np.maximum(q, 0.0)
    d = S_hat(p_k) + 0.5 * q
    p_new, n_inner = benchmark(project, d, p_k)
    assert np.all(p_new >= 0) and n_inner >= 0
    phi = lambda x: 0.5 * x @ S_hat(x) - d @ x
    assert phi(p_new) <= phi(p_k) + 1e-12 * abs(phi(p_k))
