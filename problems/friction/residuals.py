"""How a frictional answer is judged: the KKT residuals of a Tresca step (the normal rows'
of :func:`problems.kkt.kkt_residuals` with the tangential stationarity, the bound on the
tangential multipliers and the slip complementarity), scaled as the frictionless ones are,
and the step's energy, the same formulas for every solver (DESIGN.md: conventions)::

    KKT:  A u + B'p + T'lam = f,  |lam_i| <= s_i,  lam_i . slip_i = s_i |slip_i|,
          B u <= g,  p >= 0,  p'(g - B u) = 0
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from problems.kkt import KKTResiduals, row_residuals
from problems.qp import ContactQP


@dataclass
class FrictionResiduals(KKTResiduals):
    """The KKT residuals of a Tresca step (:class:`problems.friction.data.Friction`),
    scaled like :class:`problems.kkt.KKTResiduals`.

    ``stationarity = ||Au + B'p + T'lam - f||_inf / max(||f||_inf, ||Au||_inf, ||B'p||_inf,
    ||T'lam||_inf)``; ``primal``, ``dual`` and ``complementarity`` are those of the normal
    rows (:func:`problems.kkt.kkt_residuals`);
    ``bound = max_i (|lam_i| - s_i)_+ / max(max_i |lam_i|, ||s||_inf)``;
    ``slip_complementarity = sum_i |s_i |slip_i| - lam_i . slip_i| / (max(||s||_1, sum_i |lam_i|)
    max(||slip||_inf, ||Bu||_inf, ||g||_inf))`` (entrywise, as for the normal rows).
    """

    bound: float = field(kw_only=True)
    slip_complementarity: float = field(kw_only=True)


def friction_residuals(qp: ContactQP, u: np.ndarray, p: np.ndarray,
                       lam: np.ndarray) -> FrictionResiduals:
    """Verified KKT residuals of ``(u, p, lam)`` for the Tresca step ``qp`` (its
    ``friction``): ``A u + B'p + T'lam = f``, ``|lam_i| <= s_i``,
    ``lam_i . slip_i = s_i |slip_i|`` and the normal rows' conditions (``|.|`` the
    Euclidean norm of a node's tangential vector in 3D,
    :meth:`problems.friction.data.Friction.magnitude`). The faceted law:
    ``lam_i in s_i P_k`` (its gauge, :meth:`problems.friction.data.Friction.gauge`, at
    most ``s_i``) and ``lam_i . slip_i = s_i h_Pk(slip_i)``
    (:meth:`problems.friction.data.Friction.dissipation`)."""
    if qp.friction is None:
        raise ValueError("friction_residuals: this ContactQP has no friction; use kkt_residuals")
    tiny = 1e-300
    fr = qp.friction
    u, p, lam = (np.asarray(v, dtype=float) for v in (u, p, lam))
    inf = lambda v: float(np.max(np.abs(v))) if np.size(v) else 0.0
    Au, Btp, Ttl = qp.A @ u, qp.B.T @ p, fr.T.T @ lam
    r_stat = inf(Au + Btp + Ttl - qp.f)
    scaled, raw = friction_row_residuals(qp, qp.B @ u, fr.slip(u), p, lam)
    return FrictionResiduals(
        stationarity=r_stat / max(inf(qp.f), inf(Au), inf(Btp), inf(Ttl), tiny), **scaled,
        raw={"stationarity": r_stat, **raw})


def friction_row_residuals(qp: ContactQP, Bu: np.ndarray, slip: np.ndarray, p: np.ndarray,
                           lam: np.ndarray) -> tuple[dict, dict]:
    """The rows' residuals of :class:`FrictionResiduals` (every one but the
    stationarity) from the rows' values: ``Bu``, the slip ``slip``
    (:meth:`problems.friction.data.Friction.slip`) and the multipliers: ``(scaled,
    raw)``."""
    tiny = 1e-300
    fr = qp.friction
    inf = lambda v: float(np.max(np.abs(v))) if np.size(v) else 0.0
    scaled, raw = row_residuals(qp, Bu, p)
    s, size = fr.slip_bound, fr.gauge(lam)
    r_bound = max(0.0, float(np.max(size - s))) if s.size else 0.0
    r_slip = float(np.sum(np.abs(s * fr.dissipation(slip) - fr.inner(lam, slip))))
    disp_scale = max(inf(slip), inf(Bu), inf(qp.g), tiny)
    scaled.update(bound=r_bound / max(inf(size), inf(s), tiny),
                  slip_complementarity=r_slip / max(float(np.sum(s)), float(np.sum(size)), tiny)
                  / disp_scale)
    return scaled, {**raw, "bound": r_bound, "slip_complementarity": r_slip}


def tresca_energy(qp: ContactQP, u: np.ndarray) -> float:
    """The Tresca step's energy ``1/2 u'Au - f'u + sum_i s_i |slip_i(u)|`` (faceted:
    ``s_i h_Pk(slip_i(u))``, :meth:`problems.friction.data.Friction.dissipation`)."""
    fr = qp.friction
    return qp.energy(u) + (float(fr.slip_bound @ fr.dissipation(fr.slip(u))) if fr is not None
                           else 0.0)
