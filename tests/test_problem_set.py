"""The contact QP test set: its definition, the export (round trip to 1e-12), the CLI's
refusals, qpbenchmark's own runner on the exported small class against the suite's
solve of the same problems, and the runs script on one family."""
from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from workflows.cli import main as cli
from workflows.export import load_problem
from workflows.export import objective as suite_objective
from workflows.problem_set import CLASSES, CURRENT, TestSet, TestSetError, check, load

SMALL_LIMIT = 20_000          # the quick run's budget: the small class stays below it


def test_the_set_has_at_least_80_named_problems_in_three_classes():
    ts = load(CURRENT)
    every = ts.problems()
    assert len(every) >= 80
    assert len({p.name for p in every}) == len(every)
    assert all(ts.problems(c) for c in CLASSES)
    problems = {p.problem for p in every}
    assert problems == {"circle_square", "cube_sphere", "roll_stack", "flat_blocks"}
    # the variations the set promises, by their parameters
    params = [p.params for p in every]
    assert any(p.get("coupling") == "stabilised" for p in params)
    assert any(p.get("nu1", 0) >= 0.4999 for p in params)
    assert any(p.get("gap", 0) < 0 for p in params)


def added_problems(old: str, new: str) -> list:
    """The problems of the set ``new`` that ``old`` does not have, after checking that
    ``new`` keeps every problem of ``old`` unchanged and adds its own at the end."""
    before = {p.name: p for p in load(old).problems()}
    after = {p.name: p for p in load(new).problems()}
    assert all(after[name] == p for name, p in before.items())
    added = [p for name, p in after.items() if name not in before]
    assert added and list(after)[-len(added):] == [p.name for p in added]
    return added


def test_version_2_keeps_every_problem_of_version_1_and_adds_p2_families():
    added = added_problems("contact-qp-1", "contact-qp-2")
    assert all(p.params["degree"] == 2 for p in added)
    # a P2 family's own levels: level 0 in the small class (the nodes of P1 level 1)
    small = {p.name for p in added if p.size_class == "small"}
    assert small == {"circle_square_p2_L0", "cube_sphere_p2_L0", "hard_incompressible_p2_L0"}


def test_version_3_keeps_every_problem_of_version_2_and_adds_two_pass_families():
    added = added_problems("contact-qp-2", "contact-qp-3")
    assert all(p.params["coupling"] == "two_pass" for p in added)
    small = {p.name for p in added if p.size_class == "small"}
    assert small == {f"{f}_L{level}" for level in (2, 3)
                     for f in ("degenerate_two_pass_matching", "degenerate_two_pass")} | \
        {"circle_square_two_pass_L0", "circle_square_two_pass_L1"}


MORTAR_FAMILIES = ("circle_square_mortar", "circle_square_mortar_dual", "cube_sphere_mortar",
                   "cube_sphere_mortar_dual")


def test_version_4_keeps_every_problem_of_version_3_and_adds_mortar_families():
    added = added_problems("contact-qp-3", "contact-qp-4")
    assert {p.family for p in added} == set(MORTAR_FAMILIES)
    assert {(p.problem, p.params["coupling"]) for p in added} == {
        (s, c) for s in ("circle_square", "cube_sphere") for c in ("mortar", "mortar_dual")}
    # the plain family's (named after its scene) levels in every class: the rows
    # change, not the meshes
    v4 = load("contact-qp-4")
    for p in added:
        assert v4.levels(p.family, p.size_class) == v4.levels(p.problem, p.size_class)
    small = {p.name for p in added if p.size_class == "small"}
    assert small == {f"{f}_L{level}" for f in MORTAR_FAMILIES for level in (0, 1)}


def test_a_familys_own_levels_are_checked_by_name():
    ts = load()
    families = {"c": {"problem": "circle_square", "levels": {"small": [0, 99]}}}
    with pytest.raises(TestSetError, match=r"'families.c.levels.small': levels \[99\].*"
                                           r"allowed: integers 0\.\."):
        check(TestSet(ts.name, ts.version, "", ts.classes, families))
    with pytest.raises(TestSetError, match="allowed: small, medium, large"):
        check(TestSet(ts.name, ts.version, "", ts.classes,
                      {"c": {"problem": "circle_square", "levels": {"tiny": [0]}}}))
    with pytest.raises(TestSetError, match=r"'families.c': keys \['level'\].*allowed: "
                                           "problem, params, levels, step"):
        check(TestSet(ts.name, ts.version, "", ts.classes,
                      {"c": {"problem": "circle_square", "level": {"small": [0]}}}))


