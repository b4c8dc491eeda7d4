"""What defines a frictional step: the friction laws, the :class:`Friction` data a
:class:`problems.qp.ContactQP` carries on its constrained rows (tangential rows, slip
bounds, the previous state, the load path of :class:`LoadStep`), and the allowed facet
counts of the faceted law (its polygon: :mod:`problems.friction.polygon`).

The step is the Tresca problem (thesis Alg. 7.1, (7.14) for the rows; Coulomb's
``s = mu p`` is a fixed point over such steps)::

    minimise 1/2 u'Au - f'u + sum_i s_i |slip_i(u)|   subject to   B u <= g
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from problems.friction.polygon import polygon_gauge, polygon_support, project_polygon


#: The friction laws a ContactQP can carry (``none``: the thesis's frictionless problem).
FRICTION_LAWS = ("none", "tresca", "coulomb")

#: The fewest facets of a faceted friction law (a polygon needs three); ``0``: isotropic.
MIN_FRICTION_FACETS = 3


@dataclass
class LoadStep:
    """One step of a quasi-static load path: the ContactQP's data of that step.

    Attributes
    ----------
    f : (n,) array
        Load vector of the step (with the step's prescribed displacements lifted).
    g : (m,) array
        Gaps of the step.
    offset : (m_contact k,) array
        Tangential relative displacement of the step's prescribed values
        (``T_full @ u_fixed``): the step's relative tangential displacement is
        ``T u + offset``.
    u_fixed : (N dim,) array or None
        The step's prescribed values (``ContactQP.u_fixed``); None: those of the
        ContactQP that holds the path.
    """

    f: np.ndarray
    g: np.ndarray
    offset: np.ndarray
    u_fixed: np.ndarray | None = None

    def toward(self, other: "LoadStep", t: float) -> "LoadStep":
        """The step ``t`` of the way from this step to ``other``: every datum is affine
        in the prescribed values, so this is exact along a path that moves them
        proportionally."""
        mix = lambda a, b: None if a is None or b is None else a + t * (b - a)
        return LoadStep(mix(self.f, other.f), mix(self.g, other.g),
                        mix(self.offset, other.offset), mix(self.u_fixed, other.u_fixed))


@dataclass
class Friction:
    """Tresca or Coulomb friction on the constrained rows: ``k = d - 1`` tangential rows
    per constrained node (2D: one, 3D: two).

    The tangential rows of constrained node ``i`` are ``t_ij . (u(P) - sum_k w_k u(P_k))``,
    the same interpolation (Alg. 7.1, (7.14)) as its normal row with the unit tangents
    ``t_ij`` orthogonal to the row's direction ``n_i`` (and, in 3D, to each other). Rows
    and every tangential vector are node-major: entry ``i k + j`` belongs to node ``i``,
    tangent ``j``. The slip of ``u`` is measured from the previous state of the load
    path::

        slip(u) = T u + offset - previous

    and one step is the Tresca problem (isotropic: ``|.|`` is the Euclidean norm of a
    node's ``k``-vector, the absolute value in 2D)::

        minimise 1/2 u'Au - f'u + sum_i s_i |slip_i(u)|   subject to   B u <= g

    with KKT conditions ``A u + B'p + T'lam = f``, ``|lam_i| <= s_i``,
    ``lam_i . slip_i = s_i |slip_i|`` (and the normal ones). Coulomb friction sets
    ``s_i = mu p_i`` by a fixed point over Tresca problems.

    The faceted law (3D, ``facets = k >= 3``) replaces the disc ``|lam_i| <= s_i`` by
    ``s_i P_k``, ``P_k`` the regular ``k``-gon inscribed in the unit circle with one vertex
    along the first tangent (:func:`problems.friction.polygon.polygon_vertices`):
    inscribed, as the pyramid approximations of engineering codes are, so that ``P_k``
    lies inside the disc, its dissipation is a lower bound of the isotropic one and it
    grows to it as ``k`` grows (the gap is ``1 - cos(pi / k)`` relative, ``O(k^-2)``). Its
    primal term is the support function of ``s_i P_k``::

        s_i h_Pk(slip_i) = max_{l in s_i P_k} l . slip_i = s_i max_j v_j . slip_i

    (a linear function is largest at a vertex ``v_j``), so the step is

        minimise 1/2 u'Au - f'u + sum_i s_i h_Pk(slip_i(u))   subject to   B u <= g

    and, as ``s_i h_Pk`` is the support function of ``s_i P_k`` (its subdifferential at
    ``x`` is the face of ``s_i P_k`` where ``l . x`` is largest), its KKT conditions are
    ``A u + B'p + T'lam = f``, ``lam_i in s_i P_k`` (:meth:`gauge` ``<= s_i``),
    ``lam_i . slip_i = s_i h_Pk(slip_i)``. The dual is the isotropic one with the discs
    replaced by ``s_i P_k`` (``min 1/2 y'Sy - c'y``, ``p >= 0``, ``lam_i in s_i P_k``,
    :mod:`solvers.kernels.tresca`). In 2D the law is already polyhedral (the disc is the
    interval ``[-s_i, s_i]``): ``facets`` is ``0`` there.

    Attributes
    ----------
    law : {"tresca", "coulomb"}
    mu : float
        Friction coefficient (Coulomb; for Tresca it documents how ``slip_bound`` was made).
    T : (m_contact k, n) sparse
        Tangential rows on the free DOFs (node-major).
    tangent : (m_contact k, d) array
        Unit tangent of each tangential row.
    slip_bound : (m_contact,) array
        ``s_i >= 0``, a force (the bound on ``|lam_i|``).
    offset : (m_contact k,) array
        ``T_full @ u_fixed`` of this step's prescribed values.
    previous : (m_contact k,) array
        Relative tangential displacement ``T u_prev + offset_prev`` of the previous state.
    path : tuple of LoadStep
        The scene's load path (normal load first, then the tangential step); the
        ContactQP's ``f``, ``g`` and ``offset`` are those of one of its steps.
    facets : int
        ``0``: isotropic (the disc); ``k >= 3`` (3D only): the faceted law, ``lam_i`` in
        the inscribed regular ``k``-gon ``s_i P_k``.
    """

    law: str
    mu: float
    T: sp.spmatrix
    tangent: np.ndarray
    slip_bound: np.ndarray
    offset: np.ndarray
    previous: np.ndarray
    path: tuple = ()
    facets: int = 0

    @property
    def components(self) -> int:
        """``k``: tangential rows per constrained node (``d - 1``)."""
        return self.T.shape[0] // max(len(self.slip_bound), 1)

    def blocks(self, v: np.ndarray) -> np.ndarray:
        """The node-major vector ``v`` (``m_contact k`` entries) as ``(m_contact, k)``."""
        return np.asarray(v, dtype=float).reshape(-1, self.components)

    def magnitude(self, v: np.ndarray) -> np.ndarray:
        """Euclidean norm of each node's ``k``-vector of ``v`` (2D: ``|v_i|``)."""
        v = np.asarray(v, dtype=float)
        return np.abs(v) if self.components == 1 else np.linalg.norm(self.blocks(v), axis=1)

    def inner(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Per node ``a_i . b_i`` of two node-major vectors (2D: ``a_i b_i``)."""
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        return a * b if self.components == 1 else np.einsum("ij,ij->i", self.blocks(a),
                                                             self.blocks(b))

    def dissipation(self, slip: np.ndarray) -> np.ndarray:
        """Per node the dissipation per unit slip bound of the slip ``slip``: ``|slip_i|``
        (isotropic), ``h_Pk(slip_i) = max_j v_j . slip_i`` (faceted)."""
        if not self.facets:
            return self.magnitude(slip)
        return polygon_support(self.blocks(slip), self.facets)

    def gauge(self, lam: np.ndarray) -> np.ndarray:
        """Per node the size of ``lam_i`` the slip bound limits: ``|lam_i|`` (isotropic),
        the gauge of ``P_k`` (faceted, :func:`problems.friction.polygon.polygon_gauge`):
        ``lam_i`` is admissible exactly when it is ``<= s_i``."""
        if not self.facets:
            return self.magnitude(lam)
        return polygon_gauge(self.blocks(lam), self.facets)

    def clip(self, lam: np.ndarray) -> np.ndarray:
        """``lam`` projected onto the friction discs ``|lam_i| <= s_i`` (2D: the box
        ``[-s_i, s_i]``; 3D: each node's vector scaled back radially; faceted: the
        Euclidean projection onto ``s_i P_k``,
        :func:`problems.friction.polygon.project_polygon`)."""
        lam, s = np.asarray(lam, dtype=float), self.slip_bound
        if self.components == 1:
            return np.clip(lam, -s, s)
        if self.facets:
            return project_polygon(self.blocks(lam), s, self.facets).ravel()
        size = self.magnitude(lam)
        scale = np.where(size > s, s / np.where(size > 0, size, 1.0), 1.0)
        return (self.blocks(lam) * scale[:, None]).ravel()

    def tangential_force(self, lam: np.ndarray) -> np.ndarray:
        """The total tangential force ``sum_ij lam_ij t_ij`` (``(d,)``) of the multipliers
        ``lam``."""
        return (np.asarray(lam, dtype=float)[:, None] * self.tangent).sum(axis=0)

    def total_force(self, lam: np.ndarray) -> float:
        """``Q``: the size of the total tangential force of the multipliers ``lam``
        (2D: ``|sum_i lam_i|``; 3D: the norm of :meth:`tangential_force`)."""
        if self.components == 1:
            return abs(float(np.asarray(lam, dtype=float).sum()))
        return float(np.linalg.norm(self.tangential_force(lam)))

    def slip(self, u: np.ndarray) -> np.ndarray:
        """Tangential slip ``T u + offset - previous`` of ``u`` in this step."""
        return self.T @ np.asarray(u, dtype=float) + self.offset - self.previous

    def states(self, lam: np.ndarray, tol: float) -> np.ndarray:
        """Stick/slip state of each constrained node from its tangential multiplier
        ``lam``: ``free`` where ``s_i = 0`` (no tangential force can act: out of contact
        under Coulomb friction), ``stick`` where ``|lam_i|`` lies inside its bound by more
        than ``tol max(s)`` (the slip is then zero), ``slip`` where it is at the bound.
        """
        s = self.slip_bound
        margin = tol * (float(s.max()) if s.size else 0.0)
        inside = s - self.gauge(lam) > margin
        return np.where(s > 0, np.where(inside, "stick", "slip"), "free")


def check_facets(facets, dim: int, error: type, name: str = "friction.facets") -> None:
    """Raise ``error`` naming ``name`` unless ``facets`` is an allowed facet count in
    ``dim`` dimensions: ``0`` (isotropic), or in 3D an integer ``>= 3``
    (:data:`MIN_FRICTION_FACETS`); in 2D the law is already polyhedral (an interval)."""
    whole = isinstance(facets, (int, np.integer)) and not isinstance(facets, bool)
    if whole and (facets == 0 or (dim == 3 and facets >= MIN_FRICTION_FACETS)):
        return
    allowed = (f"0 (isotropic) or an integer >= {MIN_FRICTION_FACETS} (the inscribed regular "
               "k-gon)" if dim == 3 else
               "0 (in 2D the friction law is already polyhedral: the interval [-s, s])")
    raise error(f"{name} = {facets!r} is not allowed in {dim}D; allowed: {allowed}")




def coulomb_step(qp):
    """A frictional step's Coulomb step as one problem: the same rows, previous state and
    ``mu``, with Coulomb's law ``s = mu p`` in place of the given slip bounds
    (``friction.law = "coulomb"``; the bounds stay as the fixed point's starting guess).

    A solver that takes Coulomb's law directly (``stats["friction"]`` is
    :data:`solvers.base.COULOMB_MONOLITHIC`) solves it as one problem and is verified on
    the Tresca step of its own bound ``mu p`` (:func:`solvers.certificate.judged_step`);
    any other solver solves the Tresca step of the given bounds. Its fclib form is the
    same problem (:func:`solvers.kernels.fclib_form.global_problem`). A test set's
    Coulomb family is the fixed point's final Tresca step (its bounds ``mu p`` of the
    reference, rounded); this is its Coulomb step.

    Raises
    ------
    ValueError
        For a frictionless problem, a faceted law or ``mu = 0``, naming the parameter.
    """
    from dataclasses import replace

    fr = getattr(qp, "friction", None)
    if fr is None:
        raise ValueError("parameter 'qp': a frictionless problem has no Coulomb step; "
                         "allowed: a frictional step")
    if fr.facets:
        raise ValueError(f"parameter 'qp': friction.facets = {fr.facets}; allowed: 0 (Coulomb's "
                         "law is the isotropic cone)")
    if not fr.mu > 0:
        raise ValueError(f"parameter 'qp': friction.mu = {fr.mu!r}; allowed: mu > 0")
    return replace(qp, friction=replace(fr, law="coulomb"))
