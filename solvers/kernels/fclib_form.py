"""fclib's form of a contact step (the Frictional Contact Library, INRIA RT-0444).

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

Where the contacts are few enough for a dense Delassus operator, the *local* problem
``u = W r + q`` too (:func:`local_problem`). Numerics only: the files are
:mod:`workflows.fclib`'s.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from solvers.kernels.cholesky import dense_schur, factorize


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
#: Largest Delassus operator formed (entries of the dense ``W``): 2e7 (160 MB).
LOCAL_MAX_ENTRIES = 20_000_000


@dataclass
class FclibLocal:
    """fclib's local problem ``u = W r + q`` (``W = H' M^-1 H`` the Delassus operator,
    ``q = w - H' M^-1 f``), per contact the law of :class:`FclibGlobal`."""

    spacedim: int
    W: np.ndarray
    q: np.ndarray
    mu: np.ndarray


def local_problem(problem: FclibGlobal, factor=None) -> FclibLocal:
    """The local (Delassus) form of ``problem``: ``v = M^-1 (H r - f)`` eliminated.

    ``W``'s columns are partial solves (:func:`solvers.kernels.cholesky.dense_schur`): a
    column of ``H`` is nonzero only on the contact rows, and ``H'`` reads ``M^-1 H`` only
    there, so only those components are computed, which skips most of the elimination
    tree. ``factor``: a factorisation of ``M`` whose ``components`` hold ``H``'s rows
    (:func:`local_factor`; kept by a caller that recovers ``v`` from ``r`` afterwards); by
    default it is made here.

    Raises
    ------
    FclibError
        Where the dense ``W`` would exceed :data:`LOCAL_MAX_ENTRIES` entries.
    """
    n, k = problem.H.shape
    if k * k > LOCAL_MAX_ENTRIES:
        raise FclibError(f"the Delassus operator: {k} x {k} entries exceed "
                         f"{LOCAL_MAX_ENTRIES} (a dense W is formed); the global form only")
    H = sp.csc_matrix(problem.H)
    if factor is None:
        factor = local_factor(problem)
    elif factor.components is None or np.setdiff1d(H.indices, factor.components).size:
        raise ValueError("parameter 'factor': its components must hold every row of H "
                         "(local_factor(problem))")
    W = dense_schur(factor, H.T)
    q = problem.w - problem.H.T @ factor.solve(problem.f)
    return FclibLocal(spacedim=problem.spacedim, W=W, q=np.asarray(q, dtype=float),
                      mu=problem.mu)


def local_factor(problem: FclibGlobal):
    """The factorisation of ``M`` :func:`local_problem` takes: partial solves on the rows
    of ``H`` (:func:`solvers.kernels.cholesky.factorize`).

    Raises
    ------
    solvers.kernels.cholesky.FactorizationError
        Where ``M`` is not positive definite.
    """
    return factorize(sp.csr_matrix(problem.M), components=sp.csc_matrix(problem.H).indices)


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
