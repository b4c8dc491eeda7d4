"""Hertz-Mindlin contact isolated, 3D: a paraboloidal tip pressed onto a block, both
graded towards the contact, their contact faces on one grid (the suite's own scene).

Built to check the 3D contact against Hertz (Johnson, *Contact Mechanics*, 1985, Sect.
4.2) and Cattaneo-Mindlin (Sects. 7.1-7.2) without cube-sphere's geometry in the way
(:mod:`problems.cube_sphere`: a ball of radius 0.866 on a unit cube, contact radius
a ~ 0.27, so a/R and a over the cube's size are both ~ 0.3; the ball's unstructured
surface lies on the cube's structured grid with no node in common, so the nodal forces
carry the beat of the two spacings, as on circle-square; the held cap bends the ball).
Here, in dimensionless units:

* the lower body, the block ``(-L, L)^2 x (-H, 0)``, stands clamped on its bottom face;
  its top face is the constrained surface, its nodes within ``core`` of the centre in x
  and y (where the contact reaches), one inequality each;
* the upper body, the tip, is the block ``(-L, L)^2 x (0, H)`` with its bottom face lifted
  to the paraboloid ``z = r^2 / (2 R)`` (``R = radius``; the lift fades linearly to zero
  at its top face): Hertz's gap, exact. Its top face is displaced by
  ``(shift, 0, -indent)``;
* both bodies have one tensor grid in x and y (Kuhn tetrahedra), so every constrained
  node has a node of the tip straight above it and its gap is the paraboloid's: no beat.
  The grid is uniform in the core ``|x|, |y| <= core``, with ``core_cells`` cells across
  its half-width on level 0, and in a layer half as deep on either side of the contact
  plane (:func:`depth_core`); outside, :data:`OUTER_CELLS` cells each twice as wide as
  the one before (:func:`half_axis`), so ``L = core + 30 core / core_cells`` (0.875 at
  the defaults) and ``H`` likewise from the layer (0.8);
* the default ``indent`` gives a contact radius a ~ 0.116: a/R ~ 0.1 and L ~ 7.5 a, a
  small contact on nearly half-spaces, inside the core (a contact that reaches the
  core's edge is cut off by it: a larger ``indent`` needs a larger ``core``).

Levels: level k halves the core's cells k times and splits the j-th outer cell into
``2^max(k - j, 0)`` (neighbouring cells differ by at most a factor of four), so the
meshes are nested (every new node is a midpoint of a coarse edge) and the work stays at
the contact: ``core_cells 2^k`` cells across the core's half-width, about 4.6 2^k
constrained nodes across the contact radius at the defaults. The prolongations are those
of the straight blocks, before the tip's lift (the same nodes and cells).

Friction (``friction``, ``mu``, ``shift``): the nodal P1 constraints' tangential rows
along x and y, the tip's top face moved along x by ``shift`` after the normal load
(:func:`problems.fem.two_body.frictional_two_body`). The bodies are of one material by
default (E = 1, nu = 0.3): the normal load then leaves no tangential traction between
them (Johnson Sect. 5.3), and Cattaneo-Mindlin's concentric zones apply. Left out: the
plane y = 0 is a symmetry plane of the tangential load, and a half model would cost half;
the tangential rows of its nodes would vanish there, so the scene stays whole.
"""
from __future__ import annotations

import numpy as np
from skfem import MeshTet

from problems.fem.mesh import Hierarchy, nested_prolongation, orient_positive
from problems.fem.surface import tensor_coarsening
from problems.fem.two_body import (Body, TwoBodyScene, assemble_two_body, friction_facets,
                                   friction_parameters, frictional_two_body)
from problems.qp import ContactQP, HertzSetup
from problems.spec import Options, Parameter, ProblemSpec
from reference.hertz import effective_modulus

#: Cells outside the core along each half-axis on level 0, each twice the one before
#: (the first twice the core's): the blocks' half-width and depth ``L = H = core +
#: 30 h0``, ``h0 = core / core_cells`` (0.9 at the defaults, six times the core).
OUTER_CELLS = 4


def extent(core: float, core_cells: int) -> float:
    """The blocks' half-width and depth (:data:`OUTER_CELLS`)."""
    return core + core / core_cells * (2.0 ** (OUTER_CELLS + 1) - 2.0)


