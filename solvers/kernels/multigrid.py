"""Multigrid for ``A``: one symmetric V-cycle as a preconditioner, and Lanczos bounds.

* ``A-hat`` (thesis (8.18)): one symmetric V-cycle per application, either pyamg
  smoothed aggregation with the rigid-body modes of each body as near-null space, or
  geometric multigrid on the refinement hierarchy (``qp.multilevel``) with Galerkin
  coarse operators; on an adaptive hierarchy the many small refinement steps are merged
  into levels that grow by a factor (:func:`merge_levels`, exact solves where a merged
  level refined a region twice), and a level smooths only the unknowns it changed
  (local smoothing, :func:`changed_dofs`), so a V-cycle costs O(N) there as on
  uniform hierarchies; on an extruded mesh without a hierarchy (the roll stack)
  semicoarsening along the axis with zebra plane smoothing (:func:`layered_hierarchy`).
  :func:`scaled_vcycle` scales it by Lanczos (Remark 8.14) so that
  ``A-hat < A <= gamma_bar A-hat``; :func:`vcycle` is the plain V-cycle a PCG needs.
* :data:`AHAT`: the V-cycle as a solver option (kind and settings), declared once here
  and read by every solver that uses one.
* :func:`lanczos_extremes`: Ritz estimates of extreme eigenvalues of a symmetric
  pencil (Remark 8.14, kappa(S-hat) of Table 9.1).
"""
from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from problems.qp import ContactQP, Extrusion, Multilevel
from problems.spec import (Component, ComponentParameter, Parameter, ParameterError,
                           resolve_parameters)

#: Safety factors applied to Ritz values (Ritz values lie inside the spectrum).
LOW_SAFETY = 0.9
HIGH_SAFETY = 1.05

Apply = Callable[[np.ndarray], np.ndarray]


# ---------------------------------------------------------------------------
# Lanczos (Remark 8.14)
# ---------------------------------------------------------------------------
def lanczos_extremes(apply_K: Apply, n: int, steps: int = 30, apply_Minv: Apply | None = None,
                     seed: int = 0, tol: float = 1e-10, project: Apply | None = None
                     ) -> tuple[float, float]:
    """Ritz estimates of the extreme eigenvalues of ``K x = lambda M x``.

    Preconditioned Lanczos in the ``M`` inner product (only ``M^{-1}`` is
    applied), without re-orthogonalisation (extreme Ritz values converge first;
    spurious copies do not matter for extremes).

    Parameters
    ----------
    apply_K, apply_Minv : callables
        Symmetric positive (semi)definite ``K`` and SPD ``M^{-1}`` (identity if None).
    n : int
        Dimension.
    steps : int
        Lanczos steps (one ``K`` and one ``M^{-1}`` product each).
    seed : int
        Random start vector.
    project : callable, optional
        Orthogonal projection onto the subspace the pencil lives on, when ``K`` and
        ``M^{-1}`` vanish on its complement (a floating body's modes,
        :func:`scaled_vcycle`). The start vector and each ``M q`` are projected: the
        Lanczos recurrence carries ``M q`` without applying ``M``, and on the null
        space its component follows the Lanczos polynomial at 0, which grows like
        ``((sqrt(kappa) + 1) / (sqrt(kappa) - 1))^k``; unprojected, after 30 steps of a
        good preconditioner (``kappa`` ~ 4) it swamps the rest and the Ritz values are
        garbage (negative ones, measured on the roll stack).

    Returns
    -------
    (lambda_min, lambda_max) : floats
        Ritz values; ``lambda_min`` over-, ``lambda_max`` under-estimates.
    """
    Minv = apply_Minv or (lambda x: x)
    keep = project or (lambda x: x)
    r = keep(np.random.default_rng(seed).standard_normal(n))
    z = Minv(r)
    beta0 = np.sqrt(max(float(r @ z), 0.0))
    q, Mq = z / beta0, r / beta0
    Mq_prev, beta = np.zeros(n), 0.0
    alphas, betas = [], []
    for _ in range(min(steps, n)):
        w = apply_K(q)
        alpha = float(q @ w)
        alphas.append(alpha)
        w = keep(w - alpha * Mq - beta * Mq_prev)
        z = Minv(w)
        beta_new = np.sqrt(max(float(w @ z), 0.0))
        if beta_new <= tol * max(abs(alpha), 1e-300):
            break
        betas.append(beta_new)
        Mq_prev = Mq
        q, Mq, beta = z / beta_new, w / beta_new, beta_new
    k = len(alphas)
    ritz = sla.eigvalsh_tridiagonal(np.array(alphas), np.array(betas[:k - 1])) if k > 1 \
        else np.array(alphas)
    return float(ritz[0]), float(ritz[-1])


# ---------------------------------------------------------------------------
# A-hat: one symmetric V-cycle (8.18)
# ---------------------------------------------------------------------------
#: Smoothers of the V-cycle: pyamg name and settings per sweep.
SMOOTHERS = {
    "symmetric_gs": ("gauss_seidel", {"sweep": "symmetric"}),
    "block_gs": ("block_gauss_seidel", {"sweep": "symmetric"}),
    "jacobi": ("jacobi", {"omega": 0.6}),
}
#: The smoother of the gmg and sa V-cycles unless a solver's options name another.
DEFAULT_SMOOTHER = "symmetric_gs"


def _smoother(name: str, sweeps: int, blocked: bool):
    """pyamg smoother spec ``(name, settings)`` with ``sweeps`` iterations.

    Block Gauss-Seidel needs a BSR operator; otherwise pointwise symmetric GS.
    """
    if name == "block_gs" and not blocked:
        name = "symmetric_gs"
    kind, settings = SMOOTHERS[name]
    return kind, {**settings, "iterations": int(sweeps) * (2 if kind == "jacobi" else 1)}


def _as_blocked(A: sp.spmatrix, dim: int, free_dofs: np.ndarray | None):
    """``A`` as BSR with node blocks when the free DOFs come in whole nodes."""
    n = A.shape[0]
    if free_dofs is None or n % dim:
        return sp.csr_matrix(A)
    fd = np.asarray(free_dofs).reshape(-1, dim)
    if np.all(fd[:, 0] % dim == 0) and np.all(np.diff(fd, axis=1) == 1):
        return sp.bsr_matrix(A, blocksize=(dim, dim))
    return sp.csr_matrix(A)


