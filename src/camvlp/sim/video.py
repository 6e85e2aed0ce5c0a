"""Rolling-shutter videos of a moving camera, with the true trajectory beside them.

The frames (:mod:`camvlp.sim.video_frame`: each sensor row seen from the pose at its own
time, along a :class:`~camvlp.sim.trajectory.Trajectory`) are written as an H.264 video
(PyAV, libx264) or as a folder of PNG frames with ``timestamps.csv``.  :class:`Trajectory` and
:func:`load_trajectory` are importable from here as well.

Files written beside a video ``DIR/name.mp4`` (or inside a frame folder ``DIR/``):

* ``name_truth.csv`` (``truth.csv``): ``frame,t,x,y,z,theta_x,theta_y,theta_z``, the pose at
  each frame's time (map units, the thesis' angles in degrees);
* ``name_fixtures.csv`` (``fixtures.csv``): ``frame,id,u,v,fully_inside,frames_spanned``, what
  each frame shows of each fixture, seen from the pose at the time of the row through its
  centre (for checking IDs).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable, Iterator
from pathlib import Path

import cv2
import numpy as np

from camvlp.errors import InputError
from camvlp.io.atomic import StagedOutputs
from camvlp.io.limits import limit
from camvlp.model.camera import Camera
from camvlp.model.fixtures import FixtureMap
from camvlp.sim.settings import RenderSettings, check_render_size
from camvlp.sim.trajectory import TRAJECTORY_COLUMNS, Trajectory, load_trajectory
from camvlp.sim.video_frame import VideoFrame, render_frame

__all__ = [
    "VIDEO_SUFFIXES",
    "Trajectory",
    "check_frame_budget",
    "check_video_size",
    "frame_count",
    "iter_frames",
    "load_trajectory",
    "partial_path",
    "render_video",
    "truth_paths",
]

#: Video suffixes :func:`render_video` writes (anything else is a frame folder).
VIDEO_SUFFIXES = (".mp4", ".mov", ".mkv")


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
