"""The coupling study at tiny levels on circle-square and cube-sphere: the script and the
report builder end to end, the claims table, the measured errors, the figures, the
script's argument checks, and the 3D P1 interpolation onto the reference."""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from report import coupling as report
from report.claims import COLUMNS
from workflows.io import read_csv
from workflows.studies.coupling import run as script
from workflows.studies import ConfigError, check_config, load_config

ROOT = Path(__file__).resolve().parent.parent

COUPLINGS = ["nodal", "stabilised", "mortar", "mortar_dual"]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """circle_square levels 0 and 1 against a mortar_dual reference at level 2, and the
    report's outputs."""
    d = tmp_path_factory.mktemp("coupling")
    table = d / "results" / "circle_square" / "coupling.csv"
    script.main(["--problem", "circle_square", "--levels", "0", "1", "--reference-level", "2",
                 "--out", str(table)])
    out = {"claims": d / "claims.csv", "figure": d / "coupling.png",
           "hertz": d / "coupling_hertz.png"}
    report.main(["--tables", str(table), "--claims", str(out["claims"]),
                 "--figure", str(out["figure"]), "--hertz-figure", str(out["hertz"])])
    return read_csv(table), out


def test_every_solve_is_exact_and_verified(run):
    t, _ = run
    ref = t[t.role == "reference"]
    assert len(ref) == 1 and ref.coupling.iloc[0] == "mortar_dual" and ref.level.iloc[0] == 2
    c = t[t.role == "compared"]
    assert sorted(zip(c.coupling, c.level)) == sorted((k, lv) for k in COUPLINGS for lv in (0, 1))
    assert (t.status == "converged").all() and (t.solver == "pdas").all()
    assert (t.kkt_max < 1e-8).all()                   # the 'high' preset's verified residuals


def test_the_errors_against_the_reference_are_measured_and_fall(run):
    t, _ = run
    c = t[t.role == "compared"].set_index(["coupling", "level"])
    for k in COUPLINGS:
        e0, e1 = c.loc[(k, 0), "err_energy"], c.loc[(k, 1), "err_energy"]
        assert 0 < e1 < e0 < 1, (k, e0, e1)
    # the dual mortar, the reference's coupling: the nested difference falls about as h
    # (measured 0.222 -> 0.113 from level 0 to 1, ratio 0.51; O(h) would give 0.5)
    e0, e1 = c.loc[("mortar_dual", 0), "err_energy"], c.loc[("mortar_dual", 1), "err_energy"]
    assert 0.3 < e1 / e0 < 0.75, (e0, e1)
    # the multiplier error in the dual norm: measured for every coupling, falling from
    # level 0 to 1 (measured ratios 0.32-0.60; mortar_dual 0.046 -> 0.021, 0.45)
    for k in COUPLINGS:
        d0, d1 = c.loc[(k, 0), "err_pressure_dual"], c.loc[(k, 1), "err_pressure_dual"]
        assert 0 < d1 < d0 < 1, (k, d0, d1)
    d0, d1 = c.loc[("mortar_dual", 0), "err_pressure_dual"], c.loc[("mortar_dual", 1), "err_pressure_dual"]
    assert d1 / d0 < 0.75, (d0, d1)
    # Hertz: every coupling's half-width and peak within 30 % at these coarse levels
    for k in COUPLINGS:
        row = c.loc[(k, 1)]
        assert abs(row.a_moment / row.a_hertz - 1) < 0.3 and abs(row.p0_moment / row.p0_hertz - 1) < 0.3
        assert 0 < row.err_force < 0.05 and 0 < row.dev_hertz_rms < 0.5


