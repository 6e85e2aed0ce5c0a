"""Summary statistics of errors, shared by the error study and the survey evaluation."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["error_stats", "summary_stats"]


def _rounded(value: float, digits: int | None) -> float:
    v = float(value)
    return v if digits is None else float(f"{v:.{digits}g}")


def summary_stats(values, *, digits: int | None = None) -> dict[str, float | None]:
    """Mean, median, 95th percentile and maximum of the finite values.

    Parameters
    ----------
    values : array_like
        Any shape; NaN and infinite entries (failures) are left out.
    digits : int, optional
        Round each statistic to this many significant digits.

    Returns
    -------
    dict
        ``mean``, ``median``, ``p95``, ``max``: JSON-ready floats, None when no value is
        finite.
    """
    v = np.asarray(values, dtype=float).reshape(-1)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {"mean": None, "median": None, "p95": None, "max": None}
    return {
        "mean": _rounded(np.mean(v), digits),
        "median": _rounded(np.median(v), digits),
        "p95": _rounded(np.percentile(v, 95), digits),
        "max": _rounded(np.max(v), digits),
    }


def error_stats(errors_m) -> dict:
    """Mean, median, 95th percentile and max of position errors (metres), NaN = failure.

    Returns
    -------
    dict
        ``poses``, ``failures`` and ``mean_error_m``, ``median_error_m``, ``p95_error_m``,
        ``max_error_m`` over the poses that were solved (None when none was).
    """
    e = np.asarray(errors_m, dtype=float).reshape(-1)
    failures = int(np.count_nonzero(~np.isfinite(e)))
    stats = {f"{k}_error_m": v for k, v in summary_stats(e).items()}
    return {"poses": int(e.size), "failures": failures, **stats}


def json_number(value: float, digits: int = 6) -> float | None:
    """A JSON number with ``digits`` significant digits (None for NaN or infinity)."""
    v = float(value)
    return _rounded(v, digits) if math.isfinite(v) else None
