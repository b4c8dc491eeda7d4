"""Diagonal rescaling of a ContactQP, for the QP libraries (:mod:`solvers.qp_libraries`).

The general QP solvers (OSQP, ProxSuite, Clarabel) test their own stopping
criteria with absolute tolerances, so the same preset means different things
in dimensionless and in SI units. With ``scale=True`` an adapter hands the
solver the rescaled problem (all quantities dimensionless and O(1))::

    u = sigma D u~,   p = sigma R p~,
    A~ = D A D,   f~ = D f / sigma,   B~ = R B D,   g~ = R g / sigma,

with ``D = diag(A)^(-1/2)`` (symmetric Jacobi scaling), ``R`` making every row
of ``B D`` a unit vector and ``sigma = ||D f||_inf`` (the load scale; the gap
scale if there is no load). Then ``A~ u~ + B~^T p~ = f~`` holds exactly when
``A u + B^T p = f`` does, ``B~ u~ <= g~`` when ``B u <= g``, and ``p~ >= 0``
when ``p >= 0``: the unscaled pair solves the original problem. The verified
residuals (:func:`problems.kkt.kkt_residuals`) are always computed on the
original problem, so whatever the scaling does not repair still shows.

A Tresca step (``qp.friction``: ``sum_i s_i |T_i u - r_i|``, ``r = previous - offset``)
is rescaled the same way, with one factor ``rho_i`` per node for its ``k`` tangential
rows (one factor, so that the Euclidean norm of the node's slip only changes by it)::

    T~ = rho T D,   r~ = rho r / sigma,   s~ = s / (sigma rho),   lam = sigma rho lam~,

``rho_i = sqrt(k) / ||(T D)_i||_F`` (the node's rows of ``T D`` unit on average). Divided
by ``sigma^2``, the step's energy in ``u~`` is the step of ``(A~, f~, B~, g~, T~, r~,
s~)``, and ``|lam~_i| <= s~_i`` holds exactly when ``|lam_i| <= s_i`` does.

This module is private (leading underscore): the solver registry skips it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from problems.friction.forms import TrescaStep
from problems.spec import Parameter

#: Options every QP library of :mod:`solvers.qp_libraries` shares.
ADAPTER_PARAMETERS = (
    Parameter("tol_factor", 1.0, "library tolerances = tol * tol_factor", low=0.0,
              high=1.0, low_open=True),
    Parameter("scale", True, "rescale the problem (Jacobi A, unit rows of B, unit load) "
              "before handing it over"),
)


@dataclass
class ScaledQP:
    """The data handed to a solver and the factors that undo the scaling.

    Attributes
    ----------
    A, B : csc sparse
        Scaled stiffness and constraint matrices.
    f, g : arrays
        Scaled load and gaps.
    d : (n,) array
        Column scaling ``D`` (ones when scaling is off).
    r : (m,) array
        Row scaling ``R`` (ones when scaling is off).
    sigma : float
        Magnitude scaling (1 when scaling is off).
    T, slip_reference, slip_bound : optional
        A Tresca step's scaled ``T~``, ``r~`` and ``s~`` (module docstring); ``None``
        without friction.
    rho : (m_t,) array, optional
        The nodes' tangential scaling (ones when scaling is off).
    facets : int
        The friction law's facets (``0``: isotropic); one factor per node keeps the
        ``k``-gon's shape.
    """

    A: sp.csc_matrix
    f: np.ndarray
    B: sp.csc_matrix
    g: np.ndarray
    d: np.ndarray
    r: np.ndarray
    sigma: float
    T: sp.csr_matrix | None = None
    slip_reference: np.ndarray | None = None
    slip_bound: np.ndarray | None = None
    rho: np.ndarray | None = None
    facets: int = 0

    def step(self) -> TrescaStep:
        """The scaled problem (a Tresca step if it has friction) in plain arrays."""
        return TrescaStep(self.A, self.f, self.B, self.g, self.T, self.slip_reference,
                          self.slip_bound, self.facets)

    def unscale_tangential(self, lam_s: np.ndarray) -> np.ndarray:
        """The tangential multipliers ``lam = sigma rho lam~`` of the original step."""
        return (self.sigma * np.repeat(self.rho, self.step().components)
                * np.asarray(lam_s, dtype=float))

    def unscale(self, u_s: np.ndarray, p_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Map a solution of the scaled problem back: ``(u, p)`` of the original."""
        u = self.sigma * self.d * np.asarray(u_s, dtype=float)
        p = self.sigma * self.r * np.asarray(p_s, dtype=float)
        return u, p

    def scale_guess(self, u0: np.ndarray | None,
                    p0: np.ndarray | None) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Map an initial guess of the original problem into scaled variables."""
        u_s = None if u0 is None else np.asarray(u0, dtype=float) / (self.sigma * self.d)
        p_s = None if p0 is None else np.asarray(p0, dtype=float) / (self.sigma * self.r)
        return u_s, p_s


def scale_qp(qp, enabled: bool = True) -> ScaledQP:
    """Rescale ``qp`` (see the module docstring) or pass it through unchanged.

    Parameters
    ----------
    qp : ContactQP
    enabled : bool
        ``False`` returns the original data with unit factors.

    Returns
    -------
    ScaledQP

    Raises
    ------
    ValueError
        If ``A`` has a non-positive diagonal entry (then it is not SPD).
    """
    n, m = qp.n, qp.m
    if not enabled:
        return _with_friction(ScaledQP(A=sp.csc_matrix(qp.A), f=qp.f.copy(),
                                       B=sp.csc_matrix(qp.B), g=qp.g.copy(), d=np.ones(n),
                                       r=np.ones(m), sigma=1.0), qp.friction)
    diag = qp.A.diagonal()
    if np.any(diag <= 0):
        bad = np.flatnonzero(diag <= 0)
        raise ValueError(f"A has {bad.size} non-positive diagonal entries (first: "
                         f"{bad[:5].tolist()}); it is not positive definite")
    d = 1.0 / np.sqrt(diag)
    Dm = sp.diags(d)
    BD = sp.csr_matrix(qp.B @ Dm)
    row_norm = np.sqrt(np.asarray(BD.multiply(BD).sum(axis=1)).ravel()) if m else np.ones(0)
    r = 1.0 / row_norm
    f_d = d * qp.f
    g_r = r * qp.g
    sigma = _magnitude(f_d, g_r)
    A_s = sp.csc_matrix(Dm @ qp.A @ Dm)
    A_s = sp.csc_matrix(0.5 * (A_s + A_s.T))  # symmetric to the last bit
    B_s = sp.csc_matrix(sp.diags(r) @ BD) if m else sp.csc_matrix((0, n))
    return _with_friction(ScaledQP(A=A_s, f=f_d / sigma, B=B_s, g=g_r / sigma, d=d, r=r,
                                   sigma=sigma), qp.friction, enabled=True)


def _with_friction(data: ScaledQP, fr, enabled: bool = False) -> ScaledQP:
    """``data`` with the Tresca step of the friction ``fr`` scaled alike (module
    docstring; ``rho = 1`` when scaling is off)."""
    if fr is None:
        return data
    mt, k = len(fr.slip_bound), fr.components
    TD = sp.csr_matrix(fr.T @ sp.diags(data.d))
    if enabled and mt:
        norms = np.asarray(TD.multiply(TD).sum(axis=1)).ravel().reshape(mt, k).sum(axis=1)
        rho = np.sqrt(k / np.where(norms > 0, norms, k))
    else:
        rho = np.ones(mt)
    rows_rho = np.repeat(rho, k)
    data.T = sp.csr_matrix(sp.diags(rows_rho) @ TD)
    data.slip_reference = rows_rho * (fr.previous - fr.offset) / data.sigma
    data.slip_bound = fr.slip_bound / (data.sigma * rho)
    data.rho = rho
    data.facets = fr.facets
    return data


def _magnitude(f_d: np.ndarray, g_r: np.ndarray) -> float:
    """Load scale ``||f||_inf``; else the gap scale; else 1."""
    for vec in (f_d, g_r):
        size = float(np.max(np.abs(vec))) if vec.size else 0.0
        if size > 0.0:
            return size
    return 1.0


def upper_triangle(mat: sp.spmatrix) -> sp.csc_matrix:
    """Upper triangle (with diagonal) in CSC form, as OSQP and Clarabel expect."""
    return sp.csc_matrix(sp.triu(mat, format="csc"))
