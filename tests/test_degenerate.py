"""Degenerate contact problems: linearly dependent active constraint rows (LICQ fails:
the primal solution is unique, the multipliers are not) and infeasible ones.

The exact reference (``pdas``) and the semismooth Newton solver must return the unique
``u`` with one valid multiplier vector, verified, and agree with an independent solver
(the augmented projection method, Alg. 8.4, verified at the ``high`` preset) to 1e-8 in
the relative energy norm. Problems: the random two-body family of
``tests/test_solvers.py`` over 500 seeds, plain and with ``B`` perturbed at round-off
level (the rank check runs on all of them, the solvers on every rank-deficient one and on
a sample of the rest); constructed cases on the circle-square contact scene (duplicated
rows, identical rows with different gaps, a corner of three dependent rows); infeasible
problems, which must end ``failed`` with a message saying so.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp

from problems.circle_square import PROBLEM as CIRCLE_SQUARE
from problems.kkt import energy_error
from problems.qp import ContactQP
from solvers.kernels.cholesky import InfeasibleError, row_basis
from solvers.interface import STATUSES, solve, solvers
from test_solvers import two_body_qp

#: Seeds of the random two-body family whose rank the test checks.
SEEDS = range(500)

#: Seeds beyond ``SEEDS`` on which the plain PDAS step meets a singular active-set system
#: (B of 15 rows and rank 14; at 7677 the second step has 12 dependent active rows).
SINGULAR_STEP_SEEDS = (945, 1524, 7677)

#: Full-rank seeds on which the solvers run too (the rest only get the rank check).
FULL_RANK_SAMPLE = 5

#: Relative size of the perturbation of ``B``'s entries: round-off level.
PERTURBATION = 1e-14

#: Singular values below this, relative to the largest, count as zero.
RANK_RTOL = 1e-10

#: Agreement with the independent solver, relative energy norm.
AGREEMENT = 1e-8

SOLVERS = ("pdas", "semismooth_newton")

#: Outer steps within which the augmented projection certifies the infeasible cases (the
#: pair at its first step, the corner at its fifth).
AP_INFEASIBLE_STEPS = 10

#: The configurations that must solve every degenerate problem: both linear-algebra
#: routes of the exact reference, semismooth Newton and its monotone fallback alone.
CONFIGURATIONS = (("pdas", {}), ("pdas", {"method": "kkt"}), ("semismooth_newton", {}),
                  ("semismooth_newton", {"patience": 0}))


def perturbed(qp: ContactQP, seed: int) -> ContactQP:
    """``qp`` with every entry of ``B`` changed by a relative ``PERTURBATION``."""
    rng = np.random.default_rng(seed)
    B = sp.csr_matrix(qp.B, copy=True)
    B.data *= 1.0 + PERTURBATION * rng.uniform(-1.0, 1.0, B.nnz)
    return ContactQP(A=qp.A, f=qp.f, B=B, g=qp.g, name=qp.name + "-perturbed")


def numerical_rank(B: sp.spmatrix) -> int:
    sv = np.linalg.svd(B.toarray(), compute_uv=False)
    return int(np.count_nonzero(sv > RANK_RTOL * sv[0]))


def assert_exact_and_agrees(qp: ContactQP, reference: np.ndarray) -> None:
    """Every configuration of ``pdas`` and ``semismooth_newton`` verified converged and
    within AGREEMENT of ``reference`` in the energy norm."""
    for name, options in CONFIGURATIONS:
        res = solve(qp, name, "high", **options)
        assert res.claimed_status == "converged" and res.status == "converged", \
            (qp.name, name, options, res.message)
        assert energy_error(qp, res.u, reference) <= AGREEMENT, (qp.name, name, options)
        assert np.all(res.p >= 0)


def independent_solution(qp: ContactQP) -> np.ndarray:
    res = solve(qp, "augmented_projection", "high")
    assert res.status == "converged", (qp.name, res.message)
    return res.u


@pytest.fixture(scope="module")
def family() -> dict[str, list[ContactQP]]:
    """The random two-body family, split by the numerical rank of ``B``."""
    out: dict[str, list[ContactQP]] = {"deficient": [], "full": []}
    for seed in list(SEEDS) + list(SINGULAR_STEP_SEEDS):
        qp = two_body_qp(seed=seed)
        for variant in (qp, perturbed(qp, seed)):
            kind = "deficient" if numerical_rank(variant.B) < variant.m else "full"
            out[kind].append(variant)
    return out


# --------------------------------------------------------------------- the random family
def test_family_has_rank_deficient_members(family):
    """There are rank-deficient members among the 500 seeds, and the round-off
    perturbation changes none of the numerical ranks (plain and perturbed pair up)."""
    names = [qp.name for qp in family["deficient"]]
    plain = [n for n in names if not n.endswith("-perturbed")]
    in_range = [n for n in plain if int(n.rsplit("-", 1)[1]) in SEEDS]
    assert len(in_range) >= 2
    assert sorted(n + "-perturbed" for n in plain) == sorted(set(names) - set(plain))
    assert {f"two-body-{s}" for s in SINGULAR_STEP_SEEDS} <= set(plain)
    assert len(family["full"]) + len(names) == 2 * (len(SEEDS) + len(SINGULAR_STEP_SEEDS))


def test_rank_deficient_members_are_solved_exactly(family):
    """Every rank-deficient member, plain and perturbed: both active-set solvers verified
    converged and in agreement with the augmented projection method."""
    for qp in family["deficient"]:
        assert_exact_and_agrees(qp, independent_solution(qp))


def test_singular_step_gives_a_basic_multiplier():
    """Where PDAS's step meets dependent active rows, it says so, and its multiplier
    is a basic one: zero on the dependent rows, the same force ``B'p`` as the
    independent solver's multiplier."""
    qp = two_body_qp(seed=7677)
    res = solve(qp, "pdas", "high")
    assert res.status == "converged" and res.kkt.max <= 1e-12, res.message
    assert res.stats["n_dependent"] >= 1 and "linearly dependent" in res.message
    active = res.p > 0
    assert numerical_rank(qp.B[active]) == np.count_nonzero(active)   # a basis carries p
    other = solve(qp, "augmented_projection", "high")
    force, other_force = qp.B.T @ res.p, qp.B.T @ other.p
    assert np.linalg.norm(force - other_force) <= 1e-6 * np.linalg.norm(force)


