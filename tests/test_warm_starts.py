"""Cold against warm starts on the test set's frictional steps and the faceted law's
trade-off: the runs step's warm rows and ``used_guess`` (workflows/studies/test_set/run.py)
and the summary's two tables and claims (report/test_set.py),
on level-0 problems of contact-qp-5 exported into a temporary folder."""
from __future__ import annotations

import shutil

import pandas as pd
import pytest

from report.test_set import (facet_frame, ignored_guess_mismatches,
                                   main as summary_main, warm_facet_claims, warm_frame)
from solvers.base import GUESS_NOT_USED
from workflows.export import write_problem
from workflows.problem_set import CURRENT, cold_rows, load, plain_rows
from workflows.studies.test_set.run import WARM_FILE, isotropic_twin, run_problem, runs_warm

PATH = ("circle_square_tresca_path_L0_s1", "circle_square_tresca_path_L0_s2")
FACETED = ("cube_sphere_tresca_q05_L0", "cube_sphere_tresca_q05_facets8_L0",
           "cube_sphere_tresca_q05_facets32_L0")


@pytest.fixture(scope="module")
def export(tmp_path_factory):
    """Two steps of the 2D load path, a frictionless problem, and the 3D isotropic step
    with its two faceted variants, each written as the export writes it."""
    ts = load()
    out = tmp_path_factory.mktemp("warm") / "small"
    families = ["circle_square_tresca_path", "circle_square", "cube_sphere_tresca_q05",
                "cube_sphere_tresca_q05_facets8", "cube_sphere_tresca_q05_facets32"]
    items = {p.name: p for p in ts.problems("small", families)}
    for name in (*PATH, "circle_square_L0", *FACETED):
        write_problem(out / name, items[name], CURRENT)
    return ts, items, out


@pytest.fixture(scope="module")
def path_runs(export):
    """The runs script's rows on the two path steps and the frictionless problem, warm
    starts on: a solver that starts from a guess, a library and the exact reference that
    do not, and a solver without friction."""
    ts, items, out = export
    rows = []
    for name in (*PATH, "circle_square_L0"):
        rows += run_problem(items[name], out / name, ["semismooth_newton", "clarabel",
                                                      "tresca_exact", "pdas"], ["mid"], 20.0,
                            warm=True)
    # the plain runs: rung 0 of each cold ladder (tests/test_leaderboard.py has the ladder)
    return pd.DataFrame(rows).query("rung == 0").assign(time=lambda t: t.total_time)


def test_warm_rows_exist_for_exactly_the_steps_with_a_warm_start(export, path_runs):
    _, _, out = export
    t = path_runs
    assert set(t.start) == {"cold", "warm"}
    with_file = {name for name in (*PATH, "circle_square_L0") if (out / name / WARM_FILE).exists()}
    assert with_file == set(PATH)
    assert set(t[t.start == "warm"].problem) == with_file
    # every solver that took a step is run warm on it, a skipped one is not
    for name in PATH:
        cold, warm = (t[(t.problem == name) & (t.start == s)] for s in ("cold", "warm"))
        assert set(warm.solver) == set(cold[cold.status != "skipped"].solver) \
            == {"semismooth_newton", "clarabel", "tresca_exact"}
    assert len(cold_rows(t)) == 3 * 4 and (cold_rows(t).start == "cold").all()
    assert not t[t.start == "cold"].used_guess.any()


def test_used_guess_is_false_for_a_solver_that_drops_the_guess(path_runs):
    warm = path_runs[path_runs.start == "warm"].set_index(["problem", "solver"])
    cold = path_runs[path_runs.start == "cold"].set_index(["problem", "solver"])
    for name in PATH:
        for solver in ("clarabel", "tresca_exact"):     # neither takes an initial point
            assert not warm.loc[(name, solver), "used_guess"]
            assert GUESS_NOT_USED in warm.loc[(name, solver), "message"]
            assert warm.loc[(name, solver), "iterations"] == cold.loc[(name, solver),
                                                                      "iterations"]
        assert warm.loc[(name, "semismooth_newton"), "used_guess"]
        assert warm.loc[(name, "semismooth_newton"), "status"] == "converged"


def test_a_warm_start_at_the_solution_saves_newton_steps(export, tmp_path):
    """The step's own reference as its warm start: the semismooth Newton method, which
    starts from the guess, verifies it in fewer steps than from zero."""
    _, items, out = export
    name = PATH[1]
    folder = tmp_path / name
    shutil.copytree(out / name, folder)
    shutil.copy(folder / "solution.npz", folder / WARM_FILE)
    t = pd.DataFrame(run_problem(items[name], folder, ["semismooth_newton"], ["mid"], 20.0,
                                 warm=True)).query("rung == 0").set_index("start")
    assert (t.status == "converged").all() and t.loc["warm", "used_guess"]
    assert t.loc["warm", "iterations"] < t.loc["cold", "iterations"]


