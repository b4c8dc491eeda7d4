"""One Tresca step in the standard forms of the general QP and conic libraries.

A Tresca step (:class:`problems.friction.data.Friction`, its slip bound given) is::

    minimise 1/2 u'Au - f'u + sum_i s_i |T_i u - r_i|   subject to   B u <= g,

``r = previous - offset`` (the slip ``T u + offset - previous`` measured from the previous
state). An unknown ``t_i >= |T_i u - r_i|`` per node with ``s_i > 0`` moves the nonsmooth
term into the constraints, ``x = (u, t)``::

    minimise 1/2 u'Au - f'u + sum_i s_i t_i   subject to   B u <= g,   |T_i u - r_i| <= t_i.

Every form here is one :class:`ConeProgram`, ``min 1/2 x'Px + q'x`` s.t. ``Gx + z = h``,
``z`` in a nonnegative cone followed by second-order cones, the standard form Clarabel
and SCS take directly (the QP libraries take ``Gx <= h``: a nonnegative cone only). Its
multipliers ``y`` (``Px + q + G'y = 0``, ``y`` in the dual cone, which is the cone
itself) map back to the suite's ``(p, lam)`` (``A u + B'p + T'lam = f``,
``|lam_i| <= s_i``, ``lam_i . slip_i = s_i |slip_i|``):

* :func:`contact_program`: no friction, ``P = A``, ``q = -f``, ``G = B``, ``h = g``,
  ``y = p``.
* :func:`split_program` (2D, one tangential row per node): the slip split into two
  nonnegative parts, the rows ``T_i u - t_i <= r_i`` and ``-T_i u - t_i <= -r_i``: a QP.
  Stationarity in ``t_i`` gives ``a_i + b_i = s_i`` for the two rows' multipliers, in ``u``
  ``lam_i = a_i - b_i``; with ``a, b >= 0`` that is ``|lam_i| <= s_i``, and complementarity
  puts ``lam_i = s_i sign(slip_i)`` where the node slips. The dual of this QP is
  the box problem of :func:`solvers.kernels.tresca.tresca_exact`.
* :func:`facet_program` (3D, the faceted law, ``lam_i`` in the inscribed regular
  ``k``-gon ``s_i P_k`` with vertices ``v_j``, :class:`problems.friction.data.Friction`): the
  support function ``s_i max_j v_j . slip_i`` moved into the ``k`` rows
  ``v_j . (T_i u - r_i) - t_i <= 0``: a QP. Stationarity in ``t_i`` gives
  ``sum_j a_ij = s_i`` for the rows' multipliers ``a_ij >= 0``, in ``u``
  ``lam_i = sum_j a_ij v_j``: ``s_i`` times a convex combination of the vertices, so
  ``lam_i in s_i P_k``; complementarity ``a_ij (v_j . slip_i - t_i) = 0`` gives
  ``lam_i . slip_i = s_i t_i = s_i h_Pk(slip_i)``, the faceted slip complementarity.
* :func:`cone_program` (2D and 3D, isotropic): one second-order cone
  ``z_i = (t_i, T_i u - r_i)``, ``|z_i[1:]| <= z_i[0]``, per node with ``s_i > 0``.
  Stationarity in ``t_i`` gives ``y_i[0] = s_i``, the dual cone ``|y_i[1:]| <= s_i``, and
  in ``u`` ``lam_i = -y_i[1:]``; complementarity ``z_i . y_i = 0`` is
  ``s_i t_i = lam_i . slip_i``, the slip complementarity.

A library that minimises a linear objective only (ECOS) is handed any of them through
:func:`epigraph_program`: the quadratic term as second-order cones, one per row of a
factor ``F'F = P``, the multipliers unchanged.

A node with ``s_i = 0`` gets no ``t_i`` and no row (its ``t_i`` would cost nothing and
be unbounded above, which interior-point methods do not take); its ``lam_i`` is zero.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from problems.friction.polygon import polygon_support, polygon_vertices
from problems.qp import ContactQP


@dataclass(frozen=True)
class TrescaStep:
    """One Tresca step (or, without ``T``, the frictionless problem) in plain arrays.

    Attributes
    ----------
    A, f, B, g
        The contact problem ``min 1/2 u'Au - f'u`` s.t. ``Bu <= g``.
    T : (m_t k, n) sparse or None
        Tangential rows, node-major (``k`` per node); ``None``: frictionless.
    r : (m_t k,) array or None
        The slip's reference: the slip of ``u`` is ``T u - r``.
    s : (m_t,) array or None
        Slip bounds ``s_i >= 0``.
    facets : int
        ``0``: isotropic; ``k >= 3``: the faceted law (3D,
        :class:`problems.friction.data.Friction`).
    """

    A: sp.spmatrix
    f: np.ndarray
    B: sp.spmatrix
    g: np.ndarray
    T: sp.spmatrix | None = None
    r: np.ndarray | None = None
    s: np.ndarray | None = None
    facets: int = 0

    @property
    def components(self) -> int:
        """``k``: tangential rows per node (0 without friction)."""
        return 0 if self.T is None else self.T.shape[0] // max(len(self.s), 1)

    @property
    def bounded(self) -> np.ndarray:
        """The nodes with ``s_i > 0`` (the only ones with a ``t_i`` in the forms)."""
        return np.zeros(0, dtype=int) if self.s is None else np.flatnonzero(self.s > 0)

    def rows(self, nodes: np.ndarray) -> np.ndarray:
        """The tangential rows of ``nodes`` (node-major: ``i k + j``)."""
        k = self.components
        return (np.asarray(nodes)[:, None] * k + np.arange(k)).ravel()


def tresca_step(qp: ContactQP) -> TrescaStep:
    """The step ``qp`` in plain arrays (``r = previous - offset``)."""
    fr = qp.friction
    if fr is None:
        return TrescaStep(qp.A, qp.f, qp.B, qp.g)
    return TrescaStep(qp.A, qp.f, qp.B, qp.g, sp.csr_matrix(fr.T), fr.previous - fr.offset,
                      fr.slip_bound, fr.facets)


@dataclass(frozen=True)
class ConeProgram:
    """``min 1/2 x'Px + q'x`` s.t. ``Gx + z = h``, ``z`` in ``K``: the first
    ``nonnegative`` rows a nonnegative cone, then one second-order cone
    (``|z[1:]| <= z[0]``) of each size in ``cones``, in order.

    ``kind``: ``"contact"``, ``"split"``, ``"facet"`` or ``"cone"`` (which form, for the map of the
    multipliers); ``n``: the unknowns ``u`` (``x[:n]``); ``bounded``: the nodes with a
    ``t_i`` (``x[n:]``, in this order).
    """

    P: sp.csc_matrix
    q: np.ndarray
    G: sp.csc_matrix
    h: np.ndarray
    nonnegative: int
    cones: tuple
    kind: str
    n: int
    bounded: np.ndarray


def contact_program(step: TrescaStep) -> ConeProgram:
    """The frictionless problem as it is: ``P = A``, ``q = -f``, ``G = B``, ``h = g``."""
    return ConeProgram(P=sp.csc_matrix(step.A), q=-step.f, G=sp.csc_matrix(step.B), h=step.g,
                       nonnegative=step.B.shape[0], cones=(), kind="contact", n=step.A.shape[0],
                       bounded=np.zeros(0, dtype=int))


def _with_t(step: TrescaStep) -> tuple[sp.csc_matrix, np.ndarray, np.ndarray]:
    """``P = diag(A, 0)``, ``q = (-f, s_b)`` and the bounded nodes ``b``."""
    b = step.bounded
    P = sp.block_diag([sp.csc_matrix(step.A), sp.csc_matrix((b.size, b.size))], format="csc")
    return P, np.concatenate([-step.f, step.s[b]]), b


def split_program(step: TrescaStep) -> ConeProgram:
    """2D: the slip split into nonnegative parts (module docstring): a QP in ``(u, t)``
    with the rows ``B u <= g``, ``T_b u - t <= r_b``, ``-T_b u - t <= -r_b``.

    Raises
    ------
    ValueError
        With more than one tangential row per node (isotropic friction in 3D is no QP:
        :func:`cone_program`).
    """
    if step.components != 1:
        raise ValueError(f"split_program: {step.components} tangential rows per node; "
                         "allowed: 1 (2D); isotropic 3D friction is a cone program")
    P, q, b = _with_t(step)
    Tb, rb, eye = step.T[b], step.r[b], sp.identity(b.size, format="csr")
    m = step.B.shape[0]
    G = sp.bmat([[step.B, sp.csr_matrix((m, b.size))], [Tb, -eye], [-Tb, -eye]], format="csc")
    return ConeProgram(P=P, q=q, G=G, h=np.concatenate([step.g, rb, -rb]), nonnegative=G.shape[0],
                       cones=(), kind="split", n=step.A.shape[0], bounded=b)


def _facet_rows(step: TrescaStep, b: np.ndarray) -> sp.csr_matrix:
    """``kron(I, V)``: per bounded node the ``k`` vertices of ``P_k`` as rows acting on
    its two tangential entries (node-major), ``(b.size k, 2 b.size)``."""
    return sp.kron(sp.identity(b.size, format="csr"), sp.csr_matrix(polygon_vertices(step.facets)),
                   format="csr")


def facet_program(step: TrescaStep) -> ConeProgram:
    """3D, the faceted law (module docstring): a QP in ``(u, t)`` with the rows
    ``B u <= g`` and, per bounded node ``i`` and vertex ``v_j`` of ``P_k``,
    ``v_j . T_i u - t_i <= v_j . r_i`` (node-major: row ``i k + j``).

    Raises
    ------
    ValueError
        For a step without facets (``step.facets`` 0) or not in 3D.
    """
    if not step.facets or step.components != 2:
        raise ValueError(f"facet_program: facets = {step.facets}, {step.components} tangential "
                         "rows per node; allowed: facets >= 3 with 2 rows per node (3D)")
    P, q, b = _with_t(step)
    k, m = step.facets, step.B.shape[0]
    V = _facet_rows(step, b)
    Tb, rb = step.T[step.rows(b)], step.r[step.rows(b)]
    t_rows = sp.kron(sp.identity(b.size, format="csr"), np.ones((k, 1)), format="csr")
    G = sp.bmat([[step.B, sp.csr_matrix((m, b.size))], [V @ Tb, -t_rows]], format="csc")
    return ConeProgram(P=P, q=q, G=G, h=np.concatenate([step.g, V @ rb]), nonnegative=G.shape[0],
                       cones=(), kind="facet", n=step.A.shape[0], bounded=b)


def cone_program(step: TrescaStep) -> ConeProgram:
    """Isotropic Tresca (2D or 3D) as a second-order cone program in ``(u, t)``: the
    rows ``B u <= g`` (nonnegative cone), then per bounded node ``i`` the cone
    ``(t_i, T_i u - r_i)`` written ``G x + z = h`` as the rows ``(0, -e_i)`` and
    ``(-T_i, 0)`` with ``h = (0, -r_i)``."""
    P, q, b = _with_t(step)
    k, m, n = step.components, step.B.shape[0], step.A.shape[0]
    width = k + 1
    head = np.arange(b.size) * width                     # each cone's first row
    t_rows = sp.csr_matrix((-np.ones(b.size), (head, n + np.arange(b.size))),
                           shape=(b.size * width, n + b.size))
    slip_at = (head[:, None] + 1 + np.arange(k)).ravel()   # the cones' other rows
    Tb = sp.coo_matrix(step.T[step.rows(b)])
    slip_rows = sp.csr_matrix((-Tb.data, (slip_at[Tb.row], Tb.col)),
                              shape=(b.size * width, n + b.size))
    h_cones = np.zeros(b.size * width)
    h_cones[slip_at] = -step.r[step.rows(b)]
    G = sp.vstack([sp.hstack([step.B, sp.csr_matrix((m, b.size))]), t_rows + slip_rows],
                  format="csc")
    return ConeProgram(P=P, q=q, G=G, h=np.concatenate([step.g, h_cones]), nonnegative=m,
                       cones=(width,) * b.size, kind="cone", n=n, bounded=b)


def standard_program(step: TrescaStep) -> ConeProgram:
    """The form a library is handed: the frictionless problem as it is, a 2D Tresca step
    split (a QP every library takes), a 3D one as a cone program (second-order cones),
    a faceted one as a QP (:func:`facet_program`)."""
    if step.T is None:
        return contact_program(step)
    if step.facets:
        return facet_program(step)
    return split_program(step) if step.components == 1 else cone_program(step)


def epigraph_program(program: ConeProgram, F: sp.spmatrix) -> ConeProgram:
    """``program`` with a linear objective, for a library that minimises ``c'x`` only
    (ECOS): the quadratic term moved into second-order cones, one per row of ``F``.

    With ``P = F'F`` (``F`` of shape ``(k, N)``, ``N = len(q)``, rows ``F_j``) and one more
    unknown ``w_j`` per row, ``x' = (x, w)``::

        minimise  q'x + sum_j w_j   subject to   G x + z = h,  z in K,
                  1/2 (F_j x)^2 <= w_j   (j = 1..k).

    Each epigraph constraint is the second-order cone of size 3

        ``z_j = ((1 + w_j)/sqrt2, (1 - w_j)/sqrt2, F_j x)``,  ``|z_j[1:]| <= z_j[0]``,

    since ``((1 + w)^2 - (1 - w)^2) / 2 = 2 w``: ``(F_j x)^2 + (1 - w_j)^2/2 <=
    (1 + w_j)^2/2`` is ``1/2 (F_j x)^2 <= w_j`` (which makes ``w_j >= 0`` and so
    ``z_j[0] >= 0``). In the form ``G_j x' + z_j = h_j`` its rows are ``(0, -e_j/sqrt2)``,
    ``(0, e_j/sqrt2)``, ``(-F_j, 0)`` with ``h_j = (1/sqrt2, 1/sqrt2, 0)``. At a minimiser
    ``w_j = 1/2 (F_j x)^2`` (a larger ``w_j`` costs more), so ``sum_j w_j = 1/2 x'Px``:
    the optimal values and ``x`` are the program's.

    The multipliers ``y`` of the program's rows are unchanged. Stationarity of the
    lifted program, ``c + G'y + sum_j G_j'y_j = 0`` with ``c = (q, 1)``, reads in ``w_j``
    ``y_j[0] - y_j[1] = sqrt2`` and in ``x`` ``q + G'y - sum_j F_j' y_j[2] = 0``. So
    ``y_j != 0``, and ``z_j != 0`` (``z_j[0] + z_j[1] = sqrt2``): complementarity
    ``z_j . y_j = 0`` of two nonzero points of the cone puts both on its boundary with
    ``y_j = gamma_j (z_j[0], -z_j[1:])``, ``gamma_j >= 0``. The ``w_j`` row gives
    ``gamma_j (z_j[0] + z_j[1]) = sqrt2``, ``gamma_j = 1``, hence ``y_j[2] = -F_j x`` and
    ``P x + q + G'y = 0``: the program's own KKT conditions.

    One cone per row, not one cone ``1/2 |F x|^2 <= w`` of size ``k + 2``: the same
    program, but ECOS stops on the single large cone with "numerical problems" at
    circle_square level 1 (8,288 unknowns) and solves the small ones.

    Returns
    -------
    ConeProgram
        ``P = 0`` (``N + k`` unknowns, the ``w_j`` last), ``q = (q, 1, ..., 1)``, the
        program's rows followed by the epigraph cones (``cones + (3,) * k``); ``kind``,
        ``n`` and ``bounded`` as given. Its first ``N`` unknowns and first ``len(h)``
        multipliers are the program's.
    """
    F = sp.coo_matrix(F)
    k, N = F.shape
    if N != len(program.q):
        raise ValueError(f"epigraph_program: F has {N} columns; allowed: {len(program.q)} "
                         "(the program's unknowns)")
    root = 1.0 / np.sqrt(2.0)
    j = np.arange(k)
    rows = np.concatenate([3 * j, 3 * j + 1, 3 * F.row + 2])
    cols = np.concatenate([N + j, N + j, F.col])
    values = np.concatenate([np.full(k, -root), np.full(k, root), -F.data])
    epigraph = sp.csr_matrix((values, (rows, cols)), shape=(3 * k, N + k))
    G = sp.vstack([sp.hstack([program.G, sp.csr_matrix((program.G.shape[0], k))]), epigraph],
                  format="csc")
    h_cones = np.zeros(3 * k)
    h_cones[3 * j] = h_cones[3 * j + 1] = root
    return ConeProgram(P=sp.csc_matrix((N + k, N + k)),
                       q=np.concatenate([program.q, np.ones(k)]),
                       G=G, h=np.concatenate([program.h, h_cones]),
                       nonnegative=program.nonnegative, cones=(*program.cones, *(3,) * k),
                       kind=program.kind, n=program.n, bounded=program.bounded)


def lift(step: TrescaStep, program: ConeProgram, u: np.ndarray) -> np.ndarray:
    """The point ``x = (u, t)`` of ``program`` with ``t_i = |T_i u - r_i|`` (the least
    feasible ``t``): its objective is the step's energy (a guess, or a check)."""
    u = np.asarray(u, dtype=float)
    if program.kind == "contact":
        return u
    rows = step.rows(program.bounded)
    slip = (step.T[rows] @ u - step.r[rows]).reshape(program.bounded.size, -1)
    if program.kind == "facet":
        return np.concatenate([u, polygon_support(slip, step.facets)])
    return np.concatenate([u, np.linalg.norm(slip, axis=1)])


