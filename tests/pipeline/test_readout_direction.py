"""Readout direction: which way time runs along the sensor's readout axis.

Read backwards, a Manchester frame of the default format can be another ID's frame, so the
direction is part of the camera file and the locator must use it; these tests pin that down.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import camvlp.pipeline.decode.stage as decode_stage
from camvlp import LocateSettings, locate
from camvlp.model.camera import Pose
from camvlp.model.linecode import FrameFormat
from camvlp.pipeline.decode.result import StripeDecode
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


@pytest.mark.parametrize("readout", ["rows", "rows-reversed", "columns", "columns-reversed"])
def test_unknown_direction_is_found_from_the_stripes(readout):
    # odd IDs read backwards are no frame at all: the stripes say which way time ran
    room = make_small_room(ids=(2, 6, 9, 5, 12))
    camera = make_small_camera()  # no readout in the camera file
    pose = Pose.from_euler([0.05, 0.0, -0.04], [LOOK_UP[0] + 1.0, -1.5, 20.0])
    photo = render(camera, room, pose, small_settings(readout=readout, seed=7))
    res = locate(photo.image, camera, room)
    assert res, res.error
    assert res.readout == readout
    assert sorted(f.id for f in res.fixtures) == [2, 5, 6, 9, 12]
    assert np.linalg.norm(res.position - pose.position) < 3e-3


def test_unknown_direction_with_only_reversal_pairs_is_never_a_swapped_position():
    # every ID's backwards frame is another ID of the map: the stripes cannot tell the
    # direction, only the pose can (here the layout is not symmetric under the swap)
    room = make_small_room(ids=(0, 14, 2, 6, 12))
    camera = make_small_camera()
    for seed, readout in ((11, "rows"), (12, "rows-reversed")):
        pose = Pose.from_euler([0.02, 0.0, 0.03], [LOOK_UP[0] - 1.0, 1.0, -30.0])
        photo = render(camera, room, pose, small_settings(readout=readout, seed=seed))
        res = locate(photo.image, camera, room)
        if res:
            assert res.readout == readout
            assert np.linalg.norm(res.position - pose.position) < 3e-3
            truth = {t.id: t.pixel for t in photo.fixtures}
            for f in res.fixtures:
                if f.used:
                    assert np.hypot(*(truth[f.id] - f.pixel)) < 3
        else:
            assert "ambiguous" in res.error


def test_swapped_pairs_in_the_map_are_read_the_way_that_fits_the_map():
    # the same photo with a map whose pair IDs are swapped: read forwards the IDs put the
    # camera behind the lights, read backwards they give the true pose; either way no pose
    # comes from swapped fixtures
    xz = ((0.6, 0.6), (-0.6, 0.6), (0.6, -0.6), (-0.6, -0.6))
    room = make_small_room(ids=(0, 14, 2, 6), xz=xz)
    swapped = make_small_room(ids=(14, 0, 6, 2), xz=xz)
    camera = make_small_camera()
    pose = Pose.from_euler([0.0, 0.0, 0.0], LOOK_UP)
    photo = render(camera, room, pose, small_settings(readout="rows", seed=5))
    for fmap, backwards in ((room, False), (swapped, True)):
        res = locate(photo.image, camera, fmap)
        if res:
            assert res.readout.reversed == backwards
            assert np.linalg.norm(res.position - pose.position) < 3e-3
        else:
            assert res.error


def _unread(true_pixel: np.ndarray):
    """locate's Manchester decode with the fixture at ``true_pixel`` unread both ways (as
    one whose stripes span too little of the code)."""
    real = decode_stage.decode_manchester

    def fake(profiles, readout, direction_known, camera, fixture_map, *more, **kw):
        man = real(profiles, readout, direction_known, camera, fixture_map, *more, **kw)
        assert man.other is not None  # (the stripes alone leave the direction open)
        k = int(np.argmin([np.hypot(*(p - true_pixel)) for p in _PIXELS]))
        nothing = StripeDecode(
            None, "spans 0.5 frames of the code", "model", margin=0.0, rows_per_chip=4.0, frames=0.5
        )

        def without(decodes):
            return tuple(nothing if j == k else d for j, d in enumerate(decodes))

        return dataclasses.replace(man, decodes=without(man.decodes), other=without(man.other))

    return fake


#: The blobs' pixels of the photo being located (set by :func:`_located_with_unread`).
_PIXELS: list[np.ndarray] = []


def _located_with_unread(monkeypatch, xz, readout: str, seed: int):
    """The four reversal-pair lamps (0, 14, 2, 6) at ``xz``, the one of ID 6 unread: the
    photo's fixtures, the truth and the result of locate with no readout given."""
    import camvlp.pipeline.locate as locate_module

    room = make_small_room(ids=(0, 14, 2, 6), xz=xz)
    camera = make_small_camera()
    pose = Pose.from_euler([0.02, 0.0, -0.03], [LOOK_UP[0] + 1.0, -1.0, 25.0])
    photo = render(camera, room, pose, small_settings(readout=readout, seed=seed))
    truth = {t.id: t.pixel for t in photo.fixtures}
    real_profiles = locate_module.read_profiles

    def profiles(img, blobs, ro):
        _PIXELS[:] = [b.pixel for b in blobs]
        return real_profiles(img, blobs, ro)

    monkeypatch.setattr(locate_module, "read_profiles", profiles)
    monkeypatch.setattr(decode_stage, "decode_manchester", _unread(truth[6]))
    return truth, locate(photo.image, camera, room)


@pytest.mark.parametrize(("readout", "seed"), [("rows", 21), ("columns-reversed", 22)])
def test_the_direction_is_decided_by_an_unread_fixture(monkeypatch, readout, seed):
    # three lamps read (either way, the IDs of the map), the fourth unread: read the right
    # way the three and the fourth, given the ID left, fit a pose; read the wrong way no ID
    # fits the fourth.  The IDs are reported; no position (the fourth's ID is a guess)
    xz = ((0.7, 0.3), (-0.5, -0.4), (0.2, -0.6), (-0.3, 0.5))
    truth, res = _located_with_unread(monkeypatch, xz, readout, seed)
    assert res.readout == readout
    assert not res and "at least 4 are needed" in res.reason
    for f in res.fixtures:
        true_id = min(truth, key=lambda i: np.hypot(*(truth[i] - f.pixel)))
        assert f.id == (None if true_id == 6 else true_id)


def test_an_unread_fixture_does_not_decide_a_direction_both_ways_fit(monkeypatch):
    # the lamps half a turn apart pairwise (0 and 14, 2 and 6): read the wrong way, the IDs
    # are those of the lamps half a turn round, and a camera turned half a turn sees them so
    xz = ((0.7, 0.3), (-0.7, -0.3), (0.2, -0.6), (-0.2, 0.6))
    _, res = _located_with_unread(monkeypatch, xz, "rows", 23)
    assert not res and "undecided" in res.reason
    assert all(f.id is None for f in res.fixtures)