def test_full_rank_sample_is_solved_exactly(family):
    for qp in family["full"][::len(family["full"]) // FULL_RANK_SAMPLE][:FULL_RANK_SAMPLE]:
        assert_exact_and_agrees(qp, independent_solution(qp))


# --------------------------------------------------------------------- constructed cases
@pytest.fixture(scope="module")
def scene():
    """The circle-square contact scene at level 0, its active rows at the solution and
    the independent solutions of the constructed cases: the scene's own for
    ``duplicated`` and ``corner`` (the added rows hold at it with equality and zero
    multipliers), that of the scene with the tighter gaps for ``identical``."""
    qp = CIRCLE_SQUARE.make(0)
    res = solve(qp, "augmented_projection", "high")
    active = np.flatnonzero(res.p > 0)
    assert res.status == "converged" and active.size >= 2
    tight = ContactQP(A=qp.A, f=qp.f, B=qp.B, g=qp.g - tighter_by(qp, active) * np.isin(
        np.arange(qp.m), active), name="tighter gaps")
    return qp, active, {"duplicated": res.u, "corner": res.u,
                        "identical": independent_solution(tight)}


def tighter_by(qp: ContactQP, active: np.ndarray) -> float:
    """How much tighter (and looser) the copies of the ``identical`` case are."""
    return 1e-2 * float(np.abs(qp.g[active]).max())


def with_rows(qp: ContactQP, rows: sp.spmatrix, gaps: np.ndarray, name: str) -> ContactQP:
    return ContactQP(A=qp.A, f=qp.f, B=sp.vstack([qp.B, rows], format="csr"),
                     g=np.concatenate([qp.g, gaps]), name=name)


def constructed(qp: ContactQP, active: np.ndarray) -> dict[str, ContactQP]:
    """Degenerate variants of the scene.

    ``duplicated``: every row twice (same gap). ``identical``: each active row's node
    constrained twice more by the same row, once tighter and once looser (the tighter
    copy decides, the original becomes inactive). ``corner``: two active rows ``i, j``
    and their sum and difference with the consistent gaps (rows that are all active
    and pairwise independent, three at a time dependent).
    """
    B, g = qp.B.tocsr(), qp.g
    i, j = active[:2]
    delta = tighter_by(qp, active)
    return {
        "duplicated": with_rows(qp, B, g, "duplicated"),
        "identical": with_rows(qp, sp.vstack([B[active], B[active]]),
                               np.concatenate([g[active] - delta, g[active] + delta]),
                               "identical"),
        "corner": with_rows(qp, sp.vstack([B[i] + B[j], B[i] - B[j]]),
                            np.array([g[i] + g[j], g[i] - g[j]]), "corner"),
    }


@pytest.mark.parametrize("case", ["duplicated", "identical", "corner"])
def test_constructed_degenerate_cases(scene, case):
    base, active, reference = scene
    qp = constructed(base, active)[case]
    for variant in (qp, perturbed(qp, 0)):
        assert_exact_and_agrees(variant, reference[case])


def test_identical_rows_tighter_copy_decides(scene):
    """The solution with the tighter copies is not the scene's: the dependent rows'
    gaps decide which basis is consistent (a wrong one leaves a row violated)."""
    base, active, reference = scene
    qp = constructed(base, active)["identical"]
    res = solve(qp, "pdas", "high")
    assert res.status == "converged", res.message
    m = base.m
    tighter = m + np.arange(active.size)
    np.testing.assert_allclose(qp.B[tighter] @ res.u, qp.g[tighter], rtol=0,
                               atol=1e-12 * np.abs(qp.g).max())
    assert np.all(res.p[active] == 0) and np.all(res.p[tighter] > 0)
    assert energy_error(base, res.u, reference["duplicated"]) > 1e3 * AGREEMENT


@pytest.mark.slow
def test_duplicated_rows_on_a_floating_body():
    """The roll stack (the work roll held only by contact and weak springs: pdas's
    floating route) with its active rows written twice: the duplicates change nothing,
    so the solution is the scene's, to round-off; the verification certifies it."""
    from problems.roll_stack import PROBLEM as ROLL_STACK

    qp = ROLL_STACK.make(0)
    ref = solve(qp, "pdas", "high")
    active = np.flatnonzero(ref.p > 0)
    assert ref.status == "converged" and active.size >= 2
    # the rigid-body modes stay (the floating route needs them); the surface hierarchy
    # describes the scene's own rows only
    multilevel = dataclasses.replace(qp.multilevel, surface=None, extrusion=None)
    dup = ContactQP(A=qp.A, f=qp.f, B=sp.vstack([qp.B, qp.B[active]], format="csr"),
                    g=np.concatenate([qp.g, qp.g[active]]), multilevel=multilevel, dim=qp.dim,
                    name="roll stack, active rows twice")
    res = solve(dup, "pdas", "high")
    assert res.status == "converged" and res.stats["n_dependent"] == active.size, res.message
    assert energy_error(qp, res.u, ref.u) <= 1e-12


# --------------------------------------------------------------------- infeasible problems
def infeasible_problems() -> dict[str, ContactQP]:
    """Two opposite bounds that exclude each other, and a corner whose third row excludes
    what the other two allow (three dependent rows of a two-body problem)."""
    pair = ContactQP(A=2 * sp.eye(2), f=np.ones(2), B=sp.csr_matrix([[1.0, 0.0], [-1.0, 0.0]]),
                     g=[-1.0, -1.0], name="opposite-bounds")
    base = two_body_qp(seed=3)
    B = base.B.tocsr()
    corner = with_rows(base, -(B[0] + B[1]), np.array([-(base.g[0] + base.g[1]) - 0.1]),
                       "infeasible-corner")
    return {"pair": pair, "corner": corner}


@pytest.mark.parametrize("case", ["pair", "corner"])
@pytest.mark.parametrize("solver", SOLVERS + ("augmented_projection",))
def test_infeasible_problem_says_infeasible(case, solver):
    """The direct solvers meet the inconsistent rows in a face solve; the augmented
    projection reads the ray its multipliers run off along and has it confirmed by the
    same exact test, within a few outer steps."""
    qp = infeasible_problems()[case]
    res = solve(qp, solver, "mid")
    assert res.status == "failed" and "the problem is infeasible" in res.message, res.message
    assert "Farkas certificate" in res.message
    if solver == "augmented_projection":
        assert res.iterations <= AP_INFEASIBLE_STEPS, res.message


# --------------------------------------------------------------------- the row basis
def test_row_basis_of_independent_rows_is_the_plain_cholesky():
    rng = np.random.default_rng(0)
    B = rng.normal(size=(4, 7))
    K = B @ B.T
    basis = row_basis(K, rng.normal(size=4))
    assert basis.kept.tolist() == [0, 1, 2, 3] and basis.dropped.size == 0
    np.testing.assert_allclose(np.triu(basis.factor[0]), np.linalg.cholesky(K).T, rtol=1e-12,
                               atol=1e-12 * np.abs(K).max())


def test_row_basis_exchanges_a_violated_row_and_certifies_infeasibility():
    """Rows r, r (gaps 1 and 0): the basis must hold the tighter copy. Rows r, -r with
    gaps -1, -1: no u; the certificate is z = (1, 1)."""
    r = np.array([[1.0, 2.0, 0.0]])
    K = np.vstack([r, r]) @ np.vstack([r, r]).T
    for gaps, tight in (([1.0, 0.0], 1), ([0.0, 1.0], 0)):
        basis = row_basis(K, np.array(gaps))
        assert basis.kept.tolist() == [tight] and basis.dropped.tolist() == [1 - tight]
    K = np.vstack([r, -r]) @ np.vstack([r, -r]).T
    with pytest.raises(InfeasibleError, match=r"rows \[3, 8\] with weights z = \[1.0, 1.0\]"):
        row_basis(K, np.array([-1.0, -1.0]), labels=np.array([3, 8]))


# --------------------------------------------------------------------- every other solver
@pytest.mark.parametrize("solver", sorted(set(solvers()) - set(SOLVERS)))
def test_every_solver_answers_with_a_status(solver):
    """Dependent active rows and infeasible rows: every registered solver returns a
    status and says why when it does not converge; none raises."""
    problems = [two_body_qp(seed=7677), *infeasible_problems().values()]
    for qp in problems:
        res = solve(qp, solver, "mid")
        assert res.status in STATUSES and res.message, (qp.name, res.message)
        if qp.name != "two-body-7677":
            assert res.status != "converged", (qp.name, res.message)
