"""Camera calibration: intrinsics from chessboard photographs, row time from a blinking light.

Two measurements make a camera file (``docs/formats.md``) for camvlp:

* :func:`calibrate_camera` finds the intrinsic matrix and lens distortion from photographs
  of a flat chessboard (OpenCV's ``findChessboardCornersSB`` and ``calibrateCamera``).
* :func:`estimate_row_time` (:mod:`camvlp.analysis.row_time`, importable from here) finds
  the rolling shutter's row time from one photograph of a light blinking a 50 % square wave
  at a known frequency: the light appears as a disc of stripes whose period, in rows, is
  ``1 / (frequency * row_time)``.

:func:`estimate_stripe_period` (from ``stripes.py``) measures a stripe period inside any
masked region; the decoder of frequency-coded fixtures uses it too.
:func:`~camvlp.sim.chessboard.render_chessboard` (in :mod:`camvlp.sim.chessboard`, re-exported
here) renders synthetic calibration photographs with a known camera (for tests and benchmarks).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from camvlp.analysis.row_time import (
    RowTimeEstimate,
    bright_blob_mask,
    bright_blob_masks,
    estimate_row_time,
)
from camvlp.imaging.gray import to_gray
from camvlp.imaging.stripe_period import StripePeriod, estimate_stripe_period
from camvlp.io import InputError, load_image
from camvlp.model.camera import Camera
from camvlp.sim.chessboard import board_object_points, parse_board, render_chessboard

__all__ = [
    "CalibrationResult",
    "RowTimeEstimate",
    "StripePeriod",
    "board_object_points",
    "bright_blob_mask",
    "bright_blob_masks",
    "calibrate_camera",
    "estimate_row_time",
    "estimate_stripe_period",
    "find_board_corners",
    "render_chessboard",
]

#: Fewest usable chessboard photographs :func:`calibrate_camera` accepts.
MIN_CALIBRATION_PHOTOS = 3

#: Longest image side (px) the board search runs at; corners are refined at full size.
DETECT_MAX_SIDE_PX = 1600
#: Fewest pixels per square along each side for a board to show at all (light and dark must
#: alternate: at least one sample of each per square).
MIN_SQUARE_PX = 2
#: Shortest image side OpenCV's classic ``findChessboardCorners`` accepts: its adaptive
#: threshold's block, a tenth of the shorter side, must round to 3 pixels or more.
CLASSIC_MIN_SIDE_PX = 15


# --------------------------------------------------------------------------------------
# Chessboard calibration
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class CalibrationResult:
    """The outcome of :func:`calibrate_camera`.  Falsy when calibration failed.

    Attributes
    ----------
    camera : Camera or None
        The calibrated camera (intrinsics, distortion, optional row time); None on failure.
    rms_px : float
        Root-mean-square reprojection error over all used photos' corners, pixels (NaN on
        failure).
    per_image_rms_px : tuple of float
        RMS reprojection error of each used photo, pixels, in the order of ``used``.
    used : tuple of str
        Names of the photos whose board was found and used.
    rejected : tuple of (str, str)
        ``(name, reason)`` of each photo left out: unreadable, no board found, or a
        different image size from the others.
    reason : str
        Why calibration failed ("" on success).
    """

    camera: Camera | None
    rms_px: float
    per_image_rms_px: tuple[float, ...]
    used: tuple[str, ...]
    rejected: tuple[tuple[str, str], ...]
    reason: str = ""

    def __bool__(self) -> bool:
        return self.camera is not None

    @property
    def message(self) -> str:
        """The former name of :attr:`reason`."""
        return self.reason


def find_board_corners(image: np.ndarray, board: tuple[int, int]) -> np.ndarray | None:
    """Sub-pixel chessboard inner corners of a photograph, or None when no board is found.

    Finds the board with ``cv2.findChessboardCornersSB`` (or, failing that, the classic
    ``cv2.findChessboardCorners``) in a copy scaled to at most ``DETECT_MAX_SIDE_PX``
    (1600 px) on its longer side, and refines the corners at full resolution with
    ``cv2.cornerSubPix``, its window kept within 0.4 of the closest corners' spacing.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 3)
        The photograph (gray or BGR, 8- or 16-bit or float).
    board : (int, int)
        Inner corners ``(cols, rows)``.

    Returns
    -------
    ndarray, shape (cols * rows, 2), float32, or None
        Pixel positions in the order of :func:`board_object_points`.
    """
    cols, rows = parse_board(board)
    gray = to_gray(image)
    short, long = sorted(gray.shape[:2])
    if short < max(MIN_SQUARE_PX * (min(cols, rows) + 1), CLASSIC_MIN_SIDE_PX) or (
        long < MIN_SQUARE_PX * (max(cols, rows) + 1)
    ):
        return None  # too small to show (cols + 1) x (rows + 1) squares
    scale = min(1.0, DETECT_MAX_SIDE_PX / max(gray.shape))
    small = (
        gray
        if scale == 1.0
        else cv2.resize(gray, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    )
    sb_flags = cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
    found, corners = cv2.findChessboardCornersSB(small, (cols, rows), flags=sb_flags)
    if not found:
        flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
        found, corners = cv2.findChessboardCorners(small, (cols, rows), flags=flags)
        if not found:
            return None
    corners = np.asarray(corners, dtype=np.float32).reshape(rows, cols, 2)
    if scale != 1.0:  # pixel centres: x_full + 0.5 = (x_small + 0.5) / scale
        sx, sy = gray.shape[1] / small.shape[1], gray.shape[0] / small.shape[0]
        corners = (corners + 0.5) * np.array([sx, sy], dtype=np.float32) - 0.5
    # Refine with cornerSubPix, its window well inside the nearest neighbours' distance.
    spacing = min(
        float(np.linalg.norm(np.diff(corners, axis=0), axis=2).min()),
        float(np.linalg.norm(np.diff(corners, axis=1), axis=2).min()),
    )
    half = int(np.clip(0.4 * spacing, 2, 11))
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-3)
    refined = cv2.cornerSubPix(gray, corners.reshape(-1, 1, 2), (half, half), (-1, -1), crit)
    return refined.reshape(-1, 2)


def calibrate_camera(
    images: Sequence[np.ndarray | str | Path],
    board: tuple[int, int],
    square_m: float,
    *,
    names: Sequence[str] | None = None,
    row_time_s: float | None = None,
    fix_aspect: bool = False,
    zero_tangent: bool = False,
    on_image: Callable[[str], None] | None = None,
) -> CalibrationResult:
    """Calibrate a camera from photographs of a flat chessboard.

    Parameters
    ----------
    images : sequence of ndarray or path
        The photographs, as arrays ((H, W) or (H, W, 3)) or image files.  An unreadable
        file is rejected with its reason, not raised.
    board : (int, int)
        Inner corners ``(cols, rows)`` of the board (a board of 10 x 7 squares has 9 x 6).
        Use different numbers of columns and rows, so the detected corner order is unique.
    square_m : float
        Side of one square, metres.  It scales only the board poses, not the intrinsics.
    names : sequence of str, optional
        A name per image for the report; defaults to the file name or ``image <n>``.
    row_time_s : float, optional
        Rolling-shutter row time to store in the camera, seconds.
    fix_aspect : bool
        Keep ``fx = fy`` (square pixels).
    zero_tangent : bool
        Fix the tangential distortion ``p1 = p2 = 0``.
    on_image : callable, optional
        Called with each photo's name after its board search (for progress display).

    Returns
    -------
    CalibrationResult
        Truthy with the camera and the reprojection errors; falsy with a reason when fewer
        than three photos show the board.

    Raises
    ------
    ValueError
        No images, a bad ``board`` or ``square_m``, or ``names`` of the wrong length.
    """
    board = parse_board(board)
    objp = board_object_points(board, square_m)
    names = _photo_names(images, names)
    if row_time_s is not None and not (0 < row_time_s < 1):
        raise ValueError(f"row_time_s must be a positive number of seconds, got {row_time_s!r}")
    found, rejected = _find_boards(images, names, board, on_image)
    found, size = _keep_common_size(found, rejected)
    order = {n: k for k, n in enumerate(names)}
    rejected.sort(key=lambda r: order.get(r[0], 0))
    used = tuple(n for n, _, _ in found)
    if len(found) < MIN_CALIBRATION_PHOTOS or size is None:
        return CalibrationResult(
            None,
            float("nan"),
            (),
            used,
            tuple(rejected),
            f"only {len(found)} of {len(images)} photos show the {board[0]}x{board[1]} board "
            f"(need {MIN_CALIBRATION_PHOTOS})",
        )
    corners = [c for _, _, c in found]
    camera, rms, per_view = _calibrate(objp, corners, size, row_time_s, fix_aspect, zero_tangent)
    return CalibrationResult(camera, rms, per_view, used, tuple(rejected))


def _photo_names(images: Sequence, names: Sequence[str] | None) -> list[str]:
    """A name per image: the given ones, else the file name or ``image <n>``."""
    if len(images) == 0:
        raise ValueError("images must hold at least one photograph")
    if names is None:
        names = [
            Path(im).name if isinstance(im, (str, Path)) else f"image {k + 1}"
            for k, im in enumerate(images)
        ]
    if len(names) != len(images):
        raise ValueError(f"names has {len(names)} entries for {len(images)} images")
    return list(names)


#: One photo whose board was found: its name, its size (width, height) and its corners.
_Found = tuple[str, tuple[int, int], np.ndarray]


def _find_boards(
    images: Sequence, names: Sequence[str], board: tuple[int, int], on_image
) -> tuple[list[_Found], list[tuple[str, str]]]:
    """The board's corners in every photo that shows it, and ``(name, reason)`` of the rest.

    An unreadable file is rejected with its reason, not raised.
    """
    rejected: list[tuple[str, str]] = []
    found: list[_Found] = []
    for name, item in zip(names, images, strict=True):
        try:
            img = load_image(item) if isinstance(item, (str, Path)) else np.asarray(item)
            corners = find_board_corners(img, board)
        except InputError as exc:
            rejected.append((name, exc.what))
            corners = None
        else:
            if corners is None:
                rejected.append((name, f"no {board[0]}x{board[1]} board found"))
            else:
                found.append((name, (img.shape[1], img.shape[0]), corners))
        if on_image is not None:
            on_image(name)
    return found, rejected


def _keep_common_size(
    found: list[_Found], rejected: list[tuple[str, str]]
) -> tuple[list[_Found], tuple[int, int] | None]:
    """The photos of the most common size (the others appended to ``rejected``), and it."""
    if not found:
        return found, None
    size = Counter(s for _, s, _ in found).most_common(1)[0][0]
    for name, s, _ in found:
        if s != size:
            rejected.append(
                (name, f"size {s[0]}x{s[1]} differs from the others' {size[0]}x{size[1]}")
            )
    return [f for f in found if f[1] == size], size


def _calibrate(
    objp: np.ndarray,
    corners: list[np.ndarray],
    size: tuple[int, int],
    row_time_s: float | None,
    fix_aspect: bool,
    zero_tangent: bool,
) -> tuple[Camera, float, tuple[float, ...]]:
    """OpenCV's calibration of the found corners: the camera, the RMS and each photo's RMS (px)."""
    flags = 0
    k0 = np.eye(3)
    if fix_aspect:
        flags |= cv2.CALIB_FIX_ASPECT_RATIO  # ratio fx / fy taken from k0: 1
    if zero_tangent:
        flags |= cv2.CALIB_ZERO_TANGENT_DIST
    obj = [objp] * len(corners)
    img_pts = [c.reshape(-1, 1, 2) for c in corners]
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    rms, k, dist, _, _, _, _, per_view = cv2.calibrateCameraExtended(
        obj, img_pts, size, k0, np.zeros(5), flags=flags, criteria=crit
    )
    camera = Camera(size[0], size[1], k, np.asarray(dist).reshape(-1), row_time_s)
    return camera, float(rms), tuple(float(v) for v in np.asarray(per_view).reshape(-1))
