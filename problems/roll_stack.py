"""The roll stack of a four-high rolling mill, 3D, in SI units (thesis Sect. 9.3, Figs. 9.10-9.16).

Scene (the issue's specification; the same geometry as the beam reference
:class:`reference.roll_stack.RollStack`, whose conventions it follows): ``x`` along
the rolls (``x = 0`` at the mill centre), ``y`` the rolling direction, ``z`` up.

* Work roll (WR, the constrained body): axis on ``z = 0``; barrel of length 2.00 m
  and radius ``r(x) = 0.35 m - (crown / 2) (x / 1 m)^2`` (a parabolic crown of 150 um
  on the diameter, :meth:`RollStack.crown_drop`); necks of diameter 0.42 m up to the
  bearing centres at ``|x| = 1.45 m``, which carry nothing (the roll floats).
* Backup roll (BUR, the opposing body): axis on ``z = 0.35 + 0.75 m`` (touching the
  work roll at the crown's apex), barrel 1.90 m long, radius 0.75 m minus the linear
  edge relief of :meth:`RollStack.relief_drop` (0.5 mm over the last 50 mm); necks of
  diameter 1.00 m up to the bearing centres at ``|x| = 1.55 m``, held there: ``u_z =
  u_y = 0`` on the neck's end face (a simple support: the face may rotate about ``y``).
* E = 220 GPa, nu = 0.3 on both; gravity 7.66e4 N/m^3 (the thesis's
  ``f = (0, 0, -76.6e-6)`` in N/mm^3) on both rolls.
* The strip presses the work roll upward over ``|x| <= L/2 = 0.5 m`` with a uniform
  vertical traction over a bite of width ``bite`` (40 mm) in ``y`` on the roll's
  underside, scaled so that its resultant is exactly the strip force ``force``
  (15 MN or 30 MN, the thesis's "15 and 30 KN" read as kN/mm over L = 1 m).
* Contact: one inequality per node of the work roll's barrel surface in the band
  ``|y| <= band`` on top (case b of Alg. 7.1 along ``n = (0, 0, 1)``), against the
  backup roll's lower barrel surface. Nodes whose ray misses the backup barrel
  (beyond its end) carry no constraint.
* The work roll's remaining rigid motion (vertical translation; in the half model also
  the ``y`` translation and the spin about its axis) is removed by weak grounded
  springs (``u_y``, ``u_z``) on the nodes of its neck end faces, ``spring * E * R_w``
  per node (force per length): the spring force is reported by
  :func:`problems.fem.two_body.spring_forces` and is 1.5e-5 to 5.4e-5 of the strip force
  at levels 0-3 (tested below 1e-4). The springs leave ``A`` nearly singular (the
  work roll's vertical translation has a Rayleigh quotient of ~7e-10 of the diagonal):
  solvers that factorise ``A`` must keep that mode apart
  (:func:`problems.floating.floating_modes`, :class:`solvers.kernels.cholesky.FloatingCholesky`; the
  exact PDAS does), otherwise the contact solution is a difference of metre-sized
  rigid motions. Stiffer springs are no cure: the spring force is their stiffness times
  the roll's rigid rise (~0.3-0.5 mm), so 1e-4 of the strip force allows at most ~2x
  the present stiffness, which changes the conditioning by as little.

Model: ``model="quarter"`` (default) keeps ``x >= 0, y >= 0`` with the symmetry
conditions ``u_x = 0`` on ``x = 0`` and ``u_y = 0`` on ``y = 0``; ``model="half"``
keeps ``x >= 0`` (the full cross-section), for the symmetry check. Reported forces
of a quarter model are a quarter of the stack's.

Units: ``units="m"`` (m, N, Pa; default) or ``"mm"`` (mm, N, MPa): every length is
multiplied by 1000, E by 1e-6 and the weight density by 1e-9; nothing else changes
(the tests compare the sag in metres).

Mesh (mapped, the same cross-section along each roll): the cross-section (a half
disk for the quarter model, the mirrored disk for the half model) is a Delaunay
triangulation of the corners of a quadtree whose boxes are split until their side is
at most the mesh-size law

    h(d) = min(h_max, h_c + g max(0, d_c - w),  h_b + g max(0, d_b - bite / 2)),

``d_c`` the distance from the contact point (top of the work roll, bottom of the
backup roll), ``d_b`` that from the bite centre (work roll only), ``g = 0.25``,
``w = band`` (the contact band is uniformly fine), ``h_b = max(h_c, bite / 8)`` and
``h_max = R / 8``; the boundary nodes are spaced by the same law on the true circle.
Level ``L`` has ``h_c = 8 mm / 2^L`` (the spacing of the surface nodes across the contact
line: 8, 4, 2, 1 mm at levels 0-3). The section is placed
at every ``x`` layer scaled radially to the roll's radius there (crown, relief, necks;
every surface node lies on the true surface of revolution), and each prism between
layers is split into three tetrahedra (conforming: each quad face is cut from its
lowest-numbered bottom node). The ``x`` layers are uniform between the break points
(0, the strip edge, the relief's start, barrel ends, shoulder ends, bearing centres)
with spacing ``dx = 0.2 m / 2^L`` (levels 0-3: 200, 100, 50, 25 mm): the tetrahedra are
long in ``x`` (where the solution varies slowly) and fine across the contact line.
The shoulder from barrel to neck is a cone 50 mm long (a sharp step is not a surface of
revolution that one section can map onto; the beam reference has the step at the barrel
end).

Node counts (quarter model; measured): 5,969 / 13,732 / 34,316 / 109,166 at levels 0-3
(sections of 312/469/618/964 and 259/346/493/830 nodes on 10/16/30/59 and 11/18/32/63
layers). The contact width ``2 b`` at the barrel centre (b = 5.1 mm at 15 MN, 7.2 mm at
30 MN for the beam reference's line load there) is crossed by 0 / 2 / 4 / 10 cells
(15 MN) and 0 / 2 / 6 / 14 cells (30 MN) at levels 0-3: level 3 resolves it. The thesis
used 46,611 nodes and 7,089 inequalities.

Levels are separate meshes, not refinements of each other: no prolongations are
supplied. The P1 scene supplies its layers instead (``multilevel.extrusion``,
:func:`problems.fem.mesh.extrusion_layers`), and the V-cycles of the multigrid-preconditioned
solvers coarsen along ``x`` and smooth whole sections
(:func:`solvers.kernels.multigrid.layered_hierarchy`): the tetrahedra are up to 25:1 long
in ``x``, where pointwise smoothing with algebraic
coarsening (smoothed aggregation, still the P2 scene's) leaves ``kappa(V A)`` large (the
roll-stack study's page). The constrained surface has one level: the band is 25:1
anisotropic too, and a tensor coarsening of it leaves ``kappa(S-hat^-1 S_in)`` far above
:data:`solvers.augmented_projection.SCHUR_KAPPA_LIMIT` (docs/guide/measurements.md), so
the augmented projection's ``schur=auto`` takes ``S_in``.

Left out: friction and the rolls' horizontal offset; the strip's plastic response
(its pressure is a given uniform traction); the work roll's bearing/bending forces;
thermal crown and wear; the step between barrel and neck (a 50 mm cone).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import Delaunay

from problems.fem.elasticity import boundary_facets
from problems.fem.mesh import Hierarchy, extrusion_layers, orient_positive
from problems.fem.two_body import (ELEMENT_DEGREE, Body, Springs, Traction, TwoBodyScene,
                                   assemble_two_body)
from problems.qp import ContactQP, HertzSetup
from problems.spec import Options, Parameter, ProblemSpec
from reference.hertz import effective_modulus
from reference.roll_stack import RollStack

#: Length factor and the factors of E and of the weight density per unit system.
UNITS = {"m": (1.0, 1.0, 1.0), "mm": (1e3, 1e-6, 1e-9)}
GRADING = 0.25
CONTACT_H0 = 8e-3            # h_c at level 0, m
DX0 = 0.2                    # x-layer spacing at level 0, m
SHOULDER = 0.05              # length of the conical shoulder barrel -> neck, m


@dataclass(frozen=True)
class Section:
    """A triangulated cross-section of unit scale: ``points`` (n, 2) as (y, zeta), where
    ``zeta`` points from the axis towards the contact line; ``triangles`` (t, 3)."""

    points: np.ndarray
    triangles: np.ndarray

    def node(self, y: float, zeta: float) -> int:
        """Index of the node at ``(y, zeta)`` (the nearest)."""
        return int(np.argmin(np.hypot(self.points[:, 0] - y, self.points[:, 1] - zeta)))


def size_law(p: np.ndarray, R: float, h_c: float, band: float, bite: float | None) -> np.ndarray:
    """The mesh-size law of the module docstring at points ``p`` (n, 2) of a section of
    radius ``R`` (contact point at ``(0, R)``, bite centre at ``(0, -R)``)."""
    d_c = np.hypot(p[:, 0], p[:, 1] - R)
    h = h_c + GRADING * np.maximum(0.0, d_c - band)
    if bite is not None:
        d_b = np.hypot(p[:, 0], p[:, 1] + R)
        h = np.minimum(h, max(h_c, bite / 8) + GRADING * np.maximum(0.0, d_b - bite / 2))
    return np.minimum(h, R / 8)


def half_disk_section(R: float, h_c: float, band: float, bite: float | None = None,
                      full: bool = False) -> Section:
    """Graded triangulation of the half disk ``y >= 0`` (or, ``full``, the disk mirrored
    about ``y = 0``) of radius ``R`` (see the module docstring).

    Boundary nodes lie on the circle and on the axis ``y = 0`` (the centre is a node).
    """
    law = lambda q: size_law(q, R, h_c, band, bite)          # noqa: E731
    depth = int(np.ceil(np.log2(R / (h_c / 2))))
    unit = R / 2 ** depth                                     # integer grid of box corners
    boxes = [(0, -2 ** depth, 2 ** depth), (0, 0, 2 ** depth)]   # (y0, z0, size) in units
    corners = set()
    while boxes:
        y0, z0, s = boxes.pop()
        lo, hi = np.array([y0, z0]) * unit, np.array([y0 + s, z0 + s]) * unit
        if np.hypot(*np.clip([0.0, 0.0], lo, hi)) > R:          # box outside the disk
            continue
        near = np.array([np.clip([0.0, R], lo, hi), np.clip([0.0, -R], lo, hi)])
        if s > 1 and s * unit > law(near).min():
            h2 = s // 2
            boxes += [(y0, z0, h2), (y0 + h2, z0, h2), (y0, z0 + h2, h2), (y0 + h2, z0 + h2, h2)]
            continue
        corners.update({(y0, z0), (y0 + s, z0), (y0, z0 + s), (y0 + s, z0 + s)})
    c = np.array(sorted(corners), dtype=float) * unit
    margin = 0.55 * law(c)
    inner = c[(c[:, 0] > margin) & (np.hypot(*c.T) < R - margin)]
    axis = c[(c[:, 0] == 0) & (np.abs(c[:, 1]) < R - margin)]
    # the arc from the contact point (theta = 0) to the bite (theta = pi), spaced by the law
    theta = [0.0]
    while theta[-1] < np.pi:
        t = theta[-1]
        theta.append(t + law(np.array([[R * np.sin(t), R * np.cos(t)]]))[0] / R)
    theta = np.array(theta)
    theta = theta * (np.pi / theta[-1])           # stretch the last step onto pi
    if bite is not None:                          # a node at the bite's edge
        tb = np.pi - np.arcsin(bite / 2 / R)
        theta[np.argmin(np.abs(theta - tb))] = tb
        theta = np.unique(theta)
    arc = np.column_stack([R * np.sin(theta), R * np.cos(theta)])
    arc[[0, -1], 0] = 0.0
    pts = np.vstack([arc, axis, inner])
    tri = Delaunay(pts).simplices
    area = _area(pts, tri)
    tri = tri[area > 1e-10 * R ** 2]
    if full:
        n = len(pts)
        mirror = np.flatnonzero(pts[:, 0] > 0)
        image = np.arange(n)
        image[mirror] = n + np.arange(len(mirror))
        pts = np.vstack([pts, pts[mirror] * [-1.0, 1.0]])
        tri = np.vstack([tri, image[tri][:, ::-1]])
    tri = np.where(_area(pts, tri)[:, None] < 0, tri[:, ::-1], tri)
    expected = np.pi * R ** 2 / (1 if full else 2)
    if not (np.isclose(np.abs(_area(pts, tri)).sum(), expected, rtol=5e-3)
            and len(np.unique(tri)) == len(pts)):
        raise RuntimeError("the section triangulation does not cover the disk")
    return Section(pts, tri)


def _area(pts: np.ndarray, tri: np.ndarray) -> np.ndarray:
    a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))


def x_layers(breaks, dx: float) -> np.ndarray:
    """Nodes from 0 to ``max(breaks)``: every break point, uniform (spacing <= dx) between."""
    b = np.unique(np.concatenate([[0.0], np.asarray(breaks, dtype=float)]))
    parts = [np.linspace(a, c, max(1, int(np.ceil((c - a) / dx - 1e-9))) + 1)[:-1]
             for a, c in zip(b[:-1], b[1:])]
    return np.concatenate(parts + [b[-1:]])


def extrude(section: Section, x: np.ndarray, radius: np.ndarray, R: float, z_axis: float,
            sign: float) -> tuple[np.ndarray, np.ndarray]:
    """A roll: the section (radius ``R``) at every layer ``x[j]``, scaled to ``radius[j]``;
    ``sign = +1`` puts the section's contact point on top, ``-1`` at the bottom.

    Returns ``(points, tets)``, tets positively oriented.
    """
    n2 = len(section.points)
    s = (np.asarray(radius) / R)[:, None, None]
    yz = section.points[None] * s
    pts = np.concatenate([np.broadcast_to(np.asarray(x)[:, None, None], (len(x), n2, 1)),
                          yz[..., :1], z_axis + sign * yz[..., 1:]], axis=2).reshape(-1, 3)
    t = np.sort(section.triangles, axis=1)
    a, b, c = t.T
    tets = []
    for j in range(len(x) - 1):
        lo, up = j * n2, (j + 1) * n2
        tets += [np.column_stack([a + lo, b + lo, c + lo, c + up]),
                 np.column_stack([a + lo, b + lo, b + up, c + up]),
                 np.column_stack([a + lo, a + up, b + up, c + up])]
    return pts, orient_positive(pts, np.vstack(tets))


def stack_geometry(p: Options) -> RollStack:
    """The :class:`RollStack` in the scene's unit system."""
    ell, fE, fg = UNITS[p.units]
    base = RollStack(work_crown=p.crown)
    return RollStack(**{**{k: getattr(base, k) * ell for k in (
        "work_diameter", "work_barrel_length", "work_crown", "work_neck_diameter",
        "work_bearing_span", "backup_diameter", "backup_barrel_length", "backup_chamfer_length",
        "backup_chamfer_depth", "backup_neck_diameter", "backup_bearing_span", "strip_width")},
        "E": p.E * fE, "nu": p.nu, "weight_density": p.weight_density * fg})


