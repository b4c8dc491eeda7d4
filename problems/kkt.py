"""How an answer is judged: the four scaled KKT residuals and the energy-norm error, the
same formula for every solver (DESIGN.md: conventions).

    KKT:  A u + B^T p = f,  B u - C p <= g,  p >= 0,  p^T (g - B u + C p) = 0
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from problems.qp import ContactQP


@dataclass
class KKTResiduals:
    """The four KKT residuals, scaled to be comparable across meshes and units.

    ``stationarity = ||Au + B'p - f||_inf / max(||f||_inf, ||Au||_inf, ||B'p||_inf)``,
    ``primal = max(Bu - Cp - g)_+ / max(||Bu||_inf, ||g||_inf)``,
    ``dual = max(-p)_+ / ||p||_inf``,
    ``complementarity = sum_i |p_i (g - Bu + Cp)_i| / (||p||_1 max(||Bu||_inf, ||g||_inf))``
    (entrywise, so that violations of opposite sign cannot cancel).
    Every denominator is floored at the tiny number ``1e-300``; ``raw`` holds the
    unscaled values.
    """

    stationarity: float
    primal: float
    dual: float
    complementarity: float
    raw: dict = field(default_factory=dict)

    @property
    def names(self) -> tuple[str, ...]:
        """The scaled residuals' names, in order (every field but ``raw``)."""
        return tuple(f.name for f in fields(self) if f.name != "raw")

    @property
    def max(self) -> float:
        return max(getattr(self, k) for k in self.names)

    def as_dict(self, prefix: str = "kkt_") -> dict:
        return {f"{prefix}{k}": getattr(self, k) for k in self.names}


def kkt_residuals(qp: ContactQP, u: np.ndarray, p: np.ndarray) -> KKTResiduals:
    """Verified KKT residuals of ``(u, p)`` for ``qp`` (same formula for every solver)."""
    tiny = 1e-300
    u = np.asarray(u, dtype=float)
    p = np.asarray(p, dtype=float)
    Au = qp.A @ u
    Btp = qp.B.T @ p
    scaled, raw = row_residuals(qp, qp.B @ u, p)
    inf = lambda v: float(np.max(np.abs(v))) if np.size(v) else 0.0
    r_stat = inf(Au + Btp - qp.f)
    return KKTResiduals(stationarity=r_stat / max(inf(qp.f), inf(Au), inf(Btp), tiny),
                        **scaled, raw={"stationarity": r_stat, **raw})


def row_residuals(qp: ContactQP, Bu: np.ndarray, p: np.ndarray) -> tuple[dict, dict]:
    """The rows' KKT residuals of :class:`KKTResiduals` (``primal``, ``dual`` and
    ``complementarity``; every one but the stationarity) from the rows' values ``Bu``
    and ``p``: ``(scaled, raw)``."""
    tiny = 1e-300
    slack = qp.g - Bu + (qp.C @ p if qp.C is not None else 0.0)
    inf = lambda v: float(np.max(np.abs(v))) if np.size(v) else 0.0
    r_primal = max(0.0, float(np.max(-slack))) if slack.size else 0.0  # 0.0 first: never -0.0
    r_dual = max(0.0, float(np.max(-p))) if p.size else 0.0
    r_comp = float(np.sum(np.abs(p * slack)))
    disp_scale = max(inf(Bu), inf(qp.g), tiny)
    scaled = {"primal": r_primal / disp_scale, "dual": r_dual / max(inf(p), tiny),
              "complementarity": r_comp / max(float(np.sum(np.abs(p))) * disp_scale, tiny)}
    return scaled, {"primal": r_primal, "dual": r_dual, "complementarity": r_comp}


def energy_error(qp: ContactQP, u: np.ndarray, u_ref: np.ndarray) -> float:
    """Relative energy-norm error ``||u - u_ref||_A / ||u_ref||_A``.

    ``inf`` for a non-finite or mis-shaped ``u``; the absolute error if
    ``u_ref`` is zero.
    """
    u = np.asarray(u, dtype=float)
    if u.shape != (qp.n,) or not np.all(np.isfinite(u)):
        return float("inf")
    e = u - u_ref
    ref = float(u_ref @ (qp.A @ u_ref))
    err = max(float(e @ (qp.A @ e)), 0.0)
    return float(np.sqrt(err / ref)) if ref > 0 else float(np.sqrt(err))
