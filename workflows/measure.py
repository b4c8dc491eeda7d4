"""Measurement helpers at the edges: peak memory of a block of code (and returning what a
phase freed), and the linear floor.

The floor of a contact solve (DESIGN.md, performance conventions) is one linear
solve of the same elasticity system without contact, to the same energy
accuracy, timed in the same process: :func:`amg_pcg_floor` (geometric-multigrid
PCG on the refinement hierarchy, or pyamg SA-PCG as the black-box alternative)
against :func:`linear_solution`.
"""
from __future__ import annotations

import threading
import time
import tracemalloc
from contextlib import contextmanager
from typing import Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from problems.kkt import energy_error
from problems.qp import prolongate_displacement
from solvers.kernels import multigrid as pc
from solvers import tnnmg
from solvers.interface import linear_solver, verify

#: Nested iteration's stop on a coarse level (:func:`tnnmg_run`; KKT residuals, no
#: certificate): its solution only starts the next level, so it needs to be accurate to
#: well below the coarse level's discretisation error (a few per cent in energy at the
#: quick levels), no more.
NESTED_TOL = 1e-3


def return_freed_memory() -> None:
    """Free what only reference cycles still hold (a solver's closures and results keep
    arrays of the size of the problem until Python's occasional full collection) and
    hand the freed heap back to the system (glibc's ``malloc_trim``; elsewhere the
    collection only): called between the phases of a large study, so that its peak
    resident memory is that of one phase, not of the phases' leftovers. Changes no
    number."""
    import ctypes
    import gc

    gc.collect()
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):         # not glibc: the collection alone
        pass


@contextmanager
def peak_rss(interval: float = 0.005):
    """Sample the process's resident memory in a thread; yields a dict whose
    ``peak_mb`` is the peak increase over the start (MB) once the block exits.
    Sampling can miss spikes shorter than ``interval``."""
    import psutil

    proc = psutil.Process()
    base = proc.memory_info().rss
    out = {"peak_mb": 0.0}
    stop = threading.Event()

    def sample():
        peak = base
        while not stop.is_set():
            peak = max(peak, proc.memory_info().rss)
            stop.wait(interval)
        out["peak_mb"] = (max(peak, proc.memory_info().rss) - base) / 2 ** 20

    thread = threading.Thread(target=sample, daemon=True)
    thread.start()
    try:
        yield out
    finally:
        stop.set()
        thread.join()


def _gmg_vcycle(qp):
    """The augmented projection's geometric-multigrid V-cycle with its default smoother,
    unscaled: a PCG solve needs no spectral bounds, so none are timed."""
    return pc.component_vcycle(qp, pc.ahat_component("gmg"))


def linear_solution(qp, rtol: float = 1e-13, max_iter: int = 2000) -> np.ndarray:
    """``A^{-1} f`` (no contact) by geometric-multigrid PCG to a relative residual of
    ``rtol`` (untimed; the yardstick of the floor, scalable to 3D where a direct
    factorisation is not)."""
    vc = _gmg_vcycle(qp)
    M = spla.LinearOperator(qp.A.shape, matvec=vc.raw)
    u, info = spla.cg(qp.A, qp.f, M=M, rtol=rtol, atol=0.0, maxiter=max_iter)
    if info != 0:
        raise RuntimeError(f"multigrid PCG for the linear solution did not reach {rtol:g}")
    return u


def traced_peak_mb(run: Callable[[], object]) -> float:
    """Peak of the memory ``run()`` allocates beyond what was held before it, in MB, by
    :mod:`tracemalloc` (numpy and scipy arrays are traced; a run is slower under it, so
    never time one). An untimed repeat of a timed run measures its memory."""
    was_tracing = tracemalloc.is_tracing()
    if not was_tracing:
        tracemalloc.start()
    tracemalloc.reset_peak()
    before = tracemalloc.get_traced_memory()[0]
    try:
        run()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        if not was_tracing:
            tracemalloc.stop()
    return (peak - before) / 1e6


def input_mb(qp) -> float:
    """MB of what every solver of ``qp`` holds before it starts: ``A`` and the refinement
    hierarchy's prolongations (the base of a peak-memory ratio)."""
    mats = [qp.A, *qp.multilevel.prolongations]
    return sum(sum(a.nbytes for a in (M.data, M.indices, M.indptr))
               for M in (sp.csr_matrix(M) for M in mats)) / 1e6


def median_run(run: Callable[[], dict], repeats: int, key: str = "t_to_target") -> dict:
    """``run()`` ``repeats`` times; the run whose ``key`` is the median (the lower middle
    for an even count), with the spread of ``key`` over the repeats
    (``<key>_min``, ``<key>_max``) and ``timing_repeats``.

    A timed solve is deterministic in its steps, not in its time: a claim judged on one
    sub-second run flips with the machine's noise, the median of a few does not. A run
    without a finite ``key`` (not reached, skipped) is returned at once, unrepeated."""
    return interleaved_median_runs({"run": run}, repeats, key)["run"]


