"""Truncated nonsmooth Newton multigrid (TNNMG): the contact community's fastest method.

Gräser and Kornhuber (J. Comput. Math. 27, 2009), Gräser and Sander (IMA J. Numer. Anal.
39, 2019; the dune-tnnmg module). The nodal constraints become bounds on single unknowns
by the change of variables of Krause and Wohlmuth (:mod:`solvers.kernels.contact_box`:
``u = T v``, ``A~ = T' A T``, ``v[pivot] <= upper``). One step from ``v``:

1. nonlinear presmoothing: ``presmoothing`` node-block Gauss-Seidel sweeps, each block
   minimised exactly (a bound crossed is clamped and the rest of the block solved
   again; :mod:`solvers.kernels.block_gs`), alternating direction;
2. the active set ``E = {pivot : v = upper}`` and the truncated linear correction: one
   V-cycle for ``A~ c = r`` on the unknowns off ``E`` (``c = 0`` on ``E``), with the
   truncated prolongation ``D_I T^{-1} P`` at the finest transfer and the Galerkin
   coarse operators of the truncated space; these differ from the untruncated ones by
   a low-rank term on the rows of ``E``, so only that term is recomputed when ``E``
   changes (``A_c,t = A_c - Y'X - X'Y + Y'A~_EE Y``, ``Y = P~[E]``, ``X = A~[E] P~``,
   passed down by Galerkin products of the difference and added in place:
   :class:`_UpdatedOperator`; the untruncated ones are the scene's own ``P'AP``, since
   ``P~'A~P~ = P'T'A T T^{-1} P``);
3. projection of the correction onto the feasible set (``c <= upper - v`` at the
   pivots) and the exact line search on the energy over the feasible segment; beside it
   before it, points on the projection arc (``min(v + a c, upper)``, ``a = 1, 1/4,
   ...``), the first with a lower energy taken (:func:`_step`: the arc takes all bounds
   a correction crosses at once, where the projected line search crawls when a soft
   body meets a stiff one);
4. once a step leaves the active set as the previous one left it, conjugate gradients on
   that face (:class:`_FaceCG`; Dostal's MPRGP with the truncated V-cycle as the
   preconditioner) until a free pivot meets its bound or the negative multipliers
   outweigh the free residual; then TNNMG steps again. A TNNMG step is a preconditioned
   steepest descent on the face; CG is what the linear floor (multigrid-PCG) does, and
   towards incompressibility, where one V-cycle contracts slowly, it cuts the steps by
   two to three times.

Every part decreases the energy, so the iteration is monotone and converges globally
for any number of smoothing sweeps. The geometric hierarchy is the scene's refinement
hierarchy (``qp.multilevel``); without one (the roll stack) the correction is a direct
solve of the truncated system, refactorised when the active set changes (exact
truncated Newton; :func:`solvers.kernels.cholesky.factorize`). It stops when the suite's
verification passes: the four KKT residuals and the certified energy bound (:func:`certify`).

Memory: ``A~`` is the scene's ``A`` (not copied) plus the transformation's update on the
rows near the contact, which the compiled sweep reads beside it; ``T`` and ``T^{-1}`` are
kept as their changed rows; each coarse operator is held once (with explicit zeros where
the truncation's term goes). Measured: 1.16x the peak memory of the multigrid-PCG linear
solve in 2D (262k nodes) and 0.95x in 3D (135k), the input both hold included (the
solver comparison's page).

Nested iteration from the coarsest level is the caller's: the scene's coarser problems,
solved in turn, give ``u0`` (the augmented-projection study does this for every
nested row). Floating bodies are handled as they come: the truncation fixes the active
normal unknowns, which hold a body that only contact holds. The stabilised problem
(Sect. 7.5) is ``skipped``: its reverse rows do not have the one-row-per-node structure;
so are mortar rows with standard multipliers (a non-diagonal ``D``), while mortar rows
with dual multipliers (``D`` diagonal, :mod:`problems.fem.mortar`) are one row per
constrained node and are taken.

Tresca friction (one step of a load path, :class:`problems.friction.data.Friction`; Gräser and
Kornhuber's setting of a block-separable nonsmooth energy). The tangential rows become
coordinates too (:mod:`solvers.kernels.contact_box`: ``T_i u = theta_i R_i v_t,i``, ``v_t,i`` the
node's one (2D) or two (3D) unknowns after ``v_s[0]``, ``R_i`` orthogonal), so the energy
``J~(v) + sum_i weight_i |v_t,i - centre_i|`` (:class:`_TrescaTerm`; in 3D the Euclidean
norm, the isotropic disc) is separable by node blocks with the normal bound on
``v_s[0]``. The step is the one above with:

1. the node block's exact minimiser of the normal bound and the term (the normal unknown
   free or at its bound, times stick or slip; 2D: :func:`solvers.kernels.block_gs._tresca_block`,
   3D: :func:`solvers.kernels.block_gs.disc_block_minimiser`, a secular equation solved to
   round-off);
2. the truncation of the normal-active pivots and of the sticking nodes' tangential
   unknowns (slip exactly zero); a slipping node's term enters the correction's
   right-hand side by its derivative (``weight sign(slip)``; 3D: ``weight slip/|slip|``;
   in 2D the term is linear near the iterate, in 3D its curvature across the slip
   direction goes into the correction's operator, :class:`_SlipCurvature`);
3. the line search on the nonsmooth energy: in 2D exact over its kinks
   (:func:`_tresca_step`), in 3D a safeguarded Newton search on its nondecreasing
   derivative to round-off (:func:`_disc_line_search`);
4. in 2D, conjugate gradients on a face (option ``krylov="cg"``, :class:`_TrescaFaceCG`):
   once a step leaves the normal active set, the stick set and the slip signs as the
   previous one left them (:class:`_TrescaFace`), the energy is quadratic there (each
   slipping row's ``weight_i |v_t,i - centre_i|`` is linear with its sign fixed), and CG
   preconditioned by the truncated V-cycle (V(2,2), :data:`TRESCA_FACE_SWEEPS`) runs on it
   until a free pivot meets its bound, a slipping row reaches its kink, or the negative
   normal multipliers and the sticking rows' excess ``|r| - weight`` outweigh the free
   gradient; then TNNMG steps again. In 3D each step is a TNNMG step: with slipping
   nodes the energy on a face is not quadratic (``|z|`` of a 2-vector is curved across
   the slip direction), so CG's conjugacy does not hold there.

It stops when the suite's verification passes: the friction KKT residuals
(:func:`problems.friction.residuals.friction_residuals`) and the certified energy bound of the Tresca step
(:func:`certify` with ``lam``) meet tol, with the tangential multipliers
``lam_i = R_i r[v_t,i] / theta_i`` from the stationarity of the tangential unknowns, in
the disc ``|lam_i| <= s_i`` (2D: ``[-s_i, s_i]``, and ``s_i sign(slip_i)`` where the row
slips, so that the certified bound follows the energy error closely;
``SolveResult.tangential``; :meth:`_TrescaTerm.multipliers`). A Coulomb problem is solved
as the Tresca step of its given slip bound (the fixed point ``s = mu p`` over Tresca steps
is the load path's). The solve's ``stats`` split its steps at the last change of its face
(``steps_to_face``, ``steps_on_face``; :func:`_face_state`): the steps that find the
normal active set and the stick set, and the multigrid steps on the face found.
"""
from __future__ import annotations

import time
from dataclasses import InitVar, dataclass, field
from typing import Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from pyamg.relaxation.relaxation import gauss_seidel

from problems.friction.data import Friction
from problems.friction.residuals import friction_residuals
from problems.kkt import kkt_residuals
from problems.qp import ContactQP
from problems.spec import Options, Parameter
from solvers.kernels.block_gs import (BOTH_FIXED, BOUNDED, FIXED, FREE, TANGENT_FIXED, TRESCA,
                                      block_gauss_seidel, block_inverses, tresca_block_gauss_seidel,
                                      unsigned_index, with_pattern)
from solvers.base import VERIFIED_PRESETS, Role, SolveResult, SolverSpec
from solvers.certificate import certify
from solvers.kernels.cholesky import FactorizationError, factorize
from solvers.kernels.contact_box import (BoxTransformation, TransformationError, box_transformation,
                                         check_structure)


#: The suite's KKT check (and the certificate) runs once the transformed problem's own
#: stationarity residual is within this factor of tol (:func:`_stationarity`; the two
#: scalings differ by the transformation's norm, O(1)).
CHECK_FACTOR = 10.0

