"""Mortar coupling in 3D: cube_sphere with ``coupling="mortar"`` and ``"mortar_dual"``
(the clipping backend of :mod:`problems.fem.mortar`).

What is tested, with its known answer:

* the quadrature: the clipped pieces cover each triangle of the cube's top face once
  (their areas sum to the triangle's), and on each triangle the standard local mass
  matrix is ``|T| (1 + delta_ab) / 12`` and the dual basis is biorthogonal,
  ``int psi_a phi_b = delta_ab |T| / 3`` (Wohlmuth's ``psi_a = 4 phi_a - 1``);
* the 3D contact patch test on the curved, non-matching interface (the ball's projected
  triangles over the face's Kuhn triangles): a uniform pressure ``q`` on the weighted
  gaps loads each node of the ball with ``q int phi_k^o`` over its projected triangles
  within the face (its consistent load, computed independently by clipping each
  projected triangle against the face's square), and each node of the face with ``q m_j``,
  to round-off, with both bases; the nodal rows give the same total force and miss the
  ball's nodal loads node by node;
* the rows' consistency: a rigid translation by ``d`` along ``n`` of the ball changes
  every weighted gap by ``d``, of the cube by ``-d`` (the rows' weights sum to one);
* the solvers: PDAS verified ``converged`` on both bases at levels 0 and 1, with the same
  pressure whichever body comes first in memory; on the dual rows (one per constrained
  node) TNNMG and the augmented projection are verified ``converged`` and agree with
  PDAS to 1e-8 in the relative energy norm at ``high``, as semismooth Newton and the
  augmented projection do on the standard rows; TNNMG skips those with its reason;
* the nodal coupling stays as it was: the scene's nodal rows are the assembled ones,
  unchanged by the coupling step.
"""
from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from agreement import assert_solvers_agree
from problems.cube_sphere import scene
from problems.fem.mortar import mortar_integrals, multiplier_basis, surface_quadrature
from problems.fem.two_body import assemble_two_body
from problems.spec import problems
from solvers.kernels.contact_box import check_structure
from solvers.interface import solve

CUBE = problems()["cube_sphere"]
MORTAR = ("mortar", "mortar_dual")
N = np.array([0.0, 0.0, 1.0])

#: Round-off bar of the exact identities (relative).
ROUND_OFF = 1e-12

#: The clipped areas against each face triangle's area (relative).
COVERAGE = 1e-13


@cache
def make(level, coupling="nodal"):
    """The scene at ``level`` with ``coupling``, built once for this module."""
    return CUBE.make(level, coupling=coupling)


def quadrature(qp):
    c = qp.contact
    return surface_quadrature(qp.mesh.points, c.facets, c.opposing_facets, N)


def face_areas(qp):
    tri = qp.mesh.points[qp.contact.facets]
    return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)


def local_matrices(q, test, trial, n_facets):
    """``int test_a trial_b`` on each constrained facet, (n_facets, 3, 3)."""
    out = np.zeros((n_facets, 3, 3))
    np.add.at(out, q.facet, q.weight[:, None, None] * test[:, :, None] * trial[:, None, :])
    return out


@pytest.mark.parametrize("level", [0, 1])
def test_the_clipped_pieces_cover_every_face_triangle_once(level):
    qp = make(level)
    q = quadrature(qp)
    area = face_areas(qp)
    covered = np.bincount(q.facet, q.weight, minlength=len(area))
    assert np.abs(covered / area - 1.0).max() <= COVERAGE
    # every point lies in both of its triangles: the hats are in [0, 1] and sum to one
    for phi in (q.phi, q.phi_opposing):
        assert phi.min() >= -ROUND_OFF and phi.max() <= 1 + ROUND_OFF
        assert np.abs(phi.sum(axis=1) - 1.0).max() <= ROUND_OFF


