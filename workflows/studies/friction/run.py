"""Friction on a contact scene (2D or 3D): Tresca partial slip against Cattaneo-Mindlin,
the frictional solvers on the same load paths, mu = 0 against the frictionless reference,
and Coulomb's fixed point.

For one scene (a registered problem with the ``friction``, ``mu`` and ``shift``
parameters, ``--problem P --set key=value``), at each of ``--levels``:

* **the reference path per load ratio** -- Tresca friction with ``mu``; the tangential
  step (the held part moved by ``--shift``) is scaled until ``Q/(mu P)`` of the last step
  is each of ``--ratios`` (:func:`solvers.kernels.tresca.path_for_ratio`). The reference is
  ``tresca_exact`` (exact to round-off) where it takes the problem (its dual is dense:
  rows times unknowns), else the first of :data:`FALLBACK_REFERENCES` that takes it, at
  the ``high`` tolerance through :func:`solvers.interface.solve` (the ``reference``
  column names it);
* **Cattaneo-Mindlin** on the reference's last step -- the contact size ``a`` and the
  stick-zone size ``c`` (half-widths in 2D, radii in 3D) as second moments of the nodal
  normal forces and of the deficit ``s - |lam|``
  (:func:`reference.cattaneo_mindlin.stick_zone_size`), against
  ``c/a = sqrt(1 - Q/(mu P))`` (cylinder) or ``(1 - Q/(mu P))^(1/3)`` (sphere); the
  tangential traction (2D: ``lam / mass``; 3D: its component along the total tangential
  force) against :func:`reference.cattaneo_mindlin.tangential_traction` with the
  measured ``a`` and peak pressure ``p0`` and the analytic ``c``, its relative L2 error
  over the contact nodes (the lumped surface mass the quadrature weights);
* **the solvers** (``--solvers``, each ``handles_friction``) -- the same scaled load path
  run as ``contactbench solve`` runs it (:func:`solvers.interface.run_load_path`, every
  Tresca step verified by :func:`solvers.interface.solve` at ``--tol``), twice: each
  solve started from the path's last answer (``start`` ``warm``, the default of
  ``contactbench solve``) and from zero (``cold``, its ``--cold``): status, the
  solver's iterations in the normal and in the tangential step, its setup and solve
  time, and the relative energy-norm distance of its last step to the reference's;
* **timing** -- TNNMG on the reference's last Tresca step from zero and from the normal
  step's answer, its time (setup included) to the relative energy error ``--target``
  against the reference, beside the linear floor from zero: geometric-multigrid PCG for
  the same system without contact to the same accuracy; each the median of
  ``--repeats`` runs (:func:`timing_rows`);
* **mu = 0** -- the reference's path with ``mu = 0`` against ``pdas`` on each load step's
  frictionless problem, both load steps;
* **Coulomb** (Coulomb's law, the tangential step at ``--coulomb-shift``) -- the
  reference's fixed point ``s = mu p`` over Tresca steps: its Tresca solves and last
  contraction per load step (the frictionless solve that starts the path not counted).
* **the faceted law** (3D, each ``k`` of ``--facets``) -- the reference's path at the
  last ratio with the disc replaced by the inscribed regular ``k``-gon, against the
  isotropic one (:func:`solvers.kernels.tresca.facet_convergence`): the energy gap and its bound
  ``(1 - cos(pi/k)) D``, the relative energy-norm distance of ``u``, the largest
  traction difference, the Newton steps of the tangential step (``tresca_exact`` only:
  the fallback references take the isotropic law alone).

``--out`` gets one row per (level, ratio, role): ``role`` is ``reference``, ``solver``,
``timing`` (``solver`` ``tnnmg`` or ``linear_floor``), ``mu_zero``, ``coulomb`` or
``facets`` (a level no reference takes: one ``reference`` row,
``skipped``, with the reasons); ``--profiles`` one row per constrained node of each
reference's last step (distance from the contact's centre over ``a``, signed in 2D, and
the position in the contact plane; measured and analytic traction, ``mu`` times the
measured and the Hertz pressure, stick/slip state).

Example::

    python -m workflows.studies.friction.run --problem circle_square --levels 1 2 3 \\
        --mu 0.5 --ratios 0.3 0.7 --shift 0.01 --coulomb-shift 0.02 \\
        --solvers tnnmg semismooth_newton --tol high --time-limit 120 \\
        --target 1e-6 --repeats 3 --out results/circle_square/friction.csv \\
        --profiles results/circle_square/friction_profiles.csv
"""
from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np
import pandas as pd

