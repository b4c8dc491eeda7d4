"""Friction: the exact reference of a Tresca step, the load path and Coulomb's fixed point.

One Tresca step (:class:`problems.friction.data.Friction`)::

    minimise 1/2 u'Au - f'u + sum_i s_i |T_i u - r_i|   subject to   B u <= g,

``r = previous - offset`` (the slip is measured from the previous state; in 3D ``T_i``
has two rows and ``|.|`` is the Euclidean norm). Its dual is a problem in
``y = (p, lam)``::

    minimise 1/2 y'Sy - y'(G A^-1 f - h)   subject to   p >= 0,  |lam_i| <= s_i,

``G = [B; T]``, ``S = G A^-1 G'``, ``h = (g, r)``, and ``u = A^-1 (f - G'y)``.
:func:`tresca_exact` factorises ``A`` once and forms ``S`` densely (``(1 + k) m``
columns for ``k`` tangential rows per node: the reference is for small surfaces).

* 2D: ``|lam_i| <= s_i`` is a box. Splitting the slip into two nonnegative parts,
  ``T_i u - r_i = a_i - b_i`` with ``a, b >= 0``, makes the step a QP whose dual is this
  box problem (the slip parts are the multipliers of the two bounds on ``lam``); a primal
  active-set method (:func:`box_qp_active_set`) ends after finitely many steps on the
  exact active sets.
* 3D: ``|lam_i| <= s_i`` is a disc. A semismooth Newton method on the projection
  equation ``y = P_K(y - rho (S y - c))`` (:func:`disc_qp_newton`), globalised by the dual
  objective, is driven to round-off on fixed sets.
* 3D, the faceted law (:class:`problems.friction.data.Friction`, ``facets = k``): ``lam_i`` in the
  regular ``k``-gon ``s_i P_k``. The same semismooth Newton method with the projection
  onto the ``k``-gons (:func:`problems.friction.polygon.polygon_regions`: piecewise affine, identity
  inside, onto a facet's line, onto a vertex), so on the right sets its Newton step is
  exact and the method ends after finitely many steps; one solver for both laws, on the
  same dense ``S``. (A QP solved exactly by an active-set method on the dual would need
  the equality ``sum_j a_ij = s_i`` of :func:`problems.friction.forms.facet_program`'s
  multipliers, no box.)

The answer is then exact to round-off, and :func:`problems.friction.residuals.friction_residuals`
verifies it.

:func:`friction_path` runs a scene's load path (normal load, then the tangential step,
each step's slip measured from the previous step's state); for Coulomb friction each step
is the fixed point ``s = mu p`` over Tresca steps (its iterations and contraction are
reported); for Tresca friction the slip bound is ``mu p`` of the frictionless normal step.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from problems.friction.polygon import REGION_INSIDE, polygon_regions, region_projection
from problems.friction.residuals import FrictionResiduals, friction_residuals, tresca_energy
from problems.kkt import energy_error, kkt_residuals
from problems.qp import ContactQP, prolongate_displacement
from problems.spec import ParameterError
from solvers.base import SolveResult
from solvers.kernels.cholesky import factorize

#: Largest constrained surface (rows) :func:`tresca_exact` takes: ``S`` is dense,
#: ``(1 + k) m`` square for ``k`` tangential rows per node.
TRESCA_EXACT_MAX_M = 2000

#: Largest ``A^-1 G'`` (entries, ``n`` times the dual unknowns) :func:`dual_operators`
#: forms densely: 3.2 GB, and as much again for ``G'`` while it is solved for (cube_sphere
#: level 2 with friction: 4.8e7 entries; level 3: 1.4e9, beyond it).
TRESCA_EXACT_MAX_ENTRIES = 4 * 10**8


def dense_dual_size(qp: ContactQP) -> int:
    """Entries of the dense ``A^-1 G'`` of ``qp`` (:func:`dual_operators`)."""
    fr = qp.friction
    return qp.n * (qp.m + (0 if fr is None else fr.T.shape[0]))


@dataclass
class TrescaSolution:
    """The answer of one Tresca step.

    Attributes
    ----------
    u : (n,) array
    p : (m,) array
        Normal multipliers (forces).
    lam : (m,) array
        Tangential multipliers (forces), ``|lam_i| <= s_i``.
    stick : (m,) bool array
        Rows in contact (``s_i > 0``) whose tangential multiplier is strictly inside its
        bound (the dual active set): they do not slip.
    status : str
        ``converged`` (the active-set method ended on its optimality test) or ``max_iter``.
    iterations : int
    kkt : FrictionResiduals
        (:class:`problems.kkt.KKTResiduals` on a frictionless problem)
    active : (2m,) int array
        2D: the dual active set of ``(p, lam)``: ``-1`` at the lower bound, ``+1`` at the
        upper, ``0`` free (a warm start for a neighbouring problem). 3D: ``(2m,)``, ``-1``
        where ``p_i = 0`` is held and ``0`` where ``p_i`` is free, then the node's disc
        (:data:`DISC_ZERO`, :data:`DISC_INSIDE`, :data:`DISC_EDGE`).
    dual : array
        The dual point ``y = (p, lam)`` (3D: a warm start for a neighbouring problem).
    """

    u: np.ndarray
    p: np.ndarray
    lam: np.ndarray
    stick: np.ndarray
    status: str
    iterations: int
    kkt: FrictionResiduals
    active: np.ndarray | None = None
    dual: np.ndarray | None = None


