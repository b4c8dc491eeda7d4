"""Contact between a circle and a square, 2D plane strain (thesis Sect. 9.1).

Scene (dimensionless units, as in the thesis):

* the square Omega^1 = (0, 1)^2, E1 = 1, nu1 = 0.3, clamped on its bottom edge
  y = 0;
* the circle Omega^2 of radius R = 0.707 (the thesis's 0.707), E2 = 1,
  nu2 = 0.3, centred at (0.5, 1 + R + gap), i.e. touching the square at (0.5, 1)
  for ``gap = 0``;
* the constrained surface is the square's whole top edge (one inequality per
  node: N^C = 33 at level 1, as in Table 9.1); the opposing surface is the
  circle's lower half, searched along n = (0, 1) (case b, the default) or by
  closest point (case a).

Where the thesis and we differ, and why (DESIGN.md, "known gaps"):

* Sect. 9.1 prints the circle at C(0.5, 2.5; 0.707), which leaves a gap of 0.79
  that a body force of 0.01 on a body with E = 1 never closes. We put the circle
  on the square (``gap`` = 0 by default), which also fits the thesis's node
  counts.
* Load path. With the body force on both bodies and the circle hung from its
  upper arc, the square sinks under its own weight almost as fast as the circle
  and only a small part of the circle's weight passes through the contact. We
  therefore drive the contact by the circle alone: its upper arc
  (polar angle within ``held_arc`` degrees of the top) is displaced downwards by
  ``indent`` (a prescribed support displacement, like a press), and the body force
  (0, -``load``) acts on the circle only; the square carries no body force (its
  own weight would only pre-stress it and pass to its clamped bottom edge). The
  default ``indent`` = 0.017 makes the contact half-width a ~ 0.1, i.e. about 13
  square cells at level 3 (h = 1/128) and 3 cells at level 1 (0.012 gave
  a = 0.085, 10.8 cells at level 3: too close to the 8-10 cells asked for).

Levels: level L has a structured square with (16 * 2^L)^2 cells (33^2 nodes at
level 1) and a netgen mesh of the disk (maxh 0.05, 810 nodes) refined L times
uniformly with its new boundary nodes projected onto the circle, so the circle's
boundary nodes lie on the circle at every level. Total nodes: 1099, 4237, 16636,
65926, 262,8xx, ~1.05M for L = 0..5 (thesis: 4226, 16642, 66050, 263170).

Friction (``friction``, ``mu``, ``shift``; beyond the thesis, which is frictionless): each
constrained node gets a tangential row, the same interpolation (Alg. 7.1) as its normal
row along its unit tangent ((1, 0) for n = (0, 1)), and Tresca or Coulomb friction on it
(:class:`problems.friction.data.Friction`). The load path is the normal load (the press) and then the
tangential step, the held arc moved along x by ``shift``
(:func:`problems.fem.two_body.frictional_two_body`); nodal P1 rows only.

Couplings (``coupling``, :data:`problems.fem.stabilised.COUPLINGS`): the nodal
constraints of Alg. 7.1 on the square's top edge (the thesis's one pass, the default);
``stabilised``, the penalised reverse rows of Sect. 7.5; ``two_pass``, the same reverse
rows hard (:func:`problems.fem.stabilised.two_pass`): every node of the circle's lower
half is kept out of the square too. On the curved surface the circle's nodes seldom
lie above a square node, so the two passes' rows stay independent (level 0: B of 39
rows and rank 39); the pressure is the force on the square's nodes over their lumped
mass (:func:`problems.qp.surface_multipliers`). ``mortar`` and ``mortar_dual``
(:mod:`problems.fem.mortar`): the weighted gaps of the mortar method over the square's
straight top edge and the circle's chords projected onto it along n = (0, 1), with
standard or dual (Wohlmuth) multipliers; the dual rows are node-wise. The pressure is
the multiplier over the lumped mass.
"""
from __future__ import annotations

import numpy as np

from problems.fem.contact import RENAMED_SEARCHES, SEARCHES
from problems.fem.mesh import (Hierarchy, disk_hierarchy, nested_prolongation,
                               structured_rectangle)
from problems.fem.stabilised import COUPLING_PARAMETERS, check_coupling, couple
from problems.fem.surface import tensor_coarsening
from problems.fem.two_body import (ELEMENT_DEGREE, Body, TwoBodyScene, assemble_two_body,
                                   friction_parameters, frictional_two_body)
from problems.qp import ContactQP, HertzSetup
from problems.spec import Options, Parameter, ProblemSpec
from reference.hertz import effective_modulus

DISK_MAXH = 0.05


def square_meshes(level: int, cells: int = 16, height: float = 1.0) -> Hierarchy:
    """Structured rectangles (1 x ``height``) with ``cells * 2^k`` cells along x and
    as many along y as keep them about square (at least one), k = 0..level, nested.

    Level k+1 is not numbered as the red refinement of level k, so the
    prolongation is found by matching coordinates.
    """
    nx = [cells * 2 ** k for k in range(level + 1)]
    ny = [max(1, round(cells * height)) * 2 ** k for k in range(level + 1)]
    pts, cells = zip(*[structured_rectangle(a, b, width=1.0, height=height) for a, b in zip(nx, ny)])
    P = [nested_prolongation(pts[k], cells[k], pts[k + 1]) for k in range(level)]
    return Hierarchy(list(pts), list(cells), P)


