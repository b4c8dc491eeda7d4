"""Friction in 3D: the cube-sphere scene's tangential rows (two per constrained node),
the isotropic friction data (norms, the disc projection, stick/slip states, the KKT
residuals) and the sphere's Cattaneo-Mindlin reference."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from problems.fem.contact import tangent_directions
from problems.friction.residuals import friction_residuals, tresca_energy
from problems.qp import QPValidationError
from problems.spec import problems
from reference.cattaneo_mindlin import stick_zone_ratio, stick_zone_size, tangential_traction

SCENE = problems()["cube_sphere"]


@pytest.fixture(scope="module")
def cube():
    return SCENE.make(0, friction="tresca", mu=0.5, shift=0.01)


def _same_csr(X, Y):
    X, Y = X.tocsr(), Y.tocsr()
    return (X.shape == Y.shape and np.array_equal(X.indptr, Y.indptr)
            and np.array_equal(X.indices, Y.indices) and np.array_equal(X.data, Y.data))


def test_tangents_are_an_orthonormal_frame_with_the_normal():
    rng = np.random.default_rng(3)
    n = rng.normal(size=(200, 3))
    n[:3] = [[0, 0, 1], [1, 0, 0], [0.6, 0.8, 0]]          # along z, along x, in the plane
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    t = tangent_directions(n).reshape(-1, 2, 3)
    frame = np.concatenate([t, n[:, None, :]], axis=1)       # rows t1, t2, n
    assert np.allclose(frame @ frame.transpose(0, 2, 1), np.eye(3), atol=1e-14)
    assert np.allclose(np.linalg.det(frame), 1.0)           # right-handed
    assert np.allclose(t[0], [[1, 0, 0], [0, 1, 0]])         # n = z: the x and y axes


def test_friction_none_leaves_the_cube_sphere_problem_unchanged(cube):
    plain = SCENE.make(0)
    assert plain.friction is None
    normal = cube.friction.path[0]
    assert _same_csr(plain.A, cube.A) and _same_csr(plain.B, cube.B)
    assert np.array_equal(plain.f, normal.f) and np.array_equal(plain.g, normal.g)
    tangential = cube.friction.path[1]
    assert np.array_equal(normal.g, tangential.g)            # the shift is along x only
    assert not np.array_equal(normal.f, tangential.f)             # another load


def test_two_tangential_rows_per_node_measure_relative_displacement(cube):
    fr = cube.friction
    m = cube.m
    assert fr.components == 2 and fr.T.shape == (2 * m, cube.n)
    assert fr.tangent.shape == (2 * m, 3) and fr.slip_bound.shape == (m,)
    dof = cube.free_dofs
    comp, body = dof % 3, cube.mesh.body_of_node[dof // 3]
    both = np.where(comp == 0, 0.25, 0.0)                    # both bodies move along x
    assert np.allclose(fr.T @ both, 0.0, atol=1e-14)
    ball = cube.mesh.bodies.index("ball")
    ball_x = np.where((comp == 0) & (body == ball), 1.0, 0.0)
    ball_y = np.where((comp == 1) & (body == ball), 1.0, 0.0)
    # the cube's nodes are P, the ball's facet the opposing point: slip = -t . e
    assert np.allclose(fr.blocks(fr.T @ ball_x), [-1.0, 0.0], atol=1e-14)
    assert np.allclose(fr.blocks(fr.T @ ball_y), [0.0, -1.0], atol=1e-14)
    assert np.allclose(cube.B @ ball_x, 0.0, atol=1e-14)     # no normal part


def test_norms_projection_and_states_are_isotropic(cube):
    fr = replace(cube.friction, slip_bound=np.full(cube.m, 2.0))
    rng = np.random.default_rng(0)
    lam = rng.normal(size=2 * cube.m) * 2.0
    size = fr.magnitude(lam)
    assert np.allclose(size, np.hypot(lam[0::2], lam[1::2]))
    inside = fr.clip(lam)
    assert np.all(fr.magnitude(inside) <= 2.0 * (1 + 1e-15))
    kept = size <= 2.0
    assert np.array_equal(fr.blocks(inside)[kept], fr.blocks(lam)[kept])
    # projected radially: the direction of each clipped vector is kept
    cos = fr.inner(inside, lam) / (fr.magnitude(inside) * size)
    assert np.allclose(cos, 1.0)
    states = fr.states(inside, 1e-9)
    assert set(states[kept]) == {"stick"} and set(states[~kept]) == {"slip"}
    # a rotation of every node's tangential vector changes neither norm nor state
    c, s = np.cos(0.7), np.sin(0.7)
    turned = (fr.blocks(inside) @ np.array([[c, s], [-s, c]])).ravel()
    assert np.allclose(fr.magnitude(turned), fr.magnitude(inside))
    assert np.array_equal(fr.states(turned, 1e-9), states)


def test_friction_residuals_measure_the_disc_conditions(cube):
    fr = replace(cube.friction, slip_bound=np.full(cube.m, 1.0))
    qp = replace(cube, friction=fr)
    u = np.zeros(qp.n)
    slip = fr.slip(u)                        # the unloaded state: zero slip
    assert np.all(slip == 0.0)
    lam = np.tile([0.6, 0.8], qp.m)          # on the circle |lam_i| = 1
    r = friction_residuals(qp, u, np.zeros(qp.m), lam)
    assert r.raw["bound"] < 1e-15 and r.raw["slip_complementarity"] == 0.0
    r = friction_residuals(qp, u, np.zeros(qp.m), 1.5 * lam)
    assert r.raw["bound"] == pytest.approx(0.5)
    # slipping against its force: lam . slip = -s |slip| while s |slip| is wanted
    prev = replace(fr, previous=-1e-3 * np.tile([0.6, 0.8], qp.m))   # slip = +1e-3 (0.6, 0.8)
    r = friction_residuals(replace(qp, friction=prev), u, np.zeros(qp.m), -lam)
    assert r.raw["slip_complementarity"] == pytest.approx(2 * 1e-3 * qp.m)
    assert tresca_energy(replace(qp, friction=prev), u) == pytest.approx(1e-3 * qp.m)


def test_friction_data_of_the_wrong_shape_is_refused_by_name(cube):
    fr = cube.friction
    with pytest.raises(QPValidationError, match=r"friction.T must have shape \(%d" % (2 * cube.m)):
        replace(cube, friction=replace(fr, T=fr.T[0::2]))
    with pytest.raises(QPValidationError, match="friction.previous"):
        replace(cube, friction=replace(fr, previous=np.zeros(cube.m)))
    with pytest.raises(QPValidationError, match="friction.tangent"):
        replace(cube, friction=replace(fr, tangent=fr.tangent[0::2]))


def test_sphere_stick_zone_from_mindlin_forces():
    """The moment estimates recover a and c of the sphere's Mindlin tractions."""
    assert stick_zone_ratio(0.3, "point") == pytest.approx(0.7 ** (1 / 3))
    assert stick_zone_ratio(0.3) == pytest.approx(0.7 ** 0.5)
    with pytest.raises(ValueError, match="kind"):
        stick_zone_ratio(0.3, "plane")
    h, a, mu = 0.002, 0.3, 0.5                                   # p0 = 1
    g = np.arange(-0.4, 0.4 + h / 2, h)
    x = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2) + [0.013, -0.007]
    r = np.linalg.norm(x - [0.013, -0.007], axis=1)
    p = np.sqrt(np.clip(1 - (r / a) ** 2, 0, None)) * h * h      # nodal normal forces
    c = a * stick_zone_ratio(0.3, "point")
    q = tangential_traction(r, a, c, mu) * h * h                 # |lam|, mu p0 = mu
    a_est, c_est = stick_zone_size(x, p, q, mu * p, kind="point")
    assert a_est == pytest.approx(a, rel=2e-3)
    assert c_est == pytest.approx(c, rel=5e-3)
