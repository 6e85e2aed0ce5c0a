"""Look-alike IDs told apart by the pose (camvlp.pipeline.by_pose and its use in locate)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from camvlp.locate import locate
from tests.conftest import LOOK_UP

import camvlp.pipeline.locate as locate_module
from camvlp.model.camera import Pose, project_points
from camvlp.pipeline.by_pose import TOLD_APART, told_by_pose
from camvlp.pipeline.model_decode import ModelDecode

POSE = Pose.from_euler([0, 0, 0], LOOK_UP)


def where(camera, room, i: int) -> np.ndarray:
    return project_points(camera, POSE, [room.get(i).position])[0]


def test_the_id_whose_map_position_projects_onto_the_fixture(small_camera, small_room):
    px = (where(small_camera, small_room, 9) + np.array([1.0, -0.5]))[None]
    assert told_by_pose(small_camera, POSE, small_room, px, [(5, 9)], set(), 4.0) == {0: 9}
    # the true ID not among the candidates: the nearest projects far away, nothing is told
    assert told_by_pose(small_camera, POSE, small_room, px, [(5, 6)], set(), 4.0) == {}
    # an ID already given to another fixture is not a candidate
    assert told_by_pose(small_camera, POSE, small_room, px, [(5, 9)], {9}, 4.0) == {}
    # one candidate (or an ID not in the map beside it): nothing to tell apart
    assert told_by_pose(small_camera, POSE, small_room, px, [(9,)], set(), 4.0) == {}
    assert told_by_pose(small_camera, POSE, small_room, px, [(9, 3)], set(), 4.0) == {}


def test_nothing_is_told_when_the_fixture_lies_between_the_candidates(small_camera, small_room):
    a, b = where(small_camera, small_room, 5), where(small_camera, small_room, 6)
    px = np.array([(a + b) / 2])
    assert told_by_pose(small_camera, POSE, small_room, px, [(5, 6)], set(), 4.0) == {}
    # half an outlier distance from one: told when the other lies beyond TOLD_APART outlier
    # distances, not when it lies within
    ab = float(np.hypot(*(b - a)))
    for outlier, told in ((ab / (TOLD_APART + 1.5), {0: 5}), (ab / (TOLD_APART - 0.5), {})):
        near = (a + (b - a) * 0.5 * outlier / ab)[None]
        assert told_by_pose(small_camera, POSE, small_room, near, [(5, 6)], set(), outlier) == told


def test_an_id_told_for_two_fixtures_is_given_to_neither(small_camera, small_room):
    px = np.array([where(small_camera, small_room, 9)] * 2)
    got = told_by_pose(small_camera, POSE, small_room, px, [(5, 9), (9, 10)], set(), 4.0)
    assert got == {}


def _refused(true_id: int, candidates: tuple[int, ...]):
    """locate's Manchester decode with the fixture of ``true_id`` refused between
    ``candidates`` (as the model fit refuses look-alikes)."""
    real = locate_module.decode_manchester

    def fake(profiles, readout, direction_known, camera, fixture_map):
        man = real(profiles, readout, direction_known, camera, fixture_map)
        decodes = list(man.decodes)
        k = [d.id for d in decodes].index(true_id)
        decodes[k] = ModelDecode(
            None,
            f"IDs {candidates[0]} and {candidates[1]} fit almost equally (margin 0.5, at least 4 "
            "needed)",
            0.5,
            candidates[1],
            0.0,
            1.0,
            0.0,
            0.01,
            0.01,
            man.rows_per_chip,
            1.5,
            candidates=candidates,
        )
        return dataclasses.replace(man, decodes=tuple(decodes))

    return fake


@pytest.mark.parametrize("candidates", [(9, 5, 12), (5, 9)])
def test_locate_tells_a_refused_fixture_by_the_pose(
    monkeypatch, small_camera, small_room, small_render, candidates
):
    monkeypatch.setattr(locate_module, "decode_manchester", _refused(9, candidates))
    res = locate(small_render.image, small_camera, small_room)
    assert res
    f = next(
        f for f in res.fixtures if np.hypot(*(f.pixel - where(small_camera, small_room, 9))) < 5
    )
    assert f.id == 9 and f.used and f.reason == ""
    assert f.look_alikes == candidates
    assert f.to_dict()["look_alikes"] == list(candidates)
    assert sum(f.used for f in res.fixtures) == 5
    assert np.linalg.norm(res.position - POSE.position) < 0.01


def test_locate_does_not_tell_a_fixture_whose_true_id_is_not_a_candidate(
    monkeypatch, small_camera, small_room, small_render
):
    monkeypatch.setattr(locate_module, "decode_manchester", _refused(9, (5, 12)))
    res = locate(small_render.image, small_camera, small_room)
    assert res
    f = next(
        f for f in res.fixtures if np.hypot(*(f.pixel - where(small_camera, small_room, 9))) < 5
    )
    assert f.id is None and not f.used and "almost equally" in f.reason
    assert f.look_alikes == ()
