"""fclib's HDF5 form of a contact step (the Frictional Contact Library, INRIA RT-0444).

fclib's *global* problem, per contact ``i`` of ``d = spacedim`` components (normal first)::

    M v + f = H r,      u = H' v + w,
    K_i = {r_i : |r_i,T| <= mu_i r_i,N},   u^_i = u_i + (mu_i |u_i,T|, 0),
    K_i  contains r_i  _|_  u^_i  in K_i*          (Coulomb's law in De Saxce's form)

The suite's step (:class:`problems.friction.data.Friction`: ``A u + B'p + T'lam = f``,
``B u <= g``, ``slip(u) = T u + offset - previous``, ``lam_i`` along ``slip_i`` at the
bound) maps onto it with ``v = u``, ``M = A``, ``f_fclib = -f`` and, per contact, the
columns ``H_i = [-B_i', -T_i']`` and ``w_i = [g_i, previous_i - offset_i]``: then
``u_i,N = g_i - B_i u`` is the gap, ``u_i,T = -slip_i(u)`` and ``r_i = (p_i, lam_i)``,
so that ``r_i,T = -mu p_i u_i,T / |u_i,T|`` is Coulomb's friction opposing the slip. A
frictionless step has ``mu = 0`` and zero tangential columns. fclib's law is Coulomb's:
a Coulomb step of the suite (the fixed point's final Tresca step, ``s = mu p``) is its
problem exactly; a Tresca step (``s_i`` fixed, not ``mu p_i``) and a stabilised problem
(a penalty block fclib has no place for) have no fclib form (:func:`fclib_form` says
why).

Matrices are stored as fclib's C library stores them (``nzmax, m, n, nz, p, i, x``;
``nz = -1``: compressed columns), the reference solution as ``/solution/{v, u, r}``, the
load path's previous step as ``/guesses/1``; where the contacts are few enough for a dense
Delassus operator, the *local* problem ``u = W r + q`` too (:func:`local_problem`).
:func:`read_global` reads any fclib global file with ``h5py`` alone (a file with the local
form only is refused, with the reason, as no stiffness matrix maps it to the suite's
problems); :func:`read_local` reads the local form.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp

#: What the file's ``/fclib_global/info/math_info`` says.
MATH_INFO = ("M v + f = H r, u = H'v + w; per contact (normal first) r in K = "
             "{|r_T| <= mu r_N}, u + (mu |u_T|, 0) in K* = {mu |x_T| <= x_N}, "
             "r . (u + (mu |u_T|, 0)) = 0 (De Saxce)")


class FclibError(ValueError):
    """A problem or file without an fclib global form here (the message says why)."""


@dataclass
class FclibGlobal:
    """fclib's global problem: ``M, H`` (CSC), ``f, w, mu``, ``spacedim``, and the
    optional ``solution`` and ``guesses`` (dicts of ``v, u, r``) and ``info`` strings."""

    spacedim: int
    M: sp.csc_matrix
    H: sp.csc_matrix
    f: np.ndarray
    w: np.ndarray
    mu: np.ndarray
    solution: dict | None = None
    guesses: tuple = ()
    info: dict | None = None

    @property
    def contacts(self) -> int:
        return self.H.shape[1] // self.spacedim


def fclib_form(qp) -> str:
    """Why ``qp`` has no fclib form (``""`` if it has one): a Tresca step whose bounds do
    not follow ``mu p``, or a stabilised problem."""
    if qp.C is not None:
        return ("a stabilised problem (Sect. 7.5): its penalty block C has no place in "
                "fclib's global form")
    fr = qp.friction
    if fr is not None and fr.facets:
        return "the faceted friction law: fclib's cone is the isotropic one"
    return ""


def global_problem(qp, coulomb: bool) -> FclibGlobal:
    """The fclib global form of ``qp`` (module docstring): a frictional step whose bounds
    are Coulomb's (``coulomb``: the fixed point's final step, ``s = mu p``), or a
    frictionless problem (``mu = 0``).

    Raises
    ------
    FclibError
        For a problem :func:`fclib_form` refuses, and a Tresca step (``coulomb`` False).
    """
    why = fclib_form(qp)
    if why:
        raise FclibError(why)
    fr, d, m = qp.friction, qp.dim, qp.m
    if fr is not None and not coulomb:
        raise FclibError("a Tresca step (slip bounds s_i given, not mu p_i): fclib's law is "
                         "Coulomb's")
    B = sp.csr_matrix(qp.B)
    if fr is not None:
        k = fr.components
        T = sp.csr_matrix(fr.T)
        w_t = (fr.previous - fr.offset).reshape(m, k)
        mus = np.full(m, float(fr.mu))
    else:
        k = d - 1
        T = sp.csr_matrix((m * k, qp.n))
        w_t = np.zeros((m, k))
        mus = np.zeros(m)
    # rows of H' per contact: the normal row, then its k tangential rows
    normal, tangential = contact_columns(m, k + 1)
    order = np.empty(m * (k + 1), dtype=np.int64)
    order[normal] = np.arange(m)
    order[tangential] = m + np.arange(m * k)
    H = sp.csc_matrix(sp.vstack([-B, -T], format="csr")[order].T)
    w = np.column_stack([qp.g, w_t]).ravel()
    return FclibGlobal(spacedim=d, M=sp.csc_matrix(qp.A), H=H, f=-np.asarray(qp.f, float),
                       w=w, mu=mus)


def contact_columns(contacts: int, d: int) -> tuple[np.ndarray, np.ndarray]:
    """The columns of ``H`` (entries of ``w``, ``r``) holding each contact's normal
    component, and its ``d - 1`` tangential ones (contact-major)."""
    normal = np.arange(contacts) * d
    return normal, (normal[:, None] + np.arange(1, d)).ravel()


def reactions(problem: FclibGlobal, p: np.ndarray, lam: np.ndarray | None) -> np.ndarray:
    """fclib's ``r`` (normal first per contact) of the suite's multipliers ``p, lam``."""
    m, d = problem.contacts, problem.spacedim
    r = np.zeros((m, d))
    r[:, 0] = p
    if lam is not None:
        r[:, 1:] = np.asarray(lam, dtype=float).reshape(m, d - 1)
    return r.ravel()


def solution_of(problem: FclibGlobal, v: np.ndarray, r: np.ndarray) -> dict:
    """``{v, u, r}`` with fclib's local velocities ``u = H'v + w``."""
    v = np.asarray(v, dtype=float)
    return {"v": v, "u": problem.H.T @ v + problem.w, "r": np.asarray(r, dtype=float)}


def project_cone(r: np.ndarray, mu: np.ndarray, d: int) -> np.ndarray:
    """Each contact's ``r_i`` projected onto the cone ``|r_T| <= mu r_N``."""
    r = np.asarray(r, dtype=float).reshape(-1, d)
    n, t = r[:, 0], r[:, 1:]
    size = np.linalg.norm(t, axis=1)
    out = r.copy()
    below = mu * size <= -n                    # in the polar cone: to the apex
    outside = ~below & (size > mu * n)
    alpha = (n + mu * size) / (1.0 + mu ** 2)
    out[below] = 0.0
    direction = np.divide(t, size[:, None], out=np.zeros_like(t), where=size[:, None] > 0)
    out[outside, 0] = alpha[outside]
    out[outside, 1:] = (mu * alpha)[outside, None] * direction[outside]
    return out.ravel()