def test_the_local_mass_is_exact_and_the_dual_basis_is_biorthogonal():
    qp = make(1)
    q = quadrature(qp)
    area = face_areas(qp)[:, None, None]
    eye = np.eye(3)[None]
    standard = local_matrices(q, q.phi, q.phi, len(area))
    assert np.abs(standard - area * (1 + eye) / 12).max() <= COVERAGE * area.max()
    dual = local_matrices(q, multiplier_basis(q.phi, dual=True), q.phi, len(area))
    assert np.abs(dual - area * eye / 3).max() <= COVERAGE * area.max()


@pytest.mark.parametrize("dual", [False, True], ids=["standard", "dual"])
def test_both_bases_sum_to_one(dual):
    qp = make(1)
    c = qp.contact
    mi = mortar_integrals(qp.mesh.points, c.facets, c.opposing_facets, N, dual)
    np.testing.assert_allclose(mi.mass, c.mass, rtol=ROUND_OFF)      # the lumped mass
    np.testing.assert_allclose(np.asarray(mi.D.sum(axis=1)).ravel(), mi.mass, rtol=ROUND_OFF)
    np.testing.assert_allclose(np.asarray(mi.M.sum(axis=1)).ravel(), mi.mass, rtol=ROUND_OFF)
    off_diagonal = mi.D - np.diag(mi.D.diagonal())
    assert (np.abs(off_diagonal).max() == 0.0) == dual


def clip_to_unit_square(polygon):
    """Sutherland-Hodgman: a convex polygon (list of 2D points) clipped to [0, 1]^2."""
    for axis, bound, sign in ((0, 0.0, 1), (0, 1.0, -1), (1, 0.0, 1), (1, 1.0, -1)):
        out = []
        for k, cur in enumerate(polygon):
            prev = polygon[k - 1]
            inside_cur = sign * (cur[axis] - bound) >= 0
            inside_prev = sign * (prev[axis] - bound) >= 0
            if inside_cur != inside_prev:
                s = (bound - prev[axis]) / (cur[axis] - prev[axis])
                out.append(prev + s * (cur - prev))
            if inside_cur:
                out.append(cur)
        polygon = out
        if not polygon:
            break
    return polygon


def consistent_opposing_load(qp):
    """``int phi_k^o`` over the top face for every node ``k`` of the ball: each projected
    triangle clipped to the face's square, its hats integrated by the centroid rule (exact
    for linear functions)."""
    pts = qp.mesh.points
    load = np.zeros(len(pts))
    for tri in qp.contact.opposing_facets:
        xy = pts[tri, :2]
        poly = clip_to_unit_square([p for p in xy])
        if len(poly) < 3:
            continue
        origin = poly[0]
        v = np.array(poly) - origin                  # the shoelace on local coordinates
        cross = v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1]
        area = 0.5 * cross.sum()
        if abs(area) == 0.0:
            continue
        centroid = origin + ((v + np.roll(v, -1, axis=0)) * cross[:, None]).sum(axis=0) \
            / (6 * area)
        lam = np.linalg.solve(np.vstack([xy.T, np.ones(3)]), np.append(centroid, 1.0))
        load[tri] += abs(area) * lam
    return load


def normal_forces(qp, p):
    """The z component of ``B' p`` on each node (zero on prescribed unknowns)."""
    full = np.zeros(3 * qp.n_nodes)
    full[qp.free_dofs] = qp.B.T @ p
    return full[2::3]


@pytest.mark.parametrize("coupling", MORTAR)
def test_uniform_pressure_is_transferred_exactly_across_the_curved_interface(coupling):
    q = 0.3
    qp = make(1, coupling)
    exact = consistent_opposing_load(qp)
    assert exact.sum() == pytest.approx(1.0, rel=ROUND_OFF)         # the face's area
    force = normal_forces(qp, q * qp.contact.mass)
    on_face = np.zeros(qp.n_nodes, dtype=bool)
    on_face[qp.contact.nodes] = True
    # the ball's nodes: minus the consistent load; the face's nodes: q m_j
    assert np.abs(-force[~on_face] - q * exact[~on_face]).max() <= ROUND_OFF * q * exact.max()
    np.testing.assert_allclose(force[qp.contact.nodes], q * qp.contact.mass, rtol=ROUND_OFF)
    nodal = make(1)
    nodal_force = -normal_forces(nodal, q * nodal.contact.mass)
    nodal_force[nodal.contact.nodes] = 0.0
    # nodal: the same total force, distributed by interpolation weights, not consistently
    assert nodal_force.sum() == pytest.approx(q * exact.sum(), rel=ROUND_OFF)
    assert np.abs(nodal_force - q * exact).max() > 0.05 * q * exact.max()


