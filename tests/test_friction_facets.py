"""The faceted friction law (``friction_facets`` = k: the disc replaced by the inscribed
regular k-gon): the k-gon's projection, support function and gauge against exact answers,
its QP (:func:`problems.friction.forms.facet_program`) and the map of its multipliers,
the exact reference on faceted steps against every QP library, the solvers that skip it,
its distance to the isotropic law as k grows (cube_sphere level 0), and the parameter's
checks at the CLI."""
from __future__ import annotations

import functools
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from problems.friction.forms import (facet_program, facet_weights, lift, program_multipliers,
                                     tresca_step)
from problems.friction.polygon import (REGION_INSIDE, polygon_gauge, polygon_normals,
                                       polygon_regions, polygon_support, polygon_vertices,
                                       project_polygon, region_projection)
from problems.friction.residuals import friction_residuals, tresca_energy
from problems.kkt import energy_error
from problems.qp import QPValidationError
from problems.spec import ParameterError, problems
from solvers.interface import solve, solvers
from solvers.qp_libraries import LIBRARIES
from report.claims import NO_RUN
from report.friction import FACET_ENERGY_EXPONENT, FACET_FIT_LAST, complete, facet_claims
from report.rates import fitted_slope
from solvers.kernels.tresca import facet_convergence, friction_path
from workflows.cli import main
from workflows.studies.friction.run import facet_rows
from agreement import within_certificate

SCENE = problems()["cube_sphere"]
#: the tangential step of cube_sphere level 0 with sticking and slipping nodes
SHIFT = 0.05


@functools.lru_cache(maxsize=None)
def _isotropic():
    """The isotropic frictional cube_sphere level 0 (mu = 0.5)."""
    return SCENE.make(0, friction="tresca", mu=0.5, shift=SHIFT)


def _faceted(k: int):
    """The same problem with the k-gon law (the same A, B, T: its dual operators shared)."""
    qp = _isotropic()
    return replace(qp, friction=replace(qp.friction, facets=k))


@functools.lru_cache(maxsize=None)
def _exact_step(k: int):
    """``(step_qp, solution)``: the tangential step of the exact faceted load path."""
    last = friction_path(_faceted(k))[-1]
    return last.qp, last.solution


# ----------------------------------------------------------------------------- the k-gon
def test_the_square_has_its_exact_vertices_normals_support_and_gauge():
    np.testing.assert_allclose(polygon_vertices(4), [[1, 0], [0, 1], [-1, 0], [0, -1]],
                               atol=1e-15)
    r = np.sqrt(0.5)
    np.testing.assert_allclose(polygon_normals(4), [[r, r], [-r, r], [-r, -r], [r, -r]],
                               atol=1e-15)
    x = np.array([[3.0, 0.0], [1.0, 1.0], [-2.0, 0.5], [0.5, 0.5]])
    np.testing.assert_allclose(polygon_support(x, 4), [3.0, 1.0, 2.0, 0.5], rtol=1e-15)
    np.testing.assert_allclose(polygon_gauge(x, 4), [3.0, 2.0, 2.5, 1.0], rtol=1e-15)


def test_the_square_projects_onto_its_facets_and_vertices_exactly():
    z = np.array([[1.0, 1.0], [3.0, 0.2], [0.1, -0.2], [-2.0, 2.0], [0.0, 0.0]])
    s = np.array([1.0, 2.0, 1.0, 2.0, 0.0])
    projection, region = polygon_regions(z, s, 4)
    np.testing.assert_allclose(projection, [[0.5, 0.5], [2.0, 0.0], [0.1, -0.2], [-1.0, 1.0],
                                            [0.0, 0.0]], atol=1e-15)
    # facet 0's interior; vertex 0; inside; facet 1's interior; inside
    assert region.tolist() == [2, 3, REGION_INSIDE, 4, REGION_INSIDE]


