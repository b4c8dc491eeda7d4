"""The agreement check several test files share: named solvers against a reference."""
from __future__ import annotations

from problems.kkt import energy_error
from solvers.certificate import certifiable
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


def within_certificate(err: float, bound: float, floor: float) -> bool:
    """Whether a true relative energy error ``err`` lies within what a certificate with
    relative bound ``bound`` and floating-point floor ``floor`` certifies: the accuracy it
    can certify (:func:`solvers.certificate.certifiable`: the bound, or four times its
    floor), plus the floor itself, the bound's own rounding (a sharp bound equals the error
    up to it). Never a raw bound alone, which below the floor can read 0."""
    return bool(err <= certifiable(bound, floor) + floor)