@contextmanager
def _seeded_global_rng(seed: int = 0):
    """pyamg estimates spectral radii (Jacobi weights, prolongation smoothing) from
    ``np.random.rand`` start vectors: seed the global generator while a hierarchy is
    set up, so that two runs give the same hierarchy, and restore it afterwards."""
    state = np.random.get_state()
    np.random.seed(seed)
    try:
        yield
    finally:
        np.random.set_state(state)


def sa_hierarchy(A: sp.spmatrix, near_null: np.ndarray | None, dim: int,
                 free_dofs: np.ndarray | None, smoother: str, sweeps: int, max_coarse: int):
    """pyamg smoothed aggregation with ``near_null`` (rigid-body modes per body).

    Node-blocked (BSR) when the free DOFs come in whole nodes; symmetric
    smoothing so that one V-cycle is an SPD operator.
    """
    import pyamg
    Ab = _as_blocked(A, dim, free_dofs)
    sm = _smoother(smoother, sweeps, sp.isspmatrix_bsr(Ab))
    B = None if near_null is None else np.asarray(near_null, dtype=float)
    with _seeded_global_rng():
        return pyamg.smoothed_aggregation_solver(
            Ab, B=B, max_coarse=max_coarse, presmoother=sm, postsmoother=sm,
            improve_candidates=None, coarse_solver="splu")


def _injected_rows(P: sp.csr_matrix) -> np.ndarray:
    """Rows of a prolongation that inject a coarse unknown (one entry, 1): the fine
    level's old unknowns; the others are new."""
    single = np.flatnonzero(np.diff(P.indptr) == 1)
    injected = np.zeros(P.shape[0], dtype=bool)
    injected[single] = P.data[P.indptr[single]] == 1.0
    return injected


def changed_dofs(A: sp.csr_matrix, P: sp.spmatrix) -> np.ndarray:
    """The unknowns of a fine level whose basis function is new or has changed.

    ``P`` maps the coarse level to the fine one (``A``). A fine row of ``P`` that is not
    an injection (one entry, 1) is a new unknown; an old unknown's basis function
    changes where a neighbour is new (its support was bisected). These are the
    unknowns local multigrid smooths on this level (Bramble, Pasciak, Wang, Xu 1991;
    Wu, Chen 2006): on a uniform refinement every unknown, on an adaptive step only
    those near the refined cells.

    Returns
    -------
    (k,) int array, sorted
    """
    P = sp.csr_matrix(P)
    new = np.flatnonzero(~_injected_rows(P))
    mark = np.zeros(A.shape[0], dtype=bool)
    mark[new] = True
    if new.size:
        mark[sp.csr_matrix(A)[new].indices] = True
    return np.flatnonzero(mark)


def _relax(smoother: str, sweeps: int) -> Callable:
    """``relax(A, x, b)`` in place: the named smoother of :data:`SMOOTHERS` (pointwise)."""
    from pyamg.relaxation import relaxation
    kind, settings = _smoother(smoother, sweeps, blocked=False)
    method = getattr(relaxation, kind)
    return lambda A, x, b: method(A, x, b, **settings)


#: Smoothing on the levels of a geometric hierarchy: every unknown of every level
#: (``full``), or only the unknowns whose basis function the level changed (``local``,
#: :func:`changed_dofs`), which keeps a V-cycle O(N) on adaptive hierarchies.
SMOOTHING = ("local", "full")

#: ``local`` smooths a level in full where it changed more than this share of its
#: unknowns: the sweep over the principal submatrix then saves less than its index
#: bookkeeping costs (docs/guide/measurements.md).
LOCAL_SHARE = 0.8

#: A merged level solves its deep unknowns exactly (:func:`geometric_hierarchy`,
#: ``depths``) only while they are at most this share of the level: around singular
#: points, not where a whole level was refined twice (then the deep block would be the
#: level, and the merge itself the mistake).
DEEP_SHARE = 0.1


def refinement_depth(prolongations: list) -> np.ndarray:
    """How often each unknown's neighbourhood was refined along ``prolongations``: 0 for an
    unknown of the coarsest level, and for a new unknown (a row of ``P`` that is not an
    injection) one more than the deepest of the unknowns it is interpolated from.

    A merged level (:func:`merge_levels`) is one refinement of most of its region, but
    around singular points an adaptive sequence refines the same cells at every step:
    there the level spans several octaves, which one smoothing sweep does not reach.
    """
    Ps = [sp.csr_matrix(P) for P in prolongations]
    depth = np.zeros(Ps[0].shape[1]) if Ps else np.zeros(0)
    for P in Ps:
        deepest = np.zeros(P.shape[0])
        np.maximum.at(deepest, np.repeat(np.arange(P.shape[0]), np.diff(P.indptr)),
                      depth[P.indices])
        depth = np.where(_injected_rows(P), P @ depth, deepest + 1.0)
    return depth


