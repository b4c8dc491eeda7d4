"""The strong-scaling study of the distributed solver (workflows/studies/petsc_scaling/run.py):
speed-up, efficiency and the comparison with TNNMG computed right, and the script's rows
on a small scene (where PETSc and MPI are installed)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from PIL import Image

from report import petsc_scaling as report_scaling
from solvers import petsc_tao
from workflows.studies.petsc_scaling import run as petsc_scaling
from workflows.studies import ConfigError, check_config, load_config
from workflows.studies import petsc_scaling as study

ROOT = Path(__file__).resolve().parents[1]


def test_speedup_efficiency_and_the_tnnmg_ratio_are_computed_right():
    rows = pd.DataFrame([
        {"scene_problem": "s", "level": 1, "n": 100, "solver": "petsc_tao", "ranks": 1,
         "status": "converged", "total_time": 10.0},
        {"scene_problem": "s", "level": 1, "n": 100, "solver": "petsc_tao", "ranks": 2,
         "status": "converged", "total_time": 6.0},
        {"scene_problem": "s", "level": 1, "n": 100, "solver": "tnnmg", "ranks": 1,
         "status": "converged", "total_time": 12.0},
        {"scene_problem": "s", "level": 2, "n": 400, "solver": "petsc_tao", "ranks": 1,
         "status": "converged", "total_time": 40.0},
        {"scene_problem": "s", "level": 2, "n": 400, "solver": "petsc_tao", "ranks": 2,
         "status": "time_limit", "total_time": 99.0},
        {"scene_problem": "s", "level": 2, "n": 400, "solver": "tnnmg", "ranks": 1,
         "status": "converged", "total_time": 30.0},
    ])
    t = petsc_scaling.scaling_table(rows)
    np.testing.assert_allclose(t["speedup"][:2], [1.0, 10.0 / 6.0])
    np.testing.assert_allclose(t["efficiency"][:2], [1.0, 10.0 / 12.0])
    np.testing.assert_allclose(t["tnnmg_over_petsc"][:2], [1.2, 2.0])
    assert np.isnan(t["speedup"][4]) and np.isnan(t["efficiency"][4])   # did not converge
    assert np.isnan(t["speedup"][2])                                     # TNNMG's own row
    assert t["tnnmg_over_petsc"][3] == pytest.approx(0.75)
    claims = petsc_scaling.scaling_claims(t).set_index("claim")
    # the largest level's run at the most ranks timed out: no efficiency there
    assert np.isnan(claims.loc["efficiency_at_most_ranks", "value"])
    assert claims.loc["petsc_faster_than_tnnmg_from_n", "n"] == 100
    assert claims.loc["petsc_faster_than_tnnmg_from_n", "value"] == pytest.approx(1.2)


@pytest.mark.skipif(petsc_tao.runtime()[0] is None,
                    reason=f"PETSc/MPI not found: {petsc_tao.runtime()[1]}")
def test_the_script_runs_every_rank_count_and_tnnmg_beside(tmp_path):
    out = tmp_path / "results" / "circle_square" / "petsc_scaling.csv"
    petsc_scaling.main(["--problem", "circle_square", "--levels", "0", "--ranks", "1", "2",
                        "--time-limit", "300", "--out", str(out)])
    t = pd.read_csv(out)
    assert list(zip(t["solver"], t["ranks"])) == [("petsc_tao", 1), ("petsc_tao", 2),
                                                  ("tnnmg", 1)]
    assert (t["status"] == "converged").all(), t["message"].tolist()
    assert t["speedup"][0] == 1.0 and t["efficiency"][1] == pytest.approx(t["speedup"][1] / 2)
    assert (t["ksp_iterations"][:2] > 0).all()
    # the two-rank answer lies within the certified bounds' sum of the one-rank answer
    assert np.isnan(t["distance_to_one_rank"][0]) and np.isnan(t["distance_to_one_rank"][2])
    assert 0.0 <= t["distance_to_one_rank"][1] <= t["agreement_bar"][1] < 1e-5
    claims = pd.read_csv(out.with_name("petsc_scaling_claims.csv"))
    assert set(claims["claim"]) == {"efficiency_at_most_ranks", "petsc_faster_than_tnnmg_from_n"}


def test_the_ranks_must_include_one(tmp_path):
    with pytest.raises(SystemExit) as err:
        petsc_scaling.main(["--problem", "circle_square", "--levels", "0", "--ranks", "2",
                            "--out", str(tmp_path / "x.csv")])
    assert err.value.code == 2


def test_agreement_is_the_energy_distance_against_the_bounds_sum():
    A = np.diag([4.0, 1.0])
    u1, ur = np.array([1.0, 0.0]), np.array([1.0, 0.02])
    distance, bar = petsc_scaling.agreement(A, ur, u1, 1e-3, 1e-3)
    assert distance == pytest.approx(0.01)            # ||(0, 0.02)||_A / ||(1, 0)||_A
    assert bar == pytest.approx(2e-3 / (1 - 1e-3))
    assert distance > bar                             # these two cannot both be that close


def _runs(status2="converged", distance=1e-9, bar=1e-7, message=""):
    base = {"scene_problem": "circle_square", "n": 100, "message": message}
    rows = [
        {**base, "level": 1, "solver": "petsc_tao", "ranks": 1, "status": status2,
         "total_time": 2.0, "iterations": 4, "distance_to_one_rank": np.nan,
         "agreement_bar": np.nan},
        {**base, "level": 1, "solver": "petsc_tao", "ranks": 2, "status": status2,
         "total_time": 1.5, "iterations": 4, "distance_to_one_rank": distance,
         "agreement_bar": bar},
        {**base, "level": 1, "solver": "tnnmg", "ranks": 1, "status": "converged",
         "total_time": 3.0, "iterations": 5, "distance_to_one_rank": np.nan,
         "agreement_bar": np.nan},
    ]
    return petsc_scaling.scaling_table(pd.DataFrame(rows))


def test_the_report_judges_agreement_and_reports_the_efficiency(tmp_path):
    c = report_scaling.claims(_runs(), "cs").set_index("claim")
    agree = c.filter(like="agrees with one rank", axis=0).iloc[0]
    assert agree["measured"] == pytest.approx(0.01) and agree["pass"] is True
    eff = c.filter(like="parallel efficiency", axis=0).iloc[0]
    assert eff["measured"] == pytest.approx(2.0 / (2 * 1.5)) and eff["pass"] is None
    assert eff["reason"] == report_scaling.REPORTED
    ratio = c.filter(like="TNNMG's time over", axis=0).iloc[0]
    assert ratio["measured"] == pytest.approx(2.0)            # 3.0 s against 1.5 s at r = 2
    assert c.filter(like="verified converged", axis=0).iloc[0]["pass"] is True
    far = report_scaling.claims(_runs(distance=2e-7), "cs")
    assert far[far.claim.str.contains("agrees with one rank")]["pass"].iloc[0] is False
    report_scaling.figure(_runs(), "cs", str(tmp_path / "f.png"))
    assert (tmp_path / "f.png").stat().st_size > 0


def test_without_petsc_the_report_says_skipped_and_judges_nothing_of_it(tmp_path):
    reason = "skipped: no MPI launcher 'mpiexec' (CONTACTBENCH_MPIEXEC): apt-get install ..."
    t = _runs(status2="skipped", distance=np.nan, bar=np.nan, message=reason)
    c = report_scaling.claims(t, "cs")
    assert c.iloc[0]["measured"] == reason                   # the solver's own message
    assert c["pass"].isna().all()                     # nothing judged
    assert (c["reason"].str.len() > 10).all()        # and each row says why
    report_scaling.figure(t, "cs", str(tmp_path / "f.png"))
    with Image.open(tmp_path / "f.png") as im:                 # the image says why
        im.load()
        assert im.text["contactbench:nothing_to_draw"] == f"petsc_tao {reason}"


@pytest.mark.parametrize("scale", ["tiny", "quick", "full", "huge"])
def test_each_scale_declares_the_runtime_its_time_limits_bound(scale):
    """The configs' runtime of the study is the bound of :func:`runtime_bound` (not a
    measurement: the config comment says so), and the ranks include 1."""
    config = load_config(ROOT / f"workflows/config/{scale}.yaml")
    ps = config["petsc_scaling"]
    assert config["resources"]["petsc_scaling_study"]["runtime"] == study.runtime_bound(config)
    assert study.mpi_resources(config)["tasks"] == max(ps["ranks"])
    config["petsc_scaling"]["ranks"] = [2, 4]
    with pytest.raises(ConfigError, match="'petsc_scaling.ranks'"):
        check_config(config)
