"""Contact constraints B u <= g of Alg. 7.1 (problems/fem/contact.py).

Exact geometry where the answer is known, invariances (rotation, rigid
translation) and a brute-force all-pairs reference for the KD-tree search.
"""
import numpy as np
import pytest
import scipy.sparse as sp

from problems.fem.contact import (ContactConstraints, barycentric, contact_constraints,
                                  facet_normals, gap_after, orient_facets, restrict_to_free)

EPS = 1e-13


def polyline(x, y):
    """Points and segments (i, i+1) of a polyline; returns (points, segments)."""
    pts = np.column_stack([x, y])
    seg = np.column_stack([np.arange(len(x) - 1), np.arange(1, len(x))])
    return pts, seg


def two_bodies(lower_x, lower_y, upper_x, upper_y):
    """Constrained nodes on the lower curve, opposing segments of the upper one.

    The upper body lies above its polyline; segments run in +x, so their normal
    (dy, -dx) points down = out of the upper body.
    """
    lower_x, upper_x = np.asarray(lower_x, float), np.asarray(upper_x, float)
    lo = np.column_stack([lower_x, np.broadcast_to(lower_y, lower_x.shape)])
    up, seg = polyline(upper_x, np.broadcast_to(upper_y, upper_x.shape))
    points = np.vstack([lo, up])
    return points, np.arange(len(lo)), seg + len(lo)