@pytest.mark.parametrize("k", [3, 5, 8, 33])
def test_the_projection_onto_a_k_gon_is_its_variational_inequality(k):
    """``x = P(z)`` lies in ``s P_k`` and ``(z - x) . (s v_j - x) <= 0`` at every vertex (the
    k-gon is their convex hull): the projection's characterisation; and each point's
    region's affine map (:func:`region_projection`) reproduces it."""
    rng = np.random.default_rng(k)
    z = 3 * rng.standard_normal((400, 2))
    s = rng.uniform(0.5, 2.0, 400)
    x, region = polygon_regions(z, s, k)
    scale = np.abs(z).max()
    assert np.all(polygon_gauge(x, k) <= s * (1 + 1e-14))
    vertices = s[:, None, None] * polygon_vertices(k)[None]
    inequality = np.einsum("nd,nkd->nk", z - x, vertices - x[:, None, :])
    assert inequality.max() <= 1e-13 * scale ** 2
    inside = polygon_gauge(z, k) <= s
    assert 0 < inside.sum() < len(z) and np.array_equal(x[inside], z[inside])
    np.testing.assert_allclose(region_projection(z, s, k, region)[0], x, atol=1e-13 * scale)
    np.testing.assert_allclose(project_polygon(z, s, k), x, rtol=0, atol=0)


@pytest.mark.parametrize("k", [3, 8])
def test_facet_weights_write_a_point_of_the_k_gon_as_its_rows_multipliers(k):
    rng = np.random.default_rng(1)
    s = rng.uniform(0.5, 2.0, 200)
    lam = project_polygon(3 * rng.standard_normal((200, 2)), s, k)
    a = facet_weights(lam, s, k)
    assert a.min() >= -1e-14
    np.testing.assert_allclose(a.sum(axis=1), s, rtol=1e-14)
    np.testing.assert_allclose(a @ polygon_vertices(k), lam, atol=1e-14)


# ----------------------------------------------------------------------------- the model
def test_facets_zero_is_the_isotropic_law_bit_for_bit():
    qp = _isotropic()
    assert qp.friction.facets == 0
    explicit = SCENE.make(0, friction="tresca", mu=0.5, shift=SHIFT, friction_facets=0)
    a, b = friction_path(qp)[-1], friction_path(explicit)[-1]
    for name in ("u", "p", "lam"):
        assert np.array_equal(getattr(a.solution, name), getattr(b.solution, name)), name
    fr = a.qp.friction
    slip = fr.slip(a.solution.u)
    assert np.array_equal(fr.dissipation(slip), fr.magnitude(slip))
    assert np.array_equal(fr.gauge(a.solution.lam), fr.magnitude(a.solution.lam))


@pytest.mark.parametrize("params, match", [
    ({"friction": "tresca", "friction_facets": 2}, "friction_facets"),
    ({"friction": "tresca", "friction_facets": -1}, "friction_facets"),
    ({"friction": "none", "friction_facets": 8}, "friction_facets")])
def test_bad_facets_are_refused_by_name(params, match):
    with pytest.raises(ParameterError, match=f"'{match}'.*allowed"):
        SCENE.make(0, **params)


def test_facets_on_a_2d_friction_are_refused():
    qp = problems()["circle_square"].make(0, friction="tresca", mu=0.5, shift=0.03)
    with pytest.raises(QPValidationError, match=r"friction.facets = 4 is not allowed in 2D; "
                                                 r"allowed: 0"):
        replace(qp, friction=replace(qp.friction, facets=4))
    with pytest.raises(ParameterError, match="friction_facets"):
        problems()["circle_square"].make(0, friction="tresca", friction_facets=4)


def test_the_cli_refuses_bad_facets_with_exit_2(tmp_path, capsys):
    code = main(["solve", "--problem", "cube_sphere", "--level", "0", "--solver", "osqp",
                 "--out", str(tmp_path / "run.json"), "--set", "friction=tresca",
                 "--set", "mu=0.5", "--set", "friction_facets=2"])
    assert code == 2
    err = capsys.readouterr().err
    assert "friction_facets" in err and "allowed" in err and "Traceback" not in err


# ----------------------------------------------------------------------------- the forms
def test_the_facet_program_at_the_exact_answer_is_its_kkt_point():
    """``x = lift(u)``, ``y = program_multipliers(p, lam)`` of the exact faceted step:
    ``Px + q + G'y = 0``, ``y >= 0``, ``Gx <= h`` and ``y . (h - Gx) = 0`` to round-off."""
    qp, sol = _exact_step(8)
    step = tresca_step(qp)
    program = facet_program(step)
    assert program.cones == () and program.kind == "facet"
    x = lift(step, program, sol.u)
    y = program_multipliers(step, program, sol.p, sol.lam)
    stat = program.P @ x + program.q + program.G.T @ y
    scale = np.abs(program.q).max()
    assert np.abs(stat).max() <= 1e-11 * scale
    slack = program.h - program.G @ x
    assert y.min() >= -1e-14 * y.max() and slack.min() >= -1e-12 * np.abs(program.h).max()
    assert abs(y @ slack) <= 1e-12 * abs(tresca_energy(qp, sol.u))