def program_multipliers(step: TrescaStep, program: ConeProgram,
                        p: np.ndarray, lam: np.ndarray | None) -> np.ndarray:
    """The multipliers ``y`` of ``program`` that map back to ``(p, lam)`` (the inverse of
    :func:`step_multipliers`; with ``|lam_i| <= s_i`` in the dual cone): split,
    ``a = (s + lam) / 2``, ``b = (s - lam) / 2``; cone, ``y_i = (s_i, -lam_i)``; facet
    (``lam_i in s_i P_k``), :func:`facet_weights`."""
    p = np.asarray(p, dtype=float)
    if program.kind == "contact":
        return p
    b, k = program.bounded, step.components
    lam_b = np.asarray(lam, dtype=float)[step.rows(b)]
    if program.kind == "split":
        s = step.s[b]
        return np.concatenate([p, (s + lam_b) / 2, (s - lam_b) / 2])
    if program.kind == "facet":
        return np.concatenate([p, facet_weights(lam_b.reshape(b.size, 2), step.s[b],
                                                step.facets).ravel()])
    cones = np.concatenate([step.s[b][:, None], -lam_b.reshape(b.size, k)], axis=1)
    return np.concatenate([p, cones.ravel()])


def facet_weights(lam: np.ndarray, s: np.ndarray, k: int) -> np.ndarray:
    """Multipliers ``a_i >= 0`` of the ``k`` facet rows of each node (``(N, k)``) with
    ``sum_j a_ij = s_i`` and ``sum_j a_ij v_j = lam_i`` for ``lam_i in s_i P_k``
    (:func:`program_multipliers`): ``lam_i / s_i = alpha v_j + beta v_j+1`` in the
    triangle ``(0, v_j, v_j+1)`` of its angle, and the rest ``1 - alpha - beta`` spread
    evenly over all ``k`` vertices (they sum to zero)::

        a_i = s_i (alpha e_j + beta e_j+1 + (1 - alpha - beta) / k)
    """
    lam, s = np.asarray(lam, dtype=float), np.asarray(s, dtype=float)
    v = polygon_vertices(k)
    angle = np.mod(np.arctan2(lam[:, 1], lam[:, 0]), 2 * np.pi)
    j = np.minimum((angle / (2 * np.pi / k)).astype(int), k - 1)
    first, second = v[j], v[(j + 1) % k]
    det = first[:, 0] * second[:, 1] - first[:, 1] * second[:, 0]
    x = lam / np.where(s > 0, s, 1.0)[:, None]
    alpha = (x[:, 0] * second[:, 1] - x[:, 1] * second[:, 0]) / det
    beta = (first[:, 0] * x[:, 1] - first[:, 1] * x[:, 0]) / det
    rows = np.arange(len(lam))
    a = np.repeat(((1.0 - alpha - beta) / k)[:, None], k, axis=1)
    a[rows, j] += alpha
    a[rows, (j + 1) % k] += beta
    return s[:, None] * a


def step_multipliers(step: TrescaStep, program: ConeProgram,
                     y: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """``(p, lam)`` of the program's multipliers ``y`` (module docstring): ``p`` the
    normal rows' ``y``; split, ``lam_i = a_i - b_i``; facet, ``lam_i = sum_j a_ij v_j``;
    cone, ``lam_i = -y_i[1:]``;
    ``lam_i = 0`` at the nodes without a ``t_i``. ``lam`` is ``None`` without friction."""
    y = np.asarray(y, dtype=float)
    m = step.B.shape[0]
    if program.kind == "contact":
        return y[:m], None
    b, k = program.bounded, step.components
    lam = np.zeros(step.T.shape[0])
    if program.kind == "split":
        lam[step.rows(b)] = y[m:m + b.size] - y[m + b.size:m + 2 * b.size]
    elif program.kind == "facet":
        lam[step.rows(b)] = _facet_rows(step, b).T @ y[m:]
    else:
        lam[step.rows(b)] = -y[m:].reshape(b.size, k + 1)[:, 1:].ravel()
    return y[:m], lam
