"""The MPI worker of :mod:`solvers.petsc_tao`: one bound-constrained QP solved by PETSc/Tao.

Runs under an interpreter that has petsc4py and mpi4py (Debian's ``python3-petsc4py``,
built against that interpreter's numpy), started as ``mpiexec -n RANKS python3
_petsc_tao_worker.py ...``; it imports nothing of the suite, whose environment it does
not share. The problem, in PETSc's binary format (:func:`solvers.petsc_tao.problem_stream`),
is read from a file every rank can read (``--input``, loaded by PETSc's own parallel
``MatLoad`` / ``VecLoad``; the suite writes it to a temporary file, a cluster job
beforehand to a shared file system)::

    Mat A~ (n x n AIJ), Vec f~, Vec upper, Vec v0, Vec mode_1 ... Vec mode_r

and the QP is ``min 1/2 v'A~v - f~'v  s.t.  v <= upper`` (``upper`` beyond
``PETSC_INFINITY`` is no bound). The modes (orthonormal) are GAMG's near-null space.
Rank 0 prints one line to standard output: ``contactbench-petsc-tao `` and a JSON
record (Tao's reason, iterations, Krylov iterations, gradient norm, times, and the
solution ``v`` as base64 of big-endian doubles).
"""
import argparse
import base64
import json
import sys
import time

import numpy as np

#: the first word of the output line
TAG = "contactbench-petsc-tao"
#: Relative tolerance of GPCG's linear solves on the face.
GPCG_KSP_RTOL = 1e-10


def from_file(PETSc, comm, path, n_vectors):
    """PETSc's own parallel loader."""
    viewer = PETSc.Viewer().createBinary(path, "r", comm=comm)
    A = PETSc.Mat().create(comm=comm)
    A.setType("aij")
    A.load(viewer)
    vecs = []
    for _ in range(n_vectors):
        v = PETSc.Vec().create(comm=comm)
        v.load(viewer)
        vecs.append(v)
    return A, vecs


class FreshAMG:
    """A python PC that sets up a new algebraic multigrid preconditioner for each operator
    the Tao solver hands over: its reduced system on the free set changes size and
    pattern with the active set, and GAMG's own re-setup keeps the old coarse sizes.

    GAMG gets the rigid-body modes as its near-null space, restricted to the free set
    (without them it aggregates scalar unknowns, and the Krylov iterations of an
    elasticity solve grow tenfold): the reduced system keeps each rank's free rows, and
    the unknowns left out are the bounded ones nearest their bounds, as many on each rank
    as its rows shrank; the restriction is taken only where the reduced system's diagonal
    is the full one's on the rows kept, up to one shift (else no near-null space, which
    costs iterations, never the answer)."""

    def __init__(self, PETSc, kind, A, modes, solution, upper):
        self.PETSc, self.kind, self.A, self.modes = PETSc, kind, A, modes
        self.solution, self.upper = solution, upper
        self.inner, self.setups, self.with_modes = None, 0, 0

    def near_null_space(self, P):
        """The modes on the rows of ``P`` (module docstring), or None."""
        PETSc = self.PETSc
        if not self.modes:
            return None
        if P.getSize() == self.A.getSize():
            return PETSc.NullSpace().create(vectors=self.modes, comm=P.getComm())
        lo, hi = self.A.getOwnershipRange()
        upper = self.upper.getArray(readonly=True)
        bounded = upper < PETSc.INFINITY
        full = self.A.getDiagonal().getArray(readonly=True)
        reduced = P.getDiagonal().getArray(readonly=True)
        drop = hi - lo - reduced.size
        # BNLS adds a multiple of the identity where its Newton step fails: the kept
        # diagonal is the full one shifted, by what the first (unbounded) row says
        shift = float(reduced[0] - full[0]) if reduced.size and not bounded[0] else 0.0
        keep = None
        if 0 <= drop <= np.count_nonzero(bounded):
            slack = upper - self.solution.getArray(readonly=True)
            keep = np.ones(hi - lo, dtype=bool)
            nearest = np.flatnonzero(bounded)
            keep[nearest[np.argsort(slack[nearest], kind="stable")[:drop]]] = False
            if not _same(full[keep] + shift, reduced):
                keep = _aligned(full + shift, reduced, bounded)
        ok = keep is not None
        if not P.getComm().tompi4py().allreduce(ok, op=_mpi_min()):
            return None
        vectors = []
        for mode in self.modes:
            sub = P.createVecLeft()
            sub.setArray(mode.getArray(readonly=True)[keep])
            sub.normalize()
            vectors.append(sub)
        return PETSc.NullSpace().create(vectors=vectors, comm=P.getComm())

    def setUp(self, pc):
        PETSc = self.PETSc
        A, P = pc.getOperators()
        if self.inner is not None:
            self.inner.destroy()
        inner = PETSc.PC().create(comm=pc.getComm())
        if self.kind == "hypre":
            inner.setType("hypre")
            inner.setHYPREType("boomeramg")
        else:
            inner.setType("gamg")
            space = self.near_null_space(P)
            if space is not None:
                P.setNearNullSpace(space)
                self.with_modes += 1
        inner.setOperators(A, P)
        inner.setFromOptions()
        inner.setUp()
        self.inner = inner
        self.setups += 1

    def apply(self, pc, x, y):
        self.inner.apply(x, y)


