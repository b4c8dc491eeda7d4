"""The cube-sphere scene (Sect. 9.2) end to end: meshes, Alg. 7.1 on this geometry, force
balance, independent solvers, and 3D Hertz at a resolved level."""
import numpy as np
import pytest

from problems.cube_sphere import PROBLEM, ball_meshes, cube_meshes
from problems.fem.contact import contact_constraints
from problems.fem.elasticity import boundary_facets, stiffness_matrix
from problems.fem.fields import hertz_comparison
from problems.fem.mesh import tet_quality
from problems.kkt import energy_error
from solvers.interface import solve
from solvers.reference import reference_solve
from test_contact import brute_force, closest_on_triangle

R = 0.866
CENTER = np.array([0.5, 0.5, 1 + R])


@pytest.fixture(scope="module")
def level1():
    qp = PROBLEM.make(1)
    return qp, solve(qp, "pdas", tol=1e-12)


def test_sizes_match_table_9_3():
    for level, (nodes, NC) in {1: (2482, 81), 2: (18018, 289)}.items():
        qp = PROBLEM.make(level)
        assert qp.m == NC
        assert abs(qp.n_nodes / nodes - 1) < 0.1          # 2691 and 18360 nodes


def test_meshes_are_nested_valid_and_on_the_sphere():
    cubes, balls = cube_meshes(2), ball_meshes(2, CENTER, R)
    for k in range(3):
        for pts, cells in ((cubes.points[k], cubes.cells[k]), (balls.points[k], balls.cells[k])):
            q = tet_quality(pts, cells)
            assert q["min_volume"] > 0 and q["min_dihedral"] > 15 and q["max_dihedral"] < 160
        bnd = np.unique(boundary_facets(balls.cells[k]))
        np.testing.assert_allclose(np.linalg.norm(balls.points[k][bnd] - CENTER, axis=1), R,
                                   rtol=1e-12)
        vol = lambda p, c: np.abs(np.einsum("ij,ij->i", np.cross(p[c[:, 1]] - p[c[:, 0]],
                                  p[c[:, 2]] - p[c[:, 0]]), p[c[:, 3]] - p[c[:, 0]])).sum() / 6
        assert vol(cubes.points[k], cubes.cells[k]) == pytest.approx(1.0, rel=1e-12)
        assert vol(balls.points[k], balls.cells[k]) == pytest.approx(4 / 3 * np.pi * R ** 3,
                                                                     rel=0.03 / 4 ** k)
    # the prolongations interpolate linear functions exactly (nested P1 spaces), except
    # at the ball's new boundary nodes, which the projection moved onto the sphere
    lin = lambda p: 1 + p @ np.array([2.0, -1.0, 0.5])
    for h in (cubes, balls):
        for k, P in enumerate(h.prolongations):
            fine = h.points[k + 1]
            moved = np.abs(P @ h.points[k] - fine).max(axis=1) > 1e-14
            boundary = np.zeros(len(fine), dtype=bool)
            boundary[np.unique(boundary_facets(h.cells[k + 1]))] = True
            assert not moved.any() if h is cubes else (moved.any() and not moved[~boundary].any())
            np.testing.assert_allclose((P @ lin(h.points[k]))[~moved], lin(fine)[~moved],
                                       atol=1e-12)
            on_sphere = np.isclose(np.linalg.norm(fine[moved] - CENTER, axis=1), R, rtol=1e-12)
            assert on_sphere.all()


@pytest.mark.parametrize("search", ["along_direction", "closest_point"])
def test_constraints_on_this_geometry_match_brute_force(level1, search):
    qp = level1[0]
    pts, nodes, facets = qp.mesh.points, qp.contact.nodes, qp.contact.opposing_facets
    cc = contact_constraints(pts, nodes, facets, direction=[0.0, 0.0, 1.0], search=search)
    assert cc.found.all() and cc.m == 81
    if search == "along_direction":
        ref = brute_force(pts, nodes, facets, "b", dirs=np.tile([0.0, 0.0, 1.0], (len(nodes), 1)))
        for i, (key, f, g, w) in enumerate(ref):
            np.testing.assert_allclose(cc.g[i], g, atol=1e-12)
            np.testing.assert_allclose(cc.target[i], w @ pts[facets[f]], atol=1e-12)
    else:
        for i, p in enumerate(pts[nodes]):
            ws = [closest_on_triangle(p, *pts[t]) for t in facets]
            d = [np.linalg.norm(p - w @ pts[t]) for w, t in zip(ws, facets)]
            j = int(np.argmin(d))
            np.testing.assert_allclose(abs(cc.g[i]), d[j], atol=1e-12)
            np.testing.assert_allclose(cc.target[i], ws[j] @ pts[facets[j]], atol=1e-12)
        assert np.all(cc.g >= -1e-12)                  # nothing penetrates before loading
    # the gap below the pole is zero: the ball touches the cube at (0.5, 0.5, 1)
    centre = np.argmin(np.linalg.norm(pts[nodes, :2] - 0.5, axis=1))
    assert abs(cc.g[centre]) < 1e-12


