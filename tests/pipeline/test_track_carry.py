"""What the tracker carries from frame to frame: the photo-wide parameters of the stripes'
model (fitted on the first frame the model decoder reads, reused on the next ones, fitted
anew when they do not explain a frame), whether each fixture glows (told while it is seen
whole, used once the border cuts it), and the IDs of lights the border cuts (not decoded
frame after frame); the IDs right either way."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from tests.pipeline.test_track import small_scene

from camvlp.model.readout import Readout
from camvlp.pipeline.locate import LocateSettings, locate
from camvlp.pipeline.paths import recording
from camvlp.pipeline.stages import decode, find_lights, prepare, read_profiles
from camvlp.pipeline.track.tracker import Tracker, TrackSettings
from camvlp.sim.render import RenderSettings
from camvlp.sim.video import iter_frames

FIT = "photo-wide model"
MODEL = "model decode"
ROWS_PER_CHIP = 2.2  # the run-length decoder refuses most lights there


@pytest.fixture(scope="module")
def video():
    """Five frames of test_track's scene (640 x 360, discs of about 100 rows, the camera
    moving along x) with chips of 2.2 rows, rows exposed for 0.3 chip, sensor noise."""
    cam, room, traj = small_scene()
    rate = 1.0 / (ROWS_PER_CHIP * cam.row_time_s)
    look = RenderSettings(chip_rate_hz=rate, exposure_s=0.3 / rate, seed=4)
    return cam, room, list(iter_frames(cam, room, traj, 15.0, look, max_frames=5))


def tracked(video, carry: bool):
    cam, room, frames = video
    # every blob decoded in every frame (none taken from the track alone)
    settings = TrackSettings(
        verify_every=1, carry_model=carry, locate=LocateSettings(readout="rows")
    )
    tracker = Tracker(cam, room, settings)
    return [tracker.update(f.image, f.t) for f in frames]


def test_the_model_fitted_on_the_first_frame_decodes_the_next(video):
    results = tracked(video, carry=True)
    assert FIT in results[0].paths  # the first frame's parameters fitted...
    for r in results[1:]:  # ...and used as they are by the next ones
        assert MODEL in r.paths and FIT not in r.paths, r.paths
    for r in results:
        assert r.status == "fix"
        decoded = {b.id for b in r.fixtures if b.source == "decoded"}
        assert decoded == {5, 6, 9, 10}, r.fixtures
    # without carrying them, every frame fits its own
    alone = tracked(video, carry=False)
    assert all(FIT in r.paths for r in alone)
    for a, b in zip(results, alone, strict=True):
        assert [f.id for f in a.fixtures] == [f.id for f in b.fixtures]


def stages(cam, room, image):
    """A frame through the stages up to its profiles, the readout known (rows)."""
    prepared = prepare(image, cam, room, LocateSettings())
    lights = find_lights(prepared, room, LocateSettings(), readout=Readout.ROWS)
    lights = dataclasses.replace(lights, direction_known=True)
    return prepared, lights, read_profiles(prepared.image, lights.blobs, Readout.ROWS)


def test_parameters_that_do_not_explain_a_frame_are_fitted_anew(video):
    cam, room, frames = video
    prepared, lights, profiles = stages(cam, room, frames[2].image)
    with recording() as paths:
        fitted = decode(prepared, lights, profiles, room)
    assert FIT in paths
    good = fitted.manchester.model
    ids = [d.id for d in fitted.decodes]
    assert sorted(ids) == [5, 6, 9, 10]
    # the frame's own parameters explain it: no fit
    with recording() as paths:
        again = decode(prepared, lights, profiles, room, model=good)
    assert FIT not in paths and MODEL in paths
    assert [d.id for d in again.decodes] == ids
    assert again.manchester.model == good
    # parameters of another camera mode (chips 1.5 times as long) read no light: refitted
    wrong = dataclasses.replace(good, rows_per_chip=1.5 * good.rows_per_chip)
    with recording() as paths:
        refit = decode(prepared, lights, profiles, room, model=wrong)
    assert FIT in paths
    assert [d.id for d in refit.decodes] == ids
    assert refit.manchester.model != wrong


def test_a_disc_the_border_cuts_is_told_by_its_fixture_seen_whole():
    # plain discs of 100 px leaving the picture: once less than half of one is in it, its
    # round outline is smaller than the disc and its ring reads as a glow; the track knows
    # its fixture does not glow (told in the frames before), and locate that the photo's
    # whole discs do not.  (In the next frame, a sliver's outline centre is too far from
    # its fixture's prediction to be tied to it: the photo's lights tell, as in locate)
    cam, room, traj = small_scene()
    frames = list(iter_frames(cam, room, traj, 15.0, RenderSettings(seed=2), max_frames=13))
    tracker = Tracker(cam, room)
    results = [tracker.update(f.image, f.t) for f in frames]
    assert "radial fit" not in locate(frames[11].image, cam, room).paths
    cut = cut_decoded = 0
    for r, f in zip(results, frames, strict=True):
        assert "radial fit" not in r.paths, (f.t, r.paths)
        assert r.status in ("fix", "tracked")
        on_border = [b for b in r.fixtures if b.reason.startswith("cut by the image border")]
        cut += len(on_border)
        cut_decoded += sum(b.source == "decoded" for b in on_border)
        truth = {t.id: t.pixel for t in f.fixtures if np.all(np.isfinite(t.pixel))}
        for b in r.fixtures:
            if b.id is not None:  # the nearest true fixture's ID
                assert b.id == min(truth, key=lambda i: np.linalg.norm(truth[i] - b.pixel))
    assert cut >= 8  # (two discs cut in frames 7 to 12)
    # the cut discs keep their IDs from the track, decoded again only as whole ones are
    # (every tenth frame), not frame after frame
    assert cut_decoded <= 2, cut_decoded
    # a tracker that starts on a frame with two discs cut: they are told as the two whole
    # ones are (a room's lamps are alike)
    first = Tracker(cam, room).update(frames[11].image, frames[11].t)
    assert "radial fit" not in first.paths
    # a frame that shows one disc whole (another one darkened): the photo alone cannot tell
    # the cut discs' look, the track can
    last = frames[11]
    whole = [t.pixel for t in last.fixtures if t.fully_inside]
    assert len(whole) == 2
    one = last.image.copy()
    x, y = np.rint(whole[0]).astype(int)
    one[max(y - 70, 0) : y + 70, max(x - 70, 0) : x + 70] = 0
    assert "radial fit" in locate(one, cam, room).paths
    for carry in (True, False):
        tracker = Tracker(cam, room, TrackSettings(carry_glows=carry))
        for f in frames[:11]:
            tracker.update(f.image, f.t)
        assert ("radial fit" in tracker.update(one, last.t).paths) is not carry
