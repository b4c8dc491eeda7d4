"""Sag of a roll stack (thesis Sect. 9.3): an engineering reference by beam theory.

The upper half of a four-high mill, ``x`` along the rolls (0 at the mill centre),
``z`` up: a crowned work roll (WR) pressed upward by the strip over ``|x| <= L/2``
and, above it, a backup roll (BUR) held vertically at its bearings. The work roll
has no bearing force: it floats between the strip and the backup roll. Both rolls
carry their own weight. This module computes, independently of any FE model:

* the Hertz line contact of the two rolls at the local line load ``q(x)``
  (:func:`reference.hertz.two_cylinders`);
* the mutual approach of the roll axes by contact flattening,
  :class:`FlatteningLaw`;
* both rolls as Timoshenko beams of variable cross-section (barrels and necks),
  coupled along the common barrel length by the nonlinear flattening law, with the
  contact line load ``q(x) >= 0`` solved by Newton's method, :func:`solve`.

Units are any consistent set (SI defaults: m, N, Pa); nothing here depends on the
choice (the tests compare SI with mm/N/MPa).

Model and conventions
---------------------
* Vertical displacements ``w`` are positive up, measured from the unloaded, weightless
  stack whose rolls touch at ``x = 0`` (where both radii are largest).
* Initial gap between the roll surfaces at ``x``: ``g0(x) = c_w(x) + c_b(x)`` with the
  work roll's crown drop ``c_w(x) = (crown/2) (2x/B_w)^2`` on the radius (parabolic,
  ``crown`` on the diameter between barrel centre and barrel ends) and the backup
  roll's edge relief ``c_b`` (a **linear** drop of the radius by ``chamfer_depth`` over
  the last ``chamfer_length`` of its barrel).
* Contact: ``delta(x) = w_w(x) - w_b(x) - g0(x)`` is the approach of the two axes beyond
  touching; ``q = Q(delta)`` for ``delta > 0`` (the inverse of the flattening law), else 0.
  Contact is possible only over the backup barrel ``|x| <= B_b/2`` (its necks are far
  away); ``B_b <= B_w`` is required.
* Beams: two-node Timoshenko elements with the exact stiffness of a uniform segment
  (Przemieniecki, *Theory of Matrix Structural Analysis*, 1968, Ch. 5; the
  "interdependent interpolation" element of Friedman & Kosmatka, Comput. Struct. 47,
  1993, 473-481), section properties of solid circles (nominal barrel diameter; crown and relief
  change ``I`` by < 0.1 % and are neglected there), shear coefficient of a solid circle
  ``kappa = 6 (1 + nu) / (7 + 6 nu)`` (Cowper, J. Appl. Mech. 33, 1966). With element
  boundaries at every change of section and load, nodal values are exact for the
  piecewise-uniform loads used here (consistent load vectors equal the fixed-end forces).
* The backup roll is simply supported at its bearing centres; the work roll's bearing
  centres carry nothing (free ends); each roll's necks end at its bearing centres (the
  neck beyond them is not modelled).
* The contact springs are lumped at the nodes with trapezoidal weights, so the
  contact force is ``sum(weights * q)``, equal to ``F - W_w`` (work-roll weight) to the
  Newton tolerance.
* No symmetry is imposed: both rolls are modelled over their full length on a grid
  that is symmetric about ``x = 0``; ``q(x) = q(-x)`` is a result (checked in the tests).
* Strip: a uniform line load ``F/L`` upward on the work roll over ``|x| <= L/2``; the lower
  half of the mill is the mirror image of the upper half about the pass line, so the
  strip thickness varies as ``h(x) - h(0) = 2 (s(x) - s(0))`` with ``s`` the vertical
  displacement of the work roll's strip-side surface. Work-roll/strip flattening is not
  modelled: ``s = w_w + c_w`` (axis deflection minus the crown's radius change).

Left out: 3D end effects of the finite barrels (pressure peaks at the barrel ends), the
flattening by the strip, the strip's nonuniform pressure and its plastic response, the
flattening law's dependence on how each roll's section balances the contact load (the
beams carry it by shear; the law assumes a diametrically balanced disc), roll bending
forces, thermal crown and wear, friction and the horizontal offset of the rolls.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.special import lambertw

from reference.hertz import effective_modulus, two_cylinders

__all__ = [
    "FLATTENING_FORMS", "FlatteningLaw", "shear_coefficient_circle", "circle_section",
    "timoshenko_stiffness", "uniform_load_vector", "RollStack", "RollStackSolution", "solve",
]

#: Constant ``k`` per roll in ``delta_i = 2 q (1 - nu_i^2) / (pi E_i) [ln(2 D_i / b) + k]``.
#: ``johnson``: -1/2, the plane-strain disc compressed by two opposite Hertz contacts
#: (Johnson 1985, two-dimensional contact of cylinders; re-derived in :class:`FlatteningLaw`). ``foppl``: +1/3, the
#: constant 2/3 for the pair quoted in the roll-deflection literature after Foeppl (e.g.
#: Stone & Gray 1965, Shohet & Townsend 1968); its primary derivation was not checked here.
FLATTENING_FORMS = {"johnson": -0.5, "foppl": 1.0 / 3.0}

#: The thesis's roll-stack mesh, as Fig. 9.11's caption prints it (the one set of numbers
#: this module transcribes; the figure of our mesh names them beside ours).
THESIS_FIG_9_11 = {"nodes": 46611, "tetrahedra": 246338, "inequalities": 7089}


# --------------------------------------------------------------------------- checks
def _positive(name: str, value, allow_zero: bool = False) -> float:
    v = float(value)
    ok = np.isfinite(v) and (v >= 0 if allow_zero else v > 0)
    if not ok:
        rng = "[0, inf)" if allow_zero else "(0, inf)"
        raise ValueError(f"parameter '{name}': {value!r} is not allowed; allowed: a number in {rng}")
    return v


def _poisson(name: str, value) -> float:
    v = float(value)
    if not (np.isfinite(v) and -1.0 < v < 0.5):
        raise ValueError(f"parameter '{name}': {value!r} is not allowed; allowed: a number in (-1, 0.5)")
    return v


# --------------------------------------------------------------------------- flattening
@dataclass(frozen=True)
class FlatteningLaw:
    """Mutual approach of the axes of two parallel cylinders by contact flattening.

    For a line load ``q`` (force per unit length) between cylinders of diameters
    ``D1``, ``D2`` the approach of the two axes is::

        delta(q) = sum_i C_i q [ln(2 D_i / b) + k],   C_i = 2 (1 - nu_i^2) / (pi E_i),

    with the Hertz half-width ``b = sqrt(4 q R / (pi E*))``, ``1/R = 2/D1 + 2/D2``,
    ``1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2`` (:func:`reference.hertz.two_cylinders`).
    Each term is one roll's share: the approach of its axis to the contact line.

    ``form="johnson"`` (``k = -1/2``, default) is the approach of the centres of two
    cylinders in K. L. Johnson, *Contact Mechanics* (1985), Sect. 5.6 (two-dimensional
    contact of cylindrical bodies), ``delta = q (1-nu1^2)/(pi E1) (2 ln(4 R1/b) - 1) +
    (same for 2)``. The book could not be consulted here (section number as usually
    cited), so the formula was re-derived, and the tests repeat the derivation by
    quadrature (``tests/test_roll_stack_reference.py``): along the
    loaded diameter of a plane-strain disc of radius ``R`` compressed by two opposite
    Hertz contacts, (i) the Hertz field gives the compression from the surface to a depth
    ``h`` (``b << h << R``) as ``C q [ln(2h/b) - nu/(2(1-nu))]`` (integrating
    ``eps_z = ((1-nu^2) s_z - nu(1+nu) s_x)/E`` with the Hertz subsurface stresses,
    ``int s_z dz = -(2q/pi) ln(2h/b)``, ``int s_x dz = -q/pi``), and (ii) the point-load
    disc solution (two Flamant fields plus the uniform tension ``q/(pi R)``) gives the
    compression of the rest of the diameter as ``C q [2 ln(2R/h) - 1 + nu/(1-nu)]``.
    The diameter shortens by ``C q [2 ln(4R/b) - 1]``, half of it per contact: the
    ``nu/(1-nu)`` terms cancel and ``k = -1/2`` with ``4R = 2D``.

    ``form="foppl"`` (``k = +1/3``) is the formula usually quoted in the roll-deflection
    literature after Foeppl, ``delta = 2 q (1 - nu^2)/(pi E) [2/3 + ln(2 D1/b) +
    ln(2 D2/b)]`` (e.g. Stone & Gray, Iron Steel Eng. 1965; Shohet & Townsend, J. Iron
    Steel Inst. 1968). Its derivation (which "centre" and which balancing load) was not
    checked against a primary source here; it is offered for comparison only. Both forms
    share the ``q ln q`` dependence and differ by the linear term ``(5/6) C q``: Foeppl's
    is the softer foundation (by ~15 % at the scene's loads), so it gives a slightly more
    uniform ``q(x)``, a larger strip crown and a higher work roll.

    Both assume each roll's section is loaded by diametrically opposite contacts; in a
    roll stack the backup roll's section is balanced by beam shear instead, which the
    law does not see (a known limitation of all such 2D laws).

    Parameters
    ----------
    D1, D2 : float
        Diameters of the two cylinders, ``> 0``.
    E1, E2 : float
        Young's moduli, ``> 0``.
    nu1, nu2 : float
        Poisson's ratios, in ``(-1, 0.5)``.
    form : str
        ``"johnson"`` or ``"foppl"`` (:data:`FLATTENING_FORMS`).

    Notes
    -----
    ``delta(q) = q (A - (C/2) ln q)`` with ``C = C1 + C2`` and ``A = sum C_i (ln(2 D_i /
    beta) + k)``, ``b = beta sqrt(q)``; it increases with ``q`` while ``t = 2 delta/(C q)
    > 1``, i.e. up to :attr:`q_max` (where ``b`` is of the order of the diameters, far
    beyond the Hertz range). The inverse is closed-form with Lambert's W (branch -1):
    ``t e^{-t} = (2 delta / C) e^{-2A/C}``, ``q = 2 delta / (C t)``.
    """

    D1: float
    D2: float
    E1: float
    nu1: float
    E2: float
    nu2: float
    form: str = "johnson"

    def __post_init__(self):
        for name in ("D1", "D2", "E1", "E2"):
            _positive(name, getattr(self, name))
        for name in ("nu1", "nu2"):
            _poisson(name, getattr(self, name))
        if self.form not in FLATTENING_FORMS:
            raise ValueError(f"parameter 'form': {self.form!r} is not allowed; "
                             f"allowed: {', '.join(FLATTENING_FORMS)}")

    # coefficients -----------------------------------------------------------
    @property
    def k(self) -> float:
        """The constant per roll of the chosen form."""
        return FLATTENING_FORMS[self.form]

    @property
    def compliances(self) -> tuple[float, float]:
        """``C_i = 2 (1 - nu_i^2) / (pi E_i)``."""
        return (2 * (1 - self.nu1 ** 2) / (np.pi * self.E1),
                2 * (1 - self.nu2 ** 2) / (np.pi * self.E2))

    @property
    def E_star(self) -> float:
        return effective_modulus(self.E1, self.nu1, self.E2, self.nu2)

    @property
    def R(self) -> float:
        """Effective radius ``1/R = 2/D1 + 2/D2``."""
        return 1.0 / (2.0 / self.D1 + 2.0 / self.D2)

    def _beta(self) -> float:
        return float(np.sqrt(4 * self.R / (np.pi * self.E_star)))

    def _A_C(self) -> tuple[float, float]:
        C1, C2 = self.compliances
        beta = self._beta()
        A = C1 * (np.log(2 * self.D1 / beta) + self.k) + C2 * (np.log(2 * self.D2 / beta) + self.k)
        return float(A), C1 + C2

    @property
    def q_max(self) -> float:
        """End of the monotone range: ``d delta / d q = 0`` (``t = 1``)."""
        A, C = self._A_C()
        return float(np.exp(2 * A / C - 1))

    # the law ----------------------------------------------------------------
    def _check_q(self, q) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        if not np.all(np.isfinite(q) & (q >= 0)):
            raise ValueError("parameter 'q': negative or non-finite line load is not allowed; "
                             "allowed: numbers in [0, q_max)")
        if np.any(q >= self.q_max):
            raise ValueError(f"parameter 'q': {float(q.max())!r} is not allowed; allowed: numbers "
                             f"in [0, {self.q_max!r}) (beyond, the law is not monotone)")
        return q

    def half_width(self, q) -> np.ndarray:
        """Hertz half-width ``b(q)``."""
        b, _ = two_cylinders(q, self.D1 / 2, self.D2 / 2, self.E_star)
        return b

    def shares(self, q) -> tuple[np.ndarray, np.ndarray]:
        """Approach of each axis to the contact line, ``(delta_1, delta_2)``, at line load ``q``."""
        q = self._check_q(q)
        b = self.half_width(q)
        C1, C2 = self.compliances
        with np.errstate(divide="ignore", invalid="ignore"):
            d1 = np.where(q > 0, C1 * q * (np.log(2 * self.D1 / b) + self.k), 0.0)
            d2 = np.where(q > 0, C2 * q * (np.log(2 * self.D2 / b) + self.k), 0.0)
        return d1, d2

    def approach(self, q) -> np.ndarray:
        """Mutual approach ``delta(q)`` of the two axes."""
        d1, d2 = self.shares(q)
        return d1 + d2

    def _t(self, delta: np.ndarray) -> np.ndarray:
        """``t > 1`` with ``t - ln t = m``, ``m = 2A/C - ln(2 delta / C)``, for ``delta > 0``."""
        A, C = self._A_C()
        m = 2 * A / C - np.log(2 * delta / C)
        if np.any(m <= 1):
            raise ValueError(f"parameter 'delta': {float(delta.max())!r} is not allowed; allowed: "
                             f"numbers below {float(self.approach(self.q_max * (1 - 1e-12)))!r} "
                             "(the largest approach of the monotone law)")
        t = np.empty_like(m)
        small = m < 600                      # exp(-m) representable
        t[small] = -lambertw(-np.exp(-m[small]), -1).real
        tt = m[~small] + np.log(m[~small])   # fixed point t = m + ln t, contraction 1/t
        for _ in range(6):
            tt = m[~small] + np.log(tt)
        t[~small] = tt
        return t

    def load(self, delta) -> np.ndarray:
        """Line load ``q = Q(delta)``: the inverse of :meth:`approach`; 0 where ``delta <= 0``."""
        delta = np.asarray(delta, dtype=float)
        if not np.all(np.isfinite(delta)):
            raise ValueError("parameter 'delta': non-finite values; allowed: finite numbers")
        q = np.zeros_like(delta)
        pos = delta > 0
        if np.any(pos):
            _, C = self._A_C()
            q[pos] = 2 * delta[pos] / (C * self._t(delta[pos]))
        return q

    def stiffness(self, delta) -> np.ndarray:
        """``dQ/d delta = 1 / (d delta / dq) = 2 / (C (t - 1))``; 0 where ``delta <= 0``."""
        delta = np.asarray(delta, dtype=float)
        k = np.zeros_like(delta)
        pos = delta > 0
        if np.any(pos):
            _, C = self._A_C()
            k[pos] = 2.0 / (C * (self._t(delta[pos]) - 1.0))
        return k

    def energy(self, delta) -> np.ndarray:
        """``Phi(delta) = int_0^delta Q = q delta / 2 - C q^2 / 8`` (0 where ``delta <= 0``)."""
        delta = np.asarray(delta, dtype=float)
        q = self.load(delta)
        _, C = self._A_C()
        return np.where(delta > 0, q * delta / 2 - C * q ** 2 / 8, 0.0)


# --------------------------------------------------------------------------- beams
def shear_coefficient_circle(nu: float) -> float:
    """Timoshenko shear coefficient of a solid circle, ``6 (1 + nu) / (7 + 6 nu)`` (Cowper 1966)."""
    nu = _poisson("nu", nu)
    return 6 * (1 + nu) / (7 + 6 * nu)


def circle_section(d, E: float, nu: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(EI, kappa G A, A)`` of solid circular sections of diameters ``d``.

    ``A = pi d^2 / 4``, ``I = pi d^4 / 64``, ``G = E / (2 (1 + nu))``, ``kappa`` by
    :func:`shear_coefficient_circle`.
    """
    d = np.asarray(d, dtype=float)
    if not np.all(np.isfinite(d) & (d > 0)):
        raise ValueError("parameter 'd': non-positive or non-finite diameter; allowed: numbers in (0, inf)")
    E = _positive("E", E)
    kappa = shear_coefficient_circle(nu)
    A = np.pi * d ** 2 / 4
    return E * np.pi * d ** 4 / 64, kappa * E / (2 * (1 + nu)) * A, A


def _check_grid(x) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    if x.ndim != 1 or x.size < 2 or not np.all(np.isfinite(x)) or np.any(np.diff(x) <= 0):
        raise ValueError("parameter 'x': not allowed; allowed: a strictly increasing finite "
                         "1D array of at least 2 node positions")
    return x


def _per_element(value, name: str, n: int) -> np.ndarray:
    v = np.broadcast_to(np.asarray(value, dtype=float), (n,)) if np.ndim(value) == 0 else \
        np.asarray(value, dtype=float)
    if v.shape != (n,):
        raise ValueError(f"parameter '{name}': shape {v.shape} is not allowed; "
                         f"allowed: a scalar or ({n},) (one value per element)")
    return v


def timoshenko_stiffness(x, EI, kGA) -> sp.csr_matrix:
    """Stiffness of a Timoshenko beam on nodes ``x``, DOFs ``(w_0, theta_0, w_1, ...)``.

    Per element of length ``l`` with ``phi = 12 EI / (kGA l^2)`` the exact stiffness of a
    uniform Timoshenko segment (Przemieniecki 1968, Ch. 5)::

        EI / ((1 + phi) l^3) [[ 12,  6l,          -12,  6l         ],
                              [ 6l,  (4 + phi) l^2, -6l, (2 - phi) l^2],
                              [-12, -6l,           12, -6l         ],
                              [ 6l,  (2 - phi) l^2, -6l, (4 + phi) l^2]]

    ``w`` is the deflection, ``theta`` the rotation of the section (``= w'`` without shear).

    Parameters
    ----------
    x : (n,) array
        Strictly increasing node positions.
    EI, kGA : float or (n - 1,) array
        Bending and shear stiffness per element, ``> 0``.
    """
    x = _check_grid(x)
    ne = x.size - 1
    EI = _per_element(EI, "EI", ne)
    kGA = _per_element(kGA, "kGA", ne)
    for name, v in (("EI", EI), ("kGA", kGA)):
        if not np.all(np.isfinite(v) & (v > 0)):
            raise ValueError(f"parameter '{name}': non-positive or non-finite values; "
                             "allowed: numbers in (0, inf)")
    l = np.diff(x)
    phi = 12 * EI / (kGA * l ** 2)
    c = EI / ((1 + phi) * l ** 3)
    z = np.zeros_like(l)
    ke = np.array([[12 + z, 6 * l, -12 + z, 6 * l],
                   [6 * l, (4 + phi) * l ** 2, -6 * l, (2 - phi) * l ** 2],
                   [-12 + z, -6 * l, 12 + z, -6 * l],
                   [6 * l, (2 - phi) * l ** 2, -6 * l, (4 + phi) * l ** 2]]) * c  # (4, 4, ne)
    dofs = 2 * np.arange(ne)[:, None] + np.arange(4)[None, :]             # (ne, 4)
    rows = np.repeat(dofs, 4, axis=1).ravel()
    cols = np.tile(dofs, (1, 4)).ravel()
    vals = np.transpose(ke, (2, 0, 1)).ravel()
    n = 2 * x.size
    return sp.csr_matrix((vals, (rows, cols)), shape=(n, n))


def uniform_load_vector(x, p) -> np.ndarray:
    """Consistent nodal loads of a line load ``p`` (force per length, positive up) uniform per element.

    Per element ``(p l/2, p l^2/12, p l/2, -p l^2/12)``: the fixed-end forces, exact for
    Euler-Bernoulli and Timoshenko segments alike.
    """
    x = _check_grid(x)
    ne = x.size - 1
    p = _per_element(p, "p", ne)
    if not np.all(np.isfinite(p)):
        raise ValueError("parameter 'p': non-finite values; allowed: finite numbers")
    l = np.diff(x)
    f = np.zeros(2 * x.size)
    np.add.at(f, 2 * np.arange(ne), p * l / 2)
    np.add.at(f, 2 * np.arange(ne) + 1, p * l ** 2 / 12)
    np.add.at(f, 2 * np.arange(ne) + 2, p * l / 2)
    np.add.at(f, 2 * np.arange(ne) + 3, -p * l ** 2 / 12)
    return f


# --------------------------------------------------------------------------- the stack
@dataclass(frozen=True)
class RollStack:
    """Geometry and material of the roll stack (defaults: thesis Sect. 9.3 scene, SI units).

    Lengths are full lengths (barrels, bearing spans) centred on ``x = 0``; ``work_crown``
    is on the diameter (barrel centre minus barrel ends), ``backup_chamfer_depth`` on the
    radius. Any consistent unit set may be used.

    The thesis gives ``E = 220``, ``f = (0, 0, -76.6e-6)`` and "Schliff = 150 um" (Figs.
    9.10-9.16), i.e. kN/mm^2 and N/mm^3 = 7.66e4 N/m^3; its strip forces "15 KN" and
    "30 KN" with ``L = 1 m`` are read as kN/mm, i.e. 15 and 30 MN in total, which agrees
    with its text ("forces on the rolling mill of about 30 000 kN"). Roll and neck
    diameters, barrel lengths, bearing spans and the edge relief are not in the thesis's
    text: they are the scene's specification (the relief's depth, 0.5 mm, is this
    module's choice).

    Raises
    ------
    ValueError
        Naming the parameter if outside its range (all lengths and moduli ``> 0``; crown,
        relief and weight density ``>= 0``; necks no thicker than barrels; barrels within
        bearing spans; ``backup_barrel_length <= work_barrel_length``; the relief within
        half the backup barrel; the strip within the work-roll barrel).
    """

    work_diameter: float = 0.70
    work_barrel_length: float = 2.00
    work_crown: float = 150e-6
    work_neck_diameter: float = 0.42
    work_bearing_span: float = 2.90
    backup_diameter: float = 1.50
    backup_barrel_length: float = 1.90
    backup_chamfer_length: float = 0.05
    backup_chamfer_depth: float = 0.5e-3
    backup_neck_diameter: float = 1.00
    backup_bearing_span: float = 3.10
    E: float = 220e9
    nu: float = 0.3
    weight_density: float = 7.66e4
    strip_width: float = 1.0

    def __post_init__(self):
        for name in ("work_diameter", "work_barrel_length", "work_neck_diameter",
                     "work_bearing_span", "backup_diameter", "backup_barrel_length",
                     "backup_neck_diameter", "backup_bearing_span", "E", "strip_width"):
            _positive(name, getattr(self, name))
        for name in ("work_crown", "backup_chamfer_length", "backup_chamfer_depth", "weight_density"):
            _positive(name, getattr(self, name), allow_zero=True)
        _poisson("nu", self.nu)

        def need(ok: bool, name: str, allowed: str):
            if not ok:
                raise ValueError(f"parameter '{name}': {getattr(self, name)!r} is not allowed; "
                                 f"allowed: {allowed}")

        need(self.work_neck_diameter <= self.work_diameter, "work_neck_diameter",
             f"a number in (0, work_diameter = {self.work_diameter}]")
        need(self.backup_neck_diameter <= self.backup_diameter, "backup_neck_diameter",
             f"a number in (0, backup_diameter = {self.backup_diameter}]")
        need(self.work_barrel_length <= self.work_bearing_span, "work_barrel_length",
             f"a number in (0, work_bearing_span = {self.work_bearing_span}]")
        need(self.backup_barrel_length <= self.backup_bearing_span, "backup_barrel_length",
             f"a number in (0, backup_bearing_span = {self.backup_bearing_span}]")
        need(self.backup_barrel_length <= self.work_barrel_length, "backup_barrel_length",
             f"a number in (0, work_barrel_length = {self.work_barrel_length}] (the contact "
             "runs over the backup barrel)")
        need(self.backup_chamfer_length <= self.backup_barrel_length / 2, "backup_chamfer_length",
             f"a number in [0, backup_barrel_length / 2 = {self.backup_barrel_length / 2}]")
        need(self.work_crown < self.work_diameter, "work_crown",
             f"a number in [0, work_diameter = {self.work_diameter})")
        need(self.backup_chamfer_depth < self.backup_diameter / 2, "backup_chamfer_depth",
             f"a number in [0, backup_diameter / 2 = {self.backup_diameter / 2})")
        need(self.strip_width <= self.work_barrel_length, "strip_width",
             f"a number in (0, work_barrel_length = {self.work_barrel_length}]")

    # geometry -----------------------------------------------------------------
    def crown_drop(self, x) -> np.ndarray:
        """Work roll: ``r(0) - r(x) = (crown/2) (2x/B_w)^2`` on the barrel (NaN beyond)."""
        x = np.asarray(x, dtype=float)
        half = self.work_barrel_length / 2
        c = self.work_crown / 2 * (x / half) ** 2
        return np.where(np.abs(x) <= half * (1 + 1e-12), c, np.nan)

    def relief_drop(self, x) -> np.ndarray:
        """Backup roll: ``r(0) - r(x)``, a linear edge drop to ``chamfer_depth`` at the barrel ends.

        Zero on ``|x| <= B_b/2 - chamfer_length``, NaN beyond the barrel.
        """
        x = np.abs(np.asarray(x, dtype=float))
        half = self.backup_barrel_length / 2
        lc = self.backup_chamfer_length
        if lc > 0:
            drop = self.backup_chamfer_depth * np.clip((x - (half - lc)) / lc, 0.0, 1.0)
        else:
            drop = np.zeros_like(x)
        return np.where(x <= half * (1 + 1e-12), drop, np.nan)

    def flattening_law(self, form: str = "johnson") -> FlatteningLaw:
        """The work-roll/backup-roll flattening law at the nominal barrel diameters."""
        return FlatteningLaw(self.work_diameter, self.backup_diameter, self.E, self.nu,
                             self.E, self.nu, form)

    def grid(self, n_elements: int) -> np.ndarray:
        """Nodes symmetric about 0 with about ``n_elements`` elements over the longer span.

        Every break point (bearing centres, barrel ends, the relief's start, strip edges,
        0) is a node, so sections and loads are uniform per element.
        """
        if not (isinstance(n_elements, (int, np.integer)) and 8 <= n_elements <= 100_000):
            raise ValueError(f"parameter 'n_elements': {n_elements!r} is not allowed; "
                             "allowed: an integer in [8, 100000]")
        half = max(self.work_bearing_span, self.backup_bearing_span) / 2
        h = 2 * half / n_elements
        bb = self.backup_barrel_length / 2
        brk = np.array([0.0, self.strip_width / 2, bb - self.backup_chamfer_length, bb,
                        self.work_barrel_length / 2, self.work_bearing_span / 2,
                        self.backup_bearing_span / 2])
        brk = np.sort(brk)
        keep = np.concatenate([[True], np.diff(brk) > 1e-9 * half])
        brk = brk[keep]
        pos = [np.linspace(a, b, max(1, int(np.ceil((b - a) / h - 1e-9))) + 1)[:-1]
               for a, b in zip(brk[:-1], brk[1:])]
        pos = np.concatenate(pos + [brk[-1:]])
        return np.concatenate([-pos[:0:-1], pos])


@dataclass(frozen=True)
class RollStackSolution:
    """The roll stack under one strip force, on the grid ``x`` (NaN where undefined).

    Attributes
    ----------
    x : (n,) array
        Nodes over the longer bearing span.
    weights : (n,) array
        Trapezoidal weights of the contact springs (0 off the backup barrel).
    q : (n,) array
        Contact line load between the rolls (force per length, ``>= 0``).
    half_width, peak_pressure : (n,) array
        Hertz ``b`` and ``p0`` at the local ``q`` (:func:`reference.hertz.two_cylinders`).
    approach : (n,) array
        Flattening approach of the axes ``delta(q)``; ``work_share``/``backup_share``: each
        roll's part.
    work_axis, backup_axis : (n,) array
        Vertical displacement (up) of the axes; NaN beyond each roll's bearing centres.
    work_contact_line, backup_contact_line : (n,) array
        Vertical displacement of the material lines that meet in the contact, along the
        backup barrel (NaN beyond): the work roll's top line ``w_w - delta_w`` and the
        backup roll's bottom line ``w_b + delta_b`` (axis plus flattening share). Where the
        rolls touch, ``work_contact_line - backup_contact_line = g0``.
    work_surface : (n,) array
        Strip-side surface of the work roll relative to its unloaded position at
        ``x = 0``: ``w_w + c_w(x)`` (axis deflection minus the crown's radius change;
        NaN beyond the barrel). Without the crown it is ``work_axis``.
    strip_profile : (n,) array
        ``h(x) - h(0) = 2 (work_surface(x) - work_surface(0))`` over the strip (NaN beyond).
    strip_crown : float
        ``h(0) - h(+-L/2)`` (mean of both edges): the strip crown.
    work_roll_rise : float
        Rigid-body position of the floating work roll: mean vertical displacement of its
        bearing centres (which carry no force).
    contact_force, work_roll_weight, backup_roll_weight, bearing_force : float
        ``sum(weights q)``, the rolls' weights and the load on each backup bearing.
    F : float
        The strip force.
    iterations : int
        Newton steps taken.
    """

    x: np.ndarray
    weights: np.ndarray
    q: np.ndarray
    half_width: np.ndarray
    peak_pressure: np.ndarray
    approach: np.ndarray
    work_share: np.ndarray
    backup_share: np.ndarray
    work_axis: np.ndarray
    backup_axis: np.ndarray
    work_contact_line: np.ndarray
    backup_contact_line: np.ndarray
    work_surface: np.ndarray
    strip_profile: np.ndarray
    strip_crown: float
    work_roll_rise: float
    contact_force: float
    work_roll_weight: float
    backup_roll_weight: float
    bearing_force: float
    F: float
    iterations: int

    def at(self, name: str, x0: float) -> float:
        """Value of the array attribute ``name`` at the node nearest to ``x0``."""
        return float(getattr(self, name)[np.argmin(np.abs(self.x - x0))])


def _beam(x_all, span, barrel, d_barrel, d_neck, E, nu):
    """Node indices, stiffness, element diameters of one roll over ``|x| <= span/2``."""
    idx = np.flatnonzero(np.abs(x_all) <= span / 2 * (1 + 1e-12))
    x = x_all[idx]
    xm = (x[:-1] + x[1:]) / 2
    d = np.where(np.abs(xm) < barrel / 2, d_barrel, d_neck)
    EI, kGA, A = circle_section(d, E, nu)
    return idx, x, timoshenko_stiffness(x, EI, kGA), A


def solve(F: float, stack: RollStack | None = None, n_elements: int = 400,
          form: str = "johnson", rtol: float = 1e-13, max_iter: int = 50) -> RollStackSolution:
    """Solve the roll stack under the strip force ``F`` (total, over the strip width).

    Unknowns: deflection and rotation at every node of both rolls (backup roll: ``w = 0``
    at its bearing centres). The total potential energy
    ``1/2 U^T K U - f^T U + sum_i weights_i Phi(delta_i)`` (``Phi`` of
    :meth:`FlatteningLaw.energy`) is convex; it is minimised by Newton's method with the
    tangent ``K + B^T diag(weights Q'(delta)) B`` and an Armijo backtracking line search,
    from the work roll lifted rigidly to carry ``F - W_w`` uniformly. Converged when every
    residual (force or moment) is below ``rtol`` times the sum of the magnitudes of the
    terms it adds up (``|K| |U| + |f| + |B^T| weights q``): a backward error, free of
    units and reachable in floating point (a residual relative to ``F`` is not: the
    beam stiffness terms cancel from ~1e6 F).

    Parameters
    ----------
    F : float
        Strip force, larger than the work roll's weight (the roll floats on the strip).
    stack : RollStack
        Geometry and material (default: the thesis scene, SI).
    n_elements : int
        About this many elements over the longer bearing span.
    form : str
        Flattening law, :data:`FLATTENING_FORMS`.
    rtol : float
        Backward-error tolerance, in ``[1e-15, 1e-3]`` (the floating-point floor is ~2e-16;
        Newton's quadratic convergence reaches it from ~1e-11 in one step).
    max_iter : int
        Newton steps allowed, ``>= 1``.

    Raises
    ------
    ValueError
        Naming ``F``, ``rtol``, ``max_iter`` (or a parameter checked downstream) if outside
        the allowed range.
    RuntimeError
        If Newton's method has not converged in ``max_iter`` steps.
    """
    s = RollStack() if stack is None else stack
    if not isinstance(s, RollStack):
        raise ValueError(f"parameter 'stack': {type(s).__name__} is not allowed; allowed: a RollStack")
    F = _positive("F", F)
    if not (1e-15 <= rtol <= 1e-3):
        raise ValueError(f"parameter 'rtol': {rtol!r} is not allowed; allowed: a number in [1e-15, 1e-3]")
    if not (isinstance(max_iter, (int, np.integer)) and max_iter >= 1):
        raise ValueError(f"parameter 'max_iter': {max_iter!r} is not allowed; allowed: an integer >= 1")
    law = s.flattening_law(form)
    x = s.grid(n_elements)
    gamma = s.weight_density

    iw, xw, Kw, Aw = _beam(x, s.work_bearing_span, s.work_barrel_length, s.work_diameter,
                           s.work_neck_diameter, s.E, s.nu)
    ib, xb, Kb, Ab = _beam(x, s.backup_bearing_span, s.backup_barrel_length, s.backup_diameter,
                           s.backup_neck_diameter, s.E, s.nu)
    xmw = (xw[:-1] + xw[1:]) / 2
    strip = np.where(np.abs(xmw) < s.strip_width / 2, F / s.strip_width, 0.0)
    fw = uniform_load_vector(xw, strip - gamma * Aw)
    fb = uniform_load_vector(xb, -gamma * Ab)
    W_w = float(np.sum(gamma * Aw * np.diff(xw)))
    W_b = float(np.sum(gamma * Ab * np.diff(xb)))
    if F <= W_w:
        raise ValueError(f"parameter 'F': {F!r} is not allowed; allowed: a number in "
                         f"({W_w!r}, inf) (more than the work roll's weight, which it floats on)")

    nw = 2 * xw.size
    K = sp.block_diag([Kw, Kb], format="csr")
    f = np.concatenate([fw, fb])
    fixed = nw + 2 * np.array([0, xb.size - 1])          # backup w at its bearing centres
    free = np.setdiff1d(np.arange(K.shape[0]), fixed)

    # contact nodes: the backup barrel
    half_b = s.backup_barrel_length / 2
    ic = np.flatnonzero(np.abs(x) <= half_b * (1 + 1e-12))
    xc = x[ic]
    wts = np.zeros(xc.size)
    wts[:-1] += np.diff(xc) / 2
    wts[1:] += np.diff(xc) / 2
    g0 = s.crown_drop(xc) + s.relief_drop(xc)
    pos_w = np.searchsorted(x[iw], xc)
    pos_b = np.searchsorted(x[ib], xc)
    B = sp.csr_matrix((np.concatenate([np.ones(xc.size), -np.ones(xc.size)]),
                       (np.tile(np.arange(xc.size), 2),
                        np.concatenate([2 * pos_w, nw + 2 * pos_b]))),
                      shape=(xc.size, K.shape[0]))
    Kf = K[free][:, free]
    Bf = B[:, free]
    ff = f[free]
    absK, absB = abs(Kf), abs(Bf)

    def gradient(u):
        delta = Bf @ u - g0
        fc = wts * law.load(delta)
        g = Kf @ u - ff + Bf.T @ fc
        # backward error: each residual against the magnitude of the terms it sums
        size = absK @ np.abs(u) + np.abs(ff) + absB.T @ fc
        return g, delta, np.max(np.abs(g) / np.maximum(size, np.finfo(float).tiny))

    def energy(u):
        """The potential and the size of its terms (its round-off is ~1e-16 of that)."""
        delta = Bf @ u - g0
        phi = np.sum(wts * law.energy(delta))
        au = np.abs(u)
        return 0.5 * u @ (Kf @ u) - ff @ u + phi, 0.5 * au @ (absK @ au) + np.abs(ff) @ au + phi

    u = np.zeros(free.size)
    lift = float(law.approach((F - W_w) / (2 * half_b))) + float(np.max(g0))
    u[free < nw] = np.where(free[free < nw] % 2 == 0, lift, 0.0)
    g, delta, res = gradient(u)
    it = 0
    while res > rtol:
        if it == max_iter:
            raise RuntimeError(f"Newton's method did not converge in max_iter = {max_iter} steps "
                               f"(relative residual {res:.3e} > rtol = {rtol:.1e})")
        it += 1
        H = Kf + Bf.T @ sp.diags(wts * law.stiffness(delta)) @ Bf
        du = spla.spsolve(H.tocsc(), -g)
        (e0, size), slope, alpha = energy(u), g @ du, 1.0
        while alpha > 1e-10:                 # Armijo, blind below the potential's round-off
            if energy(u + alpha * du)[0] <= e0 + 1e-4 * alpha * slope + 1e-12 * size:
                break
            alpha /= 2
        u = u + alpha * du
        g, delta, res = gradient(u)

    U = np.zeros(K.shape[0])
    U[free] = u
    qc = law.load(delta)
    n = x.size
    q = np.zeros(n)
    q[ic] = qc
    weights = np.zeros(n)
    weights[ic] = wts
    bw, p0 = two_cylinders(q, s.work_diameter / 2, s.backup_diameter / 2, law.E_star)
    dw, db = law.shares(q)
    work_axis = np.full(n, np.nan)
    work_axis[iw] = U[:nw:2]
    backup_axis = np.full(n, np.nan)
    backup_axis[ib] = U[nw::2]
    work_surface = work_axis + s.crown_drop(x)
    i0 = int(np.argmin(np.abs(x)))
    in_strip = np.abs(x) <= s.strip_width / 2 * (1 + 1e-12)
    strip_profile = np.where(in_strip, 2 * (work_surface - work_surface[i0]), np.nan)
    edges = np.flatnonzero(in_strip)[[0, -1]]
    barrel = np.full(n, np.nan)
    barrel[ic] = 0.0
    contact_force = float(np.sum(wts * qc))
    return RollStackSolution(
        x=x, weights=weights, q=q, half_width=bw, peak_pressure=p0, approach=dw + db,
        work_share=dw, backup_share=db, work_axis=work_axis, backup_axis=backup_axis,
        work_contact_line=work_axis - dw + barrel, backup_contact_line=backup_axis + db + barrel,
        work_surface=work_surface, strip_profile=strip_profile,
        strip_crown=float(-np.mean(strip_profile[edges])),
        work_roll_rise=float(np.mean(U[[0, nw - 2]])), contact_force=contact_force,
        work_roll_weight=W_w, backup_roll_weight=W_b,
        bearing_force=(contact_force - W_b) / 2, F=F, iterations=it)