from problems.fem.fields import in_plane
from problems.friction.data import MIN_FRICTION_FACETS
from problems.friction.residuals import tresca_energy
from problems.kkt import energy_error
from problems.spec import ParameterError
from reference.cattaneo_mindlin import (partial_slip_reference, relative_l2, stick_zone_ratio,
                                        stick_zone_size)
from reference.hertz import moment_estimate
from solvers.kernels import tresca
from solvers.interface import parse_tolerance, run_load_path, solve, solvers
from solvers.kernels.tresca import (as_tresca_solution, friction_path, path_for_ratio,
                                    run_nested_load_path, scaled_tangential_step, tangential_ratio,
                                    tangential_scale, warm_start)
from workflows.io import write_csv
from workflows.measure import (amg_pcg_floor, interleaved_median_runs, linear_solution,
                               return_freed_memory, tnnmg_run)
from workflows.progress import study_progress
from workflows.scene_args import add_scene_arguments, check_levels, parse_sets, scene_from_args

#: The parameters the study sets on the scene itself.
FRICTION_PARAMETERS = ("friction", "mu", "shift")
#: The fallback references where tresca_exact does not take the problem (its dense dual
#: grows as rows x unknowns), in order of preference, and their verified tolerance.
FALLBACK_REFERENCES, FALLBACK_TOL = ("semismooth_newton", "tnnmg"), "high"
#: The fallback references' options: semismooth Newton judges its steps on the contact rows
#: and forms ``u`` once per solve (the same steps and answer as its default to round-off, a
#: quarter of the solves with A's factor; the solver rows run its default).
FALLBACK_OPTIONS = {"semismooth_newton": {"displacement": "at_end"}}
#: Tolerance of the frictionless pdas reference of the mu = 0 check.
PDAS_TOL = 1e-12


class ReferenceFailed(RuntimeError):
    """The fallback reference did not verify a Tresca step (the message says why)."""


def reference_route(qp) -> tuple[str, object]:
    """``(name, solve)`` of the reference for the frictional ``qp``: ``tresca_exact``
    (``solve`` None, the default of :func:`path_for_ratio` and :func:`friction_path`)
    where it takes the problem, else the first of :data:`FALLBACK_REFERENCES` that takes
    it, verified at :data:`FALLBACK_TOL` with :data:`FALLBACK_OPTIONS`, one Tresca step at
    a time."""
    registered = solvers()
    if registered["tresca_exact"].supports(qp)[0]:
        return "tresca_exact", None
    name = next((n for n in FALLBACK_REFERENCES if registered[n].supports(qp)[0]), None)
    if name is None:
        reasons = "; ".join(f"{n}: {registered[n].supports(qp)[1]}"
                            for n in ("tresca_exact", *FALLBACK_REFERENCES))
        raise ReferenceFailed(f"no reference takes {qp.name}: {reasons}")

    def fallback(step_qp):
        res = solve(step_qp, name, FALLBACK_TOL, **FALLBACK_OPTIONS.get(name, {}))
        if res.status != "converged":
            raise ReferenceFailed(f"{name}: {res.status} ({res.message})")
        return as_tresca_solution(step_qp, res)

    return name, fallback


