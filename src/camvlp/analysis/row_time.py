"""The rolling shutter's row time from one photograph of a light blinking a 50 % square wave
at a known frequency: the light appears as a disc of stripes whose period, in rows, is
``1 / (frequency * row_time)`` (:func:`estimate_row_time`, ``camvlp calibrate-rows``).

The light is found as the largest bright blob, its dark stripes included
(:func:`bright_blob_masks`); its stripe period is measured by
:func:`camvlp.imaging.stripe_period.estimate_stripe_period`, which the decoder of frequency-coded
fixtures uses too.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from camvlp.imaging.gray import gray_float
from camvlp.imaging.stripe_period import StripePeriod, estimate_stripe_period

__all__ = ["RowTimeEstimate", "bright_blob_mask", "bright_blob_masks", "estimate_row_time"]


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
