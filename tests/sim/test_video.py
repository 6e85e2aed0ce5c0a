"""Tests of the video simulator: trajectories, rows seen at their own time, files written."""

from __future__ import annotations

import csv
import dataclasses

import numpy as np
import pytest

from camvlp.errors import InputError
from camvlp.io.video import open_frames
from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.sim import video
from camvlp.sim.render import RenderSettings
from camvlp.sim.trajectory import Trajectory, load_trajectory
from camvlp.sim.video import render_video
from camvlp.sim.video_frame import render_frame

CAM = Camera.from_focal(320, 240, 250.0, row_time_s=100e-6)
ROOM = FixtureMap(
    tuple(
        Fixture(i, np.array([x, -2.7, z]), 0.3, np.array([0.0, 1.0, 0.0]))
        for i, (x, z) in zip(
            (5, 6, 9, 10), ((0.8, 0.6), (0.8, -0.6), (-0.8, -0.6), (-0.8, 0.6)), strict=True
        )
    )
)
#: Steady discs: an exposure of one whole 18-chip frame sees every LED half on in every row.
STEADY = RenderSettings(exposure_s=18e-4, read_noise=0.0, full_well_e=0.0, blur_px=0.0)


def centroids(image: np.ndarray) -> list[np.ndarray]:
    import cv2

    gray = image.max(axis=2)
    n, labels = cv2.connectedComponents((gray > 60).astype(np.uint8))
    out = []
    for k in range(1, n):
        v, u = np.nonzero(labels == k)
        w = gray[v, u].astype(float)
        out.append(np.array([np.average(u, weights=w), np.average(v, weights=w)]))
    return out


def test_each_row_sees_the_pose_at_its_own_time():
    # 5 m/s along x; the 240 rows take 24 ms: the discs are seen about 6 ms before and after
    # the frame's middle row, 3 cm away from its pose (2.5 px)
    traj = Trajectory(
        np.array([0.0, 1.0]),
        np.array([[-2.5, 0.0, 0.0], [2.5, 0.0, 0.0]]),
        np.tile([90.0, 0.0, 0.0], (2, 1)),
    )
    frame = render_frame(CAM, ROOM, traj, 0.5, STEADY)
    found = centroids(frame.image)
    assert len(found) == 4
    for c in found:
        dt = (c[1] - 0.5 * (CAM.height - 1)) * CAM.row_time_s
        moved = CAM.project(traj.pose(0.5 + dt), ROOM.positions)
        at_mid = CAM.project(frame.pose, ROOM.positions)
        k = int(np.argmin(np.linalg.norm(at_mid - c, axis=1)))
        assert np.linalg.norm(moved[k] - c) < 0.15  # where the rows saw it
        assert np.linalg.norm(at_mid[k] - c) > 2.0  # not where the middle row would


@pytest.mark.parametrize(
    "look",
    [
        {},
        {"off_level": 0.3},
        {"core": 3.0, "halo": 0.4},
        {"core": 3.0, "core_offset": 0.5},
        {"soft": 0.3, "exposure_s": 17.7e-4, "blur_px": 1.2},  # soft: a window of 18 chips
        {"stamp": "2017-02-15 17:47:52"},
    ],
)
def test_still_camera_matches_the_photo_renderer(look):
    # every look of a light (off level, hot core on its centre or off it, halo, soft driver,
    # blur) and the stamp in videos too
    from camvlp.sim.render import render

    pose = Pose.from_euler([0.1, 0.0, -0.05], [90.0, 1.0, 20.0])
    traj = Trajectory(
        np.array([0.0, 1.0]), np.tile(pose.position, (2, 1)), np.tile(pose.euler_deg, (2, 1))
    )
    settings = dataclasses.replace(STEADY, brightness=0.6, **look)
    moving = render_frame(CAM, ROOM, traj, 0.5, settings).image.astype(int)
    still = render(CAM, ROOM, pose, settings).image.astype(int)
    assert np.abs(moving - still).max() <= 1
    plain = render(CAM, ROOM, pose, dataclasses.replace(STEADY, brightness=0.6)).image
    assert (np.abs(still - plain.astype(int)).max() > 10) == bool(look)  # the look shows


def test_a_light_sending_data_in_a_video():
    pose = Pose.from_euler([0.0, 0.0, 0.0], [90.0, 0.0, 0.0])
    traj = Trajectory(
        np.array([0.0, 1.0]), np.tile(pose.position, (2, 1)), np.tile(pose.euler_deg, (2, 1))
    )
    sharp = RenderSettings(exposure_s=2e-6, read_noise=0.0, full_well_e=0.0, seed=2)
    plain = render_frame(CAM, ROOM, traj, 0.5, sharp)
    mixed = render_frame(CAM, ROOM, traj, 0.5, dataclasses.replace(sharp, data_lights=(6,)))
    assert [t.sends_data for t in mixed.fixtures] == [False, True, False, False]
    changed = np.any(mixed.image != plain.image, axis=2)
    vv, uu = np.nonzero(changed)
    t6 = mixed.fixtures[1]
    assert uu.size > 50  # the data light's stripes are others
    assert np.all(np.hypot(uu - t6.pixel[0], vv - t6.pixel[1]) < t6.rows_spanned)  # only it


