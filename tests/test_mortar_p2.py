"""Mortar coupling with P2 elements (``degree=2``, :mod:`problems.fem.mortar`).

What is tested, with its known answer:

* the quadrature: the 2D Gauss rule and the 6-point triangle rule integrate every
  monomial of degree <= 4 in the barycentric coordinates exactly (``int lam^a / |T| =
  s! a! / (s + |a|)!``), the 3-point rule does not; on cube_sphere's clipped pieces the
  P2 local mass matrix of every face triangle is the exact one (products of the P2
  shape functions expanded into monomials);
* the multipliers: the dual coefficients reproduce Wohlmuth's P1 basis, the P2 segment's
  dual basis is ``(6, 2, -1)/4`` and ``(-2, -2, 3)/2`` and biorthogonal on circle_square
  (``int psi_a phi_b = delta_ab m_a`` per facet to round-off); on triangles it does not
  exist and ``mortar_dual`` at P2 in 3D is refused naming the parameter; both bases sum to
  one (``sum_j D_ij = m_i``); on a triangle the standard rows take the modified basis
  (``psi_v = phi_v + alpha sum phi_m``, ``psi_m = (1 - 2 alpha) phi_m``): it sums to one,
  spans the same space, and its weights are ``2/15`` and ``1/5`` of the triangle's area
  where the hats' are ``0`` and ``1/3``;
* the pressure at P2 is recovered from the forces and is ``q`` for the multipliers of a
  uniform ``q`` (``s_i q``);
* the contact patch test solved (flat_blocks at P2, both sides): the uniform pressure and
  the multiplier coefficients to round-off with both bases, the nodal P2 rows off by
  about 1 %; on circle_square's curved, non-matching interface a uniform
  pressure ``q`` loads each opposing node with ``q int phi_k^o dt`` (Simpson's rule on the
  projected chords, exact for the P2 hats); on cube_sphere (the 3D contact patch test) a
  uniform pressure ``q`` loads each P2 node of the ball with ``q int phi_k^o`` over its
  projected triangles within the face (clipped and integrated independently) and each
  node of the face with ``q int phi_j``, a rigid translation by ``d`` along ``n`` shifts
  every weighted gap, a vertex's too, by ``d``;
* the model: on cube_sphere at level 0 the P2 mortar solution is within 5 % of the nodal
  P2 solution on the same mesh in the energy norm;
* the solvers at level 0: on circle_square (both bases) and cube_sphere (standard) the
  exact reference (PDAS) and semismooth Newton / OSQP are verified ``converged`` and agree
  to 1e-8 in the relative energy norm; on the dual rows (one per constrained node) TNNMG
  takes the problem and agrees too.
"""
from __future__ import annotations

from functools import cache
from itertools import product
from math import factorial

import numpy as np
import pytest

from agreement import assert_solvers_agree
from problems.fem.mortar import (TRIANGLE_RULES, dual_coefficients, modified_coefficients,
                                 mortar_integrals, multiplier_basis, quadratic_quadrature,
                                 reference_rule, surface_quadrature)
from problems.fem.quadratic import quadratic_mesh_of, shape_functions
from problems.flat_blocks import exact_pressure
from problems.spec import ParameterError, problems
from test_mortar_3d import clip_to_unit_square
from solvers.kernels.contact_box import check_structure
from solvers.interface import solve

PROBLEMS = problems()
CIRCLE, CUBE, FLAT = (PROBLEMS[k] for k in ("circle_square", "cube_sphere", "flat_blocks"))

#: Round-off bar of the exact identities (relative).
ROUND_OFF = 1e-12

#: A coupling that passes the patch test reproduces the uniform pressure to round-off.
PATCH_TOL = 1e-8


@cache
def make(name, level, coupling):
    """A scene at P2 with ``coupling``, built once for this module."""
    return PROBLEMS[name].make(level, coupling=coupling, degree=2)


def integrals(qp, dual):
    c = qp.contact
    n = np.eye(qp.dim)[-1]
    return mortar_integrals(qp.mesh.points, c.facets, c.opposing_facets, n, dual,
                            quadratic_mesh_of(qp.mesh.points, qp.mesh.cells))


def monomials(vertices, degree):
    return [a for a in product(range(degree + 1), repeat=vertices) if sum(a) <= degree]


