"""Adaptive refinement of Sect. 7.4: estimators, marking, bisection, the loop."""
import numpy as np
import pytest
import scipy.sparse as sp

from problems import circle_square, cube_sphere
from problems.fem.adaptive import (adaptive_loop, adaptive_start, mark_doerfler,
                                   mark_equidistribution, prolongate_solution)
from problems.fem.bisection import (bisect, boundary_measure, facet_counts, grow,
                                    label_longest_edge, min_angle, min_measure,
                                    parent_prolongation)
from problems.fem.elasticity import boundary_facets, lame_parameters
from problems.fem.estimators import (eta1_squared, eta2_squared, estimate, mesh_facets,
                                     penetrations)
from problems.fem.mesh import (Hierarchy, netgen_ball, netgen_disk, project_to_circle,
                               structured_cube, structured_square, tet_quality)
from problems.fem.surface import surface_levels
from problems.kkt import kkt_residuals
from solvers.augmented_projection import nested_initial_guess
from solvers.interface import solve

DISK = (np.array([0.5, 1.707]), 0.707)
BALL = (np.array([0.5, 0.5, 1.866]), 0.866)


def _affine(points, seed=0):
    rng = np.random.default_rng(seed)
    d = points.shape[1]
    G, b = rng.normal(size=(d, d)), rng.normal(size=d)
    return points @ G.T + b, G


def _smooth(x):
    cols = [np.sin(x[:, 0]) * x[:, 1] ** 2, np.cos(x[:, 1]) * x[:, 0]]
    if x.shape[1] == 3:
        cols.append(x[:, 2] ** 2 * x[:, 0])
    return np.stack(cols, axis=1)


def _near(points, cells, x0, factor=3.0):
    x = points[cells]
    n = cells.shape[1]
    h = np.max([np.linalg.norm(x[:, i] - x[:, j], axis=1) for i in range(n)
                for j in range(i + 1, n)], axis=0)
    return np.linalg.norm(x.mean(axis=1) - x0, axis=1) <= factor * h


# --------------------------------------------------------------------------- eta_T1
@pytest.mark.parametrize("dim", [2, 3])
def test_eta1_vanishes_for_a_linear_field_and_is_positive_otherwise(dim):
    p, c = structured_square(6) if dim == 2 else structured_cube(3)
    u, G = _affine(p)
    E, nu = 2.0, 0.3
    lam, mu = lame_parameters(E, nu)
    eps = 0.5 * (G + G.T)
    sigma = lam * np.trace(eps) * np.eye(dim) + 2 * mu * eps
    fc = mesh_facets(p, c)
    bnd = np.flatnonzero(~fc.interior)
    exact_traction = fc.normal[bnd] @ sigma.T                       # L = sigma n: consistent
    scale = np.sum(sigma ** 2)
    e = eta1_squared(p, c, u, E, nu, neumann=bnd, traction=exact_traction, facets=fc)
    assert e.max() < 1e-24 * scale
    # traction-free Neumann boundary: sigma n != 0 is a residual on boundary cells only
    e_free = eta1_squared(p, c, u, E, nu, neumann=bnd, facets=fc)
    on_bnd = np.zeros(len(c), dtype=bool)
    on_bnd[fc.cells[bnd, 0]] = True
    assert np.all(e_free[on_bnd] > 1e-6 * scale) and e_free[~on_bnd].max() < 1e-24 * scale
    # a body force: h_T^2 |f|^2 |T| on every cell
    e_f = eta1_squared(p, c, u, E, nu, body_force=np.ones(dim), facets=fc)
    assert np.all(e_f > 0)
    # a non-linear field jumps across interior facets
    e_q = eta1_squared(p, c, _smooth(p), E, nu, facets=fc)
    assert np.all(e_q > 0)


