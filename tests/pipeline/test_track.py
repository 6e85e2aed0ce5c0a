"""Tests of the tracker: a small moving-camera video, IDs carried and never swapped, the
filter, bad frames."""

from __future__ import annotations

import itertools

import cv2
import numpy as np
import pytest

import camvlp.pipeline.decode.stage as decode_stage
from camvlp.errors import InputError
from camvlp.model.camera import Camera
from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.pipeline.locate import locate
from camvlp.pipeline.track.tracker import ConstantVelocityFilter, Tracker, TrackSettings
from camvlp.sim.render import RenderSettings
from camvlp.sim.trajectory import Trajectory
from camvlp.sim.video import iter_frames

FPS = 15.0


def small_scene():
    """640 x 360 camera (f = 483 px, 2.5 rows per 10 kHz chip) 1.2 m under four 0.25 m discs;
    it moves along x at 0.5 m/s, and the discs at x = -0.35 leave the picture at frame 6."""
    cam = Camera.from_focal(640, 360, 483.0, row_time_s=40e-6)
    xz = ((0.35, 0.25), (0.35, -0.25), (-0.35, -0.25), (-0.35, 0.25))
    room = FixtureMap(
        tuple(
            Fixture(i, np.array([x, -2.7, z]), 0.25, np.array([0.0, 1.0, 0.0]))
            for i, (x, z) in zip((5, 6, 9, 10), xz, strict=True)
        )
    )
    traj = Trajectory(
        np.array([0.0, 1.0]),
        np.array([[0.1, -1.5, 0.0], [0.6, -1.5, 0.02]]),
        np.array([[90.0, 0.0, 0.0], [90.2, -0.1, 1.0]]),
    )
    return cam, room, traj


@pytest.fixture(scope="module")
def video():
    cam, room, traj = small_scene()
    frames = list(iter_frames(cam, room, traj, FPS, RenderSettings(seed=2)))[:12]
    return cam, room, frames


def nearest_true_id(frame, pixel) -> int:
    """The ID of the fixture whose true image is nearest to ``pixel``."""
    d = [np.linalg.norm(np.nan_to_num(t.pixel, nan=1e9) - pixel) for t in frame.fixtures]
    return frame.fixtures[int(np.argmin(d))].id


def test_tracker_follows_the_camera(video):
    cam, room, frames = video
    tracker = Tracker(cam, room)
    results = [tracker.update(f.image, f.t) for f in frames]
    statuses = [r.status for r in results]
    assert statuses[:4] == ["fix"] * 4
    assert "tracked" in statuses  # after two discs left the picture
    assert set(statuses) <= {"fix", "tracked"}
    err = np.array(
        [np.linalg.norm(r.position - f.pose.position) for r, f in zip(results, frames, strict=True)]
    )
    assert np.sqrt(np.mean(err**2)) < 0.005, err
    for r, f in zip(results, frames, strict=True):
        for b in r.fixtures:
            if b.id is not None:
                assert b.id == nearest_true_id(f, b.pixel)
        if r.status == "tracked":
            assert set(r.fixtures_used) == {5, 6}


def test_glowing_lamps_are_centred_on_their_shape():
    # a glow blinking with the LED pulls each outline about: on their outlines, the first
    # three frames of this video (seeds 1 to 5) track to 13 to 26 mm (RMSE; centres 0.5 to
    # 1.2 px off, median), centred on their radial shape to 1.1 to 2.8 mm (0.05 to 0.09 px)
    cam = Camera.from_focal(640, 480, 480.0, row_time_s=40e-6)
    _, room, _ = small_scene()
    traj = Trajectory(
        np.array([0.0, 1.0]),
        np.array([[0.0, -1.5, 0.0], [0.3, -1.5, 0.03]]),
        np.array([[90.0, 0.0, 0.0], [90.3, -0.2, 2.0]]),
    )
    look = RenderSettings(seed=2, halo=0.4, brightness=1.0)
    frames = list(itertools.islice(iter_frames(cam, room, traj, FPS, look), 3))
    tracker = Tracker(cam, room)
    results = [tracker.update(f.image, f.t) for f in frames]
    assert [r.status for r in results] == ["fix"] * 3
    err = [
        np.linalg.norm(r.position - f.pose.position) for r, f in zip(results, frames, strict=True)
    ]
    assert np.sqrt(np.mean(np.square(err))) < 0.005, err
    px = [
        np.linalg.norm(b.pixel - next(t.pixel for t in f.fixtures if t.id == b.id))
        for r, f in zip(results, frames, strict=True)
        for b in r.fixtures
        if b.used
    ]
    assert len(px) == 12 and np.median(px) < 0.2 and max(px) < 0.4, px


