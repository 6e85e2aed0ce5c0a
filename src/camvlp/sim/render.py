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

The settings are :mod:`camvlp.sim.settings`'s, the discs, LEDs and truth
:mod:`camvlp.sim.scene`'s, the physics of a light on the sensor :mod:`camvlp.sim.light`'s and
the sensor :mod:`camvlp.sim.sensor`'s; :class:`RenderSettings`, :class:`FixtureTruth`,
:func:`fixture_truths`, :func:`all_fully_inside`, :func:`tilt_limit` and
:func:`check_render_size` are importable from here as well.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import cv2
import numpy as np

from camvlp.geometry.disc import plane_basis
from camvlp.geometry.projection import in_view
from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import FixtureMap
from camvlp.sim.light import (
    blur_margin,
    coverage,
    glow_margin,
    glow_reach,
    lamp_shape,
    on_fraction,
    pixel_box,
    sensor_lines,
)
from camvlp.sim.scene import (
    FixtureTruth,
    all_fully_inside,
    check_diameters,
    core_places,
    fixture_colours,
    fixture_truths,
    fixture_views,
    sent_waveform,
    tilt_limit,
)
from camvlp.sim.sensor import burn_stamp, expose
from camvlp.sim.settings import RenderSettings, check_render_size

__all__ = [
    "FixtureTruth",
    "LightPatch",
    "Render",
    "RenderSettings",
    "all_fully_inside",
    "check_render_size",
    "distinct_colours",
    "fixture_truths",
    "light_patches",
    "render",
    "stamp_photo",
    "stored_photo",
    "tilt_limit",
]


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
    colours = fixture_colours(s, len(fixture_map.fixtures))
    truths, normals, rims = fixture_views(camera, fixture_map, pose, s)
    cores = core_places(fixture_map, s)
    off_centre = s.core > 0 and s.core_offset > 0
    w, h = camera.width, camera.height
    margin = blur_margin(s.blur_px)
    # the fixtures whose disc and glow may reach the picture (a far one across the camera's
    # plane would otherwise be searched for over the whole picture)
    reach = 0.5 * fixture_map.diameters
    seen = in_view(
        camera,
        pose,
        fixture_map.positions,
        reach * (1.0 + glow_reach(s.halo, s.brightness)),
        margin,
    )
    out = []
    for i, (f, n, rim_px, truth) in enumerate(
        zip(fixture_map.fixtures, normals, rims, truths, strict=True)
    ):
        if not (seen[i] and truth.in_front) or n @ (pose.position - f.position) <= 0:
            continue  # out of view, behind the camera, or seen from the fixture's back
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
        core_at = tuple(cores[i])
        shape = lamp_shape(cov, rho, xy, core_at, core=s.core, halo=s.halo, blur_px=s.blur_px)
        chips, chip_s, smooth = sent_waveform(fixture_map, i, s)
        k = sensor_lines(box, w, h, s.readout)
        out.append(
            LightPatch(i, box, shape, k, chips, chip_s, truth.phase_s, smooth, colours[i], rho)
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
    check_diameters(fixture_map)
    truths, lights = _lights(camera, fixture_map, pose, s)
    patches = []  # (v0, v1, u0, u1, signal float32 (bh, bw, 3))
    for light in lights:
        u0, u1, v0, v1 = light.box
        patches.append((v0, v1, u0, u1, light.light(s)))
    w, h = camera.width, camera.height
    image, box = stored_photo(expose(patches, w, h, s), camera, s)
    return Render(image=image, pose=pose, fixtures=truths, settings=s, camera=camera, stamp_box=box)


def stored_photo(
    image: np.ndarray, camera: Camera, settings: RenderSettings
) -> tuple[np.ndarray, tuple[int, int, int, int] | None]:
    """The sensor's picture as the camera stores it: flipped left-right for a ``mirrored``
    camera, then stamped (:func:`stamp_photo`).  Returns the stored image and the stamp's
    box (or None)."""
    if camera.mirrored:
        image = np.ascontiguousarray(image[:, ::-1])
    return image, stamp_photo(image, settings, camera.mirrored)


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