def merge_levels(prolongations: list, min_growth: float) -> tuple[list, list]:
    """The refinement levels a V-cycle keeps: from the finest down, the next kept level is
    the finest one with at most ``1 / min_growth`` of the unknowns of the last kept; the
    prolongations in between are multiplied together (nested meshes: the product is the
    interpolation between the kept levels).

    An adaptive sequence adds a few per cent of the nodes per step (dozens of levels whose
    sizes sum to several N: the adaptive study's page), so every level costs a transfer
    of its full size and a call overhead. With ``min_growth >= 2`` the kept sizes sum to
    at most 2 N, and a V-cycle is O(N) even with full smoothing; uniform refinement (x4
    in 2D, x8 in 3D per level) keeps every level. ``min_growth <= 1`` keeps every level.

    A merge also stops where more than :data:`DEEP_SHARE` of the finer level's unknowns
    would have been refined twice or more (:func:`refinement_depth`): those regions
    span several octaves, which :func:`geometric_hierarchy` solves exactly, so they
    must stay small (around the singular points). On the early steps, which refine
    broad regions, fewer levels merge.

    Parameters
    ----------
    prolongations : list of sparse
        ``P_k`` from level ``k`` to ``k + 1``, coarse to fine.
    min_growth : float

    Returns
    -------
    (kept, depths) : lists
        The kept levels' prolongations (CSR), coarse to fine, and for each the
        :func:`refinement_depth` of the fine level's unknowns over the merged steps
        (1 where one step refined, 2 or more where a region was refined again).
    """
    Ps = [sp.csr_matrix(P) for P in prolongations]
    if min_growth <= 1.0 or not Ps:
        return Ps, [refinement_depth([P]) for P in Ps]
    sizes = [P.shape[1] for P in Ps] + [Ps[-1].shape[0]]
    kept, depths, fine = [], [], len(Ps)
    while fine > 0:
        coarse, depth = fine - 1, refinement_depth(Ps[fine - 1:fine])
        while coarse > 0 and sizes[fine] < min_growth * sizes[coarse]:
            wider = refinement_depth(Ps[coarse - 1:fine])
            if np.mean(wider >= 2) > DEEP_SHARE:      # refined again in too wide a region
                break
            coarse, depth = coarse - 1, wider
        P = Ps[coarse]
        for k in range(coarse + 1, fine):
            P = Ps[k] @ P
        kept.append(sp.csr_matrix(P))
        depths.append(depth)
        fine = coarse
    return kept[::-1], depths[::-1]


def geometric_hierarchy(A: sp.spmatrix, prolongations: list, smoother: str, sweeps: int,
                        smoothing: str = "local", depths: list | None = None):
    """Geometric multigrid on the refinement hierarchy, Galerkin coarse operators.

    Parameters
    ----------
    prolongations : list of sparse
        ``P_k`` maps level ``k`` to ``k+1`` on the free DOFs; ``P[-1]`` ends at
        ``A``. Without prolongations the "V-cycle" is a direct solve.
    smoothing : {"local", "full"}
        ``local``: each level smooths only the unknowns it added and their
        neighbours (:func:`changed_dofs`). On a uniform hierarchy that is every
        unknown, the same cycle as ``full``; on an adaptive hierarchy, whose levels
        each add a few per cent of the nodes, the smoothing work per cycle drops from
        ``sum_k N_k`` (about 5 N for the thesis's graded meshes) to O(N), with the
        uniform spectral equivalence of local multigrid (Wu, Chen 2006). The smoothed
        rows are ``level.smooth_rows`` and the residual after pre-smoothing is formed
        from their columns alone (``level.smooth_columns``).
    depths : list of arrays, optional
        Per prolongation, the :func:`refinement_depth` of its fine unknowns
        (:func:`merge_levels`). Where a level refined a region more than once, its
        unknowns of depth >= 2 and their neighbours are solved exactly (a sparse LU of
        that principal submatrix) after pre- and before post-smoothing: the octaves
        the level skipped there. The blocks are small (docs/guide/measurements.md) and the
        cycle stays symmetric.
    """
    from pyamg.multilevel import MultilevelSolver
    from pyamg.relaxation.smoothing import change_smoothers
    if smoothing not in SMOOTHING:
        raise ValueError(f"parameter 'smoothing': {smoothing!r} is not allowed; allowed: "
                         f"{', '.join(SMOOTHING)}")
    levels = []
    A_k = sp.csr_matrix(A)
    for P in reversed(prolongations):
        lvl = MultilevelSolver.Level()
        lvl.A, lvl.P, lvl.R = A_k, sp.csr_matrix(P), sp.csr_matrix(P.T)
        levels.append(lvl)
        A_k = sp.csr_matrix(lvl.R @ A_k @ lvl.P)
    coarse = MultilevelSolver.Level()
    coarse.A = A_k
    levels.append(coarse)
    ml = MultilevelSolver(levels, coarse_solver="splu")
    sm = _smoother(smoother, sweeps, blocked=False)
    with _seeded_global_rng():
        change_smoothers(ml, presmoother=sm, postsmoother=sm)
    for lvl, depth in zip(levels[:-1], reversed(depths or [None] * len(levels[:-1]))):
        n = lvl.A.shape[0]
        deep = np.flatnonzero(depth >= 2) if depth is not None else np.zeros(0, dtype=int)
        if 0 < deep.size <= DEEP_SHARE * n:
            deep = np.unique(lvl.A[deep].indices)          # and their neighbours
            rows = lvl.A[deep].tocsr()
            lvl.deep = {"rows": deep, "A_rows": rows, "lu": spla.splu(rows[:, deep].tocsc())}
        idx = changed_dofs(lvl.A, lvl.P) if smoothing == "local" else np.arange(n)
        if len(idx) > LOCAL_SHARE * n:
            idx = np.arange(n)
        lvl.smooth_rows = idx
        if len(idx) < n:
            # the smoother runs on the principal submatrix (a contiguous sweep), the rest
            # of the smoothed rows enters its right-hand side
            rows = lvl.A[idx].tocsr()
            inside = np.zeros(n, dtype=bool)
            inside[idx] = True
            off = rows.tocoo()
            keep = ~inside[off.col]
            lvl.local = {"rows": idx, "block": rows[:, idx].tocsr(),
                         "off": sp.csr_matrix((off.data[keep], (off.row[keep], off.col[keep])),
                                              shape=rows.shape),
                         "columns": lvl.A[:, idx].tocsr(), "relax": _relax(smoother, sweeps)}
    return ml


#: The coarsest level of :func:`layered_hierarchy` keeps at most this many layers per body.
MIN_LAYERS = 3


