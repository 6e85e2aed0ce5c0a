"""Reading frames from a video file or a folder of images, and the truth written beside them.

:func:`open_frames` opens either:

* a video file (mp4, mov, mkv ... anything FFmpeg reads, through PyAV): frame times from the
  stream's timestamps (or ``index / fps`` when ``fps`` is given).  It must be a regular file
  (a named pipe would block FFmpeg), and its frame size and frame count are checked from its
  header before a frame is decoded, against ``CAMVLP_MAX_PIXELS`` (as photos) and
  ``CAMVLP_MAX_FRAMES``; FFmpeg's decoder is told the pixel limit too, so a frame that grows
  past it later in the stream is not decoded;
* a folder of images, taken in name order: times from ``timestamps.csv`` in the folder
  (columns ``frame,t``, ``frame`` the image's file name), else ``index / fps``.  Files that
  are not images are skipped with a warning.

A frame that cannot be read comes out with ``image`` None and an ``error``; a video that
breaks off ends early with a warning, as does one that has more frames than its header said
and reaches ``CAMVLP_MAX_FRAMES``.  Nothing raises once the source is open.
"""

from __future__ import annotations

import csv
import io
import itertools
import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from camvlp.errors import InputError
from camvlp.io.files import MAX_MAGNITUDE
from camvlp.io.images import load_image
from camvlp.io.limits import check_pixels, limit, open_regular_file
from camvlp.io.textfiles import read_text_file

__all__ = ["IMAGE_SUFFIXES", "MIN_FPS", "Frame", "FrameSource", "open_frames", "read_truth"]

#: Slowest ``fps`` accepted, frames per second: one frame every 1000 s (slower ones put the
#: frames' times beyond the +-1e9 s every time must keep to).
MIN_FPS = 1e-3

#: Image file suffixes taken from a folder (lower case).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".webp")

#: Files of a frame folder that are ours, not frames (no warning for them).
_OWN_FILES = ("timestamps.csv", "truth.csv", "fixtures.csv")


@dataclass(frozen=True)
class Frame:
    """One frame of a video or folder.

    Attributes
    ----------
    index : int
        Position in the source, from 0.
    name : str
        The frame's name: its number in a video, its file name in a folder.
    t : float
        Its time, s.
    image : ndarray or None
        BGR (H, W, 3) uint8 (or what the image file holds); None when it could not be read.
    error : str
        Why it could not be read ("" when it could).
    """

    index: int
    name: str
    t: float
    image: np.ndarray | None
    error: str = ""


@dataclass
class FrameSource:
    """An opened video or folder; iterate it for :class:`Frame` objects, in order.

    Attributes
    ----------
    path : Path
        The video or folder.
    kind : str
        ``"video"`` or ``"folder"``.
    total : int or None
        Frames expected (None when the video does not say).
    warnings : list of str
        What was skipped, and a video that ended early.
    gray : bool
        A video's frames come as their luma plane (H, W).
    truth_path, fixtures_truth_path : Path or None
        The truth files beside the input when they exist (see :mod:`camvlp.sim.video`).
    """

    path: Path
    kind: str
    total: int | None
    fps: float | None
    start_s: float
    max_frames: int | None
    threads: int
    warnings: list[str] = field(default_factory=list)
    truth_path: Path | None = None
    fixtures_truth_path: Path | None = None
    _files: list[Path] = field(default_factory=list, repr=False)
    _times: dict[str, float] = field(default_factory=dict, repr=False)
    gray: bool = False

    def __iter__(self) -> Iterator[Frame]:
        frames = self._video() if self.kind == "video" else self._folder()
        most = self.max_frames if self.max_frames is not None else limit("CAMVLP_MAX_FRAMES")
        n = 0
        for frame in frames:
            if frame.t < self.start_s - 1e-9:
                continue
            if n >= most:
                if self.max_frames is None:
                    self.warnings.append(
                        f"stopped after {most:,} frames, the limit (set CAMVLP_MAX_FRAMES, or "
                        "give --frames)"
                    )
                return
            n += 1
            yield frame

    def _folder(self) -> Iterator[Frame]:
        for i, p in enumerate(self._files):
            t = self._times.get(p.name)
            if t is None:
                t = i / self.fps if self.fps else math.nan
            try:
                image = load_image(p)
            except InputError as exc:
                yield Frame(i, p.name, t, None, exc.what)
                continue
            yield Frame(i, p.name, t, image)

    def _video(self) -> Iterator[Frame]:
        import av

        try:
            container, fh = _open_video(self.path)
        except InputError as exc:  # checked in open_frames; raced away
            self.warnings.append(f"cannot read the video any more: {exc.what}")
            return
        try:
            stream = container.streams.video[0]
            stream.thread_type = "AUTO" if self.threads != 1 else "SLICE"
            stream.codec_context.thread_count = max(int(self.threads), 0)
            stream.codec_context.options = _decoder_limits()
            i = 0
            try:
                for frame in container.decode(stream):
                    t = frame.time if (self.fps is None and frame.time is not None) else None
                    if t is None:
                        rate = self.fps or (float(stream.average_rate or 0) or None)
                        t = i / rate if rate else math.nan
                    try:
                        image = _luma(frame) if self.gray else frame.to_ndarray(format="bgr24")
                    except (av.FFmpegError, ValueError) as exc:
                        yield Frame(i, str(i), float(t), None, f"cannot convert the frame: {exc}")
                    else:
                        yield Frame(i, str(i), float(t), image)
                    i += 1
            except (av.FFmpegError, OSError, EOFError) as exc:
                self.warnings.append(f"the video breaks off after {i} frames: {exc}")
        finally:
            container.close()
            fh.close()


