"""Assembly speed of the P1 elasticity stiffness on a ~140k-node tetrahedral mesh.

Compares, on one structured unit-cube mesh (``skfem.MeshTet.init_tensor`` with
``n`` nodes per edge; ``n = 52`` gives 140,608 nodes, 795,906 tetrahedra,
421,824 DOFs):

(a) ``problems.fem.elasticity.stiffness_matrix`` (vectorised closed form),
(b) plain scikit-fem: ``Basis(ElementVector(ElementTetP1()))`` + ``asm(linear_elasticity)``,
(c) NGSolve's C++ assembly (``VectorH1`` order 1) including the export
    ``a.mat.CSR()`` -> ``scipy.sparse.csr_matrix``,
(d) for context: one pyamg smoothed-aggregation preconditioned CG solve of the
    body clamped on ``x = 0`` under a body force, to ``rtol`` 1e-8, with the
    rigid body modes as near-null space ``B`` (setup and solve timed apart).

Each case reports the median (and min) wall time of ``--repeat`` runs; (b) and
(c) are checked against (a) entry by entry (after mapping DOF orders).  Thread
counts are set *before* numpy is imported (``--threads``, default 1: the
machine is shared, and every case but NGSolve with a TaskManager is
single-threaded anyway).

Usage::

    python workflows/scripts/bench_assembly.py [--n 52] [--repeat 3] [--threads 1]
        [--skip skfem,ngsolve,amg] [--out results/bench/assembly.csv]
"""
from __future__ import annotations

import argparse
import os
import sys

CASES = ("ours", "skfem", "ngsolve", "amg")


def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=52,
                    help="nodes per cube edge (default 52 -> 140,608 nodes)")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs per case (median reported)")
    ap.add_argument("--threads", type=int, default=1,
                    help="OMP/OpenBLAS/MKL threads and NGSolve TaskManager threads (default 1)")
    ap.add_argument("--skip", default="", help=f"comma-separated cases to skip, from {','.join(CASES)}")
    ap.add_argument("--E", type=float, default=1.0, help="Young's modulus (default 1)")
    ap.add_argument("--nu", type=float, default=0.3, help="Poisson's ratio (default 0.3)")
    ap.add_argument("--out", default=None, help="write the table as CSV (atomically) to this path")
    args = ap.parse_args(argv)
    skip = {s.strip() for s in args.skip.split(",") if s.strip()}
    if skip - set(CASES):
        ap.error(f"argument --skip: unknown case(s) {sorted(skip - set(CASES))}; allowed: {', '.join(CASES)}")
    if args.n < 3:
        ap.error(f"argument --n: {args.n} is not allowed; allowed: an integer >= 3")
    if args.repeat < 1:
        ap.error(f"argument --repeat: {args.repeat} is not allowed; allowed: an integer >= 1")
    if args.threads < 1:
        ap.error(f"argument --threads: {args.threads} is not allowed; allowed: an integer >= 1")
    args.skip = skip
    return args


def set_threads(n: int) -> None:
    """Must run before numpy/scipy are imported."""
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
        os.environ[var] = str(n)