def roll_meshes(level: int, p: Options):
    """Work roll and backup roll meshes ``(points, tets)`` at ``level`` (module docstring)."""
    ell = UNITS[p.units][0]
    s = stack_geometry(Options({**p.flat(), "units": "m"}))   # meshed in m, then scaled
    Rw, Rb = s.work_diameter / 2, s.backup_diameter / 2
    h_c, dx = CONTACT_H0 / 2 ** level, DX0 / 2 ** level
    band, bite = p.band, p.bite
    full = p.model == "half"
    sec_w = half_disk_section(Rw, h_c, band, bite, full)
    sec_b = half_disk_section(Rb, h_c, band, None, full)
    sh = SHOULDER
    bw, bb = s.work_barrel_length / 2, s.backup_barrel_length / 2
    xw = x_layers([s.strip_width / 2, bw, bw + sh, s.work_bearing_span / 2], dx)
    xb = x_layers([bb - s.backup_chamfer_length, bb, bb + sh, s.backup_bearing_span / 2], dx)
    rw = _radius(xw, Rw, bw, s.work_neck_diameter / 2, s.crown_drop, sh)
    rb = _radius(xb, Rb, bb, s.backup_neck_diameter / 2, s.relief_drop, sh)
    (pw, cw), (pb, cb) = (extrude(sec_w, xw, rw, Rw, 0.0, 1.0),
                          extrude(sec_b, xb, rb, Rb, Rw + Rb, -1.0))
    return (pw * ell, cw), (pb * ell, cb), (sec_w, xw * ell), (sec_b, xb * ell)


