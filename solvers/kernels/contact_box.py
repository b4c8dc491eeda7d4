"""Nodal contact constraints as bounds on single unknowns: the change of variables of
Krause and Wohlmuth, what truncated nonsmooth Newton multigrid needs (:mod:`solvers.tnnmg`).

Each row ``i`` of ``B`` (Alg. 7.1, (7.14)) constrains one node ``s_i`` of the constrained
surface against the interpolant on an opposing facet::

    B_i u = b_i' u_s + sum_j B_ij u_j  <=  g_i        (j: the opposing facet's unknowns)

With ``beta_i = |b_i|`` and ``n_i = b_i / beta_i`` the new unknowns at ``s_i`` are the
relative normal displacement and the tangential complements (a Householder frame
``H_i = [n_i, t_i...]``, symmetric and orthogonal, ``H_i e_1 = n_i``)::

    v_s = H_i u_s + e_1 (sum_j B_ij u_j) / beta_i,    so that    B_i u = beta_i v_s[0],

and every other unknown is kept (``v_j = u_j``). The inverse is
``u_s = H_i v_s - n_i (sum_j B_ij v_j) / beta_i``. Row ``i`` becomes the bound
``v_s[0] <= g_i / beta_i`` on one unknown; ``u = T v`` with ``T`` sparse (a constrained
node's rows reach its opposing facet's unknowns), so ``T' A T`` stays sparse; the
energy, the feasible set and the minimiser are the same (exact, up to round-off).

The transformation needs what nodal constraints give: each row's constrained node has
unknowns of its own that no other row touches (one row per node). The scene names that
node (``qp.contact.nodes``); without contact-surface data (an exported or generated
problem) it is the row's node that no other row touches, the one with the largest
coefficients where there are several. Stabilised problems (Sect. 7.5, reverse rows on
the opposing surface; they reach the solver in slack form) and mortar rows with standard
multipliers (weighted gaps: a non-diagonal ``D`` shares constrained nodes between rows) do
not have that structure; :func:`check_structure` says why. Mortar rows with dual
multipliers (:mod:`problems.fem.mortar`, ``D`` diagonal) have it: row ``i`` moves its
constrained node by ``n`` and the opposing surface's unknowns by the mortar weights, the
form of a nodal row.

Tangential rows (2D friction, :class:`problems.friction.data.Friction`) become coordinates the same
way. Row ``i``'s tangential row ``T_i u = tau_i' u_s + sum_j T_ij u_j`` has the same
constrained node and the same opposing unknowns as its normal row, with ``tau_i``
orthogonal to ``n_i``; the Householder frame's second column ``H_i e_2`` is
``sigma_i tau_i / gamma_i`` (``gamma_i = |tau_i|``, ``sigma_i = +-1``), so with
``theta_i = sigma_i gamma_i`` the second new unknown at ``s_i``::

    v_s = H_i u_s + e_1 (sum_j B_ij u_j) / beta_i + e_2 (sum_j T_ij u_j) / theta_i

gives ``T_i u = theta_i v_s[1]``, and the inverse is ``u_s = H_i v_s - n_i (sum_j B_ij
v_j) / beta_i - tau_i (sum_j T_ij v_j) / gamma_i^2``. The tangential slip is then a
function of one unknown, and Tresca's term ``s_i |T_i u - r_i|`` is
``s_i gamma_i |v_s[1] - r_i / theta_i|``: separable by node blocks, as truncated
nonsmooth Newton multigrid needs (:mod:`solvers.tnnmg`).

In 3D each constrained node has two tangential rows (node-major), ``tau_i1, tau_i2``
orthogonal to ``n_i``, to each other and of one length ``gamma_i``; the Householder frame's
columns ``H_i e_2, H_i e_3`` span the same plane, so ``Theta_i = [tau_i1; tau_i2] [H_i e_2,
H_i e_3] = gamma_i R_i`` with ``R_i`` orthogonal (2D: ``R_i = 1``, ``gamma_i`` signed:
``theta_i``). With the rows' opposing parts ``t_i = (sum_j T_i1,j u_j, sum_j T_i2,j u_j)``::

    v_s = H_i u_s + e_1 (sum_j B_ij u_j) / beta_i + [e_2, e_3] Theta_i^{-1} t_i

gives ``T_i u = Theta_i v_s[1:3]``, and the inverse is ``u_s = H_i v_s - n_i (sum_j B_ij
v_j) / beta_i - [H_i e_2, H_i e_3] Theta_i^{-1} t_i``. As ``R_i`` keeps lengths, Tresca's
isotropic term ``s_i |T_i u - r_i|`` is ``s_i gamma_i |v_s[1:3] - R_i' r_i / gamma_i|``:
the Euclidean norm of the node's own two unknowns, again separable by node blocks.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from problems.qp import ContactQP


class TransformationError(ValueError):
    """The constraints are not nodal constraints with one row per constrained node."""


@dataclass
class BoxTransformation:
    """``u = T v`` turning ``B u <= g`` into ``v[pivot] <= upper`` (module docstring).

    Attributes
    ----------
    D, D_inv : (len(changed), n) csr
        The :attr:`changed` rows of ``T - I`` and ``T^{-1} - I``: ``u = T v`` and
        ``v = T^{-1} u`` differ from the identity there only (:attr:`T`, :attr:`T_inv`
        build the whole matrices, for tests and export).
    pivot : (m,) int array
        The unknown of ``v`` that row ``i`` bounds (first unknown of its node block).
    scale : (m,) array
        ``beta_i``: ``B_i u = beta_i v[pivot_i]``.
    upper : (m,) array
        ``g_i / beta_i``.
    node_ptr, node_dofs : int arrays
        The unknowns grouped by mesh node (block ``k`` is
        ``node_dofs[node_ptr[k]:node_ptr[k+1]]``, components in order).
    block_row : (n_blocks,) int array
        The row of ``B`` bounding block ``k``'s first unknown, or -1.
    changed : int array
        The constrained nodes' unknowns (sorted): the only rows where ``T`` and ``T_inv``
        differ from the identity (:meth:`operator`, :meth:`prolongation`).
    tangential_pivot : (m * k,) int array
        With tangential rows (:func:`box_transformation`; ``k = dim - 1`` per row, node-major):
        the unknowns of ``v`` that row ``i``'s tangential rows read (the second and, in 3D,
        third unknowns of its node block); empty without.
    tangential_scale : (m,) array
        ``theta_i``: ``T_i u = theta_i R_i v[tangential_pivot_i]`` (2D: signed, ``R_i = 1``;
        3D: ``gamma_i > 0``); empty without.
    tangential_frame : (m, k, k) array
        ``R_i``, orthogonal (the module docstring's ``Theta_i = theta_i R_i``); empty without.
    """

    D: sp.csr_matrix
    D_inv: sp.csr_matrix
    pivot: np.ndarray
    scale: np.ndarray
    upper: np.ndarray
    node_ptr: np.ndarray
    node_dofs: np.ndarray
    block_row: np.ndarray
    changed: np.ndarray
    tangential_pivot: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    tangential_scale: np.ndarray = field(default_factory=lambda: np.zeros(0))
    tangential_frame: np.ndarray = field(default_factory=lambda: np.zeros((0, 1, 1)))

    def operator_update(self, A: sp.spmatrix) -> sp.csr_matrix:
        """``T' A T - A`` for a symmetric ``A`` (sorted CSR), without a product of two
        ``n x n`` matrices: with ``T = I + D`` (``D`` nonzero on the :attr:`changed` rows
        ``S`` only), ``T'AT = A + X + X' + D_S' A_SS D_S`` with ``X = D_S' A_S``. Its
        rows are those of ``S``, the opposing facets' unknowns and their neighbours: a
        solver keeps ``A`` and this (:meth:`operator` adds them)."""
        A = sp.csr_matrix(A)
        S = self.changed
        if S.size == 0:
            return sp.csr_matrix(A.shape)
        D_S = self.D
        A_S = A[S]
        X = sp.csr_matrix(D_S.T @ A_S)
        update = sp.csr_matrix(X + X.T + D_S.T @ (A_S[:, S] @ D_S))
        update.sort_indices()
        return update

    def operator(self, A: sp.spmatrix) -> sp.csr_matrix:
        """``T' A T`` (sorted CSR; :meth:`operator_update`)."""
        out = sp.csr_matrix(sp.csr_matrix(A) + self.operator_update(A))
        out.sort_indices()
        return out

    def prolongation(self, P: sp.spmatrix) -> sp.csr_matrix:
        """``T_inv P`` (a coarse space in the new unknowns): ``P`` with its :attr:`changed`
        rows replaced."""
        P = sp.csr_matrix(P)
        S = self.changed
        if S.size == 0:
            return P.copy()
        update = sp.coo_matrix(self.D_inv @ P)
        return sp.csr_matrix(P + sp.csr_matrix((update.data, (S[update.row], update.col)),
                                               shape=P.shape))

    def _whole(self, rows: sp.csr_matrix) -> sp.csr_matrix:
        n = rows.shape[1]
        coo = rows.tocoo()
        scattered = sp.csr_matrix((coo.data, (self.changed[coo.row], coo.col)), shape=(n, n))
        return sp.csr_matrix(sp.identity(n, format="csr") + scattered)

    @property
    def T(self) -> sp.csr_matrix:
        """``T`` as a whole ``(n, n)`` matrix (built on each call)."""
        return self._whole(self.D)

    @property
    def T_inv(self) -> sp.csr_matrix:
        """``T^{-1}`` as a whole ``(n, n)`` matrix (built on each call)."""
        return self._whole(self.D_inv)

    def to_u(self, v: np.ndarray) -> np.ndarray:
        """``u = T v``."""
        u = np.array(v, dtype=float)
        u[self.changed] += self.D @ v
        return u

    def load(self, f: np.ndarray) -> np.ndarray:
        """``T' f``: a load (a gradient) in the new unknowns."""
        return np.asarray(f, dtype=float) + self.D.T @ np.asarray(f, dtype=float)[self.changed]

    def to_v(self, u: np.ndarray) -> np.ndarray:
        """``v = T^{-1} u``."""
        v = np.array(u, dtype=float)
        v[self.changed] += self.D_inv @ u
        return v

    def multipliers(self, residual_v: np.ndarray, active: np.ndarray) -> np.ndarray:
        """``p`` of ``B u <= g`` from the residual ``f~ - A~ v`` of the transformed problem:
        ``p_i = max(r[pivot_i], 0) / beta_i`` on the ``active`` rows (``T' B' p = beta p``
        at the pivots), 0 on the others (their residual is the stationarity error)."""
        return np.where(active, np.maximum(residual_v[self.pivot], 0.0) / self.scale, 0.0)


def _node_blocks(qp: ContactQP) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(node_ptr, node_dofs, node_of_block)``: the unknowns grouped by mesh node."""
    free = np.arange(qp.n) if qp.free_dofs is None else np.asarray(qp.free_dofs)
    node, comp = free // qp.dim, free % qp.dim
    order = np.lexsort((comp, node))
    sorted_nodes = node[order]
    starts = np.flatnonzero(np.r_[True, sorted_nodes[1:] != sorted_nodes[:-1]])
    node_ptr = np.r_[starts, qp.n].astype(np.int64)
    return node_ptr, order.astype(np.int64), sorted_nodes[starts]


def check_structure(qp: ContactQP) -> tuple[bool, str]:
    """``(True, "")`` if :func:`box_transformation` can take ``qp``, else ``(False, why)``.
    Cheap (a few sparse passes)."""
    try:
        _rows_and_slaves(qp)
    except TransformationError as err:
        return False, str(err)
    return True, ""


def _rows_and_slaves(qp: ContactQP):
    """The node blocks and, per row, its constrained node's block; checks the structure."""
    if qp.C is not None or qp.stabilisation is not None:
        raise TransformationError("two-sided constraints (stabilised, Sect. 7.5, or two-pass): "
                                  "the reverse rows constrain the opposing surface too, so "
                                  "the rows are not one per constrained node")
    if qp.m == 0:
        node_ptr, node_dofs, _ = _node_blocks(qp)
        return node_ptr, node_dofs, np.zeros(0, dtype=np.int64)
    node_ptr, node_dofs, node_of_block = _node_blocks(qp)
    if qp.contact is not None and len(qp.contact.nodes) == qp.m:
        nodes = np.asarray(qp.contact.nodes)
    else:
        nodes = _own_nodes(qp, node_ptr, node_dofs, node_of_block)
    if np.unique(nodes).size != nodes.size:
        raise TransformationError("a node carries more than one constraint row")
    where = np.searchsorted(node_of_block, nodes)
    where = np.minimum(where, node_of_block.size - 1)
    if np.any(node_of_block[where] != nodes):
        raise TransformationError("a constrained node has no free unknowns")
    # each constrained node's unknowns appear in its own row only
    B = qp.B.tocsc()
    size = node_ptr[where + 1] - node_ptr[where]
    for a in range(int(size.max())):
        rows = np.flatnonzero(size > a)
        cols = node_dofs[node_ptr[where[rows]] + a]
        count = np.diff(B.indptr)[cols]
        one = count == 1
        if np.any(count > 1) or np.any(B.indices[B.indptr[cols[one]]] != rows[one]):
            raise TransformationError("a constrained node's unknowns appear in other rows "
                                      "of B (rows are not one per constrained node)")
    return node_ptr, node_dofs, where


def _own_nodes(qp: ContactQP, node_ptr, node_dofs, node_of_block) -> np.ndarray:
    """Without contact-surface data: per row, the node whose unknowns no other row touches
    (the constrained node of a nodal constraint), the one with the largest coefficients
    where there are several."""
    B = qp.B.tocoo()
    block_of_dof = np.empty(qp.n, dtype=np.int64)
    block_of_dof[node_dofs] = np.repeat(np.arange(node_ptr.size - 1), np.diff(node_ptr))
    blk = block_of_dof[B.col]
    nb = node_ptr.size - 1
    lo = np.full(nb, qp.m, dtype=np.int64)
    hi = np.full(nb, -1, dtype=np.int64)
    np.minimum.at(lo, blk, B.row)
    np.maximum.at(hi, blk, B.row)
    weight = np.zeros(nb)
    np.add.at(weight, blk, B.data ** 2)
    own = np.flatnonzero((lo == hi) & (hi >= 0))
    order = np.lexsort((-weight[own], lo[own]))        # per row, heaviest first
    rows, first = np.unique(lo[own][order], return_index=True)
    if rows.size != qp.m:
        missing = np.setdiff1d(np.arange(qp.m), rows)
        raise TransformationError(f"{missing.size} rows of B have no node of their own (first: "
                                  f"row {int(missing[0])}): not one row per constrained node")
    return node_of_block[own[order][first]]


def box_transformation(qp: ContactQP, tangential: sp.spmatrix | None = None
                       ) -> BoxTransformation:
    """The change of variables of the module docstring for ``qp``.

    Parameters
    ----------
    qp : ContactQP
    tangential : (m * (dim - 1), n) sparse, optional
        Tangential rows (``qp.friction.T``), ``dim - 1`` per row of ``B`` (node-major), made
        coordinates too (the module docstring's tangential unknowns at each constrained
        node).

    Raises
    ------
    TransformationError
        If the constraints lack the structure (:func:`check_structure` says why), or the
        tangential rows do not share their normal rows' constrained nodes and opposing
        unknowns with a tangent orthogonal to the normal.
    """
    node_ptr, node_dofs, block_of_row = _rows_and_slaves(qp)
    n, m, d = qp.n, qp.m, qp.dim
    block_row = -np.ones(node_ptr.size - 1, dtype=np.int64)
    block_row[block_of_row] = np.arange(m)
    if m == 0:
        none = sp.csr_matrix((0, n))
        return BoxTransformation(none, none, np.zeros(0, np.int64), np.zeros(0), np.zeros(0),
                                 node_ptr, node_dofs, block_row, np.zeros(0, np.int64))
    B = qp.B.tocsr()
    k = node_ptr[block_of_row + 1] - node_ptr[block_of_row]          # unknowns per node
    slave = -np.ones((m, d), dtype=np.int64)                         # padded unknowns
    for a in range(d):
        has = k > a
        slave[has, a] = node_dofs[node_ptr[block_of_row[has]] + a]
    b = np.zeros((m, d))
    for a in range(d):
        has = slave[:, a] >= 0
        b[has, a] = np.asarray(B[np.flatnonzero(has), slave[has, a]]).ravel()
    beta = np.linalg.norm(b, axis=1)
    row_norm = np.sqrt(np.asarray(B.multiply(B).sum(axis=1)).ravel())
    weak = beta <= 1e-8 * row_norm
    if np.any(weak):
        raise TransformationError(f"{int(weak.sum())} rows do not move their constrained node "
                                  f"(first: row {int(np.flatnonzero(weak)[0])})")
    normal = b / beta[:, None]
    # Householder frames H = I - 2 w w'/(w'w), w = e_1 - n (H = I where n = e_1)
    w = -normal.copy()
    w[:, 0] += 1.0
    ww = np.einsum("ij,ij->i", w, w)
    coef = np.where(ww > 1e-30, 2.0 / np.where(ww > 1e-30, ww, 1.0), 0.0)
    H = np.eye(d)[None] - coef[:, None, None] * w[:, :, None] * w[:, None, :]
    # the rows' other entries (the opposing facet's unknowns)
    is_slave = np.zeros(n, dtype=bool)
    is_slave[slave[slave >= 0]] = True
    coo = B.tocoo()
    other = ~is_slave[coo.col]
    r_o, c_o, val_o = coo.row[other], coo.col[other], coo.data[other] / beta[coo.row[other]]
    changed = np.sort(slave[slave >= 0])
    local = -np.ones(n, dtype=np.int64)
    local[changed] = np.arange(changed.size)
    rows_t, cols_t, vals_t = [], [], []                 # T - I on the changed rows
    rows_i, cols_i, vals_i = [], [], []                 # T^{-1} - I on the changed rows
    for a in range(d):
        for c in range(d):
            has = (slave[:, a] >= 0) & (slave[:, c] >= 0)
            for rows, cols, vals in ((rows_t, cols_t, vals_t), (rows_i, cols_i, vals_i)):
                rows.append(local[slave[has, a]])
                cols.append(slave[has, c])
                vals.append(H[has, a, c] - (1.0 if a == c else 0.0))
        has = slave[r_o, a] >= 0
        rows_t.append(local[slave[r_o[has], a]])
        cols_t.append(c_o[has])
        vals_t.append(-normal[r_o[has], a] * val_o[has])
    rows_i.append(local[slave[r_o, 0]])
    cols_i.append(c_o)
    vals_i.append(val_o)
    t_pivot, t_scale, t_frame = np.zeros(0, np.int64), np.zeros(0), np.zeros((0, 1, 1))
    if tangential is not None:
        theta, frame, (r_t, c_t, val_t) = _tangential_frames(tangential, slave, normal, H,
                                                             is_slave)
        k = d - 1
        node, comp = r_t // k, r_t % k
        for lt in range(k):           # (Theta^-1)[lt, comp] = R[comp, lt] / theta
            rot = frame[node, comp, lt]
            for a in range(d):
                has = slave[node, a] >= 0
                rows_t.append(local[slave[node[has], a]])
                cols_t.append(c_t[has])
                vals_t.append(-H[node[has], a, 1 + lt] * rot[has] * val_t[has]
                              / theta[node[has]])
            rows_i.append(local[slave[node, 1 + lt]])
            cols_i.append(c_t)
            vals_i.append(rot * val_t / theta[node])
        t_pivot, t_scale, t_frame = slave[:, 1:].ravel(), theta, frame
    shape = (changed.size, n)
    D = sp.csr_matrix((np.concatenate(vals_t), (np.concatenate(rows_t), np.concatenate(cols_t))),
                      shape=shape)
    D_inv = sp.csr_matrix((np.concatenate(vals_i),
                           (np.concatenate(rows_i), np.concatenate(cols_i))), shape=shape)
    for M in (D, D_inv):
        M.eliminate_zeros()
        M.sort_indices()
    return BoxTransformation(D, D_inv, slave[:, 0], beta, qp.g / beta, node_ptr, node_dofs,
                             block_row, changed, t_pivot, t_scale, t_frame)


def _tangential_frames(tangential: sp.spmatrix, slave: np.ndarray, normal: np.ndarray,
                       H: np.ndarray, is_slave: np.ndarray):
    """``(theta, R, entries)``: ``Theta_i = theta_i R_i`` (module docstring; 2D: ``R_i = 1``
    and ``theta_i`` signed) and the tangential rows' entries off the constrained nodes
    ``(row, col, value)``; checks the structure."""
    m, d = slave.shape
    k = d - 1
    Tt = sp.csr_matrix(tangential)
    if Tt.shape != (m * k, is_slave.size):
        raise TransformationError(f"tangential rows of shape {Tt.shape}; allowed: ({m * k}, "
                                  f"{is_slave.size}) ({k} per row of B, node-major)")
    if np.any(slave < 0):
        raise TransformationError("tangential coordinates are built for constrained nodes "
                                  "with all their unknowns free")
    node_rows = np.arange(m * k).reshape(m, k)
    tau = np.stack([np.asarray(Tt[node_rows.ravel(), np.repeat(slave[:, a], k)]).ravel()
                    for a in range(d)], axis=1).reshape(m, k, d)
    length = np.linalg.norm(tau, axis=2)
    if np.any(length <= 0.0):
        raise TransformationError(f"{int(np.sum(length <= 0))} tangential rows do not move "
                                  "their constrained node")
    if np.any(np.abs(np.einsum("ijc,ic->ij", tau, normal)) > 1e-12 * length):
        raise TransformationError("a tangential row's tangent is not orthogonal to its "
                                  "normal row's direction")
    if k == 1:
        gamma = length[:, 0]
        theta = np.sign(np.einsum("ij,ij->i", H[:, :, 1], tau[:, 0])) * gamma
        frame = np.ones((m, 1, 1))
    else:
        gamma = np.sqrt(np.mean(length ** 2, axis=1))
        Theta = np.einsum("ijc,icl->ijl", tau, H[:, :, 1:])
        frame = Theta / gamma[:, None, None]
        gram = np.einsum("ijl,ihl->ijh", frame, frame) - np.eye(k)[None]
        if np.any(np.abs(gram) > 1e-12):
            raise TransformationError("a node's tangential rows are not orthogonal with one "
                                      "length (the isotropic Tresca disc would not stay a "
                                      "disc in the new unknowns)")
        theta = gamma
    coo = Tt.tocoo()
    other = ~is_slave[coo.col]
    own = np.zeros(coo.row.size, dtype=bool)
    for a in range(d):
        own |= coo.col == slave[coo.row // k, a]
    if np.any(~other & ~own & (coo.data != 0.0)):
        raise TransformationError("a tangential row reaches another row's constrained node "
                                  "(the tangential rows must share their normal rows' "
                                  "structure)")
    return theta, frame, (coo.row[other], coo.col[other], coo.data[other])
