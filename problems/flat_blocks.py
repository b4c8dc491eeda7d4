"""Contact patch test: two flat blocks on non-matching meshes (Ch. 6 grids, Sect. 7.2).

Scene (dimensionless units):

* the lower block (0, 1) x (0, 1) and the upper block (0, 1) x (1 + gap, 2 + gap),
  E = 1, nu = 0.3 for both, plane strain, a uniform initial ``gap`` (default 1e-3, a
  tenth of the indentation; a zero gap makes every gap and every ``B u`` vanish and
  leaves the scaled KKT residuals of :func:`problems.kkt.kkt_residuals` without a
  displacement scale);
* meshes in the ratio ``ratio`` of Ch. 6 (default 2:3, so that the interface nodes
  of the two sides coincide only at every second coarse node): the lower block has
  ``p 2^(L+1)`` cells per unit length at level L, the upper ``q 2^(L+1)``;
* supports: the lower block stands on y = 0 (u_y = 0), both blocks are symmetric
  about x = 0 (u_x = 0 there); the upper edge y = 2 + gap is pushed down by ``indent``
  with u_x free (a frictionless platen). The right edge x = 1 is free.

The exact solution is linear: uniform stress sigma_yy = -q, sigma_xx = 0 in both
blocks, u_x = nu (1 + nu) q x / E, and a uniform contact pressure

    q = E (indent - gap) / ((1 - nu^2) (H_1 + H_2)),   H_1 = H_2 = 1

(plane strain, equal materials: both blocks strain alike and the interface closes
uniformly).
Displacement control instead of a prescribed pressure keeps both stiffnesses
definite without springs; the pressure the interface must transmit is uniform
all the same.

Couplings (``coupling``):

* ``nodal``: the nodal constraints of Alg. 7.1 on the ``constrained`` side
  (``coarse`` = the lower block, ``fine`` = the upper block). The pressure is the
  multiplier over the lumped contact mass (Sect. 8.6).
* ``mortar``: the weighted gap of the mortar method (Sect. 6.1, Remark 6.8; not in the
  thesis's contact chapter): row i is ``(1/m_i) int_Gamma phi_i n.(u_c - u_o) ds`` with
  the constrained side's P1 hats ``phi_i`` (their sum is 1 on the interface, so a
  uniform pressure is transmitted exactly), integrated exactly on the merged 1D mesh
  (:mod:`problems.fem.mortar`). The pressure is again ``p_i / m_i``.
* ``mortar_dual``: the same weighted gaps with Wohlmuth's dual multipliers ``psi_i``
  (biorthogonal to the hats, so each row moves its own constrained node only); they
  too sum to 1 and pass the patch test.
* ``stabilised``: the nodal constraints plus the stabilised reverse rows of Sect. 7.5
  ((7.10)/(7.11), :func:`problems.fem.stabilised.stabilise` with ``alpha`` and
  ``penalty``): the opposing side's nodes are penalised for penetrating. The pressure
  is the total multiplier on the constrained nodes over their lumped mass
  (:func:`problems.qp.surface_multipliers`).
* ``two_pass``: two-pass node-to-segment contact (:func:`problems.fem.stabilised.two_pass`):
  the nodal constraints plus, as hard rows, every node of the opposing block against
  the constrained facets. Contact codes use it to keep each surface out of the other;
  the thesis does not (Alg. 7.1 constrains one surface, Sect. 7.5 penalises the
  reverse rows instead), and it over-constrains: where nodes of the two blocks
  coincide (every second coarse node at 2:3, every node at 1:1) the two passes give
  the same row, so the rows of ``B`` are linearly dependent and the multipliers are
  not unique. The pressure is that of the stabilised coupling, the total multiplier
  on the constrained nodes over their lumped mass, which is unique (the constrained
  nodes' part of ``B' p = f - A u``). Two-pass passes this patch test on both meshes
  (the exact, linear displacement satisfies both passes).

A discretisation that transmits the uniform pressure passes; one that does not
shows the deviation of its nodal pressure from q (the classic node-to-segment
patch-test failure on non-matching meshes).
"""
from __future__ import annotations

import numpy as np

from problems.fem.mesh import Hierarchy, nested_prolongation, structured_square
from problems.fem.stabilised import COUPLING_PARAMETERS, check_coupling, couple
from problems.fem.surface import tensor_coarsening
from problems.fem.two_body import ELEMENT_DEGREE, Body, TwoBodyScene, assemble_two_body
from problems.qp import ContactQP
from problems.spec import Options, Parameter, ParameterError, ProblemSpec


