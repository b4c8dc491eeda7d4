"""The reference solution on a common finer mesh, and the measures the adaptive and
coupling studies take of a contact answer against it and against Hertz.

:func:`contact_measures` gives a contact answer's force, its Hertz deviations (contact
size and peak pressure by moments), the mesh sizes in the contact zone (the pile-up of
Fig. 7.3), the pressure's zig-zag and its rms deviation from Hertz. :class:`Reference`
holds the reference solution and compares an answer on a coarser (or another) mesh with
it: the relative energy-norm error, its shares per region (contact zone, singular points,
the rest), the force and pressure errors, and the multiplier's error in the dual norm.
"""
from __future__ import annotations

import hashlib

import numpy as np
import scipy.sparse as sp

from problems.fem import accuracy as acc
from problems.fem.elasticity import barycentric_gradients, boundary_facets, stiffness_matrix
from problems.fem.fields import contact_forces, hertz_comparison, in_plane
from problems.fem.quadratic import quadratic_mesh_of, stiffness_matrix_p2
from problems.kkt import kkt_residuals
from problems.qp import ContactQP, surface_multipliers
from workflows.measure import dual_norm


def _sizes_in_zone(points, facets, s_of, center, radius):
    """Mean facet size of a contact surface inside the zone."""
    if not len(facets):
        return np.nan
    x = points[facets]
    size = (np.linalg.norm(x[:, 1] - x[:, 0], axis=1) if x.shape[1] == 2
            else np.sqrt(2 * 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]),
                                                  axis=1)))
    inside = np.linalg.norm(s_of(x.mean(axis=1)) - center, axis=1) <= radius
    return float(size[inside].mean()) if inside.any() else np.nan


def contact_measures(qp: ContactQP, u: np.ndarray, p: np.ndarray) -> dict:
    """Force, Hertz deviations, zone (pile-up), zig-zag, rms deviation from Hertz."""
    from reference import hertz

    row = {"kkt_max": kkt_residuals(qp, u, p).max}
    p_all, p = p, surface_multipliers(qp, p)       # the force on the constrained surface
    forces = contact_forces(qp, p_all)              # P1: p; P2: the rows' nodal forces
    row.update({"force": float(np.sum(forces)), "n_active": int(np.sum(p > 0))})
    if qp.hertz is None or np.sum(forces) <= 0:
        return row
    row.update(hertz_comparison(qp, p_all, forces))
    n = qp.contact.direction.mean(axis=0)
    n /= np.linalg.norm(n)
    basis = np.linalg.svd(n[None, :])[2][1:]
    s_of = lambda x: np.asarray(x).reshape(-1, qp.dim) @ basis.T      # in-plane coordinates
    s = in_plane(qp)
    center = np.array([row[f"center_s{i}"] for i in range(qp.dim - 1)])
    a = row["a_hertz"]
    opp = np.unique(qp.contact.opposing_facets)
    row.update(acc.pileup(s, s_of(qp.mesh.points[opp]), center, a))
    row["h_zone_constrained"] = _sizes_in_zone(qp.mesh.points, qp.contact.facets, s_of, center, a)
    row["h_zone_opposing"] = _sizes_in_zone(qp.mesh.points, qp.contact.opposing_facets, s_of,
                                            center, a)
    pressure = qp.contact.pressure(p)          # P2: recovered from the forces
    r = np.linalg.norm(s - center, axis=1)
    zone = r <= a
    p0 = row["p0_hertz"]
    dev = (pressure[zone] - hertz.pressure(qp.hertz.kind, r[zone], row["force"], qp.hertz.radius,
                                           qp.hertz.E_star)) / p0
    row["dev_hertz_rms"] = float(np.sqrt(np.mean(dev ** 2))) if zone.any() else np.nan
    if qp.dim == 2:
        z = acc.zigzag(s[:, 0], pressure, p > 0) / p0
        row["zigzag_rms"] = float(np.sqrt(np.mean(z ** 2))) if z.size else np.nan
        row["zigzag_max"] = float(np.abs(z).max()) if z.size else np.nan
    return row