def exact_monomial(a):
    """``int lam^a / |T|`` on a simplex of dimension ``s = len(a) - 1``."""
    s = len(a) - 1
    return factorial(s) * np.prod([factorial(x) for x in a]) / factorial(s + sum(a))


def rule_error(bary, w, degree):
    return max(abs(np.sum(w * np.prod(bary ** np.array(a), axis=1)) - exact_monomial(a))
               for a in monomials(bary.shape[1], degree))


def test_the_rules_integrate_degree_4_exactly():
    for vertices in (2, 3):
        assert rule_error(*reference_rule(vertices), 4) <= 1e-15
    assert rule_error(*TRIANGLE_RULES[4], 4) <= 1e-15
    assert rule_error(*TRIANGLE_RULES[2], 2) <= 1e-15
    assert rule_error(*TRIANGLE_RULES[2], 4) > 1e-3        # degree 2 only: not enough for P2


def p2_polynomials(vertices):
    """The P2 shape functions (:func:`shape_functions`' order) as ``{exponents: coefficient}``."""
    def unit(*idx):
        e = [0] * vertices
        for i in idx:
            e[i] += 1
        return tuple(e)
    edges = [(0, 1)] if vertices == 2 else [(0, 1), (1, 2), (0, 2)]
    return ([{unit(i, i): 2.0, unit(i): -1.0} for i in range(vertices)]
            + [{unit(i, j): 4.0} for i, j in edges])


def exact_p2_mass(vertices):
    """``int phi_a phi_b / |T|`` of the P2 shape functions, from their monomials."""
    polys = p2_polynomials(vertices)
    return np.array([[sum(ca * cb * exact_monomial(tuple(np.add(ea, eb)))
                          for ea, ca in pa.items() for eb, cb in pb.items())
                      for pb in polys] for pa in polys])


def test_the_clipped_p2_mass_matrices_are_exact_on_cube_sphere():
    qp = make("cube_sphere", 0, "mortar")
    c, pts = qp.contact, qp.mesh.points
    quad = surface_quadrature(pts, c.facets, c.opposing_facets, np.array([0.0, 0.0, 1.0]), 4)
    quad = quadratic_quadrature(quad, quadratic_mesh_of(pts, qp.mesh.cells))
    local = np.zeros((len(c.facets), 6, 6))
    np.add.at(local, quad.facet, quad.weight[:, None, None] * quad.phi[:, :, None]
              * quad.phi[:, None, :])
    tri = pts[c.facets]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    exact = exact_p2_mass(3)
    assert np.abs(exact.sum(axis=1)[:3]).max() <= 1e-15      # the vertex hats integrate to 0
    # the quadrature's facets may list their vertices in another order: compare invariants
    # that do not depend on it (the sorted entries of each local matrix)
    got = np.sort(local.reshape(len(area), -1) / area[:, None], axis=1)
    want = np.sort(exact.ravel())
    assert np.abs(got - want).max() <= 1e-13


def test_the_dual_coefficients():
    np.testing.assert_allclose(dual_coefficients(2, 1), [[2, -1], [-1, 2]], atol=1e-14)
    np.testing.assert_allclose(dual_coefficients(3, 1), 4 * np.eye(3) - 1, atol=1e-14)
    np.testing.assert_allclose(dual_coefficients(2, 2),
                               [[1.5, 0.5, -0.25], [0.5, 1.5, -0.25], [-1, -1, 1.5]], atol=1e-14)
    # biorthogonal on the reference segment: int psi_a phi_b = delta_ab m_a
    bary, w = reference_rule(2)
    phi = shape_functions(bary)
    psi = multiplier_basis(phi, dual=True, degree=2)
    np.testing.assert_allclose(np.einsum("q,qa,qb->ab", w, psi, phi),
                               np.diag([1 / 6, 1 / 6, 2 / 3]), atol=1e-15)
    with pytest.raises(ValueError, match="vertex hats integrate to zero"):
        dual_coefficients(3, 2)