def test_contact_force_equals_the_reaction_of_the_clamped_cube(level1):
    qp, res = level1
    mesh = qp.mesh
    on_cube = mesh.body_of_node[mesh.cells[:, 0]] == 0
    K = stiffness_matrix(mesh.points, mesh.cells[on_cube], 1.0, 0.3)
    u = qp.full_displacement(res.u).ravel()
    bottom = np.flatnonzero((mesh.body_of_node == 0) & np.isclose(mesh.points[:, 2], 0.0))
    reaction = (K @ u).reshape(-1, 3)[bottom].sum(axis=0)
    force = (res.p[:, None] * qp.contact.direction).sum(axis=0)
    assert res.status == "converged" and res.p.sum() > 1e-3
    np.testing.assert_allclose(reaction, force, rtol=1e-9, atol=1e-12 * res.p.sum())


def test_two_independent_solvers_agree(level1):
    qp, ref = level1
    for solver in ("osqp", "augmented_projection"):
        res = solve(qp, solver, tol="high")
        assert res.status == "converged", (solver, res.message)
        assert energy_error(qp, res.u, ref.u) < 1e-6
        np.testing.assert_allclose(res.p, ref.p, atol=1e-6 * ref.p.max())


def test_body_order_and_search_do_not_change_the_answer(level1):
    qp, res = level1
    swapped = PROBLEM.make(1, order="ball_first")
    res2 = solve(swapped, "pdas", tol=1e-12)
    x1, x2 = qp.constrained_points(), swapped.constrained_points()
    np.testing.assert_allclose(x1, x2)          # rows sorted by coordinates in both
    np.testing.assert_allclose(res2.p, res.p, rtol=1e-9, atol=1e-14)
    a = solve(PROBLEM.make(1, search="closest_point"), "pdas", tol=1e-12)
    assert abs(a.p.sum() / res.p.sum() - 1) < 0.02


def test_hertz_in_3d_at_a_resolved_level():
    """Level 3: 8.7 constrained nodes across the contact radius; the iterative reference
    (TNNMG to verified KKT and certified bound <= 1e-10) since a factorisation is too
    costly."""
    qp = PROBLEM.make(3)
    res = reference_solve(qp, tol=1e-10)
    assert res.solver == "tnnmg" and res.status == "converged"
    h = hertz_comparison(qp, res.p)
    assert h["a_over_h"] >= 8
    for key in ("dev_a_moment", "dev_p0_moment", "dev_a_fit", "dev_p0_fit"):
        assert abs(h[key]) < 0.05, (key, h[key])


def test_reference_beyond_the_direct_limit_is_the_verified_iterative_solve(level1, monkeypatch):
    import solvers.reference as reference
    qp, exact = level1
    assert reference.reference_solve(qp).solver == "pdas"            # 7137 unknowns: direct
    monkeypatch.setitem(reference.DIRECT_REFERENCE_LIMIT, 3, 1000)
    ref = reference.reference_solve(qp)
    assert ref.solver == "tnnmg" and ref.status == "converged"
    assert ref.kkt.max <= 1e-10 and energy_error(qp, ref.u, exact.u) < 1e-8
    # a problem TNNMG skips (a stabilisation block) goes to the augmented projection
    stabilised = PROBLEM.make(0, coupling="stabilised")
    monkeypatch.setitem(reference.DIRECT_REFERENCE_LIMIT, 3, 100)
    ref = reference.reference_solve(stabilised)
    assert ref.solver == "augmented_projection" and ref.status == "converged", ref.message
    assert ref.kkt.max <= 1e-10


def test_the_ball_is_meshed_once_per_process_and_each_caller_owns_its_copy():
    """netgen meshes a geometry once per process (the scene is built at every level and
    coupling of a study): the same arguments give the same mesh, a caller that changes
    its arrays does not change the next caller's, other arguments mesh anew, and bad
    ones still raise."""
    from problems.fem.mesh import netgen_ball

    first = netgen_ball((0.5, 0.5, 1.5), 0.5, 0.3)
    first[0][:] = 0.0
    again = netgen_ball(np.array([0.5, 0.5, 1.5]), 0.5, 0.3)
    assert np.linalg.norm(again[0] - [0.5, 0.5, 1.5], axis=1).max() == pytest.approx(0.5)
    other = netgen_ball((0.5, 0.5, 1.5), 0.5, 0.2)
    assert len(other[1]) > len(again[1])
    with pytest.raises(ValueError, match="radius"):
        netgen_ball((0.0, 0.0, 0.0), -1.0, 0.3)
