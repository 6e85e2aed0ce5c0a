"""The Python API under the second round's hostile input: decoding bounded by what a photo
costs (its JPEG scans, a time budget), the tracker's time contract, a render's size."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from bad_inputs import scan_bomb

import camvlp
from camvlp.io.images import decode_image
from camvlp.pipeline.track.tracker import Tracker


def test_a_jpeg_of_many_scans_is_refused_before_decoding():
    bomb = scan_bomb(500, 64)  # a few kilobytes; 500 passes over the picture
    with pytest.raises(camvlp.InputError, match="more than 100 scans"):
        decode_image(bomb, "bomb.jpg")
    assert decode_image(scan_bomb(20, 64), "fine.jpg").shape == (64, 64, 3)


def test_a_decode_past_its_time_budget_is_abandoned(monkeypatch):
    """In a process with several threads (a server), a decode that outruns its budget frees
    its caller with an InputError; the limits are lowered so that a small bomb outruns it."""
    monkeypatch.setenv("CAMVLP_MAX_JPEG_SCANS", "1000000")
    monkeypatch.setenv("CAMVLP_MAX_DECODE_SECONDS", "1")
    bomb = scan_bomb(6000, 4000)  # about 2 s of decoding on a quiet machine
    other = threading.Event()
    helper = threading.Thread(target=other.wait, daemon=True)  # a server's other thread
    helper.start()
    try:
        with pytest.raises(camvlp.InputError, match="over 1 s to decode"):
            decode_image(bomb, "bomb.jpg")
    finally:
        other.set()
        # the abandoned decode runs on to its end: waited for here, or the tests after this
        # one in the process would decode in a process of several threads (uncaptured)
        for t in threading.enumerate():
            if t.name == "camvlp-decode":
                t.join(timeout=60)


def _tracker() -> Tracker:
    camera = camvlp.Camera.from_focal(64, 48, 50.0)
    fixtures = camvlp.FixtureMap(
        (
            camvlp.Fixture(5, np.array([0.5, 0.5, 2.7]), 0.15),
            camvlp.Fixture(6, np.array([0.5, -0.5, 2.7]), 0.15),
        )
    )
    return Tracker(camera, fixtures)


@pytest.mark.parametrize(
    ("t", "words"),
    [
        (1e300, "finite time within"),
        (float("nan"), "finite time within"),
        (float("inf"), "finite time within"),
        (-1.0, "must increase"),
        (0.0, "must increase"),
        ("1.0", "number of seconds"),
    ],
)
def test_the_tracker_refuses_a_bad_time_and_goes_on(t, words):
    tracker = _tracker()
    frame = np.zeros((48, 64), np.uint8)
    tracker.update(frame, 0.0)
    with pytest.raises(camvlp.InputError, match=words):
        tracker.update(frame, t)
    assert tracker.update(frame, 0.1).t == 0.1  # the tracker is still usable
    with pytest.raises(camvlp.InputError):  # a wrong image does not spend its time
        tracker.update(np.zeros((5, 5), np.uint8), 0.2)
    assert tracker.update(frame, 0.2).index == 2


def test_render_refuses_a_huge_camera_before_allocating():
    camera = camvlp.Camera.from_focal(100_000, 100_000, 5e4)
    fixtures = camvlp.FixtureMap((camvlp.Fixture(5, np.array([0.0, 0.0, 3.0]), 0.15),))
    pose = camvlp.Pose.from_euler([0, 0, 0], [0, 0, 0])
    with pytest.raises(camvlp.InputError, match="CAMVLP_MAX_RENDER_PIXELS"):
        camvlp.render(camera, fixtures, pose)