def parse_ratio(text: str) -> tuple[int, int]:
    """``"2:3"`` -> (2, 3): cells per unit length of the lower : upper block."""
    try:
        a, b = (int(s) for s in str(text).split(":"))
    except ValueError:
        a = b = 0
    if not (1 <= a <= 16 and 1 <= b <= 16):
        raise ParameterError(f"parameter 'ratio': {text!r} is not allowed; allowed: 'p:q' with "
                             "integers 1..16, e.g. '2:3'")
    return a, b


def block_meshes(level: int, cells_per_unit: int, y0: float) -> Hierarchy:
    """Structured unit squares at height ``y0`` with ``cells_per_unit 2^k`` cells per
    edge, k = 0..level, nested."""
    pts, cells = zip(*[structured_square(cells_per_unit * 2 ** k, 0.0, y0, 1.0)
                       for k in range(level + 1)])
    P = [nested_prolongation(pts[k], cells[k], pts[k + 1]) for k in range(level)]
    return Hierarchy(list(pts), list(cells), P)


def exact_pressure(p: Options) -> float:
    """The uniform contact pressure q of the exact solution (module docstring)."""
    return p.E * (p.indent - p.gap) / ((1.0 - p.nu ** 2) * 2.0)


def scene(level: int, p: Options) -> TwoBodyScene:
    """The two blocks up to mesh level ``level``."""
    lo, hi = parse_ratio(p.ratio)
    lower = Body("lower", block_meshes(level, lo * 2, 0.0), p.E, p.nu, np.zeros(2))
    upper = Body("upper", block_meshes(level, hi * 2, 1.0 + p.gap), p.E, p.nu, np.zeros(2))
    coarse = 0 if lo <= hi else 1                      # the block with fewer cells
    constrained = coarse if p.constrained == "coarse" else 1 - coarse

    def supports(points, body_of_node):
        x, y = points[:, 0], points[:, 1]
        sym = np.flatnonzero(np.isclose(x, 0.0))
        bottom = np.flatnonzero((body_of_node == 0) & np.isclose(y, 0.0))
        top = np.flatnonzero((body_of_node == 1) & np.isclose(y, 2.0 + p.gap))
        fixed = np.concatenate([2 * sym, 2 * bottom + 1, 2 * top + 1])
        values = np.concatenate([np.zeros(len(sym) + len(bottom)), np.full(len(top), -p.indent)])
        return fixed, values

    level_of = (1.0, 1.0 + p.gap)                       # the lower's top, the upper's bottom
    return TwoBodyScene(
        bodies=(lower, upper), constrained_body=constrained, supports=supports,
        on_constrained=lambda x: np.isclose(x[:, 1], level_of[constrained]),
        on_opposing=lambda c: np.isclose(c[:, 1], level_of[1 - constrained]),
        direction=np.array([0.0, 1.0 if constrained == 0 else -1.0]), search="along_direction",
        surface_coarsening=lambda x: tensor_coarsening(x[:, :1]), units="dimensionless")


def build(level: int, p: Options) -> ContactQP:
    """The patch-test ContactQP at level ``level`` with the chosen coupling."""
    if p.gap >= p.indent:
        raise ParameterError(f"parameter 'gap': {p.gap!r} is not allowed; allowed: a number "
                             f"below indent = {p.indent!r} (else the blocks never touch)")
    check_coupling(p)
    sc = scene(level, p)
    qp = assemble_two_body(sc, level, degree=p.degree,
                           name=f"flat_blocks level {level} ({p.coupling}, "
                                f"{p.constrained} side constrained)" + (" P2" if p.degree == 2 else ""))
    return couple(qp, p)


PROBLEM = ProblemSpec(
    name="flat_blocks",
    summary="contact patch test: two flat blocks on non-matching meshes (ratio 2:3 as in "
            "Ch. 6) pressed together; the exact contact pressure is uniform",
    kind="contact",
    levels=(0, 6),
    default_level=1,
    parameters=(
        Parameter("ratio", "2:3", "cells per unit length of the lower : upper block"),
        Parameter("constrained", "coarse", "which block carries the constraints: the coarse "
                  "one (fewer cells; the lower at 2:3) or the fine one", choices=("coarse", "fine")),
        *COUPLING_PARAMETERS,
        Parameter("E", 1.0, "Young's modulus of both blocks", low=0.0, low_open=True),
        Parameter("nu", 0.3, "Poisson ratio of both blocks", low=-1.0, high=0.5, low_open=True,
                  high_open=True),
        Parameter("indent", 0.01, "downward displacement of the upper edge", low=0.0,
                  high=0.2, low_open=True),
        Parameter("gap", 0.001, "initial gap between the blocks (must be < indent)", low=0.0,
                  high=0.1),
        ELEMENT_DEGREE,
    ),
    build=build,
)
