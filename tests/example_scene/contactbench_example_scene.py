"""An external scene for contactbench: two parallel cylinders pressed together, 2D plane
strain (Hertz line contact of two cylinders, Johnson 1985, Sect. 4.2).

The template of the docs' "Add a scene" (docs/guide/add-a-scene.md): a function that builds
the scene's two bodies and supports (:class:`problems.fem.two_body.TwoBodyScene`), the
suite's assembly (:func:`problems.fem.two_body.assemble_two_body`) and couplings
(:func:`problems.fem.stabilised.couple`), and a ``ProblemSpec`` that the package registers
under the entry-point group ``contactbench.scenes``::

    [project.entry-points."contactbench.scenes"]
    cylinder_pair = "contactbench_example_scene:PROBLEM"

Scene (dimensionless units): the lower cylinder's upper half (radius ``R1``, the chord on
``y = 0``, clamped there); the upper cylinder (radius ``R2``, centre ``(0, R1 + R2)``,
touching the lower at ``(0, R1)``) held on its top arc, which is moved down by ``indent``.
The constrained surface is the lower cylinder's top cap; the opposing surface the upper
cylinder's lower half, searched along ``n = (0, 1)`` (Alg. 7.1, case b). The mortar
couplings project both surfaces onto a straight edge, which a curved cap is not: the scene
offers the nodal, stabilised and two-pass couplings only.

Nesting: the constrained surface of level ``k + 1`` must refine that of level ``k`` (the
multilevel solvers restrict and prolong along it). Refinement puts every new boundary node
of an arc on the circle between its two parents, so a cap cut at a node of the coarsest mesh
stays one cap at every level: :func:`cap_angles` snaps the requested cap to those nodes on
either side.
"""
from __future__ import annotations

import numpy as np

from problems.fem.mesh import disk_hierarchy, half_disk_hierarchy
from problems.fem.stabilised import COUPLINGS, MORTAR_COUPLINGS, couple, coupling_parameters
from problems.fem.two_body import Body, TwoBodyScene, assemble_two_body
from problems.qp import ContactQP, HertzSetup
from problems.spec import Options, Parameter, ProblemSpec
from reference.hertz import effective_modulus

#: Coarsest mesh size relative to the radius (about 400 nodes per cylinder at level 0).
MAXH = 0.1


def polar_from_top(points: np.ndarray, center: np.ndarray) -> np.ndarray:
    """Each point's signed angle (degrees, positive towards +x) from the upward vertical
    through ``center``."""
    rel = points - center
    return np.degrees(np.arctan2(rel[:, 0], rel[:, 1]))


def cap_angles(coarse: np.ndarray, center: np.ndarray, radius: float,
               wanted: float) -> tuple[float, float]:
    """The cap ``[low, high]`` (signed angles from the top) cut at the boundary nodes of
    the coarsest mesh ``coarse`` nearest inside ``[-wanted, wanted]``, on each side: a cap
    cut there is nested under refinement."""
    on = np.isclose(np.linalg.norm(coarse - center, axis=1), radius, rtol=1e-9)
    angles = polar_from_top(coarse[on], center)
    return (float(angles[angles >= -wanted - 1e-9].min()),
            float(angles[angles <= wanted + 1e-9].max()))


def scene(level: int, p: Options) -> TwoBodyScene:
    """The two cylinders up to mesh level ``level`` (see the module docstring)."""
    low_c, up_c = np.array([0.0, 0.0]), np.array([0.0, p.R1 + p.R2])
    lower = Body("lower", half_disk_hierarchy(low_c, p.R1, level, MAXH * p.R1, side="upper"),
                 p.E1, p.nu1, np.zeros(2))
    upper = Body("upper", disk_hierarchy(up_c, p.R2, level, MAXH * p.R2), p.E2, p.nu2,
                 np.zeros(2))
    cap_low, cap_high = cap_angles(lower.meshes.points[0], low_c, p.R1, p.cap)

    def supports(points, body_of_node):
        chord = np.flatnonzero((body_of_node == 0) & np.isclose(points[:, 1], low_c[1],
                                                                atol=1e-12 * p.R1))
        on_upper = (body_of_node == 1) & np.isclose(np.linalg.norm(points - up_c, axis=1),
                                                    p.R2, rtol=1e-9)
        top = np.flatnonzero(on_upper & (np.abs(polar_from_top(points, up_c)) <= p.held_arc))
        fixed = np.concatenate([2 * chord, 2 * chord + 1, 2 * top, 2 * top + 1])
        values = np.concatenate([np.zeros(2 * len(chord) + len(top)),
                                 np.full(len(top), -p.indent)])
        return fixed, values

    def on_cap(x):
        angle = polar_from_top(x, low_c)
        on_arc = np.isclose(np.linalg.norm(x - low_c, axis=1), p.R1, rtol=1e-9)
        return on_arc & (np.abs(np.clip(angle, cap_low, cap_high) - angle) <= 1e-9)

    return TwoBodyScene(
        bodies=(lower, upper), constrained_body=0, supports=supports,
        on_constrained=on_cap, on_opposing=lambda c: c[:, 1] < up_c[1],
        direction=np.array([0.0, 1.0]),
        hertz=HertzSetup("line", p.R1 * p.R2 / (p.R1 + p.R2),
                         effective_modulus(p.E1, p.nu1, p.E2, p.nu2)),
        units="dimensionless")


def build(level: int, p: Options) -> ContactQP:
    """The cylinder pair's ContactQP at uniform level ``level``, in its coupling."""
    return couple(assemble_two_body(scene(level, p), level, name=f"cylinder_pair level {level}"),
                  p)


PROBLEM = ProblemSpec(
    name="cylinder_pair",
    summary="two parallel cylinders pressed together, 2D plane strain (Hertz line contact); "
            "the lower cylinder's top cap is the constrained surface",
    kind="contact",
    levels=(0, 4),
    default_level=1,
    parameters=(
        Parameter("R1", 0.5, "radius of the lower cylinder", low=0.1, high=2.0),
        Parameter("R2", 0.5, "radius of the upper cylinder", low=0.1, high=2.0),
        Parameter("E1", 1.0, "Young's modulus of the lower cylinder", low=0.0, low_open=True),
        Parameter("nu1", 0.3, "Poisson ratio of the lower cylinder", low=-1.0, high=0.5,
                  low_open=True, high_open=True),
        Parameter("E2", 1.0, "Young's modulus of the upper cylinder", low=0.0, low_open=True),
        Parameter("nu2", 0.3, "Poisson ratio of the upper cylinder", low=-1.0, high=0.5,
                  low_open=True, high_open=True),
        Parameter("indent", 0.02, "prescribed downward displacement of the upper cylinder's "
                  "held arc", low=0.0, high=0.1),
        Parameter("held_arc", 45.0, "half-angle (degrees) of the upper cylinder's held arc",
                  low=5.0, high=80.0),
        Parameter("cap", 40.0, "half-angle (degrees) of the constrained cap (snapped down to a "
                  "node of the coarsest mesh)", low=5.0, high=60.0),
        *coupling_parameters(tuple(c for c in COUPLINGS if c not in MORTAR_COUPLINGS)),
    ),
    build=build,
)
