"""Fields and contact state of a solved contact problem (pure; files are written at the edges)."""
from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from problems.fem.elasticity import von_mises
from problems.fem.quadratic import linear_subcells
from problems.qp import ContactQP, surface_multipliers, surface_pressure


def contact_fields(qp: ContactQP, u: np.ndarray, p: np.ndarray) -> dict[str, np.ndarray]:
    """Nodal displacement, nodal contact pressure, body id and cell von Mises stress.

    Returns
    -------
    dict
        ``points (N, d)``, ``cells``, ``displacement (N, d)``, ``contact_pressure (N,)``
        (``p / contact mass`` at the constrained nodes, zero elsewhere; with the
        stabilisation of Sect. 7.5 the reverse rows' multipliers are spread onto the
        constrained nodes first, :func:`problems.qp.surface_multipliers`),
        ``body (N,)`` and ``von_mises (n_cells,)``. P2 meshes are given as their
        sub-simplices (:func:`problems.fem.quadratic.linear_subcells`), the von Mises stress
        there of the P1 interpolant on them (for plots).
    """
    mesh = qp.mesh
    disp = qp.full_displacement(u)
    pressure = np.zeros(mesh.n_nodes)
    if qp.contact is not None:
        pressure[qp.contact.nodes] = surface_pressure(qp, p)
    cells = mesh.cells if mesh.degree == 1 else linear_subcells(mesh.points, mesh.cells)
    per_sub = len(cells) // len(mesh.cells)
    vm = von_mises(mesh.points, cells, disp, np.repeat(mesh.E_cell, per_sub),
                   np.repeat(mesh.nu_cell, per_sub))
    return {"points": mesh.points, "cells": cells, "displacement": disp,
            "contact_pressure": pressure, "body": mesh.body_of_node, "von_mises": vm}


def contact_state(qp: ContactQP, u: np.ndarray, p: np.ndarray,
                  active_tol: float = 1e-8) -> dict[str, Any]:
    """Per-constraint state: position, multiplier, pressure, gap, activity; total force.

    ``force`` is ``sum_i p_i n_i``: the total force the constrained body exerts on
    the opposing one (the constrained body feels its negative). A constraint is
    ``active`` when ``p > 0`` and its slack is below ``active_tol`` times the
    gap scale.
    """
    p = np.asarray(p, dtype=float)
    slack = qp.g - qp.B @ u + (qp.C @ p if qp.C is not None else 0.0)
    scale = max(float(np.max(np.abs(qp.g))) if qp.m else 0.0, 1e-300)
    out: dict[str, Any] = {"p": p, "gap": slack, "active": (p > 0) & (slack <= active_tol * scale)}
    if qp.contact is not None:
        pc = surface_multipliers(qp, p)
        out["x"] = qp.constrained_points()
        out["pressure"] = qp.contact.pressure(pc)
        out["force"] = (pc[:, None] * qp.contact.direction).sum(axis=0)
    return out


def friction_state(qp: ContactQP, u: np.ndarray, p: np.ndarray, lam: np.ndarray,
                   tol: float) -> dict[str, Any]:
    """Per constrained node of the Tresca step ``qp`` (its ``friction``): the tangential
    multiplier, traction, slip, slip bound and stick/slip state; and the totals.

    ``traction`` is ``lam`` turned into a traction as the normal multiplier is turned
    into the pressure (:meth:`problems.qp.ContactSurface.pressure`: ``lam / mass``);
    ``slip`` is the step's ``T u + offset - previous``; in 3D both, like ``tangential``,
    are node-major with two entries per node (along the row's two tangents,
    ``friction.tangent``). ``state`` is ``stick``, ``slip`` or ``free``
    (:meth:`problems.friction.data.Friction.states` at ``tol``). ``tangential_force`` is
    ``sum_i lam_i t_i``; ``load_ratio`` is Q/(mu P) with ``Q``
    :meth:`problems.friction.data.Friction.total_force` (nan for ``mu = 0`` or no contact force).
    """
    fr = qp.friction
    lam, p = np.asarray(lam, dtype=float), np.asarray(p, dtype=float)
    P = float(p.sum())
    traction = fr.blocks(lam) / qp.contact.mass[:, None] if fr.components > 1 else \
        qp.contact.pressure(lam)
    return {"law": fr.law, "mu": fr.mu, "tangential": lam,
            "traction": traction.ravel(), "slip": fr.slip(u),
            "slip_bound": fr.slip_bound, "state": fr.states(lam, tol),
            "tangential_force": fr.tangential_force(lam),
            "load_ratio": fr.total_force(lam) / (fr.mu * P) if fr.mu > 0 and P > 0
            else float("nan")}