def law_residual(u: np.ndarray, r: np.ndarray, mu: np.ndarray, d: int) -> float:
    """The relative natural-map residual of Coulomb's law in De Saxce's form at the local
    velocities ``u`` and reactions ``r``: ``|r - P_K(r - rho u^)| / |r|`` over all contacts
    (``rho = |r|_inf / |u|_inf`` makes it scale-free). Zero exactly where the law holds."""
    u = np.asarray(u, dtype=float).reshape(-1, d)
    hat = u.copy()
    hat[:, 0] += mu * np.linalg.norm(u[:, 1:], axis=1)
    r = np.asarray(r, dtype=float)
    scale_r = max(float(np.max(np.abs(r), initial=0.0)), 1e-300)
    rho = scale_r / max(float(np.max(np.abs(u), initial=0.0)), 1e-300)
    return float(np.linalg.norm(r - project_cone(r - rho * hat.ravel(), mu, d))
                 / max(float(np.linalg.norm(r)), 1e-300))


def natural_map_residual(problem: FclibGlobal, v: np.ndarray, r: np.ndarray) -> float:
    """:func:`law_residual` at ``u = H'v + w``, together with the equilibrium
    ``|M v + f - H r| / |f|``: the larger of the two. Zero exactly at a solution."""
    law = law_residual(problem.H.T @ v + problem.w, r, problem.mu, problem.spacedim)
    balance = np.linalg.norm(problem.M @ v + problem.f - problem.H @ r) / max(
        float(np.linalg.norm(problem.f)), 1e-300)
    return float(max(law, balance))


# ------------------------------------------------------------------- the local form
#: Largest Delassus operator written (entries of the dense ``W``, and of ``M^-1 H``
#: formed for it): 2e7 (160 MB) each.
LOCAL_MAX_ENTRIES = 20_000_000


@dataclass
class FclibLocal:
    """fclib's local problem ``u = W r + q`` (``W = H' M^-1 H`` the Delassus operator,
    ``q = w - H' M^-1 f``), per contact the law of :class:`FclibGlobal`."""

    spacedim: int
    W: np.ndarray
    q: np.ndarray
    mu: np.ndarray


def local_problem(problem: FclibGlobal) -> FclibLocal:
    """The local (Delassus) form of ``problem``: ``v = M^-1 (H r - f)`` eliminated.

    Raises
    ------
    FclibError
        Where the dense ``W`` or ``M^-1 H`` would exceed :data:`LOCAL_MAX_ENTRIES`.
    """
    from solvers.kernels.cholesky import factorize

    n, k = problem.H.shape
    if max(n, k) * k > LOCAL_MAX_ENTRIES:
        raise FclibError(f"the Delassus operator: {n} x {k} entries of M^-1 H exceed "
                         f"{LOCAL_MAX_ENTRIES} (a dense W is formed); the global form only")
    solve = factorize(sp.csr_matrix(problem.M)).solve
    MinvH = solve(problem.H.toarray())
    W = np.asarray(problem.H.T @ MinvH)
    W = 0.5 * (W + W.T)                        # symmetric to round-off
    q = problem.w - problem.H.T @ solve(problem.f)
    return FclibLocal(spacedim=problem.spacedim, W=W, q=np.asarray(q, dtype=float),
                      mu=problem.mu)


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


def contact_arrays(problem: FclibGlobal) -> dict:
    """The suite's arrays of an fclib global problem (the inverse of
    :func:`global_problem`): ``A, f, B, g`` and, per contact, ``T`` and the slip's
    reference ``previous - offset``, and ``mu``."""
    d = problem.spacedim
    Ht = sp.csr_matrix(problem.H.T)
    normal, tangential = contact_columns(problem.contacts, d)
    return {"A": sp.csr_matrix(problem.M), "f": -problem.f, "B": -Ht[normal],
            "g": problem.w[normal], "T": -Ht[tangential],
            "slip_reference": problem.w[tangential], "mu": problem.mu}