def test_the_claims_table_has_every_claim_with_a_status_or_a_reason(run):
    _, out = run
    claims = read_csv(out["claims"])
    assert list(claims.columns) == COLUMNS
    first = claims.iloc[0]
    assert "converged" in first.claim and first.measured == "9 of 9" and first["pass"] == True  # noqa: E712
    for _, row in claims.iterrows():
        judged = isinstance(row["pass"], (bool, np.bool_)) or str(row["pass"]) in ("True", "False")
        assert judged or (isinstance(row.reason, str) and len(row.reason) > 10), row.to_dict()
    # two levels: the mortar rates (three levels) are not judged here and say why
    mortar = claims[claims.claim.str.contains("mortar")
                    & claims.claim.str.contains("energy-error rate")]
    assert len(mortar) == 2 and mortar.reason.str.contains("needs 3 levels").all()
    # the multiplier's dual-norm rate: one reported row per coupling, with its reason
    dual = claims[claims.parameters.str.contains("err_pressure_dual")]
    assert len(dual) == 4 and dual["pass"].isna().all()
    assert dual.reason.str.contains("no rate of the multiplier error alone").all()
    assert {"nodal", "stabilised"} <= {w for c in claims.claim for w in c.replace(":", " ").split()}


@pytest.mark.parametrize("dim, optimal", [(2, -1 / 2), (3, -1 / 3)])
def test_the_mortar_rate_is_judged_against_the_optimal_rate(dim, optimal):
    """Three levels of a made-up table: the fitted slope against the optimal O(h), i.e.
    -1/2 in 2D and -1/3 in 3D."""
    N = np.array([1000.0, 4000.0, 16000.0])
    rows = [{"scene": "s", "role": "reference", "coupling": "mortar_dual", "level": 5,
             "dim": dim, "N": 64000, "status": "converged"}]
    for k, r in (("mortar_dual", optimal - 0.05), ("mortar", optimal + 0.2), ("nodal", -0.25)):
        rows += [{"scene": "s", "role": "compared", "coupling": k, "level": lv, "dim": dim,
                  "N": n, "status": "converged", "err_energy": n ** r,
                  "err_pressure_dual": 3.0 * n ** (r - 0.25)}
                 for lv, n in enumerate(N)]
    claims = report.claims(pd.DataFrame(rows)).set_index("claim")
    for k, r in (("mortar_dual", optimal - 0.05), ("mortar", optimal + 0.2), ("nodal", -0.25)):
        row = claims.loc[f"{k}: rate in N of the multiplier error in the dual norm"]
        assert math.isclose(row.measured, r - 0.25, abs_tol=1e-12) and row["pass"] is None
    dual = claims.loc[[c for c in claims.index if "mortar_dual: energy" in c][0]]
    std = claims.loc[[c for c in claims.index if "mortar: energy" in c][0]]
    nodal = claims.loc[[c for c in claims.index if "nodal: energy" in c][0]]
    assert math.isclose(dual.measured, -0.05, abs_tol=1e-12) and dual["pass"] is True
    assert math.isclose(std.measured, 0.2, abs_tol=1e-12) and std["pass"] is False
    assert math.isclose(nodal.measured, -0.25, abs_tol=1e-12) and nodal["pass"] is None


def test_the_figures_decode(run):
    _, out = run
    for key in ("figure", "hertz"):
        with Image.open(out[key]) as im:
            im.load()
            assert im.size[0] > 300 and im.size[1] > 200


