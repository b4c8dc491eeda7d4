"""Friction: the claims and figures from ``workflows/studies/friction/run.py``'s tables
(its runs and its traction profiles, one scene, 2D or 3D).

Claims, per scene: Cattaneo-Mindlin's stick zone c/a at the finest level, for each load
ratio, within :data:`STICK_ZONE_BAR` (5 % on the 2D line contact, 10 % on the 3D sphere)
and the tangential traction within 10 % in L2 (judged where the contact zone is
resolved: at least :data:`RESOLVED_CONTACT_NODES` contact nodes for c/a,
:data:`RESOLVED_STICK_EDGE` for the traction); the fitted rates of both errors against N
(reported); the solvers and the reference agreeing to 1e-8 in relative energy at every
level where all ran; the mu = 0 path equal to the frictionless reference to 1e-10; every
frictional solver run verified ``converged``; TNNMG's tangential-step iterations growing at
most 15 % over the last two levels (judged when the finer is resolved); Coulomb's fixed
point converging at every level, with its Tresca solves; TNNMG's time to the target energy
error on the tangential step within :data:`TIME_BAR` times the linear multigrid solve at
the finest level; on a 3D scene the faceted law's energy gap to the isotropic one falling
like ``k^-2`` (:data:`FACET_ENERGY_EXPONENT`, the finest level that ran it; the
displacement's exponent reported, :func:`facet_claims`).
Figures: the traction profiles at the finest level, c/a against Q/(mu P), the stick and
slip nodes in the contact plane, and iterations and time against N per solver with fitted
exponents.

Example::

    python -m report.friction --runs results/circle_square/friction.csv \\
        --profiles results/circle_square/friction_profiles.csv --claims c.csv \\
        --traction t.png --stick s.png --map m.png --cost k.png
"""
from __future__ import annotations

import argparse
from dataclasses import replace

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from report.claims import COLUMNS, Claim
from report.figures import legend_below, nothing_to_draw, save_figure, solver_style
from report.rates import fitted_slope
from reference.cattaneo_mindlin import stick_zone_ratio
from workflows.io import read_csv, write_csv

#: Cattaneo-Mindlin bars at the finest level, by contact kind: c/a within 5 % on the
#: plane-strain cylinder (line) and within 10 % on the sphere (point: the stick circle
#: spans fewer nodes per radius on a 3D mesh of the same cost); the traction within 10 %
#: in L2 on both.
STICK_ZONE_BAR = {"line": 0.05, "point": 0.10}
TRACTION_BAR = 0.10
#: The contact nodes a level needs for the accuracy and growth bars, by contact kind:
#: circle-square level 3 has 25 (at 7 and 13 nodes the stick zone spans a few cells, and
#: c/a is off by up to 11 %); cube-sphere level 3 about 230 (8.7 nodes across the radius,
#: level 2 about 4).
RESOLVED_CONTACT_NODES = {"line": 25, "point": 150}
#: The contact nodes the traction's bar needs, by contact kind: its error lies at the
#: stick zone's edge, where q has a square-root kink that a node's place within its cell
#: decides. On the line the resolved zone's 25 nodes; on the sphere 800, about 16 nodes
#: across the radius (pi 16^2): the graded scene ``hertz_mindlin`` gets there at its
#: level 2, cube-sphere (8.7 across the radius at level 3) not below level 4.
RESOLVED_STICK_EDGE = {"line": 25, "point": 800}
#: Agreement of verified answers (the suite's bar for solvers on the same problem), and
#: mu = 0 against the frictionless reference (the thesis's problem to round-off).
AGREEMENT_BAR = 1e-8
MU_ZERO_BAR = 1e-10
#: TNNMG's iterations over the last two levels (multigrid: bounded in h).
STEPS_GROWTH_BAR = 1.15
#: TNNMG's time on a Tresca step over one linear multigrid solve of the same system (the
#: frictionless TNNMG takes about 2x; the nonsmooth tangential term may add half again).
TIME_BAR = 3.0
#: The fewest unknowns N at which the time bar is judged: it is set for the fine levels
#: (circle-square level 4, 262,474; cube-sphere level 3, 135,102), where the linear
#: floor's solve is no longer a sub-second run dominated by its setup; below, the ratio
#: is reported.
TIME_BAR_MIN_N = 100_000
#: The faceted law's energy gap J* - J_k* against k: between 0 and (1 - cos(pi/k)) times
#: the dissipation, so O(k^-2); its exponent fitted over the :data:`FACET_FIT_LAST`
#: largest k within 0.3 of -2. The smaller k are pre-asymptotic: while pi/k exceeds the
#: slip directions' angles to the first tangent (a vertex, along the tangential load)
#: the gap barely falls (cube-sphere level 1 at Q/(mu P) = 0.7: -1.66 over k = 8..256,
#: -2.0 over 32..256).
FACET_ENERGY_EXPONENT = (-2.3, -1.7)
FACET_FIT_LAST = 4
#: Round-off allowance of the energy bracket 0 <= J* - J_k* <= (1 - cos(pi/k)) D, relative
#: to the energy (the exact reference's energies agree to ~1e-12).
FACET_BRACKET_SLACK = 1e-10
CM = "Cattaneo-Mindlin (Johnson 1985, Sects. 7.1-7.2)"
#: c/a of Cattaneo-Mindlin by contact kind, as the figures write it.
CM_CURVE = {"line": "sqrt(1 - Q/(mu P))", "point": "(1 - Q/(mu P))^(1/3)"}

