"""One rolling-shutter frame of a moving camera, and what it shows of each fixture.

A video frame is read one sensor row after another, and the camera moves meanwhile: each
sensor row sees the room from the pose the camera has at that row's own time.  A frame is
rendered that way (the pose interpolated along a :class:`~camvlp.sim.trajectory.Trajectory`
for every row), with the photograph's physics (:mod:`camvlp.sim.light`,
:mod:`camvlp.sim.sensor`).

Time convention: a frame's time ``t`` is the middle of the exposure of its middle sensor row;
sensor row ``k`` of ``N`` is exposed over
``[t + (k - (N - 1) / 2) * row_time - exposure / 2, ... + exposure]`` and seen from the pose
at the centre of that window.  The LEDs run on the same absolute clock across frames (each
with its own random phase, the same for the whole video), and each frame gets its own noise.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from camvlp.geometry.disc import plane_basis
from camvlp.geometry.projection import in_view
from camvlp.model.camera import Camera, Pose, euler_to_matrix
from camvlp.model.fixtures import Fixture, FixtureMap
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
from camvlp.sim.render import stored_photo
from camvlp.sim.scene import (
    FixtureTruth,
    check_diameters,
    core_places,
    fixture_colours,
    fixture_rim,
    fixture_views,
    led_phases,
    lens_field_radius,
    project_within_field,
    sent_waveform,
)
from camvlp.sim.sensor import expose
from camvlp.sim.settings import RenderSettings, check_render_size
from camvlp.sim.trajectory import Trajectory

__all__ = ["VideoFrame", "render_frame", "row_truths"]


@dataclass(frozen=True)
class VideoFrame:
    """One rendered video frame and its truth.

    Attributes
    ----------
    image : ndarray of uint8, shape (H, W, 3)
        The frame, BGR.
    t : float
        The frame's time (its middle sensor row's mid-exposure), s.
    pose : Pose
        The camera's pose at ``t``.
    fixtures : tuple of FixtureTruth
        What the frame shows of each fixture, each seen from the pose at the time of the
        sensor row through its centre (:func:`row_truths`).
    """

    image: np.ndarray
    t: float
    pose: Pose
    fixtures: tuple[FixtureTruth, ...]


def _row_poses(
    trajectory: Trajectory, times: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:  # (M, 3, 3) world_from_camera, (M, 3) centres
    pos, eul = trajectory.sample(times)
    rot = np.stack([euler_to_matrix(e) for e in eul])
    return rot, pos


def row_truths(
    camera: Camera,
    fixture_map: FixtureMap,
    trajectory: Trajectory,
    t: float,
    settings: RenderSettings | None = None,
) -> tuple[FixtureTruth, ...]:
    """What a frame at ``t`` shows of each fixture, each seen from the pose at the time of
    the sensor row through its centre (where the rolling shutter saw it), in map order; a
    fixture nowhere near the picture (its centre farther outside than its disc's extent) as
    seen from the frame's middle pose."""
    s = (settings or RenderSettings()).resolved(camera)
    n_rows = camera.height if s.readout.by_rows else camera.width
    size = np.array([camera.width, camera.height]) - 0.5
    phases = led_phases(fixture_map, s)
    mid = fixture_views(camera, fixture_map, trajectory.pose(t), s, phases=phases)[0]
    out = []
    for j, truth in enumerate(mid):
        reach = truth.rows_spanned  # the disc's extent, pixels: a cut disc is refined too
        if not np.all(np.abs(truth.pixel - 0.5 * size) <= 0.5 * size + 0.5 + reach):
            out.append(truth)  # behind, or nowhere near the picture: as the mid pose sees it
            continue
        for _ in range(2):  # the row through the centre, then the centre seen from that row
            k = truth.pixel[s.readout.pixel_index]
            if not np.isfinite(k):
                break
            k = (n_rows - 1 - k) if s.readout.reversed else k
            row_t = t + (k - 0.5 * (n_rows - 1)) * s.row_time_s
            pose = trajectory.pose(row_t)
            truth = fixture_views(camera, fixture_map, pose, s, [j], phases)[0][0]
        out.append(truth)
    return tuple(out)


def render_frame(
    camera: Camera,
    fixture_map: FixtureMap,
    trajectory: Trajectory,
    t: float,
    settings: RenderSettings | None = None,
    *,
    noise_seed: int = 0,
) -> VideoFrame:
    """Render one rolling-shutter frame of a moving camera.

    Parameters
    ----------
    camera : Camera
        Intrinsics, distortion, image size and row time.
    fixture_map : FixtureMap
        The fixtures (each with a diameter).
    trajectory : Trajectory
        The camera's path; every sensor row sees the pose at its own mid-exposure time.
    t : float
        The frame's time (its middle sensor row's mid-exposure), s.
    settings : RenderSettings, optional
        LED and sensor settings as for :func:`camvlp.render`; ``seed`` sets the LEDs' phases
        (the same for every frame of a video).
    noise_seed : int
        Seed of this frame's noise (give each frame its own).

    Returns
    -------
    VideoFrame
    """
    check_render_size(camera)
    s = (settings or RenderSettings()).resolved(camera)
    check_diameters(fixture_map)
    mid = trajectory.pose(t)
    patches = _moving_lights(camera, fixture_map, trajectory, t, s)
    image = expose(
        patches, camera.width, camera.height, dataclasses.replace(s, seed=int(noise_seed))
    )
    image, _ = stored_photo(image, camera, s)
    return VideoFrame(
        image=image,
        t=float(t),
        pose=mid,
        fixtures=row_truths(camera, fixture_map, trajectory, t, s),
    )


def _moving_lights(
    camera: Camera, fixture_map: FixtureMap, trajectory: Trajectory, t: float, s: RenderSettings
) -> list[tuple]:
    """Each drawn fixture's light in the frame at ``t``, as :func:`~camvlp.sim.sensor.expose`
    takes it: ``(v0, v1, u0, u1, light)``, the light float32 (v1 - v0, u1 - u0, 3) in units
    of full scale; ``s`` resolved.  Drawn: the fixtures in front of the camera and seen from
    the front at the frame's middle pose, whose box (over the whole frame's motion) is in
    the picture."""
    n_rows = camera.height if s.readout.by_rows else camera.width
    half = 0.5 * (n_rows - 1) * s.row_time_s
    mid = trajectory.pose(t)
    truths, normals, _ = fixture_views(camera, fixture_map, mid, s)
    colours = fixture_colours(s, len(fixture_map.fixtures))
    cores = core_places(fixture_map, s)
    off_centre = s.core > 0 and s.core_offset > 0
    field = lens_field_radius(camera)
    ends = [trajectory.pose(t - half), mid, trajectory.pose(t + half)]
    # the fixtures whose disc and glow may reach the picture at the frame's start, middle
    # or end (as their boxes are swept over those poses)
    reach = 0.5 * fixture_map.diameters
    reach *= 1.0 + glow_reach(s.halo, s.brightness)
    margin = blur_margin(s.blur_px) + 2
    seen = np.any(
        [in_view(camera, pose, fixture_map.positions, reach, margin) for pose in ends], axis=0
    )
    patches = []
    for i, (f, n, truth, colour) in enumerate(
        zip(fixture_map.fixtures, normals, truths, colours, strict=True)
    ):
        if not (seen[i] and truth.in_front) or n @ (mid.position - f.position) <= 0:
            continue
        box = _swept_box(camera, f, n, ends, field, s)
        if box is None:
            continue
        u0, u1, v0, v1 = box
        sensor = sensor_lines(box, camera.width, camera.height, s.readout)
        row_t = t + (sensor - 0.5 * (n_rows - 1)) * s.row_time_s  # mid-exposure of each row
        rot, pos = _row_poses(trajectory, row_t)
        grid = np.broadcast_to(
            (
                np.arange(sensor.size)[:, None]
                if s.readout.by_rows
                else np.arange(sensor.size)[None, :]
            ),
            (v1 - v0, u1 - u0),
        )
        axes = np.stack(plane_basis(n)) if off_centre else None
        cov, rho, xy = coverage(
            camera, rot, pos, f.position, n, 0.5 * f.diameter, box, grid, axes=axes
        )
        shape = lamp_shape(
            cov, rho, xy, tuple(cores[i]), core=s.core, halo=s.halo, blur_px=s.blur_px
        )
        on = _on_fractions(fixture_map, i, row_t, truth.phase_s, s)
        lit = shape * (on[:, None] if s.readout.by_rows else on[None, :])
        lit = lit * np.float32(s.brightness)
        patches.append((v0, v1, u0, u1, lit[:, :, None] * colour[None, None, :]))
    return patches


def _swept_box(
    camera: Camera,
    fixture: Fixture,
    normal: np.ndarray,
    ends: list[Pose],
    field: float,
    s: RenderSettings,
) -> tuple[int, int, int, int] | None:
    """The pixel box ``(u0, u1, v0, v1)`` of a fixture's light over a frame: its rim seen from
    the poses at the frame's start, middle and end (``ends``), with room for the blur and the
    halo (``field``: :func:`~camvlp.sim.scene.lens_field_radius`); None when a rim point is
    behind the camera at one of them, or the box is outside the picture."""
    rim = fixture_rim(fixture, normal)
    rims = [project_within_field(camera, pose, rim, field)[0] for pose in ends]
    if not all(np.all(np.isfinite(r)) for r in rims):
        return None
    rim_all = np.concatenate(rims)
    margin = blur_margin(s.blur_px) + 2 + glow_margin(rim_all, s.halo, s.brightness)
    return pixel_box(rim_all, camera.width, camera.height, margin)


def _on_fractions(
    fixture_map: FixtureMap, index: int, row_t: np.ndarray, phase_s: float, s: RenderSettings
) -> np.ndarray:
    """Fraction of each row's exposure (centred on its time ``row_t``, s) that fixture
    ``index``'s LED is on, float32 shape (K,) (a soft waveform integrated over a longer,
    centred window, as in a photograph)."""
    chips, chip_s, smooth = sent_waveform(fixture_map, index, s)
    start = row_t - 0.5 * s.exposure_s + phase_s - 0.5 * smooth
    on = on_fraction(chips, chip_s, start, s.exposure_s + smooth, s.off_level)
    return on.astype(np.float32)