def partial_slip(step, ratio: float) -> tuple[dict, pd.DataFrame]:
    """Cattaneo-Mindlin measures of a reference's last step (a
    :class:`solvers.kernels.tresca.PathStep`; module docstring): the row's fields and the
    per-node profile.

    2D (line contact): positions along the contact line, the traction ``lam / mass``
    signed along the load. 3D (point contact): radial distances from the contact's
    centre, the traction the component of ``lam_i`` (a vector in the contact plane)
    along the total tangential force, over the node's mass; the profile keeps each
    node's position in the plane too (``px_over_a``, ``py_over_a``)."""
    step_qp, sol = step.qp, step.solution
    fr = step_qp.friction
    kind = step_qp.hertz.kind
    plane = in_plane(step_qp)
    x = plane[:, 0] if kind == "line" else plane
    _, a, p0 = moment_estimate(kind, x, sol.p)
    _, c = stick_zone_size(x, sol.p, fr.magnitude(sol.lam), fr.slip_bound, kind=kind)
    c_exact = stick_zone_ratio(ratio, kind)
    ref = partial_slip_reference(x, fr.slip_bound, fr.magnitude(sol.lam), ratio, kind)
    pressure = step_qp.contact.pressure(sol.p)
    w = step_qp.contact.mass
    if kind == "line":
        direction = 1.0 if sol.lam.sum() >= 0 else -1.0
        traction = direction * step_qp.contact.pressure(sol.lam)
        r = x - float(ref.centre[0])
        centred = np.stack([r, np.zeros_like(r)], axis=1)
    else:
        force = fr.tangential_force(sol.lam)
        along = fr.tangent @ (force / np.linalg.norm(force))       # each row's share
        traction = fr.blocks(sol.lam * along).sum(axis=1) / w
        centred = plane - ref.centre
        r = np.linalg.norm(centred, axis=1)
    zone = (sol.p > 0) | (fr.slip_bound > 0)
    l2 = relative_l2(w[zone], traction[zone], ref.traction[zone])
    state = np.where(fr.slip_bound > 0, np.where(sol.stick, "stick", "slip"), "free")
    profile = pd.DataFrame({
        "x_over_a": r / ref.a, "px_over_a": centred[:, 0] / ref.a,
        "py_over_a": centred[:, 1] / ref.a,
        "traction": traction, "traction_exact": ref.traction,
        "mu_pressure": fr.mu * pressure,
        "mu_pressure_exact": ref.mu_p0 * np.sqrt(np.clip(1 - (r / ref.a) ** 2, 0, None)),
        "state": state})
    fields = {"contact": kind, "ratio_reached": tangential_ratio([step]), "a": a, "p0": p0,
              "c": c, "c_over_a": c / a, "c_over_a_exact": c_exact,
              "dev_c_over_a": (c / a) / c_exact - 1.0, "traction_l2": l2,
              "stick_offset": (float(ref.stick_centre[0] - ref.centre[0]) / ref.a
                               if kind == "line" else ref.stick_offset),
              "contact_nodes": int((sol.p > 0).sum()), "stick_nodes": int(sol.stick.sum())}
    return fields, profile


#: The starts of a solver's load path (:func:`solver_row`): each solve from the path's
#: last answer (``warm``), from zero (``cold``), and for :data:`NESTED_SOLVERS` nested from
#: the coarser levels (``nested``, :func:`solvers.kernels.tresca.run_nested_load_path`).
STARTS = ("warm", "cold", "nested")
#: The solvers whose paths run nested too: TNNMG, the multigrid method whose steps on the
#: finest level the study's growth bar is about.
NESTED_SOLVERS = ("tnnmg",)
#: The coarser levels a nested path starts from (Alg. 8.5, as the Alg. 8.4 study nests).
NESTED_DEPTH = 2


