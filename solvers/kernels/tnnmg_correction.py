"""The linear correction of truncated nonsmooth Newton multigrid (:mod:`solvers.tnnmg`,
steps 2 and 4).

Step 2: the unknowns of the active set ``E`` fixed (the pivots at their bounds; on a
Tresca step also the sticking nodes' tangential unknowns), one V-cycle for ``A~ c = r``
on the others (:class:`TruncatedHierarchy`): the truncated prolongation
``D_I T^{-1} P`` at the finest transfer and the Galerkin coarse operators of the
truncated space, which differ from the untruncated ones by a low-rank term on the rows
of ``E``, recomputed when ``E`` changes and added in place (:class:`UpdatedOperator`).
Without a hierarchy the truncated system is solved directly (exact truncated Newton);
the unknowns around the constraint rows (:func:`contact_patch`) may be solved exactly in
each cycle. Gräser and Kornhuber (J. Comput. Math. 27, 2009), Gräser and Sander (IMA J.
Numer. Anal. 39, 2019).

Step 4: once a step leaves the active set as it found it, preconditioned conjugate
gradients on that face with the truncated V-cycle as the preconditioner, until a bound
or the negative multipliers end it (:class:`FaceCG`; Dostal's MPRGP, Optimal Quadratic
Programming Algorithms, 2009).
"""
from __future__ import annotations

from dataclasses import InitVar, dataclass, field
from typing import Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from pyamg.relaxation.relaxation import gauss_seidel

from problems.qp import ContactQP
from solvers.kernels.block_gs import FIXED, FREE, with_pattern
from solvers.kernels.cholesky import (FactorizationError, SamePatternCholesky,
                                      available_backends, canonical, factorize)
from solvers.kernels.tnnmg_system import FineSystem


class CoarseFactor:
    """The truncated coarsest operator's direct solver, factorised anew at every change of
    the truncation (:meth:`TruncatedHierarchy.truncate`).

    The truncation changes the operator's values, not its pattern
    (:class:`UpdatedOperator` keeps explicit zeros where updates go), so where MKL is
    present the ordering and symbolic analysis are kept and each change pays only the
    numerical factorisation (:class:`solvers.kernels.cholesky.SamePatternCholesky`);
    SuperLU where MKL is absent, and for a semidefinite operator (a body held by nothing
    yet), which the Cholesky kernel refuses.
    """

    def __init__(self):
        self.cholesky = SamePatternCholesky() if "pardiso" in available_backends() else None
        self.superlu = 0          # factorisations by SuperLU

    @property
    def analyses(self) -> int:
        """Factorisations that ordered and analysed the operator anew (SuperLU's all)."""
        return self.superlu + (self.cholesky.analyses if self.cholesky is not None else 0)

    def __call__(self, A: sp.spmatrix) -> Callable[[np.ndarray], np.ndarray]:
        """The solve of ``A``; the previous call's solve is no longer valid."""
        if self.cholesky is not None:
            try:
                return self.cholesky.factorize(A).solve
            except FactorizationError:
                pass
        self.superlu += 1
        return spla.splu(sp.csc_matrix(A)).solve


