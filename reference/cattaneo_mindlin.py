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

Tresca's path fixes the slip bound ``s`` at ``mu`` times the normal step's nodal forces,
so the ``mu p`` of the theory is ``s``: the reference profile takes its contact centre,
``a`` and ``mu p0`` from ``s`` (:func:`partial_slip_reference`). Its stick zone is
centred at the centre of the deficit, not at the contact's: the theory's stick zone is
concentric because the normal load leaves no tangential traction between similar
half-planes. A finite scene's normal step, loaded with friction, leaves a small traction
odd in ``x``, which adds to the load's traction on one side and subtracts on the other,
and the stick zone moves towards the latter (a few per cent of ``a``, none when the
normal step is loaded without friction; docs/guide/friction.md). That offset is reported
beside the comparison (``stick_offset``), not hidden in it: ``c`` stays the analytic one.

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

from dataclasses import dataclass

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


def tangential_traction(x: np.ndarray, a: float, c: float, mu_p0: float,
                        x_stick: np.ndarray | None = None) -> np.ndarray:
    """Johnson's (7.8)-(7.9): the tangential traction ``q(x)`` of partial slip.

    ``x`` is the distance from the contact's centre (signed on the line, radial on the
    sphere); ``x_stick`` the distance from the stick zone's centre (default ``x``: the
    theory's concentric zones)."""
    x = np.asarray(x, dtype=float)
    x_stick = x if x_stick is None else np.asarray(x_stick, dtype=float)
    outer = mu_p0 * np.sqrt(np.clip(1 - (x / a) ** 2, 0, None))
    inner = (mu_p0 * (c / a) * np.sqrt(np.clip(1 - (x_stick / c) ** 2, 0, None))
             if c > 0 else 0.0)
    return outer - inner


@dataclass(frozen=True)
class PartialSlipReference:
    """Cattaneo-Mindlin's traction at the nodes of a Tresca step
    (:func:`partial_slip_reference`).

    Attributes
    ----------
    centre, stick_centre : (k,) arrays
        Centres of the contact (of the slip bound) and of the stick zone (of the
        deficit), in the contact plane's coordinates (``k`` = 1 on the line, 2 on the
        plane).
    a, c : float
        Contact size (measured) and stick-zone size (analytic: ``a`` times
        :func:`stick_zone_ratio`).
    mu_p0 : float
        ``mu`` times the peak pressure, of the slip bound.
    traction : (m,) array
        ``q`` at the nodes.
    """

    centre: np.ndarray
    stick_centre: np.ndarray
    a: float
    c: float
    mu_p0: float
    traction: np.ndarray

    @property
    def stick_offset(self) -> float:
        """Distance of the stick zone's centre from the contact's, over ``a``."""
        return float(np.linalg.norm(self.stick_centre - self.centre) / self.a)


def partial_slip_reference(x: np.ndarray, slip_bound: np.ndarray, tangential_force: np.ndarray,
                           ratio: float, kind: str = "line") -> PartialSlipReference:
    """Cattaneo-Mindlin's traction for a Tresca step at the nodes ``x`` (``(m,)`` on the
    line, ``(m, 2)`` in the plane of a point contact).

    The outer ellipse is the slip bound's: its centre, ``a`` and ``mu p0`` are the
    second-moment measures of the nodal slip bounds ``s`` (Tresca's ``mu p``;
    :func:`reference.hertz.moment_estimate`); the inner one has the analytic half-width
    ``c = a`` :func:`stick_zone_ratio` ``(ratio, kind)`` and is centred at the first
    moment of the deficit ``s - |lam|`` (module docstring: the stick zone's offset).
    """
    s = np.asarray(slip_bound, dtype=float)
    pts = np.asarray(x, dtype=float).reshape(len(s), -1)
    centre, a, mu_p0 = moment_estimate(kind, pts, s)
    deficit = np.clip(s - np.abs(np.asarray(tangential_force, dtype=float)), 0.0, None)
    stick_centre = moment_estimate(kind, pts, deficit)[0] if deficit.sum() > 0 else centre
    c = a * stick_zone_ratio(ratio, kind)
    dist = (lambda o: pts[:, 0] - o[0]) if kind == "line" else (
        lambda o: np.linalg.norm(pts - o, axis=1))
    q = tangential_traction(dist(centre), a, c, mu_p0, dist(stick_centre))
    return PartialSlipReference(centre, stick_centre, a, c, mu_p0, q)


def relative_l2(weight: np.ndarray, measured: np.ndarray, exact: np.ndarray) -> float:
    """``||measured - exact|| / ||exact||`` in the discrete L2 norm with the nodal
    quadrature weights ``weight`` (the lumped surface mass)."""
    w = np.asarray(weight, dtype=float)
    e = np.asarray(exact, dtype=float)
    d = np.asarray(measured, dtype=float) - e
    return float(np.sqrt(np.sum(w * d ** 2) / np.sum(w * e ** 2)))


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
