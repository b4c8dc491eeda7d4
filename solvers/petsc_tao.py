"""PETSc/Tao under MPI: the box-transformed contact problem solved by Tao's bound-constrained
solvers, in a separate MPI job (the suite's path beyond one process).

After the change of variables of Krause and Wohlmuth (:mod:`solvers.kernels.contact_box`,
``u = T v``) a nodal contact problem is the bound-constrained QP::

    minimise 1/2 v'A~v - f~'v   subject to   v[pivot] <= upper,    A~ = T'AT, f~ = T'f,

which Tao's bound-constrained solvers take: BNLS (bounded Newton with a line search and
a Krylov solve on the free set; the default), GPCG (gradient projection and CG on the
face, Moré and Toraldo) and BNCG (bounded nonlinear CG, no linear solve). The Krylov
solves of BNLS and GPCG are preconditioned by GAMG, with the bodies' rigid-body modes
(``T^{-1} R``, orthonormal) as its near-null space, restricted to each reduced system's
free set, or by hypre's BoomerAMG; each reduced system gets a fresh multigrid setup (the
worker's ``FreshAMG``): BNLS and GPCG converge in a few steps with either
preconditioner, the near-null space on the reduced systems cutting their Krylov
iterations; BNCG, unpreconditioned, needs far more iterations (docs/guide/distributed.md).
Tao's interior point method BQPIP is not offered: it takes the missing bounds as finite
ones at PETSc's infinity and does not converge on the smallest scenes.

PETSc's Debian build (``python3-petsc4py``) is built against that Python's numpy, not
the suite's, so the solve runs as its own job: ``mpiexec -n RANKS python3
_petsc_tao_worker.py`` (:mod:`solvers._petsc_tao_worker`, imports nothing of the
suite). The problem is written in PETSc's binary format (:func:`problem_stream`) to a
temporary file, which PETSc's own ``MatLoad`` / ``VecLoad`` read on every rank (the
worker's ``--input``) and which is removed when the job ends, however it ends; the
answer ``v`` comes back on standard output. The job's standard input is closed, and
Open MPI's launcher is told to forward none (``--stdin none``): its forwarding of
standard input to rank 0 now and then crashes the launcher itself (a segmentation fault
in ``orte_iof_hnp_read_local_handler``), a failed row that says nothing of the solver.
``u = T v``, and the multipliers are the transformed problem's residual at the pivots at
their bounds (``p_i = max(r[pivot_i], 0) / beta_i``, :func:`at_bound`,
:meth:`~solvers.kernels.contact_box.BoxTransformation.multipliers`); the suite verifies
both like any solver's.

Where it runs: the interpreter with petsc4py is ``CONTACTBENCH_PETSC_PYTHON`` (default
``/usr/bin/python3``), the launcher ``CONTACTBENCH_MPIEXEC`` (default ``mpiexec`` on the
PATH), PETSc's directory ``PETSC_DIR`` (default: ``/usr/lib/petsc``, else the newest
real build under ``/usr/lib/petscdir``). Without them every run is ``skipped`` with the
install command. Tao's own stop is ``gatol``: the 2-norm of the projected gradient
``<= tol_factor * tol * max|f~|``, which bounds the scaled stationarity residual of the
transformed problem by ``tol_factor * tol``. A job past ``time_limit`` is stopped by Tao
(status ``time_limit``); one that does not answer within ``time_limit + grace`` seconds
is killed with its process group (``time_limit``); one that dies is ``failed`` with its
exit status and the end of its error output: a row either way.
"""
from __future__ import annotations

import base64
import functools
import glob
import os
import re
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from problems.qp import ContactQP
from problems.spec import Options, Parameter
from solvers.base import TOLERANCES, Role, SolveResult, SolverSpec
from solvers import system_python
from solvers.kernels.contact_box import box_transformation, check_structure
from solvers.system_python import JobOutcome, clean_environment, probe

#: PETSc's binary class ids (petscmat.h, petscvec.h)
MAT_FILE_CLASSID, VEC_FILE_CLASSID = 1211216, 1211214
#: Sizes and indices are 32-bit integers in the format of a PETSc built with them (Debian's;
#: a build with 64-bit indices reads 64-bit ones)
INT32_MAX = 2**31 - 1

#: The worker script, shipped beside this module (run by the interpreter with petsc4py).
WORKER = Path(__file__).with_name("_petsc_tao_worker.py")
#: The first word of the worker's answer line.
TAG = "contactbench-petsc-tao"

#: How to get PETSc and MPI on Debian (the skip reason names it).
INSTALL = ("apt-get install --no-install-recommends python3-petsc4py python3-mpi4py "
           "mpi-default-bin")