@pytest.mark.parametrize("dim, sizes", [(2, [16, 32]), (3, [8, 16])])
def test_eta1_scales_like_h_for_a_smooth_field(dim, sizes):
    """Interpolated smooth field, interior jumps only: [sigma n] ~ h, so
    eta_T^2 ~ h * h^2 * h^(d-1) = h^(d+2) and sum eta_T^2 ~ h^2."""
    gen = structured_square if dim == 2 else structured_cube
    tot, mx = [], []
    for n in sizes:
        p, c = gen(n)
        e = eta1_squared(p, c, _smooth(p), 1.0, 0.3)
        tot.append(e.sum())
        mx.append(e.max())
    assert tot[0] / tot[1] == pytest.approx(4.0, rel=0.1)
    assert mx[0] / mx[1] == pytest.approx(2.0 ** (dim + 2), rel=0.15)


# --------------------------------------------------------------------------- eta_T2
@pytest.fixture(scope="module")
def cs0():
    return circle_square.PROBLEM.make(0)


def test_eta2_zero_without_penetration(cs0):
    qp = cs0
    # touching (the circle's lowest node sits on the square) and undeformed
    assert np.all(eta2_squared(qp, np.zeros((qp.n_nodes, 2))) == 0)
    # separated by 0.05
    apart = circle_square.PROBLEM.make(0, gap=0.05)
    assert np.all(eta2_squared(apart, np.zeros((apart.n_nodes, 2))) == 0)


def test_eta2_measures_penetration_of_opposing_nodes(cs0):
    """The circle moved rigidly down by delta: every opposing node above the square's
    top edge with 1 - (y - delta) > 0 penetrates by exactly that much."""
    qp = cs0
    delta = 0.01
    u = np.zeros((qp.n_nodes, 2))
    circle = qp.mesh.body_of_node == 1
    u[circle, 1] = -delta
    pen = penetrations(qp, u)
    y = qp.mesh.points[pen.nodes, 1]
    np.testing.assert_allclose(pen.depth, np.maximum(0.0, 1.0 - (y - delta)), atol=1e-14)
    opp = np.unique(qp.contact.opposing_facets)
    x_opp = qp.mesh.points[opp]
    expected = opp[(x_opp[:, 1] - delta < 1.0) & (x_opp[:, 0] >= 0) & (x_opp[:, 0] <= 1)]
    assert set(pen.nodes[pen.depth > 0]) == set(expected) and expected.size >= 3
    e2 = eta2_squared(qp, u)
    assert e2.sum() == pytest.approx(np.sum(pen.depth ** 2), rel=1e-12)   # 2D: h^0
    hit = np.flatnonzero(e2 > 0)
    assert np.all(qp.mesh.body_of_node[qp.mesh.cells[hit, 0]] == 0)      # the square's cells
    top = qp.mesh.points[qp.mesh.cells[hit]][:, :, 1].max(axis=1)
    np.testing.assert_allclose(top, 1.0)                                 # at its top edge
    # each penetrating node counts once, on the cell below its foot point
    cen_x = qp.mesh.points[qp.mesh.cells[pen.cell]][:, :, 0]
    x_node = qp.mesh.points[pen.nodes, 0]
    assert np.all((cen_x.min(axis=1) <= x_node + 1e-12) & (x_node <= cen_x.max(axis=1) + 1e-12))


def test_estimate_on_a_solution(cs0):
    qp = cs0
    res = solve(qp, "pdas", tol=1e-10)
    est = estimate(qp, res.u, body_force=np.zeros(2))
    assert np.all(est["eta1_sq"] >= 0) and est["eta1_sq"].sum() > 0
    np.testing.assert_allclose(est["eta2"], est["eta1_sq"] + est["eta2_sq"])
    assert np.array_equal(estimate(qp, res.u, "eta1")["eta2"], est["eta1_sq"])
    with pytest.raises(ValueError, match="variant"):
        estimate(qp, res.u, "eta3")