def solver_row(path_qp, name: str, tol: str, time_limit: float, ref_step,
               start: str = "warm", coarse: tuple = ()) -> tuple[dict, list]:
    """The load path ``path_qp`` run by the registered solver ``name`` against the
    reference's last step ``ref_step``: each solve started from the path's last answer
    (``start`` ``warm``, as ``contactbench solve`` runs it), from zero (``cold``, its
    ``--cold``) or by nested iteration (``nested``, :func:`run_nested_load_path` from the
    scene's coarser levels ``coarse``, coarsest first, with the same load path). Returns
    the row (iterations and times of the finest level; a nested row adds the coarser
    levels' tangential-step iterations and solve time) and, for a nested row, the coarser
    levels' tangential-step problems (:func:`timing_rows`)."""
    calls = []

    def step(step_qp, last):
        res = solve(step_qp, name, tol, time_limit=time_limit, **warm_start(last))
        calls.append(res)
        return res

    levels = list(coarse) + [path_qp] if start == "nested" else [path_qp]
    if start == "nested":
        runs = run_nested_load_path(levels, step, tol=parse_tolerance(tol))
    else:
        runs = [run_load_path(path_qp, step, tol=parse_tolerance(tol), warm=start == "warm")]
    per_level = []
    for run in runs:                      # the solves of each level, by load step
        per_step = []
        for record in run.records:
            per_step.append(calls[:record["tresca_solves"]])
            del calls[:record["tresca_solves"]]
        per_level.append(per_step)
    run, per_step = runs[-1], per_level[-1]
    res = run.result
    steps = [sum(r.iterations for r in rs) for rs in per_step] + [np.nan, np.nan]
    # TNNMG's tangential step split at the last change of its face (solvers.tnnmg)
    tangential = per_step[1] if len(per_step) > 1 else []
    phases = [sum(r.stats.get(key, np.nan) for r in tangential) if tangential else np.nan
              for key in ("steps_to_face", "steps_on_face")]
    rate = tangential[-1].stats.get("contraction_on_face", np.nan) if tangential else np.nan
    row = {"solver": name, "start": start, "status": res.status,
           "failed_check": res.failed_check or "",
           "message": res.message if res.status != "converged" else "",
           "steps_normal": steps[0], "steps_tangential": steps[1],
           "steps_tangential_to_face": phases[0], "steps_tangential_on_face": phases[1],
           "contraction_tangential_on_face": rate,
           "solves": sum(len(rs) for rs in per_step),
           "t_setup": sum(r.setup_time for rs in per_step for r in rs),
           "t_solve": sum(r.solve_time for rs in per_step for r in rs),
           "kkt_max": res.kkt.max if res.kkt is not None else np.nan}
    if start == "nested":
        below = [rs[1] if len(rs) > 1 else [] for rs in per_level[:-1]]
        row.update(steps_tangential_coarse=" + ".join(
                       str(sum(r.iterations for r in rs)) for rs in below),
                   t_solve_coarse=sum(r.solve_time + r.setup_time
                                      for level_steps in per_level[:-1]
                                      for step_calls in level_steps for r in step_calls))
        if any(run.result.status != "converged" for run in runs[:-1]):
            bad = next(run for run in runs[:-1] if run.result.status != "converged")
            row["message"] = (f"a coarser level stopped short ({bad.result.status}: "
                              f"{bad.result.message}); " + row["message"])
    if res.status == "converged" and len(run.steps) == len(path_qp.friction.path):
        last_qp = run.steps[-1].qp
        row["err_energy"] = energy_error(last_qp, res.u, ref_step.solution.u)
        e_ref = tresca_energy(ref_step.qp, ref_step.solution.u)
        row["dev_energy"] = abs(tresca_energy(last_qp, res.u) - e_ref) / abs(e_ref)
    complete = [r.qp for r in runs[:-1]
                if r.result.status == "converged" and len(r.steps) == len(path_qp.friction.path)]
    return row, (complete if len(complete) == len(runs) - 1 else [])


def timing_rows(step_qp, u_ref, target: float, repeats: int, time_limit: float,
                u_previous=None, coarse: list = ()) -> list[dict]:
    """TNNMG on the Tresca step ``step_qp`` against the linear floor, each the median of
    ``repeats`` timed runs taken in rounds (:func:`workflows.measure.interleaved_median_runs`):
    TNNMG's steps and time
    (setup included) until its energy-norm distance to the reference's ``u_ref`` reaches
    ``target`` (:func:`workflows.measure.tnnmg_run`), then on to its verified stop, from
    zero (``start`` ``cold``); given ``u_previous`` (the previous load step's answer),
    from it (``warm``, as a load path runs it); given ``coarse`` (the same step on the
    scene's coarser levels, coarsest first), by nested iteration from zero on the
    coarsest (``nested``: each coarser step solved to the KKT residuals of
    :data:`workflows.measure.NESTED_TOL` and prolongated; its ``t_to_target`` includes
    their time, ``t_coarse_levels``; TNNMG's verification before the target is not in
    ``t_to_target`` but beside it, ``t_verify_to_target``); the floor from zero,
    geometric-multigrid PCG for ``A u = f`` of the same system without contact to the same
    energy accuracy (:func:`workflows.measure.amg_pcg_floor`)."""
    keep = ("status", "message", "n_to_target", "t_to_target", "t_to_target_min",
            "t_to_target_max", "t_verify_to_target", "timing_repeats", "energy_error",
            "kkt_max", "t_coarse_levels")
    u_lin = linear_solution(step_qp)
    runs = {("tnnmg", "cold"): lambda: tnnmg_run(step_qp, u_ref, target, time_limit),
            ("linear_floor", "cold"): lambda: amg_pcg_floor(step_qp, "gmg", target, u_lin)}
    if u_previous is not None:
        runs[("tnnmg", "warm")] = lambda: tnnmg_run(step_qp, u_ref, target, time_limit,
                                                   start=u_previous)
    if coarse:
        def nested():
            run = tnnmg_run(step_qp, u_ref, target, time_limit, coarse)
            return {**run, "t_to_target": run["t_to_target"] + run["t_coarse_levels"]}

        runs[("tnnmg", "nested")] = nested
    timed = interleaved_median_runs(runs, repeats)
    return [{"role": "timing", "solver": name, "start": start, "target": target,
             **{k: run[k] for k in keep
                if k in run and (k != "t_coarse_levels" or start == "nested")}}
            for (name, start), run in timed.items()]