@pytest.mark.parametrize("halo", [0.0, 0.4])
def test_the_tracker_reads_a_first_frame_as_locate_does(halo):
    # the same stages in the same order: the same lights, centred alike (a glowing lamp on
    # its radial shape), with the same IDs
    cam, room, traj = small_scene()
    frame = next(iter(iter_frames(cam, room, traj, FPS, RenderSettings(seed=3, halo=halo))))
    alone = locate(frame.image, cam, room)
    tracked = Tracker(cam, room, TrackSettings(rolling_shutter=False)).update(frame.image, 0.0)
    assert alone and tracked.status == "fix"
    got = {f.id: f.pixel for f in tracked.fixtures if f.id is not None}
    want = {f.id: f.pixel for f in alone.fixtures if f.id is not None}
    assert got.keys() == want.keys() and len(got) >= 4
    for i, pixel in want.items():
        np.testing.assert_allclose(got[i], pixel, atol=1e-9)


def smear(image: np.ndarray, centre, radius: int) -> np.ndarray:
    """Replace the disc around ``centre`` by a steady light (no stripes to decode)."""
    out = image.copy()
    cv2.circle(out, tuple(round(c) for c in centre), radius, (180, 180, 180), -1)
    return out


def test_undecodable_fixture_keeps_its_id(video):
    cam, room, frames = video
    tracker = Tracker(cam, room, TrackSettings(verify_every=1))  # decode every blob
    for f in frames[:4]:
        assert tracker.update(f.image, f.t).status == "fix"
    f = frames[4]
    target = next(t for t in f.fixtures if t.id == 9)
    r = tracker.update(smear(f.image, target.pixel, 50), f.t)
    carried = [b for b in r.fixtures if b.source == "carried"]
    assert [b.id for b in carried] == [9]
    assert r.status == "fix" and 9 in r.fixtures_used


def test_swapped_stripes_do_not_swap_ids(video):
    cam, room, frames = video
    tracker = Tracker(cam, room, TrackSettings(verify_every=1))  # decode every blob
    for f in frames[:4]:
        tracker.update(f.image, f.t)
    f = frames[4]
    a, b = (next(t for t in f.fixtures if t.id == i).pixel for i in (5, 10))
    img = f.image.copy()
    r = 55
    pa = f.image[int(a[1]) - r : int(a[1]) + r, int(a[0]) - r : int(a[0]) + r].copy()
    pb = f.image[int(b[1]) - r : int(b[1]) + r, int(b[0]) - r : int(b[0]) + r].copy()
    img[int(a[1]) - r : int(a[1]) + r, int(a[0]) - r : int(a[0]) + r] = pb
    img[int(b[1]) - r : int(b[1]) + r, int(b[0]) - r : int(b[0]) + r] = pa
    result = tracker.update(img, f.t)
    # the stripes say 10 where 5 is and 5 where 10 is: both decodes are refused, and the
    # track's IDs are carried instead
    swapped = [x for x in result.fixtures if min(np.linalg.norm(x.pixel - p) for p in (a, b)) < 5]
    assert sorted((x.id, x.source) for x in swapped) == [(5, "carried"), (10, "carried")]
    for x in result.fixtures:
        if x.id is not None:
            assert x.id == nearest_true_id(f, x.pixel)


def test_known_fixtures_are_decoded_now_and_then(video):
    cam, room, frames = video
    tracker = Tracker(cam, room, TrackSettings(verify_every=4))
    sources = [
        [(b.id, b.source) for b in tracker.update(f.image, f.t).fixtures] for f in frames[:9]
    ]
    assert all(src == "decoded" for _, src in sources[0])
    assert any(src == "carried" for frame in sources[1:] for _, src in frame)
    for fid in (5, 6):  # each in view throughout: decoded at least once every 4 frames
        decoded_at = [k for k, frame in enumerate(sources) if (fid, "decoded") in frame]
        assert max(np.diff([0, *decoded_at, len(sources) - 1])) <= 4


