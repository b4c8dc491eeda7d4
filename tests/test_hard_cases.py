"""Hard cases: scale-free tolerances, exact answers on degenerate cases, and the study's
script and report (every converged row certified and accurate against the reference)."""
import numpy as np
import pandas as pd
import pytest

from problems.circle_square import PROBLEM
from report.figure_audit import png_problems
from solvers.interface import solve, solvers

SI = {"E1": 2.1e11, "E2": 2.1e11, "load": 2.1e9}


@pytest.mark.parametrize("solver", sorted(solvers()))
def test_tolerances_are_scale_free(solver):
    """The same scene in SI units (E = 2.1e11 Pa) and dimensionless: the same verified
    status and iteration count, and the same answer up to the unit factor."""
    plain, si = PROBLEM.make(1), PROBLEM.make(1, **SI)
    a, b = solve(plain, solver, tol="mid"), solve(si, solver, tol="mid")
    assert a.status == b.status and a.claimed_status == b.claimed_status
    assert abs(a.iterations - b.iterations) <= 1       # the data agree to ~1e-15, not bit for bit
    np.testing.assert_allclose(b.u, a.u, rtol=1e-4, atol=1e-6 * np.abs(a.u).max())
    np.testing.assert_allclose(b.p / 2.1e11, a.p, rtol=1e-4, atol=1e-6 * np.abs(a.p).max())


def test_no_contact_gives_zero_multipliers_exactly():
    qp = PROBLEM.make(1, gap=0.1, indent=0.02)
    res = solve(qp, "pdas", tol="high")
    assert res.status == "converged" and np.all(res.p == 0) and qp.g.min() > 0.09


def test_initial_penetration_is_pushed_apart():
    qp = PROBLEM.make(1, gap=-0.005)
    res = solve(qp, "pdas", tol="high")
    assert qp.g.min() < -0.004 and res.status == "converged"
    assert np.all(qp.g - qp.B @ res.u >= -1e-12)           # separated after loading


def test_hard_case_report_from_the_test_set_runs(tmp_path):
    from report.hard_cases import main as report_main
    from workflows.cli import main as cli
    from workflows.studies.test_set.run import main as runs_main
    export = tmp_path / "export"
    families = ("hard_thin_body", "hard_grazing", "hard_friction_grazing")
    assert cli(["export", "--set", "contact-qp-5", "--class", "small", "--families", *families,
                "--out", str(export), "--quiet"]) == 0
    out = []
    for family in families:
        out.append(str(tmp_path / f"{family}.csv"))
        runs_main(["--set", "contact-qp-5", "--class", "small", "--family", family,
                   "--export", str(export), "--presets", "mid", "--levels", "0",
                   "--time-limit", "30",
                   "--out", out[-1]])
    report_main(["table", "--inputs", *out, "--cases", *(f"{f}:0" for f in families),
                 "--preset", "mid", "--table", str(tmp_path / "t.csv"),
                 "--heatmap", str(tmp_path / "h.png")])
    t = pd.read_csv(tmp_path / "t.csv")
    assert set(t["solver"]) == set(solvers())
    assert set(t["case"]) == set(families) and (t.level == 0).all()
    assert t.groupby("case").size().eq(len(solvers())).all()   # one row per solver and case
    assert t["claim_ok"].all()
    assert t.loc[t.status == "converged", "accurate"].all()
    assert (t.loc[t.case == "hard_grazing", "dropped_rows"] > 0).all()
    # the frictional case: the owned frictional solvers verified, the frictionless skipped
    friction = t[t.case == "hard_friction_grazing"].set_index("solver")
    assert (friction.loc[["tresca_exact", "tnnmg", "semismooth_newton"], "status"]
            == "converged").all()
    assert friction.loc["pdas", "status"] == "skipped"
    assert (tmp_path / "h.png").read_bytes()[:4] == b"\x89PNG"
    assert png_problems(tmp_path / "h.png") == []          # every solver: still legible


@pytest.mark.parametrize("n_cases", [14, 20])
def test_the_heat_map_stays_legible_with_every_solver_and_many_cases(tmp_path, n_cases):
    """Fifteen solvers and fourteen cases (the size that drew a 2,744 px image), and the
    full scale's twenty: the panels stack, and the image passes the figure audit, its cell
    text legible in the report's frame; the status key lists only the statuses shown."""
    from report.hard_cases import heatmap, heatmap_layout
    names = [f"solver_{k:02d}" for k in range(15)]
    cases = [f"hard_case_{k:02d}" for k in range(n_cases)]
    t = pd.DataFrame([{"case": c, "solver": s, "preset": "mid", "tol": 1e-6,
                       "status": "converged" if k % 4 else "max_iter", "kkt_max": 1e-8,
                       "energy_error": 1e-9, "wall_time": 0.01 * (k + 1), "message": ""}
                      for c in cases for k, s in enumerate(names)])
    assert heatmap_layout(15, 14)[:2] == (4, 1) and heatmap_layout(3, 1)[:2] == (2, 2)
    heatmap(t, str(tmp_path / "h.png"))
    assert png_problems(tmp_path / "h.png") == []