def test_which_families_run_warm():
    families = load().families
    path, single = families["circle_square_tresca_path"], families["circle_square_tresca_q05"]
    assert runs_warm(path, "paths") and runs_warm(path, "all") and not runs_warm(path, "none")
    assert runs_warm(single, "all") and not runs_warm(single, "paths")


def test_warm_table_and_its_claims(path_runs):
    warm = warm_frame(path_runs).set_index("solver")
    assert set(warm.index) == {"semismooth_newton", "clarabel", "tresca_exact"}
    assert (warm.steps == len(PATH)).all()
    assert warm.loc["clarabel", "guess"] == "ignored"
    assert warm.loc["tresca_exact", "guess"] == "ignored"
    assert warm.loc["semismooth_newton", "guess"] == "used"
    # over the steps run both ways (not the frictionless problem's cold run)
    newton = path_runs[(path_runs.solver == "semismooth_newton")
                       & path_runs.problem.isin(PATH)]
    for start in ("cold", "warm"):
        its = newton[newton.start == start].iterations
        assert warm.loc["semismooth_newton", f"iterations_{start}_total"] == its.sum()
        assert warm.loc["semismooth_newton", f"converged_{start}"] == len(PATH)
    assert warm.loc["clarabel", "iterations_ratio"] == 1.0
    differ, pairs = ignored_guess_mismatches(path_runs)
    assert (differ, pairs) == (0, 2 * len(PATH))
    rows = {r["claim"].split(" (")[0]: r for r in
            warm_facet_claims(path_runs, warm_frame(path_runs), facet_frame(path_runs))}
    judged = next(r for c, r in rows.items() if "ignore the guess" in c)
    assert judged["pass"] is True
    # a solver that says it ignores the guess but iterates differently warm fails the check
    tampered = path_runs.copy()
    at = tampered.index[(tampered.solver == "clarabel") & (tampered.start == "warm")][0]
    tampered.loc[at, "iterations"] += 1
    assert ignored_guess_mismatches(tampered) == (1, 2 * len(PATH))
    bad = warm_facet_claims(tampered, warm_frame(tampered), facet_frame(tampered))
    assert next(r for r in bad if "ignore the guess" in r["claim"])["pass"] is False


def test_facet_table_model_error_falls_with_k(export, path_runs, tmp_path):
    ts, items, out = export
    rows = []
    for name in FACETED:
        twin = isotropic_twin(ts, items[name])
        assert twin == (None if name == FACETED[0] else FACETED[0])
        rows += run_problem(items[name], out / name, ["tresca_exact", "osqp"], ["mid"], 20.0,
                            twin=twin)
    every = pd.DataFrame(rows).assign(time=lambda t: t.total_time)
    t = plain_rows(every)
    facets = facet_frame(t)
    assert set(facets.problem) == set(FACETED[1:]) and set(facets.solver) == {"tresca_exact",
                                                                             "osqp"}
    error = facets.drop_duplicates("problem").set_index("facets").model_error
    assert 0 < error[32] < error[8]
    osqp = facets[facets.solver == "osqp"]
    assert (osqp.status_isotropic == "skipped").all()            # a QP library: no cones
    assert (osqp.status_faceted != "skipped").all()
    exact = facets[facets.solver == "tresca_exact"]
    assert (exact.status_faceted == "converged").all() and exact.time_ratio.notna().all()
    # without its twin's runs a faceted step has no row
    assert facet_frame(t[t.problem != FACETED[0]]).empty
    # the summary writes both tables and their claims
    runs = tmp_path / "runs.csv"
    pd.concat([path_runs, every]).drop(columns="time").to_csv(runs, index=False)
    files = {k: tmp_path / f"{k}.csv" for k in ("summary", "by_class", "by_scene", "claims",
                                                "warm", "facets")}
    summary_main(["--inputs", str(runs), "--time-limit", "20", "--summary",
                  str(files["summary"]), "--by-class", str(files["by_class"]), "--by-scene",
                  str(files["by_scene"]), "--claims", str(files["claims"]), "--warm-starts",
                  str(files["warm"]), "--facets", str(files["facets"]), "--profiles",
                  str(tmp_path / "p.png")])
    summary = pd.read_csv(files["summary"])
    assert summary.runs.sum() == len(plain_rows(pd.read_csv(runs)))   # cold rung-0 rows only
    assert len(pd.read_csv(files["warm"])) == 3 and len(pd.read_csv(files["facets"])) == 4
    claims = pd.read_csv(files["claims"])
    assert claims.claim.str.contains("model error").sum() == 1