#: Tao's reasons -> the suite's claimed status (others: ``failed``). A stop on the step
#: length or the objective is not the gradient test: ``inaccurate``.
STATUS_OF_REASON = {"CONVERGED_GATOL": "converged", "CONVERGED_GRTOL": "converged",
                    "CONVERGED_GTTOL": "converged", "CONVERGED_STEPTOL": "inaccurate",
                    "CONVERGED_MINF": "inaccurate", "CONVERGED_USER": "inaccurate",
                    "DIVERGED_MAXITS": "max_iter", "DIVERGED_MAXFCN": "max_iter"}

#: Tao types whose iteration solves a linear system (and so takes the preconditioner).
KRYLOV_TYPES = ("gpcg", "bnls")


# ------------------------------------------------------------- PETSc's binary format
def petsc_mat_bytes(A: sp.spmatrix) -> bytes:
    """``A`` in PETSc's binary format (``MatView`` to a binary viewer): the class id,
    rows, columns, nonzeros, the row lengths, the column indices (big-endian int32) and
    the values (big-endian float64), row by row."""
    A = sp.csr_matrix(A)
    A.sort_indices()
    rows, cols = A.shape
    if max(rows, cols, A.nnz) > INT32_MAX:
        raise ValueError(f"a matrix of {rows} rows and {A.nnz} nonzeros does not fit PETSc's "
                         "binary format with 32-bit indices (Debian's PETSc build)")
    head = np.array([MAT_FILE_CLASSID, rows, cols, A.nnz], dtype=">i4")
    return b"".join([head.tobytes(), np.diff(A.indptr).astype(">i4").tobytes(),
                     A.indices.astype(">i4").tobytes(), A.data.astype(">f8").tobytes()])


def petsc_vec_bytes(x: np.ndarray) -> bytes:
    """``x`` in PETSc's binary format (``VecView``): class id, size, big-endian doubles."""
    x = np.asarray(x, dtype=float)
    return np.array([VEC_FILE_CLASSID, x.size], dtype=">i4").tobytes() + x.astype(">f8").tobytes()


def problem_stream(A: sp.spmatrix, f: np.ndarray, upper: np.ndarray, v0: np.ndarray,
                   modes: np.ndarray) -> bytes:
    """The worker's input: ``Mat A, Vec f, Vec upper, Vec v0, Vec mode_1 .. mode_r``."""
    return b"".join([petsc_mat_bytes(A), petsc_vec_bytes(f), petsc_vec_bytes(upper),
                     petsc_vec_bytes(v0), *(petsc_vec_bytes(c) for c in np.asarray(modes).T)])


@dataclass(frozen=True)
class BoundQP:
    """The box-transformed problem as the worker takes it (module docstring)."""

    A: sp.csr_matrix
    f: np.ndarray
    upper: np.ndarray
    modes: np.ndarray

    def gatol(self, tol: float) -> float:
        """Tao's absolute test on the projected gradient's 2-norm for the target ``tol``
        (its infinity norm, and so the scaled stationarity residual, then meets it)."""
        return tol * max(float(np.abs(self.f).max(initial=0.0)), 1e-300)


def bound_qp(qp: ContactQP, box) -> BoundQP:
    """``A~ = T'AT``, ``f~ = T'f``, the bounds (``inf`` off the pivots) and ``T^{-1} R``
    orthonormalised (GAMG's near-null space; none without the scene's rigid-body modes)."""
    upper = np.full(qp.n, np.inf)
    upper[box.pivot] = box.upper
    R = None if qp.multilevel is None else qp.multilevel.rigid_body_modes
    if R is None or np.size(R) == 0:
        modes = np.zeros((qp.n, 0))
    else:
        R = np.asarray(R, dtype=float)
        modes, _ = np.linalg.qr(np.column_stack([box.to_v(c) for c in R.T]))
    return BoundQP(box.operator(qp.A), box.load(qp.f), upper, modes)


# --------------------------------------------------------------------- the runtime
@dataclass(frozen=True)
class Runtime:
    """Where the MPI job runs: the interpreter with petsc4py, the launcher, PETSc's
    directory."""

    python: str
    mpiexec: str
    petsc_dir: str
    #: the launcher's own options before ``-n`` (Open MPI's: forward no standard input)
    launcher_options: tuple[str, ...] = ()

    def environment(self) -> dict:
        """The job's environment: PETSc's directory, OpenMPI allowed to run as root and to
        place more ranks than cores, its ranks not pinned to cores (OpenMPI pins rank 0 of
        every job to core 0: two jobs side by side would share one core), one thread per
        rank, and none of the suite's Python settings (the interpreter has its own numpy)."""
        env = clean_environment(
            PETSC_DIR=self.petsc_dir, OMPI_MCA_rmaps_base_oversubscribe="1",
            OMPI_MCA_hwloc_base_binding_policy="none")
        if os.geteuid() == 0:
            env.update({"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1"})
        return env

    def command(self, ranks: int, args: list[str]) -> list[str]:
        return [self.mpiexec, *self.launcher_options, "-n", str(ranks), self.python,
                str(WORKER), *args]


