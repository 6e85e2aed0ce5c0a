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
``plot_positions``); :func:`camvlp.viz.evaluate_plots.write_evaluation` writes all four
files.  The results' types
are :mod:`camvlp.analysis.evaluation`'s (importable from here as well).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import replace
from pathlib import Path

import numpy as np

from camvlp.analysis.evaluation import Evaluation, PhotoResult, floor_axes
from camvlp.io import InputError, load_image, load_sidecar
from camvlp.io.survey_csv import ANGLE_COLUMNS, AXES, REQUIRED_COLUMNS, Survey, read_survey
from camvlp.io.writers import write_results_csv
from camvlp.model.camera import Camera
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
    "write_results_csv",
]

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
