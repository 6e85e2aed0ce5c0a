"""The sensor and the camera's own processing: light in, the stored 8-bit photo out.

:func:`expose` turns the light that reaches each pixel (ambient plus every lamp's patch, in
units of the sensor's full scale) into the uint8 BGR photo a camera stores.

* **Plain sensor** (the default): shot noise (Gaussian approximation of Poisson with
  ``full_well_e`` electrons at full scale), read noise, clipping to [0, 1] and 8-bit
  quantisation of each of the three channels.  The response is linear up to the clip.
* **A phone's processing**, when any of ``vignetting``, ``bayer``, ``gamma``, ``sharpen`` or
  ``black_point`` is set (:func:`develops`), in the order a camera applies them:

  1. *Vignetting*: the lens passes ``1 - vignetting * (r / r_corner) ** 2`` of the light at a
     distance ``r`` from the image's centre (``r_corner`` at its corners).
  2. *Colour filters*: a white lamp's light reaches the blue, green and red pixels in the
     ratios :data:`RAW_WHITE` (green the most), so the raw channels clip at different
     levels and blue and red carry more noise once balanced.  With ``bayer`` each pixel
     senses one colour of an RGGB mosaic; otherwise all three.
  3. Shot and read noise, the clip at full scale, and a 12-bit analogue-to-digital step.
  4. *Demosaicing* (``bayer``): OpenCV's bilinear interpolation of the missing colours,
     which blurs and colours the stripes' edges.
  5. *White balance*: each channel divided by its :data:`RAW_WHITE` and clipped at full
     scale (a white lamp comes out grey; at a stripe's edge the demosaicing's colours fringe).
  6. *Black point and tone curve*: ``x`` becomes ``max(x - b, 0) / (1 - b)`` for a black
     point ``b`` (a dim background and a glow's faint tail store black, as in a phone's
     photos), then ``x ** (1 / gamma)`` (2.2 is about sRGB), so a dark stripe's dip and the
     LED's off level come out deeper or shallower than the light's.
  7. *Sharpening*: an unsharp mask of amount ``sharpen`` (sigma 1 px), which overshoots at the
     stripes' edges and clips the overshoot.
  8. 8-bit output.

Then, on the stored 8-bit photo (after a ``mirrored`` camera's flip, so that it reads the
right way), a camera may burn in text such as its date and time (:func:`burn_stamp`): white,
anti-aliased, in the bottom-right corner, about :data:`STAMP_HEIGHT` of the photo's height
tall, on top of whatever the photo shows there.

Randomness comes from ``default_rng([seed, 2])`` only, so a photo is reproducible from its
settings.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = [
    "MAX_STAMP_CHARS",
    "PHONE",
    "RAW_WHITE",
    "STAMP_HEIGHT",
    "burn_stamp",
    "camera_date",
    "check_stamp",
    "develops",
    "expose",
]

#: How a white lamp's light reaches the blue, green and red raw pixels, relative to green
#: (a daylight-white LED through a phone's colour filters); white balance divides it out.
RAW_WHITE = np.array([0.7, 1.0, 0.5], dtype=np.float32)

#: A phone camera's processing, as :class:`~camvlp.sim.render.RenderSettings` fields: a
#: colour mosaic, about sRGB's tone curve over a black point just above the default ambient
#: light (the background stores black), moderate sharpening and vignetting.
PHONE = {"bayer": True, "gamma": 2.2, "sharpen": 1.0, "vignetting": 0.3, "black_point": 0.04}

#: Largest value of the 12-bit raw pixels.
RAW_MAX = 4095

#: Sigma of the sharpening's unsharp mask, pixels.
SHARPEN_SIGMA_PX = 1.0

#: Height of a burned-in stamp's characters (a digit's), fraction of the photo's height.
STAMP_HEIGHT = 0.03

#: Most characters a stamp may have.
MAX_STAMP_CHARS = 100

_STAMP_FONT = cv2.FONT_HERSHEY_SIMPLEX
_STAMP_DIGIT_PX = 21.0  # a digit's height in that font at scale 1, pixels (not getTextSize's 27)

_ROW_CHUNK = 128  # image rows per chunk of the full-frame passes (even: see _raw)


def develops(s) -> bool:
    """Whether render settings ``s`` ask for a camera's processing beyond the plain sensor."""
    return bool(s.bayer) or s.vignetting > 0 or s.gamma != 1.0 or s.sharpen > 0 or s.black_point > 0


