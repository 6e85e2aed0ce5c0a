"""Evaluate the locator on a survey: photographs with known camera positions (thesis 5.7).

A survey is a CSV file with the columns ``photo, x, y, z``: the photograph's path (relative
to the CSV's folder, or absolute) and the true camera centre in map units.  Other columns are
allowed and kept; ``theta_x, theta_y, theta_z`` (the thesis' angles, degrees), when present,
are the true orientation and give an orientation error too.

:func:`evaluate_survey` locates every photograph, in parallel, and never stops on one: a
photo that cannot be read or located is counted and listed with its reason.  The
:class:`Evaluation` it returns gives the per-photo table (:func:`write_results_csv`), the
summary statistics (:meth:`Evaluation.summary`), and the thesis' two figures: the error over
the floor (figure 5.9, :func:`plot_error_map`) and true versus estimated positions seen from
the top and both sides (figure 5.11, :func:`plot_positions`).
"""

from __future__ import annotations

import csv
import json
import math
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from camvlp.io import InputError, load_image
from camvlp.model.camera import Camera, euler_to_matrix
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.locate import LocateSettings, locate
from camvlp.sim.survey import default_jobs, worker_context

__all__ = [
    "AXES",
    "Evaluation",
    "PhotoResult",
    "Survey",
    "evaluate_survey",
    "floor_axes",
    "plot_error_map",
    "plot_positions",
    "read_survey",
    "write_evaluation",
    "write_results_csv",
]

#: Names of the map frame's axes, in order.
AXES = ("x", "y", "z")

#: Columns every survey CSV needs.
REQUIRED_COLUMNS = ("photo", "x", "y", "z")

#: Optional columns with the true thesis angles, degrees.
ANGLE_COLUMNS = ("theta_x", "theta_y", "theta_z")

_BLUE, _ORANGE = "#1f77b4", "#ff7f0e"


# --------------------------------------------------------------------------------------------
# The survey file


@dataclass(frozen=True)
class Survey:
    """Photographs and their true camera poses, as read from a survey CSV.

    Attributes
    ----------
    path : Path
        The CSV file.
    photos : tuple of str
        Each photo's path as written in the CSV.
    positions : ndarray, shape (N, 3)
        True camera centres, map units.
    euler_deg : ndarray, shape (N, 3), or None
        True thesis angles, degrees, when the CSV has ``theta_x, theta_y, theta_z``.
    extra_columns : tuple of str
        The CSV's other columns, in order.
    extra : tuple of tuple of str
        Their values, one tuple per photo.
    """

    path: Path
    photos: tuple[str, ...]
    positions: np.ndarray
    euler_deg: np.ndarray | None
    extra_columns: tuple[str, ...]
    extra: tuple[tuple[str, ...], ...]

    def __len__(self) -> int:
        return len(self.photos)

    def photo_path(self, index: int) -> Path:
        """Path of photo ``index``: relative paths are relative to the CSV's folder."""
        p = Path(self.photos[index])
        return p if p.is_absolute() else self.path.parent / p


def read_survey(path: str | Path) -> Survey:
    """Read a survey CSV (columns ``photo, x, y, z``; others allowed).

    Blank lines and lines starting with ``#`` are skipped; column names are trimmed.

    Parameters
    ----------
    path : str or Path
        The CSV file.

    Returns
    -------
    Survey

    Raises
    ------
    InputError
        Missing or unreadable file, no header, a missing column, no rows, an empty photo
        cell, or a position or angle that is not a finite number (naming the row: the CSV's
        line number).
    """
    p = Path(path)
    if not p.exists():
        raise InputError("survey file not found", p)
    if p.is_dir():
        raise InputError("survey file is a directory", p)
    try:
        text = p.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read survey file: {exc.__class__.__name__}", p) from None
    lines = [
        (k, ln)
        for k, ln in enumerate(text.splitlines(), 1)
        if ln.strip() and not ln.lstrip().startswith("#")
    ]
    if not lines:
        raise InputError("survey file is empty (it needs the columns photo,x,y,z)", p)
    try:
        rows = list(csv.reader([ln for _, ln in lines]))
    except csv.Error as exc:
        raise InputError(f"malformed survey file: {exc}", p) from None
    header = [h.strip() for h in rows[0]]
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    if missing:
        raise InputError(
            f"survey file lacks the column{'s' if len(missing) > 1 else ''} "
            f"{', '.join(missing)} (needs photo,x,y,z)",
            p,
        )
    if len(set(header)) != len(header):
        dup = next(h for h in header if header.count(h) > 1)
        raise InputError(f"survey file has the column {dup!r} twice", p)
    if len(rows) < 2:
        raise InputError("survey file has no photos, only a header", p)
    col = {h: i for i, h in enumerate(header)}
    has_angles = all(c in col for c in ANGLE_COLUMNS)
    extra_columns = tuple(
        h for h in header if h not in REQUIRED_COLUMNS and not (has_angles and h in ANGLE_COLUMNS)
    )
    photos, positions, angles, extra = [], [], [], []
    for (line_no, _), row in zip(lines[1:], rows[1:], strict=True):
        if len(row) != len(header):
            raise InputError(
                f"line {line_no} has {len(row)} values, the header has {len(header)}", p
            )
        photo = row[col["photo"]].strip()
        if not photo:
            raise InputError(f"line {line_no}: the photo cell is empty", p)
        photos.append(photo)
        positions.append([_cell(row[col[c]], c, line_no, p) for c in AXES])
        if has_angles:
            angles.append([_cell(row[col[c]], c, line_no, p) for c in ANGLE_COLUMNS])
        extra.append(tuple(row[col[c]].strip() for c in extra_columns))
    return Survey(
        path=p,
        photos=tuple(photos),
        positions=np.array(positions, dtype=float),
        euler_deg=np.array(angles, dtype=float) if has_angles else None,
        extra_columns=extra_columns,
        extra=tuple(extra),
    )