@pytest.mark.parametrize("coupling", MORTAR)
def test_a_rigid_translation_along_n_shifts_every_weighted_gap_by_its_size(coupling):
    d = 0.01
    qp = make(1, coupling)
    ball = qp.mesh.bodies.index("ball")
    for body, sign in ((ball, -1.0), (1 - ball, 1.0)):
        u_full = np.zeros(3 * qp.n_nodes)
        u_full[2::3][qp.mesh.body_of_node == body] = d
        np.testing.assert_allclose(qp.B @ u_full[qp.free_dofs], sign * d, rtol=ROUND_OFF)
    # the geometry moved: the integrated gaps follow it
    c = qp.contact
    moved = qp.mesh.points + d * N * (qp.mesh.body_of_node == ball)[:, None]
    dual = coupling == "mortar_dual"
    before = mortar_integrals(qp.mesh.points, c.facets, c.opposing_facets, N, dual)
    after = mortar_integrals(moved, c.facets, c.opposing_facets, N, dual)
    shift = (after.weighted_gap - before.weighted_gap) / before.mass
    np.testing.assert_allclose(shift, d, rtol=ROUND_OFF)


def test_the_nodal_coupling_is_the_assembled_problem():
    opts = CUBE.options()
    assembled = assemble_two_body(scene(1, opts), 1, name="cube_sphere level 1")
    for qp in (make(1), make(1, "nodal")):
        assert (qp.B != assembled.B).nnz == 0 and np.array_equal(qp.g, assembled.g)
        assert qp.m == 81


def test_dual_rows_are_node_wise_and_standard_rows_are_not():
    dual = make(0, "mortar_dual")
    assert check_structure(dual) == (True, "")
    standard = make(0, "mortar")
    ok, reason = check_structure(standard)
    assert not ok and "other rows" in reason
    skipped = solve(standard, "tnnmg", "high")
    assert skipped.status == "skipped" and "cannot be turned into bounds" in skipped.message


@pytest.mark.parametrize("level", [0, 1])
def test_pdas_converges_on_both_bases(level):
    for coupling in MORTAR:
        qp = make(level, coupling)
        res = solve(qp, "pdas", "high")
        assert res.status == "converged", (coupling, res.message)
        assert res.kkt.max <= 1e-9, coupling
        assert res.p.max() > 0, coupling                     # the bodies touch


@pytest.mark.parametrize("coupling", MORTAR)
def test_the_solution_does_not_depend_on_the_bodies_order(coupling):
    first = make(0, coupling)
    second = CUBE.make(0, coupling=coupling, order="ball_first")
    np.testing.assert_array_equal(first.mesh.points[first.contact.nodes],
                                  second.mesh.points[second.contact.nodes])
    pressure = [qp.contact.pressure(solve(qp, "pdas", "high").p) for qp in (first, second)]
    assert np.abs(pressure[0] - pressure[1]).max() <= ROUND_OFF * pressure[0].max()


@pytest.mark.parametrize("level", [0, 1])
def test_solvers_agree_with_the_exact_reference_on_dual_rows(level):
    assert_solvers_agree(make(level, "mortar_dual"), ("tnnmg", "augmented_projection"))


@pytest.mark.slow
def test_solvers_agree_with_the_exact_reference_on_dual_rows_at_level_2():
    assert_solvers_agree(CUBE.make(2, coupling="mortar_dual"), ("tnnmg", "augmented_projection"))


def test_standard_rows_are_solved_by_semismooth_newton_and_the_augmented_projection():
    assert_solvers_agree(make(1, "mortar"), ("semismooth_newton", "augmented_projection"))
