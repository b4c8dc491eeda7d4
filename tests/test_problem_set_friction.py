"""The test set's frictional families (contact-qp-5): the family/step schema, version 4
kept, the count, the definition's machine independence, the export in QP and conic form
(round trip to 1e-12, warm starts of a load path), qpbenchmark on the QP part,
and a QP library and the exact reference on an exported frictional problem."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from workflows.cli import main as cli
from workflows.export import load_problem, objective as suite_objective, write_problem
from workflows.problem_set import (CURRENT, TestSet, TestSetError, check, cold_rows,
                                   definition_digits, frictional_steps, load, plain_rows)


def frictional(p) -> bool:
    return p.params.get("friction", "none") != "none"


def test_a_familys_step_is_checked_by_name():
    ts = load()
    fam = {"problem": "circle_square", "params": {"friction": "tresca", "mu": 0.3,
                                                  "shift": 0.01, "shift_steps": 3}}
    for step, allowed in ((4, r"allowed: last, all or an integer 1\.\.3"),
                          ("first", r"allowed: last, all or an integer 1\.\.3"),
                          (0, r"allowed: last, all or an integer 1\.\.3")):
        with pytest.raises(TestSetError, match=r"'families.c.step': .*" + allowed):
            check(TestSet(ts.name, ts.version, "", ts.classes, {"c": {**fam, "step": step}}))
    with pytest.raises(TestSetError, match=r"'families.c.step': 'all' is not allowed without "
                                           "friction"):
        check(TestSet(ts.name, ts.version, "", ts.classes,
                      {"c": {"problem": "circle_square", "step": "all"}}))
    check(TestSet(ts.name, ts.version, "", ts.classes, {"c": {**fam, "step": 2}}))
    with pytest.raises(TestSetError, match="'families.c.params': parameter 'shift_steps'.*allowed: an integer in \\[1, 20\\]"):
        check(TestSet(ts.name, ts.version, "", ts.classes,
                      {"c": {**fam, "params": {**fam["params"], "shift_steps": 0}}}))


def test_version_5_keeps_every_problem_of_version_4_and_adds_at_least_40_frictional():
    before = {p.name: p for p in load("contact-qp-4").problems()}
    after = {p.name: p for p in load("contact-qp-5").problems()}
    assert all(after[name] == p for name, p in before.items())
    added = [p for name, p in after.items() if name not in before]
    assert list(after)[-len(added):] == [p.name for p in added]      # at the end
    assert all(frictional(p) and p.step is not None for p in added)
    assert not any(frictional(p) for p in before.values())
    assert len(added) >= 40 and len([p for p in added if p.size_class == "small"]) >= 40
    params = [p.params for p in added]
    assert {p["friction"] for p in params} == {"tresca", "coulomb"}
    assert {p.problem for p in added} == {"circle_square", "cube_sphere"}
    mus = {p["mu"] for p in params}
    assert min(mus) == 0.1 and 1.0 in mus and 2.0 in mus
    assert any(p.get("E2", 1.0) >= 1e4 for p in params)
    assert any(p.get("nu1", 0.3) >= 0.499 for p in params)
    assert any(p.get("offset", 0.5) == 1.0 for p in params)               # grazing
    # a load-path family: one problem per tangential step
    path = [p.name for p in added if p.family == "circle_square_tresca_path" and p.level == 0]
    assert path == [f"circle_square_tresca_path_L0_s{j}" for j in (1, 2, 3, 4)]
    # the small frictional problems stay small: the scenes' coarsest levels
    assert {(p.problem, p.level) for p in added if p.size_class == "small"} <= {
        ("circle_square", 0), ("circle_square", 1), ("cube_sphere", 0)}


@pytest.mark.parametrize("family", ["circle_square_coulomb_path", "cube_sphere_tresca_q05"])
def test_the_definition_does_not_depend_on_the_references_last_digits(family):
    """Built twice, and with every reference solution changed by a relative 1e-12 (more
    than the round-off between machines), each step's slip bounds, previous state and
    data are identical to the last bit: the rounding to 8 digits absorbs the difference."""
    item = next(p for p in load().problems("small", [family]) if p.level == 0)
    key = (item.problem, tuple(sorted(item.params.items())), item.level)
    build = frictional_steps.__wrapped__
    runs = [build(*key), build(*key), build(*key, perturb=1e-12), build(*key, perturb=-1e-12)]
    for steps in runs[1:]:
        assert steps.keys() == runs[0].keys()
        for j, st in steps.items():
            a, b = runs[0][j].qp.friction, st.qp.friction
            for name in ("slip_bound", "previous", "offset"):
                assert np.array_equal(getattr(a, name), getattr(b, name)), (j, name)
            assert np.array_equal(runs[0][j].qp.f, st.qp.f)
    fr = runs[0][max(runs[0])].qp.friction
    assert fr.slip_bound.max() > 0 and np.array_equal(fr.slip_bound,
                                                      definition_digits(fr.slip_bound))
    assert definition_digits(np.array([1.234567891e-3, 4e-19, -0.0])).tolist() == \
        [1.2345679e-3, 0.0, 0.0]


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """A 2D, a 3D isotropic and a 3D faceted frictional family through the CLI (four
    problems), and the first two steps of a 2D load path written one by one."""
    out = tmp_path_factory.mktemp("friction") / "small"
    assert cli(["export", "--class", "small", "--families", "circle_square_tresca_q05",
                "cube_sphere_coulomb_q05", "cube_sphere_tresca_q05_facets8", "--out", str(out),
                "--quiet"]) == 0
    items = {p.name: p for p in load().problems("small", ["circle_square_tresca_path"])}
    for name in ("circle_square_tresca_path_L0_s1", "circle_square_tresca_path_L0_s2"):
        write_problem(out / name, items[name], CURRENT)
    return out


def second_order_cones(s: np.ndarray, sizes: list[int]) -> float:
    """The largest violation of ``|s_j[1:]| <= s_j[0]`` over consecutive cones."""
    worst, at = 0.0, 0
    for k in sizes:
        worst = max(worst, float(np.linalg.norm(s[at + 1:at + k]) - s[at]))
        at += k
    assert at == s.size
    return worst


def test_frictional_export_round_trip_in_qp_and_cone_form(exported):
    index = json.loads((exported / "index.json").read_text())
    forms = {e["name"]: e["form"] for e in index["problems"]}
    assert forms == {"circle_square_tresca_q05_L0": "qp", "circle_square_tresca_q05_L1": "qp",
                     "cube_sphere_coulomb_q05_L0": "cone",
                     "cube_sphere_tresca_q05_facets8_L0": "qp"}   # the k-gon law: a QP
    for name in [*forms, "circle_square_tresca_path_L0_s1", "circle_square_tresca_path_L0_s2"]:
        folder = exported / name
        meta = json.loads((folder / "meta.json").read_text())
        J, fr = meta["objective"], meta["friction"]
        assert meta["objective_constant"] == 0.0
        assert 0.05 < fr["ratio"] < 0.95 and fr["bounded_nodes"] > 0
        with np.load(folder / "solution.npz") as z:
            x, y = z["x"], z["z"]
        for source in ("npz", "mtx"):
            d = load_problem(folder, source)
            A, b = (d["G"], d["h"]) if meta["form"] == "qp" else (d["A"], d["b"])
            assert abs(0.5 * x @ (d["P"] @ x) + d["q"] @ x - J) <= 1e-12 * abs(J), (name, source)
            # the reference is a KKT point of the exported program
            assert np.abs(d["P"] @ x + d["q"] + A.T @ y).max() <= 1e-9 * np.abs(d["q"]).max()
            s = b - A @ x
            scale = np.abs(x).max()
            if meta["form"] == "qp":
                assert s.min() >= -1e-12 * scale and y.min() >= -1e-12 * np.abs(y).max()
                assert meta["convention"] == "min 1/2 x'Px + q'x  s.t.  Gx <= h"
            else:
                cones = meta["cones"]
                l = cones["nonnegative"]
                assert cones["zero"] == 0 and set(cones["second_order"]) == {3}
                assert l + sum(cones["second_order"]) == A.shape[0] == meta["m"]
                assert s[:l].min() >= -1e-12 * scale and y[:l].min() >= -1e-12
                assert second_order_cones(s[l:], cones["second_order"]) <= 1e-12 * scale
                assert second_order_cones(y[l:], cones["second_order"]) <= 1e-12 * np.abs(y).max()
                assert abs(s @ y) <= 1e-9 * np.abs(s).max() * np.abs(y).max() * s.size
        assert meta["n"] == meta["n_displacements"] + fr["bounded_nodes"]
    coulomb = json.loads((exported / "cube_sphere_coulomb_q05_L0" / "meta.json").read_text())
    fp = coulomb["friction"]["fixed_point"]
    assert fp["status"] == "converged" and fp["residual"] <= 1e-6      # s = mu p to 8 digits
    # the problem is the fixed point's final Tresca step: no solver re-runs the fixed point
    assert coulomb["friction"]["law"] == "coulomb"
    item = load().problems("small", ["cube_sphere_coulomb_q05"])[0]
    assert item.build().friction.law == "tresca"


def test_a_load_path_steps_warm_start_is_the_previous_steps_reference(exported):
    with np.load(exported / "circle_square_tresca_path_L0_s1" / "solution.npz") as z:
        first = {k: z[k] for k in ("u", "p", "lam")}
    with np.load(exported / "circle_square_tresca_path_L0_s2" / "warm_start.npz") as z:
        warm = {k: z[k] for k in ("u", "p", "lam", "x")}
    for k in ("u", "p", "lam"):
        assert np.array_equal(first[k], warm[k]), k
    item = next(p for p in load().problems("small", ["circle_square_tresca_path"])
                if p.name == "circle_square_tresca_path_L0_s2")
    st = item.frictional_step()
    before = next(p for p in load().problems("small", ["circle_square_tresca_path"])
                  if p.name == "circle_square_tresca_path_L0_s1").build().friction
    # the step's previous state is the first step's reference, rounded as the definition
    assert np.array_equal(st.qp.friction.previous,
                          definition_digits(before.T @ first["u"] + before.offset))
    meta = json.loads((exported / "circle_square_tresca_path_L0_s2" / "meta.json").read_text())
    assert meta["friction"]["step"] == 2 and meta["friction"]["steps"] == 4
    assert warm["x"].size == meta["n"]


def test_qpbenchmark_runs_the_qp_form_only(exported, tmp_path, qpbenchmark_set):
    """qpbenchmark's module reads the 2D steps and the 3D faceted one (the QP form), not
    the 3D cone programs, and its runner solves them with OSQP at the exported objective."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    test_set = qpbenchmark_set(exported / "contact_qp.py")
    problems = {p.name: p for p in test_set}
    assert set(problems) == {"circle_square_tresca_q05_L0", "circle_square_tresca_q05_L1",
                             "cube_sphere_tresca_q05_facets8_L0"}
    d = load_problem(exported / "circle_square_tresca_q05_L0")
    assert (problems["circle_square_tresca_q05_L0"].G != d["G"]).nnz == 0
    results = tmp_path / "osqp.csv"
    run = subprocess.run([Path(sys.executable).parent / "qpbenchmark", "--results-path",
                          str(results), str(exported / "contact_qp.py"), "run", "--solver",
                          "osqp", "--author",
                          "contactbench-tests"],
                         capture_output=True, text=True, cwd=tmp_path, stdin=subprocess.DEVNULL,
                         env={**os.environ, "CONTACT_QP_TIME_LIMIT": "60"})
    assert run.returncode == 0, run.stderr[-2000:]
    from qpbenchmark.utils import time_solve_problem

    theirs = pd.read_csv(results)
    assert set(theirs.problem) == set(problems)
    theirs = theirs[theirs.settings == "high_accuracy"].set_index("problem")
    for name, problem in problems.items():
        J = json.loads((exported / name / "meta.json").read_text())["objective"]
        assert bool(theirs.loc[name, "found"]), name
        sol, _ = time_solve_problem(problem, "osqp",
                                    **test_set.solver_settings["high_accuracy"]["osqp"])
        J_theirs = 0.5 * sol.x @ (problem.P @ sol.x) + problem.q @ sol.x
        assert abs(J_theirs - J) <= 1e-6 * abs(J), name


