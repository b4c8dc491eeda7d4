"""Hertz contact (analytic reference): a cylinder on a flat body (plane strain, "line")
and a sphere on a flat body ("point").

With the effective modulus ``1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2`` and the
radius ``R`` of the curved body (K. L. Johnson, Contact Mechanics, 1985,
Sects. 4.2-4.3):

* line contact, load ``P`` per unit thickness::

      a^2 = 4 P R / (pi E*),   p0 = 2 P / (pi a),   p(x) = p0 sqrt(1 - x^2/a^2);

* point contact, total load ``P``::

      a^3 = 3 P R / (4 E*),    p0 = 3 P / (2 pi a^2),   p(r) = p0 sqrt(1 - r^2/a^2);

* two parallel cylinders (radii ``R1``, ``R2``) under a line load ``q``: the line
  contact with the effective radius ``1/R = 1/R1 + 1/R2`` (Johnson, Sect. 4.2),
  :func:`two_cylinders`.

The contact size depends only on the local geometry and the total force, so it
is the yardstick for a FE contact zone that is small against the bodies.
Estimators of ``a`` and ``p0`` from nodal forces (:func:`moment_estimate`,
:func:`fit_ellipse`) are robust against the cell-by-cell jumps of a single
nodal value.
"""
from __future__ import annotations

import numpy as np

KINDS = ("line", "point")

#: ``a^2 = MOMENT[kind] * <r^2>``: second moment of the Hertz pressure about its centre
#: (line: <x^2> = a^2/4; point: <r^2> = 2 a^2/5).
MOMENT = {"line": 4.0, "point": 2.5}


def effective_modulus(E1: float, nu1: float, E2: float, nu2: float) -> float:
    """Effective modulus E* of two bodies (plane strain in 2D)."""
    return 1.0 / ((1 - nu1 ** 2) / E1 + (1 - nu2 ** 2) / E2)


def two_cylinders(q, R1: float, R2: float, E_star: float) -> tuple[np.ndarray, np.ndarray]:
    """Half-width ``b`` and peak pressure ``p0`` of two parallel cylinders under line load ``q``.

    Plane-strain Hertz line contact (Johnson 1985, Sect. 4.2) with
    the effective radius ``1/R = 1/R1 + 1/R2``::

        b = sqrt(4 q R / (pi E*)),    p0 = 2 q / (pi b) = sqrt(q E* / (pi R)).

    Parameters
    ----------
    q : float or array
        Load per unit length of the cylinders, ``q >= 0`` (finite).
    R1, R2 : float
        The cylinders' radii, ``> 0`` (convex bodies; a flat body is ``R2 = inf``).
    E_star : float
        Effective modulus, :func:`effective_modulus`, ``> 0``.

    Returns
    -------
    b, p0 : ndarray
        With the shape of ``q``; both are 0 where ``q == 0``.

    Raises
    ------
    ValueError
        Naming ``q``, ``R1``, ``R2`` or ``E_star`` if outside the allowed range.
    """
    for name, value, upper in (("R1", R1, "inf]"), ("R2", R2, "inf]"), ("E_star", E_star, "inf)")):
        if not (value > 0) or (upper == "inf)" and not np.isfinite(value)):
            raise ValueError(f"parameter '{name}': {value!r} is not allowed; "
                             f"allowed: a number in (0, {upper}")
    q = np.asarray(q, dtype=float)
    if not np.all(np.isfinite(q) & (q >= 0)):
        raise ValueError("parameter 'q': negative or non-finite line load is not allowed; "
                         "allowed: numbers in [0, inf)")
    R = 1.0 / (1.0 / R1 + 1.0 / R2)
    b = np.sqrt(4.0 * q * R / (np.pi * E_star))
    p0 = np.sqrt(q * E_star / (np.pi * R))
    return b, p0


def _check(kind: str) -> None:
    if kind not in KINDS:
        raise ValueError(f"parameter 'kind': {kind!r} is not allowed; allowed: line, point")


def contact_size(kind: str, P: float, R: float, E_star: float) -> float:
    """Half-width (line) or radius (point) ``a`` of the contact zone for load ``P``."""
    _check(kind)
    if kind == "line":
        return float(np.sqrt(4 * P * R / (np.pi * E_star)))
    return float(np.cbrt(3 * P * R / (4 * E_star)))


def peak_pressure(kind: str, P: float, a: float) -> float:
    """Maximum pressure ``p0`` for load ``P`` over a zone of size ``a``."""
    _check(kind)
    if kind == "line":
        return float(2 * P / (np.pi * a))
    return float(3 * P / (2 * np.pi * a ** 2))


def pressure(kind: str, r: np.ndarray, P: float, R: float, E_star: float) -> np.ndarray:
    """The Hertz pressure at distances ``r`` from the centre."""
    a = contact_size(kind, P, R, E_star)
    s = 1 - (np.asarray(r, dtype=float) / a) ** 2
    return peak_pressure(kind, P, a) * np.sqrt(np.clip(s, 0, None))


def moment_estimate(kind: str, x: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Centre, size and peak pressure of nodal contact forces ``p`` at positions ``x``.

    ``x`` is ``(m,)`` (positions along a line) or ``(m, k)`` (points in the contact
    plane). With ``P = sum p`` and ``<r^2> = sum p |x - xbar|^2 / P`` the Hertz
    distribution has ``a^2 = MOMENT[kind] <r^2>``; then ``p0`` by :func:`peak_pressure`.
    The whole force on one node (``a = 0``: no zone to measure) gives ``p0`` NaN.
    """
    _check(kind)
    x = np.asarray(x, dtype=float).reshape(len(p), -1)
    p = np.asarray(p, dtype=float)
    P = p.sum()
    if P <= 0:
        return np.full(x.shape[1], np.nan), float("nan"), 0.0
    xbar = (p[:, None] * x).sum(axis=0) / P
    r2 = np.sum((x - xbar) ** 2, axis=1)
    a = float(np.sqrt(MOMENT[kind] * (p * r2).sum() / P))
    return xbar, a, peak_pressure(kind, P, a) if a > 0 else float("nan")


def fit_ellipse(r: np.ndarray, pressure_values: np.ndarray) -> tuple[float, float]:
    """Least-squares fit of ``p^2 = p0^2 (1 - r^2/a^2)`` over the loaded nodes.

    ``p^2`` is linear in ``r^2``: ``p^2 = c0 + c1 r^2``. Returns ``(a, p0)``
    (NaN with fewer than three loaded nodes or a fit of the wrong shape).
    """
    r = np.asarray(r, dtype=float)
    q = np.asarray(pressure_values, dtype=float)
    loaded = q > 0
    if loaded.sum() < 3:
        return float("nan"), float("nan")
    c1, c0 = np.polyfit(r[loaded] ** 2, q[loaded] ** 2, 1)
    if c0 <= 0 or c1 >= 0:
        return float("nan"), float("nan")
    return float(np.sqrt(-c0 / c1)), float(np.sqrt(c0))
