"""Solver runs in a child process: a verified result comes back; a hung, raising or
crashing solver becomes a row with the reason, never a stuck or dead study."""
import os
import signal
import time

import numpy as np
import pytest

import solvers.interface as interface
import workflows.isolation as isolation
from problems.circle_square import PROBLEM
from solvers.interface import SolverSpec
from workflows.isolation import solve_isolated


@pytest.fixture(scope="module")
def qp():
    return PROBLEM.make(0)


def test_a_normal_run_comes_back_verified(qp):
    res = solve_isolated(qp, "osqp", "mid", time_limit=60)
    direct = interface.solve(qp, "osqp", tol="mid")
    assert res.status == direct.status == "converged"
    np.testing.assert_allclose(res.u, direct.u)
    assert res.kkt.max == pytest.approx(direct.kkt.max) and res.stats["peak_mem_mb"] >= 0


def _fake(monkeypatch, name, body):
    real = interface.solvers()
    spec = SolverSpec(name=name, summary="test double", solve=body)
    monkeypatch.setattr(interface, "solvers", lambda: {**real, name: spec})


def test_a_hung_solver_is_killed_at_the_hard_limit(qp, monkeypatch):
    _fake(monkeypatch, "hang", lambda *a: time.sleep(3600))
    monkeypatch.setattr(isolation, "GRACE_SECONDS", 1.0)
    res = solve_isolated(qp, "hang", "mid", time_limit=0.5)
    assert res.status == "time_limit" and "killed" in res.message


def test_a_crashing_solver_becomes_a_failed_row(qp, monkeypatch):
    def crash(*a):
        import faulthandler
        faulthandler.disable()          # pytest's handler would dump the child's stacks
        os.kill(os.getpid(), signal.SIGSEGV)
    _fake(monkeypatch, "crash", crash)
    res = solve_isolated(qp, "crash", "mid", time_limit=5)
    assert res.status == "failed" and "SIGSEGV" in res.message


def test_a_raising_solver_becomes_a_failed_row(qp, monkeypatch):
    def broken(*a):
        raise KeyError("bug in an adapter")
    _fake(monkeypatch, "broken", broken)
    res = solve_isolated(qp, "broken", "mid", time_limit=5)
    assert res.status == "failed" and "KeyError" in res.message