def test_the_dual_p2_basis_is_biorthogonal_on_the_curved_scene():
    qp = make("circle_square", 1, "mortar_dual")
    c, pts = qp.contact, qp.mesh.points
    quad = quadratic_quadrature(surface_quadrature(pts, c.facets, c.opposing_facets,
                                                   np.array([0.0, 1.0]), 4),
                                quadratic_mesh_of(pts, qp.mesh.cells))
    psi = multiplier_basis(quad.phi, dual=True, degree=2)
    local = np.zeros((len(c.facets), 3, 3))
    np.add.at(local, quad.facet, quad.weight[:, None, None] * psi[:, :, None]
              * quad.phi[:, None, :])
    length = np.linalg.norm(pts[c.facets[:, 1]] - pts[c.facets[:, 0]], axis=1)
    want = length[:, None, None] * np.diag([1 / 6, 1 / 6, 2 / 3])[None]
    assert np.abs(local - want).max() <= ROUND_OFF * length.max()


@pytest.mark.parametrize("name", ["circle_square", "cube_sphere"])
def test_the_standard_p2_rows_sum_to_one(name):
    qp = make(name, 0, "mortar")
    mi = integrals(qp, False)
    D, M = mi.D.toarray(), mi.M
    np.testing.assert_allclose(D.sum(axis=1), mi.mass, atol=ROUND_OFF * mi.mass.max())
    np.testing.assert_allclose(np.asarray(M.sum(axis=1)).ravel(), mi.mass,
                               atol=ROUND_OFF * mi.mass.max())
    # the surface mass matrix in 2D (psi = phi); on triangles psi is the modified basis
    assert np.allclose(D, D.T, rtol=0, atol=ROUND_OFF * D.max()) == (name == "circle_square")
    # the rows are scaled by their weights (2D: the HRZ mass, which is m_i itself)
    np.testing.assert_allclose(qp.contact.mass, mi.mass, rtol=ROUND_OFF)
    if name == "cube_sphere":
        # the modified basis: 2 |T| / 15 per triangle at a vertex, |T| / 5 at a midpoint
        c, pts = qp.contact, qp.mesh.points
        tri = pts[c.facets]
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]),
                                    axis=1)
        mesh = quadratic_mesh_of(pts, qp.mesh.cells)
        want = np.zeros(len(mesh.points))
        np.add.at(want, c.facets, np.repeat(2 * area[:, None] / 15, 3, axis=1))
        for a, b in ((0, 1), (1, 2), (0, 2)):
            np.add.at(want, mesh.midpoint(c.facets[:, a], c.facets[:, b]), area / 5)
        np.testing.assert_allclose(mi.mass, want[mi.nodes], rtol=ROUND_OFF)
        assert mi.mass.sum() == pytest.approx(1.0, rel=ROUND_OFF)       # the face's area
    # the pressure recovered from the forces is q for the multipliers of a uniform q
    q = 0.3
    assert qp.contact.mass.min() > 0
    np.testing.assert_allclose(qp.contact.pressure(q * qp.contact.mass), q, rtol=ROUND_OFF)


@pytest.mark.parametrize("side", ["coarse", "fine"])
def test_p2_mortar_passes_the_contact_patch_test_and_nodal_does_not(side):
    q = exact_pressure(FLAT.options(constrained=side))
    for coupling in ("mortar", "mortar_dual"):
        qp = FLAT.make(1, constrained=side, coupling=coupling, degree=2)
        ref = assert_solvers_agree(qp, ("semismooth_newton",))
        assert ref.kkt.max <= 1e-9
        assert np.abs(qp.contact.pressure(ref.p) / q - 1.0).max() < PATCH_TOL, coupling
        coefficients = ref.p / qp.contact.mass              # the multiplier field's
        assert np.abs(coefficients / q - 1.0).max() < PATCH_TOL, coupling
    nodal = FLAT.make(1, constrained=side, degree=2)
    res = solve(nodal, "pdas", "high")
    assert res.status == "converged"
    assert np.abs(nodal.contact.pressure(res.p) / q - 1.0).max() > 1e-3


def simpson_opposing_load(qp, lo, hi):
    """``int phi_k^o dt`` over ``[lo, hi]`` for every opposing P2 node ``k``: each
    projected chord clipped to ``[lo, hi]``, Simpson's rule (exact for quadratics)."""
    pts = qp.mesh.points
    mesh = quadratic_mesh_of(pts, qp.mesh.cells)
    load = np.zeros(len(pts))
    for a, b in qp.contact.opposing_facets:
        ta, tb = pts[a, 0], pts[b, 0]
        s0, s1 = np.clip(sorted((ta, tb)), lo, hi)
        if s1 <= s0:
            continue
        t = np.array([s0, 0.5 * (s0 + s1), s1])
        lam_b = (t - ta) / (tb - ta)
        phi = shape_functions(np.column_stack([1 - lam_b, lam_b]))
        nodes = [a, b, int(mesh.midpoint(np.array([a]), np.array([b]))[0])]
        load[nodes] += (s1 - s0) / 6 * (phi[0] + 4 * phi[1] + phi[2])
    return load


