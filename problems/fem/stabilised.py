"""The stabilised two-sided nodal constraints of thesis Sect. 7.5, (7.10)/(7.11).

The nodal constraints of Alg. 7.1 keep the constrained surface's nodes out of the
opposing body, but not the opposing surface's nodes out of the constrained body:
those "hang" between the constrained nodes and may penetrate (Fig. 7.1, the
penetrations (7.9) that eta_T,2 measures). Sect. 7.5 penalises that penetration,
motivated by the stabilisation (6.18) of Ch. 6::

    <A_s u, v> = <A u, v> + sum_E h_E^(-2 alpha) <I_+(Bu - G), I_+(Bv - G)>_E     (7.10)

with ``I_+`` the positive part at the opposing nodes. With the lumped mass
``m_i`` of the opposing surface the term is ``sum_i k h_i^(-2 alpha) m_i (d_i)_+^2``
(``d_i`` the penetration of node ``i``); dualised by artificial multipliers
``p_r >= 0`` it becomes the rows (7.11)::

    B_r u - C_r p_r <= g_r,    C_r = diag(h_i^(2 alpha) / (k m_i)),

appended to the nodal rows (which keep ``C = 0``). Alg. 8.4 solves this with
``C != 0`` as written; the QP solvers see the equivalent slack form
(:func:`problems.slack.slack_form`).

The constant ``k`` makes the penalty unit-free: ``k = penalty E* l^(2 alpha - 1)``
with ``E*`` the effective modulus of the pair (Hertz's ``1/E* = sum (1 - nu^2)/E``)
and ``l`` the extent of the constrained surface (the largest side of its
bounding box); with ``alpha = 1/2``, ``k h^-1 = penalty E*/h`` is Nitsche's
scaling and ``l`` drops out. The thesis gives neither ``alpha`` nor ``k`` for its
Fig. 7.5; Ch. 6 proves ``alpha = 1`` optimal for the Laplace problem.

Deviations from the thesis: the reverse rows are the nodal constraints of Alg. 7.1
case b along ``-n`` (``n`` the mean constraint direction, as eta_T,2 measures
them, :func:`problems.fem.estimators.penetrations`) in the reference
configuration, not the interpolated ``I^l(B_l u - G)`` of (7.11) (the same thing
for P1 elements and small displacements); ``h_i`` is the local size of the
opposing surface at node ``i`` (the thesis writes one ``h`` for a uniform mesh).

Pure functions: no files, no printing.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from problems.fem.contact import contact_constraints
from problems.fem.elasticity import lumped_surface_mass
from problems.fem.mortar import MORTAR_COUPLINGS, mortar
from problems.fem.surface import facet_sizes
from problems.qp import ContactQP, SharedWork, Stabilisation
from problems.spec import Options, Parameter, ParameterError
from reference.hertz import effective_modulus as hertz_modulus


def effective_modulus(qp: ContactQP) -> float:
    """Hertz's ``E*`` (:func:`reference.hertz.effective_modulus`) of the two bodies: the
    constrained one and the opposing one, from the cells next to each surface."""
    m = qp.mesh
    body_of_cell = m.body_of_node[m.cells[:, 0]]
    cells = [np.flatnonzero(body_of_cell == m.body_of_node[node])[0]
             for node in (qp.contact.nodes[0], qp.contact.opposing_facets[0, 0])]
    return hertz_modulus(*(x for c in cells for x in (m.E_cell[c], m.nu_cell[c])))


def stabilise(qp: ContactQP, alpha: float = 1.0, penalty: float = 1.0) -> ContactQP:
    """The stabilised two-sided formulation (7.10)/(7.11) of a nodal ContactQP.

    Parameters
    ----------
    qp : ContactQP
        The nodal constraints of a two-body scene (with ``mesh`` and ``contact``).
    alpha : float
        Exponent in ``h^(-2 alpha)``, in [0, 2].
    penalty : float
        Dimensionless factor of ``k`` (module docstring), > 0.

    Returns
    -------
    ContactQP
        ``B = [B_c; B_r]``, ``g = [g_c; g_r]``, ``C = diag(0, C_r)`` and
        ``stabilisation`` describing the reverse rows; ``contact`` and the
        multilevel data (the constrained surface's hierarchy) are unchanged.
    """
    if not (0.0 <= alpha <= 2.0):
        raise ValueError(f"parameter 'alpha': {alpha!r} is not allowed; allowed: a number in [0, 2]")
    if not (np.isfinite(penalty) and penalty > 0):
        raise ValueError(f"parameter 'penalty': {penalty!r} is not allowed; "
                         "allowed: a number in (0, inf)")
    rows = reverse_rows(qp)
    k = penalty * effective_modulus(qp) * rows.extent ** (2 * alpha - 1)
    c_r = rows.size ** (2 * alpha) / (k * rows.mass)
    return replace(
        qp, B=sp.vstack([qp.B, rows.B]).tocsr(), g=np.concatenate([qp.g, rows.g]),
        C=sp.diags(np.concatenate([np.zeros(qp.m), c_r]), format="csr"),
        stabilisation=Stabilisation(nodes=rows.nodes, mass=rows.mass, size=rows.size,
                                    transfer=rows.transfer, alpha=float(alpha),
                                    modulus=float(k)),
        name=f"{qp.name} (stabilised, alpha = {alpha:g})", cache=SharedWork())


@dataclass(frozen=True)
class ReverseRows:
    """The nodal constraints of the opposing surface's nodes against the constrained
    facets (Alg. 7.1 case b along ``-n``), on the free unknowns of a nodal ContactQP.

    Attributes
    ----------
    nodes : (r,) int array
        Opposing-surface node behind each row.
    B : (r, n) sparse
        The rows on ``qp.free_dofs``.
    g : (r,) array
        Their gaps, with the prescribed displacements moved over.
    transfer : (r, m_c) sparse
        Barycentric weights of the constrained facet each row hits, on the constrained
        rows (:attr:`problems.qp.Stabilisation.transfer`).
    mass, size : (r,) arrays
        Lumped mass and local mesh size of the opposing surface at ``nodes``.
    extent : float
        The largest side of the constrained surface's bounding box.
    """

    nodes: np.ndarray
    B: sp.csr_matrix
    g: np.ndarray
    transfer: sp.csr_matrix
    mass: np.ndarray
    size: np.ndarray
    extent: float


def reverse_rows(qp: ContactQP) -> ReverseRows:
    """The reverse rows of a nodal ContactQP (:class:`ReverseRows`): one per node of the
    opposing surface that finds a constrained facet along ``-n`` (``n`` the mean
    constraint direction)."""
    if qp.mesh is None or qp.contact is None or qp.stabilisation is not None or qp.C is not None:
        raise ValueError("parameter 'qp': a nodal ContactQP with mesh and contact, without "
                         "reverse rows yet, is required")
    pts, c = qp.mesh.points, qp.contact
    n = c.direction.mean(axis=0)
    n = n / np.linalg.norm(n)
    opposing_nodes = np.unique(c.opposing_facets)
    cc = contact_constraints(pts, opposing_nodes, c.facets, direction=-n, search="along_direction",
                             n_nodes=qp.n_nodes)
    if cc.m == 0:
        raise ValueError("no node of the opposing surface faces the constrained surface "
                         "along -n: no reverse rows")
    row_of = -np.ones(qp.n_nodes, dtype=np.int64)
    row_of[c.nodes] = np.arange(len(c.nodes))
    cols = row_of[cc.facet_nodes]
    keep = cols >= 0                  # a facet node without a row (dropped by Alg. 7.1)
    transfer = sp.csr_matrix((cc.weights[keep], (np.nonzero(keep)[0], cols[keep])),
                             shape=(cc.m, len(c.nodes)))
    return ReverseRows(
        nodes=cc.rows, B=cc.B[:, qp.free_dofs].tocsr(), g=cc.g - cc.B @ qp.u_fixed,
        transfer=transfer, mass=lumped_surface_mass(pts, c.opposing_facets, qp.n_nodes)[cc.rows],
        size=facet_sizes(pts, c.opposing_facets, cc.rows),
        extent=float(np.ptp(pts[np.unique(c.facets)], axis=0).max()))


def two_pass(qp: ContactQP) -> ContactQP:
    """Two-pass node-to-segment contact: the nodal rows of ``qp`` and, as hard rows,
    the reverse rows of every opposing node (:func:`reverse_rows`).

    Each surface's nodes are kept out of the other body: the classic symmetric
    treatment of contact codes, not the thesis's, whose Alg. 7.1 constrains one
    surface only (one pass) and Sect. 7.5 penalises the reverse rows instead
    (:func:`stabilise`; two-pass is its limit ``penalty -> inf``, ``C_r = 0``).
    Where a node of one surface coincides with a node of the other (matching meshes,
    every second coarse node at the ratio 2:3), both passes give the same row: the
    rows of ``B`` are linearly dependent there and the multipliers are not unique.
    The force on the constrained surface, ``p_c + T' p_r``
    (:func:`problems.qp.surface_multipliers`), is unique all the same: it is the
    constrained nodes' normal part of ``B' p = f - A u``.

    Returns
    -------
    ContactQP
        ``B = [B_c; B_r]``, ``g = [g_c; g_r]``, ``C = None`` and ``stabilisation``
        describing the reverse rows with ``alpha`` and ``modulus`` unset.
    """
    rows = reverse_rows(qp)
    return replace(
        qp, B=sp.vstack([qp.B, rows.B]).tocsr(), g=np.concatenate([qp.g, rows.g]),
        stabilisation=Stabilisation(nodes=rows.nodes, mass=rows.mass, size=rows.size,
                                    transfer=rows.transfer, alpha=None, modulus=None),
        name=f"{qp.name} (two-pass)", cache=SharedWork())


#: The couplings of the two-body scenes (circle_square, cube_sphere, flat_blocks), with
#: the stabilisation's settings: one declaration for every scene that offers them.
COUPLINGS = ("nodal", "stabilised", "two_pass") + MORTAR_COUPLINGS

COUPLING_HELP = ("nodal constraints (Alg. 7.1), the stabilised two-sided nodal constraints "
                 "(Sect. 7.5, (7.10)/(7.11)), two-pass node-to-segment constraints (both "
                 "surfaces' nodes, hard; not in the thesis), or the mortar weighted gaps "
                 "(Sect. 6.1, Remark 6.8) with standard or dual (Wohlmuth) multipliers")

def coupling_parameters(choices: tuple[str, ...] = COUPLINGS) -> tuple[Parameter, ...]:
    """A scene's ``coupling`` parameter and the stabilised coupling's two, the couplings
    narrowed to ``choices`` (a subset of :data:`COUPLINGS`): a scene offers only what it
    can build (the mortar couplings project the surfaces onto a straight edge or a flat
    face; a curved constrained surface refuses them), and ``contactbench list`` and its
    page show just those."""
    wrong = sorted(set(choices) - set(COUPLINGS))
    if wrong or "nodal" not in choices:
        raise ValueError(f"parameter 'choices': {wrong or choices} is not allowed; allowed: "
                         f"a subset of {COUPLINGS} with 'nodal'")
    return (
        Parameter("coupling", "nodal", COUPLING_HELP, choices=tuple(choices)),
        Parameter("alpha", 1.0, "stabilised coupling: exponent alpha of h^(-2 alpha) in (7.10)",
                  low=0.0, high=2.0),
        Parameter("penalty", 1.0, "stabilised coupling: penalty factor (k = penalty E* "
                  "l^(2 alpha - 1), problems/fem/stabilised.py)", low=0.0, low_open=True),
    )


#: Every coupling, as the scenes with a straight or flat constrained surface offer them.
COUPLING_PARAMETERS = coupling_parameters()


#: The couplings built for P2 elements too (the stabilised and two-pass rows are built for P1).
P2_COUPLINGS = ("nodal",) + MORTAR_COUPLINGS


def check_coupling(p: Options) -> None:
    """Refuse a coupling the P2 elements do not have (:data:`P2_COUPLINGS`; ``mortar_dual``
    at P2 in 3D is refused by :func:`problems.fem.mortar.mortar`, which knows the
    dimension)."""
    if getattr(p, "degree", 1) == 2 and p.coupling not in P2_COUPLINGS:
        raise ParameterError(f"parameter 'degree': 2 is not allowed with coupling="
                             f"{p.coupling!r}; allowed: degree=1, or degree=2 with coupling in "
                             f"{P2_COUPLINGS} (the {p.coupling} coupling is built for P1)")


def couple(qp: ContactQP, p: Options) -> ContactQP:
    """The scene's nodal ContactQP, or its stabilised, two-pass or mortar form when
    ``p.coupling`` asks for it."""
    if p.coupling in MORTAR_COUPLINGS:
        try:
            return mortar(qp, dual=p.coupling == "mortar_dual")
        except ValueError as err:
            raise ParameterError(f"parameter 'coupling': {p.coupling!r} is not allowed here: "
                                 f"{err}") from None
    if p.coupling == "stabilised":
        return stabilise(qp, p.alpha, p.penalty)
    return two_pass(qp) if p.coupling == "two_pass" else qp