# ----------------------------------------------------------------------------- the solvers
def test_the_exact_reference_takes_a_faceted_step_and_verifies():
    qp, sol = _exact_step(8)
    res = solve(qp, "tresca_exact", tol="high")
    assert res.status == "converged" and res.kkt.max <= 1e-12
    assert np.array_equal(res.u, sol.u)
    # the isotropic answer is no answer of the faceted step: its residuals refute it
    iso = friction_path(_isotropic())[-1]
    wrong = friction_residuals(qp, iso.solution.u, iso.solution.p, iso.solution.lam)
    assert wrong.slip_complementarity > 1e-6


#: a library's answer at ``high`` (tol 1e-9) against the exact one: the Tresca energy
#: within 1e-8 (measured <= 1e-11), the energy-norm error within sqrt(tol) (measured
#: <= 2.6e-6: HiGHS)
ENERGY_BAR, NORM_BAR = 1e-8, np.sqrt(1e-9) * 100


def test_every_qp_library_takes_a_faceted_3d_step():
    """The QP-only libraries, which skip an isotropic 3D step, take the faceted one (a
    QP), as the conic ones do: each claims converged, its energy agrees with the exact
    reference to 1e-8, and the suite's certified bound holds against the exact answer."""
    qp, sol = _exact_step(8)
    J = tresca_energy(qp, sol.u)
    for lib in LIBRARIES:
        assert solvers()[lib.name].check(qp) == (True, ""), lib.name
        res = solve(qp, lib.name, tol="high")
        assert res.claimed_status == "converged", (lib.name, res.message)
        assert res.stats["form"] == "facet"
        assert abs(tresca_energy(qp, res.u) - J) <= ENERGY_BAR * abs(J), lib.name
        err = energy_error(qp, res.u, sol.u)
        assert err <= NORM_BAR, (lib.name, err)
        assert res.gap.certified and within_certificate(err, res.gap.certified_bound,
                                                        res.gap.floor), lib.name
        assert res.status in ("converged", "inaccurate"), lib.name
        if res.status == "converged":
            assert res.kkt.max <= res.tol


@pytest.mark.parametrize("name", ["tnnmg", "semismooth_newton"])
def test_the_isotropic_solvers_skip_a_faceted_step_with_the_reason(name):
    qp, _ = _exact_step(8)
    res = solve(qp, name, tol="high")
    assert res.status == "skipped" and "faceted friction (friction_facets = 8)" in res.message


# ----------------------------------------------------------------------------- the limit
#: the facet counts of the convergence test: powers of two (the slip directions lie near
#: the first tangent, along a vertex for every k, so the error oscillates between k and
#: 2k; over six doublings the fit averages that out)
FACETS = (8, 16, 32, 64, 128, 256)


@functools.lru_cache(maxsize=None)
def _table():
    return facet_convergence(_isotropic(), FACETS)


def test_the_faceted_energy_is_bracketed_by_the_isotropic_one():
    """``P_k`` lies between the disc of radius ``cos(pi/k)`` and the unit disc, so
    ``0 <= J_iso* - J_k* <= (1 - cos(pi/k)) D_iso(u_k)`` (``D_iso`` the isotropic
    dissipation ``sum_i s_i |slip_i|``) -- exact, up to the solutions' round-off."""
    for row in _table():
        slack = 1e-12 * abs(row["energy"])
        assert -slack <= row["energy_gap"] <= row["gap_bound"] + slack, row


def test_the_faceted_law_converges_like_k_to_the_minus_2_in_energy():
    """The energy gap ``J_iso* - J_k*`` falls like ``k^-2`` (fitted exponent -2.06 over
    k = 8..256 at cube_sphere level 0; over k = 8, 16, 32 alone -1.67: the oscillation
    between k and 2k); the displacement (energy norm) only like ``k^-1`` (-1.00; the
    traction's -1.01): at a slipping node the traction's direction is a vertex of the
    k-gon, off by up to ``pi / k``. Bars +-0.3 on both."""
    table = _table()
    k = np.array([row["facets"] for row in table])
    energy = fitted_slope(k, [row["energy_gap"] for row in table], last=len(k))
    displacement = fitted_slope(k, [row["displacement"] for row in table], last=len(k))
    assert -2.3 <= energy <= -1.7, energy
    assert -1.3 <= displacement <= -0.7, displacement
    assert all(row["status"] == "converged" for row in table)