def random_rotation(dim, rng):
    q, r = np.linalg.qr(rng.normal(size=(dim, dim)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


# --------------------------------------------------------------------------- 2D exact

@pytest.mark.parametrize("offset", [0.0, 0.13, -0.21])
def test_flat_on_flat_offset(offset):
    xs = np.array([0.1, 0.35, 0.6, 0.9])
    points, nodes, seg = two_bodies(xs, 0.9, np.array([0.0, 0.5, 1.0]) + offset, 1.0)
    cc = contact_constraints(points, nodes, seg, direction=[0.0, 1.0])
    assert isinstance(cc, ContactConstraints)
    inside = (xs >= offset) & (xs <= 1.0 + offset)
    np.testing.assert_array_equal(cc.found, inside)
    np.testing.assert_array_equal(cc.rows, nodes[inside])
    np.testing.assert_allclose(cc.g, 0.1, atol=EPS)
    x = xs[inside] - offset
    seg_id = np.where(x < 0.5, 0, 1)
    seg_id[x == 0.5] = 0                      # shared vertex: lowest facet id
    s = (x - 0.5 * seg_id) / 0.5
    np.testing.assert_array_equal(cc.facet, seg_id)
    np.testing.assert_allclose(cc.weights, np.column_stack([1 - s, s]), atol=EPS)
    np.testing.assert_allclose(cc.direction, [[0.0, 1.0]] * cc.m)
    # B rows: +n at P, -w_k n at the facet vertices (y components only)
    dense = cc.B.toarray()
    assert cc.B.shape == (cc.m, 2 * len(points))
    for i, (P, (a, b)) in enumerate(zip(cc.rows, cc.facet_nodes)):
        expect = np.zeros(2 * len(points))
        expect[2 * P + 1] = 1.0
        expect[2 * a + 1] -= cc.weights[i, 0]
        expect[2 * b + 1] -= cc.weights[i, 1]
        np.testing.assert_allclose(dense[i], expect, atol=EPS)


@pytest.mark.parametrize("theta", [0.2, -0.35])
def test_tilted_opposing_line(theta):
    xs = np.array([0.05, 0.3, 0.55, 0.8])
    ux = np.array([0.0, 0.4, 1.0])
    points, nodes, seg = two_bodies(xs, 0.9, ux, 1.0 + ux * np.tan(theta))
    # case b, n = (0, 1): Q = (x, 1 + x tan theta), g = 0.1 + x tan theta
    cc = contact_constraints(points, nodes, seg, direction=[0.0, 1.0])
    assert cc.found.all()
    np.testing.assert_allclose(cc.g, 0.1 + xs * np.tan(theta), atol=EPS)
    a = np.where(xs < 0.4, 0.0, 0.4)
    b = np.where(xs < 0.4, 0.4, 1.0)
    s = (xs - a) / (b - a)
    np.testing.assert_allclose(cc.weights, np.column_stack([1 - s, s]), atol=EPS)
    # case a: distance to the line, n = inward normal of the tilted line
    ca = contact_constraints(points, nodes, seg, search="closest_point")
    d = (1.0 + xs * np.tan(theta) - 0.9) * np.cos(theta)
    np.testing.assert_allclose(ca.g, d, atol=EPS)
    np.testing.assert_allclose(ca.direction, [[-np.sin(theta), np.cos(theta)]] * 4, atol=EPS)
    q = points[nodes] + d[:, None] * ca.direction
    np.testing.assert_allclose(ca.target, q, atol=EPS)
    qa = points[seg[ca.facet, 0]]
    qb = points[seg[ca.facet, 1]]
    s = np.einsum("pd,pd->p", q - qa, qb - qa) / np.einsum("pd,pd->p", qb - qa, qb - qa)
    np.testing.assert_allclose(ca.weights, np.column_stack([1 - s, s]), atol=EPS)


def test_penetration_gives_negative_gap():
    xs = np.array([0.2, 0.45, 0.7])
    points, nodes, seg = two_bodies(xs, 1.05, np.array([0.0, 0.5, 1.0]), 1.0)
    for kwargs in ({"direction": [0.0, 1.0]}, {"search": "closest_point"}):
        cc = contact_constraints(points, nodes, seg, **kwargs)
        np.testing.assert_allclose(cc.g, -0.05, atol=EPS)
        np.testing.assert_allclose(cc.direction, [[0.0, 1.0]] * 3, atol=EPS)
        # pushing the upper body up by 0.05 exactly closes the gap
        u = np.zeros_like(points)
        u[3:, 1] = 0.05
        np.testing.assert_allclose(gap_after(points, cc, u), 0.0, atol=EPS)


def test_node_on_surface_case_a():
    points, nodes, seg = two_bodies(np.array([0.25, 0.5]), 1.0, np.array([0.0, 0.5, 1.0]), 1.0)
    cc = contact_constraints(points, nodes, seg, search="closest_point")
    np.testing.assert_allclose(cc.g, 0.0, atol=EPS)
    np.testing.assert_allclose(cc.direction, [[0.0, 1.0]] * 2, atol=EPS)
    np.testing.assert_array_equal(cc.facet, [0, 0])       # shared vertex -> lowest id


def test_case_a_agrees_with_case_b_flat_on_flat():
    rng = np.random.default_rng(3)
    xs = np.sort(rng.uniform(0.05, 0.95, 12))
    ys = 0.9 + 0.0 * xs
    points, nodes, seg = two_bodies(xs, ys, np.linspace(0, 1, 7), 1.0)
    cb = contact_constraints(points, nodes, seg, direction=[0.0, 1.0])
    ca = contact_constraints(points, nodes, seg, search="closest_point")
    for field in ("rows", "g", "direction", "facet", "weights", "target", "found"):
        np.testing.assert_allclose(getattr(ca, field), getattr(cb, field), atol=EPS, err_msg=field)
    assert abs(ca.B - cb.B).max() < EPS


def test_misses_and_max_distance_are_dropped():
    xs = np.array([-0.5, 0.2, 0.6, 1.5])
    ys = np.array([0.9, 0.9, 0.5, 0.9])
    points, nodes, seg = two_bodies(xs, ys, np.array([0.0, 0.5, 1.0]), 1.0)
    cc = contact_constraints(points, nodes, seg, direction=[0.0, 1.0])
    np.testing.assert_array_equal(cc.found, [False, True, True, False])
    cc = contact_constraints(points, nodes, seg, direction=[0.0, 1.0], max_distance=0.2)
    np.testing.assert_array_equal(cc.found, [False, True, False, False])
    assert cc.B.shape == (1, 2 * len(points)) and cc.g.shape == (1,)
    # case a: every node has a closest point; max_distance drops the far ones
    ca = contact_constraints(points, nodes, seg, search="closest_point", max_distance=0.2)
    np.testing.assert_array_equal(ca.found, [False, True, False, False])
    # the direction parallel to the surface misses everything
    cc = contact_constraints(points, nodes, seg, direction=[1.0, 0.0])
    assert cc.m == 0 and cc.B.shape == (0, 2 * len(points)) and not cc.found.any()


def test_rigid_translation_is_free():
    rng = np.random.default_rng(0)
    xs = np.sort(rng.uniform(0.0, 1.0, 15))
    points, nodes, seg = two_bodies(xs, 0.8 + 0.05 * np.sin(7 * xs),
                                    np.linspace(-0.1, 1.1, 9), 1.0 + 0.1 * np.cos(np.linspace(0, 4, 9)))
    dirs = np.column_stack([0.3 * np.sin(5 * xs), np.ones_like(xs)])
    for kwargs in ({"direction": [0.2, 1.0]}, {"direction": dirs}, {"search": "closest_point"}):
        cc = contact_constraints(points, nodes, seg, **kwargs)
        assert cc.m == len(xs)
        np.testing.assert_allclose(cc.weights.sum(axis=1), 1.0, atol=EPS)
        t = rng.normal(size=2)
        np.testing.assert_allclose(cc.B @ np.tile(t, len(points)), 0.0, atol=1e-15)
        u = rng.normal(size=points.size)
        np.testing.assert_allclose(gap_after(points, cc, u), cc.g - cc.B @ u, atol=1e-13)


@pytest.mark.parametrize("search", ["closest_point", "along_direction"])
def test_rotation_invariance_2d(search):
    rng = np.random.default_rng(11)
    xs = np.sort(rng.uniform(0.05, 0.95, 10))
    points, nodes, seg = two_bodies(xs, 0.85 + 0.05 * xs ** 2, np.linspace(0, 1, 6),
                                    1.0 + 0.1 * np.sin(3 * np.linspace(0, 1, 6)))
    n = np.array([0.1, 1.0])
    rot = random_rotation(2, rng)
    kw = {"direction": n} if search == "along_direction" else {"search": "closest_point"}
    kwr = {"direction": rot @ n} if search == "along_direction" else {"search": "closest_point"}
    cc = contact_constraints(points, nodes, seg, **kw)
    cr = contact_constraints(points @ rot.T, nodes, seg, **kwr)
    assert cc.m == cr.m == len(xs)
    np.testing.assert_allclose(cr.g, cc.g, atol=EPS)
    np.testing.assert_allclose(cr.direction, cc.direction @ rot.T, atol=EPS)
    np.testing.assert_allclose(cr.weights, cc.weights, atol=1e-12)
    u = rng.normal(size=points.shape)
    np.testing.assert_allclose(cr.B @ (u @ rot.T).ravel(), cc.B @ u.ravel(), atol=1e-12)


def test_closed_opposing_boundary_takes_nearest_hit():
    """Circle above a flat top; the whole circle is the opposing surface."""
    t = np.linspace(0, 2 * np.pi, 65)[:-1]
    centre, radius = np.array([0.5, 1.5]), 0.5
    circ = centre + radius * np.column_stack([np.cos(t), np.sin(t)])     # counter-clockwise
    seg = np.column_stack([np.arange(64), (np.arange(64) + 1) % 64]) + 3
    lower = np.array([[0.4, 1.02], [0.5, 0.98], [0.6, 1.0]])           # inside, apart, apart
    points = np.vstack([lower, circ])
    cb = contact_constraints(points, np.arange(3), seg, direction=[0.0, 1.0])
    ca = contact_constraints(points, np.arange(3), seg, search="closest_point")
    for cc in (cb, ca):
        assert cc.m == 3
        q = cc.target
        assert np.all(q[:, 1] < centre[1])                          # lower arc
        np.testing.assert_allclose(np.einsum("md,md->m", q - lower, cc.direction), cc.g, atol=EPS)
    # the polygon's lowest vertex is (0.5, 1.0), shared by segments 47 and 48
    np.testing.assert_allclose([cb.g[1], ca.g[1]], 0.02, atol=1e-12)
    assert cb.facet[1] == 47 and ca.facet[1] in (47, 48)
    assert cb.g[0] < 0 and ca.g[0] < 0 and cb.g[1] > 0 and ca.g[1] > 0


# --------------------------------------------------------------------------- 3D exact

def triangle_scene(P):
    """One triangle above P; ordered so that its normal points down (outward)."""
    tri = np.array([[0.0, 0.0, 1.0], [0.0, 2.0, 1.4], [2.0, 0.0, 1.2]])   # z = 1 + 0.1x + 0.2y
    return np.vstack([np.atleast_2d(P), tri]), np.array([[1, 2, 3]]) + len(np.atleast_2d(P)) - 1


def test_3d_triangle_case_b():
    P = np.array([[0.3, 0.5, 0.0], [1.0, 0.2, 0.4], [1.5, 1.5, 0.0]])    # the last one misses
    points, tri = triangle_scene(P)
    cc = contact_constraints(points, np.arange(3), tri, direction=[0.0, 0.0, 1.0])
    np.testing.assert_array_equal(cc.found, [True, True, False])
    x, y, z = P[:2].T
    np.testing.assert_allclose(cc.g, 1 + 0.1 * x + 0.2 * y - z, atol=EPS)
    s, t = y / 2, x / 2               # vertex order (0,0), (0,2), (2,0)
    np.testing.assert_allclose(cc.weights, np.column_stack([1 - s - t, s, t]), atol=EPS)
    nu = facet_normals(points, tri)[0]
    assert nu[2] < 0
    t3 = np.array([0.3, -0.7, 0.2])
    np.testing.assert_allclose(cc.B @ np.tile(t3, len(points)), 0.0, atol=1e-15)


def test_3d_triangle_case_a_interior_edge_vertex():
    tri_pts = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 1.0], [1.0, 0.0, 1.0]])   # normal (0,0,-1)
    P = np.array([[0.3, 0.3, 0.5],      # below the interior
                  [-0.5, 0.4, 0.5],     # closest to the edge x = 0
                  [-0.3, -0.4, 1.0],    # closest to the vertex (0,0,1), in plane
                  [0.2, 0.1, 1.3]])     # above the interior: inside the upper body
    points = np.vstack([P, tri_pts])
    tri = np.array([[4, 5, 6]])
    cc = contact_constraints(points, np.arange(4), tri, search="closest_point")
    assert cc.found.all()
    np.testing.assert_allclose(cc.target, [[0.3, 0.3, 1.0], [0.0, 0.4, 1.0], [0, 0, 1.0],
                                           [0.2, 0.1, 1.0]], atol=EPS)
    np.testing.assert_allclose(cc.g, [0.5, np.sqrt(0.5), 0.5, -0.3], atol=EPS)
    np.testing.assert_allclose(cc.weights, [[0.4, 0.3, 0.3], [0.6, 0.4, 0.0], [1, 0, 0],
                                            [0.7, 0.1, 0.2]], atol=EPS)
    np.testing.assert_allclose(cc.direction, [[0, 0, 1], [np.sqrt(0.5), 0, np.sqrt(0.5)],
                                              [0.6, 0.8, 0], [0, 0, 1]], atol=EPS)


