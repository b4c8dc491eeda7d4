"""Semicoarsening multigrid on the roll stack's extruded meshes.

The roll stack's levels are separate meshes (no refinement hierarchy), each roll one
section extruded along ``x`` with cells up to 25:1 long along the axis. Its V-cycle
coarsens along ``x`` and smooths whole sections
(:func:`solvers.kernels.multigrid.layered_hierarchy`); these tests check the layers it
reads off the mesh, the interpolation between layers,
that the cycle is a symmetric positive definite preconditioner whose ``kappa(V A)`` stays
bounded from level 0 to 1 where smoothed aggregation's grows past 100, the Lanczos
bounds on a floating body's complement. Alg. 8.4 with this cycle on the floating roll:
``tests/test_roll_stack_study.py`` (levels 0 and 1).
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

import solvers.kernels.multigrid as mg
from problems.fem.mesh import extrusion_layers
from problems.spec import ParameterError, problems
from solvers.augmented_projection import floating_coarse_space
from solvers.interface import solve


@pytest.fixture(scope="module")
def stacks():
    spec = problems()["roll_stack"]
    return {level: spec.make(level) for level in (0, 1)}


def _complement_pencil(qp):
    """``C A C`` and the projection ``C`` onto the complement of the floating modes."""
    R = floating_coarse_space(qp).R
    C = lambda x: x - R @ (R.T @ x)                   # noqa: E731
    return (lambda x: C(qp.A @ C(x))), C


def test_layers_are_read_off_the_mesh(stacks):
    qp = stacks[0]
    ext = qp.multilevel.extrusion
    points = qp.mesh.points[qp.free_dofs // 3]
    assert np.allclose(points[:, 0], ext.layer_coordinate[ext.layer_of_dof])
    # copies of one section unknown: the same component, and the same direction from the
    # roll's axis (the section is scaled radially per layer: crown, relief, necks)
    assert np.all(ext.section_dof % 3 == qp.free_dofs % 3)
    z_axis = np.where(qp.multilevel.body_of_dof == 1, 0.35 + 0.75, 0.0)
    angle = np.arctan2(points[:, 1], points[:, 2] - z_axis)
    radius = np.hypot(points[:, 1], points[:, 2] - z_axis)
    order = np.argsort(ext.section_dof, kind="stable")
    keys, starts = np.unique(ext.section_dof[order], return_index=True)
    first = np.repeat(order[starts], np.diff(np.append(starts, len(order))))
    on_axis = (radius[order] < 1e-9) & (radius[first] < 1e-9)
    assert np.all(on_axis | (np.abs(angle[order] - angle[first]) < 1e-9))
    assert len(ext.body_layers) == 2
    for layers in ext.body_layers:
        assert np.all(np.diff(ext.layer_coordinate[layers]) > 0)
    # a mesh that is not extruded is refused by name
    cs = problems()["circle_square"].make(0)
    with pytest.raises(ValueError, match="not numbered layer by layer"):
        extrusion_layers(cs.mesh.points, cs.mesh.body_of_node, cs.free_dofs, 2)
    assert cs.multilevel.extrusion is None
    assert problems()["roll_stack"].make(0, degree=2).multilevel.extrusion is None


def test_semicoarsening_interpolates_linearly_between_kept_layers(stacks):
    ext = stacks[1].multilevel.extrusion
    P, kept, coarse = mg.semicoarsening(ext)
    assert P.shape == (len(ext.layer_of_dof), len(kept))
    assert abs(P[kept] - sp.identity(len(kept))).max() == 0.0
    for fine, rough in zip(ext.body_layers, coarse.body_layers):
        assert rough[0] == fine[0] and rough[-1] == fine[-1]
        assert len(rough) == (len(fine) + 2) // 2
    # a field affine in x on each section unknown is reproduced wherever both neighbours'
    # copies are unknowns (elsewhere the missing copy is a Dirichlet zero)
    x = ext.layer_coordinate[ext.layer_of_dof]
    u = (1.0 + ext.section_dof % 7) * (2.0 - 3.0 * x) + 0.1 * ext.section_dof
    full = np.isclose(np.asarray(P.sum(axis=1)).ravel(), 1.0)
    assert full.mean() > 0.9
    assert np.allclose((P @ u[kept])[full], u[full], rtol=0, atol=1e-12 * np.abs(u).max())
    assert np.all(np.asarray(P.sum(axis=1)).ravel() <= 1.0 + 1e-12)


def test_layered_vcycle_is_spd_and_bounded_where_aggregation_is_not(stacks):
    """kappa(V A) on the complement of the floating roll: about 3.7 at levels 0 and 1
    for the layered cycle (measured 3.5 at level 2, 3.35 at level 3), against 150 for
    smoothed aggregation at level 1."""
    kappas = {}
    for level, qp in stacks.items():
        vc = mg.vcycle(qp.A, "layers", qp.multilevel, 3, qp.free_dofs, smoother="symmetric_gs",
                       sweeps=1)
        rng = np.random.default_rng(level)
        x, y = rng.standard_normal((2, qp.n))
        Vx, Vy = vc.vcycle_once(x), vc.vcycle_once(y)
        assert abs(y @ Vx - x @ Vy) <= 1e-10 * abs(x @ Vy)
        apply_A, C = _complement_pencil(qp)
        lo, hi = mg.lanczos_extremes(apply_A, qp.n, 30, lambda r: C(vc.vcycle_once(C(r))),
                                     project=C)
        assert 0.0 < lo and hi <= 1.0 + 1e-6          # symmetric GS: lambda(V A) in (0, 1]
        kappas[level] = hi / lo
        assert vc.ml.levels[-1].A.shape[0] < qp.n / 3
    assert max(kappas.values()) < 5.0
    assert kappas[1] < 1.1 * kappas[0]
    qp = stacks[1]
    sa = mg.vcycle(qp.A, "sa", qp.multilevel, 3, qp.free_dofs, smoother="symmetric_gs",
                   sweeps=1, max_coarse=500)
    apply_A, C = _complement_pencil(qp)
    lo, hi = mg.lanczos_extremes(apply_A, qp.n, 30, lambda r: C(sa.vcycle_once(C(r))),
                                 project=C)
    assert hi / lo > 10 * kappas[1]


def test_lanczos_projects_onto_the_pencils_subspace():
    """A pencil singular on one direction, and a preconditioner that is nearly exact
    elsewhere: unprojected, the recurrence's component on the null direction grows like
    the Lanczos polynomial at 0 and ruins the Ritz values; projected, they bound the
    true spectrum."""
    n = 400
    rng = np.random.default_rng(5)
    e = np.ones(n) / np.sqrt(n)                      # the null direction
    C = lambda x: x - e * (e @ x)                    # noqa: E731
    Q, _ = np.linalg.qr(np.column_stack([e, rng.standard_normal((n, n - 1))]))
    Q = Q[:, 1:]                                     # an orthonormal basis of the complement
    d = np.linspace(1.0, 1e4, n - 1)
    ratio = 1.0 + 2.0 * rng.random(n - 1)            # lambda(M^-1 K) in [1, 3]
    K, Minv = (Q * d) @ Q.T, (Q * (ratio / d)) @ Q.T
    apply_K, apply_M = (lambda x: C(K @ C(x))), (lambda x: C(Minv @ C(x)))
    lo, hi = mg.lanczos_extremes(apply_K, n, 40, apply_M, seed=1, project=C)
    assert ratio.min() - 1e-8 <= lo <= ratio.min() * 1.05
    assert ratio.max() * 0.95 <= hi <= ratio.max() + 1e-8


def test_layered_cycle_is_refused_without_layers():
    qp = problems()["circle_square"].make(0)
    with pytest.raises(ParameterError, match="'ahat'.*extruded"):
        solve(qp, "augmented_projection", tol="mid", ahat="layers")
