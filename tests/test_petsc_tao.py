"""PETSc/Tao under MPI (solvers/petsc_tao.py): verified and agreeing with the exact
reference on the contact scenes, the same answer on 1 and 2 ranks, PETSc's own loader
reads the file the suite writes (removed when the job ends), Open MPI's launcher forwards
no standard input, and a job that hangs, dies or is stopped by its time limit is a row.
Where PETSc or MPI is missing, the runs are ``skipped`` with the install command (checked
everywhere) and the rest of this file skips with that reason."""
from __future__ import annotations

import base64
import functools
import tempfile
import time

import numpy as np
import psutil
import pytest

from problems.kkt import energy_error
from problems.spec import problems
from solvers import petsc_tao, system_python
from solvers.kernels.contact_box import box_transformation
from solvers.interface import solve
from solvers.reference import reference_solve

RUNTIME, WHY = petsc_tao.runtime()
needs_petsc = pytest.mark.skipif(RUNTIME is None, reason=f"PETSc/MPI not found: {WHY}")


@functools.lru_cache(maxsize=None)
def _scene(name: str, level: int):
    qp = problems()[name].make(level)
    return qp, reference_solve(qp, tol=1e-10)


def _no_mpi_job_left():
    """No launcher or rank of ours outlives its run."""
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        left = [p for p in psutil.Process().children(recursive=True)
                if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
        if not left:
            return
        time.sleep(0.2)
    raise AssertionError(f"MPI processes left: {[p.cmdline()[:3] for p in left]}")


def test_without_petsc_every_run_is_skipped_with_the_install_command(monkeypatch):
    monkeypatch.setenv("CONTACTBENCH_MPIEXEC", "/nonexistent/mpiexec")
    qp, _ = _scene("circle_square", 0)
    res = solve(qp, solver="petsc_tao", tol="mid")
    assert res.status == "skipped"
    assert "CONTACTBENCH_MPIEXEC" in res.message and petsc_tao.INSTALL in res.message


def test_problems_the_transformation_cannot_take_are_skipped_with_the_reason():
    qp = problems()["flat_blocks"].make(2, coupling="stabilised")
    res = solve(qp, solver="petsc_tao", tol="mid")
    assert res.status == "skipped"
    assert "cannot be turned into bounds" in res.message and "Sect. 7.5" in res.message


def test_the_stream_is_petscs_binary_format():
    """Independent of PETSc: the header words and sizes of PETSc's MatView/VecView."""
    A = np.array([[2.0, -1.0, 0.0], [-1.0, 2.0, 0.5], [0.0, 0.5, 3.0]])
    import scipy.sparse as sp

    data = petsc_tao.petsc_mat_bytes(sp.csr_matrix(A))
    words = np.frombuffer(data, dtype=">i4", count=4 + 3 + 7)
    assert list(words[:4]) == [1211216, 3, 3, 7]
    assert list(words[4:7]) == [2, 3, 2]                     # row lengths
    assert list(words[7:]) == [0, 1, 0, 1, 2, 1, 2]          # column indices
    np.testing.assert_array_equal(np.frombuffer(data, dtype=">f8", offset=4 * 14),
                                  [2.0, -1.0, -1.0, 2.0, 0.5, 0.5, 3.0])
    vec = petsc_tao.petsc_vec_bytes(np.array([1.5, -2.0]))
    assert list(np.frombuffer(vec, dtype=">i4", count=2)) == [1211214, 2]
    np.testing.assert_array_equal(np.frombuffer(vec, dtype=">f8", offset=8), [1.5, -2.0])


@needs_petsc
def test_the_job_reads_its_problem_from_a_file_removed_when_it_ends(tmp_path, monkeypatch):
    """The stream goes to the job as a file PETSc's own MatLoad/VecLoad read (the worker's
    ``--input``, the cluster path), and the file is gone when the job ends; the answer is
    the exact reference's."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    qp, ref = _scene("circle_square", 0)
    box = box_transformation(qp)
    bqp = petsc_tao.bound_qp(qp, box)
    stream = petsc_tao.problem_stream(bqp.A, bqp.f, bqp.upper, np.zeros(qp.n), bqp.modes)
    args = ["--tao", "bnls", "--pc", "gamg", "--gatol", repr(bqp.gatol(1e-9)),
            "--max-iter", "100", "--modes", str(bqp.modes.shape[1])]
    job = petsc_tao.run_job(RUNTIME, 1, args, stream, 300)
    assert job.record is not None, job.message
    assert job.record["reason"] == "CONVERGED_GATOL"
    v = np.frombuffer(base64.b64decode(job.record["v"]), dtype=">f8").astype(float)
    assert energy_error(qp, box.to_u(v), ref.u) <= 1e-8
    assert list(tmp_path.iterdir()) == []


def test_open_mpis_launcher_forwards_no_standard_input(tmp_path):
    """Open MPI's launcher (4.x names its runtime OpenRTE, 5.x itself) is started with
    ``--stdin none``: its forwarding of standard input to rank 0 can crash the launcher
    itself. Another launcher gets no option it may not know."""
    said = {"openrte": "mpiexec (OpenRTE) 4.1.4\nReport bugs to http://www.open-mpi.org/",
            "ompi5": "mpiexec (Open MPI) 5.0.3", "hydra": "HYDRA build details:\n    Version: 4.1"}
    options = {}
    for name, text in said.items():
        launcher = tmp_path / name
        launcher.write_text(f"#!/bin/sh\nprintf '%s\\n' '{text}'\n")
        launcher.chmod(0o755)
        options[name] = petsc_tao.launcher_options(str(launcher))
    assert options == {"openrte": ("--stdin", "none"), "ompi5": ("--stdin", "none"),
                       "hydra": ()}
    rt = petsc_tao.Runtime("python3", "mpiexec", "", ("--stdin", "none"))
    assert rt.command(2, ["--tao", "bnls"])[:4] == ["mpiexec", "--stdin", "none", "-n"]


def test_a_launchers_crash_report_says_where_it_stopped():
    """A crashed job's message keeps the signal and the frame it stopped in, not the crash
    report's closing line."""
    report = """[host:87043] *** Process received signal ***
[host:87043] Signal: Segmentation fault (11)
[host:87043] Signal code: Address not mapped (1)
[host:87043] Failing at address: 0x88
[host:87043] [ 0] /lib/x86_64-linux-gnu/libc.so.6(+0x3c050)[0x7f0]
[host:87043] [ 1] /usr/lib/mca_iof_hnp.so(orte_iof_hnp_read_local_handler+0x30e)[0x7f1]
[host:87043] [ 2] /usr/lib/libopen-pal.so.40(+0x7efcc)[0x7f2]
[host:87043] *** End of error message ***"""
    lines = system_python.error_lines(report)
    assert any("Segmentation fault (11)" in ln for ln in lines)
    assert any("orte_iof_hnp_read_local_handler" in ln for ln in lines)
    assert not any("End of error message" in ln or "Process received" in ln for ln in lines)
    python = "Traceback (most recent call last):\n  File x\nValueError: no such contact"
    assert system_python.error_lines(python) == ["ValueError: no such contact"]


CASES = [("circle_square", 1), ("circle_square", 2),
         pytest.param("circle_square", 3, marks=pytest.mark.slow),
         ("cube_sphere", 1), pytest.param("cube_sphere", 2, marks=pytest.mark.slow)]


@needs_petsc
@pytest.mark.parametrize("name,level", CASES)
def test_verified_and_agrees_with_the_exact_reference(name, level):
    qp, ref = _scene(name, level)
    res = solve(qp, solver="petsc_tao", tol="mid", time_limit=600)
    assert res.status == "converged", res.message
    assert res.kkt.max <= 1e-6 and res.gap.certified
    assert energy_error(qp, res.u, ref.u) <= 1e-6
    assert res.stats["ksp_iterations"] > 0 and res.iterations >= 1
    # every GAMG setup had the rigid-body modes, on the reduced systems too
    assert res.stats["pc_setups_with_modes"] == res.stats["pc_setups"] >= res.iterations


@needs_petsc
@pytest.mark.parametrize("name,tao", [("circle_square", "bnls"),
                                      pytest.param("cube_sphere", "gpcg", marks=pytest.mark.slow)])
def test_one_and_two_ranks_give_the_same_answer(name, tao):
    qp, ref = _scene(name, 1)
    one, two = (solve(qp, solver="petsc_tao", tol="mid", time_limit=600, tao=tao, ranks=r)
                for r in (1, 2))
    assert one.status == two.status == "converged", (one.message, two.message)
    assert "2 ranks" in two.message
    assert energy_error(qp, two.u, one.u) <= 1e-8
    assert np.abs(two.p - one.p).max() <= 1e-6 * np.abs(ref.p).max()


@needs_petsc
def test_a_hung_job_is_killed_and_becomes_a_row(tmp_path, monkeypatch):
    """No answer within time_limit + grace: the launcher's process group is killed, and
    the problem's file is gone."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    qp, _ = _scene("circle_square", 1)
    res = solve(qp, solver="petsc_tao", tol="mid", time_limit=0.01, grace=0.01)
    assert res.status == "time_limit" and "killed" in res.message
    assert res.kkt is not None                 # verified like any row: zeros, not a crash
    _no_mpi_job_left()
    assert list(tmp_path.iterdir()) == []


@needs_petsc
def test_a_job_past_its_time_limit_is_stopped_by_tao():
    qp, _ = _scene("circle_square", 2)
    res = solve(qp, solver="petsc_tao", tol="high", time_limit=0.05, grace=300)
    assert res.status == "time_limit" and "DIVERGED_USER" in res.message
    _no_mpi_job_left()


@needs_petsc
def test_a_killed_job_becomes_a_row(tmp_path, monkeypatch):
    """A rank that dies (here: the interpreter kills itself, as the OOM killer would)."""
    fake = tmp_path / "python3"
    fake.write_text(f'#!/bin/sh\ncase "$1" in -c) exec {RUNTIME.python} "$@";; esac\n'
                    'kill -KILL $$\n')
    fake.chmod(0o755)
    monkeypatch.setenv("CONTACTBENCH_PETSC_PYTHON", str(fake))
    qp, _ = _scene("circle_square", 0)
    res = solve(qp, solver="petsc_tao", tol="mid", time_limit=120)
    assert res.status == "failed" and "gave no answer" in res.message
    _no_mpi_job_left()


@needs_petsc
def test_no_contact_gives_zero_multipliers():
    """A gap that stays open: no pivot reaches its bound, so p = 0 exactly (a free row's
    tiny residual taken as a multiplier would fail the complementarity check)."""
    qp = problems()["circle_square"].make(1, gap=0.1, indent=0.02)
    res = solve(qp, solver="petsc_tao", tol="mid", time_limit=300)
    assert res.status == "converged", res.message
    assert not np.any(res.p)