def test_a_library_and_the_exact_reference_solve_an_exported_frictional_problem(exported):
    """The exported 2D step read back is the suite's step (to 1e-12); Clarabel on the
    read-back QP itself reaches the exported objective, and the suite's OSQP and exact
    reference on the step are verified converged at it."""
    import clarabel
    import scipy.sparse as sp

    from solvers.interface import solve
    from workflows.studies.test_set.run import check_identical

    folder = exported / "circle_square_tresca_q05_L1"
    item = next(p for p in load().problems("small", ["circle_square_tresca_q05"])
                if p.name == folder.name)
    qp = item.build()
    check_identical(qp, folder)
    J = json.loads((folder / "meta.json").read_text())["objective"]
    d = load_problem(folder)
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    sol = clarabel.DefaultSolver(sp.csc_matrix(d["P"]), d["q"], sp.csc_matrix(d["G"]),
                                 d["h"], [clarabel.NonnegativeConeT(d["G"].shape[0])],
                                 settings).solve()
    assert str(sol.status) == "Solved"
    assert abs(sol.obj_val - J) <= 1e-7 * abs(J)
    for name in ("osqp", "tresca_exact"):
        res = solve(qp, name, "mid")
        assert res.status == "converged", (name, res.message)
        assert abs(suite_objective(qp, res.u, res.p) - J) <= 1e-6 * abs(J), name


