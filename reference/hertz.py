"""Plane-strain Hertz contact of a cylinder on a flat body (analytic reference).

For a line load P (force per unit thickness) between a cylinder of radius R
and a flat elastic body (a half-plane), with the effective modulus
``1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2``::

    a^2 = 4 P R / (pi E*),      p0 = 2 P / (pi a),
    p(x) = p0 sqrt(1 - (x - x0)^2 / a^2)   for |x - x0| < a.

(K. L. Johnson, Contact Mechanics, 1985, Sect. 4.3.) The half-width depends
only on the local geometry and the total force, so it is the right yardstick
for a FE contact zone that is small against the bodies.
"""
from __future__ import annotations

import numpy as np


def effective_modulus(E1: float, nu1: float, E2: float, nu2: float) -> float:
    """Plane-strain effective modulus E* of two bodies."""
    return 1.0 / ((1 - nu1 ** 2) / E1 + (1 - nu2 ** 2) / E2)


def half_width(P: float, R: float, E_star: float) -> float:
    """Contact half-width a for line load P."""
    return float(np.sqrt(4 * P * R / (np.pi * E_star)))


def peak_pressure(P: float, a: float) -> float:
    """Maximum pressure p0 = 2P / (pi a)."""
    return float(2 * P / (np.pi * a))


def pressure(x: np.ndarray, P: float, R: float, E_star: float, x0: float = 0.0) -> np.ndarray:
    """The semi-elliptic Hertz pressure at positions ``x``."""
    a = half_width(P, R, E_star)
    s = 1 - ((np.asarray(x, dtype=float) - x0) / a) ** 2
    return peak_pressure(P, a) * np.sqrt(np.clip(s, 0, None))


def moment_estimate(x: np.ndarray, p: np.ndarray) -> tuple[float, float, float]:
    """Centre, half-width and peak pressure of nodal contact forces ``p`` at ``x``.

    For a semi-elliptic distribution the second moment about the centroid is a^2/4,
    so ``a^2 = 4 sum p (x - xbar)^2 / sum p``; then ``p0 = 2 P / (pi a)`` with
    ``P = sum p``. Robust against the cell-by-cell jumps of the last loaded node.
    """
    x = np.asarray(x, dtype=float)
    p = np.asarray(p, dtype=float)
    P = p.sum()
    if P <= 0:
        return float("nan"), 0.0, 0.0
    xbar = float((p * x).sum() / P)
    a = float(np.sqrt(4 * (p * (x - xbar) ** 2).sum() / P))
    return xbar, a, peak_pressure(P, a)


def fit_semi_ellipse(x: np.ndarray, pressure_values: np.ndarray, xbar: float) -> tuple[float, float]:
    """Least-squares fit of p^2 = p0^2 (1 - (x - xbar)^2 / a^2) over the loaded nodes.

    Returns ``(a, p0)``. ``p^2`` is linear in ``(x - xbar)^2``: p^2 = c0 + c1 s.
    """
    x = np.asarray(x, dtype=float)
    q = np.asarray(pressure_values, dtype=float)
    loaded = q > 0
    if loaded.sum() < 3:
        return float("nan"), float("nan")
    s = (x[loaded] - xbar) ** 2
    c1, c0 = np.polyfit(s, q[loaded] ** 2, 1)
    if c0 <= 0 or c1 >= 0:
        return float("nan"), float("nan")
    return float(np.sqrt(-c0 / c1)), float(np.sqrt(c0))