def test_incompressibility_table_script_and_report(tmp_path):
    """The incompressibility table of the hard-case study: Alg. 8.4 with its defaults against the
    thesis's V-cycle pair over nu, and its claims (robust n_o bounded, all verified)."""
    from report.hard_cases import incompressibility_claims as claims, main as report_main
    from workflows.studies.hard_cases.run import main as script

    out = tmp_path / "inc.csv"
    script(["--scenes", "circle_square", "--level", "0", "--nus", "0.3", "0.499",
            "--out", str(out)])
    t = pd.read_csv(out).set_index(["nu", "variant"])
    assert len(t) == 4 and (t.loc[(0.3, "robust"), "ahat_degree"] == 1)
    assert t.loc[(0.499, "robust"), "ahat_degree"] > 1
    assert t.loc[(0.499, "robust"), "gamma_bar"] < t.loc[(0.499, "vcycle"), "gamma_bar"] / 3
    assert (t.xs("robust", level="variant").status == "converged").all()
    report_main(["incompressibility", "--table", str(out), "--claims", str(tmp_path / "c.csv"),
                 "--figure", str(tmp_path / "f.png")])
    c = pd.read_csv(tmp_path / "c.csv")
    assert len(c) == 2 and c["pass"].astype(bool).all() and (tmp_path / "f.png").stat().st_size
    # a run short of convergence is not judged, and a growth beyond 2x fails
    fake = pd.read_csv(out)
    fake.loc[(fake.variant == "robust") & (fake.nu == 0.499), "n_outer"] *= 10
    grown = claims(fake)
    assert grown["pass"].tolist() == [True, False]
    fake.loc[(fake.variant == "robust") & (fake.nu == 0.499), "status"] = "max_iter"
    assert claims(fake)["pass"].tolist()[0] is False and pd.isna(claims(fake)["pass"].iloc[1])


def test_incompressibility_script_refuses_bad_arguments(capsys):
    from workflows.studies.hard_cases.run import main as script

    with pytest.raises(SystemExit):
        script(["--scenes", "laplace_nonmatching", "--level", "0", "--nus", "0.3",
                "--out", "x.csv"])
    assert "allowed: circle_square" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        script(["--scenes", "circle_square", "--level", "0", "--nus", "0.7", "--out", "x.csv"])
    err = capsys.readouterr().err
    assert "--nus" in err and "0.7" in err


def test_the_random_frictional_sample_and_its_claims(tmp_path):
    """The harder sample's run step (two draws beyond the tests', level 1, the suite's
    frictional solvers, a library and a frictionless solver) and its claims: every owned
    run converged and every converged run within its certified bound; a run outside its
    bound, or an owned run that stopped, fails them; a frictionless solver is skipped."""
    from report.hard_cases import OWNED_FRICTION, random_friction_claims
    from workflows.studies.hard_cases.random_friction import main as rf_main
    out = tmp_path / "rf.csv"
    rf_main(["--first", "500", "--draws", "2", "--level", "1", "--solvers", *OWNED_FRICTION,
             "osqp", "pdas", "--out", str(out)])
    t = pd.read_csv(out)
    assert set(t.seed) == {500, 501} and (t.level == 1).all()
    assert (t.loc[t.solver == "pdas", "status"] == "skipped").all()
    owned = t[t.solver.isin(OWNED_FRICTION)]
    assert (owned.status == "converged").all() and (owned.energy_error <= 1e-6).all()
    claims = random_friction_claims(t)
    assert claims["pass"].tolist()[:2] == [True, True]
    assert claims["measured"].iloc[0] == f"{len(owned)} of {len(owned)} runs"
    assert "fallback on 0 draws" in claims["parameters"].iloc[0]
    refuted = ((t.claimed_status == "converged") & (t.status != "converged")).sum()
    assert claims["measured"].iloc[2] == f"{refuted} of {(t.status != 'skipped').sum()} runs"
    both = t[["energy_bound", "energy_bound_floor"]].dropna()
    assert len(both) and (both.energy_bound >= both.energy_bound_floor).all()
    outside = t.copy()
    row = outside.index[outside.solver == "osqp"][0]
    outside.loc[row, ["status", "energy_error"]] = ["converged", 10 * outside.energy_bound[row]]
    assert random_friction_claims(outside)["pass"].iloc[1] is False
    stopped = t.copy()
    stopped.loc[stopped.index[stopped.solver == "tnnmg"][0], "status"] = "max_iter"
    assert random_friction_claims(stopped)["pass"].iloc[0] is False
    for bad in (["--draws", "0"], ["--draws", "1", "--level", "3"],
                ["--draws", "1", "--solvers", "nope"]):
        with pytest.raises(SystemExit):
            rf_main([*bad, "--out", str(tmp_path / "x.csv")])
    assert not (tmp_path / "x.csv").exists()