def test_3d_shared_edge_gives_one_row():
    sq = np.array([[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1.0]])
    P = np.array([[0.5, 0.5, 0.8], [0.25, 0.25, 0.8], [1.0, 0.0, 0.8]])   # on the diagonal/vertex
    points = np.vstack([P, sq])
    tris = np.array([[0, 2, 1], [0, 3, 2]]) + 3                       # both normals (0,0,-1)
    for kwargs in ({"direction": [0, 0, 1]}, {"search": "closest_point"}):
        cc = contact_constraints(points, np.arange(3), tris, **kwargs)
        assert cc.m == 3
        np.testing.assert_array_equal(cc.facet, [0, 0, 0])
        np.testing.assert_allclose(cc.g, 0.2, atol=EPS)
        np.testing.assert_allclose(cc.weights, [[0.5, 0.5, 0.0], [0.75, 0.25, 0], [0, 0, 1]],
                                   atol=EPS)


def grid_surface(n, height, shift=(0.0, 0.0)):
    """Triangulated height field over [0,1]^2 with normals pointing down."""
    x, y = np.meshgrid(np.linspace(0, 1, n) + shift[0], np.linspace(0, 1, n) + shift[1])
    pts = np.column_stack([x.ravel(), y.ravel(), height(x.ravel(), y.ravel())])
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    tris = np.vstack([np.column_stack([a, c, b]), np.column_stack([a, d, c])])
    return pts, tris