def test_dark_frames_are_predicted_then_lost(video):
    cam, room, frames = video
    tracker = Tracker(cam, room)
    for f in frames[:4]:
        tracker.update(f.image, f.t)
    dark = np.zeros_like(frames[0].image)
    t = frames[3].t
    statuses = [tracker.update(dark, t + k / FPS).status for k in range(1, 11)]
    assert statuses[0] == "predicted"
    assert statuses[-1] == "lost"  # more than max_gap_s (0.5 s) without a measurement
    r = tracker.update(dark, t + 11 / FPS)
    assert r.position is None


def test_frame_of_another_size_is_an_input_error(video):
    cam, room, _ = video
    with pytest.raises(InputError, match="camera file says 640 x 360"):
        Tracker(cam, room).update(np.zeros((100, 120, 3), np.uint8), 0.0)


def test_constant_velocity_filter_learns_the_velocity():
    rng = np.random.default_rng(4)
    flt = ConstantVelocityFilter([0.0, 1.0], [0.01, 0.01], [2.0, 2.0], [0.5, 0.5])
    dt = 1 / 30
    for k in range(1, 60):
        flt.predict(dt)
        truth = np.array([0.8 * k * dt, 1.0 - 0.3 * k * dt])
        flt.update(truth + rng.normal(0, 0.002, 2), [0.002, 0.002])
    assert np.allclose(flt.rate, [0.8, -0.3], atol=0.05)
    assert np.allclose(flt.value, truth, atol=0.003)
    x, p = flt.predicted(0.5)  # half a second on: the prediction carries the velocity
    assert np.allclose(x[:2], truth + 0.5 * np.array([0.8, -0.3]), atol=0.03)
    assert np.all(np.diag(p)[:2] > np.diag(flt.P)[:2])


def test_filter_keeps_unseen_directions():
    flt = ConstantVelocityFilter([1.0, 2.0], [0.1, 0.1], [1.0, 1.0], [1.0, 1.0])
    # a measurement of the first value only, through a nonlinear model linearised at [1.5, 7]
    flt.update_linearized([0.5], [[1.0, 0.0]], [1.0, 2.0], 0.01)
    assert flt.value[0] == pytest.approx(1.5, abs=0.01)
    assert flt.value[1] == pytest.approx(2.0)


@pytest.mark.parametrize("readout", ["rows-reversed", "columns", "columns-reversed"])
def test_the_readout_direction_is_found_never_guessed(readout):
    # IDs 0/14 and 8/12 are each other's frames reversed: a direction guessed wrong would
    # read every fixture as the other one of its pair; the camera file does not say
    cam, _, traj = small_scene()
    xz = ((0.35, 0.25), (0.35, -0.25), (-0.35, -0.25), (-0.35, 0.25))
    room = FixtureMap(
        tuple(
            Fixture(i, np.array([x, -2.7, z]), 0.25, np.array([0.0, 1.0, 0.0]))
            for i, (x, z) in zip((0, 14, 8, 12), xz, strict=True)
        )
    )
    frames = list(iter_frames(cam, room, traj, FPS, RenderSettings(seed=3, readout=readout)))
    tracker = Tracker(cam, room)
    results = [tracker.update(f.image, f.t) for f in frames[:6]]
    assert str(tracker.readout) == readout
    given = [
        (fx.id, nearest_true_id(f, fx.pixel))
        for r, f in zip(results, frames, strict=False)
        for fx in r.fixtures
        if fx.id is not None
    ]
    assert len(given) >= 16 and all(a == b for a, b in given)
    statuses = [r.status for r in results]
    assert set(statuses) <= {"fix", "tracked"} and statuses[0] == "fix"


def test_the_tracker_weighs_the_rows_as_locate_does(video, monkeypatch):
    # the model fit weighs each profile line by its inverse variance (its pixels): the
    # tracker decodes the stripes it must with the same weights as camvlp.locate
    cam, room, frames = video
    seen = []
    real = decode_stage.decode_manchester

    def spy(profiles, readout, known, camera, fixture_map, weights=None, *more, **kw):
        seen.append((len(profiles), None if weights is None else len(weights)))
        return real(profiles, readout, known, camera, fixture_map, weights, *more, **kw)

    monkeypatch.setattr(decode_stage, "decode_manchester", spy)
    tracker = Tracker(cam, room, TrackSettings(carry_chip_length=False))
    tracker.update(frames[0].image, 0.0)
    assert seen and all(n == w for n, w in seen)