#: V-cycle sweeps by dimension (option ``sweeps=0``). Measured at the quick levels
#: (circle-square 66k/262k nodes, cube-sphere 18k/135k, one quiet run each): in 2D V(1,1)
#: keeps the steps level-independent (9 and 10) at the lower time, V(2,2) costs 15% more;
#: in 3D one node-block sweep a side smooths too little for that (11 -> 13 steps per level,
#: +18%), V(2,2) keeps it (8 -> 9) at the same time to the target.
AUTO_SWEEPS = {2: 1, 3: 2}

#: Nonlinear presmoothing sweeps per step (option ``presmoothing=0``): one without
#: friction; two on a Tresca step, where the sweeps alone move the slip front (the
#: truncated correction holds every sticking node). Measured on the nested load paths at
#: Q/(mu P) 0.3 / 0.7 (tangential step to tol 1e-10, :mod:`workflows.scripts.friction_study`'s
#: scenes): circle-square levels 3 and 4 10 / 10 and 9 / 12 steps with one, 9 / 10 and
#: 9 / 10 with two; cube-sphere levels 2 and 3 12 / 12 and 15 / 15 with one, 11 / 11 and
#: 14 / 15 with two. Never more steps, for one sweep more per step.
AUTO_PRESMOOTHING = {False: 1, True: 2}

#: V-cycle sweeps of a 3D Tresca step's TNNMG steps (option ``sweeps=0``; 2D as
#: :data:`AUTO_SWEEPS`). A 3D step takes no CG on its face, so each V-cycle's contraction
#: is the step's: with V(2,2) it falls with the level, 0.16 per step at cube-sphere level 2
#: and 0.28 at level 3 (the normal step, where no stick set is found, too: 12 -> 15 steps
#: to tol 1e-10). Measured on the nested load paths (Q/(mu P) 0.3 / 0.7, tangential step
#: to tol 1e-10, two presmoothing sweeps): levels 2 and 3 take 11 / 11 and 14 / 15 steps
#: with V(2,2), 9 / 10 and 11 / 10 with V(3,3), 8 / 9 and 9 / 10 with V(4,4), the sweeps a
#: compiled pass over the mesh each.
TRESCA_3D_SWEEPS = 4

#: V-cycle sweeps of the preconditioner of CG on a face of a 2D Tresca step (option
#: ``sweeps=0``): two a side, as the linear floor's V-cycle smooths (a symmetric
#: Gauss-Seidel sweep, forward and back, before and after). Measured on circle-square
#: level 3 (Q/(mu P) 0.7): to energy error 1e-6 CG with one a side takes 12 steps, as
#: TNNMG steps alone do; with two, 11.
TRESCA_FACE_SWEEPS = 2

#: The projection arc's backtracking: step factor and smallest step (:func:`_step`).
ARC_FACTOR = 0.25
ARC_MIN = 1e-4


@dataclass
class _Fine:
    """The transformed fine-level system ``A~ = A + C`` and what its block smoother needs:
    the scene's ``A`` itself (not copied) and the transformation's update ``C``
    (:meth:`~solvers.kernels.contact_box.BoxTransformation.operator_update`, rows near the
    contact only)."""

    A: sp.csr_matrix
    C: sp.csr_matrix
    f: np.ndarray
    box: BoxTransformation
    diag0: np.ndarray
    inv_full: np.ndarray
    inv_sub: np.ndarray
    bounded_blocks: np.ndarray
    upper_block: np.ndarray
    kernel_index: tuple = ()
    update_rows: np.ndarray | None = None
    update_part: sp.csr_matrix | None = None
    tresca: "_TrescaTerm | None" = None

    def __post_init__(self):
        # unsigned indices (views, no copies): the compiled sweep then skips numba's
        # negative-index test on every entry
        self.kernel_index = tuple(unsigned_index(a) for a in (
            self.A.indptr, self.A.indices, self.C.indptr, self.C.indices,
            self.box.node_dofs))
        self.update_rows = np.flatnonzero(np.diff(self.C.indptr))
        self.update_part = sp.csr_matrix(self.C[self.update_rows])

    def sweep(self, x: np.ndarray, b: np.ndarray, mode: np.ndarray, forward: bool) -> None:
        indptr, indices, c_indptr, c_indices, node_dofs = self.kernel_index
        if self.tresca is None:
            block_gauss_seidel(indptr, indices, self.A.data, c_indptr, c_indices, self.C.data,
                               x, b, self.box.node_ptr, node_dofs, self.diag0, self.inv_full,
                               self.inv_sub, mode, self.upper_block, forward)
            return
        tresca_block_gauss_seidel(indptr, indices, self.A.data, c_indptr, c_indices,
                                  self.C.data, x, b, self.box.node_ptr, node_dofs, self.diag0,
                                  self.inv_full, self.inv_sub, mode, self.upper_block,
                                  self.tresca.weight_block, self.tresca.centre_block, forward)

    def matvec(self, x: np.ndarray) -> np.ndarray:
        """``A~ x``."""
        out = self.A @ x
        out[self.update_rows] += self.update_part @ x
        return out

    def rows(self, idx: np.ndarray) -> sp.csr_matrix:
        """The rows ``idx`` of ``A~``."""
        return sp.csr_matrix(self.A[idx] + self.C[idx])