def semicoarsening(extrusion: Extrusion) -> tuple[sp.csr_matrix, np.ndarray, Extrusion]:
    """One coarsening step along the extrusion axis: every other layer of each body (its
    first and last always) stays; an unknown on a dropped layer is interpolated linearly in
    the axis coordinate from its section unknown's copies on the two kept neighbours (a
    copy that is not an unknown, a Dirichlet DOF, contributes zero).

    Returns
    -------
    (P, kept, coarse) :
        ``P`` (n, n_coarse) the prolongation, ``kept`` the fine unknowns that are the
        coarse ones (``P[kept]`` is the identity), ``coarse`` the coarse level's layers.
    """
    layer, sec, x = extrusion.layer_of_dof, extrusion.section_dof, extrusion.layer_coordinate
    n, n_layers = len(layer), len(x)
    left = np.arange(n_layers)                 # for each layer its kept neighbours
    right = np.arange(n_layers)
    body_layers = []
    for layers in extrusion.body_layers:
        pos = np.arange(len(layers))
        kept = np.unique(np.append(pos[::2], pos[-1:]))
        body_layers.append(layers[kept])
        left[layers] = layers[kept[np.searchsorted(kept, pos, side="right") - 1]]
        right[layers] = layers[kept[np.searchsorted(kept, pos, side="left")]]
    is_kept = left == right
    table = -np.ones((n_layers, int(sec.max()) + 1 if n else 0), dtype=int)
    table[layer, sec] = np.arange(n)
    kept_dofs = np.flatnonzero(is_kept[layer])
    coarse_index = -np.ones(n, dtype=int)
    coarse_index[kept_dofs] = np.arange(len(kept_dofs))
    rows, cols, vals = [kept_dofs], [np.arange(len(kept_dofs))], [np.ones(len(kept_dofs))]
    dropped = np.flatnonzero(~is_kept[layer])
    a, c = left[layer[dropped]], right[layer[dropped]]
    w_a = (x[c] - x[layer[dropped]]) / (x[c] - x[a])
    for side, w in ((a, w_a), (c, 1.0 - w_a)):
        source = table[side, sec[dropped]]
        has = source >= 0
        rows.append(dropped[has])
        cols.append(coarse_index[source[has]])
        vals.append(w[has])
    P = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n, len(kept_dofs)))
    return P, kept_dofs, Extrusion(layer[kept_dofs], sec[kept_dofs], x, tuple(body_layers))


def spd_lu(A: sp.spmatrix):
    """SuperLU of a symmetric positive definite matrix: a symmetric fill-reducing order
    and no pivoting (less fill and faster solves than the default column order with
    partial pivoting: docs/guide/measurements.md)."""
    return spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                     options={"SymmetricMode": True})


def plane_smoother(A: sp.csr_matrix, extrusion: Extrusion, sweeps: int
                   ) -> tuple[Callable, Callable]:
    """Zebra plane Gauss-Seidel: the even layers of every body solved exactly at once (they
    do not couple: a layer couples only with its neighbours), then the odd ones.

    Returns ``(forward, backward)``, ``relax(A, x, b)`` in place, ``sweeps`` times even
    then odd, and odd then even: the pre- and post-smoother of a symmetric V-cycle.
    Solving whole sections is what makes the cycle robust to the anisotropy of an
    extruded mesh (cells long along the axis, fine across the contact): with coarsening
    along the axis it damps the error's oscillations along the axis whatever the cells'
    aspect ratio (Dendy, Moulton: semicoarsening with plane relaxation).
    """
    position = np.zeros(len(extrusion.layer_coordinate), dtype=int)
    for layers in extrusion.body_layers:
        position[layers] = np.arange(len(layers))
    colour = position[extrusion.layer_of_dof] % 2
    blocks = []
    for c in (0, 1):
        idx = np.flatnonzero(colour == c)
        rows = A[idx].tocsr()
        blocks.append((idx, rows, spd_lu(rows[:, idx])))

    def sweep(order):
        def relax(A_level, x, b):
            for _ in range(sweeps):
                for c in order:
                    idx, rows, lu = blocks[c]
                    x[idx] += lu.solve(b[idx] - rows @ x)
        return relax

    return sweep((0, 1)), sweep((1, 0))


def layered_hierarchy(A: sp.spmatrix, extrusion: Extrusion, sweeps: int,
                      min_layers: int = MIN_LAYERS):
    """Semicoarsening multigrid on an extruded mesh: levels by :func:`semicoarsening` until
    each body has at most ``min_layers`` layers (solved by a sparse LU), Galerkin coarse
    operators, :func:`plane_smoother` on every level.

    For meshes that are separate per level (no refinement hierarchy) but extruded, as the
    roll stack's: its tetrahedra are up to 25:1 long along the rolls, and smoothed
    aggregation with pointwise smoothing loses the spectral equivalence there, while this
    cycle's ``kappa(V A)`` stays small on every level (``tests/test_layered_multigrid.py``;
    the roll-stack study's page). The layers
    of one body couple only with their neighbours, on every level (linear
    interpolation between kept layers keeps the block tridiagonal structure).
    """
    from pyamg.multilevel import MultilevelSolver
    levels = []
    A_k = sp.csr_matrix(A)
    while True:
        lvl = MultilevelSolver.Level()
        lvl.A = A_k
        levels.append(lvl)
        if max(len(layers) for layers in extrusion.body_layers) <= min_layers:
            break
        lvl.presmoother, lvl.postsmoother = plane_smoother(A_k, extrusion, sweeps)
        P, _, extrusion = semicoarsening(extrusion)
        lvl.P, lvl.R = P, sp.csr_matrix(P.T)
        A_k = sp.csr_matrix(lvl.R @ A_k @ P)
    return MultilevelSolver(levels, coarse_solver="splu")


def smoothing_work(ml) -> float:
    """Unknowns smoothed per V-cycle (each sweep counted once), relative to the finest
    level: 4/3 on a uniform 2D hierarchy (every level in full); on an adaptive one
    with full smoothing about the number of levels' sum of sizes over N."""
    levels = ml.levels
    if len(levels) == 1:
        return 0.0
    rows = [len(getattr(lvl, "smooth_rows", np.arange(lvl.A.shape[0]))) for lvl in levels[:-1]]
    return float(np.sum(rows)) / levels[0].A.shape[0]