@pytest.mark.parametrize("search", ["closest_point", "along_direction"])
def test_rotation_invariance_3d(search):
    rng = np.random.default_rng(5)
    up, tris = grid_surface(5, lambda x, y: 1.0 + 0.1 * np.sin(3 * x + y))
    P = np.column_stack([rng.uniform(0.1, 0.9, (8, 2)), rng.uniform(0.7, 0.85, 8)])
    points = np.vstack([P, up])
    tris = tris + 8
    assert np.all(facet_normals(points, tris)[:, 2] < 0)
    n = np.array([0.1, -0.05, 1.0])
    rot = random_rotation(3, rng)
    kw = {"direction": n} if search == "along_direction" else {"search": "closest_point"}
    kwr = {"direction": rot @ n} if search == "along_direction" else {"search": "closest_point"}
    cc = contact_constraints(points, np.arange(8), tris, **kw)
    cr = contact_constraints(points @ rot.T, np.arange(8), tris, **kwr)
    assert cc.m == cr.m == 8
    np.testing.assert_allclose(cr.g, cc.g, atol=1e-12)
    np.testing.assert_array_equal(cr.facet, cc.facet)
    np.testing.assert_allclose(cr.direction, cc.direction @ rot.T, atol=1e-12)
    u = rng.normal(size=points.shape)
    np.testing.assert_allclose(cr.B @ (u @ rot.T).ravel(), cc.B @ u.ravel(), atol=1e-12)
    np.testing.assert_allclose(cc.B @ np.tile(rng.normal(size=3), len(points)), 0.0, atol=1e-15)


