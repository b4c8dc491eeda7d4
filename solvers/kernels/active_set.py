"""Active-set machinery shared by the active-set solvers (the exact PDAS and the inexact
semismooth Newton method): the PDAS update rule with round-off hysteresis, its damped
variant for cycling sets, the unit of the PDAS parameter ``c`` and the input checks.

The rule of Hintermüller, Ito and Kunisch (SIAM J. Optim. 13, 2003):
``I = {i : p_i + c (Bu - Cp - g)_i > 0}``.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from problems.qp import ContactQP


def check_positive_diagonal(A: sp.spmatrix) -> None:
    """Raise ValueError if ``A`` has a non-positive diagonal entry (not SPD)."""
    diag = A.diagonal()
    bad = np.flatnonzero(diag <= 0)
    if bad.size:
        raise ValueError(f"A has {bad.size} non-positive diagonal entries (first: "
                         f"{bad[:5].tolist()}); it is not positive definite")


def stiffness_scale(qp: ContactQP) -> float:
    """``mean(diag A) / mean(||B_i||^2)``: the unit of ``c`` (force per length)."""
    if qp.m == 0:
        return 1.0
    row_sq = np.asarray(qp.B.multiply(qp.B).sum(axis=1)).ravel()
    return float(np.mean(qp.A.diagonal()) / np.mean(row_sq))


def constraint_residual(qp: ContactQP, u: np.ndarray, p: np.ndarray,
                        Bu: np.ndarray | None = None) -> np.ndarray:
    """``Bu - Cp - g`` (positive where a constraint is violated); ``Bu`` given where the
    caller has it (``u`` is then not read)."""
    r = (qp.B @ u if Bu is None else Bu) - qp.g
    if qp.C is not None:
        r = r - qp.C @ p
    return r


def initial_active_set(qp: ContactQP, u0, p0, c_eff: float) -> np.ndarray:
    """Empty without a guess, else the PDAS rule ``p0 + c (B u0 - C p0 - g) > 0``."""
    if u0 is None and p0 is None:
        return np.zeros(qp.m, dtype=bool)
    u = np.zeros(qp.n) if u0 is None else np.asarray(u0, dtype=float)
    p = np.zeros(qp.m) if p0 is None else np.asarray(p0, dtype=float)
    return (p + c_eff * constraint_residual(qp, u, p)) > 0


def pdas_update(qp: ContactQP, active: np.ndarray, u: np.ndarray, p: np.ndarray,
                 flip_tol: float, Bu: np.ndarray | None = None) -> np.ndarray:
    """The PDAS rule after an exact step, with round-off hysteresis.

    Keeps ``i`` in the active set while ``p_i >= -flip_tol ||p||_inf`` and adds
    ``i`` when ``(Bu - Cp - g)_i > flip_tol max(||Bu||_inf, ||g||_inf)`` (``Bu`` given
    where the caller has it; ``u`` is then not read).
    """
    Bu = qp.B @ u if Bu is None else Bu
    r = constraint_residual(qp, u, p, Bu)
    p_scale = float(np.max(np.abs(p))) if p.size else 0.0
    d_scale = max(float(np.max(np.abs(Bu))), float(np.max(np.abs(qp.g)))) if p.size else 0.0
    keep = active & (p >= -flip_tol * p_scale)
    add = ~active & (r > flip_tol * d_scale)
    return keep | add


def damped_update(qp: ContactQP, active: np.ndarray, proposed: np.ndarray, u: np.ndarray,
                   p: np.ndarray, limit: int, Bu: np.ndarray | None = None) -> np.ndarray:
    """Apply only the ``limit`` largest of the proposed changes.

    Changes are ranked by relative size: ``-p_i / ||p||_inf`` for a constraint
    leaving the active set, ``(Bu - Cp - g)_i / max(||Bu||, ||g||)`` for one
    entering it (``Bu`` given where the caller has it; ``u`` is then not read).
    """
    changes = np.flatnonzero(proposed != active)
    if changes.size <= limit:
        return proposed
    Bu = qp.B @ u if Bu is None else Bu
    r = constraint_residual(qp, u, p, Bu)
    p_scale = max(float(np.max(np.abs(p))), 1e-300)
    d_scale = max(float(np.max(np.abs(Bu))), float(np.max(np.abs(qp.g))), 1e-300)
    score = np.where(active[changes], -p[changes] / p_scale, r[changes] / d_scale)
    chosen = changes[np.argsort(-score, kind="stable")[:limit]]
    new = active.copy()
    new[chosen] = proposed[chosen]
    return new