def test_runs_script_on_a_frictional_family(exported, tmp_path):
    """The runs script on a 2D frictional step: the exact reference and OSQP verified
    converged, a solver without friction skipped with its reason, and a library whose
    claim the verification does not confirm (Clarabel's interior point) reported as
    such: no row is converged beyond its tolerance."""
    from workflows.studies.test_set.run import main as runs_main

    out = tmp_path / "runs.csv"
    runs_main(["--set", CURRENT, "--class", "small", "--family", "circle_square_tresca_q05",
               "--levels", "0", "--export", str(exported), "--solvers", "tresca_exact",
               "osqp", "clarabel", "pdas", "--presets", "mid", "--time-limit", "20",
               "--out", str(out)])
    runs = cold_rows(pd.read_csv(out))
    t = plain_rows(runs).set_index("solver")
    assert t.index.is_unique
    assert t.loc["pdas", "status"] == "skipped" and "friction" in t.loc["pdas", "message"]
    for name in ("tresca_exact", "osqp"):
        assert t.loc[name, "status"] == "converged"
        counted = runs[(runs.solver == name) & runs.counted.fillna(False).astype(bool)]
        assert len(counted) == 1 and counted.status.iloc[0] == "converged", name
    conv = runs[runs.status == "converged"]
    assert (conv.energy_error <= conv.tol).all()
    assert set(t.status) <= {"converged", "inaccurate", "max_iter", "time_limit", "skipped"}
    assert t.loc["tresca_exact", "objective_error"] <= 1e-10


def test_shift_steps_split_the_tangential_step_into_equal_increments():
    """``shift_steps = 1`` is the two-step path as assembled (every existing result
    unchanged); with 3 increments the last step is that path's and step 1 is the path
    assembled with a third of the shift (the data are affine in the shift)."""
    from problems.spec import problems

    spec = problems()["circle_square"]
    make = lambda **kw: spec.build(0, spec.options(friction="tresca", mu=0.3, **kw)).friction.path
    one, three, third = make(shift=0.012), make(shift=0.012, shift_steps=3), make(shift=0.004)
    assert len(one) == 2 and len(three) == 4
    for a, b in zip(one, (three[0], three[-1])):
        for name in ("f", "g", "offset"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
    for name in ("f", "g", "offset"):
        a, b = getattr(three[1], name), getattr(third[1], name)
        assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max(), name