def _vcycle(ml, lvl: int, b: np.ndarray) -> np.ndarray:
    """One V-cycle on level ``lvl`` of a pyamg hierarchy, zero initial guess.

    Same operations as pyamg's cycle, without its residual norms (which cost
    as much as a smoothing sweep here). A level with ``local`` data
    (:func:`geometric_hierarchy`, local smoothing) relaxes only its smoothed rows.
    """
    levels = ml.levels
    if len(levels) == 1:
        return ml.coarse_solver(levels[0].A, b)
    level = levels[lvl]
    local = getattr(level, "local", None)
    deep = getattr(level, "deep", None)
    x = np.zeros_like(b)
    if local is None:
        level.presmoother(level.A, x, b)
    else:                   # from zero: x is zero off the smoothed rows
        rows = local["rows"]
        x_rows = np.zeros(len(rows))
        local["relax"](local["block"], x_rows, b[rows])
        x[rows] = x_rows
    if deep is not None:
        _deep_solve(deep, x, b)
    residual = b - (local["columns"] @ x_rows if local is not None and deep is None
                    else level.A @ x)
    coarse_b = level.R @ residual
    if lvl == len(levels) - 2:
        coarse_x = ml.coarse_solver(levels[-1].A, coarse_b)
    else:
        coarse_x = _vcycle(ml, lvl + 1, coarse_b)
    x += level.P @ coarse_x
    if deep is not None:
        _deep_solve(deep, x, b)
    if local is None:
        level.postsmoother(level.A, x, b)
    else:
        x_rows = x[rows]
        local["relax"](local["block"], x_rows, b[rows] - local["off"] @ x)
        x[rows] = x_rows
    return x


#: Bytes of one float64 entry of a vector.
WORD = 8


@dataclass(frozen=True)
class Traffic:
    """Bytes an operation must move between memory and the core, by the STREAM
    convention: every array it reads counted once, every array it writes once (no
    write-allocate, no re-reads after eviction), so ``bytes / time`` is comparable with
    STREAM's bandwidth.

    Attributes
    ----------
    values : int
        Matrix and factor entries (8 bytes each as assembled).
    indices : int
        Their index arrays (column indices and row pointers).
    vectors : int
        Vectors read and written.
    """

    values: int = 0
    indices: int = 0
    vectors: int = 0

    @property
    def total(self) -> int:
        return self.values + self.indices + self.vectors

    def __add__(self, other: "Traffic") -> "Traffic":
        return Traffic(self.values + other.values, self.indices + other.indices,
                       self.vectors + other.vectors)

    def __mul__(self, k: int) -> "Traffic":
        return Traffic(k * self.values, k * self.indices, k * self.vectors)

    __rmul__ = __mul__


def matrix_traffic(M: sp.spmatrix) -> Traffic:
    """One pass over ``M`` stored as CSR: its values, column indices and row pointers."""
    M = sp.csr_matrix(M)
    return Traffic(M.data.nbytes, M.indices.nbytes + M.indptr.nbytes)


def spmv_traffic(M: sp.spmatrix) -> Traffic:
    """``y = M x``: the matrix, ``x`` read and ``y`` written."""
    rows, cols = M.shape
    return matrix_traffic(M) + Traffic(vectors=WORD * (rows + cols))


def vector_traffic(n: int, reads: int, writes: int) -> Traffic:
    """A vector operation on ``n`` entries reading ``reads`` and writing ``writes`` vectors."""
    return Traffic(vectors=WORD * n * (reads + writes))


def smoother_traffic(M: sp.spmatrix, smoother: str, sweeps: int) -> Traffic:
    """One smoothing step of :data:`SMOOTHERS` on ``M`` (:func:`_smoother`'s iterations):
    per pass the matrix, ``x`` read and written and ``b`` read; a symmetric Gauss-Seidel
    iteration is two passes (forward, backward), a Jacobi iteration one."""
    settings = _smoother(smoother, sweeps, blocked=False)[1]
    passes = settings["iterations"] * (2 if settings.get("sweep") == "symmetric" else 1)
    return passes * (matrix_traffic(M) + vector_traffic(M.shape[0], reads=2, writes=1))


def lu_traffic(lu) -> Traffic:
    """A solve with SuperLU's factors ``lu``: both triangles once and the vector in and out
    (the factors' supernodal storage counted as CSR of the same nonzeros)."""
    return matrix_traffic(lu.L) + matrix_traffic(lu.U) + vector_traffic(lu.shape[0], 1, 1)


def vcycle_traffic(ml, smoother: str, sweeps: int) -> Traffic:
    """Bytes one V-cycle of :func:`_vcycle` moves on the hierarchy ``ml`` (built with
    ``smoother`` and ``sweeps``), operation by operation as :func:`_vcycle` performs them:
    per level the start vector, pre-smoothing, the residual, restriction, prolongation and
    its update, post-smoothing, the deep blocks' exact solves where a level has them; the
    coarsest level's direct solve (SuperLU's factors, as pyamg's ``splu`` coarse solver
    holds them).
    """
    levels = ml.levels
    coarse = levels[-1].A
    total = lu_traffic(spla.splu(sp.csc_matrix(coarse)))
    for level in levels[:-1]:
        n = level.A.shape[0]
        local = getattr(level, "local", None)
        deep = getattr(level, "deep", None)
        total += vector_traffic(n, reads=0, writes=1)                  # x = 0
        if local is None:
            smoothing = 2 * smoother_traffic(level.A, smoother, sweeps)
            residual = spmv_traffic(level.A)
        else:
            k = len(local["rows"])
            smoothing = (2 * smoother_traffic(local["block"], smoother, sweeps)
                         + vector_traffic(k, 0, 1)                # x_rows = 0
                         + 5 * vector_traffic(k, 1, 1)            # b, x gathered; x scattered
                         + spmv_traffic(local["off"]) + vector_traffic(k, 2, 1))
            residual = (spmv_traffic(local["columns"]) if deep is None
                        else spmv_traffic(level.A))
        if deep is not None:                      # after pre- and before post-smoothing
            rows = len(deep["rows"])
            total += 2 * (vector_traffic(rows, 1, 1) + spmv_traffic(deep["A_rows"])
                          + vector_traffic(rows, 2, 1) + lu_traffic(deep["lu"])
                          + vector_traffic(rows, 2, 1))
        total += (smoothing + residual + vector_traffic(n, 2, 1)      # b - A x
                  + spmv_traffic(level.R) + spmv_traffic(level.P)
                  + vector_traffic(n, 2, 1))                          # x += P x_c
    return total


