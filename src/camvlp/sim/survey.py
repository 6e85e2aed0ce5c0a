"""Rendered surveys: simulated photographs over a set of known camera poses.

A survey is a folder of photographs plus ``survey.csv``, one row per photograph: ``photo``
(path relative to the CSV), ``x, y, z`` (the true camera centre, map units) and
``theta_x, theta_y, theta_z`` (the true thesis angles, degrees), followed by ``seed`` (the
render seed of that photo); :mod:`camvlp.io.survey_csv` writes and reads it, and
:func:`camvlp.analysis.evaluate.evaluate_survey` locates every photograph and compares.  This is
the simulated counterpart of the thesis' floor-grid experiment (section 5.7).  Positions on a
grid over the floor come from :func:`camvlp.sim.grid.grid_points`.
"""

from __future__ import annotations

import dataclasses
import multiprocessing
import multiprocessing.context
import os
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

from camvlp.errors import InputError
from camvlp.io.survey_csv import SURVEY_COLUMNS, write_survey
from camvlp.io.writers import IMAGE_SUFFIXES, save_render
from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import FixtureMap
from camvlp.sim.render import RenderSettings, render

__all__ = ["SURVEY_COLUMNS", "default_jobs", "render_survey", "worker_context"]


def default_jobs() -> int:
    """Worker processes used by default: the cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def worker_context() -> multiprocessing.context.BaseContext:
    """Start method of worker processes: ``spawn``.

    A child forked from a process whose OpenCV thread pool is already running can hang in
    its first parallel OpenCV call; spawned workers start clean (about a second each).
    """
    return multiprocessing.get_context("spawn")


# --------------------------------------------------------------------------------------------
# Rendering, one process per core

_WORKER: dict = {}


def _init_worker(camera: Camera, fixture_map: FixtureMap) -> None:
    """Keep the camera and the map in the worker; one OpenCV thread per worker."""
    import cv2

    cv2.setNumThreads(1)
    _WORKER["camera"] = camera
    _WORKER["map"] = fixture_map


def _render_one(
    position: np.ndarray, euler: np.ndarray, settings: RenderSettings, path: Path, quality: int
) -> None:
    result = render(_WORKER["camera"], _WORKER["map"], Pose.from_euler(position, euler), settings)
    save_render(result, path, jpeg_quality=quality)


def render_survey(
    camera: Camera,
    fixture_map: FixtureMap,
    positions,
    euler_deg,
    out_dir,
    settings: RenderSettings | None = None,
    *,
    jobs: int | None = None,
    jpeg_quality: int = 90,
    suffix: str = ".jpg",
    progress: Callable[[int, int], None] | None = None,
) -> Path:
    """Render one photograph per camera pose and write ``survey.csv`` beside them.

    Photo ``i`` is ``out_dir/photo_{i:03d}<suffix>`` (with its ground-truth JSON,
    ``photo_{i:03d}.json``, see :func:`camvlp.io.writers.save_render`), rendered with seed
    ``settings.seed + i`` so that each photo has its own LED phases and noise.

    Parameters
    ----------
    camera : Camera
    fixture_map : FixtureMap
    positions : array_like, shape (N, 3)
        True camera centres, map units and frame.
    euler_deg : array_like, shape (3,) or (N, 3)
        The thesis' angles ``(theta_x, theta_y, theta_z)`` in degrees: one for all photos
        or one per photo.
    out_dir : str or Path
        Folder to write into (created if needed).
    settings : RenderSettings, optional
        Render settings; ``seed`` is the first photo's seed.
    jobs : int, optional
        Worker processes; default all cores.  1 renders in this process.
    jpeg_quality : int
        JPEG quality, 1 to 100 (ignored for PNG).
    suffix : str
        Photo format: ``.jpg``, ``.jpeg`` or ``.png``.
    progress : callable, optional
        Called as ``progress(done, total)`` after each photo.

    Returns
    -------
    Path
        The path of ``survey.csv``.

    Raises
    ------
    ValueError
        Bad shapes or values (naming the argument), a pose or map that cannot be rendered,
        or an output that cannot be written.
    """
    pos, eul = _poses(positions, euler_deg)
    if suffix.lower() not in IMAGE_SUFFIXES:
        raise ValueError(f"suffix must be one of {', '.join(IMAGE_SUFFIXES)}, got {suffix!r}")
    if isinstance(jpeg_quality, bool) or not 1 <= int(jpeg_quality) <= 100:
        raise ValueError(f"jpeg_quality must be from 1 to 100, got {jpeg_quality!r}")
    n_jobs = default_jobs() if jobs is None else int(jobs)
    if n_jobs < 1:
        raise ValueError(f"jobs must be at least 1, got {jobs!r}")
    base = settings or RenderSettings()
    for f in fixture_map.fixtures:
        if f.diameter is None:
            raise ValueError(f"fixture {f.id} has no diameter (needed to render it)")
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the output folder: {exc.strerror}", out) from None
    n = pos.shape[0]
    names = [f"photo_{i:03d}{suffix}" for i in range(n)]
    tasks = [
        (pos[i], eul[i], dataclasses.replace(base, seed=int(base.seed) + i), out / names[i])
        for i in range(n)
    ]
    _render_all(tasks, camera, fixture_map, int(jpeg_quality), n_jobs, progress)
    seeds = [int(base.seed) + i for i in range(n)]
    csv_path = write_survey(out / "survey.csv", names, pos, eul, seeds)
    return csv_path


def _poses(positions, euler_deg) -> tuple[np.ndarray, np.ndarray]:
    """Positions (N, 3) and angles (N, 3, one set repeated for all), checked."""
    pos = np.asarray(positions, dtype=float)
    if pos.ndim != 2 or pos.shape[1] != 3 or pos.shape[0] == 0 or not np.isfinite(pos).all():
        raise ValueError(
            f"positions must be a non-empty (N, 3) array of finite numbers, got shape {pos.shape}"
        )
    n = pos.shape[0]
    eul = np.asarray(euler_deg, dtype=float)
    if eul.shape == (3,):
        eul = np.broadcast_to(eul, (n, 3))
    if eul.shape != (n, 3) or not np.isfinite(eul).all():
        raise ValueError(f"euler_deg must have shape (3,) or ({n}, 3), got {eul.shape}")
    return pos, eul


def _render_all(tasks, camera, fixture_map, quality: int, n_jobs: int, progress) -> None:
    """Render every ``(position, euler, settings, path)`` task, in this process or a pool."""
    n = len(tasks)
    if n_jobs == 1 or n == 1:
        _init_worker_local(camera, fixture_map)
        for done, task in enumerate(tasks, 1):
            _render_one(*task, quality)
            if progress is not None:
                progress(done, n)
        return
    with ProcessPoolExecutor(
        max_workers=min(n_jobs, n),
        mp_context=worker_context(),
        initializer=_init_worker,
        initargs=(camera, fixture_map),
    ) as pool:
        futures = [pool.submit(_render_one, *task, quality) for task in tasks]
        for done, fut in enumerate(as_completed(futures), 1):
            fut.result()  # re-raises a worker's ValueError
            if progress is not None:
                progress(done, n)


def _init_worker_local(camera: Camera, fixture_map: FixtureMap) -> None:
    """Like :func:`_init_worker` but in this process: leave OpenCV's threads alone."""
    _WORKER["camera"] = camera
    _WORKER["map"] = fixture_map