@pytest.mark.parametrize("argv, message", [
    (["--levels", "0", "1", "--reference-level", "2", "--set", "coupling=nodal"],
     "argument --set: 'coupling' is not allowed"),
    (["--levels", "0", "1", "--reference-level", "2", "--couplings", "glued"],
     "argument --couplings: glued is not allowed"),
    (["--levels", "0", "1", "--reference-level", "1"],
     "argument --reference-level: 1 is not allowed"),
])
def test_bad_arguments_are_refused_naming_the_argument(argv, message, tmp_path, capsys):
    out = tmp_path / "x.csv"
    with pytest.raises(SystemExit) as err:
        script.main(["--problem", "circle_square", *argv, "--out", str(out)])
    assert err.value.code == 2 and message in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("change, needle", [
    (lambda c: c["coupling"]["reference_level"].update(circle_square=2),
     "'coupling.reference_level.circle_square': 2 is not allowed; allowed: a level in 3.."),
    (lambda c: c["coupling"]["reference_level"].update(ghost=2),
     "'coupling.reference_level.ghost': not among coupling.scenes"),
    (lambda c: (c["scenes"].update(rolls={"problem": "roll_stack"}),
                c["coupling"]["scenes"].update(rolls=[0]),
                c["coupling"]["reference_level"].update(rolls=1)),
     "'coupling.scenes.rolls': problem 'roll_stack' does not offer the couplings"),
    (lambda c: (c["scenes"].update(cs_mortar={"problem": "circle_square",
                                              "params": {"coupling": "mortar"}}),
                c["coupling"]["scenes"].update(cs_mortar=[0]),
                c["coupling"]["reference_level"].update(cs_mortar=1)),
     "'coupling.scenes.cs_mortar': the scene sets 'coupling'"),
])
def test_config_errors_name_the_key(change, needle):
    config = load_config(ROOT / "workflows/config/quick.yaml")
    change(config)
    with pytest.raises(ConfigError, match=re.escape(needle)):
        check_config(config)


@pytest.fixture(scope="module")
def circle_square_pair():
    """circle_square levels 0 and 1 (mortar_dual), solved exactly, and level 1 as the
    reference."""
    from problems.spec import problems
    from workflows.reference_solution import Reference

    spec = problems()["circle_square"]
    qp0, qp1 = (spec.make(level, coupling="mortar_dual") for level in (0, 1))
    res0, _ = script.exact(qp0)
    res1, _ = script.exact(qp1)
    assert res0.status == res1.status == "converged"
    ref = Reference(qp1, res1.u, res1.p, {"solver": res1.solver, "status": res1.status,
                                          "t_solve": 0.0})
    return qp0, res0, qp1, res1, ref


def test_the_dual_norm_of_the_pressure_error(circle_square_pair):
    """err_pressure_dual = ||A^{-1/2} B_C'(m (I lambda_h - lambda_ref))|| over
    ||A^{-1/2} B' p_ref||: 0 for the reference's own pressure, 1 for no pressure (the
    difference is the reference's whole load), and for level 0 against level 1 the same
    as a sparse LU solve with the reference's A and the pressure interpolated by hand."""
    import scipy.sparse.linalg as spla

    from problems.fem.fields import in_plane

    qp0, res0, qp1, res1, ref = circle_square_pair
    assert ref.pressure_dual_error(qp1, res1.p) == 0.0
    assert abs(ref.pressure_dual_error(qp1, np.zeros(qp1.m)) - 1) < 1e-12
    assert abs(ref.pressure_dual_error(qp0, np.zeros(qp0.m)) - 1) < 1e-12
    lu = spla.splu(qp1.A.tocsc())
    m1 = qp1.contact.mass
    s0, s1 = in_plane(qp0).ravel(), in_plane(qp1).ravel()
    order = np.argsort(s0)
    lam0 = np.interp(s1, s0[order], (res0.p / qp0.contact.mass)[order])

    def energy(force):
        return np.sqrt(force @ lu.solve(force))

    d = qp1.B.T @ (m1 * lam0 - res1.p)
    direct = energy(d) / energy(qp1.B.T @ res1.p)
    measured = ref.pressure_dual_error(qp0, res0.p)
    assert 0.01 < measured < 1 and abs(measured / direct - 1) < 1e-10, (measured, direct)


# --------------------------------------------------------------------------- 3D (cube-sphere)
@pytest.fixture(scope="module")
def cube_sphere():
    """cube_sphere levels 0 and 1 (mortar_dual) and the level-1 solution as a reference."""
    from problems.spec import problems
    from workflows.reference_solution import Reference

    spec = problems()["cube_sphere"]
    qp0, qp1 = (spec.make(level, coupling="mortar_dual") for level in (0, 1))
    res, _ = script.exact(qp1)
    assert res.status == "converged"
    ref = Reference(qp1, res.u, res.p, {"solver": res.solver, "status": res.status,
                                         "t_solve": 0.0})
    return qp0, qp1, res, ref


