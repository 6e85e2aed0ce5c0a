"""Evaluate the locator on a survey: photographs with known camera positions (thesis 5.7).

A survey is a CSV file with the columns ``photo, x, y, z``: the photograph's path (relative
to the CSV's folder, or absolute) and the true camera centre in map units.  Other columns are
allowed and kept; ``theta_x, theta_y, theta_z`` (the thesis' angles, degrees), when present,
are the true orientation and give an orientation error too.  The file is read by
:func:`camvlp.io.survey_csv.read_survey` (re-exported here).

:func:`evaluate_survey` locates every photograph, in parallel, and never stops on one: a
photo that cannot be read or located is counted and listed with its reason.  The
:class:`Evaluation` it returns gives the per-photo table
(:func:`camvlp.io.writers.write_results_csv`), the summary statistics
(:meth:`Evaluation.summary`), and the thesis' two figures, drawn by
:mod:`camvlp.viz.evaluate_plots`: the error over the floor (figure 5.9, ``plot_error_map``)
and true versus estimated positions seen from the top and both sides (figure 5.11,
``plot_positions``).  :func:`write_evaluation` writes all four files.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from camvlp.analysis.stats import json_number, summary_stats
from camvlp.io import InputError, load_image, load_sidecar
from camvlp.io.survey_csv import ANGLE_COLUMNS, AXES, REQUIRED_COLUMNS, Survey, read_survey
from camvlp.io.writers import write_json, write_results_csv
from camvlp.model.camera import Camera, euler_to_matrix
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.locate import LocateSettings, locate
from camvlp.sim.survey import default_jobs, worker_context

__all__ = [
    "ANGLE_COLUMNS",
    "AXES",
    "REQUIRED_COLUMNS",
    "Evaluation",
    "PhotoResult",
    "Survey",
    "evaluate_survey",
    "floor_axes",
    "read_survey",
    "write_evaluation",
    "write_results_csv",
]

# --------------------------------------------------------------------------------------------
# Results


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
        along x, y and z, map units; None when not located or solved with gravity.
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


# --------------------------------------------------------------------------------------------
# Locating, one process per core

_WORKER: dict = {}


def _init_worker(camera: Camera, fixture_map: FixtureMap, settings: LocateSettings) -> None:
    """Keep the camera, map and settings in the worker; one OpenCV thread per worker."""
    import cv2

    cv2.setNumThreads(1)
    _set_worker(camera, fixture_map, settings)


def _set_worker(camera: Camera, fixture_map: FixtureMap, settings: LocateSettings) -> None:
    _WORKER.update(camera=camera, map=fixture_map, settings=settings)


def _locate_one(photo: str, path: Path, true_position, true_euler) -> PhotoResult:
    """Read and locate one photo; every failure becomes a reason, never an exception."""
    t0 = time.perf_counter()
    base = {"photo": photo, "true_position": true_position, "true_euler_deg": true_euler}

    def failed(reason: str, **more) -> PhotoResult:
        ms = 1e3 * (time.perf_counter() - t0)
        return PhotoResult(position=None, euler_deg=None, reason=reason, time_ms=ms, **base, **more)

    try:
        image = load_image(path)
    except InputError as exc:
        return failed(f"unreadable: {exc.what}")
    settings = _WORKER["settings"]
    try:
        sidecar = load_sidecar(path)  # gravity from the photo's PHOTO.json, when there is one
    except InputError as exc:
        return failed(f"unreadable: {exc}")
    gravity = None
    if sidecar is not None:
        gravity = sidecar.gravity
        if sidecar.gravity_sigma_deg is not None:
            settings = replace(settings, gravity_sigma_deg=sidecar.gravity_sigma_deg)
    try:
        res = locate(image, _WORKER["camera"], _WORKER["map"], settings, gravity=gravity)
    except InputError as exc:  # e.g. an image of another size than the camera's
        return failed(f"unreadable: {exc.what}")
    except Exception as exc:  # one bad photo must not stop a survey
        return failed(f"failed: {exc.__class__.__name__}: {exc}")
    detected = len(res.fixtures)
    used = sum(f.used for f in res.fixtures)
    if not res:
        return failed(
            f"not located: {res.reason}",
            fixtures_detected=detected,
            fixtures_used=used,
            solver=res.solver,
        )
    return PhotoResult(
        position=np.asarray(res.position, float),
        euler_deg=np.asarray(res.euler_deg, float),
        reason="",
        fixtures_detected=detected,
        fixtures_used=used,
        reprojection_rms_px=float(res.reprojection_rms_px),
        time_ms=1e3 * (time.perf_counter() - t0),
        solver=res.solver,
        position_sigma=res.position_sigma,
        **base,
    )


def evaluate_survey(
    survey: Survey,
    camera: Camera,
    fixture_map: FixtureMap,
    settings: LocateSettings | None = None,
    *,
    jobs: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Evaluation:
    """Locate every photograph of a survey and compare with the true positions.

    Parameters
    ----------
    survey : Survey
        From :func:`read_survey`.
    camera : Camera
        The camera that took the photos.
    fixture_map : FixtureMap
        The room's fixtures (same units as the survey's positions).
    settings : LocateSettings, optional
        Locator options.
    jobs : int, optional
        Worker processes (each with one OpenCV thread); default all cores.  1 works in this
        process, with OpenCV's own threading.
    progress : callable, optional
        Called as ``progress(done, total)`` after each photo.

    Returns
    -------
    Evaluation
        One :class:`PhotoResult` per photo, in survey order.  A photo that cannot be read
        or located is a result with its ``reason``; the run does not stop.

    Raises
    ------
    ValueError
        ``jobs`` below 1.
    """
    n_jobs = default_jobs() if jobs is None else int(jobs)
    if n_jobs < 1:
        raise ValueError(f"jobs must be at least 1, got {jobs!r}")
    st = settings or LocateSettings()
    n = len(survey)
    n_jobs = max(1, min(n_jobs, n))
    tasks = [
        (
            survey.photos[i],
            survey.photo_path(i),
            survey.positions[i].copy(),
            None if survey.euler_deg is None else survey.euler_deg[i].copy(),
        )
        for i in range(n)
    ]
    t0 = time.perf_counter()
    if n_jobs == 1:
        _set_worker(camera, fixture_map, st)
        results = []
        for i, task in enumerate(tasks):
            results.append(_locate_one(*task))
            if progress is not None:
                progress(i + 1, n)
    else:
        results = _locate_in_pool(tasks, camera, fixture_map, st, n_jobs, progress)
    wall = time.perf_counter() - t0
    return Evaluation(
        results=tuple(results),
        units=fixture_map.units,
        survey=survey,
        jobs=n_jobs,
        wall_time_s=wall,
    )


def _locate_in_pool(
    tasks: list[tuple],
    camera: Camera,
    fixture_map: FixtureMap,
    settings: LocateSettings,
    n_jobs: int,
    progress: Callable[[int, int], None] | None,
) -> list[PhotoResult]:
    """:func:`_locate_one` for every task in ``n_jobs`` worker processes, in task order.

    A worker that dies (out of memory) fails its photo with a reason; the others go on.
    """
    n = len(tasks)
    results: list[PhotoResult | None] = [None] * n
    with ProcessPoolExecutor(
        max_workers=n_jobs,
        mp_context=worker_context(),
        initializer=_init_worker,
        initargs=(camera, fixture_map, settings),
    ) as pool:
        futures = {pool.submit(_locate_one, *task): i for i, task in enumerate(tasks)}
        for done, fut in enumerate(as_completed(futures), 1):
            i = futures[fut]
            try:
                results[i] = fut.result()
            except BrokenProcessPool:
                photo, _, true_pos, true_eul = tasks[i]
                results[i] = PhotoResult(
                    photo=photo,
                    true_position=true_pos,
                    position=None,
                    euler_deg=None,
                    true_euler_deg=true_eul,
                    reason="failed: the worker process died (out of memory?)",
                )
            if progress is not None:
                progress(done, n)
    return [r for r in results if r is not None]


# --------------------------------------------------------------------------------------------
# Files


def write_evaluation(
    evaluation: Evaluation,
    out_dir: str | Path,
    *,
    fixture_map: FixtureMap | None = None,
    magnify: float | None = None,
) -> dict[str, Path]:
    """Write ``results.csv``, ``summary.json``, ``error_map.png`` and ``positions.png``.

    The table by :func:`camvlp.io.writers.write_results_csv`, the figures by
    :func:`camvlp.viz.evaluate_plots.plot_error_map` and ``plot_positions``.

    Returns
    -------
    dict
        The written paths under the keys ``results``, ``summary``, ``error_map``,
        ``positions``.

    Raises
    ------
    InputError
        The folder cannot be created or written (naming it).
    """
    from camvlp.viz.evaluate_plots import plot_error_map, plot_positions

    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
        paths = {
            "results": write_results_csv(evaluation, out / "results.csv"),
            "summary": write_json(out / "summary.json", evaluation.summary()),
        }
        paths["error_map"] = plot_error_map(evaluation, out / "error_map.png")
        paths["positions"] = plot_positions(
            evaluation, out / "positions.png", fixture_map=fixture_map, magnify=magnify
        )
    except OSError as exc:
        raise InputError(f"cannot write the results: {exc.strerror or exc}", out) from None
    return paths
