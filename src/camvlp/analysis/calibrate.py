"""Camera calibration: intrinsics from chessboard photographs, row time from a blinking light.

Two measurements make a camera file (``docs/formats.md``) for camvlp:

* :func:`calibrate_camera` finds the intrinsic matrix and lens distortion from photographs
  of a flat chessboard (OpenCV's ``findChessboardCornersSB`` and ``calibrateCamera``).
* :func:`estimate_row_time` finds the rolling shutter's row time from one photograph of a
  light blinking a 50 % square wave at a known frequency: the light appears as a disc of
  stripes whose period, in rows, is ``1 / (frequency * row_time)``.

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

from camvlp.imaging.stripe_period import StripePeriod, estimate_stripe_period
from camvlp.io import InputError, load_image
from camvlp.model.camera import Camera
from camvlp.pipeline.detect.candidates import gray_float, to_gray
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


# --------------------------------------------------------------------------------------
# Row time
# --------------------------------------------------------------------------------------


def bright_blob_mask(image: np.ndarray, *, erode_px: int = 2) -> np.ndarray:
    """The pixels of the largest bright light in a photo, its dark stripes included.

    The first of :func:`bright_blob_masks` (all False when nothing stands out).

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 3)
    erode_px : int
        Pixels to erode from the hull's edge.

    Returns
    -------
    ndarray of bool, shape (H, W)
    """
    masks = bright_blob_masks(image, erode_px=erode_px, most=1)
    return masks[0] if masks else np.zeros(np.asarray(image).shape[:2], dtype=bool)


def bright_blob_masks(image: np.ndarray, *, erode_px: int = 2, most: int = 8) -> list[np.ndarray]:
    """The pixels of each bright light in a photo, its dark stripes included, largest first.

    Otsu's threshold of the lightly blurred image and a 3 x 3 opening against specks give
    the bright stripes; starting from the largest, the stripes whose bounding boxes lie
    within one and a half stripe thicknesses of the group join it (the dark gap between
    two stripes of a 50 % square wave is about one stripe thick); the group's convex hull,
    eroded by ``erode_px`` pixels to drop the blurred rim, is the light.  The next light
    starts from the largest stripe left, up to ``most`` lights.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 3)
    erode_px : int
        Pixels to erode from the hull's edge.
    most : int
        At most this many lights.

    Returns
    -------
    list of ndarray of bool, shape (H, W)
        Empty when nothing stands out from the background.
    """
    img = gray_float(image)
    lo, hi = float(img.min()), float(img.max())
    if hi - lo <= 0:
        return []
    u8 = np.clip((img - lo) * (255.0 / (hi - lo)), 0, 255).astype(np.uint8)
    u8 = cv2.GaussianBlur(u8, (3, 3), 0)
    _, binary = cv2.threshold(u8, 0, 255, cv2.THRESH_BINARY | cv2.THRESH_OTSU)
    binary = cv2.morphologyEx(binary, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    n, labels, stats, _ = cv2.connectedComponentsWithStats(binary, connectivity=8)
    left = np.ones(n - 1, dtype=bool)  # stripes not yet in a light
    masks: list[np.ndarray] = []
    for _ in range(most):
        if not left.any():
            break
        member = _stripe_group(stats[1:], left)
        left &= ~member
        pts = np.column_stack(np.nonzero(np.isin(labels, np.flatnonzero(member) + 1)))[:, ::-1]
        if len(pts) < 3:
            continue
        hull = cv2.convexHull(pts.astype(np.int32))
        out = np.zeros(img.shape, dtype=np.uint8)
        cv2.fillConvexPoly(out, hull, 1)
        if erode_px > 0:
            e = 2 * int(erode_px) + 1
            out = cv2.erode(out, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (e, e)))
        masks.append(out.astype(bool))
    return masks


def _stripe_group(stats: np.ndarray, left: np.ndarray) -> np.ndarray:
    """The stripes (rows of ``stats``, OpenCV's component statistics) of one light: the
    largest of those ``left``, grown by the ones within 1.5 stripe thicknesses of the group."""
    x0 = stats[:, cv2.CC_STAT_LEFT].astype(float)
    y0 = stats[:, cv2.CC_STAT_TOP].astype(float)
    x1 = x0 + stats[:, cv2.CC_STAT_WIDTH]
    y1 = y0 + stats[:, cv2.CC_STAT_HEIGHT]
    thick = np.minimum(stats[:, cv2.CC_STAT_WIDTH], stats[:, cv2.CC_STAT_HEIGHT])
    member = np.zeros(len(stats), dtype=bool)
    member[int(np.argmax(np.where(left, stats[:, cv2.CC_STAT_AREA], -1)))] = True
    while True:
        gx0, gy0 = x0[member].min(), y0[member].min()
        gx1, gy1 = x1[member].max(), y1[member].max()
        reach = 1.5 * float(thick[member].max()) + 2.0
        gap = np.maximum(
            np.maximum(gx0 - x1, x0 - gx1).clip(0), np.maximum(gy0 - y1, y0 - gy1).clip(0)
        )
        grown = member | (left & (gap <= reach))
        if grown.sum() == member.sum():
            return member
        member = grown


@dataclass(frozen=True)
class RowTimeEstimate:
    """A rolling shutter's row time measured from a blinking light (:func:`estimate_row_time`).

    Falsy on failure.

    Attributes
    ----------
    row_time_s : float
        Seconds between the starts of two consecutive sensor rows; NaN on failure.
    period_px : float
        Stripe period in pixels (sensor rows) along ``axis``.
    axis : str
        ``"rows"`` (stripes horizontal) or ``"columns"`` (stripes vertical, portrait photo).
    strength : float
        Periodic fraction of the profile's variance, 0-1 (see :class:`StripePeriod`).
    periods_seen : float
        Periods the light spans along ``axis``.
    blob_area_px : int
        Pixels in the light's mask.
    frequency_hz : float
        The light's blink frequency, Hz.
    reason : str
        Why the estimate failed ("" on success).
    """

    row_time_s: float
    period_px: float
    axis: str
    strength: float
    periods_seen: float
    blob_area_px: int
    frequency_hz: float
    reason: str = ""

    def __bool__(self) -> bool:
        return not self.reason

    @property
    def message(self) -> str:
        """The former name of :attr:`reason`."""
        return self.reason

    @property
    def rows_per_s(self) -> float:
        """Sensor rows read per second (``1 / row_time_s``)."""
        return 1.0 / self.row_time_s


#: Weakest periodic component :func:`estimate_row_time` accepts as stripes.
MIN_STRIPE_STRENGTH = 0.3
#: Fewest pixels of a light whose stripes :func:`estimate_row_time` measures.
MIN_LIGHT_PX = 16
#: Largest relative difference between the stripe periods of two lights that may blink at
#: the same frequency: twice the largest error of :func:`estimate_stripe_period`'s precision
#: table (1.7 %, two periods seen), one for each light.
SAME_PERIOD_REL = 2 * 0.017


def estimate_row_time(
    image: np.ndarray, frequency_hz: float, *, axis: str | None = None
) -> RowTimeEstimate:
    """Row time of a rolling-shutter camera from a photo of one light blinking a square wave.

    The light (the largest bright blob, :func:`bright_blob_mask`) shows stripes of period
    ``P`` rows; ``row_time = 1 / (frequency_hz * P)``.  The photo must be at the sensor's
    full resolution (a downscaled photo scales ``P``), the exposure shorter than half a
    blink period, and ``P`` above about 3 rows.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 3)
        The photograph.
    frequency_hz : float
        The light's blink frequency (a 50 % square wave), Hz.
    axis : {"rows", "columns", None}
        Readout axis if known (see :func:`estimate_stripe_period`); None finds it.

    Returns
    -------
    RowTimeEstimate
        Falsy, with a reason, when no light or no clear stripes are found.

    Raises
    ------
    ValueError
        A non-positive frequency, a bad image or an unknown axis.
    """
    if not (np.isfinite(frequency_hz) and frequency_hz > 0):
        raise ValueError(f"frequency_hz must be a positive number, got {frequency_hz!r}")
    nan = float("nan")
    lights = bright_blob_masks(image)
    mask = lights[0] if lights else np.zeros(np.asarray(image).shape[:2], dtype=bool)
    area = int(mask.sum())
    if area < MIN_LIGHT_PX:
        return RowTimeEstimate(
            nan, nan, axis or "rows", 0.0, nan, area, frequency_hz, "no bright light found"
        )
    sp = _light_period(image, mask, axis)
    if not sp:
        return RowTimeEstimate(nan, nan, sp.axis, 0.0, nan, area, frequency_hz, sp.message)
    reason = ""
    if sp.strength < MIN_STRIPE_STRENGTH:
        reason = f"no clear stripes in the light (periodic strength {sp.strength:.2f})"
    elif (other := _other_period(image, lights[1:], sp)) is not None:
        reason = (
            f"the photo shows lights of different stripe periods ({sp.period_px:.2f} and "
            f"{other:.2f} px): photograph the one blinking at {frequency_hz:g} Hz alone"
        )
    return RowTimeEstimate(
        nan if reason else 1.0 / (frequency_hz * sp.period_px),
        sp.period_px,
        sp.axis,
        sp.strength,
        sp.periods_seen,
        area,
        frequency_hz,
        reason,
    )


def _light_period(image: np.ndarray, mask: np.ndarray, axis: str | None) -> StripePeriod:
    """The stripe period of the light ``mask`` (H, W) covers, from its bounding box."""
    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask.any(axis=0))
    box = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
    return estimate_stripe_period(np.asarray(image)[box], mask[box], axis)


def _other_period(image: np.ndarray, others: list[np.ndarray], first: StripePeriod) -> float | None:
    """The stripe period (px) of another light in the photo that cannot blink at the first
    light's frequency (its period differs by more than ``SAME_PERIOD_REL``), or None: which
    light blinks at the given frequency is then unknown."""
    for mask in others:
        if mask.sum() < MIN_LIGHT_PX:
            continue
        sp = _light_period(image, mask, first.axis)
        if sp and sp.strength >= MIN_STRIPE_STRENGTH:
            if abs(sp.period_px / first.period_px - 1.0) > SAME_PERIOD_REL:
                return float(sp.period_px)
    return None