#: The friction study's claims (report/claims.py).
CLAIMS = {
    "stick_zone": Claim(CM, "stick-zone c/a against {curve}", "|<=|",
                        STICK_ZONE_BAR["line"], details="Q/(mu P) = {ratio:g}; relative "
                        "deviation"),
    "traction": Claim(CM, "tangential traction against q(x)", "<=", TRACTION_BAR,
                      details="Q/(mu P) = {ratio:g}; relative L2 error over the contact"),
    "stick_rate": Claim(CM, "|c/a deviation| ~ N^rate",
                        unjudged="the theory gives the limit, not a rate: the fitted "
                        "rate is reported beside the finest level's bar",
                        details="Q/(mu P) = {ratio:g}; fitted over the levels"),
    "traction_rate": Claim(CM, "traction L2 error ~ N^rate",
                           unjudged="the theory gives the limit, not a rate: the fitted "
                           "rate is reported beside the finest level's bar",
                           details="Q/(mu P) = {ratio:g}; fitted over the levels"),
    "agreement": Claim("suite bar (verified answers of one Tresca problem agree to 1e-8)",
                       "frictional solvers against the reference: largest energy distance",
                       "<=", AGREEMENT_BAR, details="{solvers}; relative energy distance"),
    "mu_zero": Claim("suite bar (mu = 0 is the thesis's frictionless problem, to round-off)",
                     "the mu = 0 path against pdas: largest energy distance", "<=",
                     MU_ZERO_BAR, details="relative energy distance, both load steps, every "
                     "level"),
    "verified": Claim("suite bar (a frictional solve counts only when verified)",
                      "frictional solver runs verified converged", "given", "all",
                      details="friction KKT and the Tresca certificate, every load step"),
    "tnnmg_steps": Claim("suite bar (TNNMG, a multigrid method: iterations bounded in h)",
                         "TNNMG tangential-step iterations, nested: growth with refinement",
                         "<=", STEPS_GROWTH_BAR, level="{coarser} -> {level}",
                         details="Q/(mu P) = {ratio:g}; the finest level over the one "
                         "before, nested from the two coarser levels (Alg. 8.5 on each load "
                         "step)"),
    "tnnmg_steps_warm": Claim(
        "suite figure (the tangential step as a quasi-static path runs it)",
        "TNNMG tangential-step iterations from the normal step's answer: growth",
        unjudged="information: from the previous step's answer the slip front has to move "
        "to its place node by node (the steps that find the face grow with the nodes that "
        "change state, about 1/h); the bar is judged with the nested start, which brings "
        "the front's place from the coarser levels",
        level="{coarser} -> {level}", details="Q/(mu P) = {ratio:g}; the finest level over "
        "the one before"),
    "tnnmg_face_rate": Claim(
        "Gräser-Kornhuber: on a fixed face a TNNMG step is a linear multigrid step "
        "(contraction bounded in h)", "TNNMG's mean contraction per step on the tangential "
        "step's final face",
        unjudged="information: the steps that find the face grow with the nodes whose "
        "state changes (the slip front's nodes nearest their kink are found last); the "
        "contraction on it is the multigrid phase the h-independence is about",
        details="Q/(mu P) = {ratio:g}; the stationarity residual from the normal step's "
        "answer, after the face (normal active set, stick set, slip signs) last changed; "
        "level {coarser}: {coarse_rate}; steps to the face {to_face}, on it {on_face}"),
    "tnnmg_steps_cold": Claim("suite figure (the tangential step solved as a problem of its "
                              "own)", "TNNMG tangential-step iterations from zero: growth",
                              unjudged="information: the bar is judged with the nested "
                              "start", level="{coarser} -> {level}",
                              details="Q/(mu P) = {ratio:g}; the finest level over the one "
                              "before"),
    "tnnmg_time": Claim("suite bar (TNNMG on a Tresca step: within 3x one linear multigrid "
                        "solve)", "TNNMG's time on the tangential step, nested, over one "
                        "linear solve", "<=", TIME_BAR,
                        details="Q/(mu P) = {ratio:g}, N = {N}; to relative energy error "
                        "{target:g}, nested from zero on the two coarser levels (their time "
                        "included), over the multigrid-PCG solve of the same system without "
                        "contact from zero; medians of the timed runs"),
    "tnnmg_time_cold": Claim("suite figure (the tangential step solved as a problem of its "
                             "own on the finest level alone)",
                             "TNNMG's time on the tangential step from zero over one linear "
                             "solve",
                             unjudged="information: from zero on the finest level TNNMG "
                             "finds the slip front node by node; the bar is judged with the "
                             "nested start",
                             details="Q/(mu P) = {ratio:g}, N = {N}; to relative energy "
                             "error {target:g}, over the multigrid-PCG solve from zero; "
                             "medians of the timed runs"),
    "tnnmg_time_warm": Claim("suite figure (the tangential step as a load path runs it)",
                             "TNNMG's time on the tangential step from the normal step's "
                             "answer over one linear solve",
                             unjudged="information: a load path's cost per step against one "
                             "linear solve; the bar is judged with the nested start",
                             details="Q/(mu P) = {ratio:g}, N = {N}; to relative energy "
                             "error {target:g}, over the multigrid-PCG solve from zero; "
                             "medians of the timed runs"),
    "facet_energy": Claim("the inscribed k-gon's distance to the disc, 1 - cos(pi/k) = "
                          "O(k^-2), bounds the energy gap", "faceted law's energy gap J* - "
                          "J_k* ~ k^rate", "in", FACET_ENERGY_EXPONENT,
                          details="k = {facets}, Q/(mu P) = {ratio:g}; fitted"),
    "facet_bracket": Claim("the inscribed k-gon lies between the discs of radius cos(pi/k) "
                           "and 1", "0 <= J* - J_k* <= (1 - cos(pi/k)) D(u_k) at every k and "
                           "level", "given", "every faceted path",
                           details="slack 1e-10 of |J|{not_run}"),
    "facet_energy_all": Claim("the faceted energy gap over every k, the pre-asymptotic "
                              "ones included", "faceted law's energy gap ~ k^rate over every k",
                              unjudged="information: the small k are pre-asymptotic; the "
                              "bar is judged over the largest k",
                              details="k = {facets}, Q/(mu P) = {ratio:g}; fitted"),
    "facet_displacement": Claim("the faceted law's traction points at a vertex, off the "
                                "slip by up to pi/k: O(k^-1)", "faceted law's relative "
                                "energy-norm distance of u ~ k^rate",
                                unjudged="the theory gives -1 as an upper rate, not an "
                                "equality: reported beside the energy's bar",
                                details="k = {facets}, Q/(mu P) = {ratio:g}; fitted"),
    "coulomb": Claim("suite bar (the fixed point s = mu p must converge to count)",
                     "Coulomb's fixed point converged in every load step of every level",
                     "given", "all", details="Tresca solves per level, normal + "
                     "tangential, in the measured column"),
}


