"""Local multigrid smoothing on adaptive hierarchies (issue 24, deliverable 4).

The V-cycle of a geometric hierarchy smooths on each level only the unknowns that level
added and their neighbours (:func:`solvers.multigrid.changed_dofs`). On a uniform
hierarchy that is every unknown, so the cycle is the full one; on an adaptive hierarchy
the work per cycle falls while the cycle stays an SPD preconditioner with a bounded
condition number.
"""
import numpy as np
import pytest

from problems.fem.adaptive import adaptive_loop, adaptive_start, mark_doerfler
from problems.spec import problems
from solvers import multigrid as mg
from solvers.interface import solve


def _vcycle(qp, smoothing):
    return mg.vcycle(qp.A, "gmg", qp.multilevel, qp.dim, qp.free_dofs, smoother="symmetric_gs",
                     sweeps=1, smoothing=smoothing)


@pytest.fixture(scope="module")
def adaptive_qp():
    """circle-square after eight adaptive steps from level 0 (eta_1 + eta_2, 10 % of the
    cells at least): a graded hierarchy of nine levels, each adding 10-30 % nodes."""
    import problems.circle_square as cs
    from workflows.scripts.adaptive_study import circle_projection
    scene0 = cs.scene(0, problems()["circle_square"].options())
    make, start = adaptive_start(scene0, 0)
    run = adaptive_loop(make, start, lambda qp, u0, p0: solve(qp, "pdas", tol=1e-10, u0=u0, p0=p0),
                        estimator="eta1+eta2", marking=lambda e: mark_doerfler(e, 0.5, 0.1),
                        max_steps=8, project=circle_projection(scene0), eta2_weight=1.0)
    return run.qps[-1]


def test_local_smoothing_is_the_full_cycle_on_a_uniform_hierarchy():
    qp = problems()["circle_square"].make(2)
    b = np.random.default_rng(1).standard_normal(qp.n)
    local, full = _vcycle(qp, "local"), _vcycle(qp, "full")
    np.testing.assert_allclose(local.vcycle_once(b), full.vcycle_once(b), rtol=1e-12, atol=1e-14)
    assert local.smoothing_work() == pytest.approx(full.smoothing_work())
    assert 1.2 < full.smoothing_work() < 1.35   # 1 + 1/4 (the coarsest level is solved)


def test_changed_dofs_are_the_new_unknowns_and_their_neighbours(adaptive_qp):
    qp = adaptive_qp
    P = qp.multilevel.prolongations[-1].tocsr()
    idx = mg.changed_dofs(qp.A.tocsr(), P)
    injected = (np.diff(P.indptr) == 1) & (P.data[P.indptr[:-1]] == 1.0)
    new = np.flatnonzero(~injected)
    assert np.isin(new, idx).all() and len(new) < len(idx) < qp.n
    neighbours = np.unique(qp.A.tocsr()[new].indices)
    np.testing.assert_array_equal(idx, np.union1d(new, neighbours))


def test_local_vcycle_is_spd_with_bounded_kappa_at_less_work(adaptive_qp):
    qp = adaptive_qp
    local, full = _vcycle(qp, "local"), _vcycle(qp, "full")
    assert len(local.ml.levels) == 9
    rng = np.random.default_rng(2)
    x, y = rng.standard_normal((2, qp.n))
    Vx, Vy = local.vcycle_once(x), local.vcycle_once(y)
    assert abs(x @ Vy - y @ Vx) <= 1e-10 * abs(x @ Vy)        # symmetric
    assert x @ Vx > 0 and y @ Vy > 0
    apply_A = lambda v: qp.A @ v                               # noqa: E731
    lo_l, hi_l = mg.lanczos_extremes(apply_A, qp.n, 40, local.vcycle_once)
    lo_f, hi_f = mg.lanczos_extremes(apply_A, qp.n, 40, full.vcycle_once)
    assert hi_l / lo_l <= 1.25 * hi_f / lo_f and hi_l / lo_l < 3.5
    assert local.smoothing_work() < 0.75 * full.smoothing_work()


def test_alg84_with_local_smoothing_converges_on_the_adaptive_mesh(adaptive_qp):
    res = solve(adaptive_qp, "augmented_projection", tol="mid")
    assert res.status == "converged" and res.kkt.max <= 1e-6
    assert res.stats["smoothing_work"] < 2.5
