"""The adaptive study: nested-mesh accuracy machinery, the patch-test scene, the eta_2
constant, the study script and its report builder end to end on small sizes."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg  # noqa: F401  (sp.linalg)

from problems import circle_square, flat_blocks
from problems.fem import accuracy as acc
from problems.fem.adaptive import adaptive_loop, adaptive_start
from problems.fem.estimators import estimate
from problems.fem.mesh import project_to_circle, structured_square
from problems.fem.two_body import assemble_two_body
from solvers.interface import solve

OPTS = circle_square.PROBLEM.options()
CENTER = np.array([0.5, 1.0 + OPTS.radius])


@pytest.fixture(scope="module")
def start():
    make, meshes = adaptive_start(circle_square.scene(0, OPTS), 0)
    return make, meshes, (None, project_to_circle(CENTER, OPTS.radius))


def _affine(x):
    return np.stack([1.0 + 2.0 * x[:, 0] - x[:, 1], 0.5 * x[:, 0] + 3.0 * x[:, 1]], axis=1)


# --------------------------------------------------------------------------- location
def test_locate_and_interpolation_are_exact_for_linear_fields():
    p, c = structured_square(5)
    rng = np.random.default_rng(1)
    x = rng.uniform(0, 1, size=(300, 2))
    cell, lam = acc.locate(p, c, x)
    assert lam.min() > -1e-12 and np.allclose(lam.sum(axis=1), 1.0)
    np.testing.assert_allclose(np.einsum("ij,ijk->ik", lam, p[c[cell]]), x, atol=1e-13)
    P = acc.interpolation_matrix(p, c, x)
    np.testing.assert_allclose(P @ _affine(p), _affine(x), atol=1e-12)
    # outside the mesh: the nearest cell's linear extension
    out = np.array([[1.02, 0.5], [-0.01, 0.99]])
    np.testing.assert_allclose(acc.interpolation_matrix(p, c, out) @ _affine(p), _affine(out),
                               atol=1e-12)
    # groups: a target is only located among its group's cells
    groups = (p[c].mean(axis=1)[:, 0] > 0.6).astype(int)
    P = acc.interpolation_matrix(p, c, np.array([[0.45, 0.5]]), groups, np.array([1]))
    assert np.all(p[P.indices, 0] >= 0.6 - 1e-12)


# --------------------------------------------------------------------------- the forest
def test_uniform_bisection_has_the_red_levels_nodes_and_depth(start):
    make, meshes, proj = start
    m = acc.refine_to_depth(meshes, meshes, 2, proj)
    assert sum(len(h.points[-1]) for h in m) == 4237          # circle_square level 1
    for s, h in zip(meshes, m):
        d = acc.cell_depth(s.points[-1], s.cells[-1], h.points[-1], h.cells[-1])
        assert d.min() == 2 and d.max() == 2
    # boundary nodes stay on the circle
    disk = m[1].points[-1]
    from problems.fem.elasticity import boundary_facets
    bnd = np.unique(boundary_facets(m[1].cells[-1]))
    np.testing.assert_allclose(np.linalg.norm(disk[bnd] - CENTER, axis=1), OPTS.radius,
                               rtol=1e-12)


def test_common_refinement_contains_every_target(start):
    make, meshes, proj = start
    uni = acc.refine_to_depth(meshes, meshes, 2, proj)
    run = adaptive_loop(make, meshes, lambda qp, u0, p0: solve(qp, "pdas", tol=1e-10, u0=u0,
                                                               p0=p0),
                        estimator="eta1", max_steps=4, project=proj)
    ref = acc.common_refinement(meshes, [uni, run.meshes], proj, extra=1)
    for target in (uni, run.meshes):
        for b in range(2):
            assert acc.is_nested(target[b], ref[b], meshes[b])
            assert not acc.is_nested(ref[b], target[b], meshes[b])
    # extra=1: every reference cell is deeper than the target cell holding it
    for target in (uni, run.meshes):
        for b in range(2):
            s, t, r = meshes[b], target[b], ref[b]
            dt = acc.cell_depth(s.points[-1], s.cells[-1], t.points[-1], t.cells[-1])
            dr = acc.cell_depth(s.points[-1], s.cells[-1], r.points[-1], r.cells[-1])
            cell, _ = acc.locate(t.points[-1], t.cells[-1], r.points[-1][r.cells[-1]].mean(axis=1))
            assert np.all(dr >= dt[cell] + 1)
    # nested: the interpolant of a coarse solution keeps its energy (up to the O(h^2)
    # movement of projected boundary nodes)
    q_c = run.qps[-1]
    u_c = run.solutions[-1][0]
    q_r = assemble_two_body(make(ref), len(ref[0].points) - 1)
    m_c, m_r = q_c.mesh, q_r.mesh
    P = acc.interpolation_matrix(m_c.points, m_c.cells, m_r.points,
                                 m_c.body_of_node[m_c.cells[:, 0]], m_r.body_of_node)
    U = q_c.full_displacement(u_c)
    e_c = acc.energy_norm_by_cell(m_c.points, m_c.cells, U, m_c.E_cell, m_c.nu_cell).sum()
    e_r = acc.energy_norm_by_cell(m_r.points, m_r.cells, P @ U, m_r.E_cell, m_r.nu_cell).sum()
    assert e_r == pytest.approx(e_c, rel=2e-3)


# --------------------------------------------------------------------------- surfaces
def test_zigzag_and_pileup_measures():
    s = np.linspace(0, 1, 11)
    assert np.abs(acc.zigzag(s, 2 * s + 1, np.ones(11, bool))).max() < 1e-14
    alt = 1.0 + 0.1 * (-1.0) ** np.arange(11)
    z = acc.zigzag(s, alt, np.ones(11, bool))
    np.testing.assert_allclose(np.abs(z), 0.2)
    active = np.ones(11, bool)
    active[5] = False
    assert len(acc.zigzag(s, alt, active)) == 9 - 3       # nodes next to the gap drop out
    pu = acc.pileup(s[:, None], np.linspace(0, 1, 21)[:, None], np.array([0.5]), 0.25)
    assert pu["zone_constrained"] == 5 and pu["zone_opposing"] == 11
    assert pu["zone_ratio"] == pytest.approx(11 / 5)
    # a P1 pressure on one line mesh evaluated on another
    np.testing.assert_allclose(acc.surface_interpolate(s, 3 * s, np.array([0.05, 0.55])),
                               [0.15, 1.65])


# --------------------------------------------------------------------------- patch test
@pytest.mark.parametrize("side", ["coarse", "fine"])
def test_patch_test_nodal_fails_mortar_passes(side):
    q = flat_blocks.exact_pressure(flat_blocks.PROBLEM.options())
    dev = {}
    for coupling in ("nodal", "mortar"):
        for level in (0, 2):
            qp = flat_blocks.PROBLEM.make(level, coupling=coupling, constrained=side)
            res = solve(qp, "pdas", tol=1e-10)
            assert res.status == "converged"
            pressure = res.p / qp.contact.mass
            dev[coupling, level] = np.abs(pressure / q - 1).max()
            if coupling == "mortar":
                assert res.p.sum() == pytest.approx(q, rel=1e-10)   # the force is q x width
    assert dev["mortar", 0] < 1e-10 and dev["mortar", 2] < 1e-10
    assert dev["nodal", 0] > 0.05 and dev["nodal", 2] > 0.05
    assert dev["nodal", 2] > 0.9 * dev["nodal", 0]                 # refinement does not help


def test_patch_test_on_matching_meshes_passes_and_eta2_vanishes():
    """Ratio 1:1: every opposing node faces a constrained node, nothing hangs, the nodal
    constraints transmit the uniform pressure and no opposing node penetrates."""
    qp = flat_blocks.PROBLEM.make(1, ratio="1:1")
    res = solve(qp, "pdas", tol=1e-10)
    q = flat_blocks.exact_pressure(flat_blocks.PROBLEM.options())
    np.testing.assert_allclose(res.p / qp.contact.mass, q, rtol=1e-10)
    est = estimate(qp, res.u, "eta1+eta2", direction=np.array([0.0, 1.0]))
    assert np.all(est["eta2_sq"] == 0.0)
    # the exact solution is linear: no interior jump; eta_1 lives only on the roller-supported
    # edges, whose reaction it counts as a Neumann residual (partly prescribed facets)
    on_roller = np.isclose(qp.mesh.points[qp.mesh.cells], 0.0).any(axis=(1, 2)) | \
        np.isclose(qp.mesh.points[qp.mesh.cells][:, :, 1], 2.0 + 0.001).any(axis=1)
    assert est["eta1_sq"][~on_roller].max() < 1e-25
    with pytest.raises(Exception, match="gap"):
        flat_blocks.PROBLEM.make(0, gap=0.02)


# --------------------------------------------------------------------------- eta_2 constant
def test_eta2_weight_chosen_by_the_run(start):
    make, meshes, proj = start
    seen = []

    def weight(step, est):
        seen.append(step)
        return 7.0 * step

    run = adaptive_loop(make, meshes, lambda qp, u0, p0: solve(qp, "pdas", tol=1e-10, u0=u0,
                                                               p0=p0),
                        max_steps=2, project=proj, eta2_weight=weight)
    assert seen == [0, 1, 2]
    assert [r.eta2_weight for r in run.records] == [0.0, 7.0, 14.0]
    for r, est in zip(run.records, run.estimates):
        np.testing.assert_allclose(est["eta2"], est["eta1_sq"] + r.eta2_weight * est["eta2_sq"])
    with pytest.raises(ValueError, match="eta2_weight"):
        adaptive_loop(make, meshes, lambda qp, u0, p0: solve(qp, "pdas"), max_steps=0,
                      project=proj, eta2_weight=lambda s, e: -1.0)


# --------------------------------------------------------------------------- the script
@pytest.fixture(scope="module")
def study(tmp_path_factory):
    from workflows.studies.adaptive import run as adaptive_study

    out = tmp_path_factory.mktemp("adaptive")
    files = {"steps": out / "steps.csv",
             "fields": [out / "eta1.vtu", out / "eta1_eta2.vtu", out / "stabilised.vtu"],
             "surfaces": [out / "eta1_surface.csv", out / "eta1_eta2_surface.csv",
                          out / "stabilised_surface.csv"]}
    adaptive_study.main(["--problem", "circle_square", "--start-level", "0", "--max-nodes",
                         "1600", "--error-max-nodes", "5000", "--uniform-levels", "0", "1",
                         "--variants", "eta1", "eta1+eta2", "stabilised",
                         "--steps", str(files["steps"]),
                         "--fields", *map(str, files["fields"]),
                         "--surfaces", *map(str, files["surfaces"])])
    return out, files


def test_adaptive_study_script(study):
    out, files = study
    s = pd.read_csv(files["steps"])
    assert set(s.variant) == {"eta1", "eta1+eta2", "stabilised", "uniform", "reference"}
    ref = s[s.variant == "reference"].iloc[0]
    assert ref["solver"] == "pdas" and ref["kkt_max"] < 1e-10   # the dual route
    cmp = s[s.variant != "reference"]
    assert cmp["err_energy"].notna().all() and (cmp["err_energy"] > 0).all()
    assert (cmp["err_energy"] < 0.3).all()
    u = s[s.variant == "uniform"].sort_values("N")
    assert list(u["N"]) == [1099, 4237] and u["err_energy"].is_monotonic_decreasing
    for v in ("eta1", "eta1+eta2", "stabilised"):
        run = s[s.variant == v].sort_values("step")
        assert run["N"].is_monotonic_increasing and run["N"].iloc[-1] >= 1600
        assert run["err_energy"].iloc[-1] < 0.7 * run["err_energy"].iloc[0]
        assert (run["kkt_max"] < 1e-9).all()
    eta2 = s[s.variant == "eta1+eta2"]
    # the calibrated constant: both parts equal on the start mesh
    first = eta2.sort_values("step").iloc[0]
    assert first["eta2_weight"] * first["sum_eta2_sq"] == pytest.approx(first["sum_eta1_sq"])
    assert (eta2["n_outer_1e-03"] > 0).all() and (eta2["kappa_S"] > 1).all()
    # n_o(eps) from (0, 0) as Table 9.1; the nested guess (Alg. 8.5) reaches the same
    # absolute estimate, and local smoothing keeps the work per V-cycle below the sum of
    # the levels' sizes once the hierarchy has adaptive levels
    assert (eta2["n_outer_nested_1e-03"] >= 1).all() and eta2["t_solve_nested_1e-03"].notna().all()
    graded = eta2[eta2["mg_levels"] >= 3]
    assert len(graded) and (graded["mg_work_ratio"] < graded["mg_size_ratio"]).all()
    assert (s.loc[s.variant.isin(["eta1", "stabilised"]), "eta2_weight"] == 0).all()
    stab = s[s.variant == "stabilised"]
    assert (stab.discretisation == "stabilised").all() and (stab.estimator == "eta1").all()
    # the contact force is the constrained surface's, reverse rows included, and stays the
    # nodal run's to a few per cent (the same load)
    nodal_force = s[s.variant == "eta1"].sort_values("step")["force"].iloc[0]
    assert stab.sort_values("step")["force"].iloc[0] == pytest.approx(nodal_force, rel=0.03)
    shares = cmp[["err_share_contact", "err_share_singular", "err_share_rest"]].sum(axis=1)
    np.testing.assert_allclose(shares, 1.0)
    for f in files["fields"] + files["surfaces"]:
        assert f.stat().st_size > 0


def test_adaptive_report(study, tmp_path):
    from report import adaptive as rep
    from workflows.io import write_csv  # noqa: F401  (report writes through it)

    out, files = study
    names = {k: str(tmp_path / f"{k}.csv") for k in ("table", "accuracy", "pileup",
                                                      "convergence")}
    from pathlib import Path
    thesis = Path(__file__).resolve().parent.parent / "reference" / "table_9_2.csv"
    rep.main(["tables", "--steps", str(files["steps"]), "--thesis", str(thesis),
              *[a for k, v in names.items() for a in (f"--{k}", v)]])
    table = pd.read_csv(names["table"])
    assert set(table.source) == {"ours", "thesis"}
    assert table.loc[table.source == "thesis", "N"].tolist()[0] == 6800
    assert table.loc[table.source == "thesis", "n_outer_1e-03"].tolist()[0] == 18
    accuracy = pd.read_csv(names["accuracy"]).set_index("variant")
    assert np.isfinite(accuracy.loc["eta1+eta2", "node_saving_factor"])
    assert accuracy.loc["eta1+eta2", "e_ref_estimated"] > 0
    conv = pd.read_csv(names["convergence"]).set_index("quantity")
    assert {"err_energy", "err_pressure", "err_force"} <= set(conv.index)
    figs = {k: str(tmp_path / f"{k}.png") for k in ("meshes", "snapshot", "eta", "error",
                                                     "pressure")}
    rep.main(["figures", "--steps", str(files["steps"]), "--accuracy", names["accuracy"],
              "--variants", "eta1", "eta1+eta2", "stabilised",
              "--vtus", *map(str, files["fields"]),
              "--surfaces", *map(str, files["surfaces"]),
              *[a for k, v in figs.items() for a in (f"--fig-{k}", v)]])
    for f in figs.values():
        assert open(f, "rb").read(8) == b"\x89PNG\r\n\x1a\n"


def test_reference_error_estimate_recovers_a_known_error():
    """Synthetic: e_h = C N^-1/2 and e_ref known; m_h = sqrt(e_h^2 - e_ref^2) and the
    estimator proportional to the error recover e_ref."""
    from report.adaptive import reference_error

    N = np.array([1e3, 4e3, 1.6e4, 2e3, 8e3])
    e = 3.0 * N ** -0.5
    e_ref = 0.01
    steps = pd.DataFrame({"variant": ["uniform"] * 3 + ["eta1"] * 2, "N": N,
                          "err_energy": np.sqrt(e ** 2 - e_ref ** 2),
                          "sum_eta1_sq": 5.0 * e ** 2})
    steps = pd.concat([steps, pd.DataFrame({"variant": ["reference"], "N": [1e5],
                                            "sum_eta1_sq": [5.0 * e_ref ** 2]})])
    r = reference_error(steps)
    assert r["e_ref"] == pytest.approx(e_ref, rel=1e-10) and r["n_anchors"] == 5


def test_patch_scripts(tmp_path):
    from report import adaptive as rep
    from workflows.studies.adaptive import patch_test

    runs, pressure = tmp_path / "runs.csv", tmp_path / "p.csv"
    patch_test.main(["--problem", "flat_blocks", "--levels", "0", "1", "--out", str(runs),
                     "--pressure", str(pressure)])
    r = pd.read_csv(runs)
    assert len(r) == 4 * 2 * 2 and (r.status == "converged").all()   # couplings x sides x levels
    rep.main(["patch", "--runs", str(runs), "--pressure", str(pressure), "--table",
              str(tmp_path / "t.csv"), "--figure", str(tmp_path / "f.png")])
    t = pd.read_csv(tmp_path / "t.csv").set_index(["coupling", "constrained"])
    assert not t.loc[("nodal", "coarse"), "transmits_uniform_pressure"]
    assert t.loc[("mortar", "fine"), "transmits_uniform_pressure"]
    assert t.loc[("two_pass", "coarse"), "transmits_uniform_pressure"]
    assert t.loc[("two_pass", "fine"), "transmits_uniform_pressure"]
    for side in ("coarse", "fine"):           # stabilised: between nodal and exact
        assert 1e-3 < t.loc[("stabilised", side), "dev_max_finest"] \
            < t.loc[("nodal", side), "dev_max_finest"]
    with pytest.raises(SystemExit):
        patch_test.main(["--problem", "circle_square", "--levels", "0", "--out", "x", "--pressure",
                         "y"])


def test_bound_weight_follows_the_thesis_bound(tmp_path):
    """--eta2-weight bound: c sum eta_T2^2 = E^(3/2) ||p||_* (sum eta_T2^2)^(1/2) per step."""
    from workflows.studies.adaptive import run as adaptive_study

    steps = tmp_path / "s.csv"
    adaptive_study.main(["--problem", "circle_square", "--start-level", "0", "--max-nodes",
                         "1150", "--eta2-weight", "bound", "--variants", "eta1+eta2",
                         "--table-variant", "none", "--steps", str(steps), "--fields",
                         str(tmp_path / "f.vtu"), "--surfaces", str(tmp_path / "s2.csv")])
    s = pd.read_csv(steps)
    qp = circle_square.PROBLEM.make(0)
    res = solve(qp, "pdas", tol=1e-10)
    pstar = np.sqrt(res.p @ (qp.B @ sp.linalg.spsolve(qp.A.tocsc(), qp.B.T @ res.p)))
    first = s.sort_values("step").iloc[0]
    assert first["eta2_weight"] == pytest.approx(pstar / np.sqrt(first["sum_eta2_sq"]), rel=1e-6)
    assert s["eta2_weight"].nunique() > 1                  # chosen anew at every step


@pytest.mark.parametrize("problem, coupling", [("circle_square", "nodal"),
                                               ("cube_sphere", "stabilised")])
def test_the_iterative_exact_solve_is_verified_and_agrees_with_the_direct_one(
        problem, coupling, monkeypatch):
    """Beyond the direct limit (here forced: limit 0) a variant's step is solved by
    Alg. 8.4 with the multilevel S-hat to verified KKT <= tol, tightening its own stop
    until the certified energy bound agrees (the stabilised rows need it); it matches
    PDAS's answer."""
    from problems.fem.stabilised import stabilise
    from problems.kkt import energy_error
    from problems.spec import problems
    from workflows.studies.adaptive import run as ad

    qp = problems()[problem].make(1)
    if coupling == "stabilised":
        qp = stabilise(qp, 1.0, 1.0)
    exact = ad.exact_solve(qp, tol=1e-8)
    assert exact.solver == "pdas" and exact.status == "converged"
    monkeypatch.setattr(ad, "DIRECT_REFERENCE_LIMIT", {})
    res = ad.exact_solve(qp, tol=1e-8, time_limit=300)
    assert res.status == "converged" and res.kkt.max <= 1e-8 and res.gap.meets(1e-8)
    assert energy_error(qp, res.u, exact.u) < 1e-6