def mu_zero_path(qp, ref_solve) -> list:
    """The reference's load path of ``qp`` with ``mu = 0``."""
    return friction_path(replace(qp, friction=replace(qp.friction, mu=0.0)), ref_solve)


def mu_zero_rows(qp, steps: list) -> list[dict]:
    """The reference's path with ``mu = 0`` (:func:`mu_zero_path`) against ``pdas`` on
    each load step's frictionless problem (the step's ``f`` and ``g`` without friction: the
    scene built with ``friction=none`` and the step's shift, array for array)."""
    rows = []
    for k, (st, load) in enumerate(zip(steps, qp.friction.path), start=1):
        plain = replace(qp, f=load.f, g=load.g, friction=None)
        ref = solve(plain, "pdas", PDAS_TOL)
        row = {"load_step": k, "status": ref.status}
        if ref.status == "converged":
            row["err_energy"] = energy_error(plain, st.solution.u, ref.u)
            row["dev_p"] = float(np.max(np.abs(st.solution.p - ref.p)) / np.max(ref.p))
        rows.append(row)
    return rows


def coulomb_rows(qp, factor: float, ref_solve) -> list[dict]:
    """Coulomb's fixed point ``s = mu p`` over the reference's Tresca steps on the load
    path of ``qp`` with its tangential step scaled by ``factor`` (exact: the step is affine
    in the shift), per load step."""
    coulomb = replace(qp, friction=replace(qp.friction, law="coulomb"))
    steps = friction_path(scaled_tangential_step(coulomb, factor), ref_solve)
    return [{"load_step": k, "status": st.solution.status, "tresca_solves": st.tresca_solves,
             "contraction": st.contraction, "ratio_reached": tangential_ratio([st])}
            for k, st in enumerate(steps, start=1)]


def facet_rows(path_qp, facets: list[int], ref_name: str) -> list[dict]:
    """The faceted law against the isotropic one on the reference path of ``path_qp``
    (:func:`solvers.kernels.tresca.facet_convergence`), one row per ``k`` of ``facets``; none in
    2D (the law is already polyhedral there); one ``skipped`` row where the reference is
    not ``tresca_exact``."""
    if not facets or path_qp.friction.components != 2:
        return []
    if ref_name != "tresca_exact":
        return [{"role": "facets", "status": "skipped",
                 "message": f"the reference here is {ref_name}, which takes the isotropic law "
                            "only; the faceted paths need tresca_exact"}]
    return [{"role": "facets", "solver": ref_name, "status": r["status"],
             "facets": r["facets"], "steps_tangential": r["iterations"],
             "energy": r["energy"], "energy_gap": r["energy_gap"], "gap_bound": r["gap_bound"],
             "err_energy": r["displacement"], "traction_dev": r["traction"],
             "facet_distance": r["distance"]}
            for r in tresca.facet_convergence(path_qp, tuple(facets))]


