"""What a render draws of each fixture, and the truth it reports of it.

* **The discs.**  Each fixture is a disc of its map ``diameter`` in the plane through its
  centre with the map's ``normal`` (else the plane through all the fixtures' centres, facing
  the camera: :func:`fixture_normals`); its rim (:func:`fixture_rim`) is projected to give
  its outline, pulled back onto the lens model's field first (:func:`project_within_field`),
  for points beyond it that OpenCV's distortion polynomial folds back into the picture.
* **The LEDs.**  Each sends one period of its waveform over and over (:func:`sent_waveform`:
  its ID's, :func:`id_waveform`, or random data), from its own random time offset
  (:func:`led_phases`); a hot core lies off its disc's centre where :func:`core_places` puts
  it.
* **The truth.**  :class:`FixtureTruth` per fixture (:func:`fixture_truths`, and with the
  normals and rims a render needs, :func:`fixture_views`); whether every disc is in the
  picture (:func:`all_fully_inside`), and how far a camera may tilt keeping them so
  (:func:`tilt_limit`).

Pixel coordinates are those of the camera model (:meth:`Camera.project`): for a ``mirrored``
camera the stored image is flipped left-right after rendering, so a truth pixel ``u`` is at
``width - 1 - u`` in the stored image.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import cv2
import numpy as np

from camvlp.geometry.disc import disc_normals, plane_basis, rim_points
from camvlp.model.camera import Camera, Pose, in_front
from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.sim.light import data_chips
from camvlp.sim.settings import RenderSettings

__all__ = [
    "N_RIM",
    "FixtureTruth",
    "all_fully_inside",
    "check_data_lights",
    "check_diameters",
    "core_places",
    "fixture_colours",
    "fixture_normals",
    "fixture_rim",
    "fixture_truths",
    "fixture_views",
    "id_waveform",
    "led_phases",
    "lens_field_radius",
    "project_within_field",
    "sent_waveform",
    "tilt_limit",
]

#: Rim points used for a fixture's projected outline (bounding box, visibility, extent).
N_RIM = 64


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


def fixture_normals(fixture_map: FixtureMap, pose: Pose) -> np.ndarray:
    """Unit normal of each fixture's disc, shape (N, 3).

    The map's normal when given; otherwise the normal of the plane through all fixture
    centres (when they span one), signed to face the camera; otherwise the direction from
    the fixture towards the camera.
    """
    known = np.array(
        [f.normal if f.normal is not None else [np.nan] * 3 for f in fixture_map.fixtures]
    ).reshape(-1, 3)
    return disc_normals(fixture_map.positions, known, pose.position)


def fixture_rim(fixture: Fixture, normal: np.ndarray, n: int = N_RIM) -> np.ndarray:
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


def check_diameters(fixture_map: FixtureMap) -> None:
    """Refuse a map with a fixture without a diameter (a render draws each as a disc).

    Raises
    ------
    ValueError
        Naming the first such fixture.
    """
    for f in fixture_map.fixtures:
        if f.diameter is None:
            raise ValueError(f"fixture {f.id} has no diameter (needed to render it)")


def led_phases(fixture_map: FixtureMap, s: RenderSettings) -> list[tuple[float, float]]:
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


def fixture_views(
    camera: Camera,
    fixture_map: FixtureMap,
    pose: Pose,
    settings: RenderSettings,
    only: list[int] | None = None,
    phases: list[tuple[float, float]] | None = None,
) -> tuple[tuple[FixtureTruth, ...], np.ndarray, list[np.ndarray]]:
    """What the camera sees of each fixture: its truth, and the normal and rim a render draws.

    Parameters
    ----------
    camera, fixture_map, pose
        The scene, as :func:`fixture_truths` takes it.
    settings : RenderSettings
        Timing, readout axis, hot core, data lights and seed (resolved for ``camera`` here).
    only : list of int, optional
        The fixtures to see, by index in map order (default all).
    phases : list of (float, float), optional
        Each fixture's ``(period, phase)`` (:func:`led_phases`), when already drawn.

    Returns
    -------
    truths : tuple of FixtureTruth
        One per fixture seen, in the order of ``only`` (else map order).
    normals : ndarray, shape (K, 3)
        Their discs' unit normals (:func:`fixture_normals`).
    rims : list of ndarray, shape (N_RIM, 2)
        Their rims' pixels (:func:`project_within_field`; NaN behind the camera).
    """
    s = settings.resolved(camera)
    check_data_lights(fixture_map, s)
    normals = fixture_normals(fixture_map, pose)
    phases = phases or led_phases(fixture_map, s)
    chosen = np.arange(len(fixture_map.fixtures)) if only is None else np.asarray(only, int)
    fixtures = [fixture_map.fixtures[j] for j in chosen]
    n = normals[chosen]
    centres, diameters = fixture_map.positions[chosen], fixture_map.diameters[chosen]
    centre_px = camera.project(pose, centres)
    ahead = in_front(pose.to_camera(centres))
    rims = _rims_px(camera, pose, centres, diameters, n)
    cores = core_places(fixture_map, s)[chosen]
    core_px = _core_pixels(camera, pose, centres, diameters, n, cores, s)
    truths = []
    for k, (j, f) in enumerate(zip(chosen, fixtures, strict=True)):
        rim_px, clamped = rims[k]
        ok = bool(np.all(np.isfinite(rim_px)))
        inside = (rim_px >= -0.5) & (rim_px <= np.array([camera.width, camera.height]) - 0.5)
        fully = bool(ahead[k] and ok and not np.any(clamped) and np.all(inside))
        span = float(np.ptp(rim_px[:, s.readout.pixel_index])) if ok else float("nan")
        period, phase = phases[j]
        truths.append(
            FixtureTruth(
                id=f.id,
                pixel=centre_px[k],
                in_front=bool(ahead[k]),
                fully_inside=fully,
                rows_spanned=span,
                frames_spanned=span * s.row_time_s / period,
                phase_s=phase,
                sends_data=f.id in s.data_lights,
                core_pixel=core_px[k],
            )
        )
    return tuple(truths), n, [rim for rim, _ in rims]


def _rims_px(
    camera: Camera, pose: Pose, centres: np.ndarray, diameters: np.ndarray, normals: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each fixture's rim (:func:`fixture_rim`) projected (:func:`project_within_field`),
    all in one batch, from the centres (K, 3), diameters (K,; NaN for none) and normals
    (K, 3): per fixture, its pixels (shape (N_RIM, 2), or (1, 2), its centre, for a fixture
    without a diameter) and which of them were pulled onto the lens' field."""
    if not len(centres):
        return []
    sized = np.isfinite(diameters)
    points = rim_points(centres, np.where(sized, diameters, 0.0), normals, N_RIM)
    pixels, clamped = project_within_field(
        camera, pose, points.reshape(-1, 3), lens_field_radius(camera)
    )
    pixels, clamped = pixels.reshape(len(centres), N_RIM, 2), clamped.reshape(-1, N_RIM)
    # a fixture without a diameter: its centre, which is the rim's every point
    return [
        (p, c) if ok else (p[:1], c[:1]) for p, c, ok in zip(pixels, clamped, sized, strict=True)
    ]