# --------------------------------------------------------------------------- brute force

def brute_force(points, nodes, facets, search, dirs=None, inside_upper=None):
    """All pairs, one node and one facet at a time (independent of the module).

    Returns per node ``None`` or ``(key, facet, g, weights)``; in case a the sign
    of ``g`` comes from the predicate ``inside_upper(P)``, not from facet normals.
    """
    dim = points.shape[1]
    out = []
    for i, P in enumerate(points[nodes]):
        best = None
        for f, fac in enumerate(facets):
            V = points[fac]
            if dim == 2:
                A, Bv = V
                if search == "b":
                    M = np.column_stack([dirs[i], A - Bv])
                    if abs(np.linalg.det(M)) < 1e-12:
                        continue
                    lam, s = np.linalg.solve(M, A - P)
                    if s < -1e-10 or s > 1 + 1e-10:
                        continue
                    key, g, w = abs(lam), lam, (1 - s, s)
                else:
                    s = np.clip(np.dot(P - A, Bv - A) / np.dot(Bv - A, Bv - A), 0, 1)
                    Q = A + s * (Bv - A)
                    key = np.linalg.norm(P - Q)
                    g = -key if inside_upper is not None and inside_upper(P) else key
                    w = (1 - s, s)
            else:
                M = np.column_stack([-dirs[i], V[1] - V[0], V[2] - V[0]])
                lam, s, t = np.linalg.solve(M, P - V[0])
                if min(s, t, 1 - s - t) < -1e-10:
                    continue
                key, g, w = abs(lam), lam, (1 - s - t, s, t)
            if best is None or key < best[0] - 1e-12:
                best = (key, f, g, np.array(w))
        out.append(best)
    return out


@pytest.mark.parametrize("case", ["b-constant", "b-per-node", "a"])
def test_kdtree_search_matches_brute_force_2d(case):
    rng = np.random.default_rng(2024)
    xs = np.sort(rng.uniform(-0.1, 1.1, 40))
    ux = np.concatenate([[0.0], np.sort(rng.uniform(0, 1, 30)), [1.0]])
    points, nodes, seg = two_bodies(xs, 0.2 * np.sin(4 * xs) + rng.normal(0, 0.02, 40),
                                    ux, 0.1 + 0.15 * np.cos(5 * ux))
    if case == "b-constant":
        dirs = np.tile([0.2, 1.0] / np.hypot(0.2, 1.0), (40, 1))
        cc = contact_constraints(points, nodes, seg, direction=dirs[0])
        ref = brute_force(points, nodes, seg, "b", dirs)
    elif case == "b-per-node":
        ang = rng.uniform(-0.6, 0.6, 40)
        dirs = np.column_stack([np.sin(ang), np.cos(ang)])
        cc = contact_constraints(points, nodes, seg, direction=dirs)
        ref = brute_force(points, nodes, seg, "b", dirs)
    else:
        cc = contact_constraints(points, nodes, seg, search="closest_point")
        upper = points[seg[:, 0].min():]
        ref = brute_force(points, nodes, seg, "a", inside_upper=lambda P: (
            0 <= P[0] <= 1 and P[1] > np.interp(P[0], upper[:, 0], upper[:, 1])))
    assert (cc.g < 0).any() and (cc.g > 0).any()          # both signs occur
    np.testing.assert_array_equal(cc.found, [r is not None for r in ref])
    kept = [r for r in ref if r is not None]
    np.testing.assert_allclose(cc.g, [r[2] for r in kept], atol=1e-12)
    # B rows from the reference pairing (identical rows when Q is a shared vertex)
    B_ref = np.zeros((len(kept), points.size))
    for i, (P, r) in enumerate(zip(cc.rows, kept)):
        B_ref[i, 2 * P:2 * P + 2] += cc.direction[i]
        for k, v in enumerate(seg[r[1]]):
            B_ref[i, 2 * v:2 * v + 2] -= r[3][k] * cc.direction[i]
    np.testing.assert_allclose(cc.B.toarray(), B_ref, atol=1e-10)
    interior = np.all(cc.weights > 1e-9, axis=1)
    np.testing.assert_array_equal(cc.facet[interior], np.array([r[1] for r in kept])[interior])
    assert interior.sum() > len(kept) // 2
    if case == "a":
        q = cc.target
        np.testing.assert_allclose(np.abs(cc.g), np.linalg.norm(q - points[cc.rows], axis=1),
                                   atol=1e-12)
        np.testing.assert_allclose(cc.g[:, None] * cc.direction, q - points[cc.rows], atol=1e-12)
    else:
        np.testing.assert_allclose(cc.direction, dirs[cc.found], atol=1e-15)


