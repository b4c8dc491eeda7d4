"""Tests of the roll-stack beam reference (reference/roll_stack.py, thesis Sect. 9.3).

Hand calculations and closed forms, not re-evaluations of the module's formulas: the
Hertz numbers of the scene worked out by hand, the flattening constant re-derived by
integrating the Hertz and Flamant stress fields, a uniform Timoshenko beam against
5 p L^4 / (384 EI) + p L^2 / (8 kappa G A), and the whole stack for equilibrium,
symmetry, compatibility, the crown's effect and independence of the unit system.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse.linalg as spla
from scipy.integrate import quad

from reference.hertz import effective_modulus, two_cylinders
from reference.roll_stack import (
    FlatteningLaw, RollStack, circle_section, shear_coefficient_circle,
    solve, timoshenko_stiffness, uniform_load_vector,
)

E, NU = 220e9, 0.3
FORCES = (15e6, 30e6)


@pytest.fixture(scope="module")
def solutions():
    """The scene at both strip forces, crowned and cylindrical work roll (SI)."""
    crowned, cylindrical = RollStack(), RollStack(work_crown=0.0)
    return {(F, crown): solve(F, crowned if crown else cylindrical)
            for F in FORCES for crown in (True, False)}


# --------------------------------------------------------------------------- Hertz
def test_two_cylinders_against_a_hand_calculation():
    # q = 1e7 N/m between R1 = 0.35 m and R2 = 0.75 m, E = 220 GPa, nu = 0.3:
    # R = 0.35 * 0.75 / 1.10 = 0.238636..., E* = 220e9 / (2 * 0.91) = 120.879e9 Pa,
    # b = sqrt(4e7 * 0.238636 / (pi * 120.879e9)) = sqrt(2.51362e-5) = 5.01358 mm,
    # p0 = 2e7 / (pi * 5.01358e-3) = 1.26979 GPa.
    E_star = effective_modulus(E, NU, E, NU)
    assert E_star == pytest.approx(120.879e9, rel=1e-5)
    b, p0 = two_cylinders(1e7, 0.35, 0.75, E_star)
    assert b == pytest.approx(5.01358e-3, rel=1e-5)
    assert p0 == pytest.approx(1.26979e9, rel=1e-5)
    assert p0 == pytest.approx(2 * 1e7 / (np.pi * b), rel=1e-14)   # p0 = 2q/(pi b)
    # the semi-elliptical pressure carries q
    assert quad(lambda s: p0 * np.sqrt(1 - (s / b) ** 2), -b, b)[0] == pytest.approx(1e7, rel=1e-9)
    b, p0 = two_cylinders(np.array([0.0, 4e7]), 0.35, 0.75, E_star)
    assert b[0] == 0 and p0[0] == 0 and b[1] == pytest.approx(2 * 5.01358e-3, rel=1e-5)


def test_two_cylinders_rejects_bad_input():
    with pytest.raises(ValueError, match="parameter 'q'"):
        two_cylinders(-1.0, 0.35, 0.75, 1e11)
    with pytest.raises(ValueError, match="parameter 'R2'"):
        two_cylinders(1.0, 0.35, 0.0, 1e11)
    with pytest.raises(ValueError, match="parameter 'E_star'"):
        two_cylinders(1.0, 0.35, 0.75, np.inf)


# --------------------------------------------------------------------------- flattening
@pytest.fixture(scope="module")
def law():
    return FlatteningLaw(0.70, 1.50, E, NU, E, NU)


def test_flattening_against_a_hand_calculation(law):
    # q = 1e7 N/m, b = 5.01358 mm (above), C_i = 2 * 0.91 / (pi * 220e9) = 2.63329e-12 m^2/N:
    # ln(1.4 / b) = 5.63208, ln(3.0 / b) = 6.39422,
    # delta_w = 2.63329e-5 * 5.13208 = 0.135143 mm, delta_b = 2.63329e-5 * 5.89422 = 0.155212 mm.
    assert law.compliances[0] == pytest.approx(2.63329e-12, rel=1e-5)
    d_w, d_b = law.shares(1e7)
    assert d_w == pytest.approx(1.35143e-4, rel=1e-5)
    assert d_b == pytest.approx(1.55212e-4, rel=1e-5)
    assert law.approach(1e7) == pytest.approx(2.90354e-4, rel=1e-5)
    # Foeppl's constant (2/3 for the pair instead of -1): 5/6 C q more
    foppl = replace(law, form="foppl")
    assert foppl.approach(1e7) - law.approach(1e7) == pytest.approx(
        (5 / 6) * 2 * 2.63329e-12 * 1e7, rel=1e-5)


def test_flattening_constant_from_the_disc_between_two_hertz_contacts():
    """Johnson's k = -1/2: the diameter of a plane-strain disc pressed by two opposite
    Hertz contacts shortens by C q (2 ln(4R/b) - 1). Integrated here from the Hertz
    subsurface stresses (near each contact, to depth h) and the point-load disc solution
    (two Flamant fields plus the uniform tension q/(pi R), over the rest)."""
    E1, nu, q, R, b = 1.0, 0.3, 1.0, 1.0, 1e-6
    p0 = 2 * q / (np.pi * b)
    C = 2 * (1 - nu ** 2) / (np.pi * E1)

    def eps(s_axis, s_across):          # plane-strain strain along the loaded diameter
        return ((1 - nu ** 2) * s_axis - nu * (1 + nu) * s_across) / E1

    def near(z):
        r = np.sqrt(b * b + z * z)
        return eps(-p0 * b / r, -(p0 / b) * ((b * b + 2 * z * z) / r - 2 * z))

    def rest(y):
        return eps(-(2 * q / np.pi) * (1 / (R - y) + 1 / (R + y)) + q / (np.pi * R), q / (np.pi * R))

    totals = []
    for h in (1e-4, 1e-3):
        top = -quad(near, 0, h, points=[b, 10 * b, 100 * b], limit=200)[0]
        mid = -quad(rest, -(R - h), R - h, limit=200)[0]
        totals.append(2 * top + mid)
    disc = C * q * (2 * np.log(4 * R / b) - 1)
    assert totals == pytest.approx([disc, disc], rel=1e-4)
    # the module's law for two such discs, at the load whose Hertz half-width is b:
    # twice one roll's share is the diameter's shortening per unit load
    law = FlatteningLaw(2 * R, 2 * R, E1, nu, E1, nu)
    q_b = b ** 2 * np.pi * law.E_star / (4 * law.R)
    assert law.half_width(q_b) == pytest.approx(b, rel=1e-12)
    johnson = 2 * law.shares(q_b)[0] / q_b
    foppl = 2 * replace(law, form="foppl").shares(q_b)[0] / q_b
    assert johnson == pytest.approx(totals[1] / q, rel=1e-4)
    assert foppl - johnson == pytest.approx(2 * (5 / 6) * C, rel=1e-12)


def test_flattening_law_is_monotone_and_inverted_exactly(law):
    q = np.concatenate([[0.0], np.logspace(-3, 9, 400)])
    delta = law.approach(q)
    assert delta[0] == 0 and np.all(np.diff(delta) > 0)
    d_w, d_b = law.shares(q[1:])
    assert np.all(d_w > 0) and np.all(d_b > d_w)       # the larger roll flattens more
    assert law.load(delta[1:]) == pytest.approx(q[1:], rel=1e-12)
    assert np.all(law.load(np.array([-1e-3, 0.0])) == 0)
    # tangent and energy: dQ/d delta and d Phi / d delta = Q, by central differences
    d = np.array([1e-6, 1e-4, 3e-4, 1e-3])
    h = 1e-6 * d
    fd = (law.load(d + h) - law.load(d - h)) / (2 * h)
    assert law.stiffness(d) == pytest.approx(fd, rel=1e-6)
    fd = (law.energy(d + h) - law.energy(d - h)) / (2 * h)
    assert fd == pytest.approx(law.load(d), rel=1e-6)
    # secant stiffness grows with the load: the contact stiffens (q ~ delta / ln(1/delta))
    assert np.all(np.diff(law.load(d) / d) > 0)


def test_flattening_law_rejects_bad_input(law):
    with pytest.raises(ValueError, match="parameter 'q'"):
        law.approach(-1.0)
    with pytest.raises(ValueError, match="parameter 'q'"):
        law.approach(2 * law.q_max)
    with pytest.raises(ValueError, match="parameter 'form'"):
        FlatteningLaw(0.7, 1.5, E, NU, E, NU, form="weber")
    with pytest.raises(ValueError, match="parameter 'nu2'"):
        FlatteningLaw(0.7, 1.5, E, NU, E, 0.5)


# --------------------------------------------------------------------------- beams
def test_timoshenko_simply_supported_uniform_load_closed_form():
    """Midspan deflection 5 p L^4 / (384 EI) + p L^2 / (8 kappa G A), exact at the nodes."""
    L, d, p = 3.1, 1.5, -2e6
    EI, kGA, _ = circle_section(d, E, NU)
    assert shear_coefficient_circle(NU) == pytest.approx(6 * 1.3 / 8.8, rel=1e-15)
    for n in (2, 10, 64):
        x = np.linspace(0, L, n + 1)
        K = timoshenko_stiffness(x, EI, kGA)
        f = uniform_load_vector(x, p)
        free = np.setdiff1d(np.arange(2 * x.size), [0, 2 * n])
        u = np.zeros(2 * x.size)
        u[free] = spla.spsolve(K[free][:, free].tocsc(), f[free])
        w_mid = u[2 * (n // 2)]
        bending, shear = 5 * p * L ** 4 / (384 * EI), p * L ** 2 / (8 * kGA)
        assert w_mid == pytest.approx(bending + shear, rel=1e-11)
        assert shear / bending == pytest.approx(48 * EI / (5 * kGA * L ** 2), rel=1e-12)
        # end rotation p L^3 / (24 EI) (shear adds no rotation of the section)
        assert u[1] == pytest.approx(p * L ** 3 / (24 * EI), rel=1e-11)
    # an Euler-Bernoulli beam is the limit kappa G A -> inf
    x = np.linspace(0, L, 9)
    K = timoshenko_stiffness(x, EI, 1e12 * kGA)
    free = np.setdiff1d(np.arange(2 * x.size), [0, 16])
    u = spla.spsolve(K[free][:, free].tocsc(), uniform_load_vector(x, p)[free])
    assert u[np.flatnonzero(free == 8)[0]] == pytest.approx(5 * p * L ** 4 / (384 * EI), rel=1e-9)


def test_timoshenko_cantilever_with_two_sections():
    """A stepped cantilever under a tip force: w = P (a^3/(3 EI_1) + ...) by the unit-load method."""
    a, c, P = 0.6, 0.45, 1e5                       # root segment a (d1), tip segment c (d2)
    EI1, kGA1, _ = circle_section(1.0, E, NU)
    EI2, kGA2, _ = circle_section(0.42, E, NU)
    x = np.array([0.0, 0.3, a, a + c])
    K = timoshenko_stiffness(x, [EI1, EI1, EI2], [kGA1, kGA1, kGA2])
    f = np.zeros(8)
    f[6] = P
    u = np.zeros(8)
    u[2:] = spla.spsolve(K[2:, 2:].tocsc(), f[2:])
    L = a + c
    # bending: int_0^L (L - s)^2 / EI ds; shear: int_0^L 1 / kGA ds
    bend = ((L ** 3 - c ** 3) / (3 * EI1) + c ** 3 / (3 * EI2)) * P
    shear = (a / kGA1 + c / kGA2) * P
    assert u[6] == pytest.approx(bend + shear, rel=1e-12)


# --------------------------------------------------------------------------- the stack
def test_global_equilibrium(solutions):
    s = RollStack()
    W_w = s.weight_density * np.pi * (0.35 ** 2 * 2.0 + 0.21 ** 2 * 0.9)
    W_b = s.weight_density * np.pi * (0.75 ** 2 * 1.9 + 0.5 ** 2 * 1.2)
    for (F, _), sol in solutions.items():
        assert sol.work_roll_weight == pytest.approx(W_w, rel=1e-12)
        assert sol.backup_roll_weight == pytest.approx(W_b, rel=1e-12)
        assert np.sum(sol.weights * sol.q) == pytest.approx(F - W_w, rel=1e-8)
        assert sol.contact_force == pytest.approx(F - W_w, rel=1e-8)
        assert 2 * sol.bearing_force == pytest.approx(F - W_w - W_b, rel=1e-8)
        # weights are the trapezoidal rule over the backup barrel
        on = sol.weights > 0
        assert sol.weights.sum() == pytest.approx(1.9, rel=1e-12)
        assert np.all(np.abs(sol.x[on]) <= 0.95 + 1e-12)


def test_symmetry(solutions):
    for sol in solutions.values():
        assert sol.x == pytest.approx(-sol.x[::-1], abs=1e-15)
        assert np.max(np.abs(sol.q - sol.q[::-1])) <= 1e-9 * sol.q.max()
        for name in ("work_axis", "backup_axis"):
            w = getattr(sol, name)
            ok = np.isfinite(w)
            assert np.array_equal(ok, ok[::-1])
            assert np.max(np.abs(w[ok] - w[::-1][ok])) <= 1e-9 * np.nanmax(np.abs(w))


def test_contact_is_compressive_and_compatible(solutions):
    s = RollStack()
    for (F, crown), sol in solutions.items():
        stack = s if crown else replace(s, work_crown=0.0)
        on = sol.weights > 0
        g0 = stack.crown_drop(sol.x[on]) + stack.relief_drop(sol.x[on])
        delta = sol.work_axis[on] - sol.backup_axis[on] - g0
        assert np.all(sol.q >= 0)
        touching = sol.q[on] > 0
        assert np.all(delta[~touching] <= 1e-12 * np.max(delta))      # open where q = 0
        assert sol.approach[on][touching] == pytest.approx(delta[touching], rel=1e-9, abs=1e-15)
        # the contact lines meet where the rolls touch: their gap is g0
        gap = g0 - (sol.work_contact_line[on] - sol.backup_contact_line[on])
        assert np.max(np.abs(gap[touching])) <= 1e-9 * np.max(delta)
        # the contact ends inside the backup roll's 50 mm edge relief
        xe = sol.x[sol.q > 0].max()
        assert 0.90 < xe < 0.95
        # Hertz numbers at the local load
        i = np.argmin(np.abs(sol.x))
        b, p0 = two_cylinders(sol.q[i], 0.35, 0.75, effective_modulus(E, NU, E, NU))
        assert sol.half_width[i] == pytest.approx(b) and sol.peak_pressure[i] == pytest.approx(p0)


def test_rolls_rise_and_the_crown_reduces_the_strip_crown(solutions):
    for F in FORCES:
        crowned, cylindrical = solutions[F, True], solutions[F, False]
        for sol in (crowned, cylindrical):
            # the strip pushes the stack up; the backup roll sags upward between its bearings
            assert sol.at("backup_axis", 0) > sol.at("backup_axis", 0.95) > 0
            assert sol.at("backup_axis", 1.55) == 0
            assert sol.at("work_axis", 0) > sol.at("work_axis", 0.95) > 0
            assert sol.strip_crown > 0
            assert sol.strip_crown == pytest.approx(
                2 * (sol.at("work_surface", 0) - sol.at("work_surface", 0.5)), rel=1e-12)
        assert crowned.strip_crown < cylindrical.strip_crown
        # the crown at the strip edge is 2 * 18.75 um on the thickness; the roll bends
        # differently on it, so the gain is not exactly that
        gain = cylindrical.strip_crown - crowned.strip_crown
        assert 20e-6 < gain < 80e-6
        # without the crown the strip-side surface is the axis
        np.testing.assert_array_equal(cylindrical.work_surface[np.isfinite(cylindrical.work_surface)],
                                      cylindrical.work_axis[np.isfinite(cylindrical.work_surface)])
    # twice the force: about twice the sag (the flattening is slightly nonlinear)
    ratio = solutions[30e6, True].at("backup_axis", 0) / solutions[15e6, True].at("backup_axis", 0)
    assert 1.9 < ratio < 2.1


def test_the_softer_foppl_form_lifts_the_work_roll_and_evens_the_load():
    a = solve(15e6, RollStack(), n_elements=200)
    b = solve(15e6, RollStack(), n_elements=200, form="foppl")
    assert b.work_roll_rise > a.work_roll_rise
    assert b.at("q", 0) < a.at("q", 0) and b.at("q", 0.9) > a.at("q", 0.9)
    inner = np.abs(a.x) <= 0.9
    assert np.max(np.abs(b.q - a.q)[inner]) < 0.1 * a.q.max()
    assert b.strip_crown > a.strip_crown
    assert b.at("backup_axis", 0) == pytest.approx(a.at("backup_axis", 0), rel=0.01)


def test_unit_independence():
    """The same stack in mm, N, MPa gives the same deflections (in mm) and loads (N/mm)."""
    si = RollStack()
    mm = RollStack(
        work_diameter=700.0, work_barrel_length=2000.0, work_crown=0.150,
        work_neck_diameter=420.0, work_bearing_span=2900.0, backup_diameter=1500.0,
        backup_barrel_length=1900.0, backup_chamfer_length=50.0, backup_chamfer_depth=0.5,
        backup_neck_diameter=1000.0, backup_bearing_span=3100.0, E=220e3, nu=0.3,
        weight_density=7.66e-5, strip_width=1000.0)
    a, b = solve(15e6, si, n_elements=200), solve(15e6, mm, n_elements=200)
    assert b.x == pytest.approx(1e3 * a.x, rel=1e-12)
    for name in ("work_axis", "backup_axis", "work_contact_line", "backup_contact_line",
                 "approach", "work_surface", "strip_profile"):
        va, vb = getattr(a, name), getattr(b, name)
        ok = np.isfinite(va)
        assert np.array_equal(ok, np.isfinite(vb))
        assert vb[ok] == pytest.approx(1e3 * va[ok], rel=1e-9, abs=1e-9 * np.nanmax(np.abs(vb)))
    assert b.q == pytest.approx(1e-3 * a.q, rel=1e-9, abs=1e-12 * b.q.max())
    assert b.peak_pressure == pytest.approx(1e-6 * a.peak_pressure, rel=1e-9, abs=1e-9)
    assert b.strip_crown == pytest.approx(1e3 * a.strip_crown, rel=1e-8)
    assert b.work_roll_rise == pytest.approx(1e3 * a.work_roll_rise, rel=1e-9)


def test_grid_converged():
    a, b = solve(30e6, RollStack(), n_elements=400), solve(30e6, RollStack(), n_elements=1600)
    assert b.at("work_axis", 0) == pytest.approx(a.at("work_axis", 0), rel=1e-4)
    assert b.at("q", 0) == pytest.approx(a.at("q", 0), rel=1e-4)
    assert b.strip_crown == pytest.approx(a.strip_crown, rel=1e-3)


def test_bad_parameters_are_named():
    with pytest.raises(ValueError, match="parameter 'F'"):
        solve(5e4)                                   # less than the work roll's weight
    with pytest.raises(ValueError, match="parameter 'backup_barrel_length'"):
        RollStack(backup_barrel_length=2.1)
    with pytest.raises(ValueError, match="parameter 'work_neck_diameter'"):
        RollStack(work_neck_diameter=0.8)
    with pytest.raises(ValueError, match="parameter 'nu'"):
        RollStack(nu=0.5)
    with pytest.raises(ValueError, match="parameter 'n_elements'"):
        solve(15e6, n_elements=4)
    with pytest.raises(ValueError, match="parameter 'rtol'"):
        solve(15e6, rtol=0.0)
    with pytest.raises(ValueError, match="parameter 'EI'"):
        timoshenko_stiffness([0.0, 1.0], -1.0, 1.0)
