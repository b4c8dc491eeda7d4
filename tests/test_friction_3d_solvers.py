"""Friction in 3D: the exact reference of a Tresca step (the dual with a disc per node, by
semismooth Newton on the projection equation: solvers.tresca.disc_qp_newton) and the
semismooth Newton solver's 3D branch (Hüeber-Stadler-Wohlmuth), on small dual problems
with known optimality conditions and on cube_sphere (mu = 0.5, elastically similar
bodies: E1 = E2 = 1, nu1 = nu2 = 0.3, the scene's defaults)."""
from __future__ import annotations

import numpy as np
import pytest

from solvers.tresca import (DISC_EDGE, DISC_INSIDE, DISC_ZERO, box_qp_active_set,
                            disc_qp_newton, project_dual)


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