def _radius(x, R, barrel_half, neck_r, drop, shoulder):
    x = np.asarray(x, dtype=float)
    on_barrel = x <= barrel_half * (1 + 1e-12)
    r_barrel = R - np.nan_to_num(drop(np.where(on_barrel, x, 0.0)))
    r_end = R - float(drop(barrel_half))
    t = np.clip((x - barrel_half) / shoulder, 0.0, 1.0)
    return np.where(on_barrel, r_barrel, r_end + t * (neck_r - r_end))


def scene(level: int, p: Options) -> TwoBodyScene:
    """The roll-stack scene at mesh level ``level`` (see the module docstring)."""
    ell, fE, fg = UNITS[p.units]
    s = stack_geometry(p)
    Rw, Rb = s.work_diameter / 2, s.backup_diameter / 2
    (pw, cw), (pb, cb), _, _ = roll_meshes(level, p)
    E = p.E * fE
    gamma = np.array([0.0, 0.0, -p.weight_density * fg])
    work = Body("work_roll", Hierarchy([pw], [cw], []), E, p.nu, gamma)
    backup = Body("backup_roll", Hierarchy([pb], [cb], []), E, p.nu, gamma)
    x_wb, x_bb = s.work_bearing_span / 2, s.backup_bearing_span / 2
    bw, bb = s.work_barrel_length / 2, s.backup_barrel_length / 2
    tol = 1e-9 * ell
    quarter = p.model == "quarter"
    band, bite, L = p.band * ell, p.bite * ell, s.strip_width

    def supports(points, body_of_node):
        on_x0 = np.flatnonzero(np.abs(points[:, 0]) < tol)
        fixed = [3 * on_x0]
        if quarter:
            fixed.append(3 * np.flatnonzero(np.abs(points[:, 1]) < tol) + 1)
        bearing = np.flatnonzero((body_of_node == 1) & (np.abs(points[:, 0] - x_bb) < tol))
        fixed += [3 * bearing + 1, 3 * bearing + 2]
        fixed = np.unique(np.concatenate(fixed))
        return fixed, np.zeros(len(fixed))

    def on_constrained(x):
        r = np.hypot(x[:, 1], x[:, 2])
        on_surface = r >= _radius(x[:, 0], Rw, bw, s.work_neck_diameter / 2, s.crown_drop,
                                  SHOULDER * ell) * (1 - 1e-9)
        return on_surface & (x[:, 0] <= bw + tol) & (np.abs(x[:, 1]) <= band + tol) & (x[:, 2] > 0)

    # facets are selected by centroid; the symmetry plane x = 0 is a boundary of the model
    # but not a surface of the rolls (its facets' centroids lie on x = 0, the barrel's
    # facets' beyond it): neither the strip nor the contact acts there
    def on_opposing(c):
        r = np.hypot(c[:, 1], c[:, 2] - (Rw + Rb))
        return (c[:, 0] > tol) & (c[:, 0] <= bb + tol) & (r > 0.99 * Rb) & (c[:, 2] < Rw + Rb)

    def in_bite(c):
        return ((c[:, 0] > tol) & (c[:, 0] <= L / 2 + tol) & (np.abs(c[:, 1]) <= bite / 2 + tol)
                & (c[:, 2] < -0.9 * Rw))

    # the traction giving the strip force exactly on the selected facets
    facets = boundary_facets(cw, pw)
    facets = facets[in_bite(pw[facets].mean(axis=1))]
    v = pw[facets]
    area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1).sum()
    share = 0.25 if quarter else 0.5
    pressure = p.force * share / area

    def on_springs(x):
        return np.abs(x[:, 0] - x_wb) < tol

    return TwoBodyScene(
        bodies=(work, backup), constrained_body=0, supports=supports,
        on_constrained=on_constrained, on_opposing=on_opposing,
        direction=np.array([0.0, 0.0, 1.0]), search="along_direction",
        tractions=[Traction(0, in_bite, np.array([0.0, 0.0, pressure]))],
        springs=[Springs(0, on_springs, np.array([0.0, 1.0, 1.0]) * p.spring * E * Rw)],
        hertz=HertzSetup("line", 1.0 / (1.0 / Rw + 1.0 / Rb),
                         effective_modulus(E, p.nu, E, p.nu)),
        units="mm, N, MPa" if p.units == "mm" else "m, N, Pa")