def _cell(text: str, column: str, line_no: int, path: Path) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise InputError(
            f"line {line_no}: {column} must be a finite number, got {text.strip()!r}", path
        )
    return value


# --------------------------------------------------------------------------------------------
# Results


@dataclass(frozen=True)
class PhotoResult:
    """The outcome for one photograph of a survey.

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

    @property
    def located(self) -> bool:
        """Whether the photo was located."""
        return self.position is not None

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


def _stats(values: np.ndarray) -> dict[str, float | None]:
    """Mean, median, 95th percentile and maximum of finite values (None when there are none)."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {"mean": None, "median": None, "p95": None, "max": None}
    return {
        "mean": _num(np.mean(v)),
        "median": _num(np.median(v)),
        "p95": _num(np.percentile(v, 95)),
        "max": _num(np.max(v)),
    }


def _num(value: float) -> float | None:
    """A JSON number with 6 significant digits (None for NaN)."""
    v = float(value)
    return float(f"{v:.6g}") if math.isfinite(v) else None


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
        return np.array([r.located for r in self.results], dtype=bool)

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
        ``time_per_photo_ms`` (mean), ``jobs``, ``wall_time_s``, ``survey``, and
        ``failures``: a list of ``{"photo", "reason"}``.
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
        d["jobs"] = self.jobs
        d["wall_time_s"] = round(self.wall_time_s, 2)
        d["survey"] = str(self.survey.path)
        d["failures"] = [
            {"photo": r.photo, "reason": r.reason} for r in self.results if not r.located
        ]
        return d


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
    try:
        res = locate(image, _WORKER["camera"], _WORKER["map"], _WORKER["settings"])
    except InputError as exc:  # e.g. an image of another size than the camera's
        return failed(f"unreadable: {exc.what}")
    except Exception as exc:  # one bad photo must not stop a survey
        return failed(f"failed: {exc.__class__.__name__}: {exc}")
    detected = len(res.fixtures)
    used = sum(f.used for f in res.fixtures)
    if not res:
        return failed(f"not located: {res.error}", fixtures_detected=detected, fixtures_used=used)
    return PhotoResult(
        position=np.asarray(res.position, float),
        euler_deg=np.asarray(res.euler_deg, float),
        reason="",
        fixtures_detected=detected,
        fixtures_used=used,
        reprojection_rms_px=float(res.reprojection_rms_px),
        time_ms=1e3 * (time.perf_counter() - t0),
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
    results: list[PhotoResult | None] = [None] * n
    t0 = time.perf_counter()
    if n_jobs == 1:
        _set_worker(camera, fixture_map, st)
        for i, task in enumerate(tasks):
            results[i] = _locate_one(*task)
            if progress is not None:
                progress(i + 1, n)
    else:
        with ProcessPoolExecutor(
            max_workers=n_jobs,
            mp_context=worker_context(),
            initializer=_init_worker,
            initargs=(camera, fixture_map, st),
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
    wall = time.perf_counter() - t0
    return Evaluation(
        results=tuple(r for r in results if r is not None),
        units=fixture_map.units,
        survey=survey,
        jobs=n_jobs,
        wall_time_s=wall,
    )


# --------------------------------------------------------------------------------------------
# Files and figures

#: Columns of ``results.csv`` (the survey's other columns follow).
RESULT_COLUMNS = (
    "photo",
    "true_x",
    "true_y",
    "true_z",
    "est_x",
    "est_y",
    "est_z",
    "error",
    "error_x",
    "error_y",
    "error_z",
    "located",
    "reason",
    "fixtures_detected",
    "fixtures_used",
    "reprojection_rms_px",
    "true_theta_x",
    "true_theta_y",
    "true_theta_z",
    "est_theta_x",
    "est_theta_y",
    "est_theta_z",
    "angle_error_deg",
    "time_ms",
)


def write_results_csv(evaluation: Evaluation, path: str | Path) -> Path:
    """Write one row per photo (columns :data:`RESULT_COLUMNS`, then the survey's others).

    Errors are estimated minus true, map units; empty cells where there is no value.
    """

    def f(value, digits: int = 9) -> str:
        return "" if value is None or not math.isfinite(value) else f"{value + 0.0:.{digits}g}"

    p = Path(path)
    sv = evaluation.survey
    with open(p, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([*RESULT_COLUMNS, *sv.extra_columns])
        for r, extra in zip(evaluation.results, sv.extra, strict=True):
            est = r.position if r.position is not None else [None] * 3
            eul = r.euler_deg if r.euler_deg is not None else [None] * 3
            teul = r.true_euler_deg if r.true_euler_deg is not None else [None] * 3
            w.writerow(
                [
                    r.photo,
                    *(f(v) for v in r.true_position),
                    *(f(v) for v in est),
                    f(r.error),
                    *(f(v) for v in r.error_vector),
                    int(r.located),
                    r.reason,
                    r.fixtures_detected,
                    r.fixtures_used,
                    f(r.reprojection_rms_px, 4),
                    *(f(v, 6) for v in teul),
                    *(f(v, 6) for v in eul),
                    f(r.angle_error_deg, 4),
                    f(r.time_ms, 5),
                    *extra,
                ]
            )
    return p


def _display_unit(units: str) -> tuple[float, str]:
    """Factor from map units to the unit errors are shown in, and its name (millimetres)."""
    return {"m": (1000.0, "mm"), "cm": (10.0, "mm"), "mm": (1.0, "mm")}.get(units, (1.0, units))


def _figure(width: float, height: float):
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), dpi=100, layout="constrained")


def plot_error_map(evaluation: Evaluation, path: str | Path, *, dpi: int = 110) -> Path:
    """The thesis' figure 5.9: position error over the floor.

    Each photo is a square at its true position on the floor (the two axes along which the
    true positions spread most), coloured by its position error (millimetres for maps in
    m, cm or mm); photos that were not located are grey crosses.

    Returns
    -------
    Path
        ``path``.
    """
    ev = evaluation
    a, b, _ = floor_axes(ev.survey.positions)
    scale, unit = _display_unit(ev.units)
    true = ev.survey.positions
    ok = ev.located
    fig = _figure(6.4, 5.4)
    ax = fig.add_subplot()
    n = max(len(true), 1)
    size = float(np.clip((0.55 * 330.0 / math.sqrt(n)) ** 2, 30.0, 900.0))
    if ok.any():
        sc = ax.scatter(
            true[ok, a],
            true[ok, b],
            c=ev.errors[ok] * scale,
            s=size,
            marker="s",
            cmap="viridis",
            edgecolors="none",
        )
        cb = fig.colorbar(sc, ax=ax, shrink=0.9)
        cb.set_label(f"position error ({unit})")
    if (~ok).any():
        ax.scatter(
            true[~ok, a],
            true[~ok, b],
            s=60,
            marker="x",
            color="0.45",
            label=f"not located ({int((~ok).sum())})",
        )
        ax.legend(loc="upper right", fontsize=8, framealpha=0.9)
    ax.set_xlabel(f"{AXES[a]} ({ev.units})")
    ax.set_ylabel(f"{AXES[b]} ({ev.units})")
    ax.set_aspect("equal", adjustable="datalim")
    ax.margins(0.08)
    errs = ev.errors[ok] * scale
    stats = (
        f"mean {errs.mean():.2f} {unit}, max {errs.max():.2f} {unit}, "
        f"{int(ok.sum())}/{len(ok)} located"
        if ok.any()
        else f"0/{len(ok)} located"
    )
    ax.set_title(f"Position error over the floor ({AXES[a]}-{AXES[b]} plane)\n{stats}", fontsize=10)
    ax.grid(True, alpha=0.3)
    p = Path(path)
    fig.savefig(p, dpi=dpi)
    return p


def _auto_magnify(max_error: float, span: float) -> float:
    """A 1-2-5 magnification drawing the largest error as about 5 % of the survey's span."""
    if not (max_error > 0 and span > 0):
        return 1.0
    m = 0.05 * span / max_error
    if m <= 1.0:
        return 1.0
    decade = 10.0 ** math.floor(math.log10(m))
    return max(s * decade for s in (1.0, 2.0, 5.0) if s * decade <= m)


def plot_positions(
    evaluation: Evaluation,
    path: str | Path,
    *,
    fixture_map: FixtureMap | None = None,
    magnify: float | None = None,
    dpi: int = 110,
) -> Path:
    """The thesis' figure 5.11: true (blue) and estimated (orange) positions, three views.

    Top view (the two floor axes) and both side views (each floor axis against the third,
    vertical axis); a grey line joins each true position to its estimate.

    Parameters
    ----------
    evaluation : Evaluation
    path : str or Path
        The PNG to write.
    fixture_map : FixtureMap, optional
        When given, the vertical axis is drawn with the fixtures' side up (for the thesis'
        room, whose ``y`` points down, the axis is inverted).
    magnify : float, optional
        Draw each estimate at ``true + magnify * (estimate - true)``, so that millimetre
        errors show on a metre-wide survey; the factor is in the title.  Default: a 1-2-5
        factor that draws the largest error as about 5 % of the survey's span (1 when the
        errors are already that large).
    dpi : int

    Returns
    -------
    Path
        ``path``.
    """
    ev = evaluation
    a, b, v = floor_axes(ev.survey.positions)
    true = ev.survey.positions
    ok = ev.located
    vec = ev.error_vectors
    if magnify is None:
        span = float(np.ptp(true[:, [a, b]], axis=0).max()) if len(true) else 0.0
        magnify = _auto_magnify(float(np.nanmax(ev.errors)) if ok.any() else 0.0, span)
    if not (math.isfinite(magnify) and magnify > 0):
        raise ValueError(f"magnify must be a positive number, got {magnify!r}")
    shown = true[ok] + magnify * vec[ok]
    up_is_decreasing = False
    if fixture_map is not None and len(fixture_map.fixtures) and len(true):
        up_is_decreasing = fixture_map.positions[:, v].mean() < true[:, v].mean()
    fig = _figure(13.5, 4.6)
    axes = fig.subplots(1, 3)
    views = ((a, b, "top view"), (a, v, "side view"), (b, v, "side view"))
    for ax, (i, j, name) in zip(axes, views, strict=True):
        if ok.any():
            segs = np.stack([true[ok][:, [i, j]], shown[:, [i, j]]], axis=1)
            from matplotlib.collections import LineCollection

            ax.add_collection(LineCollection(segs, colors="0.55", linewidths=0.8, zorder=1))
        ax.scatter(true[:, i], true[:, j], s=18, color=_BLUE, label="true", zorder=2)
        if ok.any():
            ax.scatter(shown[:, i], shown[:, j], s=18, color=_ORANGE, label="estimated", zorder=3)
        if (~ok).any():
            ax.scatter(
                true[~ok, i],
                true[~ok, j],
                s=50,
                marker="x",
                color="0.3",
                label="not located",
                zorder=4,
            )
        ax.set_xlabel(f"{AXES[i]} ({ev.units})")
        offsets = f"; orange offsets x{magnify:g}" if magnify != 1 and j == v else ""
        ax.set_ylabel(f"{AXES[j]} ({ev.units}{offsets})")
        ax.set_title(f"{name} ({AXES[i]}-{AXES[j]})", fontsize=10)
        ax.grid(True, alpha=0.3)
        ax.margins(0.08)
        if j == v and up_is_decreasing:
            ax.invert_yaxis()
        if name == "top view":
            ax.set_aspect("equal", adjustable="datalim")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=9)
    title = "True (blue) and estimated (orange) camera positions"
    if magnify != 1:
        title += (
            f"; differences magnified {magnify:g}x: estimates drawn at "
            f"true + {magnify:g} x (estimate - true)"
        )
    fig.suptitle(title, fontsize=11)
    p = Path(path)
    fig.savefig(p, dpi=dpi)
    return p


def write_evaluation(
    evaluation: Evaluation,
    out_dir: str | Path,
    *,
    fixture_map: FixtureMap | None = None,
    magnify: float | None = None,
) -> dict[str, Path]:
    """Write ``results.csv``, ``summary.json``, ``error_map.png`` and ``positions.png``.

    Returns
    -------
    dict
        The written paths under the keys ``results``, ``summary``, ``error_map``,
        ``positions``.

    Raises
    ------
    ValueError
        The folder cannot be created or written (naming it).
    """
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
        paths = {
            "results": write_results_csv(evaluation, out / "results.csv"),
            "summary": out / "summary.json",
        }
        paths["summary"].write_text(json.dumps(evaluation.summary(), indent=2) + "\n")
        paths["error_map"] = plot_error_map(evaluation, out / "error_map.png")
        paths["positions"] = plot_positions(
            evaluation, out / "positions.png", fixture_map=fixture_map, magnify=magnify
        )
    except OSError as exc:
        raise ValueError(f"cannot write the results: {exc.strerror or exc} ({out})") from None
    return paths