def _aligned(full, reduced, bounded):
    """The rows kept: ``reduced`` is ``full`` with some bounded rows left out (every
    unbounded row kept, in order). Over the bounded rows in turn, the feasible counts of
    rows left out so far, each checked on the row and on the unbounded rows up to the
    next bounded one; then back from the total. None where no choice accounts for it."""
    rows = np.flatnonzero(bounded)
    drop = full.size - reduced.size

    def segment(start, end, d):          # unbounded rows start..end-1 at d rows left out
        return end <= start or (end - d <= reduced.size
                                and _same(full[start:end], reduced[start - d:end - d]))

    states = {0: None} if segment(0, rows[0] if rows.size else full.size, 0) else {}
    history = []
    for t, b in enumerate(rows):
        end = rows[t + 1] if t + 1 < rows.size else full.size
        new = {}
        for d in states:
            if b - d < reduced.size and _same(full[b], reduced[b - d]) and segment(b + 1, end, d):
                new.setdefault(d, (d, True))
            if d < drop and segment(b + 1, end, d + 1):
                new.setdefault(d + 1, (d, False))
        if not new:
            return None
        history.append(new)
        states = new
    if drop not in states:
        return None
    keep = np.ones(full.size, dtype=bool)
    d = drop
    for t in range(rows.size - 1, -1, -1):
        d, kept = history[t][d]
        keep[rows[t]] = kept
    return keep


def _same(a, b) -> bool:
    """Equal up to the round-off of a shift."""
    return bool(np.all(np.abs(np.asarray(a) - b) <= 1e-12 * np.maximum(np.abs(b), 1e-300)))


def _mpi_min():
    from mpi4py import MPI

    return MPI.MIN


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--tao", required=True)
    parser.add_argument("--pc", required=True)
    parser.add_argument("--gatol", type=float, required=True)
    parser.add_argument("--max-iter", type=int, required=True)
    parser.add_argument("--time-limit", type=float, default=0.0, help="0: none")
    parser.add_argument("--modes", type=int, default=0)
    parser.add_argument("--input", required=True, help="the problem: a PETSc binary file")
    args, petsc_args = parser.parse_known_args(argv)

    import petsc4py
    petsc4py.init([sys.argv[0], *petsc_args])
    from petsc4py import PETSc

    t_start = time.perf_counter()
    comm = PETSc.COMM_WORLD
    count = 3 + args.modes
    A, vecs = from_file(PETSc, comm, args.input, count)
    f, upper, x = vecs[0], vecs[1], vecs[2]
    modes = vecs[3:]
    A.setOption(PETSc.Mat.Option.SYMMETRIC, True)
    lower = f.duplicate()
    lower.set(-PETSc.INFINITY)
    with upper as arr:       # no bound beyond PETSc's infinity
        arr[~np.isfinite(arr) | (arr > PETSc.INFINITY)] = PETSc.INFINITY
    work = f.duplicate()

    def objective_gradient(tao, v, g):
        A.mult(v, g)
        energy = 0.5 * g.dot(v) - f.dot(v)
        g.axpy(-1.0, f)
        return energy

    def hessian(tao, v, H, P):
        pass                 # constant

    tao = PETSc.TAO().create(comm=comm)
    tao.setType(args.tao)
    tao.setObjectiveGradient(objective_gradient, work)
    tao.setHessian(hessian, A, A)
    tao.setVariableBounds(lower, upper)
    tao.setSolution(x)
    tao.setTolerances(gatol=args.gatol, grtol=0.0, gttol=0.0)
    tao.setMaximumIterations(args.max_iter)
    deadline = None if args.time_limit <= 0 else t_start + args.time_limit
    stopped = []

    def monitor(tao):
        if deadline is not None and time.perf_counter() > deadline:
            stopped.append(tao.getIterationNumber())
            tao.setConvergedReason(PETSc.TAO.Reason.DIVERGED_USER)

    tao.setMonitor(monitor)
    tao.setFromOptions()
    ksp = tao.getKSP()
    linear = ksp is not None and bool(ksp.handle)      # BNCG has no linear solve
    krylov = []                  # one entry per Krylov iteration of every linear solve
    amg = None
    if linear:
        ksp.setMonitor(lambda ksp, its, rnorm: krylov.append(1) if its > 0 else None)
        amg = FreshAMG(PETSc, args.pc, A, modes, x, upper)
        if args.tao == "gpcg":
            # GPCG's face solves at PETSc's default rtol (1e-5) stall its projected
            # gradient just above a tight gatol (docs/guide/distributed.md)
            ksp.setTolerances(rtol=GPCG_KSP_RTOL)
        ksp.getPC().setType("python")
        ksp.getPC().setPythonContext(amg)
    setup_time = time.perf_counter() - t_start
    t_solve = time.perf_counter()
    tao.solve()
    solve_time = time.perf_counter() - t_solve
    reasons = {getattr(PETSc.TAO.Reason, k): k for k in dir(PETSc.TAO.Reason)
               if not k.startswith("_") and k not in ("ITERATING", "CONVERGED_ITERATING")}
    reason = int(tao.getConvergedReason())
    f_value, gnorm, _ = tao.getSolutionNorm()
    scatter, full = PETSc.Scatter.toZero(tao.getSolution())
    scatter.scatter(tao.getSolution(), full, False, PETSc.Scatter.Mode.FORWARD)
    if comm.rank == 0:
        v = np.asarray(full.getArray(), dtype=">f8")
        record = {"tao": tao.getType(), "reason": reasons.get(reason, str(reason)),
                  "time_limit_hit": bool(stopped), "iterations": int(tao.getIterationNumber()),
                  "ksp_iterations": len(krylov), "pc": args.pc if linear else "",
                  "pc_setups": amg.setups if amg else 0,
                  "pc_setups_with_modes": amg.with_modes if amg else 0, "gnorm": float(gnorm),
                  "energy": float(f_value), "ranks": comm.size, "setup_time": setup_time,
                  "solve_time": solve_time, "petsc": ".".join(map(str, PETSc.Sys.getVersion())),
                  "v": base64.b64encode(v.tobytes()).decode("ascii")}
        sys.stdout.write(TAG + " " + json.dumps(record) + "\n")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