def build(level: int, p: Options) -> ContactQP:
    """The roll-stack ContactQP at mesh level ``level`` (see the module docstring)."""
    qp = assemble_two_body(scene(level, p), 0, degree=p.degree,
                           name=f"roll_stack level {level} ({p.model})" + (" P2" if p.degree == 2 else ""))
    qp.level = level
    if p.degree == 1:   # P2's edge nodes lie between the layers: no section to copy
        qp.multilevel.extrusion = extrusion_layers(qp.mesh.points, qp.mesh.body_of_node,
                                                   qp.free_dofs, qp.dim, axis=0)
    return qp


PROBLEM = ProblemSpec(
    name="roll_stack",
    summary="crowned work roll on a backup roll of a four-high mill, 3D, SI units, quarter "
            "model (thesis Sect. 9.3, Figs. 9.10-9.16)",
    kind="contact",
    levels=(0, 4),
    dim=3,
    default_level=0,
    parameters=(
        Parameter("force", 15e6, "strip force on the whole work roll, N", low=2e6, high=1e8),
        Parameter("crown", 150e-6, "work-roll crown on the diameter, m", low=0.0, high=1e-3),
        Parameter("model", "quarter", "symmetry planes used", choices=("quarter", "half")),
        Parameter("units", "m", "unit system: m, N, Pa or mm, N, MPa", choices=("m", "mm")),
        Parameter("E", 220e9, "Young's modulus of both rolls, Pa", low=0.0, low_open=True),
        Parameter("nu", 0.3, "Poisson ratio of both rolls", low=-1.0, high=0.5, low_open=True,
                  high_open=True),
        Parameter("weight_density", 7.66e4, "weight per volume, N/m^3", low=0.0),
        Parameter("bite", 0.04, "strip bite (width of the strip pressure in y), m", low=0.005,
                  high=0.2),
        Parameter("band", 0.012, "half-width in y of the constrained band (and of the uniformly "
                  "fine zone), m", low=0.004, high=0.1),
        Parameter("spring", 1e-8, "work-roll spring per node relative to E * R_w", low=0.0,
                  high=1e-4, low_open=True),
        ELEMENT_DEGREE,
    ),
    build=build,
)