def expose(patches, width: int, height: int, s) -> np.ndarray:
    """The stored photo of the light reaching the sensor.

    Parameters
    ----------
    patches : sequence of tuple
        ``(v0, v1, u0, u1, light)`` per lamp: its box (rows ``v0:v1``, columns ``u0:u1``) and
        its light there, float32 (v1 - v0, u1 - u0, 3), BGR, units of full scale.
    width, height : int
        Size of the photo, pixels.
    s : RenderSettings
        Resolved settings: ``ambient``, ``full_well_e``, ``read_noise``, ``seed`` and the
        camera's processing (``vignetting``, ``bayer``, ``gamma``, ``sharpen``,
        ``black_point``).

    Returns
    -------
    ndarray, uint8, shape (height, width, 3)
        The BGR photo.
    """
    if not develops(s):
        return _plain(patches, width, height, s)
    raw = _raw(patches, width, height, s)
    if s.bayer:
        raw = cv2.cvtColor(raw, cv2.COLOR_BayerBG2BGR)  # OpenCV's name for this RGGB layout
    return _develop(raw, s)


def _light(patches, r0: int, r1: int, width: int, ambient: float) -> np.ndarray:
    """The light on rows ``r0:r1``: ambient plus the lamps' patches, float32 (r1 - r0, W, 3)."""
    value = np.full((r1 - r0, width, 3), ambient, dtype=np.float32)
    for v0, v1, u0, u1, sig in patches:
        a, b = max(v0, r0), min(v1, r1)
        if a < b:
            value[a - r0 : b - r0, u0:u1] += sig[a - v0 : b - v0]
    return value


def _add_noise(value: np.ndarray, rng: np.random.Generator, s) -> None:
    """Shot and read noise added to ``value`` (units of full scale) in place."""
    shot = 1.0 / s.full_well_e if s.full_well_e > 0 else 0.0
    read_var = float(s.read_noise) ** 2
    if shot > 0 or read_var > 0:
        sigma = value * np.float32(shot)
        sigma += np.float32(read_var)
        np.sqrt(sigma, out=sigma)
        noise = rng.standard_normal(value.shape, dtype=np.float32)
        noise *= sigma
        value += noise


def _plain(patches, width: int, height: int, s) -> np.ndarray:
    """The plain sensor: noise, clip and 8-bit quantisation, in chunks of rows."""
    out = np.empty((height, width, 3), dtype=np.uint8)
    rng = np.random.default_rng([int(s.seed), 2])
    for r0 in range(0, height, _ROW_CHUNK):
        r1 = min(r0 + _ROW_CHUNK, height)
        value = _light(patches, r0, r1, width, s.ambient)
        _add_noise(value, rng, s)
        np.clip(value, 0.0, 1.0, out=value)
        value *= np.float32(255.0)
        np.rint(value, out=value)
        out[r0:r1] = value.astype(np.uint8)
    return out


def _raw(patches, width: int, height: int, s) -> np.ndarray:
    """The 12-bit raw pixels: uint16 (H, W) RGGB mosaic with ``bayer``, else (H, W, 3) BGR."""
    rng = np.random.default_rng([int(s.seed), 2])
    out = np.empty((height, width) if s.bayer else (height, width, 3), dtype=np.uint16)
    cu, cv = 0.5 * (width - 1), 0.5 * (height - 1)
    corner2 = cu * cu + cv * cv
    du2 = ((np.arange(width, dtype=np.float32) - cu) ** 2)[None, :]
    # each pixel's colour in a chunk (chunks start on even rows): rows R G R G ..., then
    # G B G B ... (BGR channels 2, 1, 0)
    mosaic = np.array([[2, 1], [1, 0]])[np.arange(_ROW_CHUNK)[:, None] % 2, np.arange(width) % 2]
    for r0 in range(0, height, _ROW_CHUNK):
        r1 = min(r0 + _ROW_CHUNK, height)
        value = _light(patches, r0, r1, width, s.ambient)
        value *= RAW_WHITE
        if s.vignetting > 0:
            dv2 = ((np.arange(r0, r1, dtype=np.float32) - cv) ** 2)[:, None]
            value *= (1.0 - np.float32(s.vignetting / corner2) * (du2 + dv2))[:, :, None]
        if s.bayer:
            value = np.take_along_axis(value, mosaic[: r1 - r0, :, None], axis=2)[:, :, 0]
        _add_noise(value, rng, s)
        np.clip(value, 0.0, 1.0, out=value)
        value *= np.float32(RAW_MAX)
        np.rint(value, out=value)
        out[r0:r1] = value.astype(np.uint16)
    return out