def _default_petsc_dir() -> str:
    if os.environ.get("PETSC_DIR"):
        return os.environ["PETSC_DIR"]
    if Path("/usr/lib/petsc").is_dir():
        return "/usr/lib/petsc"
    builds = sorted(glob.glob("/usr/lib/petscdir/petsc*/*-real"))
    return builds[-1] if builds else ""


def runtime() -> tuple[Runtime | None, str]:
    """``(Runtime, "")``, or ``(None, why)`` where PETSc or MPI is not found (probed once
    per setting: the interpreter must import petsc4py and mpi4py)."""
    return _probe(os.environ.get("CONTACTBENCH_PETSC_PYTHON", "/usr/bin/python3"),
                  os.environ.get("CONTACTBENCH_MPIEXEC", "mpiexec"), _default_petsc_dir())


@functools.lru_cache(maxsize=8)
def _probe(python: str, mpiexec: str, petsc_dir: str) -> tuple[Runtime | None, str]:
    hint = (f"install PETSc and MPI ({INSTALL} on Debian; docs/guide/distributed.md "
            f"elsewhere)")
    launcher = shutil.which(mpiexec)
    if launcher is None:
        return None, f"no MPI launcher {mpiexec!r} (CONTACTBENCH_MPIEXEC): {hint}"
    interpreter = shutil.which(python)
    if interpreter is None:
        return None, f"no interpreter {python!r} (CONTACTBENCH_PETSC_PYTHON): {hint}"
    why = probe(interpreter, "petsc4py, mpi4py", (("PETSC_DIR", petsc_dir),))
    if why:
        return None, f"{why} with PETSC_DIR={petsc_dir or '(unset)'}: {hint}"
    return Runtime(interpreter, launcher, petsc_dir, launcher_options(launcher)), ""


