"""The solver contract, checked: whatever a solver returns becomes an honest row.

A deliberately broken plug-in (wrong shapes, NaN, an unknown status, an exception, a
hang, a crash of its process) goes through ``contactbench solve``, the solver comparison
and the test set's runs: every case is a row whose ``failed_check`` says which rule broke,
the command exits as documented and nothing half-written stays behind. The verification
names the checks a claimed convergence failed, and never upgrades a solver's own claim.
"""
from __future__ import annotations

import json
import os
import signal
import time

import numpy as np
import pandas as pd
import pytest

import solvers.interface as interface
import workflows.isolation as isolation
from problems.circle_square import PROBLEM
from solvers.base import CONTRACT, SolveResult, contract_violation
from solvers.interface import SolverSpec
from workflows.io import PARTIAL

#: Hard wall-clock grace in these tests: the hang is killed after 1.25 * limit + 2 s.
GRACE = 2.0
LIMIT = 0.5


def _exact(qp):
    """The reference's ``(u, p)`` of ``qp`` (the exact PDAS)."""
    ref = interface.solve(qp, "pdas", tol=1e-10)
    assert ref.status == "converged"
    return ref.u, ref.p


def wrong_shape(qp, tol, max_iter, time_limit, u0, p0, opts):
    return SolveResult(u=np.zeros(qp.n - 1), p=np.zeros(qp.m), claimed_status="converged")


def nan_answer(qp, tol, max_iter, time_limit, u0, p0, opts):
    u = np.zeros(qp.n)
    u[3] = np.nan
    return SolveResult(u=u, p=np.zeros(qp.m), claimed_status="converged")


def unknown_status(qp, tol, max_iter, time_limit, u0, p0, opts):
    return SolveResult(u=np.zeros(qp.n), p=np.zeros(qp.m), claimed_status="optimal")


def raises(qp, tol, max_iter, time_limit, u0, p0, opts):
    return 1 / 0                 # a bug of the plug-in, not one of the solver failures


def hangs(qp, tol, max_iter, time_limit, u0, p0, opts):
    time.sleep(3600)             # ignores its time limit


def crashes(qp, tol, max_iter, time_limit, u0, p0, opts):
    import faulthandler
    faulthandler.disable()       # pytest's handler would dump the child's stacks
    os.kill(os.getpid(), signal.SIGSEGV)


#: ``{solver: (verified status, failed_check, words in the message)}``
BROKEN = {
    "broken_shape": (wrong_shape, "failed", "contract:u_shape", "u has shape"),
    "broken_nan": (nan_answer, "failed", "contract:u_finite", "non-finite entries"),
    "broken_status": (unknown_status, "failed", "contract:status", "'optimal'"),
    "broken_raise": (raises, "failed", "exception", "ZeroDivisionError"),
    "broken_hang": (hangs, "time_limit", "hard_time_limit", "killed after the hard"),
    "broken_crash": (crashes, "failed", "process", "SIGSEGV"),
}


@pytest.fixture
def broken_plugins(monkeypatch):
    """The broken solvers registered as plug-ins, the hard limit's grace shortened."""
    specs = {name: SolverSpec(name=name, summary="broken on purpose", solve=body)
             for name, (body, *_rest) in BROKEN.items()}
    monkeypatch.setattr(interface, "external_solvers", lambda: specs)
    monkeypatch.setattr(isolation, "GRACE_SECONDS", GRACE)
    return specs


def _no_partial(folder) -> None:
    assert not [p for p in os.listdir(folder) if PARTIAL in p]


# -- the contract's rules, one by one -------------------------------------------------------

def _answer(**change):
    fields = dict(u=np.zeros(4), p=np.zeros(2), claimed_status="converged")
    fields.update(change)
    return SolveResult(**fields)


@pytest.mark.parametrize("result, rule", [
    ({"u": [0.0] * 4}, "type"),
    (_answer(claimed_status="optimal"), "status"),
    (_answer(claimed_status=None), "status"),
    (_answer(message=None), "message"),
    (_answer(u=np.zeros(5)), "u_shape"),
    (_answer(u=np.zeros((4, 1))), "u_shape"),
    (_answer(u="abcd"), "u_shape"),
    (_answer(u=np.array([0, np.inf, 0, 0])), "u_finite"),
    (_answer(p=np.zeros(3)), "p_shape"),
    (_answer(p=np.array([np.nan, 0])), "p_finite"),
    (_answer(iterations=2.5), "iterations"),
    (_answer(iterations=-1), "iterations"),
    (_answer(solve_time=float("nan")), "times"),
    (_answer(setup_time=-1.0), "times"),
    (_answer(stats=[1, 2]), "records"),
])
def test_each_rule_of_the_contract_is_named(result, rule):
    assert rule in CONTRACT
    assert contract_violation(result, 4, 2)[0] == rule


