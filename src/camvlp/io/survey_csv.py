"""The survey file: photographs and their true camera poses, one CSV row per photograph.

A survey CSV has the columns ``photo, x, y, z``: the photograph's path (relative to the CSV's
folder, or absolute) and the true camera centre in map units.  Other columns are allowed and
kept; ``theta_x, theta_y, theta_z`` (the thesis' angles, degrees), when present, are the true
orientation.  :func:`write_survey` writes the file a rendered survey
(:func:`camvlp.sim.survey.render_survey`) leaves beside its photos; :func:`read_survey`
reads any survey, rendered or photographed, for :func:`camvlp.analysis.evaluate.evaluate_survey`.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camvlp.errors import InputError
from camvlp.io.files import MAX_MAGNITUDE
from camvlp.io.limits import limit, read_regular_file

__all__ = [
    "ANGLE_COLUMNS",
    "AXES",
    "REQUIRED_COLUMNS",
    "SURVEY_COLUMNS",
    "Survey",
    "read_survey",
    "write_survey",
]

#: Names of the map frame's axes, in order.
AXES = ("x", "y", "z")

#: Columns every survey CSV needs.
REQUIRED_COLUMNS = ("photo", "x", "y", "z")

#: Optional columns with the true thesis angles, degrees.
ANGLE_COLUMNS = ("theta_x", "theta_y", "theta_z")

#: Columns of the ``survey.csv`` that :func:`write_survey` writes.
SURVEY_COLUMNS = ("photo", "x", "y", "z", "theta_x", "theta_y", "theta_z", "seed")


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
    line_numbers, rows = _survey_rows(p)
    header = [h.strip() for h in rows[0]]
    col, has_angles = _columns(header, len(rows), p)
    extra_columns = tuple(
        h for h in header if h not in REQUIRED_COLUMNS and not (has_angles and h in ANGLE_COLUMNS)
    )
    photos, positions, angles, extra = [], [], [], []
    for line_no, row in zip(line_numbers[1:], rows[1:], strict=True):
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


def _survey_rows(p: Path) -> tuple[list[int], list[list[str]]]:
    """The survey file's rows (its header first) and their line numbers in the file, blank
    lines and ``#`` comments left out."""
    data = read_regular_file(p, "survey file", limit("CAMVLP_MAX_FILE_BYTES"))
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
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
    return [k for k, _ in lines], rows


def _columns(header: list[str], n_rows: int, p: Path) -> tuple[dict[str, int], bool]:
    """Each column's index, and whether the survey gives the true angles; refused when a
    column is missing or given twice, when there is no photo (``n_rows`` counts the header),
    or when only some of the angles are given."""
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
    if n_rows < 2:
        raise InputError("survey file has no photos, only a header", p)
    col = {h: i for i, h in enumerate(header)}
    has_angles = all(c in col for c in ANGLE_COLUMNS)
    some = [c for c in ANGLE_COLUMNS if c in col]
    if some and not has_angles:  # the orientation error would be left out without a word
        missing = ", ".join(c for c in ANGLE_COLUMNS if c not in col)
        raise InputError(
            f"survey file has {', '.join(some)} but not {missing}: give all three angles or none",
            p,
        )
    return col, has_angles


def _cell(text: str, column: str, line_no: int, path: Path) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and abs(value) <= MAX_MAGNITUDE):
        raise InputError(
            f"line {line_no}: {column} must be a finite number within +-{MAX_MAGNITUDE:g}, "
            f"got {text.strip()!r}",
            path,
        )
    return value


def write_survey(path: str | Path, photos, positions, euler_deg, seeds) -> Path:
    """Write a rendered survey's CSV: columns :data:`SURVEY_COLUMNS`, one row per photo.

    Parameters
    ----------
    path : str or Path
        The CSV file.
    photos : sequence of str, length N
        Photo paths relative to the CSV's folder.
    positions : array_like, shape (N, 3)
        True camera centres, map units (written with 6 decimals).
    euler_deg : array_like, shape (N, 3)
        True thesis angles, degrees (4 decimals).
    seeds : sequence of int, length N
        Render seed of each photo.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        The file cannot be written.
    """
    p = Path(path)
    pos = np.asarray(positions, dtype=float).reshape(-1, 3)
    eul = np.asarray(euler_deg, dtype=float).reshape(-1, 3)
    try:
        with open(p, "w", newline="") as fh:
            writer = csv.writer(fh)
            writer.writerow(SURVEY_COLUMNS)
            for name, c, a, seed in zip(photos, pos, eul, seeds, strict=True):
                writer.writerow(
                    [name, *(f"{v:.6f}" for v in c), *(f"{v:.4f}" for v in a), int(seed)]
                )
    except OSError as exc:
        raise InputError(f"cannot write the survey file: {exc.strerror or exc}", p) from None
    return p
