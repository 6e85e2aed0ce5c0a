"""Tests of reading frames: folders in name order with their times, videos, bad input."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from camvlp.errors import InputError
from camvlp.io.video import open_frames


def write_folder(path, n=3, size=(64, 48)):
    path.mkdir()
    for i in range(n):
        img = np.full((size[1], size[0], 3), 10 * i, np.uint8)
        cv2.imwrite(str(path / f"f{i:02d}.png"), img)
    return path


def test_folder_in_name_order_with_timestamps_and_skipped_files(tmp_path):
    d = write_folder(tmp_path / "frames")
    (d / "notes.txt").write_text("not a frame")
    (d / "timestamps.csv").write_text("frame,t\nf00.png,0.5\nf01.png,0.55\nf02.png,0.61\n")
    src = open_frames(d)
    frames = list(src)
    assert [f.name for f in frames] == ["f00.png", "f01.png", "f02.png"]
    assert [f.t for f in frames] == pytest.approx([0.5, 0.55, 0.61])
    assert [int(f.image[0, 0, 0]) for f in frames] == [0, 10, 20]
    assert any("notes.txt" in w for w in src.warnings)


@pytest.mark.parametrize(
    ("stamps", "message"),
    [
        ("f00.png,0.5\nf01.png,0.4\nf02.png,0.6\n", "f01.png is not later than f00.png"),
        ("f00.png,0.5\nf01.png,0.5\nf02.png,0.6\n", "f01.png is not later than f00.png"),
        ("f00.png,0.5\nf00.png,0.7\nf01.png,0.8\nf02.png,0.9\n", "'f00.png' has two times"),
        ("f00.png,0\nf01.png,1e300\nf02.png,2e300\n", "a time beyond"),
    ],
)
def test_times_that_do_not_increase_in_name_order_are_refused(tmp_path, stamps, message):
    """The frames are taken in name order: times going back or standing still, a frame
    given twice, a time of 1e300 s are refused (they were taken as given; 1e300 s ended in
    'Numerical result out of range')."""
    d = write_folder(tmp_path / "frames")
    (d / "timestamps.csv").write_text("frame,t\n" + stamps)
    with pytest.raises(InputError, match=message):
        open_frames(d)


def test_folder_start_and_frames(tmp_path):
    d = write_folder(tmp_path / "frames", n=5)
    frames = list(open_frames(d, fps=10, start_s=0.15, max_frames=2))
    assert [f.name for f in frames] == ["f02.png", "f03.png"]


def test_folder_without_times_needs_fps(tmp_path):
    d = write_folder(tmp_path / "frames")
    with pytest.raises(InputError, match="give --fps"):
        open_frames(d)
    assert [f.t for f in open_frames(d, fps=20)] == pytest.approx([0, 0.05, 0.1])


def test_unreadable_image_is_a_frame_with_an_error(tmp_path):
    d = write_folder(tmp_path / "frames")
    (d / "f01.png").write_bytes(b"\x89PNG broken")
    frames = list(open_frames(d, fps=10))
    assert frames[1].image is None and frames[1].error
    assert frames[0].image is not None and frames[2].image is not None


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda p: p / "missing.mp4", "no such video or folder"),
        (lambda p: (p / "x.mp4").write_bytes(b"not a video") and p / "x.mp4", "not a video"),
        (lambda p: (p / "empty").mkdir() or p / "empty", "no images"),
    ],
)
def test_bad_sources(tmp_path, make, message):
    with pytest.raises(InputError, match=message):
        open_frames(make(tmp_path))


@pytest.fixture
def small_video(tmp_path):
    from camvlp.model.camera import Camera
    from camvlp.model.fixtures import FixtureMap
    from camvlp.sim.video import Trajectory, render_video

    def make(name: str):
        cam = Camera.from_focal(160, 120, 120.0, row_time_s=1e-4)
        traj = Trajectory(np.array([0.0, 1.0]), np.zeros((2, 3)), np.tile([90.0, 0, 0], (2, 1)))
        render_video(cam, FixtureMap(()), traj, tmp_path / name, fps=10)
        return tmp_path / name

    return make


def test_truncated_mkv_keeps_the_frames_before_the_cut(small_video, tmp_path):
    video = small_video("v.mkv")
    full = list(open_frames(video))
    assert len(full) == 11
    cut = tmp_path / "cut.mkv"
    data = video.read_bytes()
    cut.write_bytes(data[: int(len(data) * 0.6)])
    frames = list(open_frames(cut))  # never raises
    assert 0 < len(frames) < len(full)
    assert all(f.image is not None for f in frames)


def test_truncated_mp4_is_refused_in_one_line(small_video, tmp_path):
    video = small_video("v.mp4")
    cut = tmp_path / "cut.mp4"
    cut.write_bytes(video.read_bytes()[:-200])  # its index is at the end
    with pytest.raises(InputError, match="not a video that can be read"):
        open_frames(cut)


def test_video_frames_as_luma(tmp_path):
    from camvlp.sim.video import _VideoWriter

    ramp = np.tile(np.linspace(0, 255, 64, dtype=np.uint8), (48, 1))
    writer = _VideoWriter(tmp_path / "ramp.mkv", 64, 48, 10.0, 0)
    for _ in range(2):
        writer.write(np.dstack([ramp] * 3))
    writer.close()
    bgr = [f.image for f in open_frames(tmp_path / "ramp.mkv")]
    luma = [f.image for f in open_frames(tmp_path / "ramp.mkv", gray=True)]
    assert luma[0].shape == (48, 64) and bgr[0].shape == (48, 64, 3)
    # black..white is 0..255 as in a photo (the video's luma 16..235 stretched, as the BGR
    # conversion does): a clipped light reads 255 in either
    assert luma[0].dtype == np.uint8
    assert np.abs(luma[0].astype(float) - ramp).max() <= 2
    gray = cv2.cvtColor(bgr[0], cv2.COLOR_BGR2GRAY).astype(float)
    assert np.abs(luma[0].astype(float) - gray).max() <= 2
