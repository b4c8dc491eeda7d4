"""The worker of :mod:`solvers.siconos`: one local frictional-contact problem solved by
Siconos's numerics library, under an interpreter that has it (Debian's
``python3-siconos``, built against that interpreter's numpy); it imports nothing of the
suite, whose environment it does not share.

Standard input: one line of JSON (``method``, ``contacts``, ``tol``, ``max_iter``), then
the arrays as little-endian doubles, one after the other::

    W (3m x 3m, row by row), q (3m), mu (m), r0 (3m)

the local problem ``u = W r + q`` with Coulomb's law in De Saxce's form per contact
(Siconos's ``FrictionContactProblem`` of dimension 3). Methods:

``nsgs``
    Coulomb's law by nonsmooth Gauss-Seidel (``SICONOS_FRICTION_3D_NSGS``).
``nsn_ac``
    Coulomb's law by the nonsmooth Newton method on Alart and Curnier's function, with
    its line search (``SICONOS_FRICTION_3D_NSN_AC``).
``tresca``
    The Tresca problem of the cylinders of radius ``mu_i r0_i,N``: Siconos's Tresca fixed
    point (``SICONOS_FRICTION_3D_TFP``) held to one outer step, whose inner solve (nonsmooth
    Gauss-Seidel with the projection onto each cylinder) is the Tresca problem itself;
    its radii are taken from ``r0`` (the only way to give them from Python), its inner
    tolerance fixed (``SICONOS_FRICTION_3D_INTERNAL_ERROR_STRATEGY_GIVEN_VALUE``) to
    ``tol``. The outer step's own verdict (Coulomb's fixed point) does not apply.

Standard output: one line, ``contactbench-siconos`` and a JSON record (Siconos's
``info``, the iterations and Siconos's own error of the solve that decides, the solve's
wall time, the version, and ``r`` as base64 of little-endian doubles).
"""
import base64
import json
import sys
import time

import numpy as np

TAG = "contactbench-siconos"


def read_problem(stream):
    header = json.loads(stream.readline())
    m = int(header["contacts"])
    data = np.frombuffer(stream.read(), dtype="<f8")
    sizes = [(3 * m) ** 2, 3 * m, m, 3 * m]
    if data.size != sum(sizes):
        raise ValueError(f"expected {sum(sizes)} doubles for {m} contacts, got {data.size}")
    parts = np.split(data, np.cumsum(sizes)[:-1])
    return header, parts[0].reshape(3 * m, 3 * m).copy(), *(p.copy() for p in parts[1:])


def solve(header, W, q, mu, r0):
    import siconos.numerics as sn

    m, tol, max_iter = int(header["contacts"]), float(header["tol"]), int(header["max_iter"])
    method = header["method"]
    ids = {"nsgs": sn.SICONOS_FRICTION_3D_NSGS, "nsn_ac": sn.SICONOS_FRICTION_3D_NSN_AC,
           "tresca": sn.SICONOS_FRICTION_3D_TFP}
    problem = sn.FrictionContactProblem(3, m, W, q, mu)
    options = sn.SolverOptions(ids[method])
    decides = options
    if method == "tresca":
        options.iparam[sn.SICONOS_IPARAM_MAX_ITER] = 1
        options.dparam[sn.SICONOS_DPARAM_TOL] = tol
        options.iparam[sn.SICONOS_FRICTION_3D_IPARAM_INTERNAL_ERROR_STRATEGY] = \
            sn.SICONOS_FRICTION_3D_INTERNAL_ERROR_STRATEGY_GIVEN_VALUE
        decides = sn.solver_options_get_internal_solver(options, 0)
    decides.iparam[sn.SICONOS_IPARAM_MAX_ITER] = max_iter
    decides.dparam[sn.SICONOS_DPARAM_TOL] = tol
    r, u = r0.copy(), np.zeros(3 * m)
    t0 = time.perf_counter()
    info = sn.fc3d_driver(problem, r, u, options)
    wall = time.perf_counter() - t0
    try:
        from siconos import version as siconos_version
        version = str(siconos_version)
    except ImportError:
        version = ""
    return {"info": int(info), "solver": sn.solver_options_id_to_name(decides.solverId),
            "iterations": int(decides.iparam[sn.SICONOS_IPARAM_ITER_DONE]),
            "error": float(decides.dparam[sn.SICONOS_DPARAM_RESIDU]), "solve_time": wall,
            "version": version,
            "r": base64.b64encode(np.ascontiguousarray(r, dtype="<f8").tobytes()).decode()}


def main():
    header, W, q, mu, r0 = read_problem(sys.stdin.buffer)
    record = solve(header, W, q, mu, r0)
    sys.stdout.write(f"{TAG} {json.dumps(record)}\n")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