def _affine_3d(x, shift):
    M = np.array([[1.0, -2.0, 0.5], [0.3, 1.5, -1.0], [2.0, 0.25, -0.75]])
    return shift + x @ M.T


def test_the_3d_interpolation_is_exact_for_linear_fields_per_body(cube_sphere):
    """P1 interpolation from level 0 to level 1 per body: a field affine on each body (a
    different one on each, so a node where the bodies touch would show a mix) comes out
    exact at every fine node, the sphere's projected boundary nodes outside the coarse
    ball (linear extension) included; on the cube (Freudenthal refinement: nested) the
    interpolated field has exactly the coarse field's energy."""
    from problems.fem import accuracy as acc

    qp0, qp1, _, ref = cube_sphere
    P = ref.prolongation(qp0)
    m0, m1 = qp0.mesh, qp1.mesh
    shifts = np.array([[0.1, 0.2, 0.3], [-5.0, 4.0, 7.0]])     # per body
    U0 = np.array([_affine_3d(x, shifts[b]) for x, b in zip(m0.points, m0.body_of_node)])
    U1 = np.array([_affine_3d(x, shifts[b]) for x, b in zip(m1.points, m1.body_of_node)])
    np.testing.assert_allclose(P @ U0, U1, atol=1e-11)
    # the linear extension is exercised: fine ball nodes lie outside the coarse ball
    ball = 1
    cells0 = m0.cells[m0.body_of_node[m0.cells[:, 0]] == ball]
    x = m1.points[m1.body_of_node == ball]
    _, lam = acc.locate(m0.points, cells0, x)
    outside = lam.min(axis=1) < -1e-9
    assert outside.sum() > 100 and lam.min() < -1e-3
    # ... each in the cell of all the ball's cells whose smallest barycentric coordinate
    # is largest (settled among its nearest cells, checked here against every cell)
    grads, _ = acc.barycentric_gradients(m0.points, cells0)
    every = np.einsum("cad,ncd->nca", grads, x[outside][:, None] - m0.points[cells0[:, 0]])
    every[..., 0] += 1.0
    np.testing.assert_allclose(lam[outside].min(axis=1), every.min(axis=2).max(axis=1),
                               rtol=0, atol=1e-14)
    # nested cube: energy of a random coarse field on the cube, coarse and interpolated
    rng = np.random.default_rng(3)
    V0 = rng.standard_normal(m0.points.shape) * (m0.body_of_node == 0)[:, None]
    cube0 = m0.body_of_node[m0.cells[:, 0]] == 0
    cube1 = m1.body_of_node[m1.cells[:, 0]] == 0
    e0 = acc.energy_norm_by_cell(m0.points, m0.cells, V0, m0.E_cell, m0.nu_cell)[cube0].sum()
    e1 = acc.energy_norm_by_cell(m1.points, m1.cells, P @ V0, m1.E_cell, m1.nu_cell)[cube1].sum()
    assert e0 > 0 and abs(e1 / e0 - 1) < 1e-10


def test_the_3d_comparison_of_a_level_with_itself_is_zero(cube_sphere):
    """The reference against itself: every error 0; a coarser level: the energy error
    equals ``||P U_0 - U_1||_A / ||U_1||_A`` with the reference's assembled stiffness."""
    qp0, qp1, res, ref = cube_sphere
    same = ref.compare(qp1, res.u, res.p)
    assert same["err_energy"] < 1e-12 and same["err_force"] < 1e-14
    assert same["err_pressure"] < 1e-12 and ref.pressure_dual_error(qp1, res.p) < 1e-12
    res0, _ = script.exact(qp0)
    row = ref.compare(qp0, res0.u, res0.p)
    E = (ref.prolongation(qp0) @ qp0.full_displacement(res0.u) - ref.U).ravel()
    direct = np.sqrt(E @ (ref.A @ E)) / ref.norm
    assert 0.1 < row["err_energy"] < 1 and abs(row["err_energy"] / direct - 1) < 1e-10