@pytest.mark.parametrize("constant", [True, False])
def test_kdtree_search_matches_brute_force_3d_case_b(constant):
    rng = np.random.default_rng(7)
    up, tris = grid_surface(7, lambda x, y: 0.5 + 0.2 * np.sin(4 * x) * np.cos(3 * y))
    k = 30
    P = np.column_stack([rng.uniform(-0.1, 1.1, (k, 2)), rng.uniform(0.2, 0.6, k)])
    points = np.vstack([P, up])
    if constant:
        dirs = np.tile(np.array([0.1, 0.2, 1.0]) / np.linalg.norm([0.1, 0.2, 1.0]), (k, 1))
        cc = contact_constraints(points, np.arange(k), tris + k, direction=dirs[0])
    else:
        dirs = np.column_stack([rng.uniform(-0.4, 0.4, (k, 2)), np.ones(k)])
        dirs /= np.linalg.norm(dirs, axis=1)[:, None]
        cc = contact_constraints(points, np.arange(k), tris + k, direction=dirs)
    ref = brute_force(points, np.arange(k), tris + k, "b", dirs)
    np.testing.assert_array_equal(cc.found, [r is not None for r in ref])
    kept = [r for r in ref if r is not None]
    assert 0 < len(kept) < k
    np.testing.assert_array_equal(cc.facet, [r[1] for r in kept])
    np.testing.assert_allclose(cc.g, [r[2] for r in kept], atol=1e-12)
    np.testing.assert_allclose(cc.weights, [r[3] for r in kept], atol=1e-10)


def test_case_a_3d_matches_dense_sampling():
    """Closest point on a triangulated surface vs. the minimum over dense samples."""
    rng = np.random.default_rng(1)
    up, tris = grid_surface(5, lambda x, y: 0.5 + 0.2 * x * y)
    P = np.column_stack([rng.uniform(-0.3, 1.3, (10, 2)), rng.uniform(0.2, 0.45, 10)])
    points = np.vstack([P, up])
    cc = contact_constraints(points, np.arange(10), tris + 10, search="closest_point")
    assert cc.found.all()
    s, t = np.meshgrid(np.linspace(0, 1, 41), np.linspace(0, 1, 41))
    keep = s + t <= 1
    bary = np.column_stack([1 - s[keep] - t[keep], s[keep], t[keep]])
    samples = np.einsum("sk,fkd->fsd", bary, up[tris]).reshape(-1, 3)
    dmin = np.min(np.linalg.norm(P[:, None] - samples[None], axis=2), axis=1)
    assert np.all(cc.g <= dmin + 1e-12) and np.all(cc.g >= dmin - 5e-3)
    np.testing.assert_allclose(np.linalg.norm(cc.target - P, axis=1), cc.g, atol=1e-12)


# --------------------------------------------------------------------------- helpers