def test_bad_set_and_class_names_are_refused():
    with pytest.raises(TestSetError, match="allowed: contact-qp-1"):
        load("contact-qp-0")
    with pytest.raises(TestSetError, match="allowed: small, medium, large"):
        load().problems("huge")


def frictionless_families() -> list[str]:
    """The current set's families without friction (the frictional ones' export and runs:
    tests/test_problem_set_friction.py)."""
    ts = load()
    return [f for f, e in ts.families.items()
            if (e.get("params") or {}).get("friction", "none") == "none"]


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    out = tmp_path_factory.mktemp("export") / "small"
    assert cli(["export", "--class", "small", "--families", *frictionless_families(),
                "--out", str(out), "--quiet"]) == 0
    return out


def objective(d, x):
    return 0.5 * x @ (d["P"] @ x) + d["q"] @ x


def test_export_round_trip_reproduces_the_reference(small):
    index = json.loads((small / "index.json").read_text())
    assert index["set"] == CURRENT and index["size_class"] == "small"
    assert len(index["problems"]) == len(load().problems("small", frictionless_families()))
    assert {e["form"] for e in index["problems"]} == {"qp"}
    assert (small / "contact_qp.py").exists()
    for entry in index["problems"]:
        folder = small / entry["folder"]
        meta = json.loads((folder / "meta.json").read_text())
        for name, digest in meta["files"].items():
            assert hashlib.sha256((folder / name).read_bytes()).hexdigest() == digest, name
        with np.load(folder / "solution.npz") as z:
            x, z_ref = z["x"], z["z"]
        J = meta["objective"]
        for source in ("npz", "mtx"):
            d = load_problem(folder, source)
            assert d["P"].shape == (meta["n"], meta["n"]) and d["G"].shape == (meta["m"],
                                                                              meta["n"])
            assert abs(objective(d, x) - J) <= 1e-12 * abs(J), (entry["name"], source)
            # the reference is a KKT point of the exported problem
            scale = np.abs(d["q"]).max()
            assert np.abs(d["P"] @ x + d["q"] + d["G"].T @ z_ref).max() <= 1e-7 * scale
            assert (d["G"] @ x - d["h"]).max() <= 1e-9 * max(np.abs(x).max(), 1e-300)
            assert z_ref.min() >= 0
        assert meta["n"] < SMALL_LIMIT
        assert meta["condition"]["kappa_1"] > 1
    # the index tells the degenerate problems apart: rows tight at the reference that
    # depend on the others (the two-pass rows of coinciding nodes: all of a matching
    # pair, every second coarse node at 2:3), none elsewhere
    dependent = {e["name"]: e["dependent_tight_rows"] for e in index["problems"]}
    coarse_nodes = {2: 17, 3: 33}                       # 2:3, level L: 2^(L+2) + 1
    for level, nodes in coarse_nodes.items():
        assert dependent[f"degenerate_two_pass_matching_L{level}"] == 2 ** (level + 1) + 1
        assert dependent[f"degenerate_two_pass_L{level}"] == (nodes + 1) // 2
    assert {name for name, k in dependent.items() if k} == {
        f"{f}_L{level}" for level in (2, 3)
        for f in ("degenerate_two_pass_matching", "degenerate_two_pass")}
    # the mortar rows' structure, read from the exported G alone: a dual row owns unknowns
    # that no other row touches (D diagonal: one constrained node per row, what the box
    # transformation of TNNMG needs); a standard row shares its constrained node with its
    # neighbours' rows (D the surface mass matrix)
    for family in MORTAR_FAMILIES:
        for level in (0, 1):
            G = load_problem(small / f"{family}_L{level}")["G"].tocsc()
            lone = np.diff(G.indptr) == 1                  # columns in one row only
            owners = np.unique(G.indices[G.indptr[:-1][lone]])
            if family.endswith("_dual"):
                assert owners.size == G.shape[0], (family, level)
            else:
                assert owners.size == 0, (family, level, owners.size)
    roll = json.loads((small / "roll_stack_L0" / "meta.json").read_text())
    assert roll["floating_modes"] > 0 and roll["units"] == "m, N, Pa"     # the scene's own
    stab = json.loads((small / "flat_blocks_stabilised_L2" / "meta.json").read_text())
    assert stab["n"] > stab["n_displacements"]          # the slack form