def cg_step_traffic(A: sp.spmatrix) -> Traffic:
    """Bytes of one preconditioned CG step of SciPy's ``cg`` beside its preconditioner,
    as its loop performs them: the residual's norm, ``rho = r'z``, ``p = z + beta p``
    (in place, two operations), ``q = A p``, ``p'q``, and ``x += alpha p`` and
    ``r -= alpha q``, each forming ``alpha p`` (``alpha q``) first."""
    n = A.shape[0]
    return (vector_traffic(n, 1, 0) + vector_traffic(n, 2, 0)          # |r|, r'z
            + vector_traffic(n, 1, 1) + vector_traffic(n, 2, 1)        # p *= beta; p += z
            + spmv_traffic(A) + vector_traffic(n, 2, 0)                # q = A p; p'q
            + 2 * (vector_traffic(n, 1, 1) + vector_traffic(n, 2, 1)))  # x, r updates


def _deep_solve(deep: dict, x: np.ndarray, b: np.ndarray) -> None:
    """``x`` corrected in place by the exact solve on a level's deep block
    (:func:`geometric_hierarchy`, ``depths``)."""
    rows = deep["rows"]
    x[rows] += deep["lu"].solve(b[rows] - deep["A_rows"] @ x)


def chebyshev_degree(lo: float, hi: float, gamma_target: float) -> int:
    """Smallest degree ``d`` of the Chebyshev polynomial in ``V A`` whose spectral ratio
    on ``[lo, hi]`` is at most ``gamma_target``: ``(1 + e) / (1 - e) <= gamma_target``
    with ``e = 1 / T_d((hi + lo) / (hi - lo))`` (1 if ``hi / lo`` already meets it)."""
    if hi / lo <= gamma_target or gamma_target <= 1.0:
        return 1
    eps = (gamma_target - 1.0) / (gamma_target + 1.0)
    sigma = (hi + lo) / (hi - lo)
    return int(np.ceil(np.arccosh(1.0 / eps) / np.arccosh(sigma)))


def chebyshev_vcycle(apply_A: Apply, vcycle_raw: Apply, lo: float, hi: float,
                     degree: int) -> Apply:
    """``x = p(V A) V r``: ``degree`` steps of Chebyshev semi-iteration for ``A x = r``
    preconditioned by the V-cycle ``V``, from ``x = 0``, on the interval ``[lo, hi]`` of
    ``lambda(V A)``.

    A fixed polynomial, so the result is a linear, symmetric operator (``V p(AV) =
    p(VA) V``); positive definite when ``hi`` bounds ``lambda(V A)`` from above (the
    residual polynomial lies in ``(0, 1)`` below ``lo``), so it is an ``A-hat^{-1}``
    in the sense of (8.18), with ``kappa`` reduced from ``hi / lo`` to
    ``(1 + e) / (1 - e)``, ``e = 1 / T_degree((hi + lo) / (hi - lo))``. One product with
    ``A`` and one V-cycle per degree (Y. Saad, *Iterative Methods for Sparse Linear
    Systems*, Alg. 12.1).
    """
    theta, delta = 0.5 * (hi + lo), 0.5 * (hi - lo)
    sigma = theta / delta

    def apply(r: np.ndarray) -> np.ndarray:
        d = vcycle_raw(r) / theta
        x = d.copy()
        rho = 1.0 / sigma
        for _ in range(degree - 1):
            z = vcycle_raw(r - apply_A(x))
            rho_new = 1.0 / (2.0 * sigma - rho)
            d = (rho_new * rho) * d + (2.0 * rho_new / delta) * z
            x += d
            rho = rho_new
        return x

    return apply


#: Passes of the automatic degree: choose, measure the polynomial's Ritz values, correct
#: the V-cycle's smallest eigenvalue from them, choose again.
CHEBYSHEV_PASSES = 3


def _below_interval(lo: float, hi: float, degree: int, lam_poly: float) -> float:
    """The eigenvalue ``lambda < lo`` of ``V A`` that the Chebyshev polynomial of
    :func:`chebyshev_vcycle` on ``[lo, hi]`` maps to ``lam_poly = lambda p(lambda)``."""
    theta, delta = 0.5 * (hi + lo), 0.5 * (hi - lo)
    t_sigma = np.cosh(degree * np.arccosh(theta / delta))
    target = (1.0 - lam_poly) * t_sigma
    if target <= 1.0:
        return lo
    return float(theta - delta * np.cosh(np.arccosh(target) / degree))


@dataclass
class ScaledVCycle:
    """``A-hat^{-1}`` = one V-cycle (or a Chebyshev polynomial in it) divided by
    ``gamma_low`` (Remark 8.14).

    After scaling ``A-hat < A <= gamma_bar A-hat`` (8.18) with
    ``gamma_bar = gamma_high / gamma_low``. ``complement``, if set, is the
    orthogonal projection onto the complement of a near-kernel (floating bodies,
    :func:`scaled_vcycle`); the operator then acts on that complement only.
    """

    kind: str
    ml: object
    gamma_low: float
    gamma_high: float
    ritz: tuple
    setup_time: float
    lanczos_time: float
    n_applications: int = 0
    time: float = 0.0
    degree: int = 1
    ritz_vcycle: tuple = (np.nan, np.nan)
    polynomial: Apply | None = None
    complement: Apply | None = None

    @property
    def gamma_bar(self) -> float:
        return self.gamma_high / self.gamma_low

    def vcycle_once(self, r: np.ndarray) -> np.ndarray:
        """One plain V-cycle with zero start (symmetric smoothing), on the complement."""
        t0 = time.perf_counter()
        if self.complement is not None:
            r = self.complement(r)
        x = _vcycle(self.ml, 0, np.asarray(r, dtype=float))
        if self.complement is not None:
            x = self.complement(x)
        self.time += time.perf_counter() - t0
        self.n_applications += 1
        return x

    def raw(self, r: np.ndarray) -> np.ndarray:
        """The unscaled operator: one V-cycle, or the Chebyshev polynomial in it."""
        if self.polynomial is None:
            return self.vcycle_once(r)
        return self.polynomial(r)

    def __call__(self, r: np.ndarray) -> np.ndarray:
        """``A-hat^{-1} r`` (scaled)."""
        return self.raw(r) / self.gamma_low

    def operator_complexity(self) -> float:
        return float(self.ml.operator_complexity())

    def smoothing_work(self) -> float:
        """Unknowns smoothed per V-cycle over the finest level's (:func:`smoothing_work`)."""
        return smoothing_work(self.ml)

    def deep_work(self) -> float:
        """Unknowns of the exact deep-block solves (:func:`geometric_hierarchy`,
        ``depths``) per V-cycle over the finest level's (each solved twice a cycle)."""
        rows = [len(lvl.deep["rows"]) for lvl in self.ml.levels if hasattr(lvl, "deep")]
        return float(np.sum(rows)) / self.ml.levels[0].A.shape[0]