def depth_core(core: float, core_cells: int) -> tuple[float, int]:
    """The core's depth below and above the contact plane and its cells: half the core's
    cells (at least one) of the same size. The stresses vary across the contact's
    radius in the plane but fall off with depth, so the layer of fine cells can be thin."""
    cells = max(core_cells // 2, 1)
    return core * cells / core_cells, cells


def half_axis(level: int, core: float, core_cells: int) -> np.ndarray:
    """Nodes of ``[0, L]`` on level ``level``: ``core_cells * 2^level`` equal cells on
    ``[0, core]``, then :data:`OUTER_CELLS` cells of widths ``2^j h0`` (``j = 1, 2, ...``),
    the ``j``-th split into ``2^max(level - j, 0)`` equal parts (adjacent cells differ by a
    factor of at most four). Nested: each level's nodes are the last's and midpoints of
    its cells."""
    h = core / core_cells
    coarse = np.concatenate([np.linspace(0.0, core, core_cells + 1),
                             core + h * (2.0 ** np.arange(2, OUTER_CELLS + 2) - 2.0)])
    splits = np.concatenate([np.full(core_cells, 2 ** level),
                             2 ** np.maximum(level - np.arange(1, OUTER_CELLS + 1), 0)])
    nodes = [np.linspace(a, b, s + 1)[:-1] for a, b, s in zip(coarse[:-1], coarse[1:], splits)]
    return np.concatenate(nodes + [coarse[-1:]])


def axis(level: int, core: float, core_cells: int) -> np.ndarray:
    """Nodes of ``[-L, L]``: :func:`half_axis` mirrored."""
    half = half_axis(level, core, core_cells)
    return np.concatenate([-half[:0:-1], half])


def block(level: int, core: float, core_cells: int, upper: bool):
    """The lower (``z <= 0``) or upper (``z >= 0``) block's tensor mesh on ``level``,
    before the upper one's bottom is lifted to the paraboloid."""
    x = axis(level, core, core_cells)
    z = half_axis(level, *depth_core(core, core_cells))
    z = z if upper else -z[::-1]
    m = MeshTet.init_tensor(x, x, z)
    pts = m.p.T.copy()
    return pts, orient_positive(pts, m.t.T)


def lifted(points: np.ndarray, radius: float) -> np.ndarray:
    """The upper block's points with its bottom face on ``z = r^2 / (2 R)``, the shift
    fading linearly to zero at its top face."""
    out = points.copy()
    r2 = points[:, 0] ** 2 + points[:, 1] ** 2
    out[:, 2] += r2 / (2.0 * radius) * (1.0 - points[:, 2] / points[:, 2].max())
    return out


def hierarchy(level: int, p: Options, upper: bool) -> Hierarchy:
    """A block's nested meshes, levels 0..``level`` (prolongations from the straight
    blocks, where each new node is a coarse edge's midpoint)."""
    meshes = [block(k, p.core, p.core_cells, upper) for k in range(level + 1)]
    P = [nested_prolongation(*meshes[k], meshes[k + 1][0]) for k in range(level)]
    points = [lifted(pts, p.radius) if upper else pts for pts, _ in meshes]
    return Hierarchy(points, [c for _, c in meshes], P)


def scene(level: int, p: Options) -> TwoBodyScene:
    """The scene up to mesh level ``level`` (module docstring)."""
    lower = Body("block", hierarchy(level, p, upper=False), p.E1, p.nu1, np.zeros(3))
    tip = Body("tip", hierarchy(level, p, upper=True), p.E2, p.nu2, np.zeros(3))
    tol = 1e-9
    L, H = extent(p.core, p.core_cells), extent(*depth_core(p.core, p.core_cells))

    def supports(points, body_of_node):
        bottom = np.flatnonzero((body_of_node == 0) & np.isclose(points[:, 2], -H))
        top = np.flatnonzero((body_of_node == 1) & np.isclose(points[:, 2], H))
        fixed = np.concatenate([3 * bottom + k for k in range(3)] + [3 * top + k for k in range(3)])
        values = np.concatenate([np.zeros(3 * len(bottom)), np.full(len(top), p.shift),
                                 np.zeros(len(top)), np.full(len(top), -p.indent)])
        return fixed, values

    def on_constrained(x):
        return (np.abs(x[:, 2]) < tol) & (np.abs(x[:, 0]) <= p.core + tol) \
            & (np.abs(x[:, 1]) <= p.core + tol)

    def on_opposing(c):
        return (c[:, 2] < 0.5 * H) & (np.abs(c[:, 0]) < L - tol) \
            & (np.abs(c[:, 1]) < L - tol)

    return TwoBodyScene(
        bodies=(lower, tip), constrained_body=0, supports=supports,
        on_constrained=on_constrained, on_opposing=on_opposing,
        direction=np.array([0.0, 0.0, 1.0]), search="along_direction",
        surface_coarsening=lambda x: tensor_coarsening(x[:, :2]),
        hertz=HertzSetup("point", p.radius, effective_modulus(p.E1, p.nu1, p.E2, p.nu2)),
        units="dimensionless")


def build(level: int, p: Options) -> ContactQP:
    """The scene's ContactQP at level ``level``; with friction, the first step of its
    load path (:func:`problems.fem.two_body.frictional_two_body`)."""
    friction_facets(p, 3)
    if p.friction != "none":
        return frictional_two_body(scene, level, p, "hertz_mindlin")
    return assemble_two_body(scene(level, p), level, name=f"hertz_mindlin level {level}")


PROBLEM = ProblemSpec(
    name="hertz_mindlin",
    summary="a paraboloidal tip pressed onto a block, 3D, both graded towards the contact "
            "and matched on it: Hertz and Cattaneo-Mindlin isolated (the suite's own)",
    kind="contact",
    levels=(0, 3),
    dim=3,
    default_level=1,
    parameters=(
        Parameter("radius", 1.0, "radius R of the tip's paraboloid z = r^2 / (2 R)",
                  low=0.2, high=20.0),
        Parameter("indent", 0.012, "prescribed downward displacement of the tip's top face",
                  low=0.0, high=0.1),
        Parameter("core", 0.125, "half-width of the uniformly meshed core around the contact "
                  "in x and y (the layer about the contact plane half as deep); the "
                  "constrained nodes lie in it, and so must the contact", low=0.02, high=0.5),
        Parameter("core_cells", 5, "cells across the core's half-width on level 0", low=1,
                  high=32, kind=int),
        Parameter("E1", 1.0, "Young's modulus of the block", low=0.0, low_open=True),
        Parameter("nu1", 0.3, "Poisson ratio of the block", low=-1.0, high=0.5, low_open=True,
                  high_open=True),
        Parameter("E2", 1.0, "Young's modulus of the tip", low=0.0, low_open=True),
        Parameter("nu2", 0.3, "Poisson ratio of the tip", low=-1.0, high=0.5, low_open=True,
                  high_open=True),
        *friction_parameters("the tip's top face", dim=3),
    ),
    build=build,
)
