"""The shared two-body machinery: springs, tractions and the assembled data on a scene."""
import numpy as np
import pytest

from problems.circle_square import PROBLEM, scene
from problems.fem.two_body import Springs, Traction, assemble_two_body, spring_forces
from solvers.interface import solve


def test_springs_carry_load_and_report_their_force():
    """Springs on the circle: their reported force is -k sum(u) over their nodes, and the
    circle's force balance (weight, springs, contact, held-arc reaction) closes."""
    from problems.fem.elasticity import body_force_vector, stiffness_matrix
    p = PROBLEM.options(held_arc=5.0, indent=0.0)
    sc = scene(1, p)
    circle = 1 - sc.constrained_body
    center = np.array([0.5, 1.707])
    near = lambda x: np.linalg.norm(x - center, axis=1) < 0.3
    sc.springs = [Springs(circle, near, 1e-3)]
    qp = assemble_two_body(sc, 1)
    res = solve(qp, "pdas", tol=1e-12)
    assert res.status == "converged"
    mesh, u = qp.mesh, qp.full_displacement(res.u)
    nodes = np.flatnonzero((mesh.body_of_node == circle) & near(mesh.points))
    f_spring = spring_forces(sc, qp, res.u)
    np.testing.assert_allclose(f_spring, -1e-3 * u[nodes].sum(axis=0), rtol=1e-12)
    contact = (res.p[:, None] * qp.contact.direction).sum(axis=0)   # on the circle, upward
    cells = mesh.cells[mesh.body_of_node[mesh.cells[:, 0]] == circle]
    K = stiffness_matrix(mesh.points, cells, 1.0, 0.3)
    f = body_force_vector(mesh.points, cells, [0.0, -p.load])
    held = np.setdiff1d(np.flatnonzero(np.repeat(mesh.body_of_node == circle, 2)), qp.free_dofs)
    reaction = (K @ u.ravel() - f)[held].reshape(-1, 2).sum(axis=0)
    weight = f.reshape(-1, 2).sum(axis=0)
    # K u - f = reaction on held DOFs; elsewhere the springs and the contact balance it
    np.testing.assert_allclose(weight + f_spring + contact + reaction, 0,
                               atol=1e-9 * abs(weight[1]))
    assert f_spring[1] > 0 and contact[1] > 0 and abs(f_spring[1]) > 0.01 * abs(weight[1])


def test_a_traction_enters_the_load():
    sc = scene(0, PROBLEM.options())
    base = assemble_two_body(sc, 0)
    sq = sc.constrained_body
    sc.tractions = [Traction(sq, lambda c: np.isclose(c[:, 0], 1.0), np.array([0.3, 0.0]))]
    loaded = assemble_two_body(sc, 0)
    df = (loaded.f - base.f).reshape(-1)
    # the traction (0.3, 0) on the square's right edge (length 1, bottom clamped) adds 0.3 in x
    full = np.zeros(loaded.u_fixed.size)
    full[loaded.free_dofs] = df
    assert full.reshape(-1, 2)[:, 0].sum() == pytest.approx(0.3 * (1 - 1 / 16 / 2), rel=1e-12)
    assert np.abs(full.reshape(-1, 2)[:, 1]).max() == 0
