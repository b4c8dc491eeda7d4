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
#: the dual problem on the contact rows), per dimension. Measured with one thread: 2D
#: level 4 (523k unknowns) factorises in ~3 s; in 3D, 104k unknowns take ~7 s and
#: 1 GB, 346k ~90 s and 4-5 GB (nested-dissection fill grows like N^(4/3) in 3D), where
#: the iterative reference takes ~9 s.
DIRECT_REFERENCE_LIMIT = {2: 2_500_000, 3: 150_000}


def reference_solve(qp: ContactQP, tol: float = 1e-10,
                    time_limit: float | None = None) -> SolveResult:
    """The suite's reference solution of ``qp`` (DESIGN.md, performance conventions).

    The exact PDAS (``A`` factorised once, the dual problem on the contact rows solved
    by active sets; :mod:`solvers.pdas`) where a factorisation is affordable
    (:data:`DIRECT_REFERENCE_LIMIT`); otherwise an iterative solve to verified KKT
    residuals and certified energy bound ``<= tol``: TNNMG (:mod:`solvers.tnnmg`) where
    it takes the problem, else the augmented projection with face-CG acceleration
    (TNNMG skips a stabilisation block, rows that share nodes and floating bodies). On
    cube-sphere P2 level 2 (391k unknowns, tol 1e-10) TNNMG takes 31 s and 2.4 GB
    where the augmented projection takes 23 min; at P2 level 1 (52k) 10 s against 74 s,
    the two within 8e-11 in relative energy. The result's ``solver`` says which route
    ran; its ``status`` is verified against ``tol`` either way.
    """
    if qp.n <= DIRECT_REFERENCE_LIMIT.get(qp.dim, 0) and qp.m <= SCHUR_MAX_M:
        return solve(qp, "pdas", tol=tol, time_limit=time_limit, method="schur")
    if solvers()["tnnmg"].supports(qp)[0]:
        return solve(qp, "tnnmg", tol=tol, time_limit=time_limit)
    return solve(qp, "augmented_projection", tol=tol, time_limit=time_limit, max_iter=5000,
                 accelerate="face_cg")