#: The runs table's columns the claims and figures read (a scene whose levels no
#: reference took has only a few of them).
RUN_COLUMNS = ("scene", "mu", "level", "N", "role", "solver", "start", "status", "message",
               "ratio",
               "contact", "contact_nodes", "dev_c_over_a", "traction_l2", "stick_offset",
               "c_over_a",
               "c_over_a_exact", "ratio_reached", "p0", "err_energy", "steps_tangential",
               "steps_tangential_to_face", "steps_tangential_on_face",
               "contraction_tangential_on_face",
               "t_setup", "t_solve", "t_solve_coarse", "load_step", "tresca_solves",
               "contraction", "target",
               "t_to_target", "facets", "energy", "energy_gap", "gap_bound", "traction_dev",
               "facet_distance")


def complete(runs: pd.DataFrame) -> pd.DataFrame:
    """``runs`` with every column of :data:`RUN_COLUMNS` (missing ones empty)."""
    missing = [c for c in RUN_COLUMNS if c not in runs]
    return runs.assign(**{c: np.nan for c in missing}) if missing else runs


def _unresolved(top, needed: int, what: str) -> str:
    """The reason a Cattaneo-Mindlin bar is not judged on the finest reference row ``top``:
    its contact nodes against the ``needed`` ones."""
    return (f"level {int(top.level)} has {int(top.contact_nodes)} contact nodes; the bar is "
            f"about {what} (>= {needed})")


