"""The suite's reference solution of a problem (DESIGN.md, performance conventions): the
exact PDAS where a factorisation is affordable, else an iterative solve to verified
KKT residuals and certified energy bound: TNNMG where it takes the problem, the
augmented projection with face-CG acceleration otherwise."""
from __future__ import annotations

from problems.qp import ContactQP
from solvers.base import SolveResult
from solvers.interface import solve, solvers
from solvers.pdas import SCHUR_MAX_M


#: Largest number of unknowns for which the exact reference factorises ``A`` (PDAS through
#: the dual problem on the contact rows), per dimension: in 2D a factorisation stays cheap
#: to millions of unknowns; in 3D nested-dissection fill grows like N^(4/3), and beyond
#: the limit the factorisation takes longer and more memory than the iterative reference
#: (docs/guide/measurements.md).
DIRECT_REFERENCE_LIMIT = {2: 2_500_000, 3: 150_000}


def reference_solve(qp: ContactQP, tol: float = 1e-10,
                    time_limit: float | None = None) -> SolveResult:
    """The suite's reference solution of ``qp`` (DESIGN.md, performance conventions).

    The exact PDAS (``A`` factorised once, the dual problem on the contact rows solved
    by active sets; :mod:`solvers.pdas`) where a factorisation is affordable
    (:data:`DIRECT_REFERENCE_LIMIT`); otherwise an iterative solve to verified KKT
    residuals and certified energy bound ``<= tol``: TNNMG (:mod:`solvers.tnnmg`) where
    it takes the problem, else the augmented projection with face-CG acceleration
    (TNNMG skips a stabilisation block, rows that share nodes and floating bodies), the
    faster of the two where both run, to the same answer (docs/guide/measurements.md).
    The result's ``solver`` says which route
    ran; its ``status`` is verified against ``tol`` either way.
    """
    if qp.n <= DIRECT_REFERENCE_LIMIT.get(qp.dim, 0) and qp.m <= SCHUR_MAX_M:
        return solve(qp, "pdas", tol=tol, time_limit=time_limit, method="schur")
    if solvers()["tnnmg"].supports(qp)[0]:
        return solve(qp, "tnnmg", tol=tol, time_limit=time_limit)
    return solve(qp, "augmented_projection", tol=tol, time_limit=time_limit, max_iter=5000,
                 accelerate="face_cg")
