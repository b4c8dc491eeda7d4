"""What a multigrid solver needs, exported (``contactbench export --multigrid``): an outside
multigrid solver (pyamg's smoothed aggregation, and a geometric V-cycle built from the
exported prolongations alone) solves an exported frictionless problem from its files,
in fewer iterations with the exported near-null space or hierarchy than without."""
from __future__ import annotations

import json

import meshio
import numpy as np
import pyamg
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from workflows.cli import main
from workflows.export import load_problem

#: ``hard_no_contact``: the load never closes the gap, so the exported problem's solution
#: is the linear solve ``P x = -q`` (``p = 0`` exactly); level 1 has a two-level hierarchy.
FAMILY, LEVEL = "hard_no_contact", 1
RTOL = 1e-10


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("multigrid") / "set"
    assert main(["export", "--set", "contact-qp-5", "--class", "small", "--families", FAMILY,
                 "--multigrid", "--out", str(out), "--quiet"]) == 0
    return out / f"{FAMILY}_L{LEVEL}"


def cg_iterations(A, b, M=None) -> tuple[np.ndarray, int]:
    count = []
    x, info = spla.cg(A, b, rtol=RTOL, maxiter=5000, M=M, callback=lambda _: count.append(1))
    assert info == 0
    return x, len(count)


def test_the_files_describe_the_unknowns_and_the_hierarchy(folder):
    meta = json.loads((folder / "meta.json").read_text())
    data = np.load(folder / "multigrid.npz")
    n = meta["n_displacements"]
    assert data["coordinates"].shape == (n, meta["dim"]) and data["node"].size == n
    assert set(np.unique(data["component"])) == set(range(meta["dim"]))
    assert data["near_null_space"].shape == (n, 3 * len(np.unique(data["body"])))
    shapes = [tuple(data[f"P{k}_shape"]) for k in range(meta["multigrid"]["levels"] - 1)]
    assert shapes[-1][0] == n and all(a[0] == b[1] for a, b in zip(shapes, shapes[1:]))
    mesh = meshio.read(folder / "mesh.vtu")
    assert np.allclose(mesh.points[data["node"]][:, :meta["dim"]], data["coordinates"])
    # the rigid motions of the bodies: near A's kernel (the clamped edges alone resist
    # them), A's response to them far below its response to a generic vector
    A = load_problem(folder)["P"]
    B = data["near_null_space"]
    response = lambda X: np.linalg.norm(A @ X, axis=0) / np.linalg.norm(X, axis=0)
    generic = response(np.random.default_rng(0).standard_normal((A.shape[0], 4)))
    assert response(B).max() < 0.1 * generic.min()


def test_smoothed_aggregation_with_the_exported_near_null_space(folder):
    problem = load_problem(folder)
    A, b = sp.csr_matrix(problem["P"]), -problem["q"]
    x_ref = np.load(folder / "solution.npz")["x"]
    B = np.load(folder / "multigrid.npz")["near_null_space"]
    with_modes = pyamg.smoothed_aggregation_solver(A, B=B).aspreconditioner()
    without = pyamg.smoothed_aggregation_solver(A).aspreconditioner()
    x, its_modes = cg_iterations(A, b, with_modes)
    _, its_plain = cg_iterations(A, b, without)
    assert np.linalg.norm(x - x_ref) <= 1e-8 * np.linalg.norm(x_ref)
    assert its_modes < its_plain


def test_a_geometric_vcycle_from_the_exported_prolongations(folder):
    """A V(1,1)-cycle (symmetric Gauss-Seidel, Galerkin coarse operators, the coarsest
    level solved exactly), built from ``multigrid.npz`` and the problem's files alone."""
    problem = load_problem(folder)
    A, b = sp.csr_matrix(problem["P"]), -problem["q"]
    data = np.load(folder / "multigrid.npz")
    levels = json.loads((folder / "meta.json").read_text())["multigrid"]["levels"]
    Ps = [sp.csr_matrix((data[f"P{k}_data"].astype(float), data[f"P{k}_indices"],
                         data[f"P{k}_indptr"]), shape=tuple(data[f"P{k}_shape"]))
          for k in range(levels - 1)]
    ops = [A]
    for P in reversed(Ps):
        ops.append(sp.csr_matrix(P.T @ ops[-1] @ P))
    coarsest = spla.factorized(sp.csc_matrix(ops[-1]))

    def vcycle(r, lvl=0):
        r = np.asarray(r, dtype=float).ravel()
        if lvl == len(ops) - 1:
            return coarsest(r)
        Al, P = ops[lvl], Ps[-(lvl + 1)]
        x = np.zeros_like(r)
        pyamg.relaxation.relaxation.gauss_seidel(Al, x, r, iterations=1, sweep="forward")
        x += P @ vcycle(P.T @ (r - Al @ x), lvl + 1)
        pyamg.relaxation.relaxation.gauss_seidel(Al, x, r, iterations=1, sweep="backward")
        return x

    M = spla.LinearOperator(A.shape, matvec=vcycle)
    x, its_mg = cg_iterations(A, b, M)
    _, its_plain = cg_iterations(A, b)
    x_ref = np.load(folder / "solution.npz")["x"]
    assert np.linalg.norm(x - x_ref) <= 1e-8 * np.linalg.norm(x_ref)
    assert its_mg < its_plain / 5
