"""Result files: CSV tables and JSON summaries of studies and evaluations, rendered photos.

Every writer turns an ``OSError`` (a folder that cannot be created, a full disk, no
permission) into :class:`~camvlp.errors.InputError` naming the path, so a command line can
report it in one line.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable, Iterable, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from camvlp.errors import InputError
from camvlp.io.atomic import finite_or_none, strict_json

__all__ = [
    "IMAGE_SUFFIXES",
    "RESULT_COLUMNS",
    "jsonable",
    "save_render",
    "write_csv",
    "write_json",
    "write_outputs",
    "write_results_csv",
]

#: Image suffixes :func:`save_render` writes.
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


@contextmanager
def _writing(path: Path):
    """Turn an OSError while writing ``path`` into an InputError naming it."""
    try:
        yield
    except OSError as exc:
        raise InputError(f"cannot write the results: {exc.strerror or exc}", path) from None


def jsonable(obj: Any) -> Any:
    """``obj`` with NumPy arrays, floats and integers turned into JSON types (NaN -> None).

    The same as :func:`camvlp.io.atomic.finite_or_none`.
    """
    return finite_or_none(obj)


def write_csv(path: str | Path, header: Sequence[str], rows: Iterable[Sequence]) -> Path:
    """Write rows (2-D array or list of sequences) under a header line, floats with %.9g.

    Non-finite floats are written as empty cells.
    """
    p = Path(path)
    with _writing(p), open(p, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for row in rows:
            w.writerow(
                [
                    ("" if not np.isfinite(v) else f"{v:.9g}")
                    if isinstance(v, (float, np.floating))
                    else v
                    for v in row
                ]
            )
    return p


def write_json(path: str | Path, data: dict) -> Path:
    """Write ``data`` as indented JSON (NumPy values converted, NaN as null)."""
    p = Path(path)
    with _writing(p):
        p.write_text(strict_json(data, indent=2) + "\n", encoding="utf-8")
    return p


def write_outputs(out_dir: str | Path, name: str, study, plot: Callable) -> dict:
    """Write a study's ``<name>.csv``, ``<name>.png`` and ``summary.json`` into ``out_dir``.

    Parameters
    ----------
    out_dir : str or Path
        Folder, created if needed.
    name : str
        Base name of the CSV and the PNG.
    study
        Anything with ``csv_header``, ``rows()`` and ``summary()`` (the study results of
        :mod:`camvlp.analysis.study`).
    plot : callable
        ``plot(study, path)`` writes the PNG (see :mod:`camvlp.viz.study_plots`).

    Returns
    -------
    dict
        The summary written.
    """
    out = Path(out_dir)
    with _writing(out):
        out.mkdir(parents=True, exist_ok=True)
        write_csv(out / f"{name}.csv", study.csv_header, study.rows())
        plot(study, out / f"{name}.png")
    summary = study.summary()
    write_json(out / "summary.json", summary)
    return summary


#: Columns of an evaluation's ``results.csv`` (the survey's other columns follow).
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
    "solver",
    "reprojection_rms_px",
    "true_theta_x",
    "true_theta_y",
    "true_theta_z",
    "est_theta_x",
    "est_theta_y",
    "est_theta_z",
    "angle_error_deg",
    "time_ms",
    "sigma_x",
    "sigma_y",
    "sigma_z",
)


def _cell(value: float | None, digits: int = 9) -> str:
    """A number with ``digits`` significant digits; empty for None or NaN."""
    return "" if value is None or not math.isfinite(value) else f"{value + 0.0:.{digits}g}"


def write_results_csv(evaluation, path: str | Path) -> Path:
    """Write one row per photo of an evaluation (:data:`RESULT_COLUMNS`, then the survey's others).

    Errors are estimated minus true, map units; empty cells where there is no value.

    Parameters
    ----------
    evaluation : camvlp.analysis.evaluate.Evaluation
    path : str or Path

    Returns
    -------
    Path
        ``path``.
    """
    p = Path(path)
    sv = evaluation.survey
    none3 = [None] * 3
    with _writing(p), open(p, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([*RESULT_COLUMNS, *sv.extra_columns])
        for r, extra in zip(evaluation.results, sv.extra, strict=True):
            est = r.position if r.position is not None else none3
            eul = r.euler_deg if r.euler_deg is not None else none3
            teul = r.true_euler_deg if r.true_euler_deg is not None else none3
            sigma = r.position_sigma
            w.writerow(
                [
                    r.photo,
                    *(_cell(v) for v in r.true_position),
                    *(_cell(v) for v in est),
                    _cell(r.error),
                    *(_cell(v) for v in r.error_vector),
                    int(bool(r)),
                    r.reason,
                    r.fixtures_detected,
                    r.fixtures_used,
                    r.solver,
                    _cell(r.reprojection_rms_px, 4),
                    *(_cell(v, 6) for v in teul),
                    *(_cell(v, 6) for v in eul),
                    _cell(r.angle_error_deg, 4),
                    _cell(r.time_ms, 5),
                    *(_cell(v, 4) for v in (none3 if sigma is None else sigma)),
                    *extra,
                ]
            )
    return p


def save_render(result, out_path, *, jpeg_quality: int = 95) -> Path:
    """Write a rendered photo and, beside it, ``<stem>.json`` with its ground truth.

    Parameters
    ----------
    result : camvlp.sim.render.Render
        The rendered photo (``image``) and its truth (``truth_dict()``).
    out_path : str or Path
        Image path; the suffix (``.png``, ``.jpg``, ``.jpeg``) picks the format.
    jpeg_quality : int
        JPEG quality, 1 to 100.

    Returns
    -------
    Path
        The JSON file's path.

    Raises
    ------
    ValueError
        Unknown suffix or bad quality.
    InputError
        The files cannot be written (naming the path).
    """
    p = Path(out_path)
    suffix = p.suffix.lower()
    if suffix not in IMAGE_SUFFIXES:
        raise ValueError(
            f"output image must end in {', '.join(IMAGE_SUFFIXES)}, got {p.suffix or 'no suffix'!r}"
            f" ({p})"
        )
    if isinstance(jpeg_quality, bool) or not 1 <= int(jpeg_quality) <= 100:
        raise ValueError(f"jpeg_quality must be from 1 to 100, got {jpeg_quality!r}")
    params = [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)] if suffix != ".png" else []
    ok, buf = cv2.imencode(suffix, result.image, params)
    if not ok:
        raise ValueError(f"cannot encode the image as {suffix} ({p})")
    json_path = p.with_suffix(".json")
    try:
        p.write_bytes(buf.tobytes())
        json_path.write_text(strict_json(result.truth_dict(), indent=2) + "\n")
    except OSError as exc:
        what = exc.strerror or exc.__class__.__name__
        raise InputError(f"cannot write output: {what}", p) from None
    return json_path