def positions(M: sp.csr_matrix, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """The positions of the entries ``(rows, cols)`` in ``M.data`` (sorted CSR), -1 where
    ``M`` has none; looks only at the rows asked for."""
    rows_u = np.unique(rows)
    starts = M.indptr[rows_u].astype(np.int64)
    lens = M.indptr[rows_u + 1] - starts
    if lens.sum() == 0:
        return -np.ones(rows.size, dtype=np.int64)
    offsets = np.r_[0, np.cumsum(lens)[:-1]]
    where = np.repeat(starts - offsets, lens) + np.arange(lens.sum())
    keys = np.repeat(rows_u.astype(np.int64), lens) * M.shape[1] + M.indices[where]
    want = rows.astype(np.int64) * M.shape[1] + cols
    k = np.minimum(np.searchsorted(keys, want), keys.size - 1)
    return np.where(keys[k] == want, where[k], -1)


class UpdatedOperator:
    """A coarse operator plus a sparse update (the truncation's low-rank term), changed in
    place where the update's pattern lies in the operator's (prepared with explicit zeros
    where updates go, from the update with every pivot truncated), the values it changed
    put back before the next update (no second copy of the operator); a coarse function
    truncated away entirely keeps a unit diagonal (an identity row) so that the smoother
    and the coarse solve stay defined. It owns ``base``: its values change in place."""

    def __init__(self, base: sp.csr_matrix, pattern: sp.spmatrix | None = None):
        work = canonical(base)
        if pattern is not None:               # explicit zeros where updates will go
            work = with_pattern(work, canonical(pattern))
        self.work = work
        self.dead_below = 1e-14 * max(float(np.max(work.diagonal(), initial=0.0)), 1e-300)
        self.touched = np.zeros(0, dtype=np.int64)
        self.saved = np.zeros(0)

    def set(self, delta: sp.spmatrix | None) -> sp.csr_matrix:
        """The operator plus ``delta`` (dead diagonals set to one); the returned matrix is
        the one the next call changes."""
        work = self.work
        work.data[self.touched] = self.saved
        self.touched, self.saved = np.zeros(0, dtype=np.int64), np.zeros(0)
        if delta is None or delta.nnz == 0:
            return work
        delta = sp.coo_matrix(delta)
        rows = np.unique(delta.row)
        pos = positions(work, delta.row, delta.col)
        diag = positions(work, rows, rows)
        if np.any(pos < 0) or np.any(diag < 0):   # rare: a coupling without a place
            out = sp.csr_matrix(work + delta)
            dead = out.diagonal() <= self.dead_below
            return sp.csr_matrix(out + sp.diags(dead.astype(float))) if dead.any() else out
        self.touched = np.union1d(pos, diag)
        self.saved = work.data[self.touched].copy()
        np.add.at(work.data, pos, delta.data)
        work.data[diag[work.data[diag] <= self.dead_below]] += 1.0
        return work


class TruncatedOperator:
    """``A~`` truncated at ``E`` for the exact truncated solve (no hierarchy): the rows and
    columns of ``E`` replaced by the identity's, in one pattern for every ``E`` (``A~``'s
    own, the update ``C``'s places included), so that :class:`CoarseFactor` keeps its
    analysis across changes of ``E``; the solve's other components are those of the
    free block's. Reads ``C``'s values at every :meth:`set` (a curvature may change
    them, never its places)."""

    def __init__(self, fine: FineSystem):
        A, C = canonical(fine.A), canonical(fine.C)
        self.fine = fine
        self.work = with_pattern(A, C)
        self.base = self.work.data.copy()             # A's values, zeros at C's places
        c = sp.coo_matrix(fine.C)                     # in the order of fine.C.data
        self.c_places = positions(self.work, c.row, c.col)
        n = A.shape[0]
        self.diag = positions(self.work, np.arange(n), np.arange(n))
        self.row = np.repeat(np.arange(n), np.diff(self.work.indptr))

    def set(self, E: np.ndarray) -> sp.csr_matrix:
        """``A~`` with the rows and columns of ``E`` the identity's (the returned matrix is
        the one the next call changes)."""
        work = self.work
        work.data[:] = self.base
        np.add.at(work.data, self.c_places, self.fine.C.data)
        frozen = np.zeros(work.shape[0], dtype=bool)
        frozen[E] = True
        work.data[frozen[self.row] | frozen[work.indices]] = 0.0
        work.data[self.diag[E]] = 1.0
        return work


@dataclass
class TruncatedHierarchy:
    """The V-cycle of the truncated linear correction (:mod:`solvers.tnnmg`, step 2)."""

    fine: FineSystem
    P: sp.csr_matrix | None            # T^{-1} P_last: coarse level -> transformed fine
    coarse_P: list                     # original prolongations below (coarse -> finer)
    A_coarse: InitVar[list]            # untruncated Galerkin operators, finest coarse first
                                       # (handed to coarse_ops, which own them)
    sweeps: int
    truncate_coarse: bool
    patch: np.ndarray | None = None    # unknowns of the contact patch (None: no patch solve)
    truncatable: np.ndarray | None = None  # unknowns that may be truncated (None: the pivots)
    curvature_places: sp.spmatrix | None = None  # every place of a fine-level curvature
                                       # (SlipCurvature.places; None: no curvature)
    frozen: np.ndarray | None = None   # the truncated unknowns
    A_t: list = field(default_factory=list)
    coarse_solve: Callable | None = None
    mode: np.ndarray | None = None
    updates: int = 0
    patch_keep: np.ndarray | None = None
    patch_rows: sp.csr_matrix | None = None
    patch_solve: Callable | None = None
    coarse_ops: list = field(default_factory=list)
    coarse_R: list = field(default_factory=list)
    coarse_factor: CoarseFactor = field(default_factory=CoarseFactor)
    exact: "TruncatedOperator | None" = None  # without a hierarchy: A~ truncated

    def __post_init__(self, A_coarse):
        self.coarse_R = [sp.csr_matrix(Pl.T) for Pl in self.coarse_P]  # restrictions, once
        pivots = self.fine.box.pivot if self.truncatable is None else self.truncatable
        patterns = (self._deltas(pivots, self.curvature_places, places=True)
                    if self.truncate_coarse and self.P is not None and pivots.size
                    else [None] * len(A_coarse))
        self.coarse_ops = [UpdatedOperator(M, d) for M, d in zip(A_coarse, patterns)]

    def _deltas(self, E: np.ndarray, curvature: sp.spmatrix | None = None,
                places: bool = False) -> list:
        """The truncation's change of each coarse operator when the pivots ``E`` are
        truncated: ``Y'A~_EE Y - Y'X - X'Y`` (:mod:`solvers.tnnmg`), plus ``P~' K P~`` for a
        fine-level ``curvature`` ``K`` added to ``A~`` off ``E``
        (:class:`solvers.kernels.tnnmg_tresca.SlipCurvature`), and its Galerkin products.

        ``places=True``: every place a change can take, not its value: the same products
        of the matrices' absolute values, summed (no cancellation drops a place), for
        :class:`UpdatedOperator`'s pattern; ``curvature`` then the pattern of every ``K``.
        """
        P, A_E = self.P, self.fine.rows(E)
        coarse_P, coarse_R = self.coarse_P, self.coarse_R
        if places:
            P, A_E, coarse_P, coarse_R = abs(P), abs(A_E), [abs(M) for M in coarse_P], \
                [abs(M) for M in coarse_R]
            curvature = None if curvature is None else abs(sp.csr_matrix(curvature))
        Y = P[E]
        X = A_E @ P
        Yt = Y.T.tocsr()
        YtX = Yt @ X
        if places:
            delta = Yt @ (A_E[:, E] @ Y) + YtX + YtX.T.tocsr()
        else:
            delta = Yt @ (A_E[:, E] @ Y) - YtX - YtX.T.tocsr()
        if curvature is not None:
            delta = delta + sp.csr_matrix(P.T @ (curvature @ P))
        deltas = [delta]
        for Pl, Rl in zip(reversed(coarse_P), reversed(coarse_R)):
            deltas.append(Rl @ (deltas[-1] @ Pl))
        return deltas

    def _update_patch(self, E: np.ndarray) -> None:
        """Factorise the truncated system on the contact patch (the active pivots out)."""
        keep = np.setdiff1d(self.patch, E, assume_unique=False)
        self.patch_keep = keep
        self.patch_rows = self.fine.rows(keep)
        self.patch_solve = factorize(self.patch_rows[:, keep]).solve

    def _patch_step(self, c: np.ndarray, r: np.ndarray) -> None:
        """``c += `` the exact correction on the contact patch (in place)."""
        keep = self.patch_keep
        c[keep] += self.patch_solve(r[keep] - self.patch_rows @ c)

    def update(self, active: np.ndarray) -> None:
        """Truncate at the active pivots (a repeated set keeps its operators)."""
        fine = self.fine
        mode = np.full(fine.box.node_ptr.size - 1, FREE, dtype=np.int64)
        mode[fine.bounded_blocks[active[fine.box.block_row[fine.bounded_blocks]]]] = FIXED
        self.truncate(fine.box.pivot[active], mode)

    def truncate(self, E: np.ndarray, mode: np.ndarray,
                 curvature: sp.spmatrix | None = None) -> None:
        """Truncate at the unknowns ``E``, the linear smoother's block modes ``mode`` (a
        repeated ``E`` keeps its operators); ``curvature``: a fine-level term the fine
        system already holds (:class:`solvers.kernels.tnnmg_tresca.SlipCurvature`), passed to
        the coarse operators too (every call then updates them)."""
        if curvature is None and self.frozen is not None and np.array_equal(E, self.frozen):
            return
        self.updates += 1
        self.frozen = E.copy()
        fine = self.fine
        self.mode = mode
        if self.patch is not None and self.P is not None:
            self._update_patch(E)
        if self.P is None:                       # no hierarchy: exact truncated solve
            if self.exact is None:
                self.exact = TruncatedOperator(fine)
            factor = self.coarse_factor(self.exact.set(E))

            def solve(r):
                out = factor(r)
                out[E] = 0.0
                return out
            self.coarse_solve = solve
            return
        deltas = (self._deltas(E, curvature)
                  if self.truncate_coarse and (E.size or curvature is not None)
                  else [None] * len(self.coarse_ops))
        self.A_t = [op.set(delta) for op, delta in zip(self.coarse_ops, deltas)]
        self.coarse_solve = self.coarse_factor(self.A_t[-1])

    def vcycle(self, r: np.ndarray, sweeps: int | None = None) -> np.ndarray:
        """One V(sweeps, sweeps)-cycle for the truncated system, zero start; ``r`` is zero
        on the active pivots and so is the result (``sweeps``: the hierarchy's unless
        given)."""
        if self.P is None:
            return self.coarse_solve(r)
        sweeps = self.sweeps if sweeps is None else sweeps
        fine = self.fine
        E = self.frozen
        c = np.zeros_like(r)
        for _ in range(sweeps):
            fine.sweep(c, r, self.mode, True)
        if self.patch_solve is not None:
            self._patch_step(c, r)
        res = r - fine.matvec(c)
        res[E] = 0.0
        corr = self.P @ self._coarse(0, self.P.T @ res, sweeps)
        corr[E] = 0.0
        c += corr
        if self.patch_solve is not None:
            self._patch_step(c, r)
        for _ in range(sweeps):
            fine.sweep(c, r, self.mode, False)
        return c

    def _coarse(self, lvl: int, b: np.ndarray, sweeps: int) -> np.ndarray:
        if lvl == len(self.A_t) - 1:
            return self.coarse_solve(b)
        A = self.A_t[lvl]
        x = np.zeros_like(b)
        gauss_seidel(A, x, b, iterations=sweeps, sweep="symmetric")
        x += self.coarse_P[-(lvl + 1)] @ self._coarse(
            lvl + 1, self.coarse_R[-(lvl + 1)] @ (b - A @ x), sweeps)
        gauss_seidel(A, x, b, iterations=sweeps, sweep="symmetric")
        return x


def contact_patch(qp: ContactQP, fine: FineSystem, hops: int) -> np.ndarray | None:
    """The unknowns of the constraint rows (constrained nodes and opposing facets) and
    ``hops`` graph layers of ``A~`` around them; None for ``hops = 0`` or no rows."""
    if hops == 0 or qp.m == 0:
        return None
    patch = np.unique(qp.B.tocsr().indices)
    for _ in range(hops):
        patch = np.union1d(patch, fine.rows(patch).indices)
    return patch


def hierarchy(qp: ContactQP, fine: FineSystem, sweeps: int, truncate_coarse: bool, hops: int,
              truncatable: np.ndarray | None = None,
              curvature_places: sp.spmatrix | None = None) -> TruncatedHierarchy:
    prolongations = [sp.csr_matrix(P) for P in qp.multilevel.prolongations]
    if not prolongations:
        return TruncatedHierarchy(fine, None, [], [], sweeps, truncate_coarse,
                                  truncatable=truncatable)
    P = fine.box.prolongation(prolongations[-1])
    # P~' A~ P~ = P' T' A T T^{-1} P = P' A P: the untruncated coarse operators are the
    # scene's own Galerkin products
    mats = [fine.A]                              # all products CSR by CSR (no conversion
    for Pl in reversed(prolongations):           # of A to CSC)
        mats.append(sp.csr_matrix(sp.csr_matrix(Pl.T) @ (mats[-1] @ Pl)))
    mats = mats[1:]
    return TruncatedHierarchy(fine, P, prolongations[:-1], mats, sweeps, truncate_coarse,
                              contact_patch(qp, fine, hops), truncatable, curvature_places)


@dataclass
class FaceCG:
    """Preconditioned CG on a face of the feasible set: the active pivots ``E`` held at
    their bounds, the truncated V-cycle (symmetric: forward sweeps before, backward after)
    as the preconditioner (Dostal's MPRGP, Optimal Quadratic Programming Algorithms, 2009,
    with the multigrid preconditioner in the face).

    A CG step minimises the energy over a growing Krylov space of the face, so the energy
    never rises; the step is cut where a free pivot meets its bound (an *expansion*: the
    face is left, the next step is TNNMG's), and the face is left too when the chopped
    residual (the negative multipliers on ``E``) outweighs the free one (*proportioning*:
    the next TNNMG step's smoother releases them). A face whose minimiser is not the
    solution is left in finitely many steps, so TNNMG's global convergence stands.
    """

    E: np.ndarray
    p: np.ndarray | None = None
    rz: float = 0.0
    sweeps: int | None = None          # the preconditioner's V(sweeps, sweeps); None: the
                                       # hierarchy's (the TNNMG steps')

    def _direction(self, fine: FineSystem, ml: "TruncatedHierarchy", g: np.ndarray
                   ) -> tuple[np.ndarray, float] | None:
        """The next conjugate direction ``self.p`` from the face's negative gradient ``g``
        (zero on ``E``): ``(A~ p, the step to the face's minimum along p)``, or None where
        ``p`` is no descent direction."""
        z = ml.vcycle(g, self.sweeps)
        rz = float(g @ z)
        self.p = z if self.p is None else z + (rz / self.rz) * self.p
        self.rz = rz
        q = fine.matvec(self.p)
        curvature = float(self.p @ q)
        if not (curvature > 0.0 and rz > 0.0):
            return None
        return q, rz / curvature

    def step(self, fine: FineSystem, ml: "TruncatedHierarchy", v: np.ndarray, r: np.ndarray,
             piv: np.ndarray, upper: np.ndarray, active: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, float, bool]:
        """One CG step from ``v`` (residual ``r``): ``(v, r, alpha, leave)``."""
        r_t = r.copy()
        r_t[self.E] = 0.0
        found = self._direction(fine, ml, r_t)
        if found is None:
            return v, r, 0.0, True
        q, alpha = found
        d = self.p[piv]
        rising = (d > 0) & ~active
        leave = False
        if rising.any():
            room = (upper[rising] - v[piv][rising]) / d[rising]
            if room.min() < alpha:
                alpha, leave = max(float(room.min()), 0.0), True
        v = v + alpha * self.p
        r = r - alpha * q
        v[piv] = np.minimum(v[piv], upper)
        chopped = np.minimum(r[self.E], 0.0)
        free = r.copy()
        free[self.E] = 0.0
        if float(chopped @ chopped) > float(free @ free):
            leave = True
        return v, r, alpha, leave