#: A limited-range ("TV") luma plane's black and white (8-bit): stretched to 0 and 255, as
#: FFmpeg's colour conversion does, so that a clipped light reads 255 as in a photo.
_BLACK, _WHITE = 16, 235


def _luma(frame) -> np.ndarray:
    """A decoded video frame's brightness (H, W) uint8, 0..255: its luma plane, without a
    colour conversion (8-bit YUV formats; a limited-range one, most videos', stretched from
    16..235); other formats through FFmpeg's gray conversion."""
    name = frame.format.name
    if name in ("yuv420p", "yuvj420p", "yuv422p", "yuvj422p", "yuv444p", "nv12"):
        plane = frame.planes[0]
        rows = np.frombuffer(plane, np.uint8).reshape(plane.height, plane.line_size)
        luma = rows[:, : plane.width]
        if name.startswith("yuvj") or frame.color_range == 2:  # full range (JPEG's)
            return luma.copy()
        gain = 255.0 / (_WHITE - _BLACK)  # rounded and saturated to 0..255 (OpenCV's)
        return cv2.addWeighted(luma, gain, luma, 0.0, -_BLACK * gain)
    return frame.to_ndarray(format="gray")


def _read_timestamps(path: Path) -> dict[str, float]:
    rows = list(csv.DictReader(io.StringIO(read_text_file(path, "timestamps"), newline="")))
    if rows and not {"frame", "t"} <= set(rows[0]):
        raise InputError("timestamps.csv must have the columns frame,t", path)
    out: dict[str, float] = {}
    for r in rows:
        try:
            t = float(r["t"])
        except (TypeError, ValueError):
            raise InputError(f"a time that is not a number: {r['t']!r}", path) from None
        if not math.isfinite(t):
            raise InputError(f"a time that is not finite: {r['t']!r}", path)
        if abs(t) > MAX_MAGNITUDE:
            raise InputError(f"a time beyond +-{MAX_MAGNITUDE:g} s: {r['t']!r}", path)
        name = str(r["frame"]).strip()
        if name in out:
            raise InputError(f"frame {name!r} has two times", path)
        out[name] = t
    return out


def open_frames(
    path: str | Path,
    *,
    fps: float | None = None,
    start_s: float = 0.0,
    max_frames: int | None = None,
    threads: int = 1,
    gray: bool = False,
) -> FrameSource:
    """Open a video file or a folder of images for reading frame by frame.

    Parameters
    ----------
    path : str or Path
        A video file, or a folder of images (name order).
    fps : float, optional
        Frames per second: the frame times when a folder has no ``timestamps.csv`` (then
        required), and for a video instead of its timestamps.
    start_s : float
        Skip the frames before this time, s.
    max_frames : int, optional
        Read at most this many frames (after ``start_s``).
    threads : int
        Decoder threads for a video (1: one core; 0: FFmpeg's choice).
    gray : bool
        Give a video's frames as their luma plane (H, W) instead of BGR (H, W, 3): no colour
        conversion, which is what locating needs; 0..255 like a photo's gray, a limited-range
        video's 16..235 stretched (folders are read as their files are).

    Returns
    -------
    FrameSource

    Raises
    ------
    InputError
        A missing path, a file that is not a video, a folder without images, a folder
        without times (no ``timestamps.csv`` and no ``fps``), a bad ``timestamps.csv``.
    """
    p = Path(path)
    if fps is not None and not (math.isfinite(fps) and fps >= MIN_FPS):
        raise InputError(f"--fps must be a number of at least {MIN_FPS:g} frames/s, got {fps}")
    most = limit("CAMVLP_MAX_FRAMES")
    if max_frames is not None and not 1 <= max_frames <= most:
        raise InputError(
            f"--frames must be from 1 to {most:,} (set CAMVLP_MAX_FRAMES), got {max_frames}"
        )
    if not math.isfinite(start_s) or start_s < 0:
        raise InputError(f"--start must be a time of 0 s or later, got {start_s}")
    if not p.exists():
        raise InputError("no such video or folder", p)
    if p.is_dir():
        source = _open_folder(p, fps, start_s, max_frames)
        if max_frames is None and source.total is not None and source.total > most:
            raise InputError(_too_many(source.total, most), p)
        return source
    total = _video_header(p, max_frames is None)
    truth = p.with_name(p.stem + "_truth.csv")
    fixtures = p.with_name(p.stem + "_fixtures.csv")
    return FrameSource(
        p,
        "video",
        total,
        fps,
        start_s,
        max_frames,
        threads,
        truth_path=truth if truth.is_file() else None,
        fixtures_truth_path=fixtures if fixtures.is_file() else None,
        gray=gray,
    )


