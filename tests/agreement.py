"""The agreement check several test files share: named solvers against a reference."""
from __future__ import annotations

from problems.kkt import energy_error
from solvers.interface import solve

#: Relative energy-norm distance two verified answers of the same problem may have.
AGREEMENT = 1e-8


def assert_solvers_agree(qp, names, reference: str = "pdas", tol: str = "high"):
    """``reference`` and every solver of ``names`` verified ``converged`` at ``tol``, each
    within :data:`AGREEMENT` of the reference's answer in the relative energy norm;
    returns the reference's result."""
    ref = solve(qp, reference, tol)
    assert ref.status == "converged", ref.message
    for name in names:
        res = solve(qp, name, tol)
        assert res.status == "converged", (name, res.message)
        assert energy_error(qp, res.u, ref.u) <= AGREEMENT, name
    return ref