def launcher_options(launcher: str) -> tuple[str, ...]:
    """``("--stdin", "none")`` for Open MPI's launcher (its ``--version`` names Open MPI or
    its runtime, OpenRTE / PRRTE), none for another launcher (whose options differ)."""
    try:
        out = subprocess.run([launcher, "--version"], capture_output=True, text=True,
                             timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return ()
    said = out.stdout + out.stderr
    return ("--stdin", "none") if re.search(r"Open MPI|OpenRTE|PRRTE|open-mpi", said) else ()


def supports(qp: ContactQP) -> tuple[bool, str]:
    """Nodal constraints with one row per constrained node (the box transformation), and
    PETSc with MPI on this machine."""
    ok, reason = check_structure(qp)
    if not ok:
        return False, f"the constraints cannot be turned into bounds: {reason}"
    rt, why = runtime()
    return (rt is not None), why


# ----------------------------------------------------------------------- the job
def run_job(rt: Runtime, ranks: int, args: list[str], stream: bytes,
            hard_limit: float | None) -> JobOutcome:
    """Run the worker under ``mpiexec -n ranks`` on the problem ``stream``, written to a
    temporary file (the worker's ``--input``) that is removed when the job ends; the job's
    standard input is closed. Past ``hard_limit`` wall seconds the launcher's process group
    is killed."""
    with tempfile.TemporaryDirectory(prefix="contactbench-petsc-") as folder:
        problem = Path(folder, "problem.petsc")
        problem.write_bytes(stream)
        return system_python.run_job(rt.command(ranks, [*args, "--input", str(problem)]),
                                     rt.environment(), None, hard_limit, TAG,
                                     f"MPI job ({ranks} ranks)")


def at_bound(v_pivot: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """The pivots at their bounds (Tao's active-set methods project onto them exactly; a
    relative 1e-12 for the round-off of the transfer). Only these carry a multiplier: a
    free row's residual is stationarity error, and as a multiplier it would leave the
    complementarity residual ``|p (g - Bu)|`` at the size of the gap however small it is."""
    scale = max(float(np.abs(upper).max(initial=0.0)), 1e-300)
    return v_pivot >= upper - 1e-12 * scale


def solve(qp: ContactQP, tol: float, max_iter: int, time_limit: float | None,
          u0: np.ndarray | None, p0: np.ndarray | None, opts: Options) -> SolveResult:
    """Solve ``qp`` by Tao in an MPI job (module docstring). ``p0`` is not used."""
    t_start = time.perf_counter()
    rt, why = runtime()
    if rt is None:
        raise RuntimeError(why)
    box = box_transformation(qp)
    bqp = bound_qp(qp, box)
    v0 = np.zeros(qp.n) if u0 is None else box.to_v(np.asarray(u0, dtype=float))
    v0[box.pivot] = np.minimum(v0[box.pivot], box.upper)
    stream = problem_stream(bqp.A, bqp.f, bqp.upper, v0, bqp.modes)
    args = ["--tao", opts.tao, "--pc", opts.pc, "--gatol", repr(bqp.gatol(tol * opts.tol_factor)),
            "--max-iter", str(max_iter), "--modes", str(bqp.modes.shape[1]),
            "--time-limit", repr(float(time_limit or 0.0))]
    hard = None if time_limit is None else time_limit + opts.grace
    setup_time = time.perf_counter() - t_start
    job = run_job(rt, opts.ranks, args, stream, hard)
    stats = {"ranks": opts.ranks, "tao": opts.tao, "job_wall_time": job.wall}
    if job.record is None:
        return SolveResult(u=np.zeros(qp.n), p=np.zeros(qp.m), claimed_status=job.status,
                           message=job.message, setup_time=setup_time, solve_time=job.wall,
                           stats=stats)
    rec = job.record
    v = np.frombuffer(base64.b64decode(rec["v"]), dtype=">f8").astype(float)
    if v.shape != (qp.n,):
        raise RuntimeError(f"the MPI job answered {v.size} unknowns for {qp.n}")
    r = bqp.f - bqp.A @ v
    u, p = box.to_u(v), box.multipliers(r, at_bound(v[box.pivot], box.upper))
    status = STATUS_OF_REASON.get(rec["reason"], "failed")
    if rec["time_limit_hit"]:
        status = "time_limit"
    pc = rec["pc"] or "none"
    message = (f"Tao {opts.tao} ({pc}, {opts.ranks} rank{'s' if opts.ranks > 1 else ''}): "
               f"{rec['reason']} after {rec['iterations']} iterations, projected gradient "
               f"{rec['gnorm']:.3g}")
    if opts.tao not in KRYLOV_TYPES:
        message += f"; no linear solve, so no preconditioner ({opts.pc} unused)"
    stats.update({"ksp_iterations": rec["ksp_iterations"], "petsc_setup_time": rec["setup_time"],
                  "petsc_solve_time": rec["solve_time"], "petsc_version": rec["petsc"],
                  "n_modes": bqp.modes.shape[1], "pc_setups": rec["pc_setups"],
                  "pc_setups_with_modes": rec["pc_setups_with_modes"]})
    return SolveResult(u=u, p=p, claimed_status=status, message=message,
                       iterations=int(rec["iterations"]), setup_time=setup_time,
                       solve_time=job.wall, stats=stats)


SOLVER = SolverSpec(
    name="petsc_tao",
    summary="PETSc/Tao's bound-constrained solvers (BNLS, GPCG, BNCG) on the "
            "Krause-Wohlmuth box-transformed problem, in an MPI job (GAMG or BoomerAMG)",
    solve=solve,
    parameters=(
        Parameter("tao", "bnls", "Tao's bound-constrained solver: bnls (bounded Newton, "
                  "line search, a Krylov solve on the free set), gpcg (gradient projection "
                  "and CG on the face), bncg (bounded nonlinear CG, no linear solve)",
                  choices=("bnls", "gpcg", "bncg")),
        Parameter("pc", "gamg", "preconditioner of the linear solves: gamg (PETSc's "
                  "smoothed aggregation, the rigid-body modes as near-null space) or hypre "
                  "(BoomerAMG)", choices=("gamg", "hypre")),
        Parameter("ranks", 1, "MPI ranks of the job (mpiexec -n)", low=1, high=4096, kind=int),
        Parameter("tol_factor", 0.1, "Tao's gradient test at tol_factor * tol (the suite's "
                  "verification decides)", low=0.0, high=1.0, low_open=True),
        Parameter("grace", 30.0, "wall seconds the job gets beyond time_limit (start-up, "
                  "loading, the answer) before it is killed", low=0.0, low_open=True),
    ),
    presets={name: f"gatol = tol_factor * {tol:g} * max|f~| (tol_factor = 0.1)"
             for name, tol in TOLERANCES.items()},
    default_max_iter=2000,
    # not among the QP libraries of solvers/qp_libraries.py (one adapter, their
    # contract): a solver in a process of its own
    role=Role.OTHER,
    # handed over as it is (not in slack form), so that ``supports`` names the
    # stabilisation block as the reason to skip
    handles_C=True,
    supports=supports,
)