def level_rows(spec, params: dict, level: int, args) -> tuple[list[dict], list[pd.DataFrame]]:
    """Every row and profile of one level (module docstring)."""
    t0 = time.perf_counter()
    qp = spec.make(level, **params, friction="tresca", mu=args.mu, shift=args.shift)
    t_build = time.perf_counter() - t0
    nested = any(name in NESTED_SOLVERS for name in args.solvers)   # else none built
    coarse = [spec.make(k, **params, friction="tresca", mu=args.mu, shift=args.shift)
              for k in range(max(0, level - NESTED_DEPTH), level) if nested]
    return_freed_memory()                      # the assembly's temporaries
    size = {"level": level, "N": qp.n_nodes, "n": qp.n, "NC": qp.m, "t_build": t_build}
    try:
        ref_name, ref_solve = reference_route(qp)
    except ReferenceFailed as err:
        return [{**size, "role": "reference", "status": "skipped", "message": str(err)}], []
    size["reference"] = ref_name
    # The reference's own work first, while its factorisation is held: its paths, its
    # solver rows, mu = 0 and Coulomb; then that factorisation is released (semismooth
    # Newton's beyond tresca_exact's size: A's sparse factor), pdas factorises A for the
    # frictionless steps, and the other solvers' rows and the timing runs follow: never
    # two factorisations at once, nor one beside the timed runs. The rows keep their order.
    blocks, profiles, paths = {}, [], []
    for ratio in args.ratios:
        t0 = time.perf_counter()
        try:
            steps = path_for_ratio(qp, ratio, solve=ref_solve)
        except ReferenceFailed as err:
            blocks[ratio] = [{**size, "ratio": ratio, "role": "reference", "status": "failed",
                              "message": str(err)}]
            continue
        ref = steps[-1]
        fields, profile = partial_slip(ref, ratio)
        blocks[ratio] = [{**size, "ratio": ratio, "role": "reference", "solver": ref_name,
                          "status": ref.solution.status, "kkt_max": ref.solution.kkt.max,
                          "steps_normal": steps[0].solution.iterations,
                          "steps_tangential": ref.solution.iterations,
                          "t_solve": time.perf_counter() - t0, **fields}]
        profiles.append(profile.assign(level=level, N=qp.n_nodes, ratio=ratio))
        factor = tangential_scale(ref.qp, qp)
        paths.append((ratio, steps, [scaled_tangential_step(q, factor) for q in coarse]))
    solver_rows = {}                            # (ratio, name, start) -> (row, found)

    def run_solver_rows(names):
        for ratio, steps, below in paths:
            for name in names:
                for start in STARTS:
                    if start == "nested" and (name not in NESTED_SOLVERS or not below):
                        continue
                    solver_rows[ratio, name, start] = solver_row(
                        steps[-1].qp, name, args.tol, args.time_limit, steps[-1], start, below)

    run_solver_rows([n for n in args.solvers if n == ref_name])
    zero_steps, coulomb, failed = None, [], None
    try:
        zero_steps = mu_zero_path(qp, ref_solve)
        if args.coulomb_shift > 0:
            coulomb = coulomb_rows(qp, args.coulomb_shift / args.shift, ref_solve)
    except ReferenceFailed as err:
        failed = err
    qp.cache.contact_schur.clear()             # semismooth Newton's factor and Schur complement
    return_freed_memory()
    zero_rows = mu_zero_rows(qp, zero_steps) if zero_steps is not None else []
    return_freed_memory()                      # pdas's factorisations
    run_solver_rows([n for n in args.solvers if n != ref_name])
    for ratio, steps, below in paths:
        ran = [solver_rows[key] for key in ((ratio, name, start) for name in args.solvers
                                            for start in STARTS) if key in solver_rows]
        blocks[ratio] += [{**size, "ratio": ratio, "role": "solver", **row} for row, _ in ran]
        coarse_steps = next((found for _, found in ran if found), [])
        blocks[ratio] += [{**size, "ratio": ratio, **r} for r in
                          timing_rows(steps[-1].qp, steps[-1].solution.u, args.target,
                                      args.repeats, args.time_limit, steps[0].solution.u,
                                      coarse_steps)]
        return_freed_memory()                  # the ratio's timed runs' leftovers
    rows = [row for ratio in args.ratios for row in blocks[ratio]]
    rows += [{**size, "role": "mu_zero", "solver": ref_name, **r} for r in zero_rows]
    rows += [{**size, "role": "coulomb", "solver": ref_name, **r} for r in coulomb]
    if failed is not None:
        rows.append({**size, "role": "mu_zero", "status": "failed", "message": str(failed)})
    if paths and not paths[-1][1][-1].qp.friction.facets:
        ratio, steps, _ = paths[-1]
        rows += [{**size, "ratio": ratio, **r}
                 for r in facet_rows(steps[-1].qp, args.facets, ref_name)]
    return rows, profiles


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scene_arguments(parser)
    parser.add_argument("--levels", type=int, nargs="+", required=True, help="mesh levels")
    parser.add_argument("--mu", type=float, required=True, help="friction coefficient (> 0)")
    parser.add_argument("--ratios", type=float, nargs="+", required=True,
                        help="load ratios Q/(mu P), each in (0, 1)")
    parser.add_argument("--shift", type=float, required=True,
                        help="the tangential step's shift before its scaling (nonzero)")
    parser.add_argument("--coulomb-shift", type=float, required=True,
                        help="the tangential shift of the Coulomb runs (0: no Coulomb runs)")
    parser.add_argument("--solvers", nargs="*", required=True,
                        help="registered solvers that take friction")
    parser.add_argument("--tol", choices=["low", "mid", "high"], required=True,
                        help="the solvers' verified tolerance")
    parser.add_argument("--time-limit", type=float, required=True,
                        help="seconds per Tresca solve (> 0)")
    parser.add_argument("--target", type=float, required=True,
                        help="relative energy error of the timed runs, in (0, 1)")
    parser.add_argument("--repeats", type=int, required=True,
                        help="timed runs of TNNMG and of the floor (the median is kept; >= 1)")
    parser.add_argument("--facets", type=int, nargs="*", default=[],
                        help="facet counts k of the faceted law compared with the isotropic "
                             "one on 3D scenes (each >= 3; none: no comparison)")
    parser.add_argument("--out", required=True, help="the runs table (CSV)")
    parser.add_argument("--profiles", required=True, help="the traction profiles (CSV)")
    args = parser.parse_args(argv)
    spec, _ = scene_from_args(parser, args)
    params = parse_sets(args.set)
    missing = [p for p in FRICTION_PARAMETERS if p not in {q.name for q in spec.parameters}]
    if missing:
        parser.error(f"argument --problem: {spec.name!r} is not allowed; allowed: a problem "
                     f"with the parameters {', '.join(FRICTION_PARAMETERS)}")
    fixed = sorted(set(params) & set(FRICTION_PARAMETERS))
    if fixed:
        parser.error(f"argument --set: {', '.join(fixed)} is not allowed; allowed: the "
                     "other scene parameters (the study sets friction, mu and shift)")
    levels = check_levels(parser, spec, args.levels)
    if not args.mu > 0:
        parser.error(f"argument --mu: {args.mu} is not allowed; allowed: > 0")
    for ratio in args.ratios:
        if not 0 < ratio < 1:
            parser.error(f"argument --ratios: {ratio} is not allowed; allowed: in (0, 1) "
                         "(at Q >= mu P the whole contact slips: gross sliding)")
    if args.shift == 0:
        parser.error("argument --shift: 0 is not allowed; allowed: a nonzero shift")
    if not 0 < args.target < 1:
        parser.error(f"argument --target: {args.target} is not allowed; allowed: in (0, 1)")
    if args.repeats < 1:
        parser.error(f"argument --repeats: {args.repeats} is not allowed; allowed: >= 1")
    small = [k for k in args.facets if k < MIN_FRICTION_FACETS]
    if small:
        parser.error(f"argument --facets: {small} is not allowed; allowed: integers >= "
                     f"{MIN_FRICTION_FACETS} (a polygon)")
    if args.time_limit <= 0:
        parser.error(f"argument --time-limit: {args.time_limit} is not allowed; allowed: > 0")
    registered = solvers()
    frictional = sorted(n for n, s in registered.items() if s.handles_friction)
    wrong = [n for n in args.solvers if n not in frictional]
    if wrong:
        parser.error(f"argument --solvers: {', '.join(wrong)} is not allowed; allowed: "
                     f"{', '.join(frictional)} (registered solvers that take friction)")
    try:                                       # the scene's own checks of the parameters
        for shift in {args.shift, args.coulomb_shift}:
            spec.options(**params, friction="tresca", mu=args.mu, shift=shift)
    except ParameterError as err:
        parser.error(str(err))

    scene = " ".join([spec.name, *args.set])
    rows, profiles = [], []
    for level in study_progress(levels, rule="friction_study", out=args.out,
                                desc=f"{scene} friction", unit="level"):
        r, p = level_rows(spec, params, level, args)
        rows += r
        profiles += p
        return_freed_memory()                  # the level's problems and factorisations
    out = pd.DataFrame(rows)
    out.insert(0, "scene", scene)
    out.insert(1, "mu", args.mu)
    prof = pd.concat(profiles, ignore_index=True) if profiles else pd.DataFrame()
    prof.insert(0, "scene", scene)
    write_csv(args.profiles, prof)
    write_csv(args.out, out)


if __name__ == "__main__":
    main()