def test_a_kept_contract_passes_and_a_skip_carries_no_answer():
    assert contract_violation(_answer(u=[0, 1, 2, 3], iterations=np.int64(3)), 4, 2) is None
    assert contract_violation(_answer(u=None, claimed_status="skipped"), 4, 2) is None


# -- through the interface (in process) ------------------------------------------------------

@pytest.fixture(scope="module")
def qp():
    return PROBLEM.make(0)


@pytest.mark.parametrize("name", ["broken_shape", "broken_nan", "broken_status", "broken_raise"])
def test_a_broken_answer_is_a_failed_row_naming_the_rule(qp, broken_plugins, name):
    _, status, check, words = BROKEN[name]
    res = interface.solve(qp, name, tol="mid")
    assert (res.status, res.failed_check) == (status, check)
    assert words in res.message and res.solver == name
    assert res.kkt is None and res.u.shape == (qp.n,)     # no answer to use downstream
    if name == "broken_raise":
        assert "Traceback" in res.traceback and "return 1 / 0" in res.traceback
    else:
        assert "the solver broke the contract" in res.message and not res.traceback


def test_a_solver_without_an_answer_that_says_so_is_failed_not_in_breach(qp, monkeypatch):
    def gave_up(qp, *a):
        return SolveResult(u=np.full(qp.n, np.nan), p=np.full(qp.m, np.nan),
                           claimed_status="max_iter", message="no iterate")
    monkeypatch.setattr(interface, "external_solvers",
                        lambda: {"gave_up": SolverSpec(name="gave_up", summary="x",
                                                       solve=gave_up)})
    res = interface.solve(qp, "gave_up")
    assert (res.status, res.failed_check, res.claimed_status) == ("failed", "no_answer",
                                                                  "max_iter")
    assert res.message.startswith("no iterate; no answer: u has")


def test_the_verification_names_the_failed_checks_and_never_upgrades(qp, monkeypatch):
    u, p = _exact(qp)
    answers = {"exact_but_modest": (u, p, "inaccurate"), "exact": (u, p, "converged"),
               "off": (u * (1 + 1e-3), p, "converged")}

    def make(name):
        def run(qp, *a):
            uu, pp, claim = answers[name]
            return SolveResult(u=uu.copy(), p=pp.copy(), claimed_status=claim)
        return SolverSpec(name=name, summary="x", solve=run)
    monkeypatch.setattr(interface, "external_solvers", lambda: {n: make(n) for n in answers})
    own = interface.solve(qp, "exact_but_modest", tol="mid")
    assert (own.status, own.failed_check) == ("inaccurate", "claimed")   # its own word stays
    assert own.kkt.max <= 1e-10 and own.gap.meets(1e-6)                 # though it is exact
    good = interface.solve(qp, "exact", tol="mid")
    assert (good.status, good.failed_check) == ("converged", "")
    off = interface.solve(qp, "off", tol="mid")
    assert off.status == "inaccurate"
    # u scaled by 1 + 1e-3: a relative energy error of 1e-3, which the certified bound sees
    assert "energy_bound" in off.failed_check.split(",")
    assert off.gap.relative_energy_bound >= 1e-3 * (1 - 1e-6)
    assert off.failed_check.split(",") == [c for c in (
        "kkt_stationarity", "kkt_primal", "kkt_dual", "kkt_complementarity", "energy_bound")
        if (getattr(off.kkt, c[4:]) > 1e-6 if c.startswith("kkt_")
            else not off.gap.meets(1e-6))]


# -- through the three commands --------------------------------------------------------------

def test_contactbench_solve_writes_a_row_for_every_broken_case(broken_plugins, tmp_path,
                                                               capsys):
    from workflows.cli import main

    for name, (_, status, check, words) in BROKEN.items():
        out = tmp_path / f"{name}.json"
        # --debug after the subcommand: accepted, and it prints the plug-in's traceback
        code = main(["solve", "--problem", "circle_square", "--level", "0", "--solver", name,
                     "--time-limit", str(LIMIT), "--out", str(out), "--debug"])
        captured = capsys.readouterr()
        assert code == 0, captured.err
        row = json.loads(out.read_text())
        assert (row["status"], row["failed_check"]) == (status, check), row["message"]
        assert words in row["message"] and row["kkt"] is None and row["contact"] is None
        assert f"{name} {status}" in captured.out
        if name == "broken_raise":
            assert "Traceback" in row["traceback"] and "Traceback" in captured.err
        else:
            assert row["traceback"] is None and "Traceback" not in captured.err
    _no_partial(tmp_path)
    assert sorted(os.listdir(tmp_path)) == sorted(
        f for name in BROKEN for f in (f"{name}.json", f"{name}.json.meta.json"))