def in_plane(qp: ContactQP) -> np.ndarray:
    """Positions of the constrained nodes in the contact plane: the coordinates
    orthogonal to the mean contact direction, ``(m, d - 1)``."""
    x = qp.constrained_points()
    n = qp.contact.direction.mean(axis=0)
    n = n / np.linalg.norm(n)
    _, _, vt = np.linalg.svd(n[None, :])
    return x @ vt[1:].T


def contact_forces(qp: ContactQP, p: np.ndarray) -> np.ndarray:
    """The contact's normal nodal forces at the constrained nodes.

    At P1 the multipliers on the constrained surface (:func:`surface_multipliers`: the
    rows carry a unit direction). At P2 (a surface with a recovered pressure) the normal
    components of the forces the contact rows exert on the constrained nodes,
    ``n . (B_C' p)`` per node: the multipliers themselves for nodal rows and dual mortar
    rows (``D`` diagonal), the consistent loads ``int lambda phi_j`` for the standard
    mortar rows, whose multipliers are no nodal forces (the consistent load of a P2
    vertex on a triangle is zero, whatever its row's multiplier). Their total
    is the force the rows transmit, and on a flat surface their second moments are the
    exact integrals of the pressure against quadratics. Every constrained node's DOFs are
    taken to be free (a prescribed one would drop its force).
    """
    p = surface_multipliers(qp, p)
    if qp.contact.pressure_map is None:
        return p
    full = np.zeros(qp.n_nodes * qp.dim)
    full[qp.free_dofs] = qp.B[:qp.m_contact].T @ p
    n = qp.contact.direction.mean(axis=0)
    return full.reshape(-1, qp.dim)[qp.contact.nodes] @ (n / np.linalg.norm(n))


def hertz_comparison(qp: ContactQP, p: np.ndarray,
                     forces: np.ndarray | None = None) -> dict[str, float]:
    """The measured contact zone against Hertz for the measured total force.

    Three estimators of the size ``a`` and the peak ``p0``: the moments of the
    nodal forces (robust), a least-squares fit of ``p^2`` against ``r^2`` and
    the single nodal maximum; deviations ``dev_* = measured / Hertz - 1``.
    ``P`` is the total contact force (``sum p``: the constraints' rows carry a
    unit direction), per unit thickness in 2D. ``forces``: the nodal forces the
    moments and ``P`` take instead of the multipliers (e.g. :func:`contact_forces`).
    """
    from reference import hertz

    if qp.hertz is None:
        raise ValueError(f"{qp.name or 'this problem'} has no Hertz reference (qp.hertz)")
    kind, R, E_star = qp.hertz.kind, qp.hertz.radius, qp.hertz.E_star
    p = surface_multipliers(qp, p)
    pressure = qp.contact.pressure(p)
    x = in_plane(qp)
    f = p if forces is None else np.asarray(forces, dtype=float)
    P = float(f.sum())
    a_h = hertz.contact_size(kind, P, R, E_star)
    p0_h = hertz.peak_pressure(kind, P, a_h)
    xbar, a_m, p0_m = hertz.moment_estimate(kind, x, f)
    r = np.linalg.norm(x - xbar, axis=1)
    a_f, p0_f = hertz.fit_ellipse(r, pressure)
    h = float(np.median(cKDTree(x).query(x, k=2)[0][:, 1]))   # nodal spacing
    return {"force": P, **{f"center_s{i}": float(c) for i, c in enumerate(xbar)},
            "a_hertz": a_h, "p0_hertz": p0_h, "a_moment": a_m, "p0_moment": p0_m,
            "a_fit": a_f, "p0_fit": p0_f, "p0_nodal_max": float(pressure.max()),
            "n_active": int((p > 0).sum()), "h": h, "a_over_h": a_m / h,
            "dev_a_moment": a_m / a_h - 1, "dev_p0_moment": p0_m / p0_h - 1,
            "dev_a_fit": a_f / a_h - 1, "dev_p0_fit": p0_f / p0_h - 1,
            "dev_p0_nodal_max": float(pressure.max()) / p0_h - 1}
