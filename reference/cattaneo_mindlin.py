"""Cattaneo-Mindlin partial slip (analytic reference) for elastically similar bodies.

After a normal load ``P`` (Hertz, :mod:`reference.hertz`) and then a tangential load
``Q < mu P``, the contact of half-width ``a`` sticks in a central zone of half-width ``c``
and slips outside it (K. L. Johnson, Contact Mechanics, 1985, Sect. 7.1, plane-strain
cylinder)::

    c / a = sqrt(1 - Q / (mu P)),
    q(x) = mu p0 (sqrt(1 - x^2/a^2) - (c/a) sqrt(1 - x^2/c^2))   for |x| < c,
    q(x) = mu p(x)                                                for c <= |x| <= a.

The theory needs elastically similar bodies (equal ``(1 - 2 nu)/G``): then the tangential
traction does not change the normal pressure. ``mu p - |q|`` is itself an ellipse of
half-width ``c`` (``mu p0 (c/a) sqrt(1 - x^2/c^2)``), so ``c`` is measured from nodal
forces like the Hertz ``a`` (:func:`reference.hertz.moment_estimate`): no node has to be
classified as sticking or slipping.

For the sphere (Johnson, Sect. 7.2; Mindlin 1949) the contact circle of radius ``a``
sticks inside the circle of radius ``c`` and::

    c / a = (1 - Q / (mu P))^(1/3),
    |q(r)| = mu p0 (sqrt(1 - r^2/a^2) - (c/a) sqrt(1 - r^2/c^2))   for r < c,

so ``mu p - |q|`` is a Hertz (point-contact) distribution of radius ``c``. The solution
takes the traction parallel to ``Q`` everywhere, which is exact only for ``nu = 0``;
Johnson estimates the effect of ``nu`` > 0 as small (Sect. 7.2), and the comparison's
bar allows for it.
"""
from __future__ import annotations

import numpy as np

from reference.hertz import moment_estimate

#: ``c / a = (1 - Q/(mu P))^POWER[kind]``: the cylinder (line contact) and the sphere.
POWER = {"line": 0.5, "point": 1.0 / 3.0}


def stick_zone_ratio(ratio: float, kind: str = "line") -> float:
    """``c / a`` for the load ratio ``ratio = Q/(mu P)``: ``sqrt(1 - Q/(mu P))`` for the
    plane-strain cylinder (``kind="line"``, Johnson Sect. 7.1), ``(1 - Q/(mu P))^(1/3)`` for
    the sphere (``kind="point"``, Johnson Sect. 7.2).

    Raises
    ------
    ValueError
        ``ratio`` outside ``[0, 1)``: at ``Q >= mu P`` the whole contact slips (gross
        sliding) and there is no static equilibrium.
    """
    if not 0.0 <= ratio < 1.0:
        raise ValueError(f"parameter 'ratio': Q/(mu P) = {ratio!r} is not allowed; allowed: "
                         "[0, 1) (at Q >= mu P the whole contact slips: gross sliding)")
    if kind not in POWER:
        raise ValueError(f"parameter 'kind': {kind!r} is not allowed; allowed: "
                         f"{', '.join(POWER)}")
    return float((1.0 - ratio) ** POWER[kind])


def tangential_traction(x: np.ndarray, a: float, c: float, mu_p0: float) -> np.ndarray:
    """Johnson's (7.8)-(7.9): the tangential traction ``q(x)`` of partial slip."""
    x = np.asarray(x, dtype=float)
    outer = mu_p0 * np.sqrt(np.clip(1 - (x / a) ** 2, 0, None))
    inner = mu_p0 * (c / a) * np.sqrt(np.clip(1 - (x / c) ** 2, 0, None)) if c > 0 else 0.0
    return outer - inner


def stick_zone_size(x: np.ndarray, normal_force: np.ndarray, tangential_force: np.ndarray,
                    slip_bound: np.ndarray, kind: str = "line") -> tuple[float, float]:
    """Contact size ``a`` and stick-zone size ``c`` of nodal forces (half-widths for
    ``kind="line"``, ``x`` ``(m,)``; radii for ``kind="point"``, ``x`` ``(m, 2)`` in the
    contact plane).

    ``a`` from the second moment of the normal forces, ``c`` from that of the deficit
    ``s - |lam|`` (the slip bound ``s = mu p`` less the size of the tangential force, one
    value per node), both Hertz distributions (module docstring;
    :func:`reference.hertz.moment_estimate`).
    """
    _, a, _ = moment_estimate(kind, x, np.asarray(normal_force, dtype=float))
    deficit = np.asarray(slip_bound, dtype=float) - np.abs(tangential_force)
    _, c, _ = moment_estimate(kind, x, np.clip(deficit, 0.0, None))
    return a, c
