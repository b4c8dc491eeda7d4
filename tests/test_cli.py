"""The command line: every registered solver on every contact scene, the installed command,
and bad input (exit code 2, a message naming the parameter, nothing written)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from problems.kkt import energy_error, kkt_residuals
from problems.slack import slack_form
from problems.spec import Parameter, ParameterError, problems, resolve_parameters
from solvers.interface import solve, solvers
from workflows.cli import main
from agreement import within_certificate

#: the roll stack (a floating work roll, minutes for some QP libraries at its size) is left
#: out here; tests/test_roll_stack.py asserts every solver's status on it instead; so is
#: hertz_mindlin (65,000 unknowns at level 1: minutes for the QP libraries), whose
#: solvers tests/test_hertz_mindlin.py runs at level 0
CONTACT_SCENES = sorted(n for n, s in problems().items()
                        if s.kind == "contact" and n not in ("roll_stack", "hertz_mindlin"))
#: the template scene of an installed package (tests/example_scene): a scene the suite's
#: solvers have never been tuned on
EXAMPLE_SCENE = "cylinder_pair"
SOLVERS = sorted(solvers())


def test_problem_registry_finds_modules_with_a_problem_spec():
    reg = problems()
    assert {"laplace_nonmatching", "circle_square"} <= set(reg)
    assert all(spec.name == name for name, spec in reg.items())
    assert "spec" not in reg and "fem" not in reg and "qp" not in reg  # machinery


def test_parameter_validation_messages():
    p = Parameter("load", 0.01, "body force", low=0.0, low_open=True)
    assert p.validate("0.5") == 0.5
    with pytest.raises(ParameterError, match=r"'load'.*\(0.0, inf\)"):
        p.validate("-1")
    with pytest.raises(ParameterError, match="'load'"):
        p.validate("abc")
    with pytest.raises(ParameterError, match="not finite"):
        p.validate("nan")
    with pytest.raises(ParameterError, match="known parameters: load"):
        resolve_parameters((p,), {"lod": 1}, "problem 'x'")


def test_cli_list(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for name in [*problems(), *solvers(), "solver_comparison", "tolerance presets",
                 "--set ahat.sweeps=..."]:
        assert name in out


def test_cli_solves_the_linear_problem(tmp_path):
    out = tmp_path / "run.json"
    rc = main(["solve", "--problem", "laplace_nonmatching", "--level", "1", "--set", "case=linear",
               "--set", "variant=conforming", "--out", str(out)])
    assert rc == 0
    data = json.loads(out.read_text())
    assert data["status"] == "converged" and data["err_h1"] < 1e-11
    assert data["provenance"]["packages"]["scikit-fem"]


@pytest.fixture(scope="module")
def references(with_example_scene):
    """The exact solution of every contact scene, and of the example scene, at level 1."""
    out = {}
    for name in [*CONTACT_SCENES, EXAMPLE_SCENE]:
        qp = problems()[name].make(1)
        ref = solve(qp, "pdas", tol=1e-12)
        assert ref.status == "converged"
        out[name] = (qp, ref)
    return out


@pytest.mark.parametrize("scene", [*CONTACT_SCENES, EXAMPLE_SCENE])
@pytest.mark.parametrize("solver", SOLVERS)
def test_every_solver_runs_through_the_cli(tmp_path, references, scene, solver, monkeypatch):
    """The command's record of a run is the run's verified result, checked against the
    scene built here independently (its KKT residuals recomputed, its error within the
    certified bound of the exact reference)."""
    qp, ref = references[scene]
    runs = []

    def recorded(*args, **kwargs):          # the run the command makes, kept for the test
        runs.append(solve(*args, **kwargs))
        return runs[-1]

    monkeypatch.setattr("solvers.interface.solve", recorded)
    out = tmp_path / "run.json"
    assert main(["solve", "--problem", scene, "--level", "1", "--solver", solver,
                 "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["solver"] == solver and data["m"] == qp.m and data["n"] == qp.n
    # the recorded status is the verified one, of the command's one run
    assert len(runs) == 1 and runs[0].solver == solver
    res = runs[0]
    assert data["status"] == res.status
    if res.status == "skipped":  # a solver for another problem (tresca_exact: friction only)
        assert data["message"] == res.message and not solvers()[solver].check(qp)[0]
        return
    if res.gap is None:         # no finite answer (HiGHS's "Solve error"): a failed row
        assert data["status"] == "failed" and "non-finite" in data["message"]
        return
    assert data["kkt_max"] == pytest.approx(res.kkt.max, rel=1e-6, abs=1e-14)
    assert (data["status"] == "converged") == (data["claimed_status"] == "converged"
                                              and data["kkt_max"] <= 1e-6
                                              and res.gap.meets(1e-6))
    # the reported bound is certified: never below its floor, and the error within it
    assert data["energy_bound"] >= data["energy_bound_floor"] > 0
    assert within_certificate(energy_error(qp, res.u, ref.u), data["energy_bound"],
                              data["energy_bound_floor"])
    p = np.asarray(data["contact"]["p"])
    assert np.allclose(p, res.p, rtol=1e-8, atol=1e-12 * np.abs(res.p).max())
    if data["status"] == "converged":
        assert energy_error(qp, res.u, ref.u) < 1e-4
        assert np.max(np.abs(p - ref.p)) < 1e-3 * np.max(ref.p)
    assert kkt_residuals(qp, res.u, res.p).max == pytest.approx(res.kkt.max)


def test_a_bound_below_its_rounding_floor_is_reported_at_the_floor(tmp_path, capsys):
    """The exact solve's duality gap is rounding: its raw bound (here ~1e-9, on another
    BLAS kernel 0) lies below the floor (~1e-7) and certifies nothing smaller. The JSON,
    the status line and the result row report the floor, with the floor beside it."""
    qp = problems()["flat_blocks"].make(1)
    res = solve(qp, "pdas", tol=1e-12)
    assert res.gap.relative_energy_bound < res.gap.floor      # the case under test
    assert res.summary()["energy_bound"] == res.gap.floor == res.gap.certified_bound
    out = tmp_path / "run.json"
    assert main(["solve", "--problem", "flat_blocks", "--level", "1", "--solver", "pdas",
                 "--tol", "1e-12", "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["energy_bound"] == data["energy_bound_floor"] == pytest.approx(res.gap.floor)
    assert f"energy_bound {data['energy_bound']:.1e} (its rounding floor)" in \
        capsys.readouterr().out


@pytest.mark.parametrize("solver", ["highs", "pdas"])
def test_solve_without_out_prints_its_status_and_writes_nothing(tmp_path, monkeypatch, capsys,
                                                                solver):
    """``--out`` is optional: the status line (with the failed check and the residuals)
    is the whole output, and no file appears."""
    monkeypatch.chdir(tmp_path)
    assert main(["solve", "--problem", "flat_blocks", "--level", "1",
                 "--solver", solver]) == 0
    line = capsys.readouterr().out.strip()
    res = solve(problems()["flat_blocks"].make(1), solver, tol="mid")
    assert res.status != "skipped"
    assert line.startswith(f"flat_blocks level 1: {solver} {res.status}")
    assert f"kkt_max {res.kkt.max:.1e}" in line and "->" not in line
    assert (f"above tolerance: {res.failed_check}" in line) == bool(res.failed_check)
    assert list(tmp_path.iterdir()) == []


def test_a_skipped_solve_is_reported_through_the_cli(tmp_path, capsys):
    out = tmp_path / "run.json"
    assert main(["solve", "--problem", "flat_blocks", "--level", "1", "--set",
                 "coupling=mortar", "--solver", "tnnmg", "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["status"] == "skipped" and "cannot be turned into bounds" in data["message"]
    assert data["kkt"] is None and data["contact"] is None
    assert "skipped (skipped: the constraints cannot be turned into bounds" in \
        capsys.readouterr().out


@pytest.mark.parametrize("solver", SOLVERS)
def test_every_solver_runs_the_stabilised_coupling_through_the_cli(tmp_path, solver):
    """The stabilised formulation of Sect. 7.5 (C != 0): natively or in slack form, every
    solver's answer is verified on the stabilised problem and certified against it."""
    qp = problems()["flat_blocks"].make(1, coupling="stabilised")
    ref = solve(qp, "pdas", tol=1e-12)
    out = tmp_path / "run.json"
    assert main(["solve", "--problem", "flat_blocks", "--level", "1", "--set",
                 "coupling=stabilised", "--solver", solver, "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["m"] == qp.m > qp.m_contact
    res = solve(qp, solver, tol="mid")
    assert data["status"] == res.status
    if res.status == "skipped":       # a solver that cannot take it says so, with its reason
        assert data["message"] == res.message and "skipped: " in res.message
        assert not solvers()[solver].check(slack_form(qp))[0]
        return
    # the bound is certified down to its floating-point floor (below it, both it and the
    # reference's own error are rounding)
    assert data["energy_bound"] >= data["energy_bound_floor"]
    assert within_certificate(energy_error(qp, res.u, ref.u), data["energy_bound"],
                              data["energy_bound_floor"])
    if data["status"] == "converged":
        assert energy_error(qp, res.u, ref.u) < 1e-4


def test_the_installed_command_runs_the_thesis_solver(tmp_path):
    """The command that once ended in a traceback (dict.update got 'n' twice)."""
    exe = Path(sys.executable).parent / "contactbench"
    assert exe.exists(), "the README's setup installs the contactbench command"
    out, vtu = tmp_path / "x.json", tmp_path / "x.vtu"
    proc = subprocess.run([str(exe), "solve", "--problem", "circle_square", "--level", "2",
                           "--solver", "augmented_projection", "--set", "schur=multilevel",
                           "--set", "ahat.sweeps=2", "--out", str(out), "--vtu", str(vtu)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    data = json.loads(out.read_text())
    assert data["status"] == "converged" and data["kkt_max"] <= 1e-6
    assert data["solver_options"]["ahat.sweeps"] == 2
    assert data["n_nodes"] == 16636 and data["contact"]["force"][1] > 0
    import meshio
    mesh = meshio.read(vtu)
    assert {"displacement", "contact_pressure"} <= set(mesh.point_data)
    assert mesh.point_data["contact_pressure"].max() > 0 and "von_mises" in mesh.cell_data


BAD_INPUTS = [
    (["--problem", "nope"], "unknown problem 'nope'; allowed: "),
    (["--problem", "circle_square", "--solver", "gurobi"], "unknown solver 'gurobi'; allowed:"),
    (["--problem", "circle_square", "--level", "99"], "'level': 99 is out of range"),
    (["--problem", "circle_square", "--level", "1.5"], "'level': cannot use '1.5'"),
    (["--problem", "circle_square", "--level", "-1"], "'level': -1 is out of range"),
    (["--problem", "circle_square", "--set", "radius"], "'--set': 'radius' is not allowed; allowed: key=value"),
    (["--problem", "circle_square", "--set", "=3"], "'--set': '=3' is not allowed"),
    (["--problem", "circle_square", "--set", "E1=2", "--set", "E1=3"], "'E1' is given twice"),
    (["--problem", "circle_square", "--set", "beta=1"], "has no parameter 'beta'"),
    # an unknown key names whose parameters were searched, and lists both
    (["--problem", "circle_square", "--solver", "osqp", "--set", "foo=1"],
     "problem 'circle_square' has no parameter 'foo', nor has solver 'osqp'; known parameters "
     "of problem 'circle_square': radius, gap,"),
    (["--problem", "circle_square", "--solver", "osqp", "--set", "foo=1"],
     "of solver 'osqp': tol_factor, scale, polish, adaptive_rho, rho"),
    (["--problem", "circle_square", "--set", "nu1=0.5"], "'nu1': 0.5 is out of range"),
    (["--problem", "circle_square", "--set", "E1=nan"], "'E1': nan is not finite"),
    (["--problem", "circle_square", "--set", "load=inf"], "'load': inf is not finite"),
    (["--problem", "circle_square", "--set", "search=c"], "'search': 'c' is not allowed; allowed: one of along_direction, closest_point"),
    (["--problem", "circle_square", "--set", "search=a"], "'search': 'a' was renamed to 'closest_point'"),
    (["--problem", "circle_square", "--tol", "-1"], "'tol': '-1' is not allowed"),
    (["--problem", "circle_square", "--tol", "nan"], "'tol': 'nan' is not allowed"),
    (["--problem", "circle_square", "--tol", "2"], "'tol': '2' is not allowed"),
    (["--problem", "circle_square", "--max-iter", "0"], "'max_iter': 0 is out of range"),
    (["--problem", "circle_square", "--max-iter", "many"], "'max_iter': cannot use 'many'"),
    (["--problem", "circle_square", "--time-limit", "-5"], "'time_limit': -5.0 is out of range"),
    (["--problem", "circle_square", "--solver", "osqp", "--set", "polish=maybe"], "'polish': cannot use 'maybe'"),
    (["--problem", "circle_square", "--solver", "augmented_projection", "--set", "ahat=amg"], "'ahat': 'amg' is not allowed"),
    (["--problem", "circle_square", "--solver", "augmented_projection", "--set", "ahat=gmg",
      "--set", "ahat.max_coarse=100"], "has no option 'ahat.max_coarse'"),
    (["--problem", "laplace_nonmatching", "--solver", "osqp"], "'--solver' does not apply to the linear problem"),
    (["--problem", "laplace_nonmatching", "--tol", "low"], "'--tol' does not apply to the linear problem"),
    (["--problem", "laplace_nonmatching", "--set", "ratio=0:3"], "'ratio': '0:3' is not allowed"),
    (["--problem", "laplace_nonmatching", "--cold"], "option '--cold' does not apply"),
    (["--problem", "circle_square", "--cold"],
     "option '--cold' is not allowed on a frictionless problem"),
]


@pytest.mark.parametrize("argv, needle", BAD_INPUTS)
def test_bad_input_is_a_clear_error_and_writes_nothing(tmp_path, capsys, argv, needle):
    out = tmp_path / "x.json"
    assert main(["solve", *argv, "--level", "0", "--out", str(out)] if "--level" not in argv
                else ["solve", *argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert needle in err, err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_output_paths_are_checked_before_any_work(tmp_path, capsys, monkeypatch):
    base = ["solve", "--problem", "circle_square", "--level", "0"]
    (tmp_path / "dir.json").mkdir()
    cases = [(["--out", str(tmp_path / "dir.json")], "is a directory"),
             (["--out", str(tmp_path / "missing" / "x.json")], "does not exist"),
             (["--out", str(tmp_path / "x.txt")], "ending in .json"),
             (["--out", str(tmp_path / "x.json"), "--vtu", str(tmp_path / "x.vt")], "ending in .vtu")]
    for extra, needle in cases:
        assert main([*base, *extra]) == 2
        assert needle in capsys.readouterr().err
    existing = tmp_path / "old.json"
    existing.write_text("precious")
    assert main([*base, "--out", str(existing)]) == 2
    assert "exists" in capsys.readouterr().err and existing.read_text() == "precious"
    assert main([*base, "--out", str(existing), "--force"]) == 0
    assert json.loads(existing.read_text())["status"] == "converged"
    ro = tmp_path / "ro"
    ro.mkdir()
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if Path(p) == ro else real_access(p, mode))
    assert main([*base, "--out", str(ro / "x.json")]) == 2
    assert "is not writable" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir.json", "old.json",
                                                          "old.json.meta.json", "ro"]


def test_an_option_for_a_solver_without_options_says_it_has_none():
    from solvers.base import SolverSpec
    from workflows.cli import split_sets

    bare = SolverSpec(name="bare", summary="x", solve=lambda *a: None)
    scene = problems()["circle_square"]
    assert split_sets({"E1": "2"}, scene, bare) == ({"E1": "2"}, {})
    assert split_sets({"rho": "2"}, scene, solvers()["osqp"]) == ({}, {"rho": "2"})
    with pytest.raises(ParameterError, match=r"nor has solver 'bare'; .* of solver 'bare': "
                                             r"none \(it takes no --set options\)"):
        split_sets({"rtol": "0.1"}, scene, bare)


def test_debug_is_accepted_anywhere_on_the_line(tmp_path, capsys):
    assert main(["list", "--debug"]) == 0
    assert main(["--debug", "list"]) == 0
    capsys.readouterr()
    # with --debug an error shows its traceback (raised here), wherever the flag stands
    for argv in (["--debug", "solve", "--problem", "nope", "--out", str(tmp_path / "x.json")],
                 ["solve", "--problem", "nope", "--debug", "--out", str(tmp_path / "x.json")]):
        with pytest.raises(ParameterError, match="unknown problem 'nope'"):
            main(argv)
    assert list(tmp_path.iterdir()) == []


def test_a_reader_that_stops_early_ends_the_listing_quietly(tmp_path):
    """``contactbench list | head``: the reader has gone before the listing is written."""
    reader, writer = os.pipe()
    os.close(reader)                                   # the reader left at once
    proc = subprocess.run([str(Path(sys.executable).parent / "contactbench"), "list"],
                          stdout=writer, stderr=subprocess.PIPE, text=True, timeout=300,
                          cwd=tmp_path)
    os.close(writer)
    assert (proc.returncode, proc.stderr) == (141, "")


def test_a_library_prints_nothing_of_its_own_through_the_cli(tmp_path):
    """HiGHS prints its banner at the first ``Highs()`` of a process, before options
    apply: the command's output is the suite's one line, nothing of the library's."""
    out = tmp_path / "run.json"
    cmd = [sys.executable, "-m", "workflows.cli", "solve", "--problem", "flat_blocks",
           "--level", "1", "--solver", "highs", "--out", str(out)]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=600, cwd=Path(__file__).resolve().parent.parent)
    assert run.returncode == 0, run.stderr
    (line,) = run.stdout.splitlines()
    data = json.loads(out.read_text())
    assert data["status"] != "skipped" and data["message"].startswith("highs: ")
    assert line.startswith(f"flat_blocks level 1: highs {data['status']}")
    assert f", energy_bound {data['energy_bound']:.1e}" in line and line.endswith(f" -> {out}")
    assert "HiGHS" not in run.stderr