def scene(level: int, p: Options) -> TwoBodyScene:
    """The circle-square scene up to mesh level ``level`` (see the module docstring)."""
    H = p.height
    center = np.array([p.offset, H + p.radius + p.gap])
    square = Body("square", square_meshes(level, p.square_cells, H), p.E1, p.nu1, np.zeros(2))
    circle = Body("circle", disk_hierarchy(center, p.radius, level,   # ~810 nodes at level 0
                                           DISK_MAXH * p.radius / 0.707), p.E2, p.nu2,
                  np.array([0.0, -p.load]))
    bodies = (square, circle) if p.order == "square_first" else (circle, square)
    sq = bodies.index(square)

    def supports(points, body_of_node):
        is_sq = body_of_node == sq
        bottom = np.flatnonzero(is_sq & np.isclose(points[:, 1], 0.0))
        rel = points - center
        on_circle = ~is_sq & np.isclose(np.linalg.norm(rel, axis=1), p.radius, rtol=1e-9)
        top_cos = p.radius * np.cos(np.radians(p.held_arc)) - 1e-12
        held = np.flatnonzero(on_circle & (rel[:, 1] >= top_cos))
        fixed = np.concatenate([2 * bottom, 2 * bottom + 1, 2 * held, 2 * held + 1])
        values = np.concatenate([np.zeros(2 * len(bottom)), np.full(len(held), p.shift),
                                 np.full(len(held), -p.indent)])
        return fixed, values

    return TwoBodyScene(
        bodies=bodies, constrained_body=sq, supports=supports,
        on_constrained=lambda x: np.isclose(x[:, 1], H),            # the square's top edge
        on_opposing=lambda c: c[:, 1] < center[1],                   # the circle's lower half
        direction=np.array([0.0, 1.0]), search=p.search,
        surface_coarsening=lambda x: tensor_coarsening(x[:, :1]),   # the top edge is a line
        hertz=HertzSetup("line", p.radius, effective_modulus(p.E1, p.nu1, p.E2, p.nu2)),
        units="dimensionless")


def build(level: int, p: Options) -> ContactQP:
    """The circle-square ContactQP at uniform level ``level`` (see module docstring);
    with friction, the first step of its load path
    (:func:`problems.fem.two_body.frictional_two_body`)."""
    check_coupling(p)
    if p.friction != "none":
        return frictional_two_body(scene, level, p, "circle_square")
    return couple(assemble_two_body(scene(level, p), level, degree=p.degree,
                                    name=f"circle_square level {level}" + (" P2" if p.degree == 2 else "")),
                  p)


PROBLEM = ProblemSpec(
    name="circle_square",
    summary="circle pressed onto a square, 2D plane strain; the square's top edge is the "
            "constrained surface (thesis Sect. 9.1, Table 9.1)",
    kind="contact",
    levels=(0, 6),
    default_level=1,
    parameters=(
        Parameter("radius", 0.707, "circle radius", low=0.05, high=5.0),
        Parameter("gap", 0.0, "initial gap between circle and square at the closest point "
                  "(negative: initial penetration)", low=-0.05, high=0.5),
        Parameter("offset", 0.5, "x of the circle's centre (1.0: grazing contact at the end of "
                  "the constrained edge)", low=-0.5, high=1.5),
        Parameter("height", 1.0, "height of the square (0.02: a thin plate, aspect ratio 1:50)",
                  low=0.01, high=2.0),
        Parameter("square_cells", 16, "the square's cells per unit length at level 0 (mesh-size "
                  "ratio across the contact: 16 ~ the circle's; 2 ~ 8x coarser)", low=2,
                  high=256, kind=int),
        Parameter("E1", 1.0, "Young's modulus of the square", low=0.0, low_open=True),
        Parameter("nu1", 0.3, "Poisson ratio of the square", low=-1.0, high=0.5, low_open=True,
                  high_open=True),
        Parameter("E2", 1.0, "Young's modulus of the circle", low=0.0, low_open=True),
        Parameter("nu2", 0.3, "Poisson ratio of the circle", low=-1.0, high=0.5, low_open=True,
                  high_open=True),
        Parameter("load", 0.01, "body-force magnitude on the circle (acts in -y)", low=0.0),
        Parameter("indent", 0.017, "prescribed downward displacement of the circle's held arc",
                  low=0.0, high=0.2),
        Parameter("held_arc", 60.0, "half-angle (degrees) of the circle's held upper arc", low=5.0,
                  high=90.0),
        Parameter("search", "along_direction", "opposing point (Alg. 7.1): along_direction = along n = (0, 1) "
                  "(case b), closest_point = closest point (case a)", choices=SEARCHES,
                  renamed=RENAMED_SEARCHES),
        Parameter("order", "square_first", "bodies' order in memory (a solution must not depend on it)",
                  choices=("square_first", "circle_first")),
        ELEMENT_DEGREE,
        *COUPLING_PARAMETERS,
        *friction_parameters("the circle's held arc"),
    ),
    build=build,
    thesis_tables={"augmented_projection": "table_9_1", "adaptive": "table_9_2"},
)