def _core_pixels(
    camera: Camera,
    pose: Pose,
    centres: np.ndarray,
    diameters: np.ndarray,
    normals: np.ndarray,
    cores: np.ndarray,
    s: RenderSettings,
) -> np.ndarray:
    """Where each fixture's hot core projects, shape (K, 2), pixels, from the fixtures'
    centres, diameters (NaN for none), normals and core places (:func:`core_places`): NaN
    without a core (``s.core`` 0), without a diameter, or with its centre behind the camera."""
    out = np.full((len(centres), 2), np.nan)
    if s.core <= 0 or not len(centres):
        return out
    drawn = np.isfinite(diameters) & in_front(pose.to_camera(centres))
    if not drawn.any():
        return out
    a, b = plane_basis(normals[drawn])
    c = cores[drawn]
    hot = centres[drawn] + 0.5 * diameters[drawn, None] * (c[:, :1] * a + c[:, 1:] * b)
    out[drawn] = camera.project(pose, hot)
    return out


def lens_field_radius(camera: Camera) -> float:
    """Largest normalised (undistorted) radius seen in the image: the lens model's field."""
    if camera.dist_or_none is None:
        return float("inf")
    w, h = camera.width - 1.0, camera.height - 1.0
    border = np.array(
        [[0, 0], [w / 2, 0], [w, 0], [w, h / 2], [w, h], [w / 2, h], [0, h], [0, h / 2]]
    )
    return float(np.linalg.norm(camera.undistort_pixels(border), axis=1).max())


def project_within_field(
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
    return fixture_views(camera, fixture_map, pose, settings or RenderSettings())[0]


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


def fixture_colours(settings: RenderSettings, n: int) -> np.ndarray:
    """Each of the ``n`` fixtures' BGR colour in 0..1, float32 shape (n, 3): the settings'
    ``colours``, else white; a ValueError when they are not one per fixture."""
    if settings.colours is None:
        return np.ones((n, 3), dtype=np.float32)
    cols = np.asarray(settings.colours, dtype=np.float32)
    if cols.shape[0] != n:
        raise ValueError(f"colours must give one BGR triple per fixture ({n}), got {cols.shape[0]}")
    return cols