# ----------------------------------------------------------------------------- the study
def test_the_study_reports_the_faceted_law_and_its_claims():
    """The friction study's ``facets`` rows (cube_sphere level 0) and their claims: the
    bracket judged at every k, the exponents fitted from the rows; a fallback reference
    gives one ``skipped`` row with the reason, a 2D scene none."""
    qp = _isotropic()
    rows = facet_rows(qp, list(FACETS), "tresca_exact")
    assert [r["facets"] for r in rows] == list(FACETS)
    assert [r["energy_gap"] for r in rows] == [r["energy_gap"] for r in _table()]
    runs = complete(pd.DataFrame([{"scene": "cube_sphere", "level": 0, "ratio": 0.7, **r}
                                  for r in rows]))
    table = {row["claim"]: row for row in facet_claims(runs, "cube_sphere")}
    bracket, last, every, displacement = table.values()
    assert bracket["pass"] is True and bracket["measured"] == f"{len(FACETS)} of {len(FACETS)}"
    k = np.array(FACETS)
    gaps = [r["energy_gap"] for r in rows]
    assert last["measured"] == fitted_slope(k[-FACET_FIT_LAST:], gaps[-FACET_FIT_LAST:],
                                            last=FACET_FIT_LAST)
    assert last["pass"] == (FACET_ENERGY_EXPONENT[0] <= last["measured"]
                            <= FACET_ENERGY_EXPONENT[1])
    assert every["measured"] == fitted_slope(k, gaps, last=len(k)) and every["pass"] is None
    assert displacement["pass"] is None
    skipped = facet_rows(qp, [8], "semismooth_newton")
    assert skipped[0]["status"] == "skipped" and "tresca_exact" in skipped[0]["message"]
    plane = problems()["circle_square"].make(0, friction="tresca", mu=0.5, shift=0.03)
    assert facet_rows(plane, [8], "tresca_exact") == []
    assert facet_claims(complete(pd.DataFrame({"role": []})), "circle_square", "line") == []
    none = facet_claims(complete(pd.DataFrame({"role": []})), "cube_sphere", "point")
    assert len(none) == 1 and none[0]["pass"] is None and none[0]["level"] == ""
    assert none[0]["reason"].startswith(NO_RUN)


def test_a_level_without_faceted_paths_is_named_not_counted_as_a_path():
    """The full scale's cube_sphere: the faceted paths at the levels ``tresca_exact`` takes,
    one ``skipped`` row at the finest (its reference is semismooth Newton). The bracket is
    judged over the paths run and names the level not run; a path outside its bracket, or
    one that ran and did not converge, fails it; with no path run it is not judged."""
    qp = _isotropic()
    rows = [{"scene": "cube_sphere", "level": 0, "ratio": 0.7, **r}
            for r in facet_rows(qp, list(FACETS), "tresca_exact")]
    skipped = {"scene": "cube_sphere", "level": 3, "ratio": 0.7,
               **facet_rows(qp, list(FACETS), "semismooth_newton")[0]}
    bracket, *energy = facet_claims(complete(pd.DataFrame(rows + [skipped])), "cube_sphere")
    assert bracket["pass"] is True and bracket["measured"] == f"{len(FACETS)} of {len(FACETS)}"
    assert "level 3 not run (the reference here is semismooth_newton" in bracket["parameters"]
    assert energy[0]["level"] == "0" and energy[0]["measured"] == facet_claims(
        complete(pd.DataFrame(rows)), "cube_sphere")[1]["measured"]
    outside = [dict(r) for r in rows]
    outside[2]["energy_gap"] = outside[2]["gap_bound"] * 1.01
    assert facet_claims(complete(pd.DataFrame(outside + [skipped])),
                        "cube_sphere")[0]["pass"] is False
    failed = [dict(r) for r in rows]
    for r in failed:
        r["status"] = "failed"
    assert facet_claims(complete(pd.DataFrame(failed)), "cube_sphere")[0]["pass"] is False
    only = facet_claims(complete(pd.DataFrame([skipped])), "cube_sphere")
    assert only[0]["pass"] is None and "level 3 not run" in only[0]["reason"]
    assert len(only) == 4 and all(row["pass"] is None for row in only)
