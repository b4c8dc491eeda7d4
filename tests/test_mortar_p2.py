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
  one (``sum_j D_ij = m_i``), and in 3D the vertices' ``m_i`` are zero, so the rows are
  scaled by the positive HRZ mass;
* the pressure at P2 is recovered from the forces and is ``q`` for the multipliers of a
  uniform ``q`` (``s_i q``);
* the contact patch test solved (flat_blocks at P2, both sides): the uniform pressure and
  the multiplier coefficients to round-off with both bases, the nodal P2 rows off by
  about 1 %; on circle_square's curved, non-matching interface a uniform
  pressure ``q`` loads each opposing node with ``q int phi_k^o dt`` (Simpson's rule on the
  projected chords, exact for the P2 hats); on cube_sphere a rigid translation by ``d``
  along ``n`` shifts weighted gap ``i`` by ``d m_i / s_i`` (zero at the face's vertices,
  whose hats integrate to zero) and ``q`` transmits the face's area times ``q``;
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
from problems.fem.mortar import (TRIANGLE_RULES, dual_coefficients, mortar_integrals,
                                 multiplier_basis, quadratic_quadrature, reference_rule,
                                 surface_quadrature)
from problems.fem.quadratic import quadratic_mesh_of, shape_functions
from problems.flat_blocks import exact_pressure
from problems.spec import ParameterError, problems
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
    assert np.allclose(D, D.T, rtol=0, atol=ROUND_OFF * D.max())
    vertex = qp.contact.nodes < quadratic_mesh_of(qp.mesh.points, qp.mesh.cells).n_vertices
    if name == "cube_sphere":                   # int phi_i = 0 at the vertices of triangles
        assert np.abs(mi.mass[vertex]).max() <= ROUND_OFF * mi.mass.max()
    else:                                       # 2D: the HRZ scaling is m_i itself
        np.testing.assert_allclose(qp.contact.mass, mi.mass, rtol=ROUND_OFF)
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


def test_a_rigid_translation_shifts_every_p2_weighted_gap_in_3d():
    d, q = 0.01, 0.3
    qp = make("cube_sphere", 0, "mortar")
    ball = qp.mesh.bodies.index("ball")
    # row i moves by d m_i / s_i: the rows' weights sum to m_i, which is zero at the face's
    # vertices (those rows do not see a translation) and not the HRZ mass s_i elsewhere
    shift = integrals(qp, False).mass / qp.contact.mass
    assert np.abs(shift).min() <= ROUND_OFF and np.abs(shift).max() > 1.0
    for body, sign in ((ball, -1.0), (1 - ball, 1.0)):
        u_full = np.zeros(3 * qp.n_nodes)
        u_full[2::3][qp.mesh.body_of_node == body] = d
        np.testing.assert_allclose(qp.B @ u_full[qp.free_dofs], sign * d * shift,
                                   rtol=ROUND_OFF, atol=ROUND_OFF * d)
    full = np.zeros(3 * qp.n_nodes)
    full[qp.free_dofs] = qp.B.T @ (q * qp.contact.mass)
    on_ball = qp.mesh.body_of_node == ball
    # the face (area 1) transmits q, wholly to the ball (no prescribed ball node touches it)
    assert full[2::3][on_ball].sum() == pytest.approx(-q, rel=ROUND_OFF)
    assert full[2::3][~on_ball].sum() == pytest.approx(q, rel=ROUND_OFF)


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
