"""The Tresca step of truncated nonsmooth Newton multigrid (:mod:`solvers.tnnmg`, Tresca
friction): what differs from the frictionless step.

One step of a load path (:class:`problems.friction.data.Friction`) is Gräser and
Kornhuber's setting of a block-separable nonsmooth energy (J. Comput. Math. 27, 2009;
Gräser and Sander, IMA J. Numer. Anal. 39, 2019), ``J~(v) + sum_i weight_i |v_t,i -
centre_i|`` (:class:`solvers.kernels.tnnmg_system.TrescaTerm`). Here:

* the line search on the nonsmooth energy (step 3): in 2D exact over its kinks
  (:func:`kink_search`, :func:`tresca_line_search_step`), in 3D a safeguarded Newton
  search on its nondecreasing derivative (:func:`disc_line_search`,
  :func:`disc_line_search_step`); the energy (:func:`tresca_energy`) and the
  stationarity residual with the term (:func:`tresca_stationarity`);
* in 3D the slip term's curvature in the truncated correction's operator
  (:class:`SlipCurvature`): the truncated Newton step of the nonsmooth energy;
* in 2D the faces on which the energy is quadratic (:class:`TrescaFace`: the normal
  active set, the stick set, the slip signs) and CG on them (:class:`TrescaFaceCG`);
  :func:`tresca_face_state` and :func:`contraction_on_face` split a solve's steps into those
  that find the face and the multigrid phase on it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from solvers.kernels.block_gs import block_inverses, with_pattern
from solvers.kernels.tnnmg_correction import FaceCG, TruncatedHierarchy, positions
from solvers.kernels.tnnmg_line_search import arc_or_line
from solvers.kernels.tnnmg_system import FineSystem, energy


@dataclass
class TrescaFace:
    """The face of a 2D Tresca step an iterate lies on: the normal pivots at their bounds
    (``active``) and each tangential row's slip sign (``sign``: +1, -1, or 0 where the row
    sticks or has no slip bound). On a face the energy is quadratic: ``J~(v)`` plus
    ``weight_i sign_i (v_t,i - centre_i)``, linear in the slipping rows."""

    active: np.ndarray
    sign: np.ndarray

    @classmethod
    def of(cls, fine: FineSystem, v: np.ndarray) -> "TrescaFace":
        term = fine.tresca
        sign = np.sign(v[term.pivot] - term.centre) * (term.weight > 0)
        return cls(v[fine.box.pivot] >= fine.box.upper, sign.astype(np.int64))

    def __eq__(self, other: object) -> bool:
        return (isinstance(other, TrescaFace) and np.array_equal(self.active, other.active)
                and np.array_equal(self.sign, other.sign))


def tresca_face_state(fine: FineSystem, v: np.ndarray) -> np.ndarray:
    """The face of a Tresca step's iterate ``v`` as one integer array: per normal pivot
    whether it is at its bound; per tangential row its slip sign (2D,
    :class:`TrescaFace`) or per node whether it slips (3D: the slip direction is not
    part of a face, the energy is curved across it). A solve's steps after the last
    change of its face (``stats["steps_on_face"]``) are its linear phase, where a TNNMG
    step is a multigrid step on a fixed face (Gräser-Kornhuber: the phase whose
    contraction is bounded in h); the steps before (``stats["steps_to_face"]``) find
    the normal active set and the stick set."""
    term = fine.tresca
    active = (v[fine.box.pivot] >= fine.box.upper).astype(np.int64)
    if term.k == 1:
        return np.concatenate([active, TrescaFace.of(fine, v).sign])
    return np.concatenate([active, (~term.stick(v) & (term.weight > 0)).astype(np.int64)])


def contraction_on_face(residuals: list, to_face: int) -> float:
    """The mean contraction per step of the stationarity residual (``residuals``: one per
    step) from the step at which the face last changed (``to_face``; 0: never, counted
    from the first step) to the last: ``(res_last / res_face)^(1/steps)``, the multigrid
    phase's rate, which does not depend on h where the step counts do through finding the
    face (:func:`tresca_face_state`); NaN without a step on the face."""
    first = max(to_face, 1)
    steps = len(residuals) - first
    if steps <= 0 or not residuals[first - 1] > 0:
        return float("nan")
    return float(residuals[-1] / residuals[first - 1]) ** (1.0 / steps)


@dataclass
class TrescaFaceCG(FaceCG):
    """:class:`solvers.kernels.tnnmg_correction.FaceCG` on a face of a 2D Tresca step
    (:class:`TrescaFace`; ``E``: its active normal pivots and sticking tangential unknowns,
    as the truncation holds them). The face's negative gradient is ``r`` minus
    ``weight sign`` at the slipping rows. A step is cut (expansion: the face is left) where
    a free normal pivot meets its bound or a slipping row reaches its kink (its slip would
    change sign; the row is written at its centre and sticks); the face is left too when
    the chopped gradient outweighs the free one (proportioning): the negative multipliers
    of the active pivots and, at the sticking rows, the excess of ``|r|`` over the weight
    (a multiplier leaving ``[-s_i, s_i]``). The energy never rises; the next TNNMG step's
    smoother releases what proportioning found.
    """

    face: TrescaFace | None = None

    def _gradient(self, fine: FineSystem, r: np.ndarray) -> np.ndarray:
        g = r.copy()
        g[fine.tresca.pivot] -= fine.tresca.weight * self.face.sign
        g[self.E] = 0.0
        return g

    def step(self, fine: FineSystem, ml: "TruncatedHierarchy", v: np.ndarray, r: np.ndarray,
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


def kink_search(base: float, curvature: float, kinks: np.ndarray, jumps: np.ndarray, longest: float
                ) -> float:
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


def tresca_energy(fine: FineSystem, v: np.ndarray, r: np.ndarray) -> float:
    """The transformed Tresca step's energy ``J~(v) + sum_i weight_i |v_t,i - centre_i|``."""
    return energy(fine, v, r) + fine.tresca.value(v)