# --------------------------------------------------------------------------- marking
def test_marking_rules():
    e = np.array([4.0, 3.0, 2.0, 1.0])
    assert mark_doerfler(e, 0.5).tolist() == [True, True, False, False]
    assert mark_doerfler(e, 0.4).tolist() == [True, False, False, False]
    assert mark_doerfler(e, 1.0).all()
    assert not mark_doerfler(np.zeros(3), 0.5).any()
    # eta_T^2 >= TOL / |tau_h| (Sect. 7.4 read as refining the large errors)
    assert mark_equidistribution(e, 4.0).tolist() == [True, True, True, True]     # share 1
    assert mark_equidistribution(e, 10.0).tolist() == [True, True, False, False]  # share 2.5
    assert mark_equidistribution(e, 12.0).tolist() == [True, True, False, False]  # share 3
    assert mark_equidistribution(e, 16.0).tolist() == [True, False, False, False]  # share 4
    with pytest.raises(ValueError, match="theta"):
        mark_doerfler(e, 1.5)
    # a minimum share of the cells, the largest errors first
    assert mark_doerfler(e, 0.4, min_fraction=0.5).tolist() == [True, True, False, False]
    assert mark_doerfler(e, 0.5, min_fraction=0.6).tolist() == [True, True, True, False]
    assert mark_doerfler(e, 0.5, min_fraction=0.1).tolist() == [True, True, False, False]
    with pytest.raises(ValueError, match="min_fraction"):
        mark_doerfler(e, 0.5, min_fraction=1.5)
    with pytest.raises(ValueError, match="tol"):
        mark_equidistribution(e, 0.0)


# --------------------------------------------------------------------------- refinement
@pytest.mark.parametrize("rule, dim", [("newest_vertex", 2), ("longest_edge", 2),
                                       ("longest_edge", 3)])
def test_bisection_is_conforming_and_nested_on_straight_domains(rule, dim):
    p, c = structured_square(8) if dim == 2 else structured_cube(3)
    if rule == "newest_vertex":
        c = label_longest_edge(p, c)
    x0 = np.array([0.5, 1.0]) if dim == 2 else np.array([0.5, 0.5, 1.0])
    bm0, vol0 = boundary_measure(p, c), 1.0
    for _ in range(5):
        ref = bisect(p, c, _near(p, c, x0), rule)
        assert np.array_equal(ref.points[:len(p)], p)                     # old nodes first
        np.testing.assert_allclose(ref.points[len(p):],
                                   0.5 * ref.points[ref.parents].sum(axis=1))
        u_c, _ = _affine(p)
        u_f, _ = _affine(ref.points)
        np.testing.assert_allclose(ref.prolongation @ u_c, u_f, atol=1e-13)   # P1 exact
        p, c = ref.points, ref.cells
        counts = facet_counts(c)
        assert counts.max() == 2                                          # conforming
        assert boundary_measure(p, c) == pytest.approx(bm0, rel=1e-12)     # no hanging node
        assert min_measure(p, c) > 0 if dim == 3 else np.abs(min_measure(p, c)) > 0
        x = p[c]
        vol = np.abs(np.linalg.det(x[:, 1:] - x[:, :1])).sum() / (2 if dim == 2 else 6)
        assert vol == pytest.approx(vol0, rel=1e-12)
    assert len(p) > (81 if dim == 2 else 64) + 40                          # it did refine
    q = min_angle(p, c) if dim == 2 else tet_quality(p, c)["min_dihedral"]
    assert q >= 44.9                                                       # Kuhn meshes stay 45 deg


@pytest.mark.parametrize("dim", [2, 3])
def test_bisection_keeps_curved_boundary_nodes_on_the_circle_or_sphere(dim):
    center, radius = DISK if dim == 2 else BALL
    p, c = netgen_disk(center, radius, 0.1) if dim == 2 else netgen_ball(center, radius, 0.3)
    rule = "newest_vertex" if dim == 2 else "longest_edge"
    if dim == 2:
        c = label_longest_edge(p, c)
    x0 = center - radius * np.eye(dim)[-1]
    proj = project_to_circle(center, radius)
    q0 = min_angle(p, c) if dim == 2 else tet_quality(p, c)["min_dihedral"]
    n_moved = 0
    for _ in range(3):
        ref = bisect(p, c, _near(p, c, x0), rule, project=proj)
        f = ref.points
        bnd = np.unique(boundary_facets(ref.cells))
        np.testing.assert_allclose(np.linalg.norm(f[bnd] - center, axis=1), radius, rtol=1e-12)
        assert facet_counts(ref.cells).max() == 2
        # nested: P1 interpolation of a linear field is exact except at projected nodes
        moved = np.zeros(len(f), dtype=bool)
        moved[bnd] = True
        moved[:len(p)] = False
        u_c, _ = _affine(p)
        u_f, _ = _affine(f)
        err = np.abs(ref.prolongation @ u_c - u_f).max(axis=1)
        assert err[~moved].max() < 1e-12
        n_moved += moved.sum()
        p, c = f, ref.cells
    assert n_moved > 0                                                     # projection happened
    assert min_measure(p, c) > 0                                           # no inverted cell
    q = min_angle(p, c) if dim == 2 else tet_quality(p, c)["min_dihedral"]
    assert q > 0.6 * q0