@dataclass
class _TrescaTerm:
    """Tresca's term of a step in the transformed unknowns (:mod:`solvers.kernels.contact_box`:
    ``T_i u = theta_i R_i v_t,i``, ``v_t,i`` the ``k = dim - 1`` tangential unknowns of
    constrained node ``i``, ``R_i`` orthogonal; 2D: ``R_i = 1``)::

        sum_i s_i |T_i u + offset_i - previous_i| = sum_i weight_i |v_t,i - centre_i|

    with ``weight = s |theta|`` and ``centre_i = R_i' (previous_i - offset_i) / theta_i``
    (``|.|`` Euclidean in 3D); per node (``pivot``, ``centre`` node-major, ``k`` per node),
    and per node block for the compiled sweep (zero weight off the constrained nodes).
    """

    pivot: np.ndarray
    theta: np.ndarray
    frame: np.ndarray
    weight: np.ndarray
    centre: np.ndarray
    weight_block: np.ndarray
    centre_block: np.ndarray

    @property
    def k(self) -> int:
        """Tangential unknowns per node."""
        return self.frame.shape[1]

    def _nodes(self, a: np.ndarray) -> np.ndarray:
        """A node-major vector as ``(m, k)``."""
        return a.reshape(-1, self.k)

    def _offsets(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per node ``v_t,i - centre_i`` ``(m, k)`` and its length."""
        z = self._nodes(v[self.pivot] - self.centre)
        return z, np.sqrt(np.einsum("ij,ij->i", z, z))

    def value(self, v: np.ndarray) -> float:
        if self.k == 1:
            return float(self.weight @ np.abs(v[self.pivot] - self.centre))
        return float(self.weight @ self._offsets(v)[1])

    def stick(self, v: np.ndarray) -> np.ndarray:
        """Nodes whose slip is exactly zero (with a positive slip bound)."""
        if self.k == 1:
            return (v[self.pivot] == self.centre) & (self.weight > 0)
        return np.all(self._nodes(v[self.pivot] == self.centre), axis=1) & (self.weight > 0)

    def multipliers(self, residual_v: np.ndarray, friction: Friction, v: np.ndarray
                    ) -> np.ndarray:
        """The tangential multipliers ``lam`` (``A u + B'p + T'lam = f``) from the residual
        ``f~ - A~v`` of the transformed problem: ``R_i r[pivot_i] / theta_i`` (the
        stationarity of the tangential unknowns), in the friction discs ``|lam_i| <= s_i``
        (:meth:`problems.friction.data.Friction.clip`; as ``p >= 0``: what is left over stays in the
        stationarity residual).

        A slipping node's multiplier is the one its slip demands, ``s_i sign(slip_i)``
        (``sign(theta_i (v_t,i - centre_i))``; 3D: ``s_i slip_i / |slip_i|`` with
        ``slip_i = theta_i R_i z_i``, ``z_i = v_t,i - centre_i``): then
        ``lam_i . slip_i = s_i |slip_i|`` exactly, and the iterate's error stays in the
        stationarity residual, which the
        certified bound weighs by ``A^-1`` (second order), instead of in the slip
        complementarity, which enters the duality gap linearly (:func:`certify`: with
        the clipped residual the bound lags the energy error by two orders at energy
        error 1e-7 on circle-square level 3). Any multiplier in ``[-s_i, s_i]`` gives a
        certified bound."""
        if self.k == 1:
            lam = friction.clip(residual_v[self.pivot] / self.theta)
            slip = np.sign(self.theta) * np.sign(v[self.pivot] - self.centre)
            slipping = (slip != 0) & (self.weight > 0)
            lam[slipping] = friction.slip_bound[slipping] * slip[slipping]
            return lam
        lam = self._nodes(friction.clip((np.einsum(
            "ijl,il->ij", self.frame, self._nodes(residual_v[self.pivot]))
            / self.theta[:, None]).ravel()))
        z, length = self._offsets(v)
        slipping = (length > 0) & (self.weight > 0)
        direction = np.einsum("ijl,il->ij", self.frame[slipping], z[slipping]) \
            * (np.sign(self.theta[slipping]) / length[slipping])[:, None]
        lam[slipping] = friction.slip_bound[slipping, None] * direction
        return lam.ravel()

    def gradient(self, v: np.ndarray) -> np.ndarray:
        """Per tangential unknown, the term's derivative off the kinks (``weight
        sign(slip)``; 3D: ``weight z / |z|``, ``z = v_t - centre``; 0 at a kink)."""
        if self.k == 1:
            return self.weight * np.sign(v[self.pivot] - self.centre)
        z, length = self._offsets(v)
        moving = length > 0
        out = np.zeros_like(z)
        out[moving] = z[moving] * (self.weight[moving] / length[moving])[:, None]
        return out.ravel()


def _tresca_term(qp: ContactQP, box: BoxTransformation) -> _TrescaTerm:
    fr = qp.friction
    theta, frame = box.tangential_scale, box.tangential_frame
    k = frame.shape[1]
    weight = np.asarray(fr.slip_bound, dtype=float) * np.abs(theta)
    shift = np.asarray(fr.previous, dtype=float) - fr.offset
    if k == 1:
        centre = shift / theta
    else:
        centre = (np.einsum("ijl,ij->il", frame, shift.reshape(-1, k))
                  / theta[:, None]).ravel()
    nb = box.node_ptr.size - 1
    weight_block, centre_block = np.zeros(nb), np.zeros((nb, k))
    rows = box.block_row
    bounded = rows >= 0
    weight_block[bounded] = weight[rows[bounded]]
    centre_block[bounded] = centre.reshape(-1, k)[rows[bounded]]
    return _TrescaTerm(box.tangential_pivot, theta, frame, weight, centre, weight_block,
                       centre_block.ravel())


def _fine_system(qp: ContactQP, tresca: bool = False) -> _Fine:
    """The transformed fine system; ``tresca``: the tangential rows made coordinates too and
    the step's Tresca term (:class:`_TrescaTerm`)."""
    box = box_transformation(qp, qp.friction.T if tresca else None)
    A = sp.csr_matrix(qp.A)
    if not A.has_sorted_indices:
        A = A.sorted_indices()
    C = box.operator_update(A)
    diag0, inv_full, inv_sub = block_inverses(A, box.node_ptr, box.node_dofs, C)
    bounded = np.flatnonzero(box.block_row >= 0)
    upper = np.full(box.node_ptr.size - 1, np.inf)
    upper[bounded] = box.upper[box.block_row[bounded]]
    return _Fine(A, C, box.load(qp.f), box, diag0, inv_full, inv_sub, bounded, upper,
                 tresca=_tresca_term(qp, box) if tresca else None)