def test_trajectory_file_errors(tmp_path):
    bad = tmp_path / "t.csv"
    bad.write_text("t,x,y,z,theta_x,theta_y\n0,0,0,0,90,0\n")
    with pytest.raises(InputError, match="lacks the column"):
        load_trajectory(bad)
    bad.write_text("t,x,y,z,theta_x,theta_y,theta_z\n0,0,0,0,90,0,0\n0,1,0,0,90,0,0\n")
    with pytest.raises(InputError, match="strictly increasing"):
        load_trajectory(bad)
    bad.write_text("t,x,y,z,theta_x,theta_y,theta_z\n0,0,0,0,90,0,0\n1,a,0,0,90,0,0\n")
    with pytest.raises(InputError, match="not a number"):
        load_trajectory(bad)
    # a camera 1e300 map units away (or a trajectory 1e300 s long) was rendered as asked
    for row in ("1,1e300,0,0,90,0,0", "1e300,0,0,0,90,0,0"):
        bad.write_text(f"t,x,y,z,theta_x,theta_y,theta_z\n0,0,0,0,90,0,0\n{row}\n")
        with pytest.raises(InputError, match="beyond"):
            load_trajectory(bad)


@pytest.mark.parametrize("out_name", ["frames", "video.mp4"])
def test_render_video_writes_frames_and_truth(tmp_path, out_name):
    traj = Trajectory(
        np.array([0.0, 0.2]),
        np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]]),
        np.tile([90.0, 0.0, 0.0], (2, 1)),
    )
    out = tmp_path / out_name
    n = render_video(CAM, ROOM, traj, out, fps=10, settings=RenderSettings(seed=1))
    assert n == 3
    truth = tmp_path / ("video_truth.csv" if out.suffix else "frames/truth.csv")
    rows = list(csv.DictReader(truth.open()))
    assert [float(r["x"]) for r in rows] == pytest.approx([0.0, 0.05, 0.1])
    frames = list(open_frames(out, fps=10))
    assert len(frames) == 3 and all(f.image.shape == (240, 320, 3) for f in frames)
    assert [f.t for f in frames] == pytest.approx([0.0, 0.1, 0.2])


def _line(duration_s: float) -> Trajectory:
    """A camera moving 0.1 map units along x in ``duration_s`` seconds, looking up."""
    return Trajectory(
        np.array([0.0, duration_s]),
        np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]]),
        np.tile([90.0, 0.0, 0.0], (2, 1)),
    )


def test_a_video_takes_its_name_only_when_complete(tmp_path):
    # while it renders, the video and its truth are written under names of their own (a
    # render killed outright leaves no "video.mp4" that cannot be read); complete, they
    # take theirs
    out = tmp_path / "video.mp4"
    seen = []

    def progress(done, total):
        seen.append(sorted(p.name for p in tmp_path.iterdir()))

    look = RenderSettings(seed=1)
    render_video(CAM, ROOM, _line(0.3), out, fps=10, settings=look, progress=progress)
    partial = {"video.partial.mp4", "video_fixtures.partial.csv", "video_truth.partial.csv"}
    assert len(seen) == 4 and all(set(names) <= partial for names in seen)  # (the encoder
    assert all("video_truth.partial.csv" in names for names in seen)  # may write late)
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "video.mp4",
        "video_fixtures.csv",
        "video_truth.csv",
    ]
    assert len(list(open_frames(out, fps=10))) == 4


def test_an_interrupted_video_keeps_its_frames_so_far_under_its_partial_names(tmp_path):
    # not under the video's own name, which would pass for a complete render
    out = tmp_path / "video.mp4"

    def progress(done, total):
        if done == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        render_video(
            CAM, ROOM, _line(0.3), out, fps=10, settings=RenderSettings(seed=1), progress=progress
        )
    assert not out.exists() and not (tmp_path / "video_truth.csv").exists()
    assert len(list(open_frames(tmp_path / "video.partial.mp4", fps=10))) == 2
    assert len(list(csv.DictReader((tmp_path / "video_truth.partial.csv").open()))) == 2


def test_a_video_stopped_before_its_first_frame_leaves_no_file(tmp_path, monkeypatch):
    # the error that stopped it is the one raised (the encoder had written nothing)
    def broken(*args, **kwargs):
        raise KeyboardInterrupt
        yield

    monkeypatch.setattr(video, "iter_frames", broken)
    with pytest.raises(KeyboardInterrupt):
        render_video(CAM, ROOM, _line(0.3), tmp_path / "video.mp4", fps=10)
    assert list(tmp_path.iterdir()) == []
