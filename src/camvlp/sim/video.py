"""Rolling-shutter videos of a moving camera, with the true trajectory beside them.

A video frame is read one sensor row after another, and the camera moves meanwhile: each
sensor row sees the room from the pose the camera has at that row's own time.  This module
renders frames that way (the pose interpolated along a trajectory for every row) and writes
them as an H.264 video (PyAV, libx264) or as a folder of PNG frames with ``timestamps.csv``.

Time convention: a frame's time ``t`` is the middle of the exposure of its middle sensor row;
sensor row ``k`` of ``N`` is exposed over
``[t + (k - (N - 1) / 2) * row_time - exposure / 2, ... + exposure]`` and seen from the pose
at the centre of that window.  The LEDs run on the same absolute clock across frames (each
with its own random phase, the same for the whole video), and each frame gets its own noise.

Files written beside a video ``DIR/name.mp4`` (or inside a frame folder ``DIR/``):

* ``name_truth.csv`` (``truth.csv``): ``frame,t,x,y,z,theta_x,theta_y,theta_z``, the pose at
  each frame's time (map units, the thesis' angles in degrees);
* ``name_fixtures.csv`` (``fixtures.csv``): ``frame,id,u,v,fully_inside,frames_spanned``, what
  each frame shows of each fixture, seen from the pose at the time of the row through its
  centre (for checking IDs).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from camvlp.errors import InputError
from camvlp.geometry.disc import plane_basis
from camvlp.io.atomic import StagedOutputs
from camvlp.io.files import MAX_MAGNITUDE, read_text_file
from camvlp.io.limits import limit
from camvlp.model.camera import Camera, Pose, euler_to_matrix
from camvlp.model.fixtures import FixtureMap
from camvlp.sim.light import coverage, glow_margin, on_fraction, pixel_box, shine
from camvlp.sim.render import stamp_photo
from camvlp.sim.scene import (
    FixtureTruth,
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

__all__ = [
    "TRAJECTORY_COLUMNS",
    "Trajectory",
    "VideoFrame",
    "check_frame_budget",
    "check_video_size",
    "load_trajectory",
    "partial_path",
    "render_frame",
    "render_video",
    "row_truths",
    "truth_paths",
]

#: Columns of a trajectory CSV.
TRAJECTORY_COLUMNS = ("t", "x", "y", "z", "theta_x", "theta_y", "theta_z")

#: Video suffixes :func:`render_video` writes (anything else is a frame folder).
VIDEO_SUFFIXES = (".mp4", ".mov", ".mkv")


@dataclass(frozen=True)
class Trajectory:
    """A camera's path: poses at increasing times, interpolated linearly in between.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Times, s, strictly increasing.
    position : ndarray, shape (N, 3)
        Camera centres, map units.
    euler_deg : ndarray, shape (N, 3)
        The thesis' angles ``(theta_x, theta_y, theta_z)``, degrees (unwrapped, so that
        interpolation never goes the long way round).
    """

    t: np.ndarray
    position: np.ndarray
    euler_deg: np.ndarray

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=float).reshape(-1)
        p = np.asarray(self.position, dtype=float).reshape(-1, 3)
        e = np.asarray(self.euler_deg, dtype=float).reshape(-1, 3)
        if t.size < 2 or p.shape[0] != t.size or e.shape[0] != t.size:
            raise ValueError("a trajectory needs at least two poses, one per time")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(p)) and np.all(np.isfinite(e))):
            raise ValueError("a trajectory's times and poses must be finite numbers")
        if np.any(np.diff(t) <= 0):
            raise ValueError("a trajectory's times must be strictly increasing")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "position", p)
        object.__setattr__(self, "euler_deg", np.rad2deg(np.unwrap(np.deg2rad(e), axis=0)))

    @property
    def duration_s(self) -> float:
        """Time from the first pose to the last, s."""
        return float(self.t[-1] - self.t[0])

    def sample(self, times) -> tuple[np.ndarray, np.ndarray]:
        """Positions (M, 3) and angles (M, 3, degrees) at ``times`` (M,), s (clamped at ends)."""
        tt = np.asarray(times, dtype=float).reshape(-1)
        pos = np.stack([np.interp(tt, self.t, self.position[:, i]) for i in range(3)], axis=1)
        eul = np.stack([np.interp(tt, self.t, self.euler_deg[:, i]) for i in range(3)], axis=1)
        return pos, eul

    def pose(self, time: float) -> Pose:
        """The pose at one time, s."""
        pos, eul = self.sample([time])
        return Pose.from_euler(pos[0], eul[0])


def load_trajectory(path: str | Path) -> Trajectory:
    """Read a trajectory CSV with the columns ``t,x,y,z,theta_x,theta_y,theta_z``.

    Raises
    ------
    InputError
        Unreadable file, missing columns, non-numbers, fewer than two rows or times that do
        not increase (one line naming the file).
    """
    p = Path(path)
    rows = list(csv.DictReader(io.StringIO(read_text_file(p, "trajectory"), newline="")))
    if not rows:
        raise InputError("the trajectory has no rows", p)
    missing = [c for c in TRAJECTORY_COLUMNS if c not in rows[0]]
    if missing:
        raise InputError(f"the trajectory lacks the column(s) {', '.join(missing)}", p)
    try:
        data = np.array([[float(r[c]) for c in TRAJECTORY_COLUMNS] for r in rows])
    except (TypeError, ValueError):
        raise InputError("the trajectory has a value that is not a number", p) from None
    if np.any(np.abs(data) > MAX_MAGNITUDE):  # as every number of camera and map files
        raise InputError(f"the trajectory has a value beyond +-{MAX_MAGNITUDE:g}", p)
    try:
        return Trajectory(data[:, 0], data[:, 1:4], data[:, 4:7])
    except ValueError as exc:
        raise InputError(str(exc), p) from None


def save_trajectory(trajectory: Trajectory, path: str | Path) -> None:
    """Write a trajectory CSV (``t,x,y,z,theta_x,theta_y,theta_z``)."""
    data = np.column_stack([trajectory.t, trajectory.position, trajectory.euler_deg])
    with Path(path).open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(TRAJECTORY_COLUMNS)
        w.writerows([[f"{v:.6f}" for v in row] for row in data])


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
    for f in fixture_map.fixtures:
        if f.diameter is None:
            raise ValueError(f"fixture {f.id} has no diameter (needed to render it)")
    w, h = camera.width, camera.height
    n_rows = h if s.readout.by_rows else w
    half = 0.5 * (n_rows - 1) * s.row_time_s
    mid = trajectory.pose(t)
    truths, normals, _ = fixture_views(camera, fixture_map, mid, s)
    colours = fixture_colours(s, len(fixture_map.fixtures))
    cores = core_places(fixture_map, s)
    off_centre = s.core > 0 and s.core_offset > 0
    field = lens_field_radius(camera)
    ends = [trajectory.pose(t - half), mid, trajectory.pose(t + half)]
    margin = math.ceil(4.0 * s.blur_px) + 2
    patches = []
    for i, (f, n, truth, colour) in enumerate(
        zip(fixture_map.fixtures, normals, truths, colours, strict=True)
    ):
        if not truth.in_front or n @ (mid.position - f.position) <= 0:
            continue
        rim = fixture_rim(f, n)
        rims = [project_within_field(camera, p, rim, field)[0] for p in ends]
        if not all(np.all(np.isfinite(r)) for r in rims):
            continue
        rim_all = np.concatenate(rims)
        box = pixel_box(rim_all, w, h, margin + 2 + glow_margin(rim_all, s.halo, s.brightness))
        if box is None:
            continue
        u0, u1, v0, v1 = box
        k = np.arange(v0, v1) if s.readout.by_rows else np.arange(u0, u1)
        sensor = (n_rows - 1 - k) if s.readout.reversed else k
        row_t = t + (sensor - 0.5 * (n_rows - 1)) * s.row_time_s  # mid-exposure of each row
        rot, pos = _row_poses(trajectory, row_t)
        grid = np.broadcast_to(
            (np.arange(k.size)[:, None] if s.readout.by_rows else np.arange(k.size)[None, :]),
            (v1 - v0, u1 - u0),
        )
        axes = np.stack(plane_basis(n)) if off_centre else None
        cov, rho, xy = coverage(
            camera, rot, pos, f.position, n, 0.5 * f.diameter, box, grid, axes=axes
        )
        cov = shine(cov, rho, s.core, s.halo, xy, tuple(cores[i]))
        if s.blur_px > 0:
            cov = cv2.GaussianBlur(cov, (0, 0), s.blur_px, borderType=cv2.BORDER_CONSTANT)
        chips, chip_s, smooth = sent_waveform(fixture_map, i, s)
        start = row_t - 0.5 * s.exposure_s + truth.phase_s - 0.5 * smooth
        on = on_fraction(chips, chip_s, start, s.exposure_s + smooth, s.off_level)
        on = on.astype(np.float32)
        lit = cov * (on[:, None] if s.readout.by_rows else on[None, :]) * np.float32(s.brightness)
        patches.append((v0, v1, u0, u1, lit[:, :, None] * colour[None, None, :]))
    image = expose(patches, w, h, dataclasses.replace(s, seed=int(noise_seed)))
    if camera.mirrored:
        image = np.ascontiguousarray(image[:, ::-1])
    stamp_photo(image, s, camera.mirrored)
    return VideoFrame(
        image=image,
        t=float(t),
        pose=mid,
        fixtures=row_truths(camera, fixture_map, trajectory, t, s),
    )


def frame_count(trajectory: Trajectory, fps: float, max_frames: int | None = None) -> int:
    """How many frames a video at ``fps`` along ``trajectory`` has (at most ``max_frames``).

    Frame ``i`` is at ``trajectory.t[0] + i / fps``, s; the times are made one frame at a time,
    never all at once (a trajectory of years at 30 frames/s is billions of frames).
    """
    if not (fps > 0 and math.isfinite(fps)):
        raise ValueError(f"fps must be a positive number, got {fps!r}")
    n = math.floor(trajectory.duration_s * fps + 1e-9) + 1
    return n if max_frames is None else min(n, max(int(max_frames), 0))


def check_frame_budget(frames: int, source: str | Path | None = None) -> None:
    """Refuse a render of more than ``CAMVLP_MAX_FRAMES`` frames (before the first one).

    Raises
    ------
    InputError
        Naming ``source`` (the trajectory) when given.
    """
    most = limit("CAMVLP_MAX_FRAMES")
    if frames > most:
        raise InputError(
            f"a render of {frames:,} frames is over the limit of {most:,} "
            "(set CAMVLP_MAX_FRAMES, or give --frames)",
            source,
        )


def check_video_size(camera: Camera, source: str | Path | None = None) -> None:
    """Refuse a camera whose picture cannot be an H.264 4:2:0 video: an odd width or height.

    Raises
    ------
    InputError
        Naming ``source`` (the camera file) when given.
    """
    if camera.width % 2 or camera.height % 2:
        raise InputError(
            f"an H.264 video needs an even width and height (4:2:0), the camera's picture is "
            f"{camera.width} x {camera.height}: write a folder of PNG frames instead",
            source,
        )


def truth_paths(out: str | Path) -> tuple[Path, Path]:
    """Where the truth of a video (``x.mp4``) or frame folder is written: (poses, fixtures)."""
    p = Path(out)
    if p.suffix.lower() in VIDEO_SUFFIXES:
        return p.with_name(p.stem + "_truth.csv"), p.with_name(p.stem + "_fixtures.csv")
    return p / "truth.csv", p / "fixtures.csv"


def iter_frames(
    camera: Camera,
    fixture_map: FixtureMap,
    trajectory: Trajectory,
    fps: float,
    settings: RenderSettings | None = None,
    max_frames: int | None = None,
) -> Iterator[VideoFrame]:
    """Render the frames of a video at ``fps`` along ``trajectory``, one after another (at most
    ``max_frames``; frame ``i`` at ``trajectory.t[0] + i / fps``, s)."""
    base = int((settings or RenderSettings()).seed)
    t0 = float(trajectory.t[0])
    for i in range(frame_count(trajectory, fps, max_frames)):
        t = t0 + i / fps
        yield render_frame(
            camera, fixture_map, trajectory, t, settings, noise_seed=base * 100003 + i + 1
        )


def render_video(
    camera: Camera,
    fixture_map: FixtureMap,
    trajectory: Trajectory,
    out: str | Path,
    *,
    fps: float = 30.0,
    settings: RenderSettings | None = None,
    crf: int = 10,
    max_frames: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> int:
    """Render a video along a trajectory and write it with its truth.

    Parameters
    ----------
    camera, fixture_map, trajectory
        The scene and the camera's path.
    out : str or Path
        ``*.mp4`` / ``*.mov`` / ``*.mkv``: an H.264 video (PyAV's libx264, constant quality
        ``crf``, 4:2:0); anything else: a folder of ``frame_000000.png`` ... with
        ``timestamps.csv`` (``frame,t``).  The truth goes beside it (:func:`truth_paths`).
        A video and its truth are written under names of their own (``x.partial.mp4``,
        ``x_truth.partial.csv``, ``x_fixtures.partial.csv``) and take theirs when the render
        is complete (the truth first, the video last): a render stopped by an error leaves
        nothing, one interrupted (Ctrl-C) keeps its frames so far under those names, and one
        killed outright leaves nothing under the video's name either (never a video that
        cannot be read, nor one taken for complete).  A folder's files are written into a
        temporary folder beside it and moved into it once the render is complete.
    fps : float
        Frames per second; frame ``i`` is at ``trajectory.t[0] + i / fps`` (its middle row).
        Its ``t`` in the files is ``i / fps`` (the video's own clock).
    settings : RenderSettings, optional
        LED and sensor settings (row time: the settings', else the camera's).
    crf : int
        x264's constant rate factor (0 lossless ... 51; 10 keeps the stripes).
    max_frames : int, optional
        Stop after this many frames.
    progress : callable, optional
        Called as ``progress(done, total)`` after each frame.

    Returns
    -------
    int
        Frames written.

    Raises
    ------
    InputError
        The camera's picture over ``CAMVLP_MAX_RENDER_PIXELS``, more frames than
        ``CAMVLP_MAX_FRAMES``, an odd width or height for a video, an output that cannot be
        written.
    """
    out = Path(out)
    check_render_size(camera)
    total = frame_count(trajectory, fps, max_frames)
    check_frame_budget(total)
    is_video = out.suffix.lower() in VIDEO_SUFFIXES
    if is_video:
        check_video_size(camera)
    out.parent.mkdir(parents=True, exist_ok=True)
    frames = iter_frames(camera, fixture_map, trajectory, fps, settings, max_frames)
    if not is_video:  # a folder: every file in a temporary folder, moved into place at the end
        with StagedOutputs() as outputs:
            folder = outputs.folder(out)
            with (folder / "timestamps.csv").open("w", newline="") as stamps:
                sw = csv.writer(stamps)
                sw.writerow(("frame", "t"))

                def write(i: int, image: np.ndarray) -> str:
                    name = f"frame_{i:06d}.png"
                    if not cv2.imwrite(str(folder / name), image):
                        raise InputError("cannot write a frame", out / name)
                    sw.writerow((name, f"{i / fps:.6f}"))
                    return name

                _write_truths(frames, write, truth_paths(folder), fps, total, progress)
        return total
    # a video's files under names of their own until it is complete (see above), renamed in
    # this order: the truth first, the video last
    truths = truth_paths(out)
    target = partial_path(out)
    partials = (*(partial_path(p) for p in truths), target)
    writer = _VideoWriter(target, camera.width, camera.height, fps, crf)
    completed = False
    try:

        def encode(i: int, image: np.ndarray) -> int:
            writer.write(image)
            return i

        _write_truths(frames, encode, partials[:2], fps, total, progress)
        completed = True
    except BaseException as exc:
        if not isinstance(exc, KeyboardInterrupt):  # an error: nothing is kept
            writer.abandon()
            for p in partials:
                p.unlink(missing_ok=True)
        raise
    finally:
        try:
            writer.close()
        except Exception:
            if completed:
                raise  # (else the error that stopped the render is the one to tell)
        if not completed and not target.exists():  # nothing encoded
            for p in partials[:2]:
                p.unlink(missing_ok=True)
    for final in (*truths, out):  # complete
        partial_path(final).replace(final)
    return total


def _write_truths(
    frames: Iterator[VideoFrame],
    write: Callable[[int, np.ndarray], str | int],
    paths: tuple[Path, Path],
    fps: float,
    total: int,
    progress: Callable[[int, int], None] | None,
) -> None:
    """Hand each frame's image to ``write`` (which names the frame) and write the truth files
    ``paths`` (poses, fixtures) row by row."""
    with paths[0].open("w", newline="") as tf, paths[1].open("w", newline="") as ff:
        tw, fw = csv.writer(tf), csv.writer(ff)
        tw.writerow(("frame", *TRAJECTORY_COLUMNS))
        fw.writerow(("frame", "id", "u", "v", "fully_inside", "frames_spanned"))
        for i, frame in enumerate(frames):
            name = write(i, frame.image)
            pos, eul = frame.pose.position, frame.pose.euler_deg
            tw.writerow(
                (
                    name,
                    f"{i / fps:.6f}",
                    *(f"{v:.6f}" for v in pos),
                    *(f"{v:.5f}" for v in eul),
                )
            )
            for ft in frame.fixtures:
                fw.writerow(
                    (
                        name,
                        ft.id,
                        f"{ft.pixel[0]:.3f}",
                        f"{ft.pixel[1]:.3f}",
                        int(ft.fully_inside),
                        f"{ft.frames_spanned:.3f}",
                    )
                )
            if progress is not None:
                progress(i + 1, total)


def partial_path(path: str | Path) -> Path:
    """Where :func:`render_video` writes ``path`` until it is complete: ``x.partial.mp4``
    for ``x.mp4`` (the suffix kept: it says the video's container)."""
    path = Path(path)
    return path.with_name(f"{path.stem}.partial{path.suffix}")


class _VideoWriter:
    """H.264 through PyAV (libx264 ships in PyAV's wheels)."""

    def __init__(self, path: Path, width: int, height: int, fps: float, crf: int) -> None:
        from fractions import Fraction

        import av

        self._av = av
        try:
            self.container = av.open(str(path), mode="w")
        except (OSError, av.FFmpegError) as exc:
            raise InputError(f"cannot write the video: {exc}", path) from None
        rate = Fraction(fps).limit_denominator(1001)
        self.stream = self.container.add_stream("libx264", rate=rate)
        self.stream.width, self.stream.height = width, height
        self.stream.pix_fmt = "yuv420p"
        self.stream.options = {"crf": str(int(crf)), "preset": "veryfast"}

    def write(self, image: np.ndarray) -> None:
        frame = self._av.VideoFrame.from_ndarray(np.ascontiguousarray(image), format="bgr24")
        for packet in self.stream.encode(frame):
            self.container.mux(packet)

    def close(self) -> None:
        """Flush the encoder and close the file (once; nothing after :meth:`abandon`)."""
        if self.container is None:
            return
        container, self.container = self.container, None
        for packet in self.stream.encode():
            container.mux(packet)
        container.close()

    def abandon(self) -> None:
        """Close the file without flushing the encoder (the render failed: it is deleted)."""
        if self.container is not None:
            container, self.container = self.container, None
            container.close()
