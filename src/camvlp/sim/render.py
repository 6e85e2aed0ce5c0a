"""Rolling-shutter photographs of coded ceiling lights (thesis chapter 3, made physical).

The thesis' simulator (section 3.3) projects points on each fixture's rim, fills the polygon
and lays a crude stripe mask over it.  This module renders the same scenes physically:

* **Geometry.**  Each fixture is a disc of its map ``diameter`` in the plane through its
  centre with the map's ``normal`` (else the plane through all the fixtures' centres, facing
  the camera).  Each pixel of the fixture's image bounding box is undistorted into a ray,
  the ray meets the fixture's plane, and the distance ``rho`` of that point from the centre
  gives an anti-aliased coverage ``clip(0.5 - (rho - r) / |grad rho|, 0, 1)``, where
  ``|grad rho|`` is the local size of a pixel on the fixture, map units.
* **The lamp's look.**  Optionally a hot core (a Gaussian bump, centred on the disc or
  ``core_offset`` radii off it in a direction drawn per fixture, in the disc's own plane) and
  a glow around the rim (:func:`camvlp.sim.light.shine`).
* **Optics.**  A Gaussian blur of the coverage (sigma ``blur_px``).
* **Rolling shutter.**  Sensor row ``k`` (image row ``v``, or column ``u`` for a photo
  stored in portrait) integrates light over ``[k * row_time, k * row_time + exposure]``.
  Each LED repeats its frame's Manchester chips (or a 50 % square wave in frequency mode)
  with its own random phase; an LED named in ``data_lights`` sends Manchester chips of random
  bits at ``chip_rate_hz`` instead (:func:`camvlp.sim.light.data_chips`).  The fraction of
  each row's exposure the LED is on is computed exactly from the waveform's cumulative
  on-time.
* **Sensor.**  Irradiance ``ambient + sum(brightness * colour * coverage * on_fraction)`` in
  units of full scale, shot noise (Gaussian approximation of Poisson with ``full_well_e``
  electrons at full scale), read noise, clipping to [0, 1] (saturation: bright stripes come
  out wider than dark ones, the thesis' bleeding, section 5.3) and 8-bit quantisation;
  optionally a phone's processing: vignetting, a Bayer mosaic and its demosaicing, white
  balance, a tone curve and sharpening (:mod:`camvlp.sim.sensor`).
* **Stamp.**  Optionally text burned into the stored photo's bottom-right corner, as a
  camera prints its date and time (:func:`camvlp.sim.sensor.burn_stamp`), after everything
  else (and after a ``mirrored`` camera's flip, so that it reads the right way).

Time origin: sensor row 0 starts its exposure at ``t = 0``.  A fixture with phase ``phase_s``
shows, at time ``t``, chip ``floor((t + phase_s) / chip_s) mod n_chips`` of its frame.

A fixture seen from its back (the camera on the far side of its plane from its normal) is
not drawn.  Points beyond the field of a distorted lens model (where OpenCV's distortion
polynomial folds them back into the picture) count as outside the image.

Pixel coordinates in the truth (:class:`FixtureTruth`) are those of the camera model
(:meth:`Camera.project`); for a ``mirrored`` camera the stored image is flipped left-right
after rendering, so a truth pixel ``u`` is at ``width - 1 - u`` in the stored image.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from camvlp.errors import InputError
from camvlp.geometry.disc import disc_normals, plane_basis, rim_points
from camvlp.io.limits import limit
from camvlp.io.writers import IMAGE_SUFFIXES, save_render
from camvlp.model.camera import DEFAULT_ROW_TIME_S, Camera, Pose, in_front
from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.model.readout import Readout
from camvlp.sim.light import (
    coverage,
    data_chips,
    glow_margin,
    on_fraction,
    pixel_box,
    shine,
)
from camvlp.sim.sensor import burn_stamp, check_stamp, expose

__all__ = [
    "IMAGE_SUFFIXES",
    "MAX_BLUR_PX",
    "FixtureTruth",
    "Render",
    "RenderSettings",
    "all_fully_inside",
    "check_data_lights",
    "check_render_size",
    "core_places",
    "distinct_colours",
    "fixture_truths",
    "id_waveform",
    "render",
    "save_render",
    "sent_waveform",
    "stamp_photo",
    "tilt_limit",
]

#: Rim points used for a fixture's projected outline (bounding box, visibility, extent).
N_RIM = 64
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
        for name in (
            "brightness",
            "ambient",
            "core",
            "halo",
            "soft",
            "blur_px",
            "full_well_e",
            "read_noise",
            "sharpen",
        ):
            value = getattr(self, name)
            if isinstance(value, bool) or not (isinstance(value, (int, float)) and value >= 0):
                raise ValueError(f"{name} must be a non-negative number, got {value!r}")
            if not math.isfinite(value):
                raise ValueError(f"{name} must be finite, got {value!r}")
        if self.blur_px > MAX_BLUR_PX:
            raise ValueError(
                f"blur_px must be at most {MAX_BLUR_PX:g} px (no stripe survives more), "
                f"got {self.blur_px!r}"
            )
        if isinstance(self.off_level, bool) or not (
            isinstance(self.off_level, (int, float)) and 0 <= self.off_level <= 1
        ):
            raise ValueError(f"off_level must be a number from 0 to 1, got {self.off_level!r}")
        for name in ("vignetting", "black_point"):  # fractions of the light, below 1
            value = getattr(self, name)
            if isinstance(value, bool) or not (isinstance(value, (int, float)) and 0 <= value < 1):
                raise ValueError(f"{name} must be a number from 0 to below 1, got {value!r}")
        if isinstance(self.core_offset, bool) or not (
            isinstance(self.core_offset, (int, float)) and 0 <= self.core_offset <= 1
        ):
            raise ValueError(
                f"core_offset must be a number from 0 to 1 (radii), got {self.core_offset!r}"
            )
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
            try:
                cols = np.asarray(self.colours, dtype=float)
            except (TypeError, ValueError):
                raise ValueError("colours must be BGR triples of numbers in 0..1") from None
            if cols.ndim != 2 or cols.shape[1] != 3 or not np.all((cols >= 0) & (cols <= 1)):
                raise ValueError("colours must be BGR triples of numbers in 0..1")
            object.__setattr__(self, "colours", tuple(tuple(map(float, c)) for c in cols))

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


@dataclass(frozen=True)
class FixtureTruth:
    """What the camera sees of one fixture (ground truth of a rendered photo).

    Attributes
    ----------
    id : int
        The fixture's ID.
    pixel : ndarray, shape (2,)
        Projection ``[u, v]`` of the disc's centre, pixels (camera model, with distortion);
        NaN when the centre is behind the camera.
    in_front : bool
        The centre is in front of the camera.
    fully_inside : bool
        The whole disc projects inside the image (and in front of the camera).
    rows_spanned : float
        Extent of the disc's image along the readout axis (sensor rows), pixels.
    frames_spanned : float
        ``rows_spanned * row_time / frame_period``: Manchester frames (or, in frequency mode,
        square-wave periods) the disc's image spans.
    phase_s : float
        The LED's time offset, s (see the module docstring).
    sends_data : bool
        The LED sends random data (``RenderSettings.data_lights``) instead of its ID's
        waveform: any ID a decoder gives it is wrong.  Its ``frames_spanned`` are those of
        the waveform its ID would send.
    core_pixel : ndarray, shape (2,)
        Projection ``[u, v]`` of the hot core's centre, pixels (camera model, with
        distortion; ``pixel`` for a centred core); NaN without a core (``core`` 0), without
        a diameter, or behind the camera.
    """

    id: int
    pixel: np.ndarray
    in_front: bool
    fully_inside: bool
    rows_spanned: float
    frames_spanned: float
    phase_s: float
    sends_data: bool = False
    core_pixel: np.ndarray = dataclasses.field(default_factory=lambda: np.full(2, np.nan))

    def to_dict(self) -> dict:
        """JSON-ready dict (NaN pixels become None)."""
        return {
            "id": int(self.id),
            "pixel": [None if not np.isfinite(x) else float(x) for x in self.pixel],
            "in_front": bool(self.in_front),
            "fully_inside": bool(self.fully_inside),
            "rows_spanned": float(self.rows_spanned),
            "frames_spanned": float(self.frames_spanned),
            "phase_s": float(self.phase_s),
            "sends_data": bool(self.sends_data),
            "core_pixel": (
                [float(x) for x in self.core_pixel]
                if np.all(np.isfinite(self.core_pixel))
                else None
            ),
        }


@dataclass(frozen=True)
class Render:
    """A rendered photograph and its ground truth.

    Attributes
    ----------
    image : ndarray of uint8, shape (H, W, 3)
        The photograph, BGR (mirrored left-right for a ``mirrored`` camera).
    pose : Pose
        The camera's pose, map units and frame.
    fixtures : tuple of FixtureTruth
        One per map fixture, in map order.
    settings : RenderSettings
        The settings used, with ``row_time_s`` and ``exposure_s`` resolved.
    camera : Camera or None
        The camera rendered with.
    stamp_box : tuple of int or None
        The pixels the burned-in text (``settings.stamp``) lights, ``(u0, v0, u1, v1)``,
        end-exclusive, in the fixtures' pixels (the camera model's: for a ``mirrored``
        camera, flipped from the stored photo's); None without a stamp.
    """

    image: np.ndarray
    pose: Pose
    fixtures: tuple[FixtureTruth, ...]
    settings: RenderSettings
    camera: Camera | None = None
    stamp_box: tuple[int, int, int, int] | None = None

    def on_stamp(self, pixel, margin_px: float = 3.0) -> bool:
        """Whether ``pixel`` [u, v] (the fixtures' pixels) lies on the burned-in text: in
        ``stamp_box`` grown by ``margin_px`` pixels each way (False without a stamp)."""
        if self.stamp_box is None:
            return False
        u0, v0, u1, v1 = self.stamp_box
        u, v = float(pixel[0]), float(pixel[1])
        return u0 - margin_px <= u <= u1 + margin_px and v0 - margin_px <= v <= v1 + margin_px

    def truth_dict(self) -> dict:
        """The ground truth as a JSON-ready dict.

        Keys: ``camera_position`` [x, y, z] (map units), ``rotation`` (3 x 3 camera-to-world),
        ``euler_deg`` (the thesis' angles), ``image_size`` [w, h], ``settings``, ``fixtures``
        (list of :meth:`FixtureTruth.to_dict`), plus ``mirrored`` and ``stamp_box``
        ([u0, v0, u1, v1] or None, see the attribute).
        """
        h, w = self.image.shape[:2]
        settings = dataclasses.asdict(self.settings)
        if settings["colours"] is not None:
            settings["colours"] = [list(c) for c in settings["colours"]]
        settings["data_lights"] = list(settings["data_lights"])
        return {
            "camera_position": [float(x) for x in self.pose.position],
            "rotation": self.pose.world_from_camera.tolist(),
            "euler_deg": [float(x) for x in self.pose.euler_deg],
            "image_size": [int(w), int(h)],
            "mirrored": bool(self.camera.mirrored) if self.camera is not None else False,
            "stamp_box": None if self.stamp_box is None else [int(x) for x in self.stamp_box],
            "settings": settings,
            "fixtures": [f.to_dict() for f in self.fixtures],
        }


# --------------------------------------------------------------------------------------------
# Geometry


def _fixture_normals(fixture_map: FixtureMap, pose: Pose) -> np.ndarray:
    """Unit normal of each fixture's disc, shape (N, 3).

    The map's normal when given; otherwise the normal of the plane through all fixture
    centres (when they span one), signed to face the camera; otherwise the direction from
    the fixture towards the camera.
    """
    known = np.array(
        [f.normal if f.normal is not None else [np.nan] * 3 for f in fixture_map.fixtures]
    ).reshape(-1, 3)
    return disc_normals(fixture_map.positions, known, pose.position)


def _rim_points(fixture: Fixture, normal: np.ndarray, n: int = N_RIM) -> np.ndarray:
    """Points on the disc's rim, shape (n, 3), map units (the centre for no diameter)."""
    if fixture.diameter is None:
        return fixture.position[None, :]
    return rim_points(fixture.position[None, :], [fixture.diameter], normal[None, :], n)[0]


def id_waveform(
    fixture_map: FixtureMap, fixture: Fixture, chip_rate_hz: float
) -> tuple[np.ndarray, float]:
    """The periodic waveform a beacon sends for its ID: (chips of one period, uint8 of
    {0, 1}, and a chip's duration, s): its frame's Manchester chips at ``chip_rate_hz``, or in
    frequency mode a 50 % square wave at its ``frequency_hz``."""
    if fixture_map.mode == "frequency":
        return np.array([1, 0], dtype=np.uint8), 0.5 / float(fixture.frequency_hz)
    return fixture_map.frame.chips(fixture.id), 1.0 / chip_rate_hz


def sent_waveform(
    fixture_map: FixtureMap, index: int, settings: RenderSettings
) -> tuple[np.ndarray, float, float]:
    """What fixture ``index`` (in map order) sends in a render with ``settings``.

    Returns
    -------
    chips : ndarray of uint8 of {0, 1}
        One period of its waveform: its ID's (:func:`id_waveform`) or, for a light of
        ``settings.data_lights``, its random data (:func:`camvlp.sim.light.data_chips`).
    chip_s : float
        A chip's duration, s (``1 / chip_rate_hz`` for data, in either map mode).
    smooth_s : float
        The slow driver's smoothing time, s: ``soft`` of a chip, or of the period for a
        frequency-coded beacon.
    """
    f = fixture_map.fixtures[index]
    if f.id in settings.data_lights:
        chip_s = 1.0 / settings.chip_rate_hz
        return data_chips(settings.seed, index), chip_s, settings.soft * chip_s
    chips, chip_s = id_waveform(fixture_map, f, settings.chip_rate_hz)
    unit = chips.size * chip_s if fixture_map.mode == "frequency" else chip_s
    return chips, chip_s, settings.soft * unit


def core_places(fixture_map: FixtureMap, settings: RenderSettings) -> np.ndarray:
    """Where each fixture's hot core is centred, float64 shape (N, 2), in map order: radii
    along the two axes of its disc's plane (:func:`camvlp.geometry.disc.plane_basis` of its
    normal), ``core_offset`` from the centre in a direction drawn from
    ``default_rng([seed, 3])``, one per fixture in map order; zeros for a centred core."""
    n = len(fixture_map.fixtures)
    if settings.core_offset <= 0:
        return np.zeros((n, 2))
    angle = np.random.default_rng([int(settings.seed), 3]).uniform(0.0, 2.0 * np.pi, n)
    return settings.core_offset * np.stack([np.cos(angle), np.sin(angle)], axis=1)


def check_data_lights(fixture_map: FixtureMap, settings: RenderSettings) -> None:
    """Refuse ``settings.data_lights`` naming an ID that is not one of the map's fixtures.

    Raises
    ------
    ValueError
        Naming the first such ID.
    """
    ids = {f.id for f in fixture_map.fixtures}
    unknown = [i for i in settings.data_lights if i not in ids]
    if unknown:
        raise ValueError(f"data_lights names ID {unknown[0]}, not a fixture of the map")


def _phases(fixture_map: FixtureMap, s: RenderSettings) -> list[tuple[float, float]]:
    """Each fixture's ``(period, phase)``, s: its ID's waveform's period and its LED's random
    time offset (drawn in map order from the settings' seed; a light sending data keeps the
    same draw, its offset into its data)."""
    rng = np.random.default_rng([int(s.seed), 1])
    out = []
    for f in fixture_map.fixtures:
        chips, chip_s = id_waveform(fixture_map, f, s.chip_rate_hz)
        period = chips.size * chip_s
        out.append((period, float(rng.uniform(0.0, period))))
    return out


def _truths(
    camera: Camera,
    fixture_map: FixtureMap,
    pose: Pose,
    settings: RenderSettings,
    only: list[int] | None = None,
    phases: list[tuple[float, float]] | None = None,
) -> tuple[tuple[FixtureTruth, ...], np.ndarray, list[np.ndarray]]:
    """Truth per fixture, plus the normals and projected rim points used to render (of the
    fixtures ``only``, by index in map order, when given; ``phases`` from :func:`_phases`)."""
    s = settings.resolved(camera)
    check_data_lights(fixture_map, s)
    normals = _fixture_normals(fixture_map, pose)
    phases = phases or _phases(fixture_map, s)
    cores = core_places(fixture_map, s)
    axis = s.readout.pixel_index
    truths, rims = [], []
    w, h = camera.width, camera.height
    field = _field_radius(camera)
    chosen = range(len(fixture_map.fixtures)) if only is None else only
    for j in chosen:
        f, n = fixture_map.fixtures[j], normals[j]
        period, phase = phases[j]
        centre_px = camera.project(pose, f.position[None, :])[0]
        ahead = bool(in_front(pose.to_camera(f.position[None, :]))[0])
        rim = _rim_points(f, n)
        rim_px, clamped = _project_within_field(camera, pose, rim, field)
        rims.append(rim_px)
        ok = np.all(np.isfinite(rim_px))
        fully = bool(
            ahead
            and ok
            and not np.any(clamped)
            and np.all((rim_px[:, 0] >= -0.5) & (rim_px[:, 0] <= w - 0.5))
            and np.all((rim_px[:, 1] >= -0.5) & (rim_px[:, 1] <= h - 0.5))
        )
        span = float(np.ptp(rim_px[:, axis])) if ok else float("nan")
        core_px = np.full(2, np.nan)
        if s.core > 0 and f.diameter is not None and ahead:
            a, b = plane_basis(n)
            hot = f.position + 0.5 * f.diameter * (cores[j, 0] * a + cores[j, 1] * b)
            core_px = camera.project(pose, hot[None, :])[0]
        truths.append(
            FixtureTruth(
                id=f.id,
                pixel=centre_px,
                in_front=ahead,
                fully_inside=fully,
                rows_spanned=span,
                frames_spanned=span * s.row_time_s / period,
                phase_s=phase,
                sends_data=f.id in s.data_lights,
                core_pixel=core_px,
            )
        )
    return tuple(truths), normals[list(chosen)], rims


def _field_radius(camera: Camera) -> float:
    """Largest normalised (undistorted) radius seen in the image: the lens model's field."""
    if camera.dist_or_none is None:
        return float("inf")
    w, h = camera.width - 1.0, camera.height - 1.0
    border = np.array(
        [[0, 0], [w / 2, 0], [w, 0], [w, h / 2], [w, h], [w / 2, h], [0, h], [0, h / 2]]
    )
    return float(np.linalg.norm(camera.undistort_pixels(border), axis=1).max())


def _project_within_field(
    camera: Camera, pose: Pose, points_world: np.ndarray, field: float
) -> tuple[np.ndarray, np.ndarray]:
    """Project points, first pulling those beyond the lens model's field back onto its edge.

    OpenCV's distortion polynomial folds points far outside the field of view back into the
    image; pulling them in radially keeps them (correctly) outside or on the image border.

    Returns
    -------
    pixels : ndarray, shape (N, 2)
        ``[u, v]``; NaN for points behind the camera.
    clamped : ndarray of bool, shape (N,)
        Points that were beyond the field (so outside the image).
    """
    pc = pose.to_camera(points_world)
    front = pc[:, 2] > 0
    xy = np.full((pc.shape[0], 2), np.nan)
    xy[front] = pc[front, :2] / pc[front, 2:3]
    radius = np.linalg.norm(xy, axis=1)
    clamped = front & (radius > field)
    xy[clamped] *= (field / radius[clamped])[:, None]
    pixels = np.full_like(xy, np.nan)
    if np.any(front):
        obj = np.concatenate([xy[front], np.ones((int(front.sum()), 1))], axis=1)
        uv, _ = cv2.projectPoints(obj, np.zeros(3), np.zeros(3), camera.matrix, camera.dist_or_none)
        pixels[front] = uv.reshape(-1, 2)
    return pixels, clamped


def fixture_truths(
    camera: Camera, fixture_map: FixtureMap, pose: Pose, settings: RenderSettings | None = None
) -> tuple[FixtureTruth, ...]:
    """What a photo from ``pose`` would show of each fixture, without rendering it.

    Parameters
    ----------
    camera : Camera
    fixture_map : FixtureMap
    pose : Pose
        Camera pose in the map's frame and units.
    settings : RenderSettings, optional
        Timing (for ``frames_spanned``), readout axis and seed (for the phases); the
        same as :func:`render` gives for the same arguments.

    Returns
    -------
    tuple of FixtureTruth
        One per fixture, in map order.
    """
    return _truths(camera, fixture_map, pose, settings or RenderSettings())[0]


def all_fully_inside(camera: Camera, fixture_map: FixtureMap, pose: Pose) -> bool:
    """Whether every fixture's whole disc projects inside the image, in front of the camera."""
    return all(t.fully_inside for t in fixture_truths(camera, fixture_map, pose))


def tilt_limit(
    camera: Camera,
    fixture_map: FixtureMap,
    position,
    euler_deg,
    axis: int,
    direction: float = 1.0,
    *,
    step_deg: float = 0.5,
    max_deg: float = 90.0,
    tol_deg: float = 1e-3,
) -> float:
    """Largest tilt keeping every fixture fully inside the image (bisection).

    The tilt is added to one of the thesis' angles: the pose is
    ``Pose.from_euler(position, euler_deg + direction * t * e_axis)``.

    Parameters
    ----------
    camera : Camera
    fixture_map : FixtureMap
    position : array_like, shape (3,)
        Camera centre, map units.
    euler_deg : array_like, shape (3,)
        The untilted thesis angles, degrees; every fixture must be fully inside there.
    axis : {0, 1, 2}
        Which angle to tilt (theta_x, theta_y or theta_z).
    direction : float
        +1 or -1: the sense of the tilt.
    step_deg, max_deg, tol_deg : float
        Search step, largest tilt tried, and bisection tolerance, degrees.

    Returns
    -------
    float
        The limit in degrees (non-negative); ``max_deg`` when never left, 0 when not fully
        inside untilted.
    """
    if axis not in (0, 1, 2):
        raise ValueError(f"axis must be 0, 1 or 2, got {axis!r}")
    base = np.asarray(euler_deg, dtype=float).reshape(3)
    unit = np.zeros(3)
    unit[axis] = math.copysign(1.0, direction)

    def inside(t: float) -> bool:
        return all_fully_inside(camera, fixture_map, Pose.from_euler(position, base + t * unit))

    if not inside(0.0):
        return 0.0
    lo = 0.0
    while lo + step_deg <= max_deg and inside(lo + step_deg):
        lo += step_deg
    hi = lo + step_deg
    if hi > max_deg:
        return max_deg
    while hi - lo > tol_deg:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if inside(mid) else (lo, mid)
    return lo


# --------------------------------------------------------------------------------------------
# Rolling shutter


# --------------------------------------------------------------------------------------------
# Rendering


def _colours(settings: RenderSettings, n: int) -> np.ndarray:
    if settings.colours is None:
        return np.ones((n, 3), dtype=np.float32)
    cols = np.asarray(settings.colours, dtype=np.float32)
    if cols.shape[0] != n:
        raise ValueError(f"colours must give one BGR triple per fixture ({n}), got {cols.shape[0]}")
    return cols


def distinct_colours(n: int) -> tuple[tuple[float, float, float], ...]:
    """``n`` distinct, saturated BGR colours in 0..1 (the thesis' colour per fixture)."""
    hues = (np.arange(n) * 0.618034 + 0.0) % 1.0
    full = np.full(n, 255, np.uint8)
    hsv = np.stack([np.round(hues * 179).astype(np.uint8), full, full], axis=1).reshape(1, n, 3)
    bgr = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR).reshape(n, 3) / 255.0
    return tuple(tuple(float(x) for x in c) for c in bgr)


@dataclass(frozen=True)
class LightPatch:
    """One fixture's light on the sensor, before exposure and noise.

    Attributes
    ----------
    index : int
        The fixture's index in the map.
    box : tuple of int
        Pixel box ``(u0, u1, v0, v1)``, end-exclusive.
    shape : ndarray of float32, shape (v1 - v0, u1 - u0)
        The light's image when fully on, in units of ``brightness``: anti-aliased disc
        coverage, with the hot core and halo, blurred.
    lines : ndarray of int, shape (K,)
        Sensor line (readout order) of each box row, or column for a readout along columns.
    chips : ndarray of {0, 1}
        One period of the LED's waveform, each chip ``chip_s`` seconds.
    chip_s, phase_s, smooth_s : float
        Chip length, the LED's phase and the slow driver's smoothing time, s.
    colour : ndarray of float32, shape (3,)
        BGR colour in 0..1.
    rho : ndarray of float32, shape of ``shape``
        Each pixel's distance from the disc's centre on its plane, in radii.
    """

    index: int
    box: tuple[int, int, int, int]
    shape: np.ndarray
    lines: np.ndarray
    chips: np.ndarray
    chip_s: float
    phase_s: float
    smooth_s: float
    colour: np.ndarray
    rho: np.ndarray

    def on_fraction(
        self, row_time_s: float, exposure_s: float, off_level: float = 0.0
    ) -> np.ndarray:
        """Fraction of each line's exposure (s) the LED is on, float64 shape (K,); a soft
        waveform is integrated over a longer, centred window; ``off_level`` is the light
        an LED gives when off, fraction of on."""
        return on_fraction(
            self.chips,
            self.chip_s,
            self.lines * row_time_s + self.phase_s - 0.5 * self.smooth_s,
            exposure_s + self.smooth_s,
            off_level,
        )

    def light(self, s, take: tuple | None = None) -> np.ndarray:
        """The light it gives over its box, float32 (h, w, 3), units of full scale, with the
        resolved settings ``s`` (timing, off level, brightness, readout); ``take`` (a row and
        a column index of the box) gives it over those pixels only."""
        on = self.on_fraction(s.row_time_s, s.exposure_s, s.off_level).astype(np.float32)
        shape = self.shape
        if take is not None:
            shape, on = shape[take], on[take[0] if s.readout.by_rows else take[1]]
        lit = shape * (on[:, None] if s.readout.by_rows else on[None, :])
        lit *= np.float32(s.brightness)
        return lit[:, :, None] * self.colour[None, None, :]


def light_patches(
    camera: Camera, fixture_map: FixtureMap, pose: Pose, settings: RenderSettings
) -> list[LightPatch]:
    """Each drawn fixture's light (:class:`LightPatch`): those in front of the camera, seen
    from the front, and with a box in the image.  ``settings`` are resolved for ``camera``."""
    return _lights(camera, fixture_map, pose, settings.resolved(camera))[1]


def _lights(camera: Camera, fixture_map: FixtureMap, pose: Pose, s: RenderSettings):
    """The fixtures' truths and their lights (:func:`light_patches`), ``s`` resolved."""
    colours = _colours(s, len(fixture_map.fixtures))
    truths, normals, rims = _truths(camera, fixture_map, pose, s)
    cores = core_places(fixture_map, s)
    off_centre = s.core > 0 and s.core_offset > 0
    w, h = camera.width, camera.height
    margin = math.ceil(4.0 * s.blur_px) + 2
    out = []
    for i, (f, n, rim_px, truth) in enumerate(
        zip(fixture_map.fixtures, normals, rims, truths, strict=True)
    ):
        if not truth.in_front or n @ (pose.position - f.position) <= 0:
            continue  # behind the camera, or seen from the fixture's back
        box = pixel_box(rim_px, w, h, margin + glow_margin(rim_px, s.halo, s.brightness))
        if box is None:
            continue
        axes = np.stack(plane_basis(n)) if off_centre else None
        cov, rho, xy = coverage(
            camera,
            pose.world_from_camera,
            pose.position,
            f.position,
            n,
            0.5 * f.diameter,
            box,
            axes=axes,
        )
        cov = shine(cov, rho, s.core, s.halo, xy, tuple(cores[i]))
        if s.blur_px > 0:
            cov = cv2.GaussianBlur(cov, (0, 0), s.blur_px, borderType=cv2.BORDER_CONSTANT)
        u0, u1, v0, v1 = box
        chips, chip_s, smooth = sent_waveform(fixture_map, i, s)
        k = np.arange(v0, v1) if s.readout.by_rows else np.arange(u0, u1)
        if s.readout.reversed:  # sensor row 0 is the last image row (column)
            k = (h if s.readout.by_rows else w) - 1 - k
        out.append(
            LightPatch(i, box, cov, k, chips, chip_s, truth.phase_s, smooth, colours[i], rho)
        )
    return truths, out


def render(
    camera: Camera,
    fixture_map: FixtureMap,
    pose: Pose,
    settings: RenderSettings | None = None,
) -> Render:
    """Render a rolling-shutter photograph of the fixtures from a camera pose.

    Parameters
    ----------
    camera : Camera
        Intrinsics, distortion, image size, row time, mirroring.
    fixture_map : FixtureMap
        The fixtures; each needs a ``diameter`` (map units).
    pose : Pose
        The camera's pose in the map's frame and units.
    settings : RenderSettings, optional
        Timing, light levels, noise, readout axis, colours, seed.

    Returns
    -------
    Render
        The uint8 BGR image, shape (camera.height, camera.width, 3), and the ground truth.

    Raises
    ------
    InputError
        The camera's picture is over ``CAMVLP_MAX_RENDER_PIXELS``.
    ValueError
        A fixture without a diameter, colours not matching the fixtures, or ``data_lights``
        naming an ID the map does not hold.
    """
    check_render_size(camera)
    s = (settings or RenderSettings()).resolved(camera)
    for f in fixture_map.fixtures:
        if f.diameter is None:
            raise ValueError(f"fixture {f.id} has no diameter (needed to render it)")
    truths, lights = _lights(camera, fixture_map, pose, s)
    patches = []  # (v0, v1, u0, u1, signal float32 (bh, bw, 3))
    for light in lights:
        u0, u1, v0, v1 = light.box
        patches.append((v0, v1, u0, u1, light.light(s)))
    w, h = camera.width, camera.height
    image = expose(patches, w, h, s)
    if camera.mirrored:
        image = np.ascontiguousarray(image[:, ::-1])
    box = stamp_photo(image, s, camera.mirrored)
    return Render(image=image, pose=pose, fixtures=truths, settings=s, camera=camera, stamp_box=box)


def stamp_photo(
    image: np.ndarray, settings: RenderSettings, mirrored: bool = False
) -> tuple[int, int, int, int] | None:
    """Burn ``settings.stamp`` into a stored photo (in place), if any; returns the pixels it
    lit, ``(u0, v0, u1, v1)`` end-exclusive, in the camera model's pixels (flipped left-right
    from the stored photo's when ``mirrored``), or None."""
    if settings.stamp is None:
        return None
    u0, v0, u1, v1 = burn_stamp(image, settings.stamp)
    if mirrored:
        u0, u1 = image.shape[1] - u1, image.shape[1] - u0
    return u0, v0, u1, v1