@pytest.mark.parametrize("coupling", ["mortar", "mortar_dual"])
def test_uniform_pressure_is_transferred_exactly_across_the_curved_interface(coupling):
    qp = make("circle_square", 1, coupling)
    x = qp.mesh.points[qp.contact.nodes, 0]
    exact = simpson_opposing_load(qp, x.min(), x.max())
    q = 0.3
    full = np.zeros(2 * qp.n_nodes)
    full[qp.free_dofs] = qp.B.T @ (q * qp.contact.mass)
    force = -full[1::2]
    force[qp.contact.nodes] = 0.0
    assert np.abs(force - q * exact).max() <= ROUND_OFF * q * exact.max()


def test_the_modified_p2_basis_of_a_triangle():
    """Popp-Wohlmuth's basis of the P2 space on a triangle: it sums to one, spans the
    same space (T invertible), and its weights are positive where the hats' vanish."""
    T = modified_coefficients()
    np.testing.assert_allclose(T.sum(axis=0), 1.0, rtol=ROUND_OFF)
    assert abs(np.linalg.det(T)) > 0.1
    bary, w = reference_rule(3)
    phi = shape_functions(bary)
    psi = multiplier_basis(phi, dual=False, degree=2)
    np.testing.assert_allclose(psi.sum(axis=1), 1.0, rtol=ROUND_OFF)
    np.testing.assert_allclose(w @ phi, [0, 0, 0, 1 / 3, 1 / 3, 1 / 3], atol=1e-15)
    np.testing.assert_allclose(w @ psi, [2 / 15] * 3 + [1 / 5] * 3, rtol=ROUND_OFF)
    # on a segment the P2 hats' weights are positive: the standard basis is kept
    bary, _ = reference_rule(2)
    np.testing.assert_array_equal(multiplier_basis(shape_functions(bary), dual=False,
                                                   degree=2), shape_functions(bary))
    for alpha in (0.0, 0.5):
        with pytest.raises(ValueError, match="parameter 'alpha'.*allowed: 0 < alpha < 1/2"):
            modified_coefficients(alpha)


def test_a_rigid_translation_shifts_every_p2_weighted_gap_in_3d():
    d, q = 0.01, 0.3
    qp = make("cube_sphere", 0, "mortar")
    ball = qp.mesh.bodies.index("ball")
    # every row, at a vertex too, moves by d: the rows' weights sum to m_i > 0 (the
    # modified basis), and each row is scaled by its m_i
    for body, sign in ((ball, -1.0), (1 - ball, 1.0)):
        u_full = np.zeros(3 * qp.n_nodes)
        u_full[2::3][qp.mesh.body_of_node == body] = d
        np.testing.assert_allclose(qp.B @ u_full[qp.free_dofs], sign * d, rtol=ROUND_OFF)
    full = np.zeros(3 * qp.n_nodes)
    full[qp.free_dofs] = qp.B.T @ (q * qp.contact.mass)
    on_ball = qp.mesh.body_of_node == ball
    # the face (area 1) transmits q, wholly to the ball (no prescribed ball node touches it)
    assert full[2::3][on_ball].sum() == pytest.approx(-q, rel=ROUND_OFF)
    assert full[2::3][~on_ball].sum() == pytest.approx(q, rel=ROUND_OFF)


