"""Hard cases: scale-free tolerances, exact answers on degenerate cases, and the study's
script and report (every converged row certified and accurate against the reference)."""
import numpy as np
import pandas as pd
import pytest

from problems.circle_square import PROBLEM
from solvers.interface import solve, solvers

SI = {"E1": 2.1e11, "E2": 2.1e11, "load": 2.1e9}


@pytest.mark.parametrize("solver", sorted(solvers()))
def test_tolerances_are_scale_free(solver):
    """The same scene in SI units (E = 2.1e11 Pa) and dimensionless: the same verified
    status and iteration count, and the same answer up to the unit factor."""
    plain, si = PROBLEM.make(1), PROBLEM.make(1, **SI)
    a, b = solve(plain, solver, tol="mid"), solve(si, solver, tol="mid")
    assert a.status == b.status and a.claimed_status == b.claimed_status
    assert abs(a.iterations - b.iterations) <= (1 if solver == "clarabel" else 0)
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
    from workflows.scripts.test_set_runs import main as runs_main
    export = tmp_path / "export"
    assert cli(["export", "--class", "small", "--families", "hard_thin_body", "hard_grazing",
                "--out", str(export), "--quiet"]) == 0
    out = []
    for family in ("hard_thin_body", "hard_grazing"):
        out.append(str(tmp_path / f"{family}.csv"))
        runs_main(["--set", "contact-qp-1", "--class", "small", "--family", family,
                   "--export", str(export), "--presets", "mid", "--levels", "0",
                   "--time-limit", "30",
                   "--out", out[-1]])
    report_main(["--inputs", *out, "--cases", "hard_thin_body:0", "hard_grazing:0",
                 "--preset", "mid", "--table", str(tmp_path / "t.csv"),
                 "--heatmap", str(tmp_path / "h.png")])
    t = pd.read_csv(tmp_path / "t.csv")
    assert set(t["solver"]) == set(solvers())
    assert set(t["case"]) == {"hard_thin_body", "hard_grazing"} and (t.level == 0).all()
    assert t["claim_ok"].all()
    assert t.loc[t.status == "converged", "accurate"].all()
    assert (t.loc[t.case == "hard_grazing", "dropped_rows"] > 0).all()
    assert (tmp_path / "h.png").read_bytes()[:4] == b"\x89PNG"
