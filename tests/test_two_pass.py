"""Two-pass node-to-segment contact (``coupling="two_pass"``): the degenerate families of the
test set. Both surfaces' nodes carry hard rows; where nodes of the two sides coincide the
two passes give the same row, so the rows at the solution are linearly dependent. The
exact reference (``pdas``) and semismooth Newton must be verified ``converged`` there and
agree with an independent solver (OSQP at the ``high`` preset) to 1e-8 in the relative
energy norm; the patch test's pressure is measured; the solvers that need one row per
constrained node, or a definite ``S-hat``, skip with their reason.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from agreement import AGREEMENT, assert_solvers_agree
from problems.fem.stabilised import stabilise, two_pass
from problems.flat_blocks import exact_pressure
from problems.kkt import energy_error
from problems.qp import QPValidationError, surface_pressure
from problems.spec import ParameterError, problems
from solvers.interface import solve
from workflows.problem_set import load

#: Singular values below this, relative to the largest, count as zero.
RANK_RTOL = 1e-10

#: The patch test's bar: a discretisation that fails it misses the uniform pressure by an
#: amount that does not shrink with h (the nodal coupling at 2:3: 8-18 %); one that passes
#: reproduces it to round-off. Any bar orders of magnitude between the two tells them apart.
PATCH_TOL = 1e-8

FLAT = problems()["flat_blocks"]


def degenerate_small():
    """The degenerate families' small-class problems of the current test set."""
    return [p for p in load().problems("small") if p.family.startswith("degenerate_")]


def tight(qp, u):
    """Rows holding with equality at ``u`` (slack below 1e-9 of the gaps' scale)."""
    Bu = qp.B @ u
    scale = max(np.abs(qp.g).max(), np.abs(Bu).max())
    return np.flatnonzero(qp.g - Bu <= 1e-9 * scale)


def interface_positions(qp, rows):
    """Distinct x coordinates of the nodes behind ``rows`` (constrained, then reverse)."""
    nodes = np.concatenate([qp.contact.nodes, qp.stabilisation.nodes])[rows]
    return np.unique(np.round(qp.mesh.points[nodes, 0], 12)).size


def assert_exact_and_agrees(qp):
    """``pdas`` and ``semismooth_newton`` verified ``converged`` at ``high`` and within
    :data:`AGREEMENT` of OSQP's verified solution; returns OSQP's result."""
    return assert_solvers_agree(qp, ("pdas", "semismooth_newton"), reference="osqp")


def test_the_current_set_has_degenerate_families_in_its_small_class():
    names = {p.name for p in degenerate_small()}
    assert names == {"degenerate_two_pass_matching_L2", "degenerate_two_pass_matching_L3",
                     "degenerate_two_pass_L2", "degenerate_two_pass_L3"}


@pytest.mark.parametrize("item", degenerate_small(), ids=lambda p: p.name)
def test_degenerate_family_is_solved_exactly_and_its_rows_are_dependent(item):
    qp = item.build()
    qp.validate()
    independent = assert_exact_and_agrees(qp)
    # the rows tight at the solution are dependent: their rank is the number of distinct
    # interface positions (a coinciding pair of nodes gives one row twice)
    rows = tight(qp, independent.u)
    B_t = qp.B[rows].toarray()
    sv = np.linalg.svd(B_t, compute_uv=False)
    rank = int(np.sum(sv > RANK_RTOL * sv[0]))
    assert rank == interface_positions(qp, rows) < len(rows)
    if item.params.get("ratio") == "1:1":        # matching meshes: every row twice
        assert 2 * rank == len(rows) == qp.m


@pytest.mark.parametrize("ratio", ["1:1", "2:3"])
@pytest.mark.parametrize("side", ["coarse", "fine"])
def test_two_pass_transmits_the_uniform_pressure(ratio, side):
    """The patch test: two-pass (Taylor-Papadopoulos) transmits the uniform pressure q on
    the non-matching 2:3 meshes, where one pass (Alg. 7.1) does not; the exact, linear
    displacement lies in the discrete space and satisfies both passes."""
    p = FLAT.options(coupling="two_pass", ratio=ratio, constrained=side)
    q = exact_pressure(p)
    qp = FLAT.build(2, p)
    res = solve(qp, "pdas", "high")
    assert res.status == "converged", res.message
    assert np.abs(surface_pressure(qp, res.p) / q - 1.0).max() <= PATCH_TOL
    nodal = FLAT.build(2, FLAT.options(ratio=ratio, constrained=side))
    ref = solve(nodal, "pdas", "high")
    deviation = np.abs(surface_pressure(nodal, ref.p) / q - 1.0).max()
    if ratio == "2:3":
        assert deviation > 1e-2                  # one pass fails the patch test there
    else:
        assert deviation <= PATCH_TOL            # matching meshes: both pass
        assert energy_error(qp, res.u, ref.u) <= AGREEMENT


@pytest.mark.parametrize("solver, reason", [
    ("tnnmg", "two-sided constraints"),
    ("augmented_projection", "two-pass constraints"),
])
def test_solvers_that_cannot_take_two_pass_rows_skip_with_their_reason(solver, reason):
    qp = FLAT.build(1, FLAT.options(coupling="two_pass"))
    res = solve(qp, solver, "mid")
    assert res.status == "skipped" and reason in res.message


@pytest.mark.parametrize("name, level", [("circle_square", 0), ("cube_sphere", 0)])
def test_two_pass_on_curved_scenes(name, level):
    """Curved surfaces: the reverse rows add the opposing nodes' constraints; coincident
    nodes are rare (cube-sphere: the ball's lowest node over a cube node gives one
    dependent row). The exact reference and semismooth Newton agree with OSQP."""
    spec = problems()[name]
    qp = spec.build(level, spec.options(coupling="two_pass"))
    nodal = spec.build(level, spec.options())
    assert qp.m_contact == nodal.m and qp.m > nodal.m and qp.C is None
    assert_exact_and_agrees(qp)


def test_two_pass_rows_are_the_stabilised_reverse_rows_hard():
    """Two-pass and the stabilised coupling share their reverse rows; two-pass keeps them
    hard (no C), and a ContactQP that mixes the two is refused by name."""
    nodal = FLAT.build(1, FLAT.options())
    tp, st = two_pass(nodal), stabilise(nodal)
    assert tp.C is None and tp.stabilisation.hard and not st.stabilisation.hard
    assert abs(tp.B - st.B).max() == 0 and np.array_equal(tp.g, st.g)
    assert FLAT.build(1, FLAT.options(coupling="two_pass")).B.shape == tp.B.shape
    with pytest.raises(ValueError, match="'qp'"):
        two_pass(tp)
    with pytest.raises(QPValidationError, match="take no C"):
        dataclasses.replace(tp, C=st.C).validate()
    with pytest.raises(ParameterError, match="'degree'"):
        FLAT.build(0, FLAT.options(coupling="two_pass", degree=2))