def test_parent_prolongation_composes_generations_and_grow_keeps_levels():
    # node 3 = mid(0, 1), node 4 = mid(3, 2): a second generation inside one call
    P = parent_prolongation(3, np.array([[0, 1], [2, 3]])).toarray()
    np.testing.assert_allclose(P[3], [0.5, 0.5, 0])
    np.testing.assert_allclose(P[4], [0.25, 0.25, 0.5])
    with pytest.raises(ValueError, match="parents"):
        parent_prolongation(3, np.array([[0, 4], [0, 1]]))
    p, c = structured_square(2)
    h = Hierarchy([p], [label_longest_edge(p, c)], [])
    h1 = grow(h, np.zeros(len(c), dtype=bool))
    assert len(h1.points) == 2 and len(h.points) == 1
    assert (h1.prolongations[0] != sp.identity(len(p))).nnz == 0
    h2 = grow(h1, [0])
    assert len(h2.points) == 3 and h2.prolongations[1].shape == (len(h2.points[2]), len(p))
    with pytest.raises(ValueError, match="rule"):
        bisect(*structured_cube(1), [0], rule="newest_vertex")


# --------------------------------------------------------------------------- the loop
def _circle_square_start(level):
    opts = circle_square.PROBLEM.options()
    make, meshes = adaptive_start(circle_square.scene(level, opts), level)
    proj = (None, project_to_circle(np.array([0.5, 1.0 + opts.radius]), opts.radius))
    return make, meshes, proj


def _pdas(qp, u0, p0):
    return solve(qp, "pdas", tol=1e-10, u0=u0, p0=p0)


@pytest.fixture(scope="module")
def cs_run():
    make, meshes, proj = _circle_square_start(0)
    return adaptive_loop(make, meshes, _pdas, max_steps=3, project=proj)


def test_adaptive_loop_refines_near_the_contact_zone(cs_run):
    run = cs_run
    recs = run.records
    assert len(recs) == 4 and run.stop_reason == "max_steps"
    assert [r.level for r in recs] == [0, 1, 2, 3]
    assert all(b.N > a.N for a, b in zip(recs[:-1], recs[1:]))
    assert recs[-1].NC > recs[0].NC                        # the top edge got finer too
    assert recs[-1].sum_eta2 < 0.5 * recs[0].sum_eta2
    qp, (_, p) = run.qps[-1], run.solutions[-1]
    x_active = qp.mesh.points[qp.contact.nodes[p > 0], 0]
    a = 0.5 * np.ptp(x_active)                             # contact half-width, measured
    assert 0.05 < a < 0.2 and np.mean(x_active) == pytest.approx(0.5, abs=0.02)
    for qp, m in zip(run.qps[:-1], run.marked[:-1]):
        cen = qp.mesh.points[qp.mesh.cells[m]].mean(axis=1)
        near = np.linalg.norm(cen - [0.5, 1.0], axis=1) < 3 * a
        assert m.size > 0 and near.mean() > 0.8
    for qp, (u, p) in zip(run.qps, run.solutions):
        assert kkt_residuals(qp, u, p).max < 1e-9
        assert facet_counts(qp.mesh.cells).max() == 2
    # the circle's boundary stays on the circle, the square's top edge is nested
    qp = run.qps[-1]
    circle = qp.mesh.body_of_node == 1
    cells = qp.mesh.cells[circle[qp.mesh.cells[:, 0]]]
    bnd = np.unique(boundary_facets(cells))
    np.testing.assert_allclose(np.linalg.norm(qp.mesh.points[bnd] - DISK[0], axis=1), DISK[1],
                               rtol=1e-9)
    s = qp.multilevel.surface
    assert s.n_levels == len(s.prolongations) + 1 and len(s.masses[-1]) == qp.m
    assert len(qp.multilevel.prolongations) == 3