def test_export_never_overwrites_and_names_what_is_allowed(small, tmp_path, capsys):
    before = (small / "index.json").read_bytes()
    assert cli(["export", "--class", "small", "--out", str(small)]) == 2
    assert "--force" in capsys.readouterr().err
    assert (small / "index.json").read_bytes() == before
    assert cli(["export", "--set", "nope", "--class", "small", "--out",
                str(tmp_path / "a")]) == 2
    assert "allowed: contact-qp-1" in capsys.readouterr().err
    assert cli(["export", "--class", "tiny", "--out", str(tmp_path / "b")]) == 2
    assert "allowed: small, medium, large" in capsys.readouterr().err
    assert cli(["export", "--class", "small", "--families", "nope", "--out",
                str(tmp_path / "c")]) == 2
    assert not any(tmp_path.iterdir())            # nothing written, not even a partial folder
    out = tmp_path / "d"
    out.mkdir()
    (out / "old").write_text("x")
    assert cli(["export", "--class", "small", "--families", "hard_no_contact", "--out",
                str(out), "--force", "--quiet"]) == 0
    assert not (out / "old").exists()
    assert [e["name"] for e in json.loads((out / "index.json").read_text())["problems"]] == \
        ["hard_no_contact_L0", "hard_no_contact_L1"]
    assert [p.name for p in tmp_path.iterdir()] == ["d"]


#: qpbenchmark's settings and the suite's presets with the same tolerances
SETTINGS = {"low_accuracy": "low", "mid_accuracy": "mid", "high_accuracy": "high"}


#: One family of each kind for qpbenchmark's runner: 2D and 3D, a floating body, P2,
#: stabilised, dependent rows, dual mortar, no contact, and SI units (where Clarabel at
#: high accuracy finds no solution).
QPBENCHMARK_SAMPLE = ("circle_square", "hard_si_units", "hard_no_contact", "cube_sphere",
                      "roll_stack", "flat_blocks_stabilised", "circle_square_p2",
                      "degenerate_two_pass", "cube_sphere_mortar_dual")


@pytest.fixture(scope="module")
def small_sample(tmp_path_factory):
    """The small class of :data:`QPBENCHMARK_SAMPLE`, exported."""
    out = tmp_path_factory.mktemp("export") / "sample"
    assert cli(["export", "--class", "small", "--families", *QPBENCHMARK_SAMPLE,
                "--out", str(out), "--quiet"]) == 0
    return out


@pytest.mark.slow
def test_qpbenchmark_runner_agrees_with_the_suite(small_sample, tmp_path, qpbenchmark_set):
    """qpbenchmark's CLI runs Clarabel on an exported sample of the small class (one family
    of each kind, :data:`QPBENCHMARK_SAMPLE`) and writes its report;
    per problem and settings its status agrees with the suite's Clarabel on the same
    (unscaled) problem, and the objective of qpbenchmark's solve agrees too.

    The settings are not identical: qpbenchmark sets Clarabel's relative tolerances to 0,
    the suite's presets set them to tol (solvers/qp_libraries.py), so the suite's test is
    the looser one: what qpbenchmark finds, the suite's Clarabel finds (on SI units at
    high accuracy qpbenchmark's absolute gap of 1e-9 is out of reach, the suite's is not)."""
    results = tmp_path / "clarabel.csv"
    env = {**os.environ, "CONTACT_QP_TIME_LIMIT": "60"}
    run = subprocess.run([Path(sys.executable).parent / "qpbenchmark", "--results-path",
                          str(results), str(small_sample / "contact_qp.py"), "run", "--solver",
                          "clarabel", "--author", "contactbench-tests"],
                         capture_output=True, text=True, env=env, cwd=tmp_path,
                         stdin=subprocess.DEVNULL)
    assert run.returncode == 0, run.stderr[-2000:]
    assert (tmp_path / "contact_qp.md").exists()
    theirs = pd.read_csv(results)
    index = json.loads((small_sample / "index.json").read_text())
    assert set(theirs.problem) == {e["name"] for e in index["problems"]}

    from qpbenchmark.utils import time_solve_problem

    from solvers.interface import solve
    test_set = qpbenchmark_set(small_sample / "contact_qp.py")
    by_name = {p.name: p for p in load().problems("small")}
    compared = 0
    for problem in test_set:
        item = by_name[problem.name]
        qp = item.build()
        J_ref = json.loads((small_sample / item.name / "meta.json").read_text())["objective"]
        for settings, preset in SETTINGS.items():
            row = theirs[(theirs.problem == problem.name) & (theirs.settings == settings)]
            ours = solve(qp, "clarabel", preset, scale=False, time_limit=60)
            if bool(row.found.iloc[0]):
                assert ours.claimed_status == "converged", (problem.name, settings,
                                                            ours.message)
            if settings == "mid_accuracy" and ours.claimed_status == "converged":
                sol, _ = time_solve_problem(problem, "clarabel",
                                            **test_set.solver_settings[settings]["clarabel"])
                J_theirs = 0.5 * sol.x @ (problem.P @ sol.x) + problem.q @ sol.x
                J_ours = suite_objective(qp, ours.u, ours.p)
                assert abs(J_theirs - J_ours) <= 1e-6 * abs(J_ref), problem.name
                compared += 1
    assert compared >= len(index["problems"]) // 2


