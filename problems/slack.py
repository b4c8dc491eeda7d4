"""The stabilised problem (thesis Sect. 7.5) without its ``C`` block, for solvers that take
``Bu <= g`` only: one slack unknown per penalised row."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from problems.qp import ContactQP, QPValidationError


def slack_form(qp: ContactQP) -> ContactQP:
    """The equivalent QP without ``C``, for solvers that take ``Bu <= g`` only (Sect. 7.5).

    With ``C = diag(c)`` (``c_i >= 0``) and one slack ``s_i`` per row with ``c_i > 0``::

        min 1/2 u'Au - f'u + 1/2 s' diag(1/c) s   s.t.  B_h u <= g_h,  B_s u - s <= g_s

    has the same ``u`` and the same multipliers (stationarity in ``s`` gives
    ``s = c p``, so ``B_s u - c p <= g_s``): ``min_s`` of the slack term is the
    penalty ``1/2 (B_s u - g_s)_+^2 / c`` of (7.10). The unknowns are ``(u, s)``;
    ``u = x[:qp.n]``. Mesh and contact data are kept for output; the multilevel data
    are dropped (the slack unknowns are on no mesh).
    """
    if qp.C is None:
        return qp
    c = qp.C.diagonal()
    if abs(qp.C - sp.diags(c)).max() > 0 or np.any(c < 0):
        raise QPValidationError("slack_form needs a diagonal C >= 0")
    soft = np.flatnonzero(c > 0)
    k = soft.size
    A = sp.block_diag([qp.A, sp.diags(1.0 / c[soft])], format="csr")
    S = sp.csr_matrix((-np.ones(k), (soft, np.arange(k))), shape=(qp.m, k))
    return ContactQP(A=A, f=np.concatenate([qp.f, np.zeros(k)]), B=sp.hstack([qp.B, S]).tocsr(),
                     g=qp.g, dim=qp.dim, name=qp.name + " (slack form)", units=qp.units,
                     level=qp.level)