def tresca_line_search_step(fine: FineSystem, v: np.ndarray, r: np.ndarray, c: np.ndarray,
                            piv: np.ndarray, upper: np.ndarray
                            ) -> tuple[np.ndarray, np.ndarray, float]:
    """The new iterate of a Tresca step from the truncated correction ``c``:
    :func:`solvers.kernels.tnnmg_line_search.line_search_step` with the line search on the
    nonsmooth energy.

    Along the projected correction ``d`` the energy is convex and piecewise quadratic in
    the step ``a``: the quadratic part, and ``weight_i |z_i + a d_i|`` with a kink at
    ``-z_i / d_i`` for every slipping row (``z = v_t - centre``); its exact minimiser over
    the feasible segment (:func:`kink_search`; a kink reached is written exactly, the row
    then sticks). Where the normal bounds cut the segment short, the projection arc
    ``min(v + a c, upper)`` as in :func:`solvers.kernels.tnnmg_line_search.line_search_step`,
    judged by the nonsmooth energy.
    """
    term = fine.tresca
    slack = upper - v[piv]
    d = c.copy()
    d[piv] = np.minimum(d[piv], slack)
    Ad = fine.matvec(d)
    curvature, slope = float(d @ Ad), float(r @ d)
    if term.k > 1:
        return disc_line_search_step(fine, v, r, c, d, Ad, curvature, slope, piv, upper, slack)
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
        step = kink_search(base, curvature, kinks, jumps, longest)
        cut = step == 0.0 or (step >= longest and base + longest * curvature + float(
            jumps[kinks < longest].sum()) < 0.0)
    v_line, r_line = v + step * d, r - step * Ad
    if step > 0:
        reached = (kink == step) if curvature > 0 else np.zeros(term.pivot.size, dtype=bool)
        v_line[term.pivot[reached]] = term.centre[reached]
    return arc_or_line(fine, tresca_energy, v, c, piv, upper, v_line, r_line, step, cut)


