"""The random frictional family: frictional two-body problems drawn at random, seeded.

A draw is a scene and its options: circle–square (2D, four draws in five) or cube–sphere
(3D) at level 0, Tresca or Coulomb friction, and the quantities that make a frictional
step hard drawn over wide ranges (:data:`RANGES`): the friction coefficient (log-uniform),
the tangential load (the held arc's or cap's prescribed tangential displacement, either
sign) and its number of equal steps, the bodies' stiffness ratio (log-uniform) and their
Poisson ratios, the contact's size (the indentation) and, in 2D, its position (the
circle's centre along the edge, on a grid of nine positions, each circle meshed once per
process) and the square's mesh size. Loads that carry the whole
contact at ``mu P`` (gross sliding) are drawn too: under a prescribed displacement that
is a static equilibrium like any other. The ball of cube–sphere is centred on the face
(the scene has no position option).

Pure functions of the seed: the same seed gives the same problem on every machine.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: The ranges the draws take their options from: ``(low, high)`` uniform, ``("log", low,
#: high)`` log-uniform, a list a uniform choice; ``"2d"`` and ``"3d"`` are per dimension.
RANGES = {
    "friction": ["tresca", "coulomb"],
    "mu": ("log", 0.05, 1.5),
    "shift": {"2d": (-0.03, 0.03), "3d": (-0.06, 0.06)},
    "shift_steps": [1, 2, 3],
    "E2": ("log", 0.25, 8.0),
    "nu1": (0.0, 0.49),
    "nu2": (0.0, 0.49),
    "indent": {"2d": (0.01, 0.025), "3d": (0.05, 0.1)},
    "offset": {"2d": [0.3, 0.35, 0.4, 0.45, 0.5, 0.55, 0.6, 0.65, 0.7]},
    "square_cells": {"2d": [4, 8, 16]},
}

#: The share of 3D draws.
SHARE_3D = 0.2

#: The finest level a draw is made at: every frictional step's exact reference
#: (``tresca_exact``, a dense dual) takes both scenes' contact surfaces up to it.
MAX_LEVEL = 2


@dataclass(frozen=True)
class Draw:
    """One member of the family: ``problems()[problem].make(level, **dict(params))``."""

    seed: int
    problem: str
    params: tuple
    level: int = 0

    @property
    def name(self) -> str:
        return f"random_friction_{self.seed}"


def _value(rng: np.random.Generator, spec):
    if isinstance(spec, list):
        return spec[int(rng.integers(len(spec)))]
    if spec[0] == "log":
        return float(np.exp(rng.uniform(np.log(spec[1]), np.log(spec[2]))))
    return float(rng.uniform(spec[0], spec[1]))


def draw(seed: int, level: int = 0) -> Draw:
    """The family's member ``seed`` (module docstring) at mesh ``level`` (the same options
    at every level: level 1 is the harder sample of the hard-case study).

    Raises
    ------
    ValueError
        For a negative ``seed``, or a ``level`` outside 0 .. :data:`MAX_LEVEL`.
    """
    if int(seed) != seed or seed < 0:
        raise ValueError(f"parameter 'seed': {seed!r} is not allowed; allowed: an integer >= 0")
    if int(level) != level or not 0 <= level <= MAX_LEVEL:
        raise ValueError(f"parameter 'level': {level!r} is not allowed; allowed: an integer "
                         f"0 .. {MAX_LEVEL}")
    rng = np.random.default_rng([int(seed), 65])
    dim = "3d" if rng.random() < SHARE_3D else "2d"
    params = {}
    for key, spec in RANGES.items():
        if isinstance(spec, dict):
            if dim not in spec:
                continue
            spec = spec[dim]
        params[key] = _value(rng, spec)
    problem = "cube_sphere" if dim == "3d" else "circle_square"
    return Draw(int(seed), problem, tuple(sorted(params.items())), int(level))
