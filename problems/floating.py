"""Floating bodies: the rigid motions of a body that only weak springs (or nothing) hold,
detected from the problem's rigid-body modes (thesis Sect. 9.3, the roll stack's work roll)."""
from __future__ import annotations

import numpy as np

from problems.qp import ContactQP


#: A rigid-body mode of one body counts as *floating* when its Rayleigh quotient
#: ``r'Ar / r'r`` is below this fraction of the mean diagonal of ``A`` over that body's
#: unknowns: the body is held in that direction only by weak springs (or not at all).
#: Held modes (a Dirichlet or symmetry condition acts on them) measure >= 1e-4 on the
#: roll stack and >= 3e-5 on every other scene and hard case of the suite (3.5e-3 with a
#: stiffness contrast of 1e4, each body against its own diagonal), the roll stack's
#: floating vertical translation 7e-10: the gap makes the test free of units and E.
FLOATING_THRESHOLD = 1e-6


def floating_modes(qp: ContactQP, threshold: float = FLOATING_THRESHOLD) -> np.ndarray:
    """The near-kernel of ``A``: rigid motions of a body that only weak springs hold.

    A body held only by the contact (the roll stack's work roll, thesis Sect. 9.3:
    "the eigenvalues of the problem may be very small") leaves ``A`` nearly
    singular: its stiffness in those directions is the springs' alone, ~1e-9 of the
    elastic stiffness. A factorisation of ``A`` then returns the huge rigid response
    ``A^{-1} f`` (metres where the answer is ~0.1 mm) and the contact solution is a
    difference of such numbers. Solvers that know these modes treat them exactly
    (:class:`solvers.kernels.cholesky.FloatingCholesky`).

    Parameters
    ----------
    qp : ContactQP
        With ``multilevel.rigid_body_modes`` and ``multilevel.body_of_dof``.
    threshold : float
        Largest Rayleigh quotient ``r'Ar / (r'r mean(diag A_bb))`` (dimensionless; ``A_bb``
        the body's block).

    Returns
    -------
    (n, k) array
        Orthonormal columns spanning the floating modes (k = 0: none, or no modes known).
        Cached in ``qp.cache``.
    """
    if threshold in qp.cache.floating_modes:
        return qp.cache.floating_modes[threshold]
    R = qp.multilevel.rigid_body_modes
    found = []
    if R is not None and qp.multilevel.body_of_dof is not None:
        diag = qp.A.diagonal()
        for b in np.unique(qp.multilevel.body_of_dof):
            scale = float(np.mean(diag[qp.multilevel.body_of_dof == b]))   # the body's own
            cols = R[:, np.any(R[qp.multilevel.body_of_dof == b] != 0, axis=0)]
            cols = cols * (qp.multilevel.body_of_dof == b)[:, None]
            if cols.shape[1] == 0:
                continue
            Q, s, _ = np.linalg.svd(cols, full_matrices=False)
            Q = Q[:, s > 1e-10 * s.max()]
            lam, V = np.linalg.eigh(Q.T @ (qp.A @ Q))
            keep = lam < threshold * scale
            found.append(Q @ V[:, keep])
    modes = np.hstack(found) if found else np.zeros((qp.n, 0))
    qp.cache.floating_modes[threshold] = modes
    return modes