def consistent_p2_load(qp):
    """``int phi_k^o`` over the cube's top face for every P2 node ``k`` of the ball: each
    projected triangle clipped to the face's square, the clipped polygon split into a
    fan of triangles, the P2 hats integrated on each by the edge-midpoint rule (exact for
    quadratics)."""
    pts = qp.mesh.points
    mesh = quadratic_mesh_of(pts, qp.mesh.cells)
    load = np.zeros(len(mesh.points))
    for tri in qp.contact.opposing_facets:
        xy = pts[tri, :2]
        poly = clip_to_unit_square([p for p in xy])
        nodes = np.concatenate([tri, [mesh.midpoint(np.array([tri[a]]), np.array([tri[b]]))[0]
                                      for a, b in ((0, 1), (1, 2), (0, 2))]])
        to_bary = np.linalg.inv(np.vstack([xy.T, np.ones(3)]))
        for k in range(1, len(poly) - 1):
            a, b, c = poly[0], poly[k], poly[k + 1]
            area = 0.5 * abs((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]))
            mids = np.array([(a + b) / 2, (b + c) / 2, (a + c) / 2])
            lam = (to_bary @ np.vstack([mids.T, np.ones(3)])).T
            load[nodes] += area / 3 * shape_functions(lam).sum(axis=0)
    return load


def test_the_3d_p2_contact_patch_test():
    """A uniform pressure ``q`` on the modified basis (every coefficient ``q``) loads each
    P2 node of the ball with ``q int phi_k^o`` over the face (computed independently) and
    each node of the face with its consistent load ``q int phi_j`` (zero at a vertex)."""
    q = 0.3
    qp = make("cube_sphere", 1, "mortar")
    exact = consistent_p2_load(qp)
    assert exact.sum() == pytest.approx(1.0, rel=ROUND_OFF)              # the face's area
    full = np.zeros(3 * qp.n_nodes)
    full[qp.free_dofs] = qp.B.T @ (q * qp.contact.mass)
    force = full[2::3]
    on_face = np.zeros(qp.n_nodes, dtype=bool)
    on_face[qp.contact.nodes] = True
    assert np.abs(-force[~on_face] - q * exact[~on_face]).max() <= ROUND_OFF * q * exact.max()
    face_load = np.asarray(integrals(qp, False).D.sum(axis=0)).ravel()   # int phi_j
    np.testing.assert_allclose(force[qp.contact.nodes], q * face_load,
                               atol=ROUND_OFF * q * face_load.max())
    vertex = qp.contact.nodes < quadratic_mesh_of(qp.mesh.points, qp.mesh.cells).n_vertices
    assert np.abs(face_load[vertex]).max() <= ROUND_OFF * face_load.max()


#: The 3D P2 mortar solution's distance to the nodal P2 solution on the same mesh, relative
#: to that solution's energy norm, at level 0 (measured 0.011; P1 mortar from P1 nodal:
#: 0.028). A basis whose vertex rows do not see a translation is off by its whole size.
NEAR_NODAL = 0.05


def test_the_3d_p2_mortar_solution_is_near_the_nodal_one():
    qp, nodal = make("cube_sphere", 0, "mortar"), CUBE.make(0, degree=2)
    u, u_nodal = (solve(q, "pdas", "high") for q in (qp, nodal))
    assert u.status == u_nodal.status == "converged"
    e = u.u - u_nodal.u
    assert np.sqrt(e @ (qp.A @ e) / (u_nodal.u @ (qp.A @ u_nodal.u))) < NEAR_NODAL
    # every row's multiplier is a pressure coefficient: none negative, the vertices' too
    assert u.p.min() >= 0.0 and u.p.max() > 0.0


def test_dual_p2_in_3d_and_stabilised_p2_are_refused():
    with pytest.raises(ParameterError, match="parameter 'coupling'.*vertex hats integrate to "
                                             "zero.*allowed: coupling='mortar' at degree=2"):
        CUBE.make(0, coupling="mortar_dual", degree=2)
    for coupling in ("stabilised", "two_pass"):
        with pytest.raises(ParameterError, match="parameter 'degree': 2 is not allowed"):
            CIRCLE.make(0, coupling=coupling, degree=2)


@pytest.mark.parametrize("name, coupling, others", [
    ("circle_square", "mortar", ("semismooth_newton", "osqp")),
    ("circle_square", "mortar_dual", ("tnnmg", "semismooth_newton")),
    ("cube_sphere", "mortar", ("semismooth_newton",)),
])
def test_p2_mortar_is_solved_by_the_exact_reference_and_another_solver(name, coupling, others):
    qp = make(name, 0, coupling)
    assert check_structure(qp)[0] == (coupling == "mortar_dual")
    ref = assert_solvers_agree(qp, others)
    assert ref.kkt.max <= 1e-9 and ref.p.max() > 0
