"""Convergence rates fitted to error tables."""
from __future__ import annotations

import numpy as np
import pandas as pd


def fitted_rate(h: np.ndarray, err: np.ndarray, last: int = 3, roundoff: float = 1e-10) -> float:
    """Least-squares slope of log(err) against log(h) over the ``last`` finest levels.

    Returns NaN when fewer than two usable (positive, finite) points remain, or
    when every error is at round-off level (< ``roundoff``): the discretisation
    is exact there and a "rate" would only fit floating-point noise.
    """
    h = np.asarray(h, dtype=float)
    err = np.asarray(err, dtype=float)
    order = np.argsort(h)[:last]
    h, err = h[order], err[order]
    ok = np.isfinite(err) & (err > 0) & (h > 0)
    if ok.sum() < 2 or np.all(err[ok] < roundoff):
        return float("nan")
    return float(np.polyfit(np.log(h[ok]), np.log(err[ok]), 1)[0])


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