def vcycle(A: sp.spmatrix, kind: str, multilevel: Multilevel | None, dim: int,
           free_dofs: np.ndarray | None, *, smoother: str = DEFAULT_SMOOTHER, sweeps: int,
           max_coarse: int = 0, smoothing: str = "local", min_growth: float = 1.0
           ) -> ScaledVCycle:
    """One symmetric V-cycle as a preconditioner, unscaled (``gamma_low = 1``).

    ``kind`` {"gmg", "layers", "sa"}: geometric multigrid on
    ``multilevel.prolongations``, semicoarsening on ``multilevel.extrusion``
    (:func:`layered_hierarchy`, whose plane smoother ignores ``smoother``) or pyamg
    smoothed aggregation (rigid-body modes as near-null space);
    V(sweeps, sweeps) with the named symmetric smoother; ``max_coarse`` (SA
    only) the largest coarsest level; ``smoothing`` (gmg only) local or full
    (:func:`geometric_hierarchy`); ``min_growth`` (gmg only) which refinement levels
    the cycle keeps (:func:`merge_levels`; 1 = every one). What a multigrid-PCG
    linear solve needs; :func:`scaled_vcycle` adds the scaling of (8.18).
    """
    multilevel = multilevel or Multilevel()
    t0 = time.perf_counter()
    if kind == "sa":
        ml = sa_hierarchy(A, multilevel.rigid_body_modes, dim, free_dofs, smoother, sweeps,
                          max_coarse)
    elif kind == "gmg":
        kept, depths = merge_levels(multilevel.prolongations, min_growth)
        ml = geometric_hierarchy(A, kept, smoother, sweeps, smoothing, depths)
    elif kind == "layers":
        if multilevel.extrusion is None:
            raise ParameterError("parameter 'ahat': 'layers' needs an extruded mesh "
                                 "(multilevel.extrusion), which this problem does not "
                                 "supply; allowed here: gmg, sa")
        ml = layered_hierarchy(A, multilevel.extrusion, sweeps)
    else:
        raise ValueError(f"unknown A-hat kind {kind!r}; allowed: gmg, layers, sa")
    return ScaledVCycle(kind, ml, 1.0, 1.0, (np.nan, np.nan), time.perf_counter() - t0, 0.0)


def vcycle_kind(qp: ContactQP, kind: str) -> str:
    """``kind``, with ``auto`` resolved: gmg when ``qp`` has a refinement hierarchy, layers
    when it is an extruded mesh, else sa."""
    if kind != "auto":
        return kind
    if qp.multilevel.prolongations:
        return "gmg"
    return "layers" if qp.multilevel.extrusion is not None else "sa"


def component_vcycle(qp: ContactQP, ahat) -> ScaledVCycle:
    """The unscaled V-cycle an ``ahat`` component (:class:`problems.spec.Component`, as the
    augmented projection declares it) describes on ``qp.A``: what a PCG solve needs.

    Kind ``auto`` as :func:`vcycle_kind`; a Lanczos step count among the options is
    not used.
    """
    o = ahat.options
    return vcycle(qp.A, vcycle_kind(qp, ahat.kind), qp.multilevel, qp.dim, qp.free_dofs,
                  smoother=o.get("smoother", DEFAULT_SMOOTHER), sweeps=o["sweeps"],
                  max_coarse=o.get("max_coarse", 0),
                  smoothing=o.get("smoothing", "local"), min_growth=o.get("min_growth", 1.0))


def scaled_vcycle(A: sp.spmatrix, kind: str, multilevel: Multilevel | None, dim: int,
                  free_dofs: np.ndarray | None, *, smoother: str = DEFAULT_SMOOTHER, sweeps: int,
                  lanczos_steps: int, max_coarse: int = 0, seed: int = 0,
                  degree: int = 1, gamma_target: float = 2.0, smoothing: str = "local",
                  min_growth: float = 1.0, near_kernel: np.ndarray | None = None
                  ) -> ScaledVCycle:
    """Build ``A-hat`` (:func:`vcycle`) and scale it by Lanczos so that (8.18) holds.

    Parameters
    ----------
    kind, multilevel, smoother, sweeps, max_coarse, smoothing, min_growth
        As :func:`vcycle`.
    lanczos_steps : int
        Steps of preconditioned Lanczos for ``lambda(A-hat^{-1} A)``.
    degree : int
        ``A-hat^{-1}`` as a Chebyshev polynomial of this degree in the V-cycle
        (:func:`chebyshev_vcycle`; 1 = the V-cycle itself); 0 = the smallest degree
        that brings the Ritz ratio of the V-cycle's ``lambda(V A)`` to at most
        ``gamma_target`` (:func:`chebyshev_degree`). A V-cycle loses its spectral
        equivalence with ``A`` as the material locks (``nu -> 1/2``: ``kappa(V A)`` grows
        without bound, independent of h; the hard-cases study's page): the polynomial
        restores a
        bounded ``gamma_bar`` at ``~sqrt(kappa)`` V-cycles per application.
    near_kernel : (n, k) array, optional
        Orthonormal floating modes (:func:`problems.floating.floating_modes`): the
        operator acts on their orthogonal complement (FETI's natural coarse space;
        the augmented projection treats the modes in the multiplier space).

    The defaults of these options are declared once, in :data:`AHAT_SCALED`.

    Returns
    -------
    ScaledVCycle
        With ``gamma_low = LOW_SAFETY * ritz_min`` and
        ``gamma_high = HIGH_SAFETY * ritz_max`` of the final operator.
    """
    vc = vcycle(A, kind, multilevel, dim, free_dofs, smoother=smoother, sweeps=sweeps,
                max_coarse=max_coarse, smoothing=smoothing, min_growth=min_growth)
    apply_A = lambda x: A @ x                                     # noqa: E731
    if near_kernel is not None and near_kernel.shape[1]:
        R = np.asarray(near_kernel, dtype=float)
        vc.complement = lambda x: x - R @ (R.T @ x)
        apply_A = lambda x: vc.complement(A @ vc.complement(x))   # noqa: E731
    t0 = time.perf_counter()
    lo, hi = lanczos_extremes(apply_A, A.shape[0], lanczos_steps, vc.vcycle_once, seed,
                              project=vc.complement)
    vc.ritz_vcycle = (lo, hi)
    vc.degree = chebyshev_degree(lo, hi, gamma_target) if degree == 0 else int(degree)
    # the interval: lambda_max of a symmetric V-cycle is <= 1 in theory; the Ritz value
    # under-estimates it, so take the larger with a margin (a larger upper end keeps the
    # polynomial positive; eigenvalues below the lower end are damped less)
    top = HIGH_SAFETY * max(hi, 1.0)
    passes = CHEBYSHEV_PASSES if degree == 0 else 1
    measured = None         # the Ritz values of the polynomial built last
    for k in range(passes):
        if vc.degree <= 1:
            break
        vc.polynomial = chebyshev_vcycle(apply_A, vc.vcycle_once, lo, top, vc.degree)
        measured = lanczos_extremes(apply_A, A.shape[0], lanczos_steps, vc.raw, seed,
                                    project=vc.complement)
        lo_p, hi_p = measured
        if degree or hi_p / lo_p <= gamma_target or k == passes - 1:
            break
        # Ritz values over-estimate lambda_min(V A) when kappa is large: read the smallest
        # eigenvalue off the polynomial's measured lambda_min (1 - lambda p(lambda) =
        # T_d((theta - lambda) / delta) / T_d(sigma) below the interval) and choose again
        lam = _below_interval(lo, top, vc.degree, lo_p)
        if not lam < lo:
            break
        lo = lam
        vc.ritz_vcycle = (lo, vc.ritz_vcycle[1])
        vc.degree = max(chebyshev_degree(lo, top, gamma_target), vc.degree + 1)
    if measured is not None:
        lo, hi = measured
    vc.lanczos_time = time.perf_counter() - t0
    vc.ritz = (lo, hi)
    vc.gamma_low, vc.gamma_high = LOW_SAFETY * lo, HIGH_SAFETY * hi
    return vc