def dual_box(m: int, bound: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The bounds ``(lo, hi)`` of a 2D Tresca step's dual ``y = (p, lam)``: ``p >= 0``
    on the ``m`` normal rows, ``|lam_i| <= s_i`` on the tangential ones."""
    return (np.concatenate([np.zeros(m), -bound]),
            np.concatenate([np.full(m, np.inf), bound]))


def box_qp_active_set(S: np.ndarray, c: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                      max_iter: int | None = None,
                      start: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, int, bool]:
    """``min 1/2 y'Sy - c'y`` s.t. ``lo <= y <= hi`` (``S`` symmetric positive definite), by
    the primal active-set method (Nocedal-Wright, Alg. 16.3): exact on its final active set.

    ``start``: a guess of the active set (``at_bound`` of a neighbouring problem); the
    method starts from the minimiser on that face, projected onto the box (feasible), with
    the bounds it meets as its active set.

    Returns
    -------
    y : array
    at_bound : (k,) int array
        ``-1`` at the lower bound, ``+1`` at the upper, ``0`` free.
    iterations : int
    converged : bool
        The optimality test held (every bound's multiplier has the right sign).
    """
    k = len(c)
    max_iter = 10 * k + 50 if max_iter is None else max_iter
    y = np.clip(np.zeros(k), lo, hi)
    if start is not None and np.shape(start) == (k,):
        guess = np.where(start < 0, lo, np.where(start > 0, hi, 0.0))
        guess = np.where(np.isfinite(guess), guess, 0.0)
        face = (start == 0) | ~np.isfinite(np.where(start < 0, lo, hi))
        if face.any():
            guess[face] = np.linalg.solve(S[np.ix_(face, face)],
                                          c[face] - S[np.ix_(face, ~face)] @ guess[~face])
        y = np.clip(guess, lo, hi)
    at = np.where(lo == hi, -1, np.where(y <= lo, -1, np.where(y >= hi, 1, 0)))
    for it in range(1, max_iter + 1):
        free = at == 0
        target = y.copy()
        if free.any():
            rhs = c[free] - S[np.ix_(free, ~free)] @ y[~free]
            target[free] = np.linalg.solve(S[np.ix_(free, free)], rhs)
        d = target - y
        with np.errstate(divide="ignore", invalid="ignore"):
            room = np.where(d < 0, (lo - y) / d, np.where(d > 0, (hi - y) / d, np.inf))
        room[~free] = np.inf
        blocking = int(np.argmin(room)) if k else 0
        if k and room[blocking] < 1.0:
            y = y + max(room[blocking], 0.0) * d
            y[blocking] = lo[blocking] if d[blocking] < 0 else hi[blocking]
            at[blocking] = -1 if d[blocking] < 0 else 1
            continue
        y = target
        grad = S @ y - c
        wrong = np.where(at == -1, -grad, np.where(at == 1, grad, 0.0))
        wrong[lo == hi] = 0.0
        worst = int(np.argmax(wrong)) if k else 0
        if not k or wrong[worst] <= 1e-14 * max(float(np.max(np.abs(c))), 1e-300):
            return y, at, it, True
        at[worst] = 0
    return y, at, max_iter, False


def project_dual(z: np.ndarray, m: int, bound: np.ndarray, facets: int = 0) -> np.ndarray:
    """``P_K(z)`` onto ``K = {p >= 0, |lam_i| <= s_i}`` of a 3D Tresca step's dual,
    ``z = (p, lam)`` with ``lam`` node-major in blocks of ``k``: ``p`` clipped at zero,
    each ``lam_i`` moved radially onto its disc (onto ``0`` where ``s_i = 0``); with
    ``facets = k``, onto its ``k``-gon ``s_i P_k`` (:func:`problems.friction.polygon.polygon_regions`)."""
    lam = z[m:].reshape(len(bound), -1)
    if facets:
        return np.concatenate([np.maximum(z[:m], 0.0),
                               polygon_regions(lam, bound, facets)[0].ravel()])
    norm = np.sqrt(np.sum(lam * lam, axis=1))
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(norm > bound, bound / norm, 1.0)
    return np.concatenate([np.maximum(z[:m], 0.0), (lam * scale[:, None]).ravel()])


#: Dual sets of :func:`disc_qp_newton` per constrained node: the disc of ``lam_i`` is
#: ``DISC_ZERO`` (``s_i = 0``: ``lam_i = 0``), ``DISC_INSIDE`` (free: ``lam_i`` strictly
#: inside, the node sticks) or ``DISC_EDGE`` (on the circle ``|lam_i| = s_i``: it slips).
DISC_ZERO, DISC_INSIDE, DISC_EDGE = 0, 1, 2

#: Round-off level of the projection residual ``y - P_K(y - rho (S y - c))`` relative
#: to the size of ``y``: below it :func:`disc_qp_newton` has nothing left to gain.
DISC_ROUNDOFF = 1e3 * np.finfo(float).eps


def _dual_sets(z: np.ndarray, m: int, bound: np.ndarray, before: tuple | None,
               eps: float, facets: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The sets of ``z = y - rho (S y - c)``: ``p_i`` free where ``z_i > 0`` and each
    node's disc (:data:`DISC_EDGE` where ``|z_lam,i| > s_i``). Round-off hysteresis: a
    component within ``eps`` of its boundary keeps its set of ``before``.

    ``facets = k``: each node's region of its ``k``-gon (:func:`problems.friction.polygon.polygon_regions`;
    :data:`DISC_INSIDE` is its inside, the codes from :data:`DISC_EDGE` on its facets and
    vertices); a node keeps its region of ``before`` where that region's affine projection
    (:func:`problems.friction.polygon.region_projection`) is within ``eps`` of the projection."""
    free = z[:m] > 0
    if facets:
        lam = z[m:].reshape(len(bound), 2)
        projection, code = polygon_regions(lam, bound, facets)
        disc = np.where(bound <= 0, DISC_ZERO, code)
        if before is not None:
            free = np.where(np.abs(z[:m]) <= eps, before[0], free)
            kept = np.where(before[1] == DISC_ZERO, REGION_INSIDE, before[1])
            near = np.max(np.abs(region_projection(lam, bound, facets, kept)[0] - projection),
                          axis=1) <= eps
            disc = np.where((bound > 0) & (before[1] != DISC_ZERO) & near, before[1], disc)
        return free, disc
    norm = np.sqrt(np.sum(z[m:].reshape(len(bound), -1) ** 2, axis=1))
    disc = np.where(bound <= 0, DISC_ZERO, np.where(norm > bound, DISC_EDGE, DISC_INSIDE))
    if before is not None:
        free = np.where(np.abs(z[:m]) <= eps, before[0], free)
        near = (bound > 0) & (np.abs(norm - bound) <= eps) & (before[1] != DISC_ZERO)
        disc = np.where(near, before[1], disc)
    return free, disc


def _projection_jacobian(z: np.ndarray, m: int, bound: np.ndarray, sets: tuple,
                         facets: int = 0) -> sp.csr_matrix:
    """An element ``D`` of the generalised Jacobian of :func:`project_dual` at ``z`` on
    the given sets: ``1``/``0`` on ``p``; per node ``I`` inside the disc, ``0`` with
    ``s_i = 0`` and ``(s_i / |z_i|) (I - n n')``, ``n = z_i / |z_i|``, on its edge.
    ``facets = k``: per node the Jacobian of its region's affine projection onto the
    ``k``-gon (:func:`problems.friction.polygon.region_projection`; ``0`` with ``s_i = 0``)."""
    free, disc = sets
    lam = z[m:].reshape(len(bound), -1)
    if facets:
        code = np.where(disc == DISC_ZERO, REGION_INSIDE, disc)
        blocks = region_projection(lam, bound, facets, code)[1]
        blocks = np.where((disc == DISC_ZERO)[:, None, None], 0.0, blocks)
        return _block_diagonal(free * 1.0, blocks)
    k = lam.shape[1]
    norm = np.sqrt(np.sum(lam * lam, axis=1))
    edge = disc == DISC_EDGE
    n = np.zeros_like(lam)
    n[edge] = lam[edge] / norm[edge, None]
    alpha = np.where(edge, bound / np.where(edge, norm, 1.0), (disc == DISC_INSIDE) * 1.0)
    blocks = alpha[:, None, None] * (np.eye(k)[None] - n[:, :, None] * n[:, None, :])
    return _block_diagonal(free * 1.0, blocks)


def _block_diagonal(diagonal: np.ndarray, blocks: np.ndarray) -> sp.csr_matrix:
    """``sp.block_diag([sp.diags(diagonal), sp.block_diag(list(blocks))], format="csr")``
    with its arrays built at once rather than block by block (the same matrix, the same
    arrays: the diagonal's zeros left out, every entry of the dense ``(r, k, k)`` blocks
    kept, zeros too, row by row)."""
    m = diagonal.size
    r, k = blocks.shape[0], blocks.shape[1]
    if m == 0 or r == 0 or blocks.shape != (r, k, k):
        return sp.block_diag([sp.diags(diagonal), sp.block_diag(list(blocks))], format="csr")
    size = m + r * k
    kept = np.flatnonzero(diagonal != 0)
    counts = np.concatenate([(diagonal != 0).astype(np.int64), np.full(r * k, k, np.int64)])
    indptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32)
    block_cols = (m + (np.arange(r * k) // k) * k)[:, None] + np.arange(k)[None]
    indices = np.concatenate([kept, block_cols.ravel()]).astype(np.int32)
    data = np.concatenate([diagonal[kept], blocks.reshape(-1)])
    return sp.csr_matrix((data, indices, indptr), shape=(size, size))


def disc_qp_newton(S: np.ndarray, c: np.ndarray, m: int, bound: np.ndarray,
                   max_iter: int | None = None,
                   start: np.ndarray | None = None,
                   facets: int = 0) -> tuple[np.ndarray, tuple, int, bool]:
    """``min 1/2 y'Sy - c'y`` s.t. ``y = (p, lam)``, ``p >= 0``, ``|lam_i| <= s_i``
    (``lam`` node-major in blocks of ``k``, ``S`` symmetric positive definite): the dual
    of a 3D Tresca step, by a semismooth Newton method on the projection equation

        F(y) = y - P_K(y - rho (S y - c)) = 0,   rho = 1 / ||S||_inf

    (:func:`project_dual`). Its Newton matrix ``I - D + rho D S`` (``D``:
    :func:`_projection_jacobian`, block diagonal) is exact; the components with
    ``D = 0`` are eliminated (they are set to their projection) and the rest is one
    dense LU. Globalised on the dual objective ``theta``: the Newton point projected
    onto ``K``, halved towards ``y`` until ``theta`` does not rise (round-off allowed),
    and kept where it is no worse than the projected gradient step
    ``P_K(y - rho (S y - c))`` (taken otherwise), which lowers ``theta`` since
    ``rho <= 1 / lambda_max(S)``: ``theta`` never rises by more than round-off. It ends when the sets of
    ``y - rho (S y - c)`` (:func:`_dual_sets`, with round-off hysteresis) are those of
    the previous step and ``||F||_inf`` is at :data:`DISC_ROUNDOFF` of ``||y||_inf``.

    ``start``: a dual point of a neighbouring problem (projected onto ``K``).
    ``facets = k``: ``|lam_i| <= s_i`` replaced by ``lam_i in s_i P_k`` (the faceted
    law): the projection and its Jacobian onto the ``k``-gons, piecewise affine, so the
    Newton step on the right sets is exact.

    Returns
    -------
    y : array
    sets : (free, disc)
        ``free``: ``(m,)`` bool, ``p_i`` off its bound; ``disc``: ``(m,)`` int, the
        node's :data:`DISC_ZERO`, :data:`DISC_INSIDE` or :data:`DISC_EDGE` (faceted: the
        region codes of :func:`problems.friction.polygon.polygon_regions` from :data:`DISC_EDGE` on).
    iterations : int
    converged : bool
    """
    size = len(c)
    max_iter = 10 * len(bound) + 50 if max_iter is None else max_iter
    rho = 1.0 / max(float(np.max(np.sum(np.abs(S), axis=1), initial=0.0)), 1e-300)
    theta = lambda y: 0.5 * float(y @ (S @ y)) - float(c @ y)
    y = project_dual(np.zeros(size) if start is None or np.shape(start) != (size,)
                     else np.asarray(start, float), m, bound, facets)
    sets = before = None
    for it in range(1, max_iter + 1):
        y_old = y
        z = y - rho * (S @ y - c)
        gradient_step = project_dual(z, m, bound, facets)
        F = y - gradient_step
        scale = max(float(np.max(np.abs(y), initial=0.0)),
                    float(np.max(np.abs(gradient_step), initial=0.0)), 1e-300)
        sets = _dual_sets(z, m, bound, before, DISC_ROUNDOFF * scale, facets)
        if (before is not None and all(np.array_equal(a, b) for a, b in zip(sets, before))
                and float(np.max(np.abs(F), initial=0.0)) <= DISC_ROUNDOFF * scale):
            return y, sets, it, True
        before = sets
        D = _projection_jacobian(z, m, bound, sets, facets)
        fixed = np.asarray(abs(D).sum(axis=1)).ravel() == 0      # D = 0: y_j -> P_K(z)_j
        d = np.where(fixed, -F, 0.0)
        rest = np.flatnonzero(~fixed)
        if rest.size:
            D_rr = D[rest][:, rest]
            J = rho * (D_rr @ S[np.ix_(rest, rest)]) - D_rr.toarray()
            J[np.diag_indices_from(J)] += 1.0
            b = -F[rest] - rho * (D_rr @ (S[np.ix_(rest, np.flatnonzero(fixed))]
                                          @ d[fixed]))
            try:
                d[rest] = sla.lu_solve(sla.lu_factor(J, check_finite=True), b)
            except (sla.LinAlgError, ValueError):      # no Newton point: the gradient step
                y = gradient_step
                continue
        value = theta(y)
        slack = 10 * np.finfo(float).eps * (abs(value) + 1e-300)
        y = gradient_step
        for halvings in range(30):
            trial = project_dual(y_old + 0.5 ** halvings * d, m, bound, facets)
            if theta(trial) <= value + slack:
                if theta(trial) <= theta(gradient_step) + slack:
                    y = trial
                break
    return y, sets, max_iter, False


@dataclass
class DualOperators:
    """What every step of one ContactQP's load path shares: ``A`` factorised,
    ``G = [B; T]``, ``W = A^-1 G'`` and ``S = G W`` (module docstring)."""

    factor: object
    G: sp.csr_matrix
    W: np.ndarray
    S: np.ndarray


def dual_operators(qp: ContactQP) -> DualOperators:
    """:class:`DualOperators` of ``qp``: frictional (nodal rows; ``G = [B; T]``) or
    frictionless (``G = B``, the same dual box problem without ``lam``: the exact QP
    route). Computed once per problem and kept in ``qp.cache.dual_operators`` (the steps
    of a load path share ``A``, ``B`` and ``T``).

    Raises
    ------
    ValueError
        With a stabilisation block ``C``, with friction on reverse rows, beyond
        :data:`TRESCA_EXACT_MAX_M` rows or :data:`TRESCA_EXACT_MAX_ENTRIES`.
    """
    fr = qp.friction
    if qp.C is not None or (fr is not None and qp.stabilisation is not None):
        raise ValueError("tresca_exact takes a ContactQP without a stabilisation block, and "
                         "friction on nodal rows only")
    if qp.m > TRESCA_EXACT_MAX_M:
        raise ValueError(f"tresca_exact: {qp.m} rows is not allowed; allowed: at most "
                         f"{TRESCA_EXACT_MAX_M} (S is dense)")
    if dense_dual_size(qp) > TRESCA_EXACT_MAX_ENTRIES:
        raise ValueError(f"tresca_exact: A^-1 G' of {dense_dual_size(qp):.2e} entries is not "
                         f"allowed; allowed: at most {TRESCA_EXACT_MAX_ENTRIES:.0e} (it is "
                         f"dense)")
    kept = qp.cache.dual_operators.get(fr is not None)
    if kept is not None:
        return kept
    G = (qp.B if fr is None else sp.vstack([qp.B, fr.T])).tocsr()
    factor = factorize(qp.A)
    W = factor.solve(G.T.toarray()) if G.shape[0] else np.zeros((qp.n, 0))   # A^-1 G'
    S = G @ W
    ops = DualOperators(factor, G, W, 0.5 * (S + S.T))
    qp.cache.dual_operators[fr is not None] = ops
    return ops


def tresca_exact(qp: ContactQP, ops: DualOperators | None = None,
                 start: np.ndarray | None = None,
                 max_iter: int | None = None,
                 dual_start: np.ndarray | None = None) -> TrescaSolution:
    """The exact solution of the Tresca step ``qp`` (module docstring; nodal rows).

    2D: the dual box problem by the primal active-set method (:func:`box_qp_active_set`).
    3D (two tangential rows per node, ``|lam_i| <= s_i`` a disc): the dual by the
    semismooth Newton method :func:`disc_qp_newton`, driven to round-off on fixed sets;
    the faceted law (``qp.friction.facets`` = k) the same with ``lam_i`` in the
    ``k``-gons ``s_i P_k``.

    ``ops``: :func:`dual_operators` of a ContactQP with the same ``A``, ``B`` and ``T``
    (the other steps of its load path), computed here if not given. ``start`` (2D): the
    dual active set of a neighbouring problem (:attr:`TrescaSolution.active`), a warm
    start; ``dual_start`` (3D): its dual point (:attr:`TrescaSolution.dual`).
    ``max_iter``: the cap on the active-set steps (default ``10 k + 50`` for ``k`` dual
    unknowns) or the Newton steps (default ``10 m + 50``). Without friction (``qp.friction`` None) the same route solves the
    frictionless QP (``y = p``; ``lam`` empty, the residuals :func:`kkt_residuals`).
    """
    fr = qp.friction
    ops = dual_operators(qp) if ops is None else ops
    G, W = ops.G, ops.W
    Ainv_f = ops.factor.solve(qp.f)
    m = qp.m
    if fr is None:
        h, lo, hi = qp.g, np.zeros(m), np.full(m, np.inf)
    else:
        h = np.concatenate([qp.g, fr.previous - fr.offset])
        lo, hi = dual_box(m, fr.slip_bound)
    if fr is not None and fr.components > 1:
        y, (free, disc), iterations, ok = disc_qp_newton(ops.S, G @ Ainv_f - h, m,
                                                         fr.slip_bound, max_iter=max_iter,
                                                         start=dual_start, facets=fr.facets)
        at = np.concatenate([np.where(free, 0, -1), disc])
        stick = disc == DISC_INSIDE
    else:
        y, at, iterations, ok = box_qp_active_set(ops.S, G @ Ainv_f - h, lo, hi,
                                                  max_iter=max_iter, start=start)
        stick = None if fr is None else (fr.slip_bound > 0) & (at[m:] == 0)
    u = Ainv_f - W @ y
    p, lam = np.maximum(y[:m], 0.0), y[m:]
    if fr is None:
        return TrescaSolution(u=u, p=p, lam=lam, stick=np.zeros(0, dtype=bool),
                              status="converged" if ok else "max_iter",
                              iterations=iterations, kkt=kkt_residuals(qp, u, p), active=at,
                              dual=y)
    return TrescaSolution(u=u, p=p, lam=lam, stick=stick,
                          status="converged" if ok else "max_iter", iterations=iterations,
                          kkt=friction_residuals(qp, u, p, lam), active=at, dual=y)


@dataclass
class PathStep:
    """One solved step of a frictional load path.

    Attributes
    ----------
    qp : ContactQP
        The step's Tresca problem (its final slip bounds).
    solution : TrescaSolution
    tresca_solves : int
        Tresca problems the step took (Coulomb: the fixed point's iterations).
    contraction : float
        Coulomb: the last ratio ``||s_k+1 - s_k|| / ||s_k - s_k-1||`` (``nan`` with fewer
        than two updates; Tresca: ``nan``).
    """

    qp: ContactQP
    solution: TrescaSolution
    tresca_solves: int = 1
    contraction: float = float("nan")
    history: list = field(default_factory=list)


def with_step(qp: ContactQP, step: int, slip_bound: np.ndarray, previous: np.ndarray) -> ContactQP:
    """The Tresca problem of ``qp``'s load-path step ``step`` with the given slip bounds,
    its slip measured from ``previous``."""
    ls = qp.friction.path[step]
    fr = replace(qp.friction, slip_bound=np.asarray(slip_bound, float), offset=ls.offset,
                 previous=np.asarray(previous, float))
    return replace(qp, f=ls.f, g=ls.g, friction=fr,
                   u_fixed=qp.u_fixed if ls.u_fixed is None else ls.u_fixed)


def coulomb_step(qp: ContactQP, step: int, previous: np.ndarray, s0: np.ndarray,
                 solve, tol: float = 1e-12, max_iter: int = 50) -> PathStep:
    """Coulomb friction in one step: the fixed point ``s = mu p`` over Tresca problems,
    from the slip bound ``s0``; stops when ``||s_k+1 - s_k||_inf <= tol ||s_k+1||_inf``."""
    mu, s = qp.friction.mu, np.asarray(s0, float)
    changes = []
    for k in range(1, max_iter + 1):
        step_qp = with_step(qp, step, s, previous)
        sol = solve(step_qp)
        s_new = mu * sol.p
        changes.append(float(np.max(np.abs(s_new - s))) if s.size else 0.0)
        if changes[-1] <= tol * max(float(np.max(np.abs(s_new))), 1e-300):
            break
        s = s_new
    contraction = changes[-1] / changes[-2] if len(changes) > 1 and changes[-2] > 0 else float("nan")
    if changes[-1] > tol * max(float(np.max(np.abs(s_new))), 1e-300):
        sol = replace(sol, status="max_iter")
    return PathStep(step_qp, sol, tresca_solves=k, contraction=contraction, history=changes)


def friction_path(qp: ContactQP, solve=None, tol: float = 1e-12, max_iter: int = 50,
                  done: tuple = (), define=None) -> list[PathStep]:
    """Run the load path of the frictional ``qp`` (``qp.friction.path``): each step's slip
    measured from the previous step's state (the first: from the unloaded state).
    ``solve(step_qp) -> TrescaSolution`` solves one Tresca step (default: :func:`tresca_exact`).
    ``done``: the first steps, already solved on the same path (kept as they are).

    Tresca: ``s = mu p`` of the frictionless normal step, the same in every step.
    Coulomb: each step the fixed point ``s = mu p`` (:func:`coulomb_step`), started from the
    previous step's bound (the first: from the frictionless normal step's).

    ``define(v) -> v``: applied to every slip bound and previous state before a step is
    solved (a test problem's machine-independent definition,
    :func:`workflows.problem_set.definition_digits`); a Coulomb step is then solved once
    more at its defined bound, its fixed point's record kept.
    """
    fr = qp.friction
    if fr is None or not fr.path:
        raise ValueError("friction_path needs a ContactQP with friction and a load path")
    if solve is None:                               # the exact reference, A factorised once
        ops = dual_operators(qp)
        solve = lambda step_qp: tresca_exact(step_qp, ops)
    keep = define or (lambda v: v)
    zero = np.zeros(qp.m)
    steps = list(done)
    if steps:
        last = steps[-1].qp.friction
        s, previous = last.slip_bound, last.T @ steps[-1].solution.u + last.offset
    else:
        rest = np.zeros(fr.T.shape[0])                 # the unloaded state
        s, previous = keep(fr.mu * solve(with_step(qp, 0, zero, rest)).p), rest
    for k in range(len(steps), len(fr.path)):
        if fr.law == "coulomb":
            done = coulomb_step(qp, k, previous, s, solve, tol, max_iter)
            s = keep(done.qp.friction.slip_bound)
            if define is not None:
                step_qp = with_step(qp, k, s, previous)
                done = replace(done, qp=step_qp, solution=solve(step_qp))
        else:
            step_qp = with_step(qp, k, s, previous)
            done = PathStep(step_qp, solve(step_qp))
        steps.append(done)
        previous = keep(done.qp.friction.T @ done.solution.u + done.qp.friction.offset)
    return steps


@dataclass
class LoadPathRun:
    """A frictional load path run with a registered solver (:func:`run_load_path`).

    Attributes
    ----------
    steps : list of PathStep
        The steps solved and verified (all of the path unless the run stopped).
    qp : ContactQP
        The Tresca problem of ``result`` (the last step's, or the one the run stopped on).
    result : SolveResult
        The verified answer that ends the run: the last Tresca solve of the last step,
        or the solve that did not verify. Its ``status`` is the run's: ``max_iter``
        (``failed_check`` ``coulomb_fixed_point``) if a step's Coulomb fixed point did not
        converge in ``max_iter`` Tresca solves. A last step in which every row with a slip
        bound slips (gross sliding: the prescribed tangential displacement has carried the
        whole contact past ``mu P``) is a static equilibrium like any other, solved and
        verified; its message says so.
    records : list of dict
        Per step run: ``step`` (from 1), ``load`` (``normal`` or ``tangential``),
        ``tresca_solves`` (the solver's runs in the step: Coulomb's fixed point
        iterations, and for the first step of Tresca friction also the frictionless
        normal solve that gives ``s = mu p``), ``contraction`` (Coulomb: the fixed
        point's last ratio of changes, :class:`PathStep`; else ``nan``), ``warm_start``
        (whether its solves started from the path's last answer) and ``status`` (the
        step's verified status; ``max_iter`` where the fixed point did not converge).
    """

    steps: list
    qp: ContactQP
    result: SolveResult
    records: list


def as_tresca_solution(step_qp: ContactQP, res: SolveResult) -> TrescaSolution:
    """A registered solver's verified answer of the Tresca step ``step_qp`` as a
    :class:`TrescaSolution` (its ``tangential`` the multipliers; a row sticks by
    :meth:`problems.friction.data.Friction.states` at the solve's tolerance)."""
    lam = np.asarray(res.tangential, dtype=float)
    return TrescaSolution(u=res.u, p=res.p, lam=lam,
                          stick=step_qp.friction.states(lam, res.tol) == "stick",
                          status=res.status, iterations=res.iterations, kkt=res.kkt)


class _Stopped(Exception):
    """A Tresca solve of the path did not verify: the path ends with its answer."""


def warm_start(start) -> dict:
    """The initial guess of a load path's next Tresca solve as keyword arguments of
    :func:`solvers.interface.solve`: ``u0`` and ``p0`` of ``start``, the path's last
    verified answer (a :class:`~solvers.base.SolveResult`) or a nested start
    (:class:`NestedStart`); ``{}`` for none: the solver starts from zero."""
    return {} if start is None else {"u0": start.u, "p0": start.p}


def run_load_path(qp: ContactQP, solve_step, tol: float, max_iter: int = 50,
                  warm: bool = True) -> LoadPathRun:
    """Run the load path of the frictional ``qp`` (:func:`friction_path`) with
    ``solve_step(step_qp, start) -> SolveResult``, one verified Tresca solve of a
    registered solver (:func:`solvers.interface.solve`), whose ``tangential`` are the
    multipliers, started from ``start`` (:func:`warm_start`).

    ``warm``: each solve starts from the path's last verified answer, as a quasi-static
    computation does (the previous load step's, or the previous Tresca solve of a
    Coulomb fixed point; the first solve from zero); ``False``: every solve starts from
    zero. The records say which (``warm_start``); a solver that takes no initial guess
    says so in its message.

    The path stops at the first solve that is not verified ``converged`` (a solver that
    cannot take friction: ``skipped`` at once). Coulomb's fixed point ``s = mu p`` runs
    around the solver to the relative change ``tol`` (at most ``max_iter`` Tresca solves
    per step). A row sticks when its multiplier lies inside its bound by more than
    ``tol max(s)`` (:meth:`problems.friction.data.Friction.states`). Gross sliding (no row of the
    last step sticks although some have a bound, ``mu > 0``: the tangential load has
    reached ``mu P`` and no static partial-slip state is left) makes the run ``failed``.
    A solver that solves a Coulomb step itself (``stats["friction"]`` is
    :data:`solvers.base.COULOMB_MONOLITHIC`; verified on its own bound ``mu p``) ends the
    fixed point at its second solve, which confirms ``s = mu p``.
    """
    fr = qp.friction
    if fr is None or not fr.path:
        raise ValueError("run_load_path needs a ContactQP with friction and a load path")
    last, solves = {}, []

    def step(step_qp):
        res = solve_step(step_qp, last.get("result") if warm else None)
        last.update(qp=step_qp, result=res)
        solves[-1] += 1
        if res.status != "converged":
            raise _Stopped
        return as_tresca_solution(step_qp, res)

    steps, n, records = [], len(fr.path), []
    for k in range(n):
        head = replace(qp, friction=replace(fr, path=fr.path[:k + 1]))
        solves.append(0)
        record = {"step": k + 1, "load": "normal" if k == 0 else "tangential",
                  "warm_start": warm}
        try:
            steps = friction_path(head, step, tol=tol, max_iter=max_iter, done=tuple(steps))
        except _Stopped:
            res = last["result"]
            if res.status != "skipped":            # a skip says why on its own
                res.message = f"load step {k + 1} of {n}: {res.message}"
            records.append({**record, "tresca_solves": solves[-1], "contraction": float("nan"),
                            "status": res.status})
            break
        records.append({**record, "tresca_solves": solves[-1],
                        "contraction": steps[-1].contraction,
                        "status": steps[-1].solution.status})
    res = last["result"]
    if len(steps) == n:
        final = steps[-1]
        states = final.qp.friction.states(final.solution.lam, res.tol)
        short = [k for k, st in enumerate(steps) if st.solution.status != "converged"]
        if short:
            res.status, res.failed_check = steps[short[0]].solution.status, "coulomb_fixed_point"
            res.message = (f"load step {short[0] + 1} of {n}: the Coulomb fixed point "
                           f"s = mu p did not converge in {steps[short[0]].tresca_solves} "
                           f"Tresca solves; {res.message}")
        elif fr.mu > 0 and (states != "free").any() and not (states == "stick").any():
            # under the prescribed displacement the fully sliding state is the (unique)
            # static equilibrium: verified as any other, reported as the state it is
            res.message = ("gross sliding: every row with a friction bound slips in the "
                           "last step (the prescribed tangential displacement carries the "
                           f"whole contact at mu P); {res.message}")
    return LoadPathRun(steps=steps, qp=last["qp"], result=res, records=records)


@dataclass
class NestedStart:
    """The initial guess of one Tresca solve of a nested load path
    (:func:`run_nested_load_path`), read as a path's last answer is
    (:func:`warm_start`)."""

    u: np.ndarray
    p: np.ndarray | None = None


def run_nested_load_path(levels: list[ContactQP], solve_step, tol: float,
                         max_iter: int = 50) -> list[LoadPathRun]:
    """Run one Tresca load path on consecutive levels of a scene, coarsest first, by
    nested iteration on every solve of the path (Alg. 8.5 applied per load step).

    The coarsest level runs as :func:`run_load_path` does, each solve started from the
    path's last answer. On a finer level, solve ``i`` of the path starts from::

        u0 = u_last + I (u_c,i) - I (u_c,i-1),

    ``u_last`` its own path's last answer (zero before the first solve), ``u_c,i`` and
    ``u_c,i-1`` the coarser level's answers to the same solve and to the one before it
    (zero before the first), ``I`` the interpolation on the finer level with the coarser
    step's prescribed values (:func:`problems.qp.prolongate_displacement`,
    ``P u + P_D u_fixed``): the coarser level's change over the solve, the change of
    its prescribed values included, is added to the finer level's own state. The slip
    of a step is measured from the finer level's own previous state, so only the start
    comes from below; what it brings is the stick zone's and the slip front's place,
    which a start from the previous step makes the solver find node by node
    (:mod:`solvers.tnnmg`, ``steps_to_face``).
    ``p0`` is the finer path's last answer's (the pressure changes little over a step).

    Parameters
    ----------
    levels : list of ContactQP
        The same scene's frictional problem at consecutive levels, coarsest first, each
        with the same load path (e.g. :func:`scaled_tangential_step` by one factor) and
        Tresca's law: Coulomb's fixed point takes a different number of solves on each
        level, so its solves do not pair up.
    solve_step : callable
        ``solve_step(step_qp, start) -> SolveResult`` as for :func:`run_load_path`;
        ``start`` is the path's last answer on the coarsest level and a
        :class:`NestedStart` above it (None for the coarsest level's first solve).
    tol, max_iter
        As for :func:`run_load_path`.

    Returns
    -------
    list of LoadPathRun
        One per level, coarsest first. A coarser run that stopped short leaves the finer
        level's later solves started as :func:`run_load_path` starts them.
    """
    if not levels:
        raise ValueError("run_nested_load_path needs at least one level")
    for qp in levels:
        if qp.friction is None or qp.friction.law != "tresca":
            raise ValueError(f"run_nested_load_path: {qp.name} is not allowed; allowed: "
                             "problems with Tresca friction and a load path (Coulomb's "
                             "fixed point takes a different number of solves per level)")
    runs, below = [], None
    for qp in levels:
        answers = []

        def step(step_qp, start, below=below, answers=answers):
            i = len(answers)
            if below is not None and i < len(below):
                change = prolongate_displacement(*below[i], step_qp)
                if i:
                    change -= prolongate_displacement(*below[i - 1], step_qp)
                u_last = start.u if start is not None else np.zeros(step_qp.n)
                start = NestedStart(u_last + change, None if start is None else start.p)
            res = solve_step(step_qp, start)
            answers.append((step_qp, res.u))
            return res

        runs.append(run_load_path(qp, step, tol, max_iter, warm=True))
        below = answers
    return runs


def tangential_scale(scaled: ContactQP, qp: ContactQP) -> float:
    """The factor by which the tangential step of ``scaled``'s load path is
    :func:`scaled_tangential_step`'s scaling of ``qp``'s (least squares over the step's
    data, exact: they are affine in the factor)."""
    (normal, step), (_, base) = scaled.friction.path, qp.friction.path
    a = np.concatenate([normal.f, normal.g, normal.offset])
    d = np.concatenate([base.f, base.g, base.offset]) - a
    x = np.concatenate([step.f, step.g, step.offset]) - a
    return float(x @ d / (d @ d))


def scaled_tangential_step(qp: ContactQP, factor: float) -> ContactQP:
    """``qp`` with the tangential step of its two-step load path scaled by ``factor``
    (the step's data are affine in the prescribed shift: exact)."""
    fr = qp.friction
    if fr is None or len(fr.path) != 2:
        raise ValueError("scaled_tangential_step needs a two-step frictional load path")
    normal, tangential = fr.path
    return replace(qp, friction=replace(fr, path=(normal, normal.toward(tangential, factor))))


def tangential_ratio(steps: list[PathStep]) -> float:
    """``Q / (mu P)`` of the last step: the total tangential over ``mu`` times the total
    normal contact force (3D: the norm of the total tangential force)."""
    sol, fr = steps[-1].solution, steps[-1].qp.friction
    return fr.total_force(sol.lam) / (fr.mu * float(np.sum(sol.p)))


def path_for_ratio(qp: ContactQP, ratio: float, rtol: float = 1e-6,
                   max_iter: int = 60, solve=None) -> list[PathStep]:
    """The load path of ``qp`` with its tangential step scaled so that ``Q / (mu P)`` of the
    last step is ``ratio`` (within ``rtol``), by bracketing and the Illinois variant of
    regula falsi on the monotone ``Q / (mu P)`` of the scale.

    ``solve(step_qp) -> TrescaSolution`` solves one Tresca step (default:
    :func:`tresca_exact`, ``A`` factorised once, each tangential step warm-started from
    the last scale's active set; a surface beyond :data:`TRESCA_EXACT_MAX_M` rows needs
    another solver, e.g. a registered one through :func:`as_tresca_solution`).

    Raises
    ------
    ParameterError
        ``ratio`` outside ``[0, 1)``: at ``Q >= mu P`` the whole contact slips (gross
        sliding) and there is no static equilibrium to find.
    """
    if not 0.0 <= ratio < 1.0:
        raise ParameterError(f"parameter 'ratio': Q/(mu P) = {ratio!r} is not allowed; allowed: "
                             "[0, 1) (at Q >= mu P the whole contact slips: gross sliding, no "
                             "static equilibrium)")
    if solve is None:
        ops = dual_operators(qp)
        exact = lambda step_qp: tresca_exact(step_qp, ops)
    else:
        exact = solve
    normal = friction_path(replace(qp, friction=replace(qp.friction, path=qp.friction.path[:1])),
                           exact)                  # the normal step: the same for every scale
    warm = {"solution": normal[-1].solution}

    def warm_exact(step_qp):                     # warm-started from the last scale's answer
        last = warm["solution"]
        sol = tresca_exact(step_qp, ops, start=last.active, dual_start=last.dual)
        warm["solution"] = sol
        return sol

    tangential = warm_exact if solve is None else solve

    run = lambda t: friction_path(scaled_tangential_step(qp, t), tangential, done=normal)
    lo, f_lo = 0.0, tangential_ratio(run(0.0)) - ratio
    hi, steps = 1.0, run(1.0)
    f_hi = tangential_ratio(steps) - ratio
    while f_hi < 0 and hi < 2.0 ** 30:
        lo, f_lo, hi = hi, f_hi, 2.0 * hi
        steps = run(hi)
        f_hi = tangential_ratio(steps) - ratio
    side = 0
    for _ in range(max_iter):
        if abs(f_hi) <= rtol * ratio:
            return steps
        t = hi - f_hi * (hi - lo) / (f_hi - f_lo)
        steps = run(t)
        f_t = tangential_ratio(steps) - ratio
        if (f_t > 0) == (f_hi > 0):
            hi, f_hi = t, f_t
            f_lo, side = (f_lo / 2, side) if side == 1 else (f_lo, 1)
        else:
            lo, f_lo, hi, f_hi = hi, f_hi, t, f_t
            side = 0
    raise RuntimeError(f"path_for_ratio: Q/(mu P) = {ratio} not reached within {max_iter} "
                       "solves")


def facet_convergence(qp: ContactQP, facets: tuple, solve=None) -> list[dict]:
    """The faceted law's distance to the isotropic one as the facets grow: the load path
    of the frictional ``qp`` (isotropic, ``qp.friction.facets`` 0) and of the same problem
    with each ``k`` of ``facets`` (:class:`problems.friction.data.Friction`), each by ``solve``
    (default: :func:`tresca_exact`, ``A`` factorised once for all), compared in the last
    step.

    ``P_k`` lies between the disc of radius ``cos(pi/k)`` and the unit disc, so
    ``cos(pi/k) |x| <= h_Pk(x) <= |x|`` and, with ``J`` and ``J_k`` the two energies,
    ``J_k <= J <= J_k + (1 - cos(pi/k)) D(u)`` for every ``u`` (``D(u) = sum_i s_i
    |slip_i(u)|``); at the minimisers ``0 <= J* - J_k* <= (1 - cos(pi/k)) D(u_k*)``: the
    energy gap is ``O(k^-2)``. The displacement and the traction are only ``O(k^-1)``
    in general: at a slipping node ``lam_i`` is ``s_i`` times a vertex of ``P_k``,
    whose direction is off the slip's by up to ``pi / k``.

    Returns
    -------
    list of dict
        One row per ``k``: ``facets``, ``status`` and ``iterations`` of its last step,
        ``energy`` (``J_k*``), ``energy_gap`` (``J* - J_k*``), ``gap_bound``
        (``(1 - cos(pi/k)) D(u_k*)``), ``displacement`` (``||u_k - u||_A / ||u||_A``),
        ``traction`` (``max_i |lam_k,i - lam_i| / max_i |lam_i|``), ``distance``
        (``1 - cos(pi/k)``, the k-gon's relative distance to the disc).
    """
    fr = qp.friction
    if fr is None or fr.facets or fr.components != 2:
        raise ValueError("facet_convergence needs an isotropic 3D frictional ContactQP")
    if solve is None:
        ops = dual_operators(qp)
        solve = lambda step_qp: tresca_exact(step_qp, ops)
    iso = friction_path(qp, solve)[-1]
    energy = tresca_energy(iso.qp, iso.solution.u)
    lam_iso = fr.magnitude(iso.solution.lam)
    rows = []
    for k in facets:
        last = friction_path(replace(qp, friction=replace(fr, facets=int(k))), solve)[-1]
        u, lam, step_fr = last.solution.u, last.solution.lam, last.qp.friction
        distance = float(1.0 - np.cos(np.pi / k))
        rows.append({
            "facets": int(k), "status": last.solution.status,
            "iterations": int(last.solution.iterations),
            "energy": tresca_energy(last.qp, u),
            "energy_gap": energy - tresca_energy(last.qp, u),
            "gap_bound": distance * float(step_fr.slip_bound @ step_fr.magnitude(step_fr.slip(u))),
            "displacement": energy_error(iso.qp, u, iso.solution.u),
            "traction": float(np.max(fr.magnitude(lam - iso.solution.lam))
                              / max(float(np.max(lam_iso, initial=0.0)), 1e-300)),
            "distance": distance})
    return rows