def disc_line_search_step(fine: FineSystem, v: np.ndarray, r: np.ndarray, c: np.ndarray,
                          d: np.ndarray, Ad: np.ndarray, curvature: float, slope: float,
                          piv: np.ndarray, upper: np.ndarray, slack: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray, float]:
    """:func:`tresca_line_search_step` in 3D: along the projected correction ``d`` the
    energy is convex and smooth but where a node's tangential offset ``z_i + a d_i``
    passes through zero; its minimiser over the feasible segment by
    :func:`disc_line_search`. A kink reached is written exactly (the node then sticks);
    where the normal bounds cut the segment short, the projection arc as in
    :func:`solvers.kernels.tnnmg_line_search.line_search_step`."""
    term = fine.tresca
    step, cut, reached = 0.0, True, np.zeros(term.weight.size, dtype=bool)
    if curvature > 0:
        rising = d[piv] > 0
        longest = float(np.min(slack[rising] / d[piv][rising])) if rising.any() else np.inf
        z = term.blocks(v[term.pivot] - term.centre)
        dt = term.blocks(d[term.pivot])
        step, reached, ends_short = disc_line_search(-slope, curvature, z, dt, term.weight,
                                                     longest)
        cut = step == 0.0 or ends_short
    v_line, r_line = v + step * d, r - step * Ad
    if reached.any():
        nodes = term.blocks(term.pivot)[reached].ravel()
        v_line[nodes] = term.blocks(term.centre)[reached].ravel()
    return arc_or_line(fine, tresca_energy, v, c, piv, upper, v_line, r_line, step, cut)


def disc_line_search(base: float, curvature: float, z: np.ndarray, dt: np.ndarray,
                     weight: np.ndarray, longest: float) -> tuple[float, np.ndarray, bool]:
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


def tresca_stationarity(fine: FineSystem, r: np.ndarray, bound: np.ndarray, v: np.ndarray) -> float:
    """:func:`solvers.kernels.tnnmg_system.stationarity` with Tresca's term: at a
    tangential unknown ``r`` minus the term's derivative where the row slips, the excess of
    ``|r|`` over the weight where it sticks."""
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
        stick = np.repeat(np.all(term.blocks(v[term.pivot] == term.centre), axis=1), term.k)
        rn = term.blocks(rt)
        length = np.sqrt(np.einsum("ij,ij->i", rn, rn))
        excess = np.maximum(length - term.weight, 0.0) / np.where(length > 0, length, 1.0)
        res[term.pivot] = np.where(stick, (rn * excess[:, None]).ravel(),
                                   rt - term.gradient(v))
    scale = max(float(np.abs(fine.f).max()), float(np.abs(fine.f - r).max()), 1e-300)
    return float(np.abs(res).max()) / scale


@dataclass
class SlipCurvature:
    """3D Tresca: the slip term's curvature in the truncated linear correction.

    Where node ``i`` slips (``z_i = v_t,i - centre_i != 0``) its term ``weight_i |z_i|`` is
    smooth, with the Hessian ``weight_i / |z_i| (I - z_i z_i' / |z_i|^2)`` on its two
    tangential unknowns (in 2D it is zero: the term is linear off its kink). Left out, the
    correction overshoots across the slip direction and the line search shortens every
    step; put into the correction's operator (the fine system ``A~ + K``: the
    transformation's update with places for ``K`` and the constrained blocks' inverses
    refreshed; the coarse operators by
    :meth:`solvers.kernels.tnnmg_correction.TruncatedHierarchy.truncate`), the step is the
    truncated Newton step of the nonsmooth energy (Gräser-Kornhuber: the Hessian of
    the energy where it is twice differentiable).
    """

    fine: FineSystem
    positions: np.ndarray          # (m, k, k): the places of K's entries in fine.C.data
    base: np.ndarray               # fine.C.data without K
    block_ptr: np.ndarray          # the constrained node blocks, for block_inverses
    block_dofs: np.ndarray
    places: sp.csr_matrix          # every place of K: the tangential unknowns' blocks

    @classmethod
    def build(cls, fine: FineSystem) -> "SlipCurvature":
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
        lin = FineSystem(fine.A, C, fine.f, box, fine.diag0.copy(), fine.inv_full.copy(),
                         fine.inv_sub.copy(), blocks, fine.upper_block, tresca=term)
        return cls(lin, positions(C, rows, cols).reshape(-1, k, k), C.data.copy(),
                   block_ptr, block_dofs, pattern)

    def set(self, v: np.ndarray, stick: np.ndarray) -> sp.csr_matrix:
        """Put the curvature of the iterate ``v`` (slipping nodes: not ``stick``) into the
        fine system; returns ``K`` ``(n, n)``."""
        fine, term = self.fine, self.fine.tresca
        z, length = term.offsets(v)
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
