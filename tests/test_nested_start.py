"""The start of nested iteration (Alg. 8.5) on uniform levels,
:func:`problems.qp.prolongate_displacement`: the coarser level's displacement interpolated
with its prescribed values, ``P u + P_D u_fixed``. A displacement linear in space, on
the free and the prescribed DOFs alike, is reproduced exactly at the finer free DOFs;
without the prescribed values' share it is not (the Dirichlet lift's layer), and the
start from a coarse solve is then as far from the answer on every level."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from problems.fem.mesh import midpoint_anchors
from problems.kkt import energy_error
from problems.qp import prolongate_displacement
from problems.spec import problems
from solvers.interface import solve


def _linear_field(qp, gradient):
    """A displacement ``u(x) = b + G x`` on every node of ``qp``, node-major."""
    b = np.arange(1.0, qp.dim + 1.0)
    return (qp.mesh.points @ gradient.T + b).ravel()


def _nested_nodes(coarse, fine):
    """The fine nodes that are a coarse node or a coarse edge's midpoint (same body)."""
    from scipy.spatial import cKDTree
    X = coarse.mesh.points
    edges, anchors = midpoint_anchors(X, coarse.mesh.cells)
    body = np.concatenate([coarse.mesh.body_of_node, coarse.mesh.body_of_node[edges[:, 0]]])
    tol = 1e-12 * np.ptp(X, axis=0).max()
    found = np.zeros(len(fine.mesh.points), bool)
    for k in np.unique(body):
        on = fine.mesh.body_of_node == k
        dist, _ = cKDTree(anchors[body == k]).query(fine.mesh.points[on])
        found[on] = dist <= tol
    return found


@pytest.mark.parametrize("scene", ["circle_square", "cube_sphere"])
def test_a_linear_displacement_is_reproduced_exactly(scene):
    coarse, fine = (problems()[scene].make(k) for k in (0, 1))
    rng = np.random.default_rng(7)
    G = rng.standard_normal((coarse.dim, coarse.dim))
    full_c, full_f = _linear_field(coarse, G), _linear_field(fine, G)
    fixed = np.ones(full_c.size, bool)
    fixed[coarse.free_dofs] = False
    assert fixed.any()
    # the coarse level as it would carry these prescribed values (zero at free DOFs)
    lifted = replace(coarse, u_fixed=np.where(fixed, full_c, 0.0))
    u0 = prolongate_displacement(lifted, full_c[coarse.free_dofs], fine)
    expected = full_f[fine.free_dofs]
    scale = np.abs(expected).max()
    # exact where the fine node is a coarse node or a coarse edge's midpoint (the
    # refinement moves the others onto the curved boundary)
    nested = np.repeat(_nested_nodes(coarse, fine), fine.dim)[fine.free_dofs]
    assert nested.mean() > 0.7
    np.testing.assert_allclose(u0[nested], expected[nested], rtol=0, atol=1e-13 * scale)
    # the free DOFs' share alone misses the nodes next to the prescribed ones
    free_only = fine.multilevel.prolongations[-1] @ full_c[coarse.free_dofs]
    assert np.abs(free_only - expected)[nested].max() > 0.1 * scale
    # P_D acts on the prescribed DOFs only
    P_D = fine.multilevel.prescribed_prolongation.tocsc()
    assert P_D.shape == (fine.n, full_c.size)
    assert np.diff(P_D.indptr)[coarse.free_dofs].max() == 0


def test_the_nested_start_is_close_and_closer_on_finer_levels():
    scene = problems()["circle_square"]
    qps = [scene.make(k) for k in (0, 1, 2)]
    results = [solve(q, "tnnmg", tol="high") for q in qps]
    assert all(r.status == "converged" for r in results)
    errors = [energy_error(f, prolongate_displacement(c, rc.u, f), rf.u)
              for c, f, rc, rf in zip(qps, qps[1:], results, results[1:])]
    # the P1 interpolation error of the solution, O(h): about 0.015 and 0.006; without the
    # prescribed values' share 0.7 on both levels
    assert errors[0] < 0.05 and errors[1] < 0.6 * errors[0]


def test_levels_that_do_not_follow_each_other_are_refused():
    scene = problems()["circle_square"]
    q0, q2 = scene.make(0), scene.make(2)
    with pytest.raises(ValueError, match="not consecutive levels"):
        prolongate_displacement(q0, np.zeros(q0.n), q2)
    with pytest.raises(ValueError, match="parameter 'qp_fine'"):
        prolongate_displacement(q0, np.zeros(q0.n), q0)