def test_without_debug_the_traceback_is_kept_and_pointed_to(broken_plugins, tmp_path, capsys):
    from workflows.cli import main

    out = tmp_path / "r.json"
    assert main(["solve", "--problem", "circle_square", "--level", "0", "--solver",
                 "broken_raise", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err and "its traceback is in" in err and "--debug" in err
    assert "ZeroDivisionError" in json.loads(out.read_text())["traceback"]


def _check_rows(table: pd.DataFrame) -> None:
    for name, (_, status, check, words) in BROKEN.items():
        row = table[table.solver == name]
        assert len(row) == 1, name
        row = row.iloc[0]
        assert (row.status, row.failed_check) == (status, check), row.message
        assert words in row.message
    if "kkt_max" in table:
        assert table.loc[table.solver.isin(BROKEN), "kkt_max"].isna().all()


def test_the_solver_comparison_has_a_row_for_every_broken_case(broken_plugins, tmp_path,
                                                               capsys):
    from workflows.studies.solver_comparison.run import main

    out = tmp_path / "solvers.csv"
    main(["--problem", "circle_square", "--level", "0", "--solvers", *BROKEN, "osqp",
          "--presets", "mid", "--time-limit", str(LIMIT), "--out", str(out)])
    table = pd.read_csv(out)
    _check_rows(table)
    assert np.isnan(table.set_index("solver").loc[list(BROKEN), "energy_error"]).all()
    osqp = table[table.solver == "osqp"].iloc[0]
    assert osqp.status == "converged" and pd.isna(osqp.failed_check)
    # the plug-in's traceback goes to the run's log (the rule sends stderr there)
    assert "ZeroDivisionError" in capsys.readouterr().err
    _no_partial(tmp_path)


@pytest.fixture(scope="module")
def small_circle_square(tmp_path_factory):
    from workflows.cli import main

    out = tmp_path_factory.mktemp("export") / "small"
    assert main(["export", "--class", "small", "--families", "circle_square", "--out",
                 str(out), "--quiet"]) == 0
    return out


def test_the_test_set_runs_have_a_row_for_every_broken_case(broken_plugins, tmp_path,
                                                            small_circle_square, capsys):
    from workflows.studies.test_set.run import main
    from workflows.problem_set import CURRENT

    out = tmp_path / "runs.csv"
    main(["--set", CURRENT, "--class", "small", "--family", "circle_square", "--levels", "0",
          "--export", str(small_circle_square), "--solvers", *BROKEN, "--presets", "mid",
          "--time-limit", str(LIMIT), "--out", str(out)])
    table = pd.read_csv(out)
    _check_rows(table)
    assert "objective_error" not in table                 # no answer, no objective
    assert "ZeroDivisionError" in capsys.readouterr().err
    _no_partial(tmp_path)


def test_the_plug_in_authors_page_covers_every_rule_status_and_check():
    """The page (docs/guide/solver-contract.md) lists what the code declares."""
    from pathlib import Path

    from solvers.base import STATUSES, TOLERANCES
    from workflows.isolation import GRACE_FACTOR, GRACE_SECONDS

    page = (Path(__file__).resolve().parent.parent / "docs/guide/solver-contract.md").read_text()
    assert page.startswith("# ")
    for rule, text in CONTRACT.items():
        assert f"| `{rule}` |" in page, rule
    for status in STATUSES:
        assert f"`{status}`" in page, status
    for check in ("claimed", "no_answer", "exception", "process", "hard_time_limit",
                  "kkt_stationarity", "kkt_primal", "kkt_dual", "kkt_complementarity",
                  "energy_bound", "no_certificate", "contract:<rule>"):
        assert f"`{check}`" in page, check
    assert f"{GRACE_FACTOR:g} * time_limit + {GRACE_SECONDS:g} s" in page
    assert ", ".join(f"`{t:.0e}`".replace("e-0", "e-") for t in TOLERANCES.values()) in page
    assert "default_max_iter" in page and "`qp.n`" in page and "`qp.m`" in page
    assert '"inf"' in page and '"nan"' in page


@pytest.mark.parametrize("change", [dict(stats=[1]), dict(iterations="many", u=np.zeros(3)),
                                    dict(solve_time=float("inf")), dict(message=7)])
def test_a_row_of_a_broken_answer_keeps_only_what_keeps_the_contract(qp, monkeypatch,
                                                                       change):
    def broken(qp, *a):
        fields = dict(u=np.zeros(qp.n), p=np.zeros(qp.m), claimed_status="converged",
                      iterations=4, solve_time=0.5)
        fields.update(change)
        return SolveResult(**fields)
    monkeypatch.setattr(interface, "external_solvers",
                        lambda: {"b": SolverSpec(name="b", summary="x", solve=broken)})
    res = interface.solve(qp, "b")
    assert res.status == "failed" and res.failed_check.startswith("contract:")
    summary = res.summary()                       # the table row: plain, never a crash
    assert summary["solver"] == "b" and isinstance(summary["message"], str)
    assert summary["iterations"] == (4 if "iterations" not in change else 0)
    assert np.isfinite(summary["solve_time"]) and isinstance(res.stats, dict)
