"""The verification: how the suite certifies an answer, whoever produced it.

:func:`verify` fills in a :class:`~solvers.base.SolveResult`'s four KKT residuals
(:func:`problems.kkt.kkt_residuals`; on a frictional problem the six of
:func:`problems.friction.residuals.friction_residuals`) and a certified bound on its energy error
(:func:`duality_gap`, weak duality; for a Tresca step with the tangential multipliers),
and decides the verified status. :func:`certify`
computes the bound (kept per problem, ``qp.cache.certificate``) with the linear solver
of :func:`linear_solver` (kept per problem, ``qp.cache.linear_solver``). Solvers that
stop on the verification itself (the exact PDAS, semismooth Newton, the augmented
projection) call :func:`certify`.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from problems.floating import floating_modes
from problems.friction.polygon import polygon_normals, polygon_vertices
from problems.friction.residuals import friction_residuals, tresca_energy
from problems.kkt import KKTResiduals, kkt_residuals
from problems.qp import ContactQP
from solvers.base import (CONTRACT, COULOMB_MONOLITHIC, SolveResult, contract_violation,
                          tangential_rows)


@dataclass
class DualityGap:
    """A certified bound on the energy error of ``u`` by weak duality.

    For a feasible ``u_f`` (``B u_f <= g``) and any ``p~ >= 0`` the duality gap with
    the exact dual function ``q(p~) = min_v L(v, p~)`` bounds the energy error:
    ``J(u_f) - q(p~) >= J(u_f) - J(u*) >= 1/2 ||u_f - u*||_A^2``, so
    ``||u - u*||_A <= ||u - u_f||_A + sqrt(2 gap)``. :func:`duality_gap` tries a few
    pairs ``(u_f, p~)`` built from the solver's ``(u, p)`` and keeps the smallest
    bound (each is valid).

    Attributes
    ----------
    gap : float
        The duality gap of the best pair (>= 0 up to round-off).
    relative_gap : float
        ``gap / |J(u_f)|``: dimensionless.
    shift : float
        ``||u - u_f||_A``: the correction making ``u`` feasible.
    energy_bound : float
        Certified ``||u - u*||_A <= shift + sqrt(2 gap)``.
    relative_energy_bound : float
        ``energy_bound / (||u_f||_A - sqrt(2 gap))``: the raw bound on the relative
        energy error ``||u - u*||_A / ||u*||_A`` (inf if not positive). Below
        ``floor`` it is rounding, not a bound; :attr:`certified_bound` is what is
        reported.
    floor : float
        The bound's floating-point floor (relative): the gap is a sum of terms
        known to about machine precision, so bounds below ``~sqrt(eps)`` cannot be
        certified.
    pair_gap : float
        The relative gap of the solver's own pair ``(u_f, p)``: with its
        multipliers as they are (their complementarity and S-norm error,
        ``1/2 ||p - p*||_S^2 <= gap``).
    certified : bool
        False if no feasible ``u_f`` was found (then the bounds are inf).
    """

    gap: float
    relative_gap: float
    shift: float
    energy_bound: float
    relative_energy_bound: float
    floor: float
    pair_gap: float
    certified: bool

    @property
    def certified_bound(self) -> float:
        """The relative energy error the certificate certifies: the raw bound, or its
        floor where the raw bound lies below it (a gap known to rounding certifies no
        less). What every result row, JSON file and report cell reports as
        ``energy_bound``, with the floor beside it as ``energy_bound_floor``."""
        return max(self.relative_energy_bound, self.floor)

    def as_dict(self) -> dict:
        return {"energy_bound": self.certified_bound, "energy_bound_floor": self.floor,
                "relative_gap": self.relative_gap, "pair_gap": self.pair_gap,
                "feasibility_shift": self.shift, "certified": self.certified}

    def meets(self, tol: float) -> bool:
        """The certified relative energy bound is <= ``tol`` (or at its floor)."""
        return self.certified and self.relative_energy_bound <= certifiable(tol, self.floor)


#: How far above its floating-point floor a bound counts as "at the floor".
FLOOR_FACTOR = 4.0


def certifiable(tol, floor):
    """The energy-error level a run at ``tol`` is certified to: ``tol``, or the bound's
    floor (times :data:`FLOOR_FACTOR`) where that is higher (arrays work too)."""
    return np.maximum(tol, FLOOR_FACTOR * np.asarray(floor, dtype=float))


def _pivots(qp: ContactQP, B: sp.csr_matrix) -> tuple[np.ndarray, np.ndarray]:
    """One unknown per row of ``B`` (the hard rows of ``qp``, constrained surface's first)
    to move it with: the constrained node's component along the row's direction if free
    (a contact code would move the constrained surface), else the row's largest entry.
    Returns ``(pivot, coefficient)``."""
    pivot = np.asarray(abs(B).argmax(axis=1)).ravel()
    if qp.contact is not None and qp.free_dofs is not None and qp.u_fixed is not None:
        pos = -np.ones(len(qp.u_fixed), dtype=np.int64)
        pos[qp.free_dofs] = np.arange(qp.n)
        comp = np.abs(qp.contact.direction).argmax(axis=1)
        own = pos[qp.contact.nodes * qp.dim + comp]
        mc = qp.m_contact                  # the reverse rows keep their largest entry
        pivot[:mc] = np.where(own >= 0, own, pivot[:mc])
    return pivot, np.asarray(B[np.arange(B.shape[0]), pivot]).ravel()


def feasible_point(qp: ContactQP, u: np.ndarray, tight: np.ndarray | None = None,
                   sweeps: int = 3) -> tuple[np.ndarray, bool]:
    """``u_f = u + delta`` with ``B u_f <= g``, and ``B u_f = g`` on the rows ``tight``,
    on the hard rows: all rows without ``C``, else the constrained surface's (the first
    ``qp.m_contact``; a stabilised problem's reverse rows are penalised, not hard).

    Each violated (or, in ``tight``, slack) row is moved on its pivot unknown
    (:func:`_pivots`); rows sharing unknowns interact, so up to ``sweeps``
    passes. Returns ``(u_f, feasible)``.
    """
    u_f = np.array(u, dtype=float)
    mc = qp.m if qp.C is None else qp.m_contact
    if mc == 0:
        return u_f, True
    B, g = qp.B.tocsr()[:mc], qp.g[:mc]
    pivot, coef = _pivots(qp, B)
    tight = np.zeros(mc, dtype=bool) if tight is None else np.asarray(tight, dtype=bool)
    scale = max(float(np.max(np.abs(B @ u_f))), float(np.max(np.abs(g))), 1e-300)
    for _ in range(sweeps):
        res = B @ u_f - g
        move = (res > 0) | (tight & (res < 0))
        if not move.any():
            break
        np.subtract.at(u_f, pivot[move], res[move] / coef[move])
    return u_f, bool(np.all(B @ u_f - g <= 1e-14 * scale))


def duality_gap(qp: ContactQP, u: np.ndarray, p: np.ndarray,
                solve_A: Callable[..., np.ndarray],
                target: float | None = None, lam: np.ndarray | None = None) -> DualityGap:
    """The certified energy-error bound of ``u`` (:class:`DualityGap`).

    ``solve_A(r, guess=x0)`` returns ``A^{-1} r`` (the bound is certified up to that
    solve's accuracy, which the caller drives far below the gap); ``x0``, the feasible
    point of the pair (close to ``A^{-1} r`` for a good pair), is where an iterative
    solve may start: it changes the cost, not the accuracy asked for. For a pair
    ``(u_f, p~)`` with ``x = A^{-1}(f - B'p~)`` the gap is a sum of non-negative
    terms, computed without cancellation::

        J(u_f) - q(p~) = 1/2 ||u_f - x||_A^2 + p~'(g - B u_f)

    Pairs tried: the solver's ``(u, p_+)`` made feasible; and, for thresholds
    ``theta`` in (1e-8, 1e-4), ``u`` made feasible and tight on the rows with
    ``p > theta max p`` with ``p~`` = ``p`` there and 0 elsewhere (a solver's
    complementarity error would otherwise dominate the bound of its ``u``).
    Each pair costs one linear solve; with ``target`` the search stops at the
    first pair whose bound meets it. With a stabilisation block ``C`` (Sect. 7.5;
    diagonal, zero on the hard rows, which come first) the primal function is
    ``P(u) = J(u) + 1/2 v'C^{-1}v``, ``v = (Bu - g)_+`` on the rows with ``C > 0``;
    ``u`` is made feasible on the hard rows only:
    ``P(u) - q(p) = 1/2 ||u - x||_A^2 + p'(g - Bu) + 1/2 p'Cp + 1/2 v'C^{-1}v``.

    A Tresca step (``qp.friction``, the tangential multipliers ``lam`` given; nodal
    rows, no ``C``): the primal function is ``J(u) = 1/2 u'Au - f'u + sum_i s_i
    |slip_i(u)|``, ``slip(u) = T u - r`` (``r = previous - offset``). With
    ``s_i |t| = max_{|l| <= s_i} l t`` the Lagrangian is
    ``L(v, p, l) = 1/2 v'Av - f'v + p'(Bv - g) + l'(Tv - r)`` and for any dual point in
    the box ``p~ >= 0``, ``|l~_i| <= s_i`` (``l~`` = ``lam`` clipped to ``[-s, s]``; in 3D
    each node's 2-vector scaled back radially into its disc, isotropic friction) and
    any feasible ``u_f``: ``J(u_f) >= L(u_f, p~, l~) >= q(p~, l~) = min_v L``, the
    minimiser ``x = A^{-1}(f - B'p~ - T'l~)``. The faceted law (``s_i h_Pk(t) =
    max_{l in s_i P_k} l . t``, :class:`problems.friction.data.Friction`) is the same with ``l~``
    projected onto the ``k``-gons ``s_i P_k`` and ``s_i h_Pk(slip_i)`` in place of
    ``s_i |slip_i|`` in ``J`` and in the gap. The dual is the box problem of
    :mod:`solvers.kernels.tresca` (``p >= 0``, ``|lam| <= s``), so weak duality holds as
    above, and as ``L`` is quadratic in ``v`` with Hessian ``A`` the gap is again a sum
    of non-negative terms::

        J(u_f) - q(p~, l~) = 1/2 ||u_f - x||_A^2 + p~'(g - B u_f)
                             + sum_i (s_i |slip_i(u_f)| - l~_i . slip_i(u_f))

    ``J`` is ``A``-strongly convex (a quadratic plus a convex term) and ``u*`` minimises
    it on the convex feasible set, so ``J(u_f) - J(u*) >= 1/2 ||u_f - u*||_A^2`` as in
    the frictionless case: the same bound ``||u - u*||_A <= ||u - u_f||_A +
    sqrt(2 gap)``, relative to ``||u_f||_A - sqrt(2 gap)``, and ``relative_gap``
    relative to the Tresca energy ``|J(u_f)|``. The pairs tried are those above, each
    with ``l~``, and then the stick pairs: a library's ``u`` carries a small residual
    slip at the stick nodes (``|l_i| < s_i``, exact slip 0) and the friction term is
    linear in it (``~ s_i |slip_i|``) where the energy error is quadratic, so the pairs
    above overestimate the error by orders of magnitude. ``u_f`` is the
    ``A``-orthogonal projection of ``u`` onto ``{v : B_a v = g_a, slip_i(v) = 0 on the
    stick nodes}`` (:func:`stick_point`; the active rows ``a`` by
    :func:`complementary_active`, the stick nodes by :func:`stick_nodes`, on a faceted law
    also the slip along the facet at the nodes of :func:`facet_slips`; none where
    ``A^{-1} C'`` is neither cached nor cheap), made feasible, with ``p~ = p_+`` on the
    active rows and 0 elsewhere, and with ``l~``, then with ``l~`` aligned to the slip of
    ``u_f`` at the slipping nodes (:func:`aligned_multipliers`, which makes those nodes'
    friction terms vanish; not repeated where it moves none). They cost one solve with
    ``A`` for the columns of ``C'`` (none with the cached dual operators) and one per
    pair, at most two. Each is a feasible ``u_f`` and a dual point in the box, so the
    chain above holds for it unchanged::

        ||u - u*||_A <= ||u - u_f||_A + ||u_f - u*||_A
                     <= ||u - u_f||_A + sqrt(2 (J(u_f) - J(u*)))
                     <= ||u - u_f||_A + sqrt(2 (J(u_f) - q(p~, l~)))

    and the best of all pairs is kept. On the stick nodes the friction term vanishes,
    and ``||u - u_f||_A <= ||u - u*||_A`` whenever the exact solution lies in the
    projected set (the held rows hold for it), so the bound is of
    the size of the true error. Frictionless problems (or ``lam`` None) never try them.
    """
    eps = np.finfo(float).eps
    u = np.asarray(u, dtype=float)
    p_plus = np.maximum(np.asarray(p, dtype=float), 0.0)
    inf = float("inf")

    fr = qp.friction if lam is not None else None
    if fr is not None:
        if qp.C is not None:
            return DualityGap(inf, inf, inf, inf, inf, inf, inf, False)
        s = fr.slip_bound
        lam_t = fr.clip(lam)           # into the dual box (3D: the discs or the k-gons)
        energy = lambda v: tresca_energy(qp, v)
    else:
        energy = qp.energy

    def pair(u_f, p_t, extra=0.0, l_t=None):
        r = qp.f - qp.B.T @ p_t
        if fr is not None:
            l_t = lam_t if l_t is None else l_t
            r = r - fr.T.T @ l_t
            slip = fr.slip(u_f)
            extra = float(np.sum(s * fr.dissipation(slip) - fr.inner(l_t, slip)))
            extra_noise = float((s + fr.magnitude(l_t)) @ fr.magnitude(slip)) + float(
                np.abs(l_t) @ (abs(fr.T) @ np.abs(u_f) + np.abs(fr.offset - fr.previous)))
        x = solve_A(r, guess=u_f)
        e = u_f - x
        slack = qp.g - qp.B @ u_f
        gap = 0.5 * float(e @ (qp.A @ e)) + float(p_t @ slack) + extra
        d = u_f - u
        shift = float(np.sqrt(max(d @ (qp.A @ d), 0.0)))
        norm = float(np.sqrt(max(u_f @ (qp.A @ u_f), 0.0)))
        root = np.sqrt(2.0 * max(gap, 0.0))
        noise = 8 * eps * (float(p_t @ (np.abs(qp.g) + abs(qp.B) @ np.abs(u_f))) + norm ** 2
                           + abs(float(qp.f @ u_f)))
        if fr is not None:
            noise += 8 * eps * extra_noise
        if norm > 0:
            rel = (shift + root) / (norm - root) if norm > root else inf
            floor = np.sqrt(2 * noise) / norm
        else:            # u_f = 0: certified exactly if the bound is zero (e.g. no load)
            rel, floor = (0.0 if shift + root == 0 else inf), 0.0
        return gap, shift, shift + root, rel, floor, gap / max(abs(energy(u_f)), 1e-300)

    if qp.C is not None:
        c = qp.C.diagonal()
        soft = c > 0
        hard_rows = np.flatnonzero(~soft)
        if (abs(qp.C - sp.diags(c)).max() > 0 or np.any(c < 0)
                or np.any(hard_rows >= qp.m_contact)):
            return DualityGap(inf, inf, 0.0, inf, inf, inf, inf, False)
        u_f, feasible = feasible_point(qp, u) if hard_rows.size else (u, True)
        if not feasible:
            return DualityGap(inf, inf, inf, inf, inf, inf, inf, False)
        v = np.maximum(qp.B @ u_f - qp.g, 0.0)[soft]
        gap, shift, bound, rel, floor, relgap = pair(
            u_f, p_plus, 0.5 * float(p_plus[soft] @ (c[soft] * p_plus[soft]))
            + 0.5 * float(v @ (v / c[soft])))
        return DualityGap(gap, relgap, shift, bound, rel, floor, relgap, True)
    u_f, feasible = feasible_point(qp, u)
    if not feasible:
        return DualityGap(inf, inf, inf, inf, inf, inf, inf, False)
    best = pair(u_f, p_plus)
    pair_gap = best[5]
    top = float(p_plus.max()) if qp.m else 0.0
    for theta in (1e-8, 1e-4):
        if target is not None and best[3] <= max(target, 4.0 * best[4]):
            break
        active = p_plus > theta * top
        if top == 0 or active.all() and theta > 1e-8:
            continue
        u_t, ok = feasible_point(qp, u, tight=active)
        if ok:
            cand = pair(u_t, np.where(active, p_plus, 0.0))
            if cand[3] < best[3]:
                best = cand
    if fr is not None and not (target is not None and best[3] <= max(target, 4.0 * best[4])):
        active = complementary_active(qp, u_f, p_plus)
        stick = stick_nodes(fr, u, lam_t)
        facets = facet_slips(fr, fr.slip(u), stick)
        u_s = stick_point(qp, u, active, stick, facets, solve_A)
        if u_s is not None:
            p_t = np.where(active, p_plus, 0.0)
            aligned = aligned_multipliers(fr, lam_t, fr.slip(u_s), stick, facets)
            for l_t in (lam_t,) if np.array_equal(aligned, lam_t) else (lam_t, aligned):
                if target is not None and best[3] <= max(target, 4.0 * best[4]):
                    break
                cand = pair(u_s, p_t, l_t=l_t)
                if cand[3] < best[3]:
                    best = cand
    gap, shift, bound, rel, floor, relgap = best
    return DualityGap(gap=float(gap), relative_gap=float(relgap), shift=shift,
                      energy_bound=float(bound), relative_energy_bound=float(rel),
                      floor=float(floor), pair_gap=float(pair_gap), certified=True)


#: A node sticks (:func:`stick_nodes`) where its slip is at most this fraction of the
#: largest slip, whatever its multiplier.
STICK_SLIP = 1e-8
#: A faceted law's slipping node slips along a facet's normal (:func:`facet_slips`) where
#: its slip direction is within this angle (radians) of it: the exact slip is exactly
#: along it, an answer's within its accuracy; a vertex node's lies inside a cone of
#: ``2 pi / k`` around the vertex.
FACET_ANGLE = 1e-2
#: Most stacked rows (active normal rows and the stick nodes' tangential rows) for which
#: :func:`stick_point` forms ``A^{-1} C'`` without the cached dual operators: the dense
#: ``C A^{-1} C'`` is then factorised in ``rows^3 / 3`` flops (2.7e9 at the limit, about a
#: second), the size the exact Tresca route also takes
#: (:data:`solvers.kernels.tresca.TRESCA_EXACT_MAX_M`).
STICK_MAX_ROWS = 2000
#: Largest dense ``A^{-1} C'`` (entries, ``n`` times the stacked rows) :func:`stick_point`
#: forms: 200 MB, about four such arrays at once while it is solved for (``C'``, the solve
#: and its refinement step), e.g. 2000 rows at 12.5k unknowns, 160 rows at 150k.
STICK_MAX_ENTRIES = 25 * 10**6


def complementary_active(qp: ContactQP, u_f: np.ndarray, p_plus: np.ndarray) -> np.ndarray:
    """The normal rows the stick pair holds tight (:func:`stick_point`): ``p_i``
    larger, relative to the largest, than the row's slack ``g_i - B_i u_f`` relative to
    the largest. Of the two complementary quantities an answer has the active row's
    slack and the inactive row's ``p_i`` small (an interior-point method's ``p_i ~
    mu / slack_i`` lies far above a fixed threshold ``theta max p`` at a loose stop).
    ``(m,)`` bool, none where ``p_+ = 0``."""
    top = float(p_plus.max(initial=0.0))
    if top == 0:
        return np.zeros(qp.m, dtype=bool)
    slack = np.maximum(qp.g - qp.B @ u_f, 0.0)
    return p_plus / top > slack / max(float(slack.max()), np.finfo(float).tiny)


def stick_nodes(fr, u: np.ndarray, lam_t: np.ndarray) -> np.ndarray:
    """The nodes :func:`stick_point` holds at zero slip: ``s_i > 0`` and the clipped
    multiplier ``lam_t`` further inside its bound, relative to the largest bound, than
    the node slips relative to the largest slip (of the two complementary quantities,
    ``s_i - |lam_i|`` and ``|slip_i|``, an answer has the stick node's one small), or a
    slip of at most :data:`STICK_SLIP` of the largest (a node at the stick-slip
    transition). Only the sharpness of the bound depends on this choice, never its
    validity. ``(m_contact,)`` bool."""
    s = fr.slip_bound
    size = fr.magnitude(fr.slip(u))
    top_s = max(float(s.max(initial=0.0)), np.finfo(float).tiny)
    top_slip = float(size.max(initial=0.0))
    return (s > 0) & (((s - fr.gauge(lam_t)) / top_s
                       > size / max(top_slip, np.finfo(float).tiny))
                      | (size <= STICK_SLIP * top_slip))


def facet_slips(fr, slip: np.ndarray, stick: np.ndarray) -> np.ndarray:
    """The slipping nodes of a faceted law whose slip points along a facet's outward
    normal ``n_j`` (within :data:`FACET_ANGLE`): there the exact multiplier lies on the
    facet ``[s_i v_j, s_i v_j+1]`` and the exact slip is along ``n_j``, so the stick
    point also holds the slip's component along the facet at zero. ``(m_contact, 2)``:
    the facet's direction ``(v_j+1 - v_j) / |.|`` at those nodes, 0 elsewhere (all 0 for
    an isotropic law)."""
    out = np.zeros((len(fr.slip_bound), fr.components))
    if not fr.facets:
        return out
    blocks, size = fr.blocks(slip), fr.magnitude(slip)
    normals = polygon_normals(fr.facets)
    cosine = (blocks @ normals.T) / np.where(size > 0, size, 1.0)[:, None]
    j = np.argmax(cosine, axis=1)
    on = ((fr.slip_bound > 0) & ~stick & (size > 0)
          & (cosine[np.arange(len(j)), j] >= np.cos(FACET_ANGLE)))
    along = np.column_stack([-normals[:, 1], normals[:, 0]])[j]   # n_j turned by 90 degrees
    out[on] = along[on]
    return out


def aligned_multipliers(fr, lam_t: np.ndarray, slip: np.ndarray, stick: np.ndarray,
                        facets: np.ndarray) -> np.ndarray:
    """``lam_t`` with each slipping node's multiplier moved onto the subgradient of its
    dissipation at ``slip``, so that its friction term ``s_i |slip_i| - l_i . slip_i``
    (faceted: ``s_i h_Pk(slip_i) - l_i . slip_i``) vanishes: ``s_i slip_i / |slip_i|``
    (isotropic; 2D ``s_i sign(slip_i)``); faceted, on a facet node of ``facets``
    (:func:`facet_slips`, its slip along the facet's normal) ``lam_t_i`` projected onto
    that facet's segment, elsewhere the vertex ``s_i v_j`` where ``v_j . slip_i`` is
    largest. Only nodes that are not in ``stick``, have ``s_i > 0``, ``slip_i != 0`` and
    ``lam_t_i . slip_i > 0`` move. The result lies in the dual box (``|l_i| <= s_i``,
    ``l_i in s_i P_k``)."""
    s = fr.slip_bound
    blocks, size, lam = fr.blocks(slip), fr.magnitude(slip), fr.blocks(lam_t)
    if fr.facets:
        vertices = polygon_vertices(fr.facets)
        top = np.argmax(blocks @ vertices.T, axis=1)
        target = s[:, None] * vertices[top]
        on = np.any(facets != 0, axis=1)
        normal = np.column_stack([facets[:, 1], -facets[:, 0]])        # back to n_j
        first = np.argmax(normal @ polygon_normals(fr.facets).T, axis=1)
        start = s[:, None] * vertices[first]
        edge = s[:, None] * (vertices[(first + 1) % fr.facets] - vertices[first])
        length2 = np.maximum(np.einsum("nd,nd->n", edge, edge), 1e-300)
        t = np.clip(np.einsum("nd,nd->n", lam - start, edge) / length2, 0.0, 1.0)
        target = np.where(on[:, None], start + t[:, None] * edge, target)
    else:
        target = s[:, None] * blocks / np.where(size > 0, size, 1.0)[:, None]
    move = (s > 0) & ~stick & (size > 0) & (fr.inner(lam_t, slip) > 0)
    out = lam.copy()
    out[move] = target[move]
    return out.ravel()


def held_rows(qp: ContactQP, active: np.ndarray, stick: np.ndarray,
              facets: np.ndarray) -> sp.csr_matrix:
    """The rows ``R`` with ``C = R G``, ``G = [B; T]`` (:func:`stick_point`): the
    ``active`` rows of ``B``, the ``k`` tangential rows of each ``stick`` node, and the
    slip along the facet at each facet node (:func:`facet_slips`, a row
    ``e_i' T_i``)."""
    fr = qp.friction
    k, width = fr.components, qp.m + fr.T.shape[0]
    nodes = np.flatnonzero(stick)
    single = np.concatenate([np.flatnonzero(active),
                             qp.m + (nodes[:, None] * k + np.arange(k)).ravel()])
    on = np.flatnonzero(np.any(facets != 0, axis=1))
    rows = np.concatenate([np.arange(single.size),
                           single.size + np.repeat(np.arange(on.size), k)])
    cols = np.concatenate([single, qp.m + (on[:, None] * k + np.arange(k)).ravel()])
    data = np.concatenate([np.ones(single.size), facets[on].ravel()])
    return sp.csr_matrix((data, (rows, cols)), shape=(single.size + on.size, width))


def times_transpose(W: np.ndarray, R: sp.csr_matrix) -> np.ndarray:
    """``W @ R.T`` for a dense ``W`` (``n x M``) and a sparse ``R`` (``r x M``), computed as
    ``(R @ W.T).T`` computes it, reading only the columns of ``W`` that ``R`` holds.

    The same products summed in the same order (bit for bit), column-major as that result
    is, without its copy of the whole ``W.T`` into row-major order (SciPy's sparse times
    dense makes one at every call: ``W = A^-1 G'`` of
    :func:`solvers.kernels.tresca.dual_operators` holds up to
    :data:`solvers.kernels.tresca.TRESCA_EXACT_MAX_ENTRIES` entries).
    """
    cols, local = np.unique(R.indices, return_inverse=True)
    R_local = sp.csr_matrix((R.data, local.reshape(-1), R.indptr), shape=(R.shape[0], cols.size))
    return (R_local @ np.ascontiguousarray(W.T[cols])).T


def stick_point(qp: ContactQP, u: np.ndarray, active: np.ndarray, stick: np.ndarray,
                facets: np.ndarray, solve_A: Callable[..., np.ndarray]) -> np.ndarray | None:
    """The feasible point ``u_f`` with zero slip on the ``stick`` nodes (and zero slip
    along the facet on the ``facets`` nodes, :func:`facet_slips`) and tight on the
    normal rows ``active``, for :func:`duality_gap`; None where it is not found.

    With ``C = R G`` the stacked rows (:func:`held_rows`) and ``c`` their values
    (``R [g; previous - offset]``), the ``A``-orthogonal projection of ``u`` onto
    ``{v : C v = c}``::

        u_f = u - A^{-1} C' y,   (C A^{-1} C') y = C u - c

    the smallest correction in the energy norm: ``||u - u_f||_A <= ||u - v||_A`` for every
    ``v`` of that set, the exact solution among them when the held rows hold for it.
    ``A^{-1} C' = (A^{-1} G') R'`` and ``C A^{-1} C' = R S R'`` come from the cached
    dual operators (``qp.cache.dual_operators``, :func:`solvers.kernels.tresca.dual_operators`)
    where present; else ``A^{-1} C'`` is formed with ``solve_A`` on the matrix ``C'``
    when ``solve_A`` is direct (``solve_A.direct``, :func:`linear_solver`), at most
    :data:`STICK_MAX_ROWS` rows and :data:`STICK_MAX_ENTRIES` entries (one solve with
    the factor for all columns; a CG route would need a solve per row); beyond, no
    point. ``C A^{-1} C'`` may be singular (dependent rows): Cholesky, else least
    squares. ``u_f`` is then made feasible (:func:`feasible_point`, tight on ``active``;
    it moves nothing beyond round-off when ``B u_f <= g`` already holds); None if that
    fails.
    """
    fr = qp.friction
    R = held_rows(qp, active, stick, facets)
    if R.shape[0] == 0:
        return None
    ops = qp.cache.dual_operators.get(True)
    if ops is not None and ops.G.shape == (R.shape[1], qp.n):
        W = times_transpose(ops.W, R)
        S = R @ (R @ ops.S).T
    elif (getattr(solve_A, "direct", False) and R.shape[0] <= STICK_MAX_ROWS
          and R.shape[0] * qp.n <= STICK_MAX_ENTRIES):
        C = (R @ sp.vstack([qp.B, fr.T]).tocsr()).tocsr()
        W = solve_A(C.T.toarray())
        S = C @ W
    else:
        return None
    S = 0.5 * (S + S.T)
    res = R @ np.concatenate([qp.B @ u - qp.g, fr.slip(u)])
    try:
        y = sla.cho_solve(sla.cho_factor(S), res)
    except (sla.LinAlgError, ValueError):
        y = sla.lstsq(S, res)[0]
    u_f, ok = feasible_point(qp, u - W @ y, tight=active)
    return u_f if ok else None


#: Largest number of unknowns for which :func:`linear_solver` factorises A (per dimension);
#: beyond, multigrid-preconditioned CG.
DIRECT_LINEAR_LIMIT = {2: 2_500_000, 3: 150_000}


def linear_solver(qp: ContactQP) -> Callable[..., np.ndarray]:
    """``(r, guess=None, rtol=1e-14) -> A^{-1} r`` for the verification's duality gap,
    built once per problem (``qp.cache.linear_solver``).

    The route depends on the problem alone, never on which solver ran before: a sparse
    Cholesky of ``A`` (:func:`solvers.kernels.cholesky.factorize`) up to
    :data:`DIRECT_LINEAR_LIMIT`, and for a problem with floating bodies at any size
    (with their near-kernel removed, :class:`solvers.kernels.cholesky.FloatingCholesky`, the
    factor shared with the exact solver: a multigrid PCG on such a nearly singular
    ``A`` needs thousands of steps); else CG
    preconditioned by one V-cycle (geometric multigrid on the problem's hierarchy, pyamg
    SA without one) to a residual of ``rtol ||r||`` (1e-14 for the duality gap; a
    measurement may ask for less, :func:`workflows.measure.dual_norm`), started from
    ``guess`` (the direct route ignores both): a guess close to the solution saves steps,
    never accuracy. The direct route takes the columns of a matrix ``r`` as well and says
    so (``solve_A.direct`` True; :func:`stick_point`).
    """
    if qp.cache.linear_solver is not None:
        return qp.cache.linear_solver
    import scipy.sparse.linalg as spla

    modes = floating_modes(qp)
    if qp.n <= DIRECT_LINEAR_LIMIT.get(qp.dim, 0) or modes.shape[1]:
        from solvers.kernels.cholesky import factorize, shared_floating_factor
        # a body held only by weak springs: its rigid part solved apart (no 1/spring-sized
        # intermediate results; see FloatingCholesky)
        if modes.shape[1]:
            chol = shared_floating_factor(qp, modes)
        else:
            # the dual operators' factor where they are cached (the same factorize(qp.A):
            # the same factor, bit for bit), else a factorisation of its own
            kept = next(iter(qp.cache.dual_operators.values()), None)
            chol = kept.factor if kept is not None else factorize(qp.A)

        def solve_A(r, guess=None, rtol=1e-14):
            x = chol.solve(r)
            return x + chol.solve(r - qp.A @ x)        # one step of iterative refinement
        solve_A.direct = True
    else:
        from solvers.kernels.multigrid import ahat_component, component_vcycle
        vc = component_vcycle(qp, ahat_component())
        M = spla.LinearOperator(qp.A.shape, matvec=vc.raw)

        def solve_A(r, guess=None, rtol=1e-14):
            x, info = spla.cg(qp.A, r, x0=guess, M=M, rtol=rtol, atol=0.0, maxiter=3000)
            if info != 0:
                raise RuntimeError("multigrid PCG for the duality gap did not converge")
            return x
    qp.cache.linear_solver = solve_A
    return solve_A


def certify(qp: ContactQP, u: np.ndarray, p: np.ndarray, tol: float | None = None,
            lam: np.ndarray | None = None) -> DualityGap:
    """The certified bound of ``(u, p)`` (one to three linear solves with A; with
    ``tol``, as few as meet it); of ``(u, p, lam)`` for a Tresca step (``lam`` its
    tangential multipliers, :func:`duality_gap`).

    The last certificate is kept in ``qp.cache.certificate`` with the digest of
    ``(u, p, tol)`` (and of ``lam`` and the step's friction data, its facets included:
    the steps of a load path share the cache, and so may a law's faceted variant):
    a solver that certifies its own stop and :func:`verify` after it pay for one.
    """
    u, p = np.ascontiguousarray(u, dtype=float), np.ascontiguousarray(p, dtype=float)
    data = u.tobytes() + p.tobytes() + repr(tol).encode()
    if lam is not None and qp.friction is not None:
        fr = qp.friction
        data += b"".join(np.ascontiguousarray(v, dtype=float).tobytes() for v in
                         (lam, fr.slip_bound, fr.offset, fr.previous, qp.f, qp.g))
        if fr.facets:                          # the law's shape (a faceted step shares A)
            data += repr(fr.facets).encode()
    key = hashlib.blake2b(data, digest_size=16).digest()
    last = qp.cache.certificate
    if last is not None and last[0] == key:
        return last[1]
    gap = duality_gap(qp, u, p, linear_solver(qp), target=tol, lam=lam)
    qp.cache.certificate = (key, gap)
    return gap


def verify(qp: ContactQP, result: SolveResult, tol: float) -> SolveResult:
    """Fill in ``kkt``, ``gap``, the verified ``status`` and ``failed_check``.

    An answer that breaks the solver contract (:func:`solvers.base.contract_violation`:
    its type, status vocabulary, the shapes and finiteness of ``u`` and ``p``, on a
    frictional problem of ``tangential``, ...)
    becomes a ``failed`` row without residuals, ``failed_check = "contract:<rule>"``.
    On a frictional problem (``qp.friction``: one Tresca step) the residuals are the six
    of :func:`problems.friction.residuals.friction_residuals` with ``result.tangential`` and the bound
    is that of the Tresca step (:func:`duality_gap` with ``lam``); an answer that solved
    a Coulomb step itself is judged on the Tresca step of its own bound
    (:func:`judged_step`).
    Otherwise qpbenchmark's rule, strengthened: ``converged`` only if the solver claims
    it, every scaled KKT residual is <= ``tol`` and the certified bound on the relative
    energy error (from the duality gap, :func:`duality_gap`) is <= ``tol`` (or at the
    bound's floating-point floor, ~1e-8: below it the KKT residuals decide); a claimed
    convergence that fails becomes ``inaccurate`` with the failing checks in
    ``failed_check``. Any other claim is kept as it is (``failed_check = "claimed"``):
    the suite never upgrades a solver's own ``inaccurate``, ``max_iter``, ... A scaled
    residual alone can pass a wrong answer when A is ill-conditioned; the certified bound
    cannot.
    """
    broken = contract_violation(result, qp.n, qp.m, tangential_rows(qp))
    if broken is not None:
        return broken_contract(qp, result, tol, *broken)
    if result.claimed_status == "skipped":          # nothing was computed: nothing to check
        result.status, result.failed_check = "skipped", ""
        return result
    lam = None
    if qp.friction is None:
        result.kkt = kkt_residuals(qp, result.u, result.p)
    else:
        lam = np.asarray(result.tangential, dtype=float)
        qp = judged_step(qp, result)
        result.kkt = friction_residuals(qp, result.u, result.p, lam)
    from solvers.kernels.cholesky import FactorizationError
    try:
        result.gap = certify(qp, result.u, result.p, tol, lam=lam)
    except FactorizationError as err:          # A not positive definite: no certificate
        inf = float("inf")
        result.gap = DualityGap(inf, inf, inf, inf, inf, inf, inf, False)
        result.message = (result.message + "; " if result.message else "") + (
            f"no certificate: {err}")
    if result.claimed_status == "converged":
        failing = failed_checks(result.kkt, result.gap, tol)
        result.status = "inaccurate" if failing else "converged"
        result.failed_check = ",".join(failing)
    else:
        result.status, result.failed_check = result.claimed_status, "claimed"
    return result


def judged_step(qp: ContactQP, result: SolveResult) -> ContactQP:
    """The Tresca step a frictional answer is judged on: ``qp`` itself, or, for an answer
    that solved the Coulomb step itself (``stats["friction"]`` is
    :data:`solvers.base.COULOMB_MONOLITHIC`), the Tresca step of its own bound
    ``s = mu p_+`` (the condition of Coulomb friction; its certificate bounds the error
    against the Tresca step of that bound, as for the last step of the fixed point)."""
    fr = qp.friction
    if fr.law != "coulomb" or result.stats.get("friction") != COULOMB_MONOLITHIC:
        return qp
    own = fr.mu * np.maximum(np.asarray(result.p, dtype=float), 0.0)
    return replace(qp, friction=replace(fr, slip_bound=own))


def failed_checks(kkt: KKTResiduals, gap: DualityGap, tol: float) -> list[str]:
    """The verification's checks that ``(kkt, gap)`` fail at ``tol``, in order: the four
    scaled KKT residuals (``kkt_<name>`` above ``tol``; a Tresca step's six, with
    ``kkt_bound`` and ``kkt_slip_complementarity``), then ``energy_bound`` (the
    certified relative bound above ``tol`` and its floor) or ``no_certificate`` (no
    feasible point, or A not positive definite)."""
    out = [f"kkt_{name}" for name, value in kkt.as_dict(prefix="").items() if not value <= tol]
    if not gap.certified:
        out.append("no_certificate")
    elif not gap.meets(tol):
        out.append("energy_bound")
    return out


def broken_contract(qp: ContactQP, result, tol: float, rule: str, what: str) -> SolveResult:
    """The ``failed`` row of an answer that broke the contract's ``rule``
    (:data:`solvers.base.CONTRACT`): no answer to use, the message naming the rule."""
    keep = isinstance(result, SolveResult)
    if (keep and rule in ("u_finite", "p_finite", "tangential_finite")
            and result.claimed_status != "converged"):
        text, check = f"no answer: {what}", "no_answer"
    else:
        text, check = f"the solver broke the contract: {CONTRACT[rule]} ({what})", \
            f"contract:{rule}"
    own = result.message if keep and isinstance(result.message, str) else ""
    claimed = (result.claimed_status if keep and isinstance(result.claimed_status, str)
               else "failed")
    row = SolveResult.without_answer(qp.n, qp.m, result.solver if keep else "", tol, "failed",
                                     f"{own}; {text}" if own else text,
                                     failed_check=check, claimed_status=claimed)
    if keep:
        row.options, row.traceback = result.options, result.traceback
        # what of the rest keeps the contract is kept (the later rules are unchecked yet)
        if isinstance(result.history, dict) and isinstance(result.stats, dict):
            row.history, row.stats = result.history, result.stats
        its = result.iterations
        if isinstance(its, (int, np.integer)) and not isinstance(its, bool) and its >= 0:
            row.iterations = int(its)
        for name in ("setup_time", "solve_time"):
            t = getattr(result, name)
            if (isinstance(t, (int, float)) and not isinstance(t, bool) and np.isfinite(t)
                    and t >= 0):
                setattr(row, name, float(t))
    return row