def _develop(raw: np.ndarray, s) -> np.ndarray:
    """White balance, black point, tone curve and sharpening of 12-bit BGR ``raw``: uint8
    (H, W, 3)."""
    levels = np.arange(RAW_MAX + 1, dtype=np.float64) / RAW_MAX
    toned = np.empty(raw.shape, dtype=np.uint16)
    black = float(s.black_point)
    for c in range(3):  # one lookup table per channel: balance, clip, black, tone, to 16 bits
        lut = np.minimum(levels / float(RAW_WHITE[c]), 1.0)
        if black > 0:
            lut = np.maximum(lut - black, 0.0) / (1.0 - black)
        lut **= 1.0 / float(s.gamma)
        toned[..., c] = np.rint(65535.0 * lut).astype(np.uint16)[raw[..., c]]
    if s.sharpen > 0:
        blurred = cv2.GaussianBlur(toned, (0, 0), SHARPEN_SIGMA_PX)
        toned = cv2.addWeighted(toned, 1.0 + float(s.sharpen), blurred, -float(s.sharpen), 0.0)
    return cv2.convertScaleAbs(toned, alpha=255.0 / 65535.0)


def check_stamp(text) -> None:
    """Refuse a stamp that is not 1 to :data:`MAX_STAMP_CHARS` printable ASCII characters
    (the camera's font has no others).

    Raises
    ------
    ValueError
        Naming ``stamp``.
    """
    if not isinstance(text, str):
        raise ValueError(f"stamp must be text, got {text!r}")
    if not 1 <= len(text) <= MAX_STAMP_CHARS or not text.strip():
        raise ValueError(
            f"stamp must be 1 to {MAX_STAMP_CHARS} characters, not all spaces, got {len(text)}"
        )
    bad = next((c for c in text if not " " <= c <= "~"), None)
    if bad is not None:
        raise ValueError(f"stamp must be printable ASCII text, got {bad!r} in {text!r}")


def camera_date(rng: np.random.Generator) -> str:
    """A random date and time as a camera stamps it, ``"2017-02-15 17:47:52"`` (years 2010 to
    2025, days 1 to 28), drawn from ``rng``."""
    y, mo, d = int(rng.integers(2010, 2026)), int(rng.integers(1, 13)), int(rng.integers(1, 29))
    h, mi, sec = int(rng.integers(24)), int(rng.integers(60)), int(rng.integers(60))
    return f"{y}-{mo:02d}-{d:02d} {h:02d}:{mi:02d}:{sec:02d}"


def burn_stamp(image: np.ndarray, text: str) -> tuple[int, int, int, int]:
    """Burn ``text`` into a stored photo, in place, as a camera prints its date and time.

    White, anti-aliased (OpenCV's Hershey simplex font), in the bottom-right corner with a
    margin of 2 % of the photo's height; a digit :data:`STAMP_HEIGHT` of the photo's height
    tall, strokes an eighth of that wide; smaller if it would not fit the photo's width.
    Each pixel is blended towards white by the text's coverage of it; no other pixel changes.

    Parameters
    ----------
    image : ndarray of uint8, shape (H, W, 3) or (H, W)
        The stored photo.
    text : str
        Printable ASCII (:func:`check_stamp`).

    Returns
    -------
    tuple of int
        The pixels lit, ``(u0, v0, u1, v1)``, end-exclusive (empty, ``(0, 0, 0, 0)``, if the
        photo is too small to show any).
    """
    check_stamp(text)
    h, w = image.shape[:2]
    tall = STAMP_HEIGHT * h
    margin = round(0.02 * h)
    scale = tall / _STAMP_DIGIT_PX
    thickness = max(1, round(tall / 8))
    (tw, _), base = cv2.getTextSize(text, _STAMP_FONT, scale, thickness)
    room = w - 2 * margin - thickness
    if tw > room > 0:  # too wide: smaller, strokes as well
        scale *= room / tw
        thickness = max(1, round(thickness * room / tw))
        (tw, _), base = cv2.getTextSize(text, _STAMP_FONT, scale, thickness)
    origin = (w - margin - tw - thickness // 2, h - margin - base)
    mask = np.zeros((h, w), dtype=np.uint8)
    cv2.putText(mask, text, origin, _STAMP_FONT, scale, 255, thickness, cv2.LINE_AA)
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if rows.size == 0:
        return 0, 0, 0, 0
    v0, v1, u0, u1 = int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1
    alpha = mask[v0:v1, u0:u1].astype(np.uint16)
    if image.ndim == 3:
        alpha = alpha[:, :, None]
    part = image[v0:v1, u0:u1].astype(np.uint16)
    part += ((255 - part) * alpha + 127) // 255
    image[v0:v1, u0:u1] = part.astype(np.uint8)
    return u0, v0, u1, v1
