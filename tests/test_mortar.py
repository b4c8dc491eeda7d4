"""Mortar coupling (``coupling="mortar"``, ``"mortar_dual"``; :mod:`problems.fem.mortar`).

What is tested, with its known answer:

* the mortar integrals: both multiplier bases sum to one (``sum_j D_ij = m_i``, the
  lumped mass), the dual ``D`` is diagonal, and on circle_square's curved, non-matching
  interface (the circle's chords over the square's top edge) a uniform pressure ``q``
  loads each opposing node with exactly ``q int phi_k^o dt`` (its consistent load, the
  trapezoidal rule on the projected chords, computed independently), to round-off;
  the nodal rows of Alg. 7.1 load it with interpolation weights times lumped masses
  and miss it by percents (the interface error of the nodal coupling);
* the contact patch test solved (flat_blocks at the mesh ratio 2:3, both sides): the
  uniform pressure to round-off with both bases, nodal off by percents;
* the solvers: on the dual rows (one per constrained node) TNNMG and the augmented
  projection are verified ``converged`` and agree with the exact reference (PDAS) to
  1e-8 in the relative energy norm at ``high``, as semismooth Newton does on both bases;
  TNNMG skips the standard rows with its reason.
"""
from __future__ import annotations

import numpy as np
import pytest

from agreement import assert_solvers_agree
from problems.fem.mortar import mortar_integrals
from problems.flat_blocks import exact_pressure
from problems.spec import ParameterError, problems
from solvers.kernels.contact_box import check_structure
from solvers.interface import solve

#: Round-off bar of the exact identities (relative).
ROUND_OFF = 1e-12

#: A coupling that passes the patch test reproduces the uniform pressure to round-off;
#: one that fails misses it by percents. Any bar between the two tells them apart.
PATCH_TOL = 1e-8

PROBLEMS = problems()
CIRCLE = PROBLEMS["circle_square"]
FLAT = PROBLEMS["flat_blocks"]


def integrals(qp, dual):
    c = qp.contact
    return mortar_integrals(qp.mesh.points, c.facets, c.opposing_facets, np.array([0.0, 1.0]),
                            dual)


def consistent_opposing_load(qp, lo, hi):
    """``int phi_k^o dt`` over ``[lo, hi]`` for every opposing node ``k`` (trapezoidal rule
    on each projected chord, clipped to ``[lo, hi]``: exact for the linear hats)."""
    x = qp.mesh.points[:, 0]
    load = np.zeros(len(x))
    for a, b in qp.contact.opposing_facets:
        ta, tb = x[a], x[b]
        s0, s1 = np.clip(sorted((ta, tb)), lo, hi)
        if s1 <= s0:
            continue
        hat_a = lambda t: (t - tb) / (ta - tb)          # noqa: E731  (the hat of node a)
        load[a] += 0.5 * (s1 - s0) * (hat_a(s0) + hat_a(s1))
        load[b] += 0.5 * (s1 - s0) * (2.0 - hat_a(s0) - hat_a(s1))
    return load


def opposing_force(qp, p):
    """The normal force of the multipliers ``p`` on each node of the opposing body
    (minus the y part of ``B' p`` on all DOFs, per node)."""
    full = np.zeros(2 * len(qp.mesh.points))
    full[qp.free_dofs] = qp.B.T @ p
    force = -full[1::2]
    force[qp.contact.nodes] = 0.0
    return force


@pytest.mark.parametrize("dual", [False, True], ids=["standard", "dual"])
def test_multipliers_sum_to_one_and_the_dual_basis_is_biorthogonal(dual):
    qp = CIRCLE.make(1)
    mi = integrals(qp, dual)
    np.testing.assert_allclose(np.asarray(mi.D.sum(axis=1)).ravel(), mi.mass, rtol=ROUND_OFF)
    np.testing.assert_allclose(mi.mass, qp.contact.mass, rtol=ROUND_OFF)
    # each row's opposing weights sum to its mass too: the opposing surface covers Gamma
    np.testing.assert_allclose(np.asarray(mi.M.sum(axis=1)).ravel(), mi.mass, rtol=ROUND_OFF)
    off_diagonal = mi.D - np.diag(mi.D.diagonal())
    assert (np.abs(off_diagonal).max() == 0.0) == dual


@pytest.mark.parametrize("coupling", ["mortar", "mortar_dual"])
def test_uniform_pressure_is_transferred_exactly_across_the_curved_interface(coupling):
    nodal = CIRCLE.make(1)
    qp = CIRCLE.make(1, coupling=coupling)
    x = qp.mesh.points[qp.contact.nodes, 0]
    exact = consistent_opposing_load(qp, x.min(), x.max())
    q = 0.3
    force = opposing_force(qp, q * qp.contact.mass)
    assert np.abs(force - q * exact).max() <= ROUND_OFF * q * exact.max()
    nodal_force = opposing_force(nodal, q * nodal.contact.mass)
    # nodal: the same total force, distributed by interpolation weights, not consistently
    assert nodal_force.sum() == pytest.approx(q * exact.sum(), rel=ROUND_OFF)
    assert np.abs(nodal_force - q * exact).max() > 0.05 * q * exact.max()


@pytest.mark.parametrize("side", ["coarse", "fine"])
def test_mortar_passes_the_contact_patch_test_and_nodal_does_not(side):
    opts = FLAT.options(constrained=side)
    q = exact_pressure(opts)
    deviation = {}
    for coupling in ("nodal", "mortar", "mortar_dual"):
        qp = FLAT.make(1, constrained=side, coupling=coupling)
        res = solve(qp, "pdas", "high")
        assert res.status == "converged", res.message
        deviation[coupling] = np.abs(qp.contact.pressure(res.p) / q - 1.0).max()
    assert deviation["mortar"] < PATCH_TOL and deviation["mortar_dual"] < PATCH_TOL
    assert deviation["nodal"] > 1e-2


def test_dual_rows_are_node_wise_and_standard_rows_are_not():
    dual = CIRCLE.make(1, coupling="mortar_dual")
    assert check_structure(dual) == (True, "")
    ok, reason = check_structure(CIRCLE.make(1, coupling="mortar"))
    assert not ok and "other rows" in reason


@pytest.mark.parametrize("level", [1])
def test_solvers_agree_with_the_exact_reference_on_dual_rows(level):
    qp = CIRCLE.make(level, coupling="mortar_dual")
    ref = assert_solvers_agree(qp, ("tnnmg", "augmented_projection", "semismooth_newton"))
    assert ref.kkt.max <= 1e-9


def test_standard_rows_are_solved_by_the_exact_methods_and_skipped_by_tnnmg():
    qp = CIRCLE.make(1, coupling="mortar")
    assert_solvers_agree(qp, ("semismooth_newton", "osqp"))
    skipped = solve(qp, "tnnmg", "high")
    assert skipped.status == "skipped" and "cannot be turned into bounds" in skipped.message


@pytest.mark.parametrize("scene, bad, needle", [
    (scene, bad, needle) for scene, uncovered in (("circle_square", {"offset": 1.3}),
                                                  ("cube_sphere", {"radius": 0.5}))
    for bad, needle in (({"search": "closest_point"}, "parameter 'search'"),
                        (uncovered, "parameter 'coupling'.*does not cover"))
])
def test_bad_mortar_settings_name_the_parameter(scene, bad, needle):
    with pytest.raises(ParameterError, match=needle):
        PROBLEMS[scene].make(0, coupling="mortar_dual", **bad)
