"""The adaptive loop of thesis Sect. 7.4: solve -> estimate -> mark -> refine.

A pure driver (:func:`adaptive_loop`) over any two-body scene: each step
assembles the ContactQP of the finest level of the bodies' nested meshes
(:func:`problems.fem.two_body.assemble_two_body`, so constraints, masses and
the multilevel data incl. the constrained-surface hierarchy come as on a
uniform hierarchy), solves it by a callback started from the previous step's
solution (Alg. 8.5, :func:`prolongate_solution`), evaluates the element
estimators (:mod:`problems.fem.estimators`), marks (:func:`mark_equidistribution`
or :func:`mark_doerfler`) and bisects the marked cells of both bodies
(:func:`problems.fem.bisection.grow`), so every body's :class:`Hierarchy`
grows by one level per step.

Marking, Sect. 7.4: the thesis aims at ``sum_T eta_T^2 <= TOL`` with the error
equidistributed, ``eta_T^2 ~ TOL / |tau_h|``, and prints "refine T if
``eta_T^2 <= TOL / |tau_h|``". Refining the elements whose error is already
below the equidistributed share would refine the wrong ones (and, with a
small TOL, everything); the sentence before it says the refinement aims at
equidistribution, so we read it as: refine T if ``eta_T^2 >= TOL / |tau_h|``.

Pure functions: no files, no printing, no clocks.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np
import scipy.sparse as sp

from problems.fem.bisection import grow, label_longest_edge
from problems.fem.estimators import VARIANTS, estimate
from problems.fem.mesh import Hierarchy
from problems.fem.two_body import TwoBodyScene, assemble_two_body
from problems.kkt import kkt_residuals
from problems.qp import ContactQP, prolongate_displacement


#: The adaptive study's variants (Sects. 7.4, 7.5): ``name -> (estimator, discretisation)``.
#: ``"nodal"`` is the scene's own ContactQP (the nodal constraints of Alg. 7.1);
#: ``"stabilised"`` the stabilised two-sided formulation (7.10)/(7.11)
#: (:func:`problems.fem.stabilised.stabilise`), marked by eta_1 as in Fig. 7.5.
STUDY_VARIANTS = {"eta1": ("eta1", "nodal"), "eta1+eta2": ("eta1+eta2", "nodal"),
                  "stabilised": ("eta1", "stabilised")}


# --------------------------------------------------------------------------- marking
def _check_eta(eta_sq) -> np.ndarray:
    e = np.asarray(eta_sq, dtype=float)
    if e.ndim != 1 or not np.all(np.isfinite(e)) or np.any(e < 0):
        raise ValueError("parameter 'eta_sq': allowed: a 1-D array of finite numbers >= 0")
    return e


def mark_equidistribution(eta_sq, tol: float) -> np.ndarray:
    """Sect. 7.4: refine T if ``eta_T^2 >= TOL / |tau_h|`` (see the module docstring
    for why ``>=``). Returns a bool mask."""
    e = _check_eta(eta_sq)
    if not (np.isfinite(tol) and tol > 0):
        raise ValueError(f"parameter 'tol': {tol!r} is not allowed; allowed: a number in (0, inf)")
    return e >= tol / len(e)


def mark_doerfler(eta_sq, theta: float = 0.5, min_fraction: float = 0.0) -> np.ndarray:
    """Doerfler's bulk criterion: the smallest set M (largest errors first) with
    ``sum_{T in M} eta_T^2 >= theta sum_T eta_T^2``, and at least ``min_fraction`` of the
    cells (the largest errors). Returns a bool mask.

    Once a few cells at singular points (clamped corners, the ends of a held arc) carry
    a ``theta`` share of the estimate, the bulk set alone is a handful of cells and
    every step adds a few hundred nodes (circle-square's adaptive runs): a minimum
    share keeps the growth per step geometric, so a run reaches the thesis's node
    counts in tens of steps instead of hundreds (and a multigrid hierarchy of as many
    levels)."""
    e = _check_eta(eta_sq)
    if not (0 < theta <= 1):
        raise ValueError(f"parameter 'theta': {theta!r} is not allowed; "
                         "allowed: a number in (0, 1]")
    if not (0 <= min_fraction <= 1):
        raise ValueError(f"parameter 'min_fraction': {min_fraction!r} is not allowed; "
                         "allowed: a number in [0, 1]")
    out = np.zeros(len(e), dtype=bool)
    total = e.sum()
    if total <= 0:
        return out
    order = np.argsort(-e, kind="stable")
    k = int(np.searchsorted(np.cumsum(e[order]), theta * total * (1 - 1e-12))) + 1
    k = max(k, int(np.ceil(min_fraction * len(e))))
    out[order[:min(k, len(e))]] = True
    return out


# --------------------------------------------------------------------------- scenes
def truncated(h: Hierarchy, level: int) -> Hierarchy:
    """Levels ``0..level`` of ``h``."""
    if not 0 <= level < len(h.points):
        raise ValueError(f"parameter 'level': {level!r} is not allowed; "
                         f"allowed: 0..{len(h.points) - 1}")
    return Hierarchy(list(h.points[:level + 1]), list(h.cells[:level + 1]),
                     list(h.prolongations[:level]))


def with_meshes(scene: TwoBodyScene, meshes) -> TwoBodyScene:
    """``scene`` with each body's nested meshes replaced (material, supports, loads kept)."""
    if len(meshes) != len(scene.bodies):
        raise ValueError(f"parameter 'meshes': {len(meshes)} hierarchies for "
                         f"{len(scene.bodies)} bodies")
    return replace(scene, bodies=tuple(replace(b, meshes=m) for b, m in zip(scene.bodies, meshes)))


def adaptive_start(scene: TwoBodyScene, level: int):
    """Each body's uniform levels ``0..level`` as the start of an adaptive hierarchy.

    In 2D the finest level's triangles are relabelled for newest-vertex
    bisection (:func:`problems.fem.bisection.label_longest_edge`: a cyclic
    rotation per cell, same mesh). Returns ``(make_scene, meshes)`` with
    ``make_scene(meshes) = with_meshes(scene, meshes)``.
    """
    meshes = []
    for b in scene.bodies:
        h = truncated(b.meshes, level)
        if h.points[-1].shape[1] == 2:
            h.cells[-1] = label_longest_edge(h.points[-1], h.cells[-1])
        meshes.append(h)
    return (lambda m: with_meshes(scene, m)), tuple(meshes)


def body_force_per_cell(scene: TwoBodyScene, qp: ContactQP) -> np.ndarray:
    """The bodies' force densities on the stacked cells of ``qp.mesh``."""
    force = np.array([b.body_force for b in scene.bodies], dtype=float)
    return force[qp.mesh.body_of_node[qp.mesh.cells[:, 0]]]


# --------------------------------------------------------------------------- nested start
def prolongate_solution(qp_coarse: ContactQP, u: np.ndarray, p: np.ndarray, qp_fine: ContactQP,
                        node_prolongation: sp.spmatrix | None = None):
    """Initial guess on the next level from ``(u, p)`` (Alg. 8.5, Sect. 8.6).

    ``p0 = M_L P_s (M_{L-1}^{-1} p)``: the pressure (multiplier over lumped
    contact mass) prolongated with the surface prolongation and multiplied by
    the new contact mass, clipped at 0. With the stabilisation of Sect. 7.5 the
    reverse rows' pressure ``p_r / m_r`` lives on the opposing surface's nodes and
    is prolongated as a nodal field (:func:`_reverse_pressure`): the reverse rows
    carry most of the load there, and the
    split between the two sets of rows is the stabilised problem's slowest direction.
    ``u0`` is the P1 prolongation of the full nodal displacement (prescribed values
    included) restricted to the free DOFs: by ``node_prolongation`` (stacked
    nodal P, fine x coarse nodes) when given, else on uniform levels by
    :func:`problems.qp.prolongate_displacement` (``P u + P_D u_fixed``).
    """
    ml = qp_fine.multilevel
    if not ml.prolongations or ml.surface is None:
        raise ValueError("parameter 'qp_fine': multilevel.prolongations and .surface are required")
    if (qp_coarse.stabilisation is None) != (qp_fine.stabilisation is None):
        raise ValueError("parameter 'qp_fine': both levels nodal or both stabilised are required")
    mc_c, mc_f = qp_coarse.m_contact, qp_fine.m_contact
    P_s = ml.surface.prolongations[-1]
    if P_s.shape != (mc_f, mc_c):
        raise ValueError(f"surface prolongation has shape {P_s.shape}, expected "
                         f"{(mc_f, mc_c)}: not consecutive levels of one scene")
    pressure = p[:mc_c] / qp_coarse.contact.mass
    p0 = np.maximum(P_s @ pressure, 0.0) * qp_fine.contact.mass
    if node_prolongation is None:
        u0 = prolongate_displacement(qp_coarse, u, qp_fine)
    else:
        u0 = (node_prolongation @ qp_coarse.full_displacement(u)).ravel()[qp_fine.free_dofs]
    if qp_fine.stabilisation is not None:
        p0 = np.concatenate([p0, _reverse_pressure(qp_coarse, p[mc_c:], qp_fine,
                                                   node_prolongation)])
    return u0, p0


def _reverse_pressure(qp_coarse: ContactQP, p_r: np.ndarray, qp_fine: ContactQP,
                      node_prolongation: sp.spmatrix | None) -> np.ndarray:
    """The reverse rows' pressure ``p_r / m_r`` on the coarse opposing nodes carried to
    the fine ones by the nodal prolongation, or, on uniform levels, as the normal
    component of a displacement-like field by ``P`` (the opposing surface is nested with
    its body; the normal is a component no symmetry plane fixes); times the fine lumped
    masses, clipped at 0."""
    st_c, st_f = qp_coarse.stabilisation, qp_fine.stabilisation
    if node_prolongation is not None:
        coarse = np.zeros(qp_coarse.n_nodes)
        coarse[st_c.nodes] = p_r / st_c.mass
        fine = node_prolongation @ coarse
        return np.maximum(fine[st_f.nodes], 0.0) * st_f.mass
    comp = int(np.argmax(np.abs(qp_fine.contact.direction.mean(axis=0))))
    coarse = np.zeros(qp_coarse.n_nodes * qp_coarse.dim)
    coarse[st_c.nodes * qp_coarse.dim + comp] = p_r / st_c.mass
    fine = np.zeros(qp_fine.n_nodes * qp_fine.dim)
    fine[qp_fine.free_dofs] = qp_fine.multilevel.prolongations[-1] @ coarse[qp_coarse.free_dofs]
    return np.maximum(fine[st_f.nodes * qp_fine.dim + comp], 0.0) * st_f.mass


# --------------------------------------------------------------------------- the loop
@dataclass
class StepRecord:
    """One step of the adaptive loop.

    ``N`` nodes, ``NC`` constraints (N^C), ``n_cells``, ``sum_eta2`` the sum
    of ``eta_T^2``, ``max_eta`` the largest ``eta_T`` (Fig. 9.2 plots it),
    ``n_marked`` cells marked for the next step (0 on the last), ``kkt_max``
    the verified KKT residual of the solution, ``iterations`` of the solver,
    ``eta2_weight`` the constant in front of ``eta_T2^2`` at this step.
    """

    step: int
    level: int
    N: int
    NC: int
    n_cells: int
    sum_eta2: float
    max_eta: float
    n_marked: int
    kkt_max: float
    iterations: int = -1
    eta2_weight: float = float("nan")


@dataclass
class AdaptiveRun:
    """What :func:`adaptive_loop` returns: per step the ContactQP, ``(u, p)``, the
    estimate (dict of per-cell arrays), the marked cells (stacked numbering),
    the solver's own result, the record; the final meshes and why it stopped."""

    qps: list = field(default_factory=list)
    solutions: list = field(default_factory=list)
    estimates: list = field(default_factory=list)
    marked: list = field(default_factory=list)
    results: list = field(default_factory=list)
    records: list = field(default_factory=list)
    meshes: tuple = ()
    stop_reason: str = ""


#: ``solve(qp, u0, p0) -> SolveResult-like (with .u, .p) or (u, p)``; u0, p0 None on the first step.
SolveCallback = Callable[[ContactQP, "np.ndarray | None", "np.ndarray | None"], object]


def adaptive_loop(make_scene: Callable, meshes, solve: SolveCallback, *,
                  estimator: str = "eta1+eta2", marking: Callable | None = None,
                  tol: float | None = None, max_nodes: int | None = None, max_steps: int = 5,
                  project=None, rule: str | None = None,
                  eta2_weight: float | Callable[[int, dict], float] = 1.0,
                  nested: bool = True, discretise: Callable | None = None,
                  name: str = "adaptive") -> AdaptiveRun:
    """Sect. 7.4's loop: solve, estimate, mark, refine, until a stopping rule holds.

    Parameters
    ----------
    make_scene : callable
        ``make_scene(meshes) -> TwoBodyScene`` with the bodies' meshes replaced
        (e.g. from :func:`adaptive_start`).
    meshes : tuple of Hierarchy
        One per body, equally many levels; the finest is the first to be solved.
    solve : callable
        ``solve(qp, u0, p0)`` (see :data:`SolveCallback`).
    estimator : {"eta1", "eta1+eta2"}
    marking : callable, optional
        ``marking(eta_sq) -> bool mask``; default Doerfler with theta = 0.5.
    tol : float, optional
        Stop when ``sum_T eta_T^2 <= tol``.
    max_nodes : int, optional
        Node budget: stop once ``N >= max_nodes`` (after solving that mesh).
    max_steps : int
        Refinements at most (``max_steps + 1`` solves).
    project : sequence of callables or None, optional
        Per body, ``project(points, is_boundary)`` for new boundary nodes
        (curved boundaries), or None.
    rule : str, optional
        Bisection rule (default per dimension,
        :func:`problems.fem.bisection.default_rule`).
    eta2_weight : float or callable
        Constant in front of ``eta_T2^2``, or ``eta2_weight(step, estimate) -> float``
        with the step's unweighted parts (``eta1_sq``, ``eta2_sq``): a constant
        chosen from the run itself (e.g. calibrated on the start mesh).
    nested : bool
        Start each solve from the previous solution (Alg. 8.5); else from zero.
    discretise : callable, optional
        ``discretise(qp) -> ContactQP`` applied to each step's nodal ContactQP before
        it is solved, e.g. the stabilisation of Sect. 7.5
        (``lambda qp: stabilise(qp, alpha)``); the estimators see the same mesh.

    Returns
    -------
    AdaptiveRun
    """
    if estimator not in VARIANTS:
        raise ValueError(f"parameter 'estimator': {estimator!r} is not allowed; "
                         f"allowed: {', '.join(VARIANTS)}")
    if not (isinstance(max_steps, (int, np.integer)) and max_steps >= 0):
        raise ValueError(f"parameter 'max_steps': {max_steps!r} is not allowed; "
                         "allowed: an integer >= 0")
    meshes = tuple(meshes)
    n_levels = {len(h.points) for h in meshes}
    if len(n_levels) != 1:
        raise ValueError("parameter 'meshes': the bodies' hierarchies must have equally many "
                         "levels")
    project = tuple(project) if project is not None else (None,) * len(meshes)
    if len(project) != len(meshes):
        raise ValueError(f"parameter 'project': {len(project)} callbacks for {len(meshes)} bodies")
    marking = marking or (lambda e: mark_doerfler(e, 0.5))
    run = AdaptiveRun()
    prev = None
    for step in range(max_steps + 1):
        level = len(meshes[0].points) - 1
        scene = make_scene(meshes)
        qp = assemble_two_body(scene, level, name=f"{name} step {step}")
        if discretise is not None:
            qp = discretise(qp)
        u0 = p0 = None
        if nested and prev is not None:
            node_P = sp.block_diag([h.prolongations[-1] for h in meshes], format="csr")
            u0, p0 = prolongate_solution(prev[0], prev[1], prev[2], qp, node_P)
        res = solve(qp, u0, p0)
        u, p = (res.u, res.p) if hasattr(res, "u") else res
        est = estimate(qp, u, estimator, body_force=body_force_per_cell(scene, qp),
                       tractions=scene.tractions, direction=scene.direction, eta2_weight=0.0)
        weight = float(eta2_weight(step, est) if callable(eta2_weight) else eta2_weight)
        if not weight >= 0:
            raise ValueError(f"parameter 'eta2_weight': {weight!r} is not allowed; "
                             "allowed: a number >= 0")
        est["eta2"] = est["eta1_sq"] + weight * est["eta2_sq"]
        eta_sq = est["eta2"]
        total = float(eta_sq.sum())
        reason = ""
        if tol is not None and total <= tol:
            reason = "tol"
        elif max_nodes is not None and qp.n_nodes >= max_nodes:
            reason = "max_nodes"
        elif step == max_steps:
            reason = "max_steps"
        marked = np.zeros(len(eta_sq), dtype=bool) if reason else np.asarray(marking(eta_sq))
        if run.qps:      # a finished step's factorisations and solvers are not used again
            run.qps[-1].cache = type(qp.cache)()
        run.qps.append(qp)
        run.solutions.append((u, p))
        run.estimates.append(est)
        run.marked.append(np.flatnonzero(marked))
        run.results.append(res)
        run.records.append(StepRecord(
            step=step, level=level, N=qp.n_nodes, NC=qp.m_contact, n_cells=len(qp.mesh.cells),
            sum_eta2=total, max_eta=float(np.sqrt(eta_sq.max())), n_marked=int(marked.sum()),
            kkt_max=kkt_residuals(qp, u, p).max, iterations=int(getattr(res, "iterations", -1)),
            eta2_weight=weight))
        if reason:
            run.stop_reason = reason
            break
        offsets = np.cumsum([0] + [len(h.cells[-1]) for h in meshes])
        meshes = tuple(grow(h, marked[a:b], pr, rule)
                       for h, a, b, pr in zip(meshes, offsets[:-1], offsets[1:], project))
        prev = (qp, u, p)
    run.meshes = meshes
    return run
