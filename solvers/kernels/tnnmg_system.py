"""What truncated nonsmooth Newton multigrid (:mod:`solvers.tnnmg`) iterates on: the
box-transformed fine system, its node-block smoother and, on a Tresca step, the nonsmooth
term in the transformed unknowns.

The change of variables of Krause and Wohlmuth (:mod:`solvers.kernels.contact_box`:
``u = T v``, ``A~ = T' A T``, ``v[pivot] <= upper``) turns the nodal constraints into
bounds on single unknowns. :class:`FineSystem` holds ``A~ = A + C``: the scene's ``A``
(not copied) and the transformation's update ``C`` on the rows near the contact, with the
node blocks' inverses the compiled Gauss-Seidel sweeps of :mod:`solvers.kernels.block_gs`
need; :func:`presmooth` is step 1 of a TNNMG step, nonlinear node-block Gauss-Seidel with
each block minimised exactly (Gräser and Kornhuber, J. Comput. Math. 27, 2009). On a
Tresca step the tangential rows become coordinates too, and :class:`TrescaTerm` is the
energy's nonsmooth part ``sum_i weight_i |v_t,i - centre_i|``, separable by node blocks
(Gräser and Sander, IMA J. Numer. Anal. 39, 2019), with the tangential multipliers it
gives back. :func:`energy` and :func:`stationarity` are the transformed problem's energy
and scaled stationarity residual, which gates the suite's verification.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from problems.friction.data import Friction
from problems.qp import ContactQP
from solvers.kernels.block_gs import (block_gauss_seidel, block_inverses, tresca_block_gauss_seidel,
                                      unsigned_index)
from solvers.kernels.contact_box import BoxTransformation, box_transformation


@dataclass
class FineSystem:
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
    tresca: "TrescaTerm | None" = None

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
class TrescaTerm:
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

    def blocks(self, a: np.ndarray) -> np.ndarray:
        """A node-major vector as ``(m, k)``."""
        return a.reshape(-1, self.k)

    def offsets(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per node ``v_t,i - centre_i`` ``(m, k)`` and its length."""
        z = self.blocks(v[self.pivot] - self.centre)
        return z, np.sqrt(np.einsum("ij,ij->i", z, z))

    def value(self, v: np.ndarray) -> float:
        if self.k == 1:
            return float(self.weight @ np.abs(v[self.pivot] - self.centre))
        return float(self.weight @ self.offsets(v)[1])

    def stick(self, v: np.ndarray) -> np.ndarray:
        """Nodes whose slip is exactly zero (with a positive slip bound)."""
        if self.k == 1:
            return (v[self.pivot] == self.centre) & (self.weight > 0)
        return np.all(self.blocks(v[self.pivot] == self.centre), axis=1) & (self.weight > 0)

    def multipliers(self, residual_v: np.ndarray, friction: Friction, v: np.ndarray
                    ) -> np.ndarray:
        """The tangential multipliers ``lam`` (``A u + B'p + T'lam = f``) from the residual
        ``f~ - A~v`` of the transformed problem: ``R_i r[pivot_i] / theta_i`` (the
        stationarity of the tangential unknowns), in the friction discs ``|lam_i| <= s_i``
        (:meth:`problems.friction.data.Friction.clip`; as ``p >= 0``: what is left over
        stays in the stationarity residual).

        A slipping node's multiplier is the one its slip demands, ``s_i sign(slip_i)``
        (``sign(theta_i (v_t,i - centre_i))``; 3D: ``s_i slip_i / |slip_i|`` with
        ``slip_i = theta_i R_i z_i``, ``z_i = v_t,i - centre_i``): then
        ``lam_i . slip_i = s_i |slip_i|`` exactly, and the iterate's error stays in the
        stationarity residual, which the certified bound weighs by ``A^-1`` (second
        order), instead of in the slip complementarity, which enters the duality gap
        linearly (:func:`solvers.certificate.certify`: with the clipped residual the bound
        lags the energy error by orders of magnitude, docs/guide/friction.md). Any
        multiplier in ``[-s_i, s_i]`` gives a certified bound."""
        if self.k == 1:
            lam = friction.clip(residual_v[self.pivot] / self.theta)
            slip = np.sign(self.theta) * np.sign(v[self.pivot] - self.centre)
            slipping = (slip != 0) & (self.weight > 0)
            lam[slipping] = friction.slip_bound[slipping] * slip[slipping]
            return lam
        lam = self.blocks(friction.clip((np.einsum(
            "ijl,il->ij", self.frame, self.blocks(residual_v[self.pivot]))
            / self.theta[:, None]).ravel()))
        z, length = self.offsets(v)
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
        z, length = self.offsets(v)
        moving = length > 0
        out = np.zeros_like(z)
        out[moving] = z[moving] * (self.weight[moving] / length[moving])[:, None]
        return out.ravel()


def tresca_term(qp: ContactQP, box: BoxTransformation) -> TrescaTerm:
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
    return TrescaTerm(box.tangential_pivot, theta, frame, weight, centre, weight_block,
                      centre_block.ravel())


def fine_system(qp: ContactQP, tresca: bool = False) -> FineSystem:
    """The transformed fine system; ``tresca``: the tangential rows made coordinates too and
    the step's Tresca term (:class:`TrescaTerm`)."""
    box = box_transformation(qp, qp.friction.T if tresca else None)
    A = sp.csr_matrix(qp.A)
    if not A.has_sorted_indices:
        A = A.sorted_indices()
    C = box.operator_update(A)
    diag0, inv_full, inv_sub = block_inverses(A, box.node_ptr, box.node_dofs, C)
    bounded = np.flatnonzero(box.block_row >= 0)
    upper = np.full(box.node_ptr.size - 1, np.inf)
    upper[bounded] = box.upper[box.block_row[bounded]]
    return FineSystem(A, C, box.load(qp.f), box, diag0, inv_full, inv_sub, bounded, upper,
                      tresca=tresca_term(qp, box) if tresca else None)


def stationarity(fine: FineSystem, r: np.ndarray, bound: np.ndarray) -> float:
    """The transformed problem's scaled stationarity residual: ``r = f~ - A~v`` off the
    pivots at their bounds, its negative part on them (the positive part is the
    multiplier), over ``max(|f~|, |A~v|)``. Feasibility and complementarity hold by
    construction; it gates the suite's check (:data:`solvers.tnnmg.CHECK_FACTOR`)."""
    res = r.copy()
    res[bound] = np.minimum(res[bound], 0.0)
    scale = max(float(np.abs(fine.f).max()), float(np.abs(fine.f - r).max()), 1e-300)
    return float(np.abs(res).max()) / scale


def energy(fine: FineSystem, v: np.ndarray, r: np.ndarray) -> float:
    """``J~(v) = 1/2 v'A~v - f~'v`` from the residual ``r = f~ - A~v``."""
    return -0.5 * float(v @ (fine.f + r))


def presmooth(fine: FineSystem, v: np.ndarray, mode: np.ndarray, forward: bool, sweeps: int
              ) -> bool:
    """Step 1 (:mod:`solvers.tnnmg`): ``sweeps`` nonlinear node-block Gauss-Seidel sweeps on
    ``v`` in place, alternating direction from ``forward``; returns the next direction."""
    for _ in range(sweeps):
        fine.sweep(v, fine.f, mode, forward)
        forward = not forward
    return forward