def claims(runs: pd.DataFrame) -> pd.DataFrame:
    """The claims of the module docstring, per scene."""
    runs = complete(runs)
    rows = []
    for scene, t in runs.groupby("scene", sort=True):
        ref = t[(t.role == "reference") & (t.status == "converged")]
        kind = contact_kind(t)
        for ratio, g in ref.groupby("ratio", sort=True):
            g = g.sort_values("N")
            top = g.iloc[-1]
            resolved = top.contact_nodes >= RESOLVED_CONTACT_NODES[kind]
            why = _unresolved(top, RESOLVED_CONTACT_NODES[kind], "a resolved zone")
            fields = dict(scene=scene, ratio=ratio, level=int(top.level))
            stick = replace(CLAIMS["stick_zone"], bar=STICK_ZONE_BAR[kind])
            rows.append(stick.row(float(top.dev_c_over_a), judged=resolved, reason=why,
                                  curve=CM_CURVE[kind], **fields))
            edge = RESOLVED_STICK_EDGE[kind]
            rows.append(CLAIMS["traction"].row(
                float(top.traction_l2), judged=bool(top.contact_nodes >= edge),
                reason=_unresolved(top, edge, "a resolved stick-zone edge"), **fields))
            if len(g) >= 2:
                rows.append(CLAIMS["stick_rate"].row(
                    fitted_slope(g.N, g.dev_c_over_a.abs(), last=len(g)), scene=scene,
                    ratio=ratio))
                rows.append(CLAIMS["traction_rate"].row(
                    fitted_slope(g.N, g.traction_l2, last=len(g)), scene=scene, ratio=ratio))
        if len(ref) and (ref.groupby("ratio").size() < 2).all():
            rows += [CLAIMS[key].absent("a reference on one level only: no rate to fit",
                                        scene=scene) for key in ("stick_rate", "traction_rate")]
        rows.append(_agreement(t, scene))
        mu0 = t[t.role == "mu_zero"]
        ok = len(mu0) and (mu0.status == "converged").all()
        rows.append(CLAIMS["mu_zero"].row(float(mu0.err_energy.max()) if ok else np.nan,
                                          judged=bool(ok), scene=scene,
                                          reason="the frictionless reference did not converge"
                                          if len(mu0) else no_reference(t)))
        solved = t[t.role == "solver"]
        rows.append(_verified(solved, scene))
        nodes = ref.groupby("level").contact_nodes.min()
        starts = solved.start.fillna("warm")
        for start, claim in (("nested", "tnnmg_steps"), ("warm", "tnnmg_steps_warm"),
                             ("cold", "tnnmg_steps_cold")):
            rows += _tnnmg_growth(solved[starts == start], nodes, scene,
                                  RESOLVED_CONTACT_NODES[kind], claim=claim)
        rows += _tnnmg_face_rate(solved[starts == "warm"], scene)
        for start, claim in (("nested", "tnnmg_time"), ("cold", "tnnmg_time_cold"),
                             ("warm", "tnnmg_time_warm")):
            rows += _time_ratio(t[t.role == "timing"], scene, start, claim)
        rows.append(_coulomb(t[t.role == "coulomb"], scene))
        rows += facet_claims(t[t.role == "facets"], scene, kind)
    return pd.DataFrame(rows, columns=COLUMNS)


def facet_claims(facets: pd.DataFrame, scene: str, kind: str = "point") -> list[dict]:
    """The faceted law against the isotropic one: the energy bracket at every k and
    level the faceted paths ran at (a level whose reference takes the isotropic law only
    has one ``skipped`` row: named in the claim, not counted as a path); at the finest
    level where every faceted path converged, the energy gap's exponent over the
    :data:`FACET_FIT_LAST` largest k judged against :data:`FACET_ENERGY_EXPONENT`, over
    every k and the displacement's reported.

    Without faceted runs a line contact (``kind``, a 2D scene: its friction law is
    already polyhedral) has no facet claims, a point contact one row saying so."""
    if facets.empty:
        return [] if kind == "line" else [CLAIMS["facet_bracket"].absent(
            "no faceted runs (the study's facets are not set)", scene=scene)]
    skipped = facets[facets.status == "skipped"]   # a level whose reference takes no facets
    facets = facets[facets.status != "skipped"]
    not_run = "; ".join(f"level {int(lv)} not run ({msg})"
                        for lv, msg in zip(skipped.level, skipped.message))
    solved = facets[facets.status == "converged"]
    slack = FACET_BRACKET_SLACK * solved.energy.abs()
    inside = ((solved.energy_gap >= -slack) & (solved.energy_gap <= solved.gap_bound + slack))
    rows = [CLAIMS["facet_bracket"].row(f"{int(inside.sum())} of {len(facets)}",
                                        passed=bool(inside.all()) and len(solved) == len(facets),
                                        judged=len(facets) > 0, scene=scene,
                                        not_run=f"; {not_run}" if not_run else "",
                                        reason=not_run.replace("{", "{{").replace("}", "}}"))]
    if facets.empty:
        return rows + [CLAIMS[name].absent(not_run, scene=scene)
                       for name in ("facet_energy", "facet_energy_all", "facet_displacement")]
    complete_levels = [lv for lv, g in facets.groupby("level") if (g.status == "converged").all()]
    top = facets[facets.level == (max(complete_levels) if complete_levels
                                  else facets.level.max())].sort_values("facets")
    ok = bool(complete_levels) and len(top) >= FACET_FIT_LAST
    why = (f"{int((top.status == 'converged').sum())} of {len(top)} faceted paths converged"
           + ("" if top.message.isna().all() else f": {top.message.dropna().iloc[0]}"))
    k = top.facets.to_numpy(dtype=float)
    fit = lambda column, last: fitted_slope(k, top[column], last=last) if ok else np.nan
    fields = dict(scene=scene, level=int(top.level.iloc[0]), ratio=float(top.ratio.iloc[0]))
    listed = lambda ks: ", ".join(str(int(x)) for x in ks)
    return rows + [
        CLAIMS["facet_energy"].row(fit("energy_gap", FACET_FIT_LAST), judged=ok, reason=why,
                                   facets=listed(k[-FACET_FIT_LAST:]), **fields),
        CLAIMS["facet_energy_all"].row(fit("energy_gap", len(k)), facets=listed(k), **fields),
        CLAIMS["facet_displacement"].row(fit("err_energy", len(k)), facets=listed(k), **fields)]