@pytest.fixture(scope="module")
def run_3d(run, tmp_path_factory):
    """cube_sphere level 0 against a mortar_dual reference at level 1, and the report on
    both scenes' tables."""
    d = tmp_path_factory.mktemp("coupling_3d")
    table = d / "results" / "cube_sphere" / "coupling.csv"
    script.main(["--problem", "cube_sphere", "--levels", "0", "--reference-level", "1",
                 "--out", str(table)])
    t2, out2 = run
    out = {"claims": d / "claims.csv", "figure": d / "coupling.png",
           "hertz": d / "coupling_hertz.png"}
    both = d / "both.csv"
    pd.concat([t2, read_csv(table)]).to_csv(both, index=False)
    report.main(["--tables", str(both), "--claims", str(out["claims"]),
                 "--figure", str(out["figure"]), "--hertz-figure", str(out["hertz"])])
    return read_csv(table), out


def test_the_3d_study_solves_every_coupling_exactly_and_measures_its_errors(run_3d):
    t, _ = run_3d
    assert (t.dim == 3).all() and (t.status == "converged").all() and (t.kkt_max < 1e-8).all()
    ref = t[t.role == "reference"]
    assert ref.level.tolist() == [1] and ref.N.tolist() == [2691] and ref.NC.tolist() == [81]
    c = t[t.role == "compared"].set_index("coupling")
    assert sorted(c.index) == sorted(COUPLINGS) and (c.N == 450).all()
    # level 0 (h = 1/4 on the cube, a ~ 0.28) against level 1: every coupling's energy
    # difference is large but below the solution's norm, its force within 15 %
    assert ((0.1 < c.err_energy) & (c.err_energy < 1)).all(), c.err_energy
    assert ((0 < c.err_force) & (c.err_force < 0.15)).all(), c.err_force
    # the error budget's regions partition the energy error
    shares = c[["err_share_contact", "err_share_singular", "err_share_rest"]].sum(axis=1)
    np.testing.assert_allclose(shares, 1.0, rtol=1e-12)


def test_the_3d_claims_judge_against_the_3d_optimal_rate(run_3d):
    t, out = run_3d
    claims = read_csv(out["claims"])
    cs = claims[claims.scene == "cube_sphere"]
    first = cs.iloc[0]
    assert "converged" in first.claim and first.measured == "5 of 5" and first["pass"] == True  # noqa: E712
    mortar = cs[cs.claim.str.contains("mortar") & cs.claim.str.contains("energy-error rate")]
    assert len(mortar) == 2 and mortar.parameters.str.contains("-0.333").all()
    assert mortar.reason.str.contains("needs 3 levels; this run has 1").all()
    for key in ("figure", "hertz"):
        with Image.open(out[key]) as im:
            im.load()
            assert im.size[1] > 600                     # one row of panels per scene


def test_the_dual_norm_by_multigrid_pcg_meets_the_direct_one(monkeypatch, cg_steps):
    """``err_pressure_dual``'s norm beyond the direct limit: multigrid PCG to
    DUAL_NORM_RTOL (not the duality gap's 1e-14) gives sqrt(F' A^-1 F) to 1e-8, from
    below (CG from zero: ||w_k||_A^2 = ||w||_A^2 - ||w - w_k||_A^2), in fewer steps."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from problems.circle_square import PROBLEM
    from solvers import certificate
    from workflows.measure import DUAL_NORM_RTOL, dual_norm

    qp = PROBLEM.make(1)
    force = qp.B.T @ np.random.default_rng(2).uniform(0.0, 1.0, qp.m)
    exact = float(np.sqrt(force @ spla.spsolve(sp.csc_matrix(qp.A), force)))
    monkeypatch.setattr(certificate, "DIRECT_LINEAR_LIMIT", {})
    steps = cg_steps
    measured = dual_norm(qp, force)
    assert DUAL_NORM_RTOL == 1e-8 and -1e-12 <= (exact - measured) / exact <= 1e-8
    certificate.linear_solver(qp)(force)              # the duality gap's 1e-14
    assert steps[0] < steps[1], steps