def interleaved_median_runs(runs: dict[str, Callable[[], dict]], repeats: int,
                            key: str = "t_to_target") -> dict[str, dict]:
    """Each of ``runs`` ``repeats`` times in rounds, one run of each per round, and per
    name the row :func:`median_run` keeps. Timings compared as a ratio are taken this way:
    a drift of the machine's speed during the measurement (a shared host's neighbours,
    its clock) then meets every run alike instead of one run's repeats. A run without a
    finite ``key`` in the first round (not reached, skipped) is not repeated."""
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats}")
    rows: dict[str, list] = {name: [] for name in runs}
    for round_ in range(repeats):
        for name, run in runs.items():
            if round_ and not np.isfinite(rows[name][0].get(key, np.nan)):
                continue
            rows[name].append(run())
    return {name: _median_row(r, key) for name, r in rows.items()}


def _median_row(runs: list[dict], key: str) -> dict:
    if not np.isfinite(runs[0].get(key, np.nan)):
        return {**runs[0], "timing_repeats": 1}
    values = np.array([r.get(key, np.nan) for r in runs], dtype=float)
    order = np.argsort(values)                  # NaN last
    middle = runs[int(order[(len(runs) - 1) // 2])]
    return {**middle, f"{key}_min": float(np.nanmin(values)),
            f"{key}_max": float(np.nanmax(values)), "timing_repeats": len(runs)}


def amg_pcg_floor(qp, kind: str, target: float, u_exact: np.ndarray,
                  max_iter: int = 500) -> dict:
    """PCG for ``A u = f`` (no contact) with one V-cycle, to energy error ``target``
    against ``u_exact`` (:func:`linear_solution`), timed with its setup."""
    norm = np.sqrt(u_exact @ (qp.A @ u_exact))
    t0, cpu0 = time.perf_counter(), time.process_time()
    if kind == "sa":  # pyamg defaults + rigid-body modes, node blocks
        ml = pc.sa_hierarchy(qp.A, qp.multilevel.rigid_body_modes, qp.dim, qp.free_dofs,
                             smoother="block_gs", sweeps=1, max_coarse=500)
        M = ml.aspreconditioner(cycle="V")
    else:
        vc = _gmg_vcycle(qp)
        M = spla.LinearOperator(qp.A.shape, matvec=vc.raw)
    t_setup = time.perf_counter() - t0
    rec = {"t": [], "err": [], "overhead": 0.0, "cpu": [], "cpu_overhead": 0.0}
    t_start = time.perf_counter()

    def cb(x):
        t1, c1 = time.perf_counter(), time.process_time()
        e = x - u_exact
        rec["err"].append(np.sqrt(max(e @ (qp.A @ e), 0.0)) / norm)
        rec["overhead"] += time.perf_counter() - t1
        rec["cpu_overhead"] += time.process_time() - c1
        rec["t"].append(time.perf_counter() - t_start - rec["overhead"])
        rec["cpu"].append(time.process_time() - cpu0 - rec["cpu_overhead"])
        if rec["err"][-1] <= target:
            raise StopIteration

    try:
        spla.cg(qp.A, qp.f, M=M, rtol=1e-14, atol=0.0, maxiter=max_iter, callback=cb)
    except StopIteration:
        pass
    ok = rec["err"] and rec["err"][-1] <= target
    return {"n": qp.n, "n_outer": len(rec["err"]), "t_setup": t_setup,
            "t_solve": rec["t"][-1] if rec["t"] else np.nan,
            "t_to_target": t_setup + rec["t"][-1] if ok else np.nan,
            "n_to_target": len(rec["err"]) if ok else -1,
            "cpu_total": rec["cpu"][-1] if rec["cpu"] else np.nan,
            "cpu_to_target": rec["cpu"][-1] if ok else np.nan,
            "energy_error": rec["err"][-1] if rec["err"] else np.nan,
            "status": "converged" if ok else "max_iter"}


def stream_triad_gbs(entries: int, repeats: int = 10) -> float:
    """One core's memory bandwidth in GB/s by the STREAM triad ``a = b + s c`` (a compiled
    loop, one thread) on three arrays of ``entries`` each (far beyond the caches, or it
    measures a cache level): 24 bytes per entry (STREAM's count, without write-allocate),
    the best of ``repeats`` passes after one untimed pass, as STREAM reports it."""
    if entries < 1 or repeats < 1:
        raise ValueError(f"entries and repeats must be >= 1, got {entries} and {repeats}")
    from numba import njit

    @njit(cache=False)
    def triad(a, b, c, s):
        for i in range(a.size):
            a[i] = b[i] + s * c[i]

    a, b, c = np.zeros(entries), np.ones(entries), np.full(entries, 2.0)
    triad(a, b, c, 3.0)                         # compiled and every page touched
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        triad(a, b, c, 3.0)
        best = min(best, time.perf_counter() - t0)
    return 3 * a.itemsize * entries / best / 1e9


def floor_traffic(qp, repeats: int, cg_steps: int = 20, seed: int = 0) -> dict:
    """The floor's bytes against its time: one V-cycle of :func:`amg_pcg_floor`'s
    geometric multigrid and one of its PCG steps, each timed as the median of ``repeats``
    (a V-cycle on a seeded random right-hand side; ``cg_steps`` PCG steps from zero,
    divided by their number), and the bytes each must move by the STREAM convention
    (:func:`solvers.kernels.multigrid.vcycle_traffic`, ``cg_step_traffic``).

    Returns the row's bytes (split into matrix values, index arrays and vectors), median
    times with their spread (``_min``, ``_max``) and attained bandwidths in GB/s."""
    if repeats < 1 or cg_steps < 1:
        raise ValueError(f"repeats and cg_steps must be >= 1, got {repeats} and {cg_steps}")
    ahat = pc.ahat_component("gmg")
    smoother = ahat.options.get("smoother", pc.DEFAULT_SMOOTHER)
    vc = _gmg_vcycle(qp)
    vcycle = pc.vcycle_traffic(vc.ml, smoother, ahat.options["sweeps"])
    step = pc.cg_step_traffic(qp.A) + vcycle
    M = spla.LinearOperator(qp.A.shape, matvec=vc.vcycle_once)
    r = np.random.default_rng(seed).standard_normal(qp.n)
    vc.vcycle_once(r)                                   # untimed: first touch
    t_vcycle, t_step = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        vc.vcycle_once(r)
        t_vcycle.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        spla.cg(qp.A, qp.f, M=M, rtol=0.0, atol=0.0, maxiter=cg_steps)   # no early stop
        t_step.append((time.perf_counter() - t0) / cg_steps)
    t_v, t_s = float(np.median(t_vcycle)), float(np.median(t_step))
    return {"n": qp.n, "nnz_A": int(qp.A.nnz), "mg_levels": len(vc.ml.levels),
            "operator_complexity": vc.operator_complexity(),
            "vcycle_mb": vcycle.total / 1e6, "vcycle_values_mb": vcycle.values / 1e6,
            "vcycle_indices_mb": vcycle.indices / 1e6,
            "vcycle_vectors_mb": vcycle.vectors / 1e6,
            "t_vcycle": t_v, "t_vcycle_min": min(t_vcycle), "t_vcycle_max": max(t_vcycle),
            "vcycle_gbs": vcycle.total / t_v / 1e9,
            "cg_step_mb": step.total / 1e6, "t_cg_step": t_s, "t_cg_step_min": min(t_step),
            "t_cg_step_max": max(t_step), "cg_step_gbs": step.total / t_s / 1e9,
            "timing_repeats": repeats,
            "cg_steps": cg_steps}


#: Relative residual of the multigrid PCG in :func:`dual_norm` (where ``A`` is not
#: factorised): the norm's relative error is below ``kappa(A) DUAL_NORM_RTOL^2 / 2``
#: (:func:`dual_norm`), under 1e-8 up to ``kappa(A) = 1e8``.
DUAL_NORM_RTOL = 1e-8


def dual_norm(qp, force: np.ndarray) -> float:
    """``||A^{-1/2} F|| = sqrt(F' A^{-1} F)``: the norm of the nodal force vector ``F`` (on
    ``qp``'s free DOFs) as a functional on the displacements, ``sup_v F'v / ||v||_A``,
    i.e. the energy norm of the displacement it produces, ``w = A^{-1} F``
    (:func:`solvers.interface.linear_solver`: ``A`` factorised once per problem where
    affordable, else multigrid PCG from zero to the relative residual
    :data:`DUAL_NORM_RTOL`). For ``F = B' q`` it is the S-norm of the multipliers ``q``
    (``S = B A^{-1} B'``).

    The norm needs far less than the duality gap's 1e-14: CG from zero minimises the
    energy error over its Krylov space, so its iterate ``w_k`` has
    ``||w||_A^2 = ||w_k||_A^2 + ||w - w_k||_A^2``, and ``||w_k||_A`` is low by the
    relative amount ``||w - w_k||_A^2 / (2 ||w||_A^2) <= kappa(A) rtol^2 / 2``
    (``||w - w_k||_A <= lambda_min^{-1/2} ||r_k||``, ``||w||_A >= lambda_max^{-1/2} ||F||``).
    """
    w = linear_solver(qp)(np.asarray(force, dtype=float), rtol=DUAL_NORM_RTOL)
    return float(np.sqrt(max(w @ (qp.A @ w), 0.0)))


def multiplier_errors(qp, p, p_ref, u_ref) -> dict:
    """Errors of the multipliers against the reference (max norm, S-norm, total force)."""
    top = float(np.max(np.abs(p_ref))) if p_ref.size else 0.0
    dp = np.asarray(p) - p_ref
    s_norm = dual_norm(qp, qp.B.T @ dp)
    norm_u = float(np.sqrt(max(u_ref @ (qp.A @ u_ref), 0.0)))
    force = float(np.sum(p_ref))
    return {"multiplier_error": float(np.max(np.abs(dp))) / top if top > 0
            else float(np.max(np.abs(dp), initial=0.0)),
            "multiplier_error_S": s_norm / norm_u if norm_u > 0 else s_norm,
            "force_error": abs(float(np.sum(p)) - force) / abs(force) if force > 0
            else abs(float(np.sum(p)))}


def tnnmg_run(qp, u_ref, target: float, time_limit: float, coarse=(), start=None) -> dict:
    """Truncated nonsmooth Newton multigrid (:mod:`solvers.tnnmg`), the contact community's
    fastest method: steps and time (setup included) until the energy-norm error reaches
    ``target``, read by a callback whose own cost is subtracted, then on to its verified stop.

    The suite's verification inside the solve (the KKT residuals and the certified bound,
    checked once the step's own residual is near tol; the certificate's first call
    factorises ``A``) is kept out of ``t_to_target`` and reported beside it as
    ``t_verify_to_target``: what it spent before the step that reached the target. The
    floor's time holds no verification either.

    ``coarse``: the scene's coarser problems, coarsest first, for nested iteration from
    the coarsest level: each solved by TNNMG until its KKT residuals meet
    :data:`NESTED_TOL` (no certificate: it only gives the next level's start) and
    prolongated with their prescribed values (``u0 = P u_coarse + P_D u_fixed``,
    :func:`problems.qp.prolongate_displacement`); their time is ``t_coarse_levels``.
    ``start``: the initial guess without ``coarse`` (a load path's previous answer; default zero).
    """
    ok, reason = tnnmg.supports(qp)
    if not ok:          # a row that says why, at once (the stabilised rows, Sect. 7.5)
        return {"status": "skipped", "message": reason}
    t0 = time.perf_counter()
    u0 = start
    chain = list(coarse) + [qp]
    coarse_opts = tnnmg.SOLVER.options(stop="kkt")       # no certificate on a coarse level
    for q_c, q_f in zip(chain[:-1], chain[1:]):
        r_c = tnnmg.solve(q_c, max(target, NESTED_TOL), tnnmg.SOLVER.default_max_iter,
                          time_limit, u0, None, coarse_opts)
        u0 = prolongate_displacement(q_c, r_c.u, q_f)
    t_coarse = time.perf_counter() - t0
    rec = {"err": [], "at": [], "overhead": 0.0}
    norm = np.sqrt(max(float(u_ref @ (qp.A @ u_ref)), 0.0)) if u_ref is not None else np.nan

    def callback(u, p):
        t1 = time.perf_counter()
        rec["at"].append(rec["overhead"])
        e = u - u_ref if u_ref is not None else None
        rec["err"].append(np.sqrt(max(float(e @ (qp.A @ e)), 0.0)) / norm
                          if e is not None else np.nan)
        rec["overhead"] += time.perf_counter() - t1
        return False

    opts = tnnmg.SOLVER.options()
    res = tnnmg.solve(qp, target, tnnmg.SOLVER.default_max_iter, time_limit, u0, None, opts,
                      callback=callback)
    res = verify(qp, res, target)
    err = np.asarray(rec["err"])
    t_hist = np.asarray(res.history["time"]) - np.asarray(rec["at"])
    t_verify = np.asarray(res.history["t_verify"])
    hit = np.flatnonzero(err <= target)
    s = res.stats
    return {"status": res.status, "energy_error": energy_error(qp, res.u, u_ref)
            if u_ref is not None else np.nan, "kkt_max": res.kkt.max,
            "n_outer": res.iterations, "t_setup": res.setup_time,
            "t_solve": float(t_hist[-1]) if t_hist.size else np.nan,
            "n_to_target": int(hit[0]) + 1 if hit.size else -1,
            "t_to_target": (float(res.setup_time + t_hist[hit[0]] - t_verify[hit[0]])
                            if hit.size else np.nan),
            "t_verify_to_target": float(t_verify[hit[0]]) if hit.size else np.nan,
            "t_coarse_levels": t_coarse, "n_vcycles": s["n_vcycles"],
            "truncation_updates": s["truncation_updates"], "message": res.message}