def _time_ratio(timing: pd.DataFrame, scene: str, start: str = "nested",
                claim: str = "tnnmg_time") -> list[dict]:
    """TNNMG's time to the target from ``start`` over the linear floor's (from zero) at
    the finest timed level, per ratio (a level where either did not reach the target,
    or without a run from ``start``, gives its reason; tables without a ``start`` column
    time from zero; a nested run's time includes its coarser levels')."""
    rows = []
    starts = timing.start.fillna("cold")
    for ratio, g in timing.groupby("ratio", sort=True):
        top = g[g.N == g.N.max()]
        tn = top[(top.solver == "tnnmg") & (starts[top.index] == start)]
        fl = top[top.solver == "linear_floor"]
        if not len(tn) and start == "warm":      # a table without warm runs
            continue
        fields = dict(scene=scene, ratio=ratio, level=int(top.level.iloc[0]),
                      N=f"{int(top.N.iloc[0]):,}", target=float(top.target.iloc[0]))
        if len(tn) and len(fl) and np.isfinite(float(tn.t_to_target.iloc[0])) and \
                np.isfinite(float(fl.t_to_target.iloc[0])):
            rows.append(CLAIMS[claim].row(
                float(tn.t_to_target.iloc[0] / fl.t_to_target.iloc[0]),
                judged=int(top.N.iloc[0]) >= TIME_BAR_MIN_N,
                reason=f"the bar is judged from N = {TIME_BAR_MIN_N:,} (the fine levels "
                       "it is set for; the full scale)", **fields))
        else:
            said = "; ".join(f"{r.solver} ({starts[r.Index]}): {r.status}"
                             for r in top.itertuples())
            rows.append(CLAIMS[claim].row(np.nan, judged=False, reason=(
                f"no TNNMG run from this start at level {fields['level']} (nested needs a "
                "coarser level)" if not len(tn) else
                f"not both reached the target ({said})"), **fields))
    return rows


def _verified(solved: pd.DataFrame, scene: str) -> dict:
    """The solver runs verified ``converged`` among those that ran: a run its solver
    skipped at once (a size beyond its limit, a law it does not take) is named in the
    claim's conditions with its level, not counted as a run that failed."""
    skipped = solved[solved.status == "skipped"]
    ran = solved[solved.status != "skipped"]
    good = int((ran.status == "converged").sum())
    row = CLAIMS["verified"].row(f"{good} of {len(ran)}", passed=good == len(ran),
                                 judged=len(ran) > 0, scene=scene, reason="no solver ran")
    if len(skipped):
        names = sorted({f"{n} at level {int(lv)}" for n, lv in zip(skipped.solver,
                                                                     skipped.level)})
        row["parameters"] += f"; skipped at once, not counted: {', '.join(names)}"
    return row


def _agreement(t: pd.DataFrame, scene: str) -> dict:
    """The largest energy distance to the reference over the (level, ratio) pairs where
    every solver ran verified (a solver that skipped a level at once is left out there,
    and named nowhere if it ran nowhere)."""
    solved = t[t.role == "solver"]
    every = solved.solver.dropna().nunique()
    groups = [g[g.status != "skipped"] for _, g in solved.groupby(["level", "ratio", "start"],
                                                                   dropna=False)
              if len(g) == every]
    both = [g for g in groups if len(g) and (g.status == "converged").all()]
    names = sorted({name for g in both for name in g.solver})
    levels = sorted({int(g.level.iloc[0]) for g in both})
    worst = max((float(g.err_energy.max()) for g in both), default=np.nan)
    return CLAIMS["agreement"].row(worst, judged=bool(both), scene=scene,
                                   solvers=", ".join(names) or "no solver",
                                   levels=", ".join(map(str, levels)) or "none",
                                   reason="no level where every solver ran verified")


def no_reference(runs: pd.DataFrame) -> str:
    """Why a scene's runs hold no reference answer (the skipped rows' messages)."""
    ref = runs[runs.role == "reference"]
    said = sorted(set(ref.message.dropna())) if "message" in ref else []
    return "no level has a reference answer" + (f" ({'; '.join(said)})" if said else "")


def contact_kind(runs: pd.DataFrame) -> str:
    """``line`` or ``point``: the Hertz contact of a scene's runs (tables written before
    the study recorded it are line contacts, circle-square)."""
    if "contact" not in runs:
        return "line"
    kinds = runs.contact.dropna().unique()
    return str(kinds[0]) if len(kinds) else "line"