def test_orient_facets_outward():
    # unit square, two triangles, boundary given in random orientations
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
    cells = np.array([[0, 1, 2], [0, 2, 3]])
    facets = np.array([[1, 0], [1, 2], [3, 2], [0, 3]])
    out = orient_facets(pts, facets, cells)
    nu = facet_normals(pts, out)
    mid = pts[out].mean(axis=1)
    assert np.all(np.einsum("fd,fd->f", nu, mid - 0.5) > 0)
    # 3D: one tetrahedron
    pts3 = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    faces = np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]])
    out = orient_facets(pts3, faces, np.array([[0, 1, 2, 3]]))
    nu = facet_normals(pts3, out)
    assert np.all(np.einsum("fd,fd->f", nu, pts3[out].mean(axis=1) - 0.25) > 0)
    with pytest.raises(ValueError, match="facets"):
        orient_facets(pts, np.array([[0, 2], [1, 3]]), np.array([[0, 1, 2]]))


def test_barycentric_projection_7_14():
    V = np.array([[[0.0, 0, 0], [2, 0, 0], [0, 2, 0]]])
    w = barycentric(V, np.array([[0.5, 0.5, 3.0]]))          # off-plane point is projected
    np.testing.assert_allclose(w, [[0.5, 0.25, 0.25]])


def test_restrict_to_free_and_gap_after():
    points, nodes, seg = two_bodies(np.array([0.2, 0.7]), 0.9, np.array([0.0, 0.5, 1.0]), 1.0)
    cc = contact_constraints(points, nodes, seg, direction=[0.0, 1.0])
    free = np.array([1, 3, 5, 7])
    Bf = restrict_to_free(cc.B, free)
    assert sp.isspmatrix_csr(Bf) or isinstance(Bf, sp.csr_array)
    np.testing.assert_allclose(Bf.toarray(), cc.B.toarray()[:, free])
    u = np.zeros((len(points), 2))
    u[:2, 1] = 0.1                       # lower nodes move up by the gap: contact
    np.testing.assert_allclose(gap_after(points, cc, u), 0.0, atol=EPS)
    np.testing.assert_allclose(cc.B @ u.ravel(), cc.g, atol=EPS)
    with pytest.raises(ValueError, match="free_dofs"):
        restrict_to_free(cc.B, np.array([0.5]))
    with pytest.raises(ValueError, match="u_full"):
        gap_after(points, cc, np.zeros(3))


def test_bad_input_names_the_parameter():
    points, nodes, seg = two_bodies(np.array([0.2, 0.7]), 0.9, np.array([0.0, 0.5, 1.0]), 1.0)
    cases = [
        ({"search": "c", "direction": [0, 1]}, "search"),
        ({"search": "a", "direction": [0, 1]}, "'a' was renamed to 'closest_point'"),
        ({"search": "b", "direction": [0, 1]}, "'b' was renamed to 'along_direction'"),
        ({}, "direction"),
        ({"direction": [0, 1, 0]}, "direction"),
        ({"direction": [0, 0]}, "direction"),
        ({"direction": [0, 1], "dim": 3}, "dim"),
        ({"direction": [0, 1], "max_distance": -1.0}, "max_distance"),
        ({"direction": [0, 1], "n_nodes": 2}, "n_nodes"),
    ]
    for kwargs, name in cases:
        with pytest.raises(ValueError, match=name):
            contact_constraints(points, nodes, seg, **kwargs)
    with pytest.raises(ValueError, match="constrained_nodes"):
        contact_constraints(points, [0, 0], seg, direction=[0, 1])
    with pytest.raises(ValueError, match="opposing_facets"):
        contact_constraints(points, nodes, seg[:, :1], direction=[0, 1])
    with pytest.raises(ValueError, match="opposing_facets"):
        contact_constraints(points, nodes, np.array([[2, 2]]), direction=[0, 1])


def test_n_nodes_pads_columns_and_empty_inputs():
    points, nodes, seg = two_bodies(np.array([0.2, 0.7]), 0.9, np.array([0.0, 0.5, 1.0]), 1.0)
    cc = contact_constraints(points, nodes, seg, direction=[0, 1], n_nodes=10)
    assert cc.B.shape == (2, 20)
    cc = contact_constraints(points, np.array([], dtype=int), seg, direction=[0, 1])
    assert cc.m == 0 and cc.B.shape == (0, 2 * len(points))
    cc = contact_constraints(points, nodes, np.zeros((0, 2), dtype=int), search="closest_point")
    assert cc.m == 0 and cc.found.shape == (2,)