def main(argv=None) -> int:
    args = parse_args(argv)
    set_threads(args.threads)

    import gc
    import platform
    import statistics
    import time

    import numpy as np
    import scipy
    import scipy.sparse as sp

    sys.path.insert(0, os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..")))
    from problems.fem.elasticity import (body_force_vector, dirichlet_split, lame_parameters,
                                         rigid_body_modes, stiffness_matrix)

    def clock():
        """(wall, process CPU) seconds; CPU time is less sensitive to a busy shared machine."""
        return np.array([time.perf_counter(), time.process_time()])

    def timed(fn, repeat):
        times, out = [], None
        for _ in range(repeat):
            out = None
            gc.collect()
            t0 = clock()
            out = fn()
            times.append(clock() - t0)
        return times, out

    def rel_diff(A, B):
        return float(abs(A - B).max() / abs(A).max())

    from skfem import MeshTet
    ax = np.linspace(0.0, 1.0, args.n)
    skmesh = MeshTet.init_tensor(ax, ax, ax)
    pts, cells = skmesh.p.T.copy(), skmesh.t.T.copy()
    n_nodes, n_cells, d = len(pts), len(cells), 3
    lam, mu = lame_parameters(args.E, args.nu)
    versions = {"numpy": np.__version__, "scipy": scipy.__version__}
    rows = []

    def record(case, what, times, **extra):
        wall = [float(t[0]) for t in times]
        cpu = [float(t[1]) for t in times]
        rows.append({"case": case, "what": what, "seconds_median": statistics.median(wall),
                     "seconds_min": min(wall), "cpu_seconds_median": statistics.median(cpu),
                     "repeats": len(wall), "times": " ".join(f"{t:.3f}" for t in wall),
                     **extra})

    print(f"mesh: unit cube, {args.n}^3 = {n_nodes} nodes, {n_cells} tets, {n_nodes * d} dofs; "
          f"threads={args.threads}; {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cpus, load average {os.getloadavg()[0]:.2f}", flush=True)

    # (a) vectorised closed form -------------------------------------------------------
    times, K = timed(lambda: stiffness_matrix(pts, cells, args.E, args.nu), args.repeat)
    record("ours", "closed-form assembly -> csr", times, nnz=K.nnz, check="reference")

    # (b) plain scikit-fem ------------------------------------------------------------
    if "skfem" not in args.skip:
        import skfem
        from skfem import Basis, ElementTetP1, ElementVector, asm
        from skfem.models.elasticity import linear_elasticity
        versions["scikit-fem"] = skfem.__version__
        t_basis, t_asm, Ksk, basis = [], [], None, None
        for _ in range(args.repeat):
            Ksk = basis = None
            gc.collect()
            t0 = clock()
            basis = Basis(skmesh, ElementVector(ElementTetP1()))
            t1 = clock()
            Ksk = asm(linear_elasticity(lam, mu), basis).tocsr()
            t2 = clock()
            t_basis.append(t1 - t0)
            t_asm.append(t2 - t1)
        ours_to_sk = basis.nodal_dofs.T.ravel()
        diff = rel_diff(K, Ksk[ours_to_sk][:, ours_to_sk])
        del basis
        record("skfem", "Basis + asm(linear_elasticity)", [a + b for a, b in zip(t_basis, t_asm)],
               nnz=Ksk.nnz, check=f"max|K-K_skfem|/max|K|={diff:.1e}")
        record("skfem", "  of which asm only", t_asm, nnz=Ksk.nnz, check="")
        del Ksk

    # (c) NGSolve C++ assembly + export to scipy ----------------------------------------
    if "ngsolve" not in args.skip:
        import ngsolve as ng
        from netgen.meshing import Mesh as NGMesh
        versions["ngsolve"] = ng.__version__
        ng.SetNumThreads(args.threads)
        ngm = NGMesh(dim=3)
        ngm.AddPoints(pts)
        ngm.AddElements(dim=3, index=1, data=cells.astype(np.int32), base=0)
        ngm.SetMaterial(1, "body")
        mesh = ng.Mesh(ngm)
        fes = ng.VectorH1(mesh, order=1)
        u, v = fes.TnT()
        eps = lambda w: ng.Sym(ng.Grad(w))
        form = (2 * mu * ng.InnerProduct(eps(u), eps(v)) + lam * ng.div(u) * ng.div(v)) * ng.dx

        def ngsolve_assemble():
            a = ng.BilinearForm(fes)
            a += form
            if args.threads > 1:
                with ng.TaskManager():
                    a.Assemble()
            else:
                a.Assemble()
            vals, cols, indptr = a.mat.CSR()
            return sp.csr_matrix((np.array(vals), np.array(cols), np.array(indptr)),
                                 shape=(fes.ndof, fes.ndof))

        times, Kng = timed(ngsolve_assemble, args.repeat)
        ng_dof = np.array([fes.GetDofNrs(ng.NodeId(ng.VERTEX, k)) for k in range(mesh.nv)]).ravel()
        same_pts = np.array_equal(np.array([p.point for p in mesh.vertices]), pts)
        diff = rel_diff(K, Kng[ng_dof][:, ng_dof]) if same_pts else float("nan")
        record("ngsolve", "C++ assembly + CSR export", times, nnz=Kng.nnz,
               check=f"max|K-K_ng|/max|K|={diff:.1e}")
        del Kng, mesh, ngm, fes

    # (d) context: one AMG-PCG solve of the clamped body ---------------------------------
    if "amg" not in args.skip:
        import pyamg
        import scipy.sparse.linalg as spla
        versions["pyamg"] = pyamg.__version__
        clamped = np.flatnonzero(pts[:, 0] == 0.0)
        free, _ = dirichlet_split(n_nodes * d, (clamped[:, None] * d + np.arange(d)).ravel())
        Kff = K[free][:, free].tocsr()
        f = body_force_vector(pts, cells, [0.0, 0.0, -1.0])[free]
        B = rigid_body_modes(pts)[free]
        t_setup, t_solve, iters, resid = [], [], [], []
        for _ in range(args.repeat):
            gc.collect()
            count = [0]
            t0 = clock()
            ml = pyamg.smoothed_aggregation_solver(Kff, B=B)
            t1 = clock()
            x, info = spla.cg(Kff, f, rtol=1e-8, M=ml.aspreconditioner(cycle="V"), maxiter=1000,
                              callback=lambda xk: count.__setitem__(0, count[0] + 1))
            t2 = clock()
            t_setup.append(t1 - t0)
            t_solve.append(t2 - t1)
            iters.append(count[0])
            resid.append(float(np.linalg.norm(f - Kff @ x) / np.linalg.norm(f)))
            if info != 0:
                print(f"warning: CG info={info}", file=sys.stderr)
        note = (f"{iters[-1]} CG its, |f-Ku|/|f|={resid[-1]:.1e}, levels={len(ml.levels)}, "
                f"op.complexity={ml.operator_complexity():.2f}")
        record("amg", "pyamg SA setup (B = rigid body modes)", t_setup, nnz=Kff.nnz, check="")
        record("amg", "PCG solve, rtol 1e-8", t_solve, nnz=Kff.nnz, check=note)
        record("amg", "  setup + solve", [a + b for a, b in zip(t_setup, t_solve)], nnz=Kff.nnz,
               check="")

    # table ------------------------------------------------------------------------------
    ref = rows[0]["seconds_median"]
    print(f"\n{'case':8s} {'what':38s} {'median s':>9s} {'min s':>8s} {'cpu s':>7s} "
          f"{'x ours':>7s}  check")
    for r in rows:
        print(f"{r['case']:8s} {r['what']:38s} {r['seconds_median']:9.2f} {r['seconds_min']:8.2f} "
              f"{r['cpu_seconds_median']:7.2f} {r['seconds_median'] / ref:7.1f}  {r['check']}")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"load average (1 min) at the end: {load:.2f} on {os.cpu_count()} cpus")
    print("versions: " + ", ".join(f"{k} {v}" for k, v in versions.items()))

    if args.out:
        import csv
        import tempfile
        common = {"n_nodes": n_nodes, "n_cells": n_cells, "n_dofs": n_nodes * d,
                  "threads": args.threads, "E": args.E, "nu": args.nu,
                  "machine": platform.machine(), "cpus": os.cpu_count(), "load_1min": load,
                  "versions": "; ".join(f"{k}={v}" for k, v in versions.items())}
        fields = list(rows[0]) + list(common)
        out_dir = os.path.dirname(os.path.abspath(args.out))
        os.makedirs(out_dir, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=out_dir, prefix=".bench_assembly.", suffix=".csv.tmp")
        try:
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(tmp, 0o666 & ~umask)       # mkstemp creates 0600
            with os.fdopen(fd, "w", newline="") as fh:
                w = csv.DictWriter(fh, fieldnames=fields)
                w.writeheader()
                for r in rows:
                    w.writerow({**r, **common})
            os.replace(tmp, args.out)
        except BaseException:
            os.unlink(tmp)
            raise
        print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