def _tnnmg_growth(solved: pd.DataFrame, contact_nodes: pd.Series, scene: str,
                  resolved_nodes: int, claim: str = "tnnmg_steps") -> list[dict]:
    """TNNMG's tangential-step iterations over the last two levels, per ratio
    (``solved``: the solver rows of one start; ``contact_nodes``: per level, from the
    reference rows; ``resolved_nodes``: the fewest the finer level needs for the bar to
    be judged; ``claim``: the key in :data:`CLAIMS`)."""
    rows = []
    pairs = list(_last_two_levels(solved))
    if pairs and all(pair is None for _, pair in pairs):
        return [CLAIMS[claim].absent("TNNMG converged on one level only; the growth needs "
                                     "two", scene=scene)]
    for ratio, pair in pairs:
        if pair is None:
            continue
        coarse, fine = pair
        resolved = contact_nodes.get(fine.level, 0) >= resolved_nodes
        rows.append(CLAIMS[claim].row(
            float(fine.steps_tangential / coarse.steps_tangential), judged=resolved,
            scene=scene, ratio=ratio, level=int(fine.level), coarser=int(coarse.level),
            reason=f"level {int(fine.level)} has fewer than {resolved_nodes} "
                   "contact nodes: the bar is about fine levels (on coarse ones the stick "
                   "and slip sets still change from level to level)"))
    if not rows:                       # no converged TNNMG row from this start: say so
        said = "; ".join(sorted({f"level {int(r.level)}: {r.status}" for r in
                                 solved[solved.solver == "tnnmg"].itertuples()}))
        rows.append(CLAIMS[claim].absent(f"TNNMG did not converge ({said})" if said else
                                         "no TNNMG run from this start", scene=scene))
    return rows


def _tnnmg_face_rate(solved: pd.DataFrame, scene: str) -> list[dict]:
    """TNNMG's contraction on the tangential step's face at the finest level beside the
    next coarser one's, and the steps to and on the face at both, per ratio
    (``solved``: the solver rows of one start)."""
    rows = []
    pairs = [(ratio, pair) for ratio, pair in _last_two_levels(solved) if pair is not None]
    if not pairs:
        return [CLAIMS["tnnmg_face_rate"].absent("no two levels with a converged TNNMG run "
                                                 "from the normal step's answer",
                                                 scene=scene)]
    for ratio, pair in pairs:
        coarse, fine = pair
        both = lambda column: " -> ".join(f"{float(r[column]):g}" for r in pair)
        rows.append(CLAIMS["tnnmg_face_rate"].row(
            float(fine.contraction_tangential_on_face), scene=scene, ratio=ratio,
            level=int(fine.level), coarser=int(coarse.level),
            coarse_rate=_rate_text(float(coarse.contraction_tangential_on_face)),
            to_face=both("steps_tangential_to_face"), on_face=both("steps_tangential_on_face")))
    return rows


def _rate_text(rate: float) -> str:
    """A contraction on the face as the conditions column gives it: three digits, or why
    there is none (the face last changed at the last step)."""
    return f"{rate:.3g}" if np.isfinite(rate) else "none (no step on its face)"


def _last_two_levels(solved: pd.DataFrame):
    """Per ratio, TNNMG's converged rows of the last two levels ``(coarser, finer)``, or
    None where fewer than two levels ran."""
    tn = solved[(solved.solver == "tnnmg") & (solved.status == "converged")]
    for ratio, g in tn.groupby("ratio", sort=True):
        g = g.sort_values("N")
        yield ratio, ((g.iloc[-2], g.iloc[-1]) if len(g) >= 2 else None)


def _coulomb(co: pd.DataFrame, scene: str) -> dict:
    """Coulomb's fixed point: converged in every load step; its Tresca solves per level."""
    if not len(co):
        return CLAIMS["coulomb"].absent("no Coulomb runs at this configuration", scene=scene)
    per_level = "; ".join(
        f"level {int(lv)}: " + " + ".join(str(int(s)) for s in g.sort_values("load_step")
                                           .tresca_solves)
        + f" (contraction {g.contraction.max():.2g})"
        for lv, g in co.groupby("level", sort=True))
    good = int((co.status == "converged").sum())
    return CLAIMS["coulomb"].row(f"{good} of {len(co)} load steps; {per_level}",
                                 passed=good == len(co), scene=scene)


def _finest(runs: pd.DataFrame, profiles: pd.DataFrame) -> tuple[bool, pd.DataFrame, list]:
    """``(line contact?, the finest level's profiles, their ratios)`` (``profiles``
    not empty)."""
    top = profiles[profiles.N == profiles.N.max()]
    return contact_kind(runs) == "line", top, sorted(top.ratio.unique())


