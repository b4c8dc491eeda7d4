"""fclib's HDF5 files (the Frictional Contact Library, INRIA RT-0444): the suite's contact
steps written in fclib's global and local forms, and fclib files of any writer read back.

The mapping between a contact step and fclib's problems, and the residual of Coulomb's
law in De Saxce's form, are numerics (:mod:`solvers.kernels.fclib_form`, whose names this
module re-exports); here are the files: matrices stored as fclib's C library stores them
(``nzmax, m, n, nz, p, i, x``; ``nz = -1``: compressed columns), the reference solution
as ``/solution/{v, u, r}``, the load path's previous step as ``/guesses/1``, the local
form under ``/fclib_local``. :func:`read_global` reads any fclib global file with
``h5py`` alone (a file with the local form only is refused, with the reason, as no
stiffness matrix maps it to the suite's problems); :func:`read_local` reads the local
form.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from solvers.kernels.fclib_form import (LOCAL_MAX_ENTRIES, FclibError, FclibGlobal,  # noqa: F401
                                        FclibLocal, contact_arrays, contact_columns,
                                        fclib_form, global_problem, law_residual,
                                        local_problem, natural_map_residual, project_cone,
                                        reactions, solution_of)

#: What the file's ``/fclib_global/info/math_info`` says.
MATH_INFO = ("M v + f = H r, u = H'v + w; per contact (normal first) r in K = "
             "{|r_T| <= mu r_N}, u + (mu |u_T|, 0) in K* = {mu |x_T| <= x_N}, "
             "r . (u + (mu |u_T|, 0)) = 0 (De Saxce)")


def write_local(path: str | os.PathLike, local: FclibLocal) -> None:
    """Add ``local`` to the fclib file at ``path`` as ``/fclib_local`` (``W`` stored as a
    compressed-column matrix, ``q`` and ``mu`` under ``vectors``)."""
    import h5py

    with h5py.File(path, "a") as h5:
        if "fclib_local" in h5:
            del h5["fclib_local"]
        g = h5.create_group("fclib_local")
        g.create_dataset("spacedim", data=np.array([local.spacedim], dtype=np.int32))
        _write_matrix(g.create_group("W"), sp.csc_matrix(local.W))
        vec = g.create_group("vectors")
        vec.create_dataset("q", data=local.q)
        vec.create_dataset("mu", data=np.asarray(local.mu, dtype=np.float64))


def read_local(path: str | os.PathLike) -> FclibLocal:
    """The local problem of an fclib file (the suite's or fclib's published ones, whose
    ``q`` some writers name ``a``).

    Raises
    ------
    FclibError
        For a file without ``/fclib_local``, or with the blocks ``V, R`` of a local problem
        with bilateral constraints (not a contact step of the suite's kind).
    """
    import h5py

    with h5py.File(path, "r") as h5:
        if "fclib_local" not in h5:
            raise FclibError(f"{path}: no /fclib_local (its global form: read_global)")
        g = h5["fclib_local"]
        if "R" in g or "V" in g:
            raise FclibError(f"{path}: a local problem with bilateral constraints (V, R): "
                             "the suite's contact steps have none")
        vec = g["vectors"]
        q = vec["q"] if "q" in vec else vec["a"]
        return FclibLocal(spacedim=int(np.asarray(g["spacedim"]).ravel()[0]),
                          W=_read_matrix(g["W"]).toarray(), q=np.asarray(q, dtype=float),
                          mu=np.asarray(vec["mu"], dtype=float))


# ------------------------------------------------------------------------------- files
def _write_matrix(group, A: sp.spmatrix) -> None:
    A = sp.csc_matrix(A)
    A.sort_indices()
    one = lambda value: np.array([value], dtype=np.int32)
    group.create_dataset("nzmax", data=one(A.nnz))
    group.create_dataset("m", data=one(A.shape[0]))
    group.create_dataset("n", data=one(A.shape[1]))
    group.create_dataset("nz", data=one(-1))              # compressed columns
    group.create_dataset("p", data=A.indptr.astype(np.int32))
    group.create_dataset("i", data=A.indices.astype(np.int32))
    group.create_dataset("x", data=A.data.astype(np.float64))


def _read_matrix(group) -> sp.csc_matrix:
    m, n, nz = (int(np.asarray(group[key]).ravel()[0]) for key in ("m", "n", "nz"))
    p, i, x = (np.asarray(group[key]) for key in ("p", "i", "x"))
    if nz >= 0:                                            # triplet: p the column indices
        return sp.csc_matrix(sp.coo_matrix((x[:nz], (i[:nz], p[:nz])), shape=(m, n)))
    if nz == -1:
        return sp.csc_matrix((x, i, p), shape=(m, n))
    if nz == -2:
        return sp.csc_matrix(sp.csr_matrix((x, i, p), shape=(m, n)))
    raise FclibError(f"{group.name}: nz = {nz} is not an fclib matrix type (allowed: >= 0 "
                     "triplet, -1 compressed columns, -2 compressed rows)")


def write_global(path: str | os.PathLike, problem: FclibGlobal) -> Path:
    """Write ``problem`` as an fclib global file at ``path`` (written beside it and
    renamed into place: complete or absent)."""
    import h5py

    path = Path(path)
    tmp = path.with_name(f".{path.name}.partial-{os.getpid()}")
    try:
        with h5py.File(tmp, "w") as h5:
            g = h5.create_group("fclib_global")
            g.create_dataset("spacedim", data=np.array([problem.spacedim], dtype=np.int32))
            _write_matrix(g.create_group("M"), problem.M)
            _write_matrix(g.create_group("H"), problem.H)
            vec = g.create_group("vectors")
            for key in ("f", "w", "mu"):
                vec.create_dataset(key, data=np.asarray(getattr(problem, key), np.float64))
            info = g.create_group("info")
            for key, text in {"math_info": MATH_INFO, **(problem.info or {})}.items():
                info.create_dataset(key, data=np.bytes_(text))
            if problem.solution is not None:
                _write_solution(h5.create_group("solution"), problem.solution)
            if problem.guesses:
                guesses = h5.create_group("guesses")
                guesses.create_dataset("number_of_guesses",
                                       data=np.array([len(problem.guesses)], dtype=np.int32))
                for j, guess in enumerate(problem.guesses, start=1):
                    _write_solution(guesses.create_group(str(j)), guess)
        tmp.rename(path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


def _write_solution(group, solution: dict) -> None:
    for key in ("v", "u", "r"):
        if solution.get(key) is not None:
            group.create_dataset(key, data=np.asarray(solution[key], dtype=np.float64))


def _read_solution(group) -> dict:
    return {key: np.asarray(group[key], dtype=float) for key in ("v", "u", "r", "l")
            if key in group}


def read_global(path: str | os.PathLike) -> FclibGlobal:
    """An fclib global file (the suite's or any other), read with ``h5py`` alone.

    Raises
    ------
    FclibError
        For a local (Delassus) problem, an equality block ``G`` (not a contact step of
        the suite's kind), or a file without either form.
    """
    import h5py

    with h5py.File(path, "r") as h5:
        if "fclib_global" not in h5:
            if "fclib_local" in h5:
                raise FclibError(f"{path}: an fclib local problem (u = W r + q, the Delassus "
                                 "operator W): it has no stiffness matrix and no "
                                 "displacements, which the suite's problems are built on")
            raise FclibError(f"{path}: neither /fclib_global nor /fclib_local")
        g = h5["fclib_global"]
        if "G" in g:
            raise FclibError(f"{path}: an equality block G (bilateral constraints): the "
                             "suite's contact steps have none")
        d = int(np.asarray(g["spacedim"]).ravel()[0])
        vec = g["vectors"]
        info = ({key: bytes(np.asarray(g["info"][key]).ravel()[0]
                            if np.asarray(g["info"][key]).shape else
                            np.asarray(g["info"][key]).item()).decode()
                 for key in g["info"]} if "info" in g else None)
        problem = FclibGlobal(
            spacedim=d, M=_read_matrix(g["M"]), H=_read_matrix(g["H"]),
            f=np.asarray(vec["f"], dtype=float), w=np.asarray(vec["w"], dtype=float),
            mu=np.asarray(vec["mu"], dtype=float),
            solution=_read_solution(h5["solution"]) if "solution" in h5 else None,
            guesses=tuple(_read_solution(h5["guesses"][str(j)]) for j in range(
                1, int(np.asarray(h5["guesses"]["number_of_guesses"]).ravel()[0]) + 1))
            if "guesses" in h5 else (),
            info=info)
    if problem.H.shape[1] % d or problem.mu.size != problem.H.shape[1] // d:
        raise FclibError(f"{path}: H has {problem.H.shape[1]} columns and mu "
                         f"{problem.mu.size} entries: not {d} columns per contact")
    return problem