def test_runs_script_on_one_family(small, tmp_path):
    from workflows.studies.test_set.run import main as runs_main
    from report.test_set import main as summary_main

    out = tmp_path / "runs.csv"
    runs_main(["--set", CURRENT, "--class", "small", "--family", "flat_blocks_stabilised",
               "--export", str(small), "--solvers", "pdas", "osqp", "semismooth_newton",
               "--time-limit", "20", "--out", str(out)])
    every = pd.read_csv(out)
    t = every[every.rung == 0]
    assert len(t) == 2 * 3 * 3                      # levels x solvers x presets
    conv = t[t.status == "converged"]
    assert len(conv) >= 12
    assert (conv.energy_error <= conv.tol * 1.001).all()
    assert (t[t.solver == "pdas"].objective_error <= 1e-10).all()
    # each ladder: at least three rungs, the counted one the loosest verified, repeated
    for _, ladder in every.groupby(["problem", "solver", "preset"]):
        assert len(ladder) >= 3 and ladder.rung.is_unique
        counted = ladder[ladder.counted.astype(bool)]
        verified = ladder[ladder.status == "converged"]
        assert len(counted) == (1 if len(verified) else 0)
        if len(counted):
            c = counted.iloc[0]
            assert c.rung == verified.rung.min() and c.repeats == 3
            assert c.time_min <= c.time_median <= c.time_max
    files = {k: tmp_path / f"{k}.csv" for k in ("summary", "by_class", "by_scene", "claims",
                                                 "boards")}
    summary_main(["--inputs", str(out), "--time-limit", "20", "--summary", str(files["summary"]),
                  "--by-class", str(files["by_class"]), "--by-scene", str(files["by_scene"]),
                  "--claims", str(files["claims"]), "--profiles", str(tmp_path / "p.png"),
                  "--leaderboards", str(files["boards"]),
                  "--pages", f"frictionless={tmp_path / 'frictionless.md'}",
                  "--charts", str(tmp_path / "p.html"),
                  "--work-precision", f"flat_blocks_stabilised={tmp_path / 'w.png'}"])
    s = pd.read_csv(files["summary"])
    assert set(s.solver) == {"pdas", "osqp", "semismooth_newton"} and (s.problems == 2).all()
    assert (s.problem_class == "frictionless").all()
    boards = pd.read_csv(files["boards"])
    assert set(boards[boards.standing == "reference"].solver) == {"pdas"}
    assert set(boards[boards.standing == "ranked"].solver) == {"osqp", "semismooth_newton"}
    assert "# Leaderboard: frictionless contact QP" in (tmp_path / "frictionless.md").read_text()
    assert (pd.read_csv(files["by_scene"]).scene == "flat_blocks").all()
    assert pd.read_csv(files["claims"])["pass"].iloc[0]
    assert (tmp_path / "w.png").read_bytes()[:4] == b"\x89PNG"
    from report.charts import page_specs, spec_problems
    profiles, work = page_specs((tmp_path / "p.html").read_text())
    assert spec_problems(profiles) == [] and spec_problems(work) == []
    assert {r["solver"] for r in profiles["data"]["values"]} == set(s.solver) - {"pdas"}
    shares = pd.DataFrame(profiles["data"]["values"])
    assert shares["share"].between(0, 1).all() and (shares.groupby(
        ["problem_class", "preset", "solver"])["share"].apply(
            lambda x: x.is_monotonic_increasing)).all()
    # the work-precision chart has the runs the PNG draws: one per rung with an energy error
    solved = every[~every.solver.isin(["reference", "linear_floor"])]
    assert len(work["data"]["values"]) == int(solved.energy_error.notna().sum())


