"""What evaluating the locator on a survey gives: each photo's outcome (:class:`PhotoResult`),
and the run's (:class:`Evaluation`, its summary statistics), made by
:func:`camvlp.analysis.evaluate.evaluate_survey`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from camvlp.analysis.stats import json_number, summary_stats
from camvlp.io.survey_csv import AXES, Survey
from camvlp.model.camera import euler_to_matrix

__all__ = ["Evaluation", "PhotoResult", "floor_axes"]


@dataclass(frozen=True)
class PhotoResult:
    """The outcome for one photograph of a survey.  Falsy when the photo was not located.

    Attributes
    ----------
    photo : str
        The photo's path as written in the survey.
    true_position : ndarray, shape (3,)
        The true camera centre, map units.
    position : ndarray, shape (3,), or None
        The estimated camera centre, map units; None when not located.
    euler_deg : ndarray, shape (3,), or None
        The estimated thesis angles, degrees.
    true_euler_deg : ndarray, shape (3,), or None
        The true thesis angles, degrees, when the survey gives them.
    reason : str
        Why the photo was not located: ``"unreadable: ..."``, ``"not located: ..."`` or
        ``"failed: ..."`` ("" when located).
    fixtures_detected, fixtures_used : int
        Fixtures found in the photo, and used by the pose.
    reprojection_rms_px : float
        RMS reprojection error of the fixtures used, pixels (NaN when not located).
    time_ms : float
        Time to read and locate the photo, milliseconds.
    solver : str
        How the pose was solved (``LocateResult.solver``; "" when the photo was not read).
        Photos with a sidecar ``PHOTO.json`` giving gravity are located with it.
    position_sigma : ndarray, shape (3,), or None
        How sure the position is (``LocateResult.position_sigma``): its standard deviation
        along x, y and z, map units; None when not located.
    """

    photo: str
    true_position: np.ndarray
    position: np.ndarray | None
    euler_deg: np.ndarray | None
    true_euler_deg: np.ndarray | None
    reason: str
    fixtures_detected: int = 0
    fixtures_used: int = 0
    reprojection_rms_px: float = math.nan
    time_ms: float = math.nan
    solver: str = ""
    position_sigma: np.ndarray | None = None

    def __bool__(self) -> bool:
        """True when the photo was located (the package's result convention)."""
        return self.position is not None

    @property
    def located(self) -> bool:
        """Whether the photo was located (the same as ``bool(result)``)."""
        return bool(self)

    @property
    def error_vector(self) -> np.ndarray:
        """Estimated minus true position, shape (3,), map units (NaN when not located)."""
        if self.position is None:
            return np.full(3, math.nan)
        return np.asarray(self.position, float) - np.asarray(self.true_position, float)

    @property
    def error(self) -> float:
        """Distance between the estimated and true positions, map units (NaN if not located)."""
        return float(np.linalg.norm(self.error_vector))

    @property
    def angle_error_deg(self) -> float:
        """Angle of the rotation between the true and estimated orientations, degrees.

        NaN when not located or when the survey gives no true angles.
        """
        if self.euler_deg is None or self.true_euler_deg is None:
            return math.nan
        r = euler_to_matrix(self.true_euler_deg).T @ euler_to_matrix(self.euler_deg)
        c = np.clip(0.5 * (np.trace(r) - 1.0), -1.0, 1.0)
        return float(np.degrees(np.arccos(c)))


def _stats(values) -> dict[str, float | None]:
    """Mean, median, 95th percentile and maximum, 6 significant digits (None when empty)."""
    return summary_stats(values, digits=6)


_num = json_number


def floor_axes(positions) -> tuple[int, int, int]:
    """The two axes with the largest spread of positions, and the third one.

    Parameters
    ----------
    positions : array_like, shape (N, 3)

    Returns
    -------
    (first, second, vertical) : tuple of int
        Axis indices: the floor's two axes in increasing order (ties favour the lower
        index), then the remaining one.
    """
    p = np.asarray(positions, float).reshape(-1, 3)
    spread = np.ptp(p, axis=0) if p.shape[0] else np.zeros(3)
    order = sorted(range(3), key=lambda k: (-spread[k], k))
    a, b = sorted(order[:2])
    return a, b, order[2]


@dataclass(frozen=True)
class Evaluation:
    """Every photo's outcome, and how the run went.

    Attributes
    ----------
    results : tuple of PhotoResult
        One per survey row, in survey order.
    units : str
        The map's length unit.
    survey : Survey
        The survey evaluated.
    jobs : int
        Worker processes used.
    wall_time_s : float
        Wall-clock time of the whole run, seconds.
    """

    results: tuple[PhotoResult, ...]
    units: str
    survey: Survey
    jobs: int
    wall_time_s: float

    @property
    def located(self) -> np.ndarray:
        """Which photos were located, bool shape (N,)."""
        return np.array([bool(r) for r in self.results], dtype=bool)

    @property
    def errors(self) -> np.ndarray:
        """Position error per photo, map units, shape (N,) (NaN when not located)."""
        return np.array([r.error for r in self.results], dtype=float)

    @property
    def error_vectors(self) -> np.ndarray:
        """Estimated minus true position per photo, shape (N, 3), map units."""
        return np.array([r.error_vector for r in self.results], dtype=float).reshape(-1, 3)

    def summary(self) -> dict[str, Any]:
        """The run's statistics as a JSON-ready dict (map units unless a key says otherwise).

        Keys: ``photos``, ``located``, ``failed``, ``success_rate`` (0 to 1), ``units``,
        ``mean_error``, ``median_error``, ``p95_error``, ``max_error``, ``rms_error``
        (position errors over the located photos; None when none was located),
        ``abs_error_per_axis`` (per axis: mean, median, p95 and max of the absolute error),
        ``bias_per_axis`` (mean signed error per axis: a systematic offset),
        ``angle_error_deg`` (mean, median, p95, max; when the survey gives true angles),
        ``reprojection_rms_px`` (mean and max), ``fixtures_used`` (mean), ``floor_axes``,
        ``time_per_photo_ms`` (mean), ``jobs``, ``wall_time_s``, ``survey``,
        ``within_sigma`` (the share of the located photos' coordinates whose error is within
        1, 2 and 3 of their ``position_sigma``, keys ``"1"``, ``"2"``, ``"3"``, of ``count``
        coordinates; a normal law gives 0.683, 0.954 and 0.997), and ``failures``: a list of
        ``{"photo", "reason"}``.
        """
        ok = self.located
        err = self.errors[ok]
        vec = self.error_vectors[ok]
        stats = _stats(err)
        a, b, _ = floor_axes(self.survey.positions)
        d: dict[str, Any] = {
            "photos": len(self.results),
            "located": int(ok.sum()),
            "failed": int((~ok).sum()),
            "success_rate": _num(ok.mean()) if ok.size else None,
            "units": self.units,
            "mean_error": stats["mean"],
            "median_error": stats["median"],
            "p95_error": stats["p95"],
            "max_error": stats["max"],
            "rms_error": _num(np.sqrt(np.mean(err**2))) if err.size else None,
            "abs_error_per_axis": {ax: _stats(np.abs(vec[:, k])) for k, ax in enumerate(AXES)},
            "bias_per_axis": {
                ax: _num(vec[:, k].mean()) if err.size else None for k, ax in enumerate(AXES)
            },
        }
        if self.survey.euler_deg is not None:
            d["angle_error_deg"] = _stats(np.array([r.angle_error_deg for r in self.results]))
        rms = np.array([r.reprojection_rms_px for r in self.results])
        d["reprojection_rms_px"] = {"mean": _stats(rms)["mean"], "max": _stats(rms)["max"]}
        used = np.array([r.fixtures_used for r in self.results], float)[ok]
        d["fixtures_used"] = {"mean": _num(used.mean()) if used.size else None}
        d["floor_axes"] = [AXES[a], AXES[b]]
        d["time_per_photo_ms"] = {
            "mean": _stats(np.array([r.time_ms for r in self.results]))["mean"]
        }
        d["within_sigma"] = _within_sigma(self.results)
        d["jobs"] = self.jobs
        d["wall_time_s"] = round(self.wall_time_s, 2)
        d["survey"] = str(self.survey.path)
        d["failures"] = [{"photo": r.photo, "reason": r.reason} for r in self.results if not r]
        return d


def _within_sigma(results: list[PhotoResult]) -> dict[str, Any]:
    """How often the located photos' coordinates are within 1, 2 and 3 of their own
    ``position_sigma`` (see :meth:`Evaluation.summary`)."""
    z = np.array(
        [np.abs(r.error_vector) / r.position_sigma for r in results if r.position_sigma is not None]
    ).ravel()
    z = z[np.isfinite(z)]
    out: dict[str, Any] = {k: _num(np.mean(z <= float(k))) if z.size else None for k in "123"}
    out["count"] = int(z.size)
    return out
