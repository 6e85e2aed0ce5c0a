"""The tracker gathers the pieces of a long frame that discs too short for it show from frame
to frame, and reads each fixture's ID from them: every fixture identified, none wrongly,
lights that send no ID given none."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from tests.pipeline.test_partial import profile

from camvlp.model.camera import Camera
from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.model.linecode import FrameFormat
from camvlp.model.readout import Readout
from camvlp.pipeline.decode.partial import ChipEvidence
from camvlp.pipeline.decode.result import StripeDecode
from camvlp.pipeline.track.gather import LightTracks
from camvlp.pipeline.track.tracker import Tracker, TrackSettings
from camvlp.sim.render import RenderSettings
from camvlp.sim.trajectory import Trajectory
from camvlp.sim.video import iter_frames

#: ``camvlp encode --design``'s format for 600 fixtures: 50 chips, IDs at least 4 apart.
LONG = FrameFormat("1111", 10, "000", 8)
IDS = (37, 402, 615, 901)
DATA = (500, 777)  # fixtures that send random chips
CHIP_RATE = 10_700.0  # 2.3 rows a chip: the discs of 75 rows show 0.65 of a frame
FPS = 15.0


def long_scene():
    """480 x 270 camera (40 us rows, the readout known) 1.2 m under six 0.25 m discs sending
    the long format (two of them random data); it moves along x at 0.2 m/s."""
    cam = Camera.from_focal(480, 270, 362.0, row_time_s=40e-6, readout="rows")
    xz = ((0.4, 0.25), (0.4, -0.25), (-0.4, -0.25), (-0.4, 0.25), (0.0, 0.25), (0.0, -0.25))
    room = FixtureMap(
        tuple(
            Fixture(i, np.array([x, -2.7, z]), 0.25, np.array([0.0, 1.0, 0.0]))
            for i, (x, z) in zip(IDS + DATA, xz, strict=True)
        ),
        frame=LONG,
        chip_rate_hz=CHIP_RATE,
    )
    traj = Trajectory(
        np.array([0.0, 1.0]),
        np.array([[0.05, -1.5, 0.0], [0.25, -1.5, 0.02]]),
        np.array([[90.0, 0.0, 0.0], [90.2, -0.1, 1.0]]),
    )
    return cam, room, traj


def tracked(gather_frames: int = 12, frames: int = 8):
    """The tracker's answers on the long-format video, each blob as (frame, its ID, its
    source, the true ID nearest it)."""
    cam, room, traj = long_scene()
    look = RenderSettings(seed=2, chip_rate_hz=CHIP_RATE, data_lights=DATA)
    video = list(iter_frames(cam, room, traj, FPS, look, max_frames=frames))
    spans = [t.frames_spanned for f in video for t in f.fixtures]
    assert 0.6 < min(spans) and max(spans) < 0.7  # every disc under a frame
    tracker = Tracker(cam, room, TrackSettings(gather_frames=gather_frames))
    out = []
    for k, f in enumerate(video):
        for b in tracker.update(f.image, f.t).fixtures:
            true = min(f.fixtures, key=lambda t: np.linalg.norm(t.pixel - b.pixel)).id
            out.append((k, b.id, b.source, true))
    return out


@pytest.fixture(scope="module")
def video():
    return tracked()


def test_every_fixture_is_identified_from_its_gathered_chips(video):
    gathered = {true for _, fid, src, true in video if src == "gathered" and fid == true}
    assert gathered == set(IDS)
    assert max(k for k, *_ in video) < 10  # within ten frames (the video has eight)
    assert all(fid == true for _, fid, _, true in video if fid is not None)  # none wrong
    # once four are identified, the pose places every fixture from then on
    first = min(k for k, fid, src, _ in video if src == "gathered")
    assert all(fid is not None for k, fid, *_ in video if k > first + 2)


def test_lights_sending_random_chips_are_given_no_id_by_them(video):
    # two fixtures send random Manchester data (a corrupted stream): their chips fit no ID's
    # frame and are refused, while the four others are read; the pose then tells which
    # fixtures they are ("carried")
    data = [(fid, src) for _, fid, src, true in video if true in DATA]
    assert len(data) >= 14
    assert all(src in ("", "carried") for _, src in data), data
    assert all(fid == true for _, fid, _, true in video if fid is not None)
    assert {true for _, fid, src, true in video if src == "gathered"} == set(IDS)


def at(*pixels):
    """Blobs at these pixels (only their centres are followed)."""
    return [SimpleNamespace(pixel=np.array(p, dtype=float)) for p in pixels]


def test_a_light_is_followed_while_it_stays_and_starts_over_when_it_leaves():
    lights = LightTracks(LONG, 12, gate=20.0, ambiguity=2.0)
    a = lights.follow(at((100, 50), (300, 50)), 0.0, "rows")
    b = lights.follow(at((305, 52), (104, 50)), 0.1, "rows")
    assert b[0] is a[1] and b[1] is a[0]
    # moved on at its velocity (4 px a frame): followed 30 px on, beyond the gate of where
    # it was
    c = lights.follow(at((134, 50)), 0.85, "rows")
    assert c[0] is a[0]
    # the other left: it comes back as a new light
    d = lights.follow(at((138, 50), (320, 56)), 0.95, "rows")
    assert d[0] is a[0] and d[1] is not a[1]
    # two blobs as near one light: neither continues it
    e = lights.follow(at((141, 48), (141, 52), (320, 56)), 1.05, "rows")
    assert e[0] is not a[0] and e[1] is not a[0] and e[2] is d[1]
    # read along the other axis: every light starts over
    f = lights.follow(at((320, 56)), 1.15, "columns")
    assert isinstance(f[0], ChipEvidence) and f[0] is not d[1]


@pytest.mark.parametrize("bad", [-1, 2.5, True])
def test_the_gathering_window_is_checked(bad):
    with pytest.raises(ValueError, match="gather_frames"):
        TrackSettings(gather_frames=bad)


def test_two_lights_gathered_one_way_tell_the_readout_direction():
    # the sensor reads the rows bottom up; read top down (a guess), each light's stripes
    # show its code backwards: once two lights' pieces say their IDs read that way, and none
    # the other, the direction is told
    rng = np.random.default_rng(4)
    lights = LightTracks(LONG, 12, gate=20.0, ambiguity=2.0)
    blobs = at((100, 50), (300, 50))
    told = []
    for k in range(10):
        profiles = [
            profile(LONG.chips(fid), rng.uniform(0, 50), 30.0, rng)[::-1] for fid in (37, 901)
        ]
        got = lights.gather(
            k, 0.1 * k, blobs, (0, 1), profiles, Readout.ROWS, [StripeDecode(None)] * 2
        )
        told.append((got.reversed, len(got.gathered)))
        for j, d in enumerate(got.decodes):
            assert d.id in (None, (37, 901)[j])
            assert (d.id is not None) == (j in got.gathered) == (d.method == "gathered")
    # told from the first frame both lights' IDs are read, not before
    first = next(k for k, (_, n) in enumerate(told) if n == 2)
    assert all(w is None for w, _ in told[:first]) and all(w is True for w, _ in told[first:])
