"""Solvers that run under another interpreter, as a process of their own (PETSc/Tao's MPI
job, Siconos): the job, its environment and its answer, shared by their adapters.

Debian builds its packages for the system Python (``python3-petsc4py``,
``python3-siconos``) against that Python's numpy, not the suite's, so such a solve runs
as a child process started from the suite: the problem goes to its standard input as
bytes (or, for a job that reads it from a file, standard input is closed), the answer
comes back on its standard output as one line, ``TAG`` and a JSON record. A job past its
hard limit is killed with its process group, one that dies is reported with its exit
status and the end of its error output: a row either way (:func:`run_job`).
"""
from __future__ import annotations

import functools
import json
import os
import re
import shutil
import signal
import subprocess
import time
from dataclasses import dataclass


def clean_environment(**extra: str) -> dict:
    """The child's environment: none of the suite's Python settings (the interpreter has
    its own numpy), one thread per process, the user's site packages off; ``extra`` on top."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    env.update({"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "PYTHONNOUSERSITE": "1",
                **extra})
    return env


@functools.lru_cache(maxsize=16)
def probe(python: str, imports: str, env_items: tuple = ()) -> str:
    """Why ``python`` cannot import ``imports`` (a comma-separated module list; ``""``
    if it can), probed once per setting."""
    if shutil.which(python) is None:
        return f"no interpreter {python!r}"
    try:
        out = subprocess.run([shutil.which(python), "-c", f"import {imports}"],
                             env=clean_environment(**dict(env_items)), capture_output=True,
                             text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired) as err:
        return f"{python} could not be run ({err})"
    if out.returncode != 0:
        last = (out.stderr.strip().splitlines() or ["no output"])[-1]
        return f"{python} cannot import {imports} ({last})"
    return ""


@dataclass
class JobOutcome:
    """What the job gave: its record (None if it gave none), or why not."""

    record: dict | None
    status: str = ""
    message: str = ""
    wall: float = 0.0


def die_with_parent() -> None:
    """The child gets SIGTERM when the process that started it dies (a study's isolation
    kills its child): no job outlives its run. Linux only."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)   # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


#: A line of a job's error output that says what went wrong: Python's exception, PETSc's
#: error stack (``[0]...``), a crash report's signal and the frame it stopped in (Open MPI's
#: ``[host:pid] Signal: Segmentation fault (11)``, ``[host:pid] [ 1] lib.so(function+0x30)``).
SAYS_WHAT_WENT_WRONG = re.compile(r"[Ee]rror|^\[0\]|Signal: |\[ ?1\] ")
#: A crash report's frame lines, which say nothing themselves.
REPORT_FRAME = re.compile(r"\*\*\* (End of error message|Process received signal) \*\*\*")


def error_lines(text: str, count: int = 4) -> list[str]:
    """The last ``count`` lines of a job's error output that say what went wrong
    (:data:`SAYS_WHAT_WENT_WRONG`), without a crash report's frame lines."""
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    said = [ln for ln in lines if SAYS_WHAT_WENT_WRONG.search(ln) and not REPORT_FRAME.search(ln)]
    return (said or lines)[-count:]


def run_job(command: list[str], env: dict, stream: bytes | None, hard_limit: float | None,
            tag: str, what: str) -> JobOutcome:
    """Run ``command`` with ``stream`` on its input (``None``: its input closed) and read
    its answer line (``tag``, a space, a JSON record); past ``hard_limit`` wall seconds its
    process group is killed. ``what`` names the job in the messages (e.g. ``"MPI job (2
    ranks)"``)."""
    t0 = time.perf_counter()
    stdin = subprocess.DEVNULL if stream is None else subprocess.PIPE
    proc = subprocess.Popen(command, stdin=stdin, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=env, start_new_session=True,
                            preexec_fn=die_with_parent)
    try:
        out, err = proc.communicate(stream, timeout=hard_limit)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        return JobOutcome(None, "time_limit", f"{what} killed: no answer within "
                          f"{hard_limit:.3g} s", time.perf_counter() - t0)
    wall = time.perf_counter() - t0
    text = out.decode("utf-8", "replace")
    line = next((ln for ln in text.splitlines() if ln.startswith(tag + " ")), None)
    if proc.returncode != 0 or line is None:
        how = (f"killed by signal {-proc.returncode}" if proc.returncode < 0
               else f"exit status {proc.returncode}")
        tail = " | ".join(error_lines(err.decode("utf-8", "replace")))
        return JobOutcome(None, "failed", f"{what} gave no answer ({how})"
                          + (f": {tail}" if tail else ""), wall)
    return JobOutcome(json.loads(line[len(tag) + 1:]), wall=wall)
