"""Readout direction: which way time runs along the sensor's readout axis.

Read backwards, a Manchester frame of the default format can be another ID's frame, so the
direction is part of the camera file and the locator must use it; these tests pin that down.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from camvlp.locate import LocateSettings, locate

from camvlp.model.camera import Pose
from camvlp.model.linecode import FrameFormat
from camvlp.sim.render import render
from conftest import LOOK_UP, make_small_camera, make_small_room, small_settings

#: IDs of the default frame whose frames, read backwards, are each other's frames.
REVERSAL_PAIRS = {(0, 14), (2, 6), (4, 10), (8, 12)}


def test_backwards_frames_of_the_default_format_are_other_ids():
    fmt = FrameFormat()
    pairs = set()
    for i in range(fmt.n_ids):
        res = fmt.decode(np.tile(fmt.chips(i)[::-1], 2))
        if res.id is not None:
            pairs.add(tuple(sorted((i, res.id))))
    assert pairs == REVERSAL_PAIRS


@pytest.mark.parametrize("axis", ["rows", "columns"])
def test_reversed_readout_is_rendered_and_located(axis):
    # a room whose IDs include a reversal pair: read the wrong way, 2 would look like 6
    room = make_small_room(ids=(2, 6, 9, 5, 12))
    camera = make_small_camera()
    pose = Pose.from_euler([0.05, 0.0, -0.04], [LOOK_UP[0] + 1.0, -1.5, 20.0])
    photo = render(camera, room, pose, small_settings(readout=f"{axis}-reversed", seed=3))
    res = locate(photo.image, camera, room, LocateSettings(readout=f"{axis}-reversed"))
    assert res, res.error
    assert res.readout == f"{axis}-reversed"
    assert np.linalg.norm(res.position - pose.position) < 3e-3
    assert sorted(f.id for f in res.fixtures) == [2, 5, 6, 9, 12]
    # the camera file can say it too
    res2 = locate(photo.image, dataclasses.replace(camera, readout=f"{axis}-reversed"), room)
    assert res2 and np.allclose(res2.position, res.position)


def test_reading_the_wrong_way_never_gives_a_position_from_swapped_ids():
    room = make_small_room(ids=(2, 6, 9, 5, 12))
    camera = make_small_camera()
    pose = Pose.from_euler([0.0, 0.0, 0.0], LOOK_UP)
    photo = render(camera, room, pose, small_settings(readout="rows-reversed", seed=4))
    res = locate(photo.image, camera, room, LocateSettings(readout="rows"))
    truth = {t.id: t.pixel for t in photo.fixtures}
    for f in res.fixtures:
        true_id = min(truth, key=lambda i: np.hypot(*(truth[i] - f.pixel)))
        if f.used:  # anything used for a pose must be the right fixture
            assert f.id == true_id
    if res:
        assert np.linalg.norm(res.position - pose.position) < 3e-3
    else:
        assert res.position is None and res.error