def test_runs_script_on_the_mortar_families_tnnmg_takes_dual_rows_only(small, tmp_path):
    """TNNMG's box transformation needs one constrained node per row: on the exported
    3D mortar problems it takes the dual rows (verified, within tol of the exact
    reference in the energy norm) and skips the standard ones, saying why."""
    from workflows.studies.test_set.run import main as runs_main

    tables = []
    for family in ("cube_sphere_mortar", "cube_sphere_mortar_dual"):
        out = tmp_path / f"{family}.csv"
        runs_main(["--set", CURRENT, "--class", "small", "--family", family, "--levels", "0",
                   "--export", str(small), "--solvers", "tnnmg", "--presets", "mid",
                   "--time-limit", "20", "--out", str(out)])
        tables.append(pd.read_csv(out).query("rung == 0"))     # the plain runs
    t = pd.concat(tables).set_index("family")
    standard, dual = t.loc["cube_sphere_mortar"], t.loc["cube_sphere_mortar_dual"]
    assert standard.status == "skipped" and "one per constrained node" in standard.message
    assert dual.status == "converged" and dual.energy_error <= dual.tol


def test_a_rebuilt_problem_that_differs_from_its_export_is_refused(small, tmp_path):
    import shutil

    from workflows.studies.test_set.run import check_identical
    folder = tmp_path / "hard_no_contact_L0"
    shutil.copytree(small / "hard_no_contact_L0", folder)
    item = next(p for p in load().problems("small") if p.name == folder.name)
    qp = item.build()
    check_identical(qp, folder)
    d = load_problem(folder)
    np.savez_compressed(folder / "problem.npz", q=d["q"], h=d["h"] + 1e-6,
                        **{f"{k}_{a}": getattr(d[k], a) for k in ("P", "G")
                           for a in ("data", "indices", "indptr")},
                        P_shape=np.array(d["P"].shape), G_shape=np.array(d["G"].shape))
    with pytest.raises(RuntimeError, match="rebuilt h differs"):
        check_identical(qp, folder)


def test_a_run_is_correct_to_what_the_verification_certifies():
    """At the high preset the certified bound bottoms out at its floating-point floor
    (~1e-7 relative): a verified run there is correct up to that floor, not to 1e-9;
    below the floor the tolerance itself is the bar."""
    from report.test_set import accurate_runs

    t = pd.DataFrame({"tol": [1e-9, 1e-9, 1e-6, 1e-6],
                      "energy_bound_floor": [8e-8, 8e-8, 8e-8, np.nan],
                      "energy_error": [5e-9, 4e-7, 9e-7, 2e-6]})
    assert accurate_runs(t).tolist() == [True, False, True, False]


def test_a_set_file_of_your_own_extends_the_suites(tmp_path):
    """A set file outside the suite, loaded by its path, holds the set it extends and its
    own families after them; it may not define a family of that set again, and a file
    that is not there is named."""
    import yaml

    base = load(CURRENT)
    mine = tmp_path / "mine.yaml"
    mine.write_text(yaml.safe_dump({
        "name": "mine", "version": 2, "extends": CURRENT,
        "families": {"circle_square_soft": {"problem": "circle_square",
                                            "params": {"E2": 0.5}, "levels": {"small": [0]}}}}))
    ts = load(mine)
    assert ts.id == "mine-2" and list(ts.families)[:len(base.families)] == list(base.families)
    assert list(ts.families)[-1] == "circle_square_soft" and ts.classes == base.classes
    assert [p.name for p in ts.problems("small", ["circle_square_soft"])] == [
        "circle_square_soft_L0"]
    again = tmp_path / "again.yaml"
    again.write_text(yaml.safe_dump({"name": "again", "version": 1, "extends": "mine.yaml",
                                     "families": {"circle_square": {"problem": "circle_square"}}}))
    with pytest.raises(TestSetError, match=r"\['circle_square'\] are families of the set it "
                                           r"extends, mine-2"):
        load(again)
    with pytest.raises(TestSetError, match="'nowhere.yaml' does not exist"):
        load("nowhere.yaml")
