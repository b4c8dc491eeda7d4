"""The strong-scaling study of the distributed solver (workflows/scripts/petsc_scaling.py):
speed-up, efficiency and the comparison with TNNMG computed right, and the script's rows
on a small scene (where PETSc and MPI are installed)."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from solvers import petsc_tao
from workflows.scripts import petsc_scaling


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
    claims = pd.read_csv(out.with_name("petsc_scaling_claims.csv"))
    assert set(claims["claim"]) == {"efficiency_at_most_ranks", "petsc_faster_than_tnnmg_from_n"}


def test_the_ranks_must_include_one(tmp_path):
    with pytest.raises(SystemExit) as err:
        petsc_scaling.main(["--problem", "circle_square", "--levels", "0", "--ranks", "2",
                            "--out", str(tmp_path / "x.csv")])
    assert err.value.code == 2