def traction_figure(runs: pd.DataFrame, profiles: pd.DataFrame, path: str) -> None:
    """The tangential traction at the finest level, one panel per ratio: measured nodes,
    the Cattaneo-Mindlin curve, mu p (measured and Hertz)."""
    scene = runs.scene.iloc[0]
    if not len(profiles):
        return nothing_to_draw(path, f"{scene}: tangential traction", no_reference(runs))
    line, top, ratios = _finest(runs, profiles)
    fig, axes = plt.subplots(1, len(ratios), figsize=(5.5 * len(ratios), 4.2), squeeze=False)
    for ax, ratio in zip(axes[0], ratios):
        g = top[top.ratio == ratio].sort_values("x_over_a")
        ref = runs[(runs.role == "reference") & (runs.ratio == ratio)
                   & (runs.N == g.N.iloc[0])].iloc[0]
        x = np.linspace(-1.2 if line else 0.0, 1.2, 481)
        c = float(ref.c_over_a_exact)
        e = float(ref.stick_offset) if line else 0.0       # the stick zone's centre over a
        e = 0.0 if np.isnan(e) else e
        mu_p0 = float(ref.mu) * float(ref.p0)
        outer = mu_p0 * np.sqrt(np.clip(1 - x ** 2, 0, None))
        inner = mu_p0 * c * np.sqrt(np.clip(1 - ((x - e) / c) ** 2, 0, None))
        ax.plot(x, outer - inner, "-", color="C0", label="Cattaneo-Mindlin q(x)")
        ax.plot(x, outer, ":", color="gray", label="mu p(x), Hertz")
        ax.plot(g.x_over_a, g.mu_pressure, "x", color="gray", ms=4, label="mu p, measured")
        for state, style in (("stick", "o"), ("slip", "s")):
            h = g[g.state == state]
            if len(h):
                ax.plot(h.x_over_a, h.traction, style, color="C1" if state == "stick" else "C3",
                        ms=4, ls="none", label=f"traction, {state} nodes")
        ax.axvspan(e - c if line else 0.0, e + c, color="C0", alpha=0.06)
        ax.set_xlim(-1.25 if line else 0.0, 1.25)
        ax.set_xlabel("x / a (contact half-width a, measured)" if line else
                      "r / a (distance from the contact's centre; radius a, measured)")
        ax.set_ylabel("tangential traction (units of E)" if line else
                      "tangential traction along Q (units of E)")
        ax.set_title(f"{scene}: level {int(ref.level)}, Q/(mu P) = {ratio:g}, "
                     f"L2 error {float(ref.traction_l2):.1%}", fontsize=9)
        ax.grid(True, alpha=0.3)
        legend_below(ax, ncol=2)
    save_figure(fig, path)


def stick_figure(runs: pd.DataFrame, path: str) -> None:
    """c/a against Q/(mu P): the measured points per level, the analytic curve."""
    scene = runs.scene.iloc[0]
    kind = contact_kind(runs)
    ref = runs[(runs.role == "reference") & (runs.status == "converged")]
    fig, ax = plt.subplots(figsize=(6, 4.5))
    r = np.linspace(0, 1, 201)
    ax.plot(r, [stick_zone_ratio(x, kind) if x < 1 else 0.0 for x in r], "-", color="gray",
            label=CM_CURVE[kind])
    for i, (level, g) in enumerate(ref.groupby("level", sort=True)):
        ax.plot(g.ratio_reached, g.c_over_a, "o", color=f"C{i}", ls="none",
                label=f"level {int(level)} (N = {int(g.N.iloc[0]):,}, "
                      f"{int(g.contact_nodes.iloc[0])} contact nodes)")
    ax.set_xlabel("load ratio Q / (mu P) (dimensionless)")
    ax.set_ylabel("stick-zone half-width c / a (dimensionless)" if kind == "line" else
                  "stick-zone radius c / a (dimensionless)")
    ax.set_title(f"{scene}: Cattaneo-Mindlin stick zone")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1.05)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    save_figure(fig, path)