def singular_points(qp: ContactQP) -> np.ndarray:
    """Boundary points where a facet with every DOF prescribed meets one without: the
    ends of Dirichlet parts (clamped corners, ends of a held arc)."""
    d = qp.dim
    fixed = np.ones(qp.n_nodes * d, dtype=bool)
    fixed[qp.free_dofs] = False
    node_fixed = fixed.reshape(-1, d).all(axis=1)
    f = boundary_facets(qp.mesh.cells[:, :d + 1])       # P2: the vertices' facets
    full = node_fixed[f].all(axis=1)
    touched = np.zeros(qp.n_nodes, dtype=int)
    np.add.at(touched, f[full].ravel(), 1)
    loose = np.zeros(qp.n_nodes, dtype=bool)
    loose[f[~full].ravel()] = True
    return qp.mesh.points[(touched > 0) & loose]


class Reference:
    """The reference solution on the common refinement and the comparisons with it.

    A P1 reference (the adaptive and coupling studies) or a P2 one (``degree=2``: cells
    with midpoint columns, the coupling study's P2 rows). At P2 the energy norm is the
    P2 stiffness's (:func:`problems.fem.quadratic.stiffness_matrix_p2`) on all nodal
    DOFs, the nodal pressure the recovered one (:meth:`ContactSurface.pressure`), and
    two measures are P1 only: the energy shares per region (``err_share_*``, from the
    P1 energy per cell) and the multiplier's dual-norm error (NaN: the forces
    ``B_C' (m lambda)`` of an interpolated nodal pressure are the P1 multiplier
    basis's)."""

    def __init__(self, qp: ContactQP, u: np.ndarray, p: np.ndarray, info: dict):
        self.qp, self.info = qp, info
        m = qp.mesh
        self.quadratic = m.cells.shape[1] > qp.dim + 1
        if self.quadratic:
            self.A = stiffness_matrix_p2(quadratic_mesh_of(m.points, m.cells), m.E_cell,
                                         m.nu_cell)
            self.geometry = None
        else:
            self.A = stiffness_matrix(m.points, m.cells, m.E_cell, m.nu_cell)
            self.geometry = barycentric_gradients(m.points, m.cells)   # every compare's
        self._prolongations = {}          # per compared mesh (a study's couplings share one)
        self.U = qp.full_displacement(u)
        self.norm = float(np.sqrt(self.U.ravel() @ (self.A @ self.U.ravel())))
        self.p = p
        self.force = float(np.sum(contact_forces(qp, p)))
        self.s = in_plane(qp)
        self.pressure = qp.contact.pressure(p)
        self._force_norm = None          # ||A^{-1/2} B_C' p_ref||, at the first dual error
        meas = contact_measures(qp, u, p)
        a = meas.get("a_hertz", np.nan)
        center = (p @ qp.constrained_points()) / p.sum() if p.sum() > 0 else None
        cen = m.points[m.cells].mean(axis=1)
        self.regions = {}
        if center is not None and np.isfinite(a) and not self.quadratic:
            self.regions["contact"] = np.linalg.norm(cen - center, axis=1) <= 2 * a
            sing = singular_points(qp)
            near = np.zeros(len(cen), dtype=bool)
            for x in sing:
                near |= np.linalg.norm(cen - x, axis=1) <= 2 * a
            self.regions["singular"] = near & ~self.regions["contact"]
            self.regions["rest"] = ~(self.regions["contact"] | self.regions["singular"])
        self.row = {"variant": "reference", "step": -1, "N": qp.n_nodes, "NC": qp.m,
                    "n_cells": len(m.cells), **meas, "solver": info["solver"],
                    "status": info["status"], "t_solve": info["t_solve"],
                    "n_singular_points": len(singular_points(qp))}

    def prolongation(self, qp: ContactQP) -> sp.csr_matrix:
        """Nodal P1 interpolation from ``qp``'s mesh to the reference's (per body), built
        once per mesh."""
        m, r = qp.mesh, self.qp.mesh
        key = hashlib.blake2b(b"".join(np.ascontiguousarray(a).tobytes() for a in
                                       (m.points, m.cells, m.body_of_node)),
                              digest_size=16).digest()
        if key not in self._prolongations:
            self._prolongations[key] = acc.interpolation_matrix(
                m.points, m.cells, r.points, m.body_of_node[m.cells[:, 0]], r.body_of_node)
        return self._prolongations[key]

    def compare(self, qp: ContactQP, u: np.ndarray, p: np.ndarray,
                P: sp.csr_matrix | None = None) -> dict:
        """The errors of ``(u, p)`` on ``qp`` against the reference (module docstring)."""
        P = self.prolongation(qp) if P is None else P
        diff = self.pressure_difference(qp, p)
        p = contact_forces(qp, p)
        E = (P @ qp.full_displacement(u)) - self.U
        m = self.qp.mesh
        if self.quadratic:
            by_cell = None
            total = float(E.ravel() @ (self.A @ E.ravel()))
        else:
            by_cell = acc.energy_norm_by_cell(m.points, m.cells, E, m.E_cell, m.nu_cell,
                                              self.geometry)
            total = float(by_cell.sum())
        row = {"err_energy": float(np.sqrt(max(total, 0.0))) / self.norm,
               "err_force": abs(float(np.sum(p)) - self.force) / self.force}
        for name, mask in self.regions.items():
            row[f"err_share_{name}"] = float(by_cell[mask].sum()) / total if total > 0 else np.nan
            row[f"err_energy_{name}"] = float(np.sqrt(max(by_cell[mask].sum(), 0.0))) / self.norm
        w = self.qp.contact.mass
        row["err_pressure"] = float(np.sqrt(np.sum(w * diff ** 2) / np.sum(w * self.pressure ** 2)))
        return row

    def pressure_difference(self, qp: ContactQP, p: np.ndarray) -> np.ndarray:
        """The nodal pressure of ``p`` on ``qp`` minus the reference's, at the reference's
        constrained nodes: ``p``'s pressure (:func:`problems.qp.surface_multipliers` over
        the lumped surface mass; at P2 recovered from the forces,
        :meth:`problems.qp.ContactSurface.pressure`) interpolated P1 along the in-plane coordinates
        (:func:`problems.fem.accuracy.surface_interpolate`; in 3D on ``qp``'s surface
        triangles)."""
        facets = None
        if qp.dim == 3:
            index = {n: i for i, n in enumerate(qp.contact.nodes)}
            facets = np.vectorize(index.get)(qp.contact.facets)
        lam_h = qp.contact.pressure(surface_multipliers(qp, p))
        return acc.surface_interpolate(in_plane(qp), lam_h, self.s, facets) - self.pressure

    def pressure_dual_error(self, qp: ContactQP, p: np.ndarray) -> float:
        """The multiplier error in the dual (energy) norm of the reference's discretisation,
        ``||A^{-1/2} (F_h - F_ref)|| / ||A^{-1/2} F_ref||``
        (:func:`workflows.measure.dual_norm`): each pressure turned into nodal forces on
        both bodies by the reference's constrained rows ``B_C`` (its multiplier basis,
        weighted by the lumped surface mass ``m``), ``F = B_C' (m * pressure)``, the
        compared pressure as :meth:`pressure_difference` interpolates it; the reference's
        own forces are ``B_C' p_ref``. By the trace theorem equivalent to the
        ``H^{-1/2}(Gamma_C)`` norm of the mortar theory (the coupling study's
        docstring). One linear solve with the reference's ``A`` per call (its
        factorisation, or multigrid PCG, built once)."""
        q = self.qp
        if self.quadratic or qp.contact.pressure_map is not None:
            return float("nan")          # P1 only (the class docstring)
        rows = q.B[:q.m_contact]
        m = q.contact.mass
        if self._force_norm is None:
            self._force_norm = dual_norm(q, rows.T @ (m * self.pressure))
        return dual_norm(q, rows.T @ (m * self.pressure_difference(qp, p))) / self._force_norm
