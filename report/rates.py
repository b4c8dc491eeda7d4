"""Fitted rates and slopes: one least-squares fit of log y against log x for every table."""
from __future__ import annotations

import numpy as np
import pandas as pd


def fitted_slope(x, y, last: int = 3, finest: str = "largest", roundoff: float = 0.0) -> float:
    """Least-squares slope of ``log y`` against ``log x`` over the ``last`` finest points.

    Parameters
    ----------
    x, y : arrays
    last : int
        Number of points used: those with the largest ``x`` (``finest="largest"``,
        e.g. problem sizes N) or the smallest (``"smallest"``, e.g. mesh sizes h).
    roundoff : float
        If every ``y`` used is below it, return NaN: the quantity is exact there
        and a rate would only fit floating-point noise.

    Returns
    -------
    float
        NaN when fewer than two usable (positive, finite) points remain.
    """
    if finest not in ("largest", "smallest"):
        raise ValueError(f"parameter 'finest': {finest!r} is not allowed; allowed: largest, smallest")
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    order = np.argsort(x)
    order = order[-last:] if finest == "largest" else order[:last]
    x, y = x[order], y[order]
    ok = np.isfinite(x) & np.isfinite(y) & (x > 0) & (y > 0)
    if ok.sum() < 2 or np.all(y[ok] < roundoff):
        return float("nan")
    return float(np.polyfit(np.log(x[ok]), np.log(y[ok]), 1)[0])


def fitted_rate(h, err, last: int = 3, roundoff: float = 1e-10) -> float:
    """Convergence rate: slope of ``log err`` against ``log h`` over the ``last`` finest
    levels (smallest ``h``); NaN when every error is at round-off (< ``roundoff``)."""
    return fitted_slope(h, err, last, finest="smallest", roundoff=roundoff)


def rate_table(errors: pd.DataFrame, keys: list[str], columns: dict[str, str],
               last: int = 3) -> pd.DataFrame:
    """One row per group of ``keys``: the fitted rate of each error column.

    ``columns`` maps error column -> rate column, e.g. ``{"err_h1": "rate_h1"}``.
    """
    rows = []
    for key, grp in errors.groupby(keys, sort=False):
        key = key if isinstance(key, tuple) else (key,)
        row = dict(zip(keys, key))
        for err_col, rate_col in columns.items():
            row[rate_col] = fitted_rate(grp["h"].to_numpy(), grp[err_col].to_numpy(), last)
        finest = grp.nsmallest(last, "h")["level"]
        row["levels"] = f"{int(finest.min())}..{int(finest.max())}"
        rows.append(row)
    return pd.DataFrame(rows)