def _positions(M: sp.csr_matrix, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
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


class _UpdatedOperator:
    """A coarse operator plus a sparse update (the truncation's low-rank term), changed in
    place where the update's pattern lies in the operator's (prepared with explicit zeros
    where updates go, from the update with every pivot truncated), the values it changed
    put back before the next update (no second copy of the operator); a coarse function
    truncated away entirely keeps a unit diagonal (an identity row) so that the smoother
    and the coarse solve stay defined. It owns ``base``: its values change in place."""

    def __init__(self, base: sp.csr_matrix, pattern: sp.spmatrix | None = None):
        work = sp.csr_matrix(base)
        work.sum_duplicates()
        work.sort_indices()
        if pattern is not None:               # explicit zeros where updates will go
            pattern = sp.csr_matrix(pattern)
            pattern.sum_duplicates()
            pattern.sort_indices()
            work = with_pattern(work, pattern)
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
        pos = _positions(work, delta.row, delta.col)
        diag = _positions(work, rows, rows)
        if np.any(pos < 0) or np.any(diag < 0):   # rare: a coupling without a place
            out = sp.csr_matrix(work + delta)
            dead = out.diagonal() <= self.dead_below
            return sp.csr_matrix(out + sp.diags(dead.astype(float))) if dead.any() else out
        self.touched = np.union1d(pos, diag)
        self.saved = work.data[self.touched].copy()
        np.add.at(work.data, pos, delta.data)
        work.data[diag[work.data[diag] <= self.dead_below]] += 1.0
        return work


@dataclass
class _TruncatedHierarchy:
    """The V-cycle of the truncated linear correction (module docstring, step 2)."""

    fine: _Fine
    P: sp.csr_matrix | None            # T^{-1} P_last: coarse level -> transformed fine
    coarse_P: list                     # original prolongations below (coarse -> finer)
    A_coarse: InitVar[list]            # untruncated Galerkin operators, finest coarse first
                                       # (handed to coarse_ops, which own them)
    sweeps: int
    truncate_coarse: bool
    patch: np.ndarray | None = None    # unknowns of the contact patch (None: no patch solve)
    truncatable: np.ndarray | None = None  # unknowns that may be truncated (None: the pivots)
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

    def __post_init__(self, A_coarse):
        self.coarse_R = [sp.csr_matrix(Pl.T) for Pl in self.coarse_P]  # restrictions, once
        pivots = self.fine.box.pivot if self.truncatable is None else self.truncatable
        patterns = (self._deltas(pivots) if self.truncate_coarse and self.P is not None
                    and pivots.size else [None] * len(A_coarse))
        self.coarse_ops = [_UpdatedOperator(M, d) for M, d in zip(A_coarse, patterns)]

    def _deltas(self, E: np.ndarray, curvature: sp.spmatrix | None = None) -> list:
        """The truncation's change of each coarse operator when the pivots ``E`` are
        truncated: ``Y'A~_EE Y - Y'X - X'Y`` (module docstring), plus ``P~' K P~`` for a
        fine-level ``curvature`` ``K`` added to ``A~`` off ``E`` (:class:`_SlipCurvature`),
        and its Galerkin products."""
        Y = self.P[E]
        A_E = self.fine.rows(E)
        X = A_E @ self.P
        Yt = Y.T.tocsr()
        YtX = Yt @ X
        delta = Yt @ (A_E[:, E] @ Y) - YtX - YtX.T.tocsr()
        if curvature is not None:
            delta = delta + sp.csr_matrix(self.P.T @ (curvature @ self.P))
        deltas = [delta]
        for Pl, Rl in zip(reversed(self.coarse_P), reversed(self.coarse_R)):
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
        system already holds (:class:`_SlipCurvature`), passed to the coarse operators
        too (every call then updates them)."""
        if curvature is None and self.frozen is not None and np.array_equal(E, self.frozen):
            return
        self.updates += 1
        self.frozen = E.copy()
        fine = self.fine
        self.mode = mode
        if self.patch is not None and self.P is not None:
            self._update_patch(E)
        if self.P is None:                       # no hierarchy: exact truncated solve
            keep = np.ones(fine.A.shape[0], dtype=bool)
            keep[E] = False
            idx = np.flatnonzero(keep)
            A_free = fine.rows(idx)[:, idx]
            try:
                factor = factorize(A_free).solve
            except FactorizationError:         # semidefinite (a body held by nothing yet)
                factor = spla.splu(sp.csc_matrix(A_free)).solve

            def solve(r):
                out = np.zeros_like(r)
                out[idx] = factor(r[idx])
                return out
            self.coarse_solve = solve
            return
        deltas = (self._deltas(E, curvature)
                  if self.truncate_coarse and (E.size or curvature is not None)
                  else [None] * len(self.coarse_ops))
        self.A_t = [op.set(delta) for op, delta in zip(self.coarse_ops, deltas)]
        self.coarse_solve = spla.splu(sp.csc_matrix(self.A_t[-1])).solve

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


def contact_patch(qp: ContactQP, fine: _Fine, hops: int) -> np.ndarray | None:
    """The unknowns of the constraint rows (constrained nodes and opposing facets) and
    ``hops`` graph layers of ``A~`` around them; None for ``hops = 0`` or no rows."""
    if hops == 0 or qp.m == 0:
        return None
    patch = np.unique(qp.B.tocsr().indices)
    for _ in range(hops):
        patch = np.union1d(patch, fine.rows(patch).indices)
    return patch


def _hierarchy(qp: ContactQP, fine: _Fine, sweeps: int, truncate_coarse: bool, hops: int,
               truncatable: np.ndarray | None = None) -> _TruncatedHierarchy:
    prolongations = [sp.csr_matrix(P) for P in qp.multilevel.prolongations]
    if not prolongations:
        return _TruncatedHierarchy(fine, None, [], [], sweeps, truncate_coarse,
                                   truncatable=truncatable)
    P = fine.box.prolongation(prolongations[-1])
    # P~' A~ P~ = P' T' A T T^{-1} P = P' A P: the untruncated coarse operators are the
    # scene's own Galerkin products
    mats = [fine.A]                              # all products CSR by CSR (no conversion
    for Pl in reversed(prolongations):           # of A to CSC)
        mats.append(sp.csr_matrix(sp.csr_matrix(Pl.T) @ (mats[-1] @ Pl)))
    mats = mats[1:]
    return _TruncatedHierarchy(fine, P, prolongations[:-1], mats, sweeps, truncate_coarse,
                               contact_patch(qp, fine, hops), truncatable)


def _stationarity(fine: _Fine, r: np.ndarray, bound: np.ndarray) -> float:
    """The transformed problem's scaled stationarity residual: ``r = f~ - A~v`` off the
    pivots at their bounds, its negative part on them (the positive part is the
    multiplier), over ``max(|f~|, |A~v|)``. Feasibility and complementarity hold by
    construction; it gates the suite's check (:data:`CHECK_FACTOR`)."""
    res = r.copy()
    res[bound] = np.minimum(res[bound], 0.0)
    scale = max(float(np.abs(fine.f).max()), float(np.abs(fine.f - r).max()), 1e-300)
    return float(np.abs(res).max()) / scale


def _energy(fine: _Fine, v: np.ndarray, r: np.ndarray) -> float:
    """``J~(v) = 1/2 v'A~v - f~'v`` from the residual ``r = f~ - A~v``."""
    return -0.5 * float(v @ (fine.f + r))


def _step(fine: _Fine, v: np.ndarray, r: np.ndarray, c: np.ndarray, piv: np.ndarray,
          upper: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The new iterate from the truncated correction ``c`` (module docstring, step 3).

    The exact line search along ``c`` projected onto the feasible set (``c <= upper - v``
    at the pivots; Gräser-Kornhuber) is the safe candidate. Where a bound cut it short
    (or ``c`` is no descent direction), points on the
    projection arc ``min(v + a c, upper)`` at the pivots, ``a = 1, 1/4, ...`` down to
    :data:`ARC_MIN` (a projected Newton step with backtracking, Bertsekas): the first
    whose energy is lower than the line search's is taken. The arc takes every bound
    the correction crosses at once; the projected line search is cut short by the
    unknowns nearest their bounds and crawls when a soft body is pressed into a stiff
    one (contrast 1e-4: hundreds of steps). The energy never rises. Returns
    ``(v, r, step)``: the line search's length, or ``-a`` for an arc point.
    """
    slack = upper - v[piv]
    d = c.copy()
    d[piv] = np.minimum(d[piv], slack)
    Ad = fine.matvec(d)
    curvature, slope = float(d @ Ad), float(r @ d)
    step, cut = 0.0, True
    if curvature > 0 and slope > 0:
        step = free = slope / curvature
        rising = d[piv] > 0
        if rising.any():
            step = min(step, float(np.min(slack[rising] / d[piv][rising])))
        cut = step < free
    v_line, r_line = v + step * d, r - step * Ad
    return _arc_or_line(fine, _energy, v, c, piv, upper, v_line, r_line, step, cut)


def _arc_or_line(fine: _Fine, energy: Callable, v: np.ndarray, c: np.ndarray,
                 piv: np.ndarray, upper: np.ndarray, v_line: np.ndarray, r_line: np.ndarray,
                 step: float, cut: bool) -> tuple[np.ndarray, np.ndarray, float]:
    """The line search's point ``v_line`` (step ``step``), or where a bound ``cut`` it short
    the first point of the projection arc with a lower ``energy(fine, v, r)``
    (:func:`_step`)."""
    J_line = energy(fine, v_line, r_line)
    arc = 1.0 if cut else 0.0          # the arc only where a bound cut the line search short
    while arc >= ARC_MIN:
        v_arc = v + arc * c
        v_arc[piv] = np.minimum(v_arc[piv], upper)
        r_arc = fine.f - fine.matvec(v_arc)
        if energy(fine, v_arc, r_arc) < J_line:
            return v_arc, r_arc, -arc
        arc *= ARC_FACTOR
    v_line[piv] = np.minimum(v_line[piv], upper)
    return v_line, r_line, step


@dataclass
class _StepLog:
    """A TNNMG solve's per-step history, its phases' times and its end (:func:`solve`)."""

    t_solve: float
    deadline: float | None
    history: dict = field(default_factory=lambda: {
        key: [] for key in ("energy", "residual", "kkt_max", "n_active", "step", "phase",
                            "time")})
    timing: dict = field(default_factory=lambda: dict.fromkeys(
        ("t_smoother", "t_truncation", "t_vcycle", "t_check"), 0.0))

    def record(self, **values) -> None:
        """Append the step's ``values`` (a new name starts its list) and its time."""
        for key, value in values.items():
            self.history.setdefault(key, []).append(value)
        self.history["time"].append(time.perf_counter() - self.t_solve)

    def close(self, k: int, times: tuple, kkt_max: float, verified: bool, converged: str,
              stop: Callable[[], bool]) -> tuple[str, str] | None:
        """Record the check and the phases' times ``(t0, t1, t2, t3)`` of step ``k``, then
        ask ``stop`` (the caller's callback); ``(status, message)`` if the solve ends here."""
        t0, t1, t2, t3 = times
        self.history["kkt_max"].append(kkt_max)
        self.timing["t_smoother"] += t1 - t0
        self.timing["t_truncation"] += t2 - t1
        self.timing["t_vcycle"] += t3 - t2
        self.timing["t_check"] += time.perf_counter() - t3
        stopped = stop()
        if verified:
            return "converged", converged
        if stopped:
            return "max_iter", f"stopped by the caller after {k} steps"
        if self.deadline is not None and time.perf_counter() > self.deadline:
            return "time_limit", f"time limit reached after {k} steps"
        return None


@dataclass
class _FaceCG:
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

    def _direction(self, fine: _Fine, ml: "_TruncatedHierarchy", g: np.ndarray
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

    def step(self, fine: _Fine, ml: "_TruncatedHierarchy", v: np.ndarray, r: np.ndarray,
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


@dataclass
class _TrescaFace:
    """The face of a 2D Tresca step an iterate lies on: the normal pivots at their bounds
    (``active``) and each tangential row's slip sign (``sign``: +1, -1, or 0 where the row
    sticks or has no slip bound). On a face the energy is quadratic: ``J~(v)`` plus
    ``weight_i sign_i (v_t,i - centre_i)``, linear in the slipping rows."""

    active: np.ndarray
    sign: np.ndarray

    @classmethod
    def of(cls, fine: _Fine, v: np.ndarray) -> "_TrescaFace":
        term = fine.tresca
        sign = np.sign(v[term.pivot] - term.centre) * (term.weight > 0)
        return cls(v[fine.box.pivot] >= fine.box.upper, sign.astype(np.int64))

    def __eq__(self, other: object) -> bool:
        return (isinstance(other, _TrescaFace) and np.array_equal(self.active, other.active)
                and np.array_equal(self.sign, other.sign))


def _face_state(fine: _Fine, v: np.ndarray) -> np.ndarray:
    """The face of a Tresca step's iterate ``v`` as one integer array: per normal pivot
    whether it is at its bound; per tangential row its slip sign (2D,
    :class:`_TrescaFace`) or per node whether it slips (3D: the slip direction is not
    part of a face, the energy is curved across it). A solve's steps after the last
    change of its face (``stats["steps_on_face"]``) are its linear phase, where a TNNMG
    step is a multigrid step on a fixed face (Gräser-Kornhuber: the phase whose
    contraction is bounded in h); the steps before (``stats["steps_to_face"]``) find
    the normal active set and the stick set."""
    term = fine.tresca
    active = (v[fine.box.pivot] >= fine.box.upper).astype(np.int64)
    if term.k == 1:
        return np.concatenate([active, _TrescaFace.of(fine, v).sign])
    return np.concatenate([active, (~term.stick(v) & (term.weight > 0)).astype(np.int64)])


def _contraction_on_face(residuals: list, to_face: int) -> float:
    """The mean contraction per step of the stationarity residual (``residuals``: one per
    step) from the step at which the face last changed (``to_face``; 0: never, counted
    from the first step) to the last: ``(res_last / res_face)^(1/steps)``, the multigrid
    phase's rate, which does not depend on h where the step counts do through finding the
    face (:func:`_face_state`); NaN without a step on the face."""
    first = max(to_face, 1)
    steps = len(residuals) - first
    if steps <= 0 or not residuals[first - 1] > 0:
        return float("nan")
    return float(residuals[-1] / residuals[first - 1]) ** (1.0 / steps)


@dataclass
class _TrescaFaceCG(_FaceCG):
    """:class:`_FaceCG` on a face of a 2D Tresca step (:class:`_TrescaFace`; ``E``: its
    active normal pivots and sticking tangential unknowns, as the truncation holds them).
    The face's negative gradient is ``r`` minus ``weight sign`` at the slipping rows. A
    step is cut (expansion: the face is left) where a free normal pivot meets its bound or
    a slipping row reaches its kink (its slip would change sign; the row is written at its
    centre and sticks); the face is left too when the chopped gradient outweighs the free
    one (proportioning): the negative multipliers of the active pivots and, at the
    sticking rows, the excess of ``|r|`` over the weight (a multiplier leaving
    ``[-s_i, s_i]``). The energy never rises; the next TNNMG step's smoother releases
    what proportioning found.
    """

    face: _TrescaFace | None = None

    def _gradient(self, fine: _Fine, r: np.ndarray) -> np.ndarray:
        g = r.copy()
        g[fine.tresca.pivot] -= fine.tresca.weight * self.face.sign
        g[self.E] = 0.0
        return g

    def step(self, fine: _Fine, ml: "_TruncatedHierarchy", v: np.ndarray, r: np.ndarray,
             piv: np.ndarray, upper: np.ndarray, active: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, float, bool]:
        """One CG step from ``v`` (residual ``r``): ``(v, r, alpha, leave)``."""
        term, sign = fine.tresca, self.face.sign
        found = self._direction(fine, ml, self._gradient(fine, r))
        if found is None:
            return v, r, 0.0, True
        q, alpha = found
        dn, dt = self.p[piv], self.p[term.pivot]
        rising = (dn > 0) & ~self.face.active
        toward = sign * dt < 0                  # a slipping row moving towards its kink
        room_n = (upper[rising] - v[piv][rising]) / dn[rising]
        room_t = (term.centre[toward] - v[term.pivot][toward]) / dt[toward]
        room = min(float(room_n.min(initial=np.inf)), float(room_t.min(initial=np.inf)))
        leave = room < alpha
        if leave:
            alpha = max(room, 0.0)
        v = v + alpha * self.p
        r = r - alpha * q
        v[piv] = np.minimum(v[piv], upper)
        if leave:                               # what the cut step reached, exactly
            hit = np.flatnonzero(rising)[room_n <= alpha]
            v[piv[hit]] = upper[hit]
        # a kink reached (or passed by round-off) is written exactly: the row sticks
        kink = np.flatnonzero((sign != 0) & (sign * (v[term.pivot] - term.centre) <= 0))
        v[term.pivot[kink]] = term.centre[kink]
        leave = leave or kink.size > 0
        stick = (sign == 0) & (term.weight > 0)
        rt = r[term.pivot[stick]]
        chopped = np.concatenate([np.minimum(r[piv[self.face.active]], 0.0),
                                  np.maximum(np.abs(rt) - term.weight[stick], 0.0)])
        free = self._gradient(fine, r)
        if float(chopped @ chopped) > float(free @ free):
            leave = True
        return v, r, alpha, leave


def _kink_search(base: float, curvature: float, kinks: np.ndarray, jumps: np.ndarray,
                 longest: float) -> float:
    """The minimiser over ``[0, longest]`` of a convex piecewise quadratic ``phi`` with
    ``phi'(a) = base + a curvature`` on ``(0, kinks[0])`` and ``phi'`` rising by ``jumps[j]``
    at ``kinks[j]`` (sorted, positive; ``curvature > 0``): the first piece on whose right
    end ``phi'`` is not negative holds it, at its stationary point or at its left end (a
    kink); exact."""
    ends = np.append(kinks[kinks < longest], longest)
    slopes = base + np.r_[0.0, np.cumsum(jumps[:ends.size - 1])]   # phi' at each piece's start
    starts = np.r_[0.0, ends[:-1]]
    if not np.isfinite(ends[-1]):
        ends = ends.copy()
        ends[-1] = max(float(starts[-1]), -float(slopes[-1]) / curvature) + 1.0
    turning = np.flatnonzero(slopes + ends * curvature >= 0.0)
    if turning.size == 0:
        return float(longest)
    j = int(turning[0])
    return float(min(max(float(starts[j]), -float(slopes[j]) / curvature), ends[j]))


def _tresca_energy(fine: _Fine, v: np.ndarray, r: np.ndarray) -> float:
    """The transformed Tresca step's energy ``J~(v) + sum_i weight_i |v_t,i - centre_i|``."""
    return _energy(fine, v, r) + fine.tresca.value(v)


def _tresca_step(fine: _Fine, v: np.ndarray, r: np.ndarray, c: np.ndarray, piv: np.ndarray,
                 upper: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The new iterate of a Tresca step from the truncated correction ``c``: :func:`_step`
    with the line search on the nonsmooth energy.

    Along the projected correction ``d`` the energy is convex and piecewise quadratic in
    the step ``a``: the quadratic part, and ``weight_i |z_i + a d_i|`` with a kink at
    ``-z_i / d_i`` for every slipping row (``z = v_t - centre``); its exact minimiser over
    the feasible segment (:func:`_kink_search`; a kink reached is written exactly, the row
    then sticks). Where the normal bounds cut the segment short, the projection arc
    ``min(v + a c, upper)`` as in :func:`_step`, judged by the nonsmooth energy.
    """
    term = fine.tresca
    slack = upper - v[piv]
    d = c.copy()
    d[piv] = np.minimum(d[piv], slack)
    Ad = fine.matvec(d)
    curvature, slope = float(d @ Ad), float(r @ d)
    if term.k > 1:
        return _disc_step(fine, v, r, c, d, Ad, curvature, slope, piv, upper, slack)
    step, cut = 0.0, True
    if curvature > 0:
        rising = d[piv] > 0
        longest = float(np.min(slack[rising] / d[piv][rising])) if rising.any() else np.inf
        z, dt = v[term.pivot] - term.centre, d[term.pivot]
        moving = (dt != 0) & (term.weight > 0)
        kink = np.full(z.size, -np.inf)
        kink[moving] = -z[moving] / dt[moving]
        ahead = moving & (kink > 0)
        behind = moving & ~ahead
        base = -slope + float(term.weight[behind] @ np.abs(dt[behind])) \
            - float(term.weight[ahead] @ np.abs(dt[ahead]))
        order = np.argsort(kink[ahead], kind="stable")
        kinks = kink[ahead][order]
        jumps = 2.0 * (term.weight[ahead] * np.abs(dt[ahead]))[order]
        step = _kink_search(base, curvature, kinks, jumps, longest)
        cut = step == 0.0 or (step >= longest and base + longest * curvature + float(
            jumps[kinks < longest].sum()) < 0.0)
    v_line, r_line = v + step * d, r - step * Ad
    if step > 0:
        reached = (kink == step) if curvature > 0 else np.zeros(term.pivot.size, dtype=bool)
        v_line[term.pivot[reached]] = term.centre[reached]
    return _arc_or_line(fine, _tresca_energy, v, c, piv, upper, v_line, r_line, step, cut)


def _disc_step(fine: _Fine, v: np.ndarray, r: np.ndarray, c: np.ndarray, d: np.ndarray,
               Ad: np.ndarray, curvature: float, slope: float, piv: np.ndarray,
               upper: np.ndarray, slack: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """:func:`_tresca_step` in 3D: along the projected correction ``d`` the energy is convex
    and smooth but where a node's tangential offset ``z_i + a d_i`` passes through zero;
    its minimiser over the feasible segment by :func:`_disc_line_search`. A kink reached is
    written exactly (the node then sticks); where the normal bounds cut the segment short,
    the projection arc as in :func:`_step`."""
    term = fine.tresca
    step, cut, reached = 0.0, True, np.zeros(term.weight.size, dtype=bool)
    if curvature > 0:
        rising = d[piv] > 0
        longest = float(np.min(slack[rising] / d[piv][rising])) if rising.any() else np.inf
        z = term._nodes(v[term.pivot] - term.centre)
        dt = term._nodes(d[term.pivot])
        step, reached, ends_short = _disc_line_search(-slope, curvature, z, dt, term.weight,
                                                      longest)
        cut = step == 0.0 or ends_short
    v_line, r_line = v + step * d, r - step * Ad
    if reached.any():
        nodes = term._nodes(term.pivot)[reached].ravel()
        v_line[nodes] = term._nodes(term.centre)[reached].ravel()
    return _arc_or_line(fine, _tresca_energy, v, c, piv, upper, v_line, r_line, step, cut)


def _disc_line_search(base: float, curvature: float, z: np.ndarray, dt: np.ndarray,
                      weight: np.ndarray, longest: float
                      ) -> tuple[float, np.ndarray, bool]:
    """The minimiser over ``[0, longest]`` of the convex ``phi(a) = base a + curvature a^2 / 2
    + sum_i weight_i |z_i + a dt_i|`` (``z, dt`` of shape ``(m, k)``, ``curvature > 0``):
    ``(a, reached, short)``, ``reached`` the nodes whose offset is zero at ``a`` (a kink
    taken: only where ``z_i`` and ``dt_i`` are parallel), ``short`` if ``phi`` still falls
    at ``a = longest``.

    ``phi'`` is nondecreasing (it jumps up at the kinks); its sign change is bracketed
    (from ``[0, longest]``, or ``phi' >= base - sum weight |dt| + a curvature`` where the
    segment is unbounded) and found by Newton's method on ``phi'`` safeguarded by
    bisection, to round-off; a kink inside the last bracket is the minimiser.
    """
    moving = (weight > 0) & np.any(dt != 0, axis=1)
    z, dt, w = z[moving], dt[moving], weight[moving]
    dd = np.einsum("ij,ij->i", dt, dt)
    zd = np.einsum("ij,ij->i", z, dt)
    zz = np.einsum("ij,ij->i", z, z)
    # kinks: z_i + a dt_i = 0 for some a >= 0 (z_i antiparallel to dt_i, or z_i = 0)
    at = -zd / dd
    parallel = np.abs(z[:, 0] * dt[:, 1] - z[:, 1] * dt[:, 0]) <= 1e-14 * np.sqrt(zz * dd)
    kink = np.where(parallel & (at >= 0.0), at, -1.0)

    def slope_at(a: float, side: float) -> tuple[float, float]:
        """``phi'(a)`` (one-sided at a kink: ``side`` +1 right, -1 left) and ``phi''(a)``."""
        y = z + a * dt                    # not |z|^2 + 2a z.dt + ...: it cancels at a kink
        yy = np.einsum("ij,ij->i", y, y)
        yd = np.einsum("ij,ij->i", y, dt)
        length = np.sqrt(yy)
        on = (length <= 1e-15 * np.sqrt(dd) * (a + 1.0)) | (kink == a)
        inner = np.where(on, side * np.sqrt(dd), yd / np.where(on, 1.0, length))
        second = np.where(on, 0.0, (dd * yy - yd * yd) / np.where(on, 1.0, length ** 3))
        return (base + a * curvature + float(w @ inner),
                curvature + float(w @ np.maximum(second, 0.0)))

    if slope_at(0.0, +1.0)[0] >= 0.0:
        return 0.0, _reached(moving, kink, 0.0), False
    lo = 0.0
    hi = (longest if np.isfinite(longest)
          else max((float(w @ np.sqrt(dd)) - base) / curvature, 0.0))
    if np.isfinite(longest) and slope_at(longest, -1.0)[0] <= 0.0:
        return float(longest), _reached(moving, kink, longest), True
    a = lo
    for _ in range(200):
        slope_a, second = slope_at(a, +1.0)
        if slope_a < 0.0:
            lo = a
        elif a > lo and slope_at(a, -1.0)[0] > 0.0:
            hi = a
        elif a > lo:                      # phi'(a-) <= 0 <= phi'(a+): a kink holds it
            return a, _reached(moving, kink, a), False
        if hi - lo <= 4e-16 * hi:
            break
        nxt = a - slope_a / second
        if not lo < nxt < hi:
            nxt = 0.5 * (lo + hi)
        if nxt == a:
            break
        a = nxt
    inside = (kink >= lo) & (kink <= hi)
    if inside.any():                      # the bracket closed on a kink
        a = float(kink[inside][0])
        return a, _reached(moving, kink, a), False
    phi = lambda t: base * t + 0.5 * curvature * t * t + float(
        w @ np.sqrt(np.einsum("ij,ij->i", z + t * dt, z + t * dt)))
    a = lo if phi(lo) <= phi(hi) else hi
    return a, _reached(moving, kink, a), False


def _reached(moving: np.ndarray, kink: np.ndarray, a: float) -> np.ndarray:
    """Per node (all nodes), whether its kink is at ``a``."""
    out = np.zeros(moving.size, dtype=bool)
    out[np.flatnonzero(moving)[kink == a]] = True
    return out


def _tresca_stationarity(fine: _Fine, r: np.ndarray, bound: np.ndarray, v: np.ndarray
                         ) -> float:
    """:func:`_stationarity` with Tresca's term: at a tangential unknown ``r`` minus the
    term's derivative where the row slips, the excess of ``|r|`` over the weight where it
    sticks."""
    term = fine.tresca
    res = r.copy()
    res[bound] = np.minimum(res[bound], 0.0)
    rt = r[term.pivot]
    if term.k == 1:
        stick = v[term.pivot] == term.centre
        res[term.pivot] = np.where(stick, np.sign(rt) * np.maximum(np.abs(rt) - term.weight,
                                                                   0.0),
                                   rt - term.gradient(v))
    else:
        stick = np.repeat(np.all(term._nodes(v[term.pivot] == term.centre), axis=1), term.k)
        rn = term._nodes(rt)
        length = np.sqrt(np.einsum("ij,ij->i", rn, rn))
        excess = np.maximum(length - term.weight, 0.0) / np.where(length > 0, length, 1.0)
        res[term.pivot] = np.where(stick, (rn * excess[:, None]).ravel(),
                                   rt - term.gradient(v))
    scale = max(float(np.abs(fine.f).max()), float(np.abs(fine.f - r).max()), 1e-300)
    return float(np.abs(res).max()) / scale


def _verified(qp: ContactQP, u: np.ndarray, p: np.ndarray, tol: float, stop: str,
              lam: np.ndarray | None = None) -> tuple[float, bool]:
    """``(kkt_max, verified)`` of an iterate, judged as the suite's verification judges
    it: the KKT residuals (the friction ones with the tangential multipliers ``lam``)
    within ``tol`` and, unless ``stop`` is ``"kkt"``, the certified bound too."""
    kkt_max = (kkt_residuals(qp, u, p) if lam is None
               else friction_residuals(qp, u, p, lam)).max
    return kkt_max, kkt_max <= tol and (stop == "kkt"
                                        or certify(qp, u, p, tol, lam=lam).meets(tol))


@dataclass
class _SlipCurvature:
    """3D Tresca: the slip term's curvature in the truncated linear correction.

    Where node ``i`` slips (``z_i = v_t,i - centre_i != 0``) its term ``weight_i |z_i|`` is
    smooth, with the Hessian ``weight_i / |z_i| (I - z_i z_i' / |z_i|^2)`` on its two
    tangential unknowns (in 2D it is zero: the term is linear off its kink). Left out, the
    correction overshoots across the slip direction and the line search shortens every
    step; put into the correction's operator (the fine system ``A~ + K``: the
    transformation's update with places for ``K`` and the constrained blocks' inverses
    refreshed; the coarse operators by :meth:`_TruncatedHierarchy.truncate`), the step is
    the truncated Newton step of the nonsmooth energy (Gräser-Kornhuber: the Hessian of
    the energy where it is twice differentiable).
    """

    fine: _Fine
    positions: np.ndarray          # (m, k, k): the places of K's entries in fine.C.data
    base: np.ndarray               # fine.C.data without K
    block_ptr: np.ndarray          # the constrained node blocks, for block_inverses
    block_dofs: np.ndarray

    @classmethod
    def build(cls, fine: _Fine) -> "_SlipCurvature":
        term, box = fine.tresca, fine.box
        k = term.k
        tpiv = term.pivot.reshape(-1, k)
        rows = np.repeat(tpiv, k, axis=1).ravel()
        cols = np.tile(tpiv, (1, k)).ravel()
        pattern = sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=fine.C.shape)
        pattern.sort_indices()
        C = sp.csr_matrix(fine.C)
        C.sum_duplicates()
        C.sort_indices()
        C = with_pattern(C, pattern)
        blocks = fine.bounded_blocks
        sizes = np.diff(box.node_ptr)[blocks]
        block_ptr = np.r_[0, np.cumsum(sizes)].astype(np.int64)
        block_dofs = np.concatenate([box.node_dofs[box.node_ptr[b]:box.node_ptr[b + 1]]
                                     for b in blocks]) if blocks.size else np.zeros(0, np.int64)
        lin = _Fine(fine.A, C, fine.f, box, fine.diag0.copy(), fine.inv_full.copy(),
                    fine.inv_sub.copy(), blocks, fine.upper_block, tresca=term)
        return cls(lin, _positions(C, rows, cols).reshape(-1, k, k), C.data.copy(),
                   block_ptr, block_dofs)

    def set(self, v: np.ndarray, stick: np.ndarray) -> sp.csr_matrix:
        """Put the curvature of the iterate ``v`` (slipping nodes: not ``stick``) into the
        fine system; returns ``K`` ``(n, n)``."""
        fine, term = self.fine, self.fine.tresca
        z, length = term._offsets(v)
        slipping = ~stick & (term.weight > 0) & (length > 0)
        zs, ls = z[slipping], length[slipping]
        hess = (term.weight[slipping] / ls)[:, None, None] * (
            np.eye(term.k)[None] - zs[:, :, None] * zs[:, None, :] / (ls * ls)[:, None, None])
        fine.C.data[:] = self.base
        fine.C.data[self.positions[slipping].ravel()] += hess.ravel()
        fine.update_part = sp.csr_matrix(fine.C[fine.update_rows])
        diag0, inv_full, inv_sub = block_inverses(fine.A, self.block_ptr, self.block_dofs,
                                                  fine.C)
        blocks = fine.bounded_blocks
        fine.diag0[blocks], fine.inv_full[blocks], fine.inv_sub[blocks] = \
            diag0, inv_full, inv_sub
        tpiv = term.pivot.reshape(-1, term.k)[slipping]
        rows = np.repeat(tpiv, term.k, axis=1).ravel()
        cols = np.tile(tpiv, (1, term.k)).ravel()
        return sp.csr_matrix((hess.ravel(), (rows, cols)), shape=fine.C.shape)


def _presmooth(fine: _Fine, v: np.ndarray, mode: np.ndarray, forward: bool, sweeps: int
               ) -> bool:
    """Step 1 (module docstring): ``sweeps`` nonlinear node-block Gauss-Seidel sweeps on
    ``v`` in place, alternating direction from ``forward``; returns the next direction."""
    for _ in range(sweeps):
        fine.sweep(v, fine.f, mode, forward)
        forward = not forward
    return forward


def _tresca_solve(qp: ContactQP, tol: float, max_iter: int, time_limit: float | None,
                  u0: np.ndarray | None, opts: Options, callback: Callable | None
                  ) -> SolveResult:
    """One Tresca step (``qp.friction``, 2D or 3D) by TNNMG (module docstring, Tresca
    friction)."""
    t_start = time.perf_counter()
    fine = _fine_system(qp, tresca=True)
    box, term = fine.box, fine.tresca
    piv, upper, tpiv = box.pivot, box.upper, term.pivot
    curvature = _SlipCurvature.build(fine) if term.k > 1 else None
    presmoothing = opts.presmoothing or AUTO_PRESMOOTHING[True]
    sweeps = opts.sweeps or (TRESCA_3D_SWEEPS if qp.dim == 3 else AUTO_SWEEPS.get(qp.dim, 2))
    ml = _hierarchy(qp, fine if curvature is None else curvature.fine, sweeps,
                    opts.coarse == "truncated", opts.patch, np.concatenate([piv, tpiv]))
    nb = box.node_ptr.size - 1
    mode_nonlinear = np.full(nb, FREE, dtype=np.int64)
    mode_nonlinear[fine.bounded_blocks] = TRESCA
    block_of_row = np.empty(qp.m, dtype=np.int64)
    block_of_row[box.block_row[fine.bounded_blocks]] = fine.bounded_blocks
    v = np.zeros(qp.n) if u0 is None else box.to_v(np.asarray(u0, dtype=float))
    v[piv] = np.minimum(v[piv], upper)
    setup_time = time.perf_counter() - t_start
    deadline = None if time_limit is None else t_start + time_limit

    log = _StepLog(time.perf_counter(), deadline)
    status, message, k = "max_iter", f"not verified after {max_iter} steps", 0
    forward = True
    face_cg = opts.krylov == "cg" and term.k == 1   # 3D: TNNMG steps only (docstring)
    cg, n_cg, previous = None, 0, None
    face_state, to_face = _face_state(fine, v), 0
    for k in range(1, max_iter + 1):
        t0 = t1 = time.perf_counter()
        if cg is None:                            # a TNNMG step
            forward = _presmooth(fine, v, mode_nonlinear, forward, presmoothing)
            t1 = time.perf_counter()
            face = _TrescaFace.of(fine, v) if face_cg else None
            r = fine.f - fine.matvec(v)
            active, stick = v[piv] >= upper, term.stick(v)
            mode = np.full(nb, FREE, dtype=np.int64)
            mode[block_of_row[active]] = FIXED
            mode[block_of_row[stick]] = TANGENT_FIXED
            mode[block_of_row[active & stick]] = BOTH_FIXED
            E = np.concatenate([piv[active], tpiv.reshape(-1, term.k)[stick].ravel()])
            ml.truncate(E, mode, None if curvature is None else curvature.set(v, stick))
            t2 = time.perf_counter()
            g = r.copy()
            g[tpiv] -= term.gradient(v)
            g[E] = 0.0
            c = ml.vcycle(g)
            v, r, step = _tresca_step(fine, v, r, c, piv, upper)
            if face_cg:                           # the face is stable: CG on it
                if previous == face and _TrescaFace.of(fine, v) == face:
                    cg = _TrescaFaceCG(E, sweeps=opts.sweeps or TRESCA_FACE_SWEEPS, face=face)
                previous = face
            phase = "tnnmg"
        else:                                     # a CG step on the face (_TrescaFaceCG)
            t2 = t1
            v, r, step, leave = cg.step(fine, ml, v, r, piv, upper, cg.face.active)
            n_cg += 1
            phase = "cg"
            if leave:
                cg = None
        t3 = time.perf_counter()
        state = _face_state(fine, v)
        if not np.array_equal(state, face_state):
            face_state, to_face = state, k
        bound = v[piv] >= upper
        residual = _tresca_stationarity(fine, r, piv[bound], v)
        log.record(energy=_tresca_energy(fine, v, r), residual=residual,
                   n_active=int(np.count_nonzero(bound)), step=step, phase=phase,
                   n_stick=int(np.count_nonzero(term.stick(v))))
        verified, kkt_max = False, np.nan
        if residual <= CHECK_FACTOR * tol or callback is not None:
            u, p = box.to_u(v), box.multipliers(r, bound)
            lam = term.multipliers(r, qp.friction, v)
        if residual <= CHECK_FACTOR * tol:         # the suite's verification decides
            kkt_max, verified = _verified(qp, u, p, tol, opts.stop, lam)
        end = log.close(k, (t0, t1, t2, t3), kkt_max, verified,
                        f"verified after {k} steps" + (f" ({n_cg} of them CG)" if face_cg
                                                       else ""),
                        lambda: callback is not None and callback(u, p))
        if end is not None:
            status, message = end
            break
    if k == 0:
        r = fine.f - fine.matvec(v)
    bound = v[piv] >= upper
    u, p = box.to_u(v), box.multipliers(r, bound)
    lam = term.multipliers(r, qp.friction, v)
    stick = term.stick(v)
    stats = {"friction": "tresca_step", "n_steps": k, "n_cg": n_cg, "n_vcycles": k,
             "steps_to_face": to_face, "steps_on_face": k - to_face,
             "contraction_on_face": _contraction_on_face(log.history["residual"], to_face),
             "presmoothing": presmoothing,
             "truncation_updates": ml.updates, "n_active": int(np.count_nonzero(p > 0)),
             "n_stick": int(np.count_nonzero(stick)),
             "n_slip": int(np.count_nonzero(~stick & (term.weight > 0))),
             "n_levels": len(ml.coarse_ops) + 1, **log.timing}
    return SolveResult(u=u, p=p, claimed_status=status, message=message, iterations=k,
                       setup_time=setup_time, solve_time=time.perf_counter() - log.t_solve,
                       history=log.history, stats=stats, tangential=lam)


def supports(qp: ContactQP) -> tuple[bool, str]:
    """Nodal constraints with one row per constrained node (:mod:`solvers.kernels.contact_box`);
    with friction, one Tresca step (2D or 3D) whose tangential rows become coordinates too
    (a Coulomb problem's step at its given slip bound: the fixed point ``s = mu p`` is the
    load path's)."""
    fr = qp.friction
    if fr is not None:
        try:
            box_transformation(qp, fr.T)
        except TransformationError as err:
            return False, f"the constraints cannot be turned into bounds: {err}"
        return True, ""
    ok, reason = check_structure(qp)
    return ok, (f"the constraints cannot be turned into bounds: {reason}" if not ok else "")


def solve(qp: ContactQP, tol: float, max_iter: int, time_limit: float | None,
          u0: np.ndarray | None, p0: np.ndarray | None, opts: Options,
          callback: Callable | None = None) -> SolveResult:
    """Solve ``qp`` by TNNMG (module docstring). ``p0`` is not used (a primal method).

    ``callback(u, p)``, if given, is called after every step, after ``history["time"]``
    is stamped (its cost is the caller's to subtract), and stops an unverified run by
    returning True (status ``max_iter``). A Tresca step (``qp.friction``) goes to
    :func:`_tresca_solve`.
    """
    if qp.friction is not None:
        return _tresca_solve(qp, tol, max_iter, time_limit, u0, opts, callback)
    t_start = time.perf_counter()
    fine = _fine_system(qp)
    presmoothing = opts.presmoothing or AUTO_PRESMOOTHING[False]
    ml = _hierarchy(qp, fine, opts.sweeps or AUTO_SWEEPS.get(qp.dim, 2),
                    opts.coarse == "truncated", opts.patch)
    box = fine.box
    piv, upper = box.pivot, box.upper
    mode_nonlinear = np.full(box.node_ptr.size - 1, FREE, dtype=np.int64)
    mode_nonlinear[fine.bounded_blocks] = BOUNDED
    v = np.zeros(qp.n) if u0 is None else box.to_v(np.asarray(u0, dtype=float))
    v[piv] = np.minimum(v[piv], upper)
    setup_time = time.perf_counter() - t_start
    deadline = None if time_limit is None else t_start + time_limit

    log = _StepLog(time.perf_counter(), deadline)
    status, message, k = "max_iter", f"not verified after {max_iter} steps", 0
    forward, cg, n_cg, previous = True, None, 0, None
    for k in range(1, max_iter + 1):
        t0 = t1 = time.perf_counter()
        if cg is None:                            # a TNNMG step
            forward = _presmooth(fine, v, mode_nonlinear, forward, presmoothing)
            t1 = time.perf_counter()
            r = fine.f - fine.matvec(v)
            active = v[piv] >= upper
            ml.update(active)
            t2 = time.perf_counter()
            r_t = r.copy()
            r_t[piv[active]] = 0.0
            c = ml.vcycle(r_t)
            v, r, step = _step(fine, v, r, c, piv, upper)
            bound = v[piv] >= upper
            if (opts.krylov == "cg" and previous is not None
                    and np.array_equal(active, previous) and np.array_equal(bound, active)):
                cg = _FaceCG(piv[active])         # the face is stable: CG on it
            previous = active
            phase = "tnnmg"
        else:                                     # a CG step on the face (_FaceCG)
            t2 = t1
            v, r, step, leave = cg.step(fine, ml, v, r, piv, upper, active)
            bound = v[piv] >= upper
            n_cg += 1
            phase = "cg"
            if leave:
                cg = None
        t3 = time.perf_counter()
        residual = _stationarity(fine, r, piv[bound])
        log.record(energy=_energy(fine, v, r), residual=residual,
                   n_active=int(np.count_nonzero(bound)), step=step, phase=phase)
        verified, kkt_max = False, np.nan
        if residual <= CHECK_FACTOR * tol or callback is not None:
            u, p = box.to_u(v), box.multipliers(r, bound)
        if residual <= CHECK_FACTOR * tol:         # the suite's verification decides
            kkt_max, verified = _verified(qp, u, p, tol, opts.stop)
        end = log.close(k, (t0, t1, t2, t3), kkt_max, verified,
                        f"verified after {k} steps ({n_cg} of them CG)",
                        lambda: callback is not None and callback(u, p))
        if end is not None:
            status, message = end
            break
    if k == 0:
        r = fine.f - fine.matvec(v)
    u, p = box.to_u(v), box.multipliers(r, v[piv] >= upper)
    stats = {"n_steps": k, "n_cg": n_cg, "n_vcycles": k, "presmoothing": presmoothing,
             "truncation_updates": ml.updates, "n_active": int(np.count_nonzero(p > 0)),
             "n_levels": len(ml.coarse_ops) + 1, **log.timing}
    return SolveResult(u=u, p=p, claimed_status=status, message=message, iterations=k,
                       setup_time=setup_time, solve_time=time.perf_counter() - log.t_solve,
                       history=log.history, stats=stats)


SOLVER = SolverSpec(
    name="tnnmg",
    summary="truncated nonsmooth Newton multigrid (Gräser-Kornhuber): nonlinear block "
            "Gauss-Seidel, a truncated geometric-multigrid V-cycle, projection and an exact "
            "line search on the Krause-Wohlmuth box-transformed problem",
    solve=solve,
    parameters=(
        Parameter("presmoothing", 0, "nonlinear node-block Gauss-Seidel sweeps per step "
                  "(alternating direction); 0: one, two on a Tresca step "
                  "(AUTO_PRESMOOTHING)", low=0, high=10, kind=int),
        Parameter("sweeps", 0, "smoothing sweeps of the linear V-cycle: V(sweeps, sweeps); "
                  "0: by dimension (AUTO_SWEEPS: 1 in 2D, 2 in 3D; a 3D Tresca step: 4, "
                  "TRESCA_3D_SWEEPS; CG on a 2D Tresca step's face: 2, TRESCA_FACE_SWEEPS)",
                  low=0, high=10, kind=int),
        Parameter("patch", 0, "graph layers of the contact patch around the constraint "
                  "rows' unknowns, solved exactly in each V-cycle after pre- and before "
                  "post-smoothing (0: none; each change of the active set refactorises it, "
                  "which costs more than it saves once CG runs on the face)",
                  low=0, high=20, kind=int),
        Parameter("stop", "verified", "verified: stop when the KKT residuals and the "
                  "certified energy bound meet tol; kkt: the KKT residuals alone (nested "
                  "iteration's coarse levels; the interface still certifies the answer)",
                  choices=("verified", "kkt")),
        Parameter("krylov", "cg", "cg: once a TNNMG step leaves the active set as it found "
                  "it (twice in a row), conjugate gradients on that face, preconditioned by "
                  "the truncated V-cycle, until a bound or a negative multiplier ends it "
                  "(MPRGP's expansion and proportioning; a 2D Tresca step's face also fixes "
                  "the stick set and the slip signs, and a kink ends it too; 3D Tresca "
                  "steps: TNNMG steps only); none: TNNMG steps only",
                  choices=("cg", "none")),
        Parameter("coarse", "truncated", "coarse operators: Galerkin products of the truncated "
                  "space (truncated) or the untruncated ones (untruncated; still monotone by "
                  "the projection and line search, fewer updates, more steps)",
                  choices=("truncated", "untruncated")),
    ),
    presets=VERIFIED_PRESETS,
    default_max_iter=500,
    role=Role.NEWTON,
    handles_friction=True,
    facets_reason=("its nonlinear smoother and truncation are built for the isotropic law "
                   "(discs); the faceted law is a QP, taken by the QP libraries and "
                   "tresca_exact"),
    # not that it solves the stabilised problem: handed over as it is, ``supports`` sees
    # its C block and names it as the reason to skip (its slack form would hide why)
    handles_C=True,
    supports=supports,
)