# ---------------------------------------------------------------------------
# The V-cycle as a solver option (declared once)
# ---------------------------------------------------------------------------
_LANCZOS = Parameter("lanczos_steps", 12, "Lanczos steps for the spectral bounds", low=5, kind=int)
_SMOOTHER = Parameter("smoother", DEFAULT_SMOOTHER, "V-cycle smoother", choices=tuple(SMOOTHERS))
_SWEEPS = Parameter("sweeps", 1, "pre- and post-smoothing steps: V(sweeps, sweeps)", low=1,
                    high=10, kind=int)
_MAX_COARSE = Parameter("max_coarse", 500, "SA: largest coarsest level", low=10, kind=int)
_SMOOTHING = Parameter("smoothing", "local", "gmg: smooth on each level only the unknowns it "
                       "added and their neighbours (local: O(N) work per V-cycle on adaptive "
                       "hierarchies; the same cycle on uniform ones) or every unknown (full)",
                       choices=SMOOTHING)
_MIN_GROWTH = Parameter("min_growth", 3.0, "gmg: keep a refinement level only if the next "
                        "finer kept level has at least this factor more unknowns (products "
                        "of the prolongations in between, and an exact solve where a kept level "
                        "refined a region more than once; sizes sum to <= 1.5 N at 3, so a "
                        "V-cycle is O(N) on graded sequences of many small steps; uniform "
                        "refinement, x4 per level in 2D, keeps every level); 1 = every level",
                        low=1.0)

#: ``A-hat``: the kind of V-cycle and its settings, per kind.
AHAT = ComponentParameter(
    "ahat", "auto", {"auto": (_SMOOTHER, _SWEEPS, _SMOOTHING, _MIN_GROWTH, _MAX_COARSE,
                              _LANCZOS),
                     "gmg": (_SMOOTHER, _SWEEPS, _SMOOTHING, _MIN_GROWTH, _LANCZOS),
                     "layers": (_SWEEPS, _LANCZOS),
                     "sa": (_SMOOTHER, _SWEEPS, _MAX_COARSE, _LANCZOS)},
    "A-hat (8.18): one symmetric V-cycle of geometric MG on the refinement hierarchy "
    "(gmg), of semicoarsening along an extruded mesh's axis with zebra plane smoothing "
    "(layers; the smoother is fixed), or pyamg SA with rigid-body modes (sa), scaled by "
    "Lanczos (Remark 8.14) where a solver needs spectral bounds; auto = gmg if the problem "
    "has a hierarchy, layers if it is extruded, else sa")


_DEGREE = Parameter("degree", 0, "A-hat^-1 as a Chebyshev polynomial of this degree in the "
                    "V-cycle (1 = the V-cycle); 0 = auto: the smallest degree that brings "
                    "kappa(A-hat^-1 A) to gamma_target (more V-cycles as nu -> 1/2)", low=0,
                    high=200, kind=int)
_GAMMA_TARGET = Parameter("gamma_target", 2.5, "kappa(A-hat^-1 A) the automatic degree aims at",
                          low=1.0, low_open=True)

#: ``A-hat`` of the augmented projection (8.18): :data:`AHAT` plus the polynomial
#: acceleration that keeps ``gamma_bar`` bounded towards incompressibility.
AHAT_SCALED = ComponentParameter(
    "ahat", "auto", {k: opts + (_DEGREE, _GAMMA_TARGET) for k, opts in AHAT.kinds.items()},
    AHAT.help + "; a Chebyshev polynomial in the V-cycle of the given degree (0 = chosen "
    "from the measured kappa(V A), i.e. from the material)")


def ahat_component(kind: str = "auto", **options) -> Component:
    """The :data:`AHAT` component of ``kind`` with its defaults (``options`` override)."""
    given = {"ahat": kind, **{f"ahat.{k}": v for k, v in options.items()}}
    return resolve_parameters((AHAT,), given, "A-hat").ahat
