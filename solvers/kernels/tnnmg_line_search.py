"""Projection and line search of truncated nonsmooth Newton multigrid
(:mod:`solvers.tnnmg`, step 3), frictionless.

The truncated correction projected onto the feasible set and the exact line search on the
energy along it (Gräser and Kornhuber, J. Comput. Math. 27, 2009); where a bound cuts that
short, points on the projection arc ``min(v + a c, upper)`` with backtracking (a
projected Newton step, Bertsekas, SIAM J. Control Optim. 20, 1982), the first with a
lower energy taken. :func:`arc_or_line` serves the Tresca step's line searches too
(:mod:`solvers.kernels.tnnmg_tresca`).
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from solvers.kernels.tnnmg_system import FineSystem, energy


#: The projection arc's backtracking: step factor and smallest step (:func:`line_search_step`).
ARC_FACTOR = 0.25
ARC_MIN = 1e-4


def line_search_step(fine: FineSystem, v: np.ndarray, r: np.ndarray, c: np.ndarray, piv: np.ndarray,
                     upper: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The new iterate from the truncated correction ``c`` (:mod:`solvers.tnnmg`, step 3).

    The exact line search along ``c`` projected onto the feasible set (``c <= upper - v``
    at the pivots; Gräser-Kornhuber) is the safe candidate. Where a bound cut it short
    (or ``c`` is no descent direction), points on the
    projection arc ``min(v + a c, upper)`` at the pivots, ``a = 1, 1/4, ...`` down to
    :data:`ARC_MIN` (a projected Newton step with backtracking, Bertsekas): the first
    whose energy is lower than the line search's is taken. The arc takes every bound
    the correction crosses at once; the projected line search is cut short by the
    unknowns nearest their bounds and crawls when a soft body is pressed into a stiff
    one (contrast 1e-4: hundreds of steps). The energy never rises. Returns
    ``(v, r, step)``: the line search's length, or ``-a`` for an arc point.
    """
    slack = upper - v[piv]
    d = c.copy()
    d[piv] = np.minimum(d[piv], slack)
    Ad = fine.matvec(d)
    curvature, slope = float(d @ Ad), float(r @ d)
    step, cut = 0.0, True
    if curvature > 0 and slope > 0:
        step = free = slope / curvature
        rising = d[piv] > 0
        if rising.any():
            step = min(step, float(np.min(slack[rising] / d[piv][rising])))
        cut = step < free
    v_line, r_line = v + step * d, r - step * Ad
    return arc_or_line(fine, energy, v, c, piv, upper, v_line, r_line, step, cut)


def arc_or_line(fine: FineSystem, energy: Callable, v: np.ndarray, c: np.ndarray, piv: np.ndarray,
                upper: np.ndarray, v_line: np.ndarray, r_line: np.ndarray, step: float, cut: bool
                ) -> tuple[np.ndarray, np.ndarray, float]:
    """The line search's point ``v_line`` (step ``step``), or where a bound ``cut`` it short
    the first point of the projection arc with a lower ``energy(fine, v, r)``
    (:func:`line_search_step`)."""
    J_line = energy(fine, v_line, r_line)
    arc = 1.0 if cut else 0.0          # the arc only where a bound cut the line search short
    while arc >= ARC_MIN:
        v_arc = v + arc * c
        v_arc[piv] = np.minimum(v_arc[piv], upper)
        r_arc = fine.f - fine.matvec(v_arc)
        if energy(fine, v_arc, r_arc) < J_line:
            return v_arc, r_arc, -arc
        arc *= ARC_FACTOR
    v_line[piv] = np.minimum(v_line[piv], upper)
    return v_line, r_line, step