def map_figure(runs: pd.DataFrame, profiles: pd.DataFrame, path: str) -> None:
    """Stick and slip nodes in the contact plane at the finest level, one panel per ratio,
    with the measured contact size a (circle of radius 1) and Cattaneo-Mindlin's c/a."""
    scene = runs.scene.iloc[0]
    if not len(profiles):
        return nothing_to_draw(path, f"{scene}: stick and slip nodes", no_reference(runs))
    line, top, ratios = _finest(runs, profiles)
    n = len(ratios)
    fig, axes = plt.subplots(1, n, figsize=(5.5 * n, 3.0 if line else 5.0), squeeze=False)
    angle = np.linspace(0, 2 * np.pi, 241)
    for ax, ratio in zip(axes[0], ratios):
        g = top[(top.ratio == ratio) & (top.x_over_a.abs() <= 1.5)]
        ref = runs[(runs.role == "reference") & (runs.ratio == ratio)
                   & (runs.N == g.N.iloc[0])].iloc[0]
        c = float(ref.c_over_a_exact)
        for state, style, colour in (("stick", "o", "C1"), ("slip", "s", "C3"),
                                     ("free", ".", "gray")):
            h = g[g.state == state]
            if len(h):
                ax.plot(h.px_over_a, h.py_over_a, style, color=colour, ms=4, ls="none",
                        label=f"{state} nodes ({len(h)})")
        if line:
            ax.axvspan(-c, c, color="C0", alpha=0.08, label=f"|x| < c: stick zone, c/a = {c:.3f}")
            ax.axvline(-1, color="gray", ls=":")
            ax.axvline(1, color="gray", ls=":", label="|x| = a, measured")
            ax.set_ylim(-0.4, 0.4)
            ax.set_yticks([])
        else:
            ax.plot(np.cos(angle), np.sin(angle), ":", color="gray", label="r = a, measured")
            ax.plot(c * np.cos(angle), c * np.sin(angle), "-", color="C0",
                    label=f"r = c, Cattaneo-Mindlin (c/a = {c:.3f})")
            ax.set_aspect("equal")
            ax.set_ylabel("y / a (contact plane)")
        ax.set_xlabel("x / a (contact plane; the tangential load along x)")
        ax.set_title(f"{scene}: level {int(ref.level)}, Q/(mu P) = {ratio:g}, measured c/a "
                     f"{float(ref.c_over_a):.3f}", fontsize=9)
        ax.grid(True, alpha=0.3)
        legend_below(ax, ncol=2)
    save_figure(fig, path)


def cost_figure(runs: pd.DataFrame, path: str) -> None:
    """Tangential-step iterations (top) and solve time (whole path, bottom) against N per
    solver and ratio, with fitted exponents; one legend for both panels, below them."""
    scene = runs.scene.iloc[0]
    solved = runs[(runs.role == "solver") & (runs.status == "converged")]
    if not len(solved):
        return nothing_to_draw(path, f"{scene}: the solvers' cost",
                               "no solver run was verified converged")
    starts = solved.start.fillna("warm")
    curves = solved.groupby(["solver", "ratio", starts], sort=True)
    fig, axes = plt.subplots(2, 1, figsize=(7.5, 6.4 + 0.16 * curves.ngroups), sharex=True)
    for (name, ratio, start), g in curves:
        g = g.sort_values("N")
        t = g.t_setup + g.t_solve + g.t_solve_coarse.fillna(0.0)   # nested: with below
        style = _cost_style(name, start, ratio == min(solved.ratio), g.N.nunique())
        growth = _growth(g.N, {"iterations": g.steps_tangential, "time": t})
        for ax, y in zip(axes, (g.steps_tangential, t)):
            ax.plot(g.N, y, **style, label=f"{name} ({start}), Q/(mu P) = {ratio:g}: {growth}")
    axes[0].set_xscale("log")
    axes[1].set_xscale("log")
    axes[1].set_yscale("log")
    axes[0].set_ylabel("iterations of the tangential\nload step (finest level)")
    axes[1].set_ylabel("setup + solve time of the\nload path [s] (this machine)")
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
    axes[1].set_xlabel("nodes N")
    fig.suptitle(f"{scene}: Tresca friction, the solvers' cost", fontsize=10)
    legend_below(axes[1])
    save_figure(fig, path)


def _growth(n: pd.Series, quantities: dict[str, pd.Series]) -> str:
    """The fitted exponents against ``n`` of each quantity, as a legend reads them
    ("one size, no exponent" at one size; "none" where a fit has no answer)."""
    if n.nunique() < 2:
        return "one size, no exponent"
    fits = {q: fitted_slope(n, y, last=len(n)) for q, y in quantities.items()}
    return "exponents " + ", ".join(f"{v:.2f} ({q})" if np.isfinite(v) else f"none ({q})"
                                    for q, v in fits.items())


def _cost_style(name: str, start: str, low: bool, sizes: int) -> dict:
    """The cost figure's style of one solver's runs: the solver's colour and marker of
    every figure, a solid (``low``: the smaller ratio) or dashed line, hollow and lighter
    from zero (cold), hollow and dash-dotted or dotted from the coarser levels (nested);
    no line at one size."""
    style = {**solver_style(name), "ls": "-" if low else "--"}
    if start == "cold":
        style.update(mfc="none", alpha=0.55)
    elif start == "nested":
        style.update(ls="-." if low else ":", mfc="none")
    if sizes < 2:
        style["ls"] = "none"
    return style


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", required=True)
    parser.add_argument("--profiles", required=True)
    parser.add_argument("--claims", required=True)
    parser.add_argument("--traction", required=True)
    parser.add_argument("--stick", required=True)
    parser.add_argument("--cost", required=True)
    parser.add_argument("--map", required=True)
    args = parser.parse_args(argv)
    runs, profiles = complete(read_csv(args.runs)), read_csv(args.profiles)
    write_csv(args.claims, claims(runs))
    traction_figure(runs, profiles, args.traction)
    stick_figure(runs, args.stick)
    map_figure(runs, profiles, args.map)
    cost_figure(runs, args.cost)


if __name__ == "__main__":
    main()
