"""Solve an fclib file's local problem with Siconos, under the system Python: an
independent code (h5py and Siconos, nothing of the suite) reading the suite's export.

    /usr/bin/python3 tests/siconos_fclib.py FILE

reads ``/fclib_local`` (``W`` in fclib's compressed columns, ``q``, ``mu``, ``spacedim``),
runs Siconos's nonsmooth Gauss-Seidel (``fc3d`` / ``fc2d`` NSGS) to 1e-12 and prints one
JSON line: ``info`` (0: converged), ``iterations``, Siconos's own ``error`` and the
reactions ``r``.
"""
import json
import sys

import h5py
import numpy as np
import siconos.numerics as sn


def main(path):
    with h5py.File(path, "r") as h5:
        g = h5["fclib_local"]
        W = g["W"]
        m, n = int(W["m"][0]), int(W["n"][0])
        assert int(W["nz"][0]) == -1, "compressed columns expected"
        p, i, x = W["p"][()], W["i"][()], W["x"][()]
        W = np.zeros((m, n))
        for j in range(n):                     # column j: entries p[j] .. p[j + 1] - 1
            W[i[p[j]:p[j + 1]], j] = x[p[j]:p[j + 1]]
        q, mu = g["vectors"]["q"][()], g["vectors"]["mu"][()]
        dim = int(g["spacedim"][0])
    problem = sn.FrictionContactProblem(dim, m // dim, W, q, mu)
    r, u = np.zeros(m), np.zeros(m)
    solver, driver = ((sn.SICONOS_FRICTION_3D_NSGS, sn.fc3d_driver) if dim == 3 else
                      (sn.SICONOS_FRICTION_2D_NSGS, sn.fc2d_driver))
    options = sn.SolverOptions(solver)
    options.iparam[sn.SICONOS_IPARAM_MAX_ITER] = 100000
    options.dparam[sn.SICONOS_DPARAM_TOL] = 1e-12
    info = driver(problem, r, u, options)
    print(json.dumps({"info": int(info), "iterations": int(options.iparam[
        sn.SICONOS_IPARAM_ITER_DONE]), "error": float(options.dparam[sn.SICONOS_DPARAM_RESIDU]),
        "r": r.tolist()}))


if __name__ == "__main__":
    main(sys.argv[1])
