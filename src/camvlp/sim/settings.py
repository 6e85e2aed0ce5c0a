"""How a photograph is rendered: :class:`RenderSettings` (LED and sensor timing, light levels,
the lamps' look, noise, a phone's processing, readout, colours, seed), each checked as it is
given, and the size a render may have.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camvlp.errors import InputError
from camvlp.io.limits import limit
from camvlp.model.camera import DEFAULT_ROW_TIME_S, Camera
from camvlp.model.readout import Readout
from camvlp.sim.sensor import check_stamp

__all__ = ["MAX_BLUR_PX", "RenderSettings", "check_render_size"]

#: The settings that are non-negative numbers (0 turns each off, or is none of it).
_NON_NEGATIVE = (
    "brightness",
    "ambient",
    "core",
    "halo",
    "soft",
    "blur_px",
    "full_well_e",
    "read_noise",
    "sharpen",
)

#: Largest blur sigma, pixels: past it no stripe is left and the blur's cost grows as sigma
#: (OpenCV's kernel of a sigma of 1e6 pixels crashes the process).
MAX_BLUR_PX = 100.0


@dataclass(frozen=True, kw_only=True)
class RenderSettings:
    """How to render a photograph: LED timing, sensor timing, light levels, noise.

    Attributes
    ----------
    chip_rate_hz : float
        Manchester chips per second sent by every LED.
    row_time_s : float or None
        Seconds between the exposure starts of two consecutive sensor rows; None takes the
        camera's ``row_time_s``, else 20 us.
    exposure_s : float or None
        Exposure time of each row, s; None is half a chip (``0.5 / chip_rate_hz``).
    brightness : float
        Irradiance of a fully-on, fully-covered pixel, in units of the sensor's full scale
        (above 1 saturates).
    ambient : float
        Background level, fraction of full scale.
    off_level : float
        Light an LED still gives when "off", fraction of its on level (0 to 1; real drivers
        often leave a few per cent).
    data_lights : tuple of int
        IDs of map fixtures that are no beacon but LEDs sending data: Manchester chips of
        random bits (a sequence of 2 ** 17 chips drawn from ``seed``) at ``chip_rate_hz``,
        in either map mode, instead of their own waveform.  A decoder must give them no ID.
    core : float
        A hot core: the core's centre is ``1 + core`` times as bright as the disc without it
        (a Gaussian bump of sigma 0.4 radius; 0 for a uniform disc).
    core_offset : float
        Where the hot core lies: its centre is this fraction of the disc's radius from the
        disc's centre (0 to 1; 0, the default, centres it), in the disc's own plane, in a
        direction drawn per fixture from ``seed`` (:func:`core_places`); as a real LED's
        brightest spot behind a diffuser, off the middle.
    halo : float
        A glow around the disc (light scattered near the lamp), blinking with it: its level
        just outside the rim, as a fraction of the disc's, decaying over half a radius.
    soft : float
        Softer stripes: the LED's waveform smoothed over this fraction of its period
        (frequency mode) or of a chip (Manchester), like a slow driver (0 for sharp edges).
    blur_px : float
        Sigma of the Gaussian optical blur, pixels (0 for none).
    full_well_e : float
        Electrons at full scale, for shot noise; 0 disables shot noise.
    read_noise : float
        Read-noise sigma, fraction of full scale; 0 disables it.
    vignetting : float
        Fraction of the light the lens loses at the image's corners (0 to 1; falls off as
        the squared distance from the centre).
    bayer : bool
        Sense one colour per pixel through an RGGB mosaic and demosaic it, as a phone does.
    gamma : float
        The camera's tone curve, ``x ** (1 / gamma)`` (1 for a linear response, 2.2 about
        sRGB).
    sharpen : float
        Amount of the camera's unsharp-mask sharpening (0 for none; phones use 0.5 to 1.5).
    black_point : float
        The level of light (fraction of full scale, 0 to below 1) that the camera's
        processing stores as black: levels at or under it store 0, the rest are stretched to
        full scale before the tone curve, as a phone's processing crushes a dim background.
    stamp : str or None
        Text the camera burns into the stored photo's bottom-right corner, white, about 3 %
        of the photo's height tall (e.g. a date and time, ``"2017-02-15 17:47:52"``); printable
        ASCII, at most 100 characters; None for none.
    readout : {"rows", "columns", "rows-reversed", "columns-reversed"}
        ``"rows"``: exposure start grows with image row ``v`` (stripes horizontal);
        ``"columns"``: with image column ``u`` (a photo stored in portrait, stripes vertical);
        ``-reversed``: it falls instead (read bottom up, or right to left).
    colours : tuple of (b, g, r) or None
        One BGR colour in 0..1 per fixture, in map order; None for white.
    seed : int
        Seed of the fixtures' phases and of the noise.
    """

    chip_rate_hz: float = 10_000.0
    row_time_s: float | None = None
    exposure_s: float | None = None
    brightness: float = 4.0
    ambient: float = 0.03
    off_level: float = 0.0
    core: float = 0.0
    core_offset: float = 0.0
    halo: float = 0.0
    soft: float = 0.0
    blur_px: float = 0.8
    full_well_e: float = 8000.0
    read_noise: float = 0.004
    vignetting: float = 0.0
    bayer: bool = False
    gamma: float = 1.0
    sharpen: float = 0.0
    black_point: float = 0.0
    stamp: str | None = None
    readout: Readout = Readout.ROWS
    colours: tuple | None = None
    data_lights: tuple[int, ...] = ()
    seed: int = 0

    def __post_init__(self) -> None:
        _positive(self.chip_rate_hz, "chip_rate_hz")
        if self.row_time_s is not None:
            _positive(self.row_time_s, "row_time_s")
            if self.row_time_s >= 1:
                raise ValueError(f"row_time_s must be below 1 s, got {self.row_time_s}")
        if self.exposure_s is not None:
            _positive(self.exposure_s, "exposure_s")
        for name in _NON_NEGATIVE:
            _non_negative(getattr(self, name), name)
        if self.blur_px > MAX_BLUR_PX:
            raise ValueError(
                f"blur_px must be at most {MAX_BLUR_PX:g} px (no stripe survives more), "
                f"got {self.blur_px!r}"
            )
        _fraction(self.off_level, "off_level")
        for name in ("vignetting", "black_point"):  # fractions of the light, below 1
            _fraction(getattr(self, name), name, below_one=True)
        _fraction(self.core_offset, "core_offset", unit=" (radii)")
        if self.stamp is not None:
            check_stamp(self.stamp)
        object.__setattr__(self, "data_lights", _fixture_ids(self.data_lights))
        _positive(self.gamma, "gamma")
        if not isinstance(self.bayer, bool):
            raise ValueError(f"bayer must be true or false, got {self.bayer!r}")
        object.__setattr__(self, "readout", Readout.parse(self.readout))
        if (
            isinstance(self.seed, bool)
            or not isinstance(self.seed, (int, np.integer))
            or (self.seed < 0)
        ):
            raise ValueError(f"seed must be a non-negative integer, got {self.seed!r}")
        if self.colours is not None:
            object.__setattr__(self, "colours", _bgr_colours(self.colours))

    def resolved(self, camera: Camera) -> RenderSettings:
        """These settings with ``row_time_s`` and ``exposure_s`` filled in for ``camera``."""
        row_time = self.row_time_s
        if row_time is None:
            row_time = camera.row_time_s if camera.row_time_s is not None else DEFAULT_ROW_TIME_S
        exposure = self.exposure_s if self.exposure_s is not None else 0.5 / self.chip_rate_hz
        return dataclasses.replace(self, row_time_s=float(row_time), exposure_s=float(exposure))


def check_render_size(camera: Camera, source: str | Path | None = None) -> None:
    """Refuse a camera whose picture is over ``CAMVLP_MAX_RENDER_PIXELS`` (a render takes
    about 5.5 bytes a pixel with its encoding), before anything is allocated.

    Raises
    ------
    InputError
        Naming ``source`` (the camera file) when given.
    """
    most = limit("CAMVLP_MAX_RENDER_PIXELS")
    if camera.width * camera.height > most:
        raise InputError(
            f"a render of {camera.width} x {camera.height} pixels is over the limit of "
            f"{most:,} (set CAMVLP_MAX_RENDER_PIXELS)",
            source,
        )


def _fixture_ids(value) -> tuple[int, ...]:
    """``data_lights`` as a tuple of distinct non-negative integers, or a ValueError."""
    what = "data_lights must be distinct fixture IDs (non-negative integers)"
    if isinstance(value, (str, bytes)):
        raise ValueError(f"{what}, got {value!r}")
    try:
        ids = tuple(value)
    except TypeError:
        raise ValueError(f"{what}, got {value!r}") from None
    for i in ids:
        if isinstance(i, bool) or not isinstance(i, (int, np.integer)) or i < 0:
            raise ValueError(f"{what}, got {i!r}")
    if len(set(ids)) != len(ids):
        raise ValueError(f"{what}, got {list(ids)} (an ID twice)")
    return tuple(int(i) for i in ids)


def _positive(value, name: str) -> None:
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not (math.isfinite(value) and value > 0)
    ):
        raise ValueError(f"{name} must be a positive number, got {value!r}")


def _non_negative(value, name: str) -> None:
    if isinstance(value, bool) or not (isinstance(value, (int, float)) and value >= 0):
        raise ValueError(f"{name} must be a non-negative number, got {value!r}")
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value!r}")


def _fraction(value, name: str, *, below_one: bool = False, unit: str = "") -> None:
    """Refuse a ``value`` that is not a number from 0 to 1 (``below_one``: to below 1)."""
    top = "below 1" if below_one else "1"
    number = isinstance(value, (int, float)) and not isinstance(value, bool)
    if not number or not (0 <= value < 1 if below_one else 0 <= value <= 1):
        raise ValueError(f"{name} must be a number from 0 to {top}{unit}, got {value!r}")


def _bgr_colours(colours) -> tuple[tuple[float, float, float], ...]:
    """``colours`` as a tuple of BGR triples of floats in 0..1, or a ValueError."""
    try:
        cols = np.asarray(colours, dtype=float)
    except (TypeError, ValueError):
        raise ValueError("colours must be BGR triples of numbers in 0..1") from None
    if cols.ndim != 2 or cols.shape[1] != 3 or not np.all((cols >= 0) & (cols <= 1)):
        raise ValueError("colours must be BGR triples of numbers in 0..1")
    return tuple(tuple(map(float, c)) for c in cols)