def _decoder_limits() -> dict[str, str]:
    """FFmpeg's decoder options that hold it to the pixel limit (it refuses a larger frame)."""
    return {"max_pixels": str(limit("CAMVLP_MAX_PIXELS"))}


def _open_video(p: Path):
    """``(container, file)``: the video opened by PyAV through a regular file of ours (a
    named pipe or a device is refused: FFmpeg would block on it), its header read with the
    decoder held to the pixel limit."""
    import av

    fh = open_regular_file(p, "video")
    try:
        return av.open(fh, stream_options=[_decoder_limits()]), fh
    except (OSError, av.FFmpegError, UnicodeDecodeError, ValueError):
        fh.close()
        raise InputError("not a video that can be read", p) from None
    except BaseException:
        fh.close()
        raise


def _too_many(n: int, most: int) -> str:
    return (
        f"the input has {n:,} frames, over the limit of {most:,} "
        "(set CAMVLP_MAX_FRAMES, or give --frames)"
    )


def _video_header(p: Path, check_count: bool) -> int | None:
    """The frames a video says it has (None when it does not say), once its header is known to
    describe frames within the pixel limit and (``check_count``) a count within the frame
    limit; nothing is decoded beyond what FFmpeg reads to know the stream."""
    container, fh = _open_video(p)
    try:
        if not container.streams.video:
            raise InputError("the file has no video stream", p)
        stream = container.streams.video[0]
        width, height = stream.codec_context.width, stream.codec_context.height
        if not (width > 0 and height > 0):
            raise InputError(
                "the video's frame size cannot be read within the pixel limit "
                f"{limit('CAMVLP_MAX_PIXELS'):,} (set CAMVLP_MAX_PIXELS)",
                p,
            )
        check_pixels(width, height, None, p)
        total = int(stream.frames) or None
        estimate = total
        rate = float(stream.average_rate or 0)
        if estimate is None and container.duration and rate > 0:
            estimate = math.ceil(container.duration / 1e6 * rate)
        most = limit("CAMVLP_MAX_FRAMES")
        if check_count and estimate is not None and estimate > most:
            raise InputError(_too_many(estimate, most), p)
        return total
    finally:
        container.close()
        fh.close()


def _open_folder(p: Path, fps: float | None, start_s: float, max_frames: int | None) -> FrameSource:
    files = sorted(f for f in p.iterdir() if f.is_file() and not f.name.startswith("."))
    images = [f for f in files if f.suffix.lower() in IMAGE_SUFFIXES]
    others = [f.name for f in files if f not in images and f.name not in _OWN_FILES]
    if not images:
        raise InputError("the folder has no images", p)
    stamps = p / "timestamps.csv"
    times = _read_timestamps(stamps) if stamps.is_file() else {}
    given = [(f.name, times[f.name]) for f in images if f.name in times]
    for (a, ta), (b, tb) in itertools.pairwise(given):
        if tb <= ta:  # the frames are taken in name order: their times must increase
            raise InputError(
                f"{b} is not later than {a} (times must increase in name order)", stamps
            )
    missing = [f.name for f in images if f.name not in times]
    if missing and fps is None:
        what = "no timestamps.csv" if not times else f"no time for {missing[0]} in timestamps.csv"
        raise InputError(f"{what}: give --fps", p)
    warnings = []
    if others:
        shown = ", ".join(others[:3]) + (" ..." if len(others) > 3 else "")
        warnings.append(f"skipped {len(others)} file(s) that are not images: {shown}")
    truth, fixtures = p / "truth.csv", p / "fixtures.csv"
    return FrameSource(
        p,
        "folder",
        len(images),
        fps,
        start_s,
        max_frames,
        1,
        warnings,
        truth if truth.is_file() else None,
        fixtures if fixtures.is_file() else None,
        images,
        times,
    )


def read_truth(path: str | Path) -> dict[str, np.ndarray]:
    """A truth CSV (``frame,t,x,y,z,theta_x,theta_y,theta_z``): frame name -> the 6 values
    ``(x, y, z, theta_x, theta_y, theta_z)`` (map units, degrees).

    Raises
    ------
    InputError
        Unreadable, missing columns or values that are not numbers.
    """
    p = Path(path)
    cols = ("x", "y", "z", "theta_x", "theta_y", "theta_z")
    rows = list(csv.DictReader(io.StringIO(read_text_file(p, "truth"), newline="")))
    try:
        return {
            str(r["frame"]).strip(): np.array([float(r[c]) for c in cols], dtype=float)
            for r in rows
        }
    except (KeyError, TypeError, ValueError):
        raise InputError(
            "cannot read the truth (frame,t,x,y,z,theta_x,theta_y,theta_z)", p
        ) from None