def test_facets_of_the_node_itself_are_skipped():
    """A constrained node that is a vertex of opposing facets never pairs with them."""
    ang = np.linspace(0, 2 * np.pi, 10)[:-1] + 0.1
    star = np.vstack([[0.0, 0.0], 0.1 * np.column_stack([np.cos(ang), np.sin(ang)])])
    far = np.array([[-1.0, 2.0], [1.0, 2.0]])
    points = np.vstack([star, far])
    facets = np.vstack([np.column_stack([np.zeros(9, int), np.arange(1, 10)]), [[10, 11]]])
    ca = contact_constraints(points, [0], facets, search="closest_point")     # all nearest facets are own
    cb = contact_constraints(points, [0], facets, direction=[0.0, 1.0])
    for cc in (ca, cb):
        np.testing.assert_array_equal(cc.facet, [9])
        np.testing.assert_allclose(cc.g, [2.0], atol=EPS)
        np.testing.assert_allclose(cc.weights, [[0.5, 0.5]], atol=EPS)
    dirs = np.array([[0.0, 1.0], [0.3, 1.0]])
    cc = contact_constraints(points, [0, 1], facets, direction=dirs)   # per-node lines
    assert cc.found.all() and cc.facet[0] == 9 and cc.facet[1] != 0   # node 1 owns facet 0


def closest_on_triangle(p, a, b, c):
    """Ericson, Real-Time Collision Detection 5.1.5 (scalar reference)."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = ab @ ap, ac @ ap
    if d1 <= 0 and d2 <= 0:
        return np.array([1.0, 0, 0])
    bp = p - b
    d3, d4 = ab @ bp, ac @ bp
    if d3 >= 0 and d4 <= d3:
        return np.array([0, 1.0, 0])
    vc = d1 * d4 - d3 * d2
    if vc <= 0 and d1 >= 0 and d3 <= 0:
        v = d1 / (d1 - d3)
        return np.array([1 - v, v, 0])
    cp = p - c
    d5, d6 = ab @ cp, ac @ cp
    if d6 >= 0 and d5 <= d6:
        return np.array([0, 0, 1.0])
    vb = d5 * d2 - d1 * d6
    if vb <= 0 and d2 >= 0 and d6 <= 0:
        w = d2 / (d2 - d6)
        return np.array([1 - w, 0, w])
    va = d3 * d6 - d5 * d4
    if va <= 0 and (d4 - d3) >= 0 and (d5 - d6) >= 0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return np.array([0, 1 - w, w])
    denom = 1.0 / (va + vb + vc)
    v, w = vb * denom, vc * denom
    return np.array([1 - v - w, v, w])


def test_kdtree_search_matches_brute_force_3d_case_a():
    rng = np.random.default_rng(17)
    up, tris = grid_surface(6, lambda x, y: 0.5 + 0.15 * np.sin(4 * x) * np.cos(3 * y))
    k = 40
    P = np.column_stack([rng.uniform(-0.2, 1.2, (k, 2)), rng.uniform(0.3, 0.65, k)])
    points = np.vstack([P, up])
    cc = contact_constraints(points, np.arange(k), tris + k, search="closest_point")
    assert cc.found.all()

    def height(x, y):                 # the piecewise-linear surface, None outside
        for t in tris:
            w = np.linalg.solve(np.vstack([up[t, :2].T, np.ones(3)]), [x, y, 1.0])
            if w.min() >= -1e-12:
                return w @ up[t, 2]
        return None

    for i, p in enumerate(P):
        ws = [closest_on_triangle(p, *up[t]) for t in tris]
        d = [np.linalg.norm(p - w @ up[t]) for w, t in zip(ws, tris)]
        j = int(np.argmin(d))
        h = height(p[0], p[1])
        if h is None:
            # beside the open surface: the sign comes from the facet plane (documented)
            np.testing.assert_allclose(abs(cc.g[i]), d[j], atol=1e-12)
        else:
            np.testing.assert_allclose(cc.g[i], (-1.0 if p[2] > h else 1.0) * d[j], atol=1e-12)
        np.testing.assert_allclose(cc.target[i], ws[j] @ up[tris[j]], atol=1e-12)
    assert (cc.g < 0).any() and (cc.g > 0).any()


def test_case_a_ignores_direction():
    points, nodes, seg = two_bodies(np.array([0.2, 0.7]), 0.9, np.array([0.0, 0.5, 1.0]), 1.1)
    plain = contact_constraints(points, nodes, seg, search="closest_point")
    given = contact_constraints(points, nodes, seg, search="closest_point", direction=[0.3, 1.0])
    np.testing.assert_array_equal(given.direction, plain.direction)
    np.testing.assert_array_equal(given.g, plain.g)