def test_surface_levels_accept_the_adaptive_surfaces(cs_run):
    """The constrained surface of every adaptive level interpolates from the previous one."""
    qps = cs_run.qps
    node_P = [sp.block_diag([h.prolongations[k] for h in cs_run.meshes]) for k in range(3)]
    s = surface_levels(node_P, [q.contact.nodes for q in qps], [q.contact.mass for q in qps],
                       [np.ones(q.m) for q in qps])
    for k, P in enumerate(s.prolongations):
        x_c = qps[k].mesh.points[qps[k].contact.nodes, 0]
        x_f = qps[k + 1].mesh.points[qps[k + 1].contact.nodes, 0]
        np.testing.assert_allclose(P @ x_c, x_f, atol=1e-14)


def test_adaptive_level_pdas_and_augmented_projection_agree(cs_run):
    qp = cs_run.qps[-1]
    u_ref, p_ref = cs_run.solutions[-1]
    res = solve(qp, "augmented_projection", tol=1e-9)
    assert res.status == "converged"
    e = res.u - u_ref
    assert np.sqrt(e @ (qp.A @ e) / (u_ref @ (qp.A @ u_ref))) < 1e-6
    assert np.abs(res.p - p_ref).max() < 1e-5 * np.abs(p_ref).max()


def test_nested_start_is_alg_8_5_and_cuts_outer_steps():
    make, meshes, proj = _circle_square_start(1)
    runs = {}
    for nested in (True, False):
        runs[nested] = adaptive_loop(
            make, meshes,
            lambda qp, u0, p0: solve(qp, "augmented_projection", tol=1e-6, u0=u0, p0=p0),
            max_steps=2, project=proj, nested=nested)
    it = {k: [r.iterations for r in v.records] for k, v in runs.items()}
    assert [r.N for r in runs[True].records] == [r.N for r in runs[False].records]
    assert sum(it[True][1:]) < 0.85 * sum(it[False][1:]), it
    assert all(r.kkt_max <= 1e-6 for v in runs.values() for r in v.records)
    # the multiplier start is that of solvers.augmented_projection.nested_initial_guess
    run = runs[True]
    q0, q1 = run.qps[0], run.qps[1]
    u, p = run.solutions[0]
    u_a, p_a = nested_initial_guess(q0, (u, p), q1)
    u_b, p_b = prolongate_solution(q0, u, p, q1)
    np.testing.assert_array_equal(p_a, p_b)
    np.testing.assert_array_equal(u_a, u_b)


def test_adaptive_loop_in_3d_and_stopping_rules():
    opts = cube_sphere.PROBLEM.options()
    make, meshes = adaptive_start(cube_sphere.scene(0, opts), 0)
    center = np.array([0.5, 0.5, 1.0 + opts.radius])
    proj = (None, project_to_circle(center, opts.radius))
    run = adaptive_loop(make, meshes, _pdas, max_steps=5, max_nodes=480, project=proj)
    assert run.stop_reason == "max_nodes" and run.records[-1].N >= 480
    assert len(run.records) >= 2
    for qp, (u, p), m in zip(run.qps, run.solutions, run.marked):
        assert kkt_residuals(qp, u, p).max < 1e-9
        assert facet_counts(qp.mesh.cells).max() == 2
        assert tet_quality(qp.mesh.points, qp.mesh.cells)["min_volume"] > 0
    m = run.marked[0]
    cen = run.qps[0].mesh.points[run.qps[0].mesh.cells[m]].mean(axis=1)
    assert np.mean(np.linalg.norm(cen - [0.5, 0.5, 1.0], axis=1) < 0.4) > 0.8
    tol_run = adaptive_loop(make, meshes, _pdas, max_steps=5, tol=1.0, project=proj)
    assert tol_run.stop_reason == "tol" and len(tol_run.records) == 1
    with pytest.raises(ValueError, match="estimator"):
        adaptive_loop(make, meshes, _pdas, estimator="eta2")
