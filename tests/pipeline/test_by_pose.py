"""Look-alike IDs told apart by the pose (camvlp.pipeline.by_pose and its use in locate)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from camvlp.locate import locate
from tests.conftest import LOOK_UP

import camvlp.pipeline.locate as locate_module
from camvlp.model.camera import Pose, project_points
from camvlp.pipeline.by_pose import TOLD_APART, assigned_by_pose, told_by_pose
from camvlp.pipeline.model_decode import ModelDecode
from camvlp.pipeline.pose import estimate_pose

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


#: Each of the small room's IDs and a look-alike: the next ID round the room (no rigid motion
#: takes the room onto itself that way) and the ID half a turn away (the rectangle's turn by
#: 180 degrees about the middle light takes it onto itself: both assignments give a pose).
NEXT = {5: 6, 6: 9, 9: 10, 10: 12, 12: 5}
TURNED = {5: 9, 9: 5, 6: 10, 10: 6, 12: 5}


def _assigned(camera, room, look_alike: dict[int, int], seed: int) -> dict[int, int]:
    """assigned_by_pose on the small room's fixtures seen from POSE (centres 0.3 px noisy),
    each refused between its ID and ``look_alike[ID]``; fixture index -> ID."""
    ids = [f.id for f in room.fixtures]
    rng = np.random.default_rng(seed)
    px = project_points(camera, POSE, [room.get(i).position for i in ids])
    px = px + rng.normal(0.0, 0.3, px.shape)
    cands = [(i, look_alike[i]) if rng.random() < 0.5 else (look_alike[i], i) for i in ids]

    def pose_of(given: dict[int, int]):
        ks = sorted(given)
        obj = [room.get(given[k]).position for k in ks]
        est = estimate_pose(px[ks], obj, camera, outlier_px=10.0)
        return est.pose if est and all(est.used) else None

    return assigned_by_pose(camera, room, px, {}, cands, 10.0, pose_of)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_look_alikes_alone_give_the_pose_when_one_assignment_fits(small_camera, small_room, seed):
    got = _assigned(small_camera, small_room, NEXT, seed)
    assert got == {k: f.id for k, f in enumerate(small_room.fixtures)}


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_look_alikes_are_not_assigned_when_two_assignments_fit(small_camera, small_room, seed):
    assert _assigned(small_camera, small_room, TURNED, seed) == {}


def test_look_alikes_are_assigned_only_from_every_way_for_the_fixtures_tried(
    monkeypatch, small_camera, small_room
):
    # the first four fixtures (IDs 5, 6, 9, 10, each beside the next ID round the room) have
    # 5 ways with no ID twice; a cap below that tries none of them (a part of the ways could
    # miss the one that contradicts an assignment)
    import camvlp.pipeline.by_pose as by_pose

    monkeypatch.setattr(by_pose, "HYPOTHESES", 4)
    assert _assigned(small_camera, small_room, NEXT, 0) == {}
    monkeypatch.setattr(by_pose, "HYPOTHESES", 5)
    assert len(_assigned(small_camera, small_room, NEXT, 0)) == 5


def _refused(true_id: int | tuple[int, ...], candidates: tuple[int, ...] | dict[int, int]):
    """locate's Manchester decode with the fixtures of ``true_id`` (one ID or several)
    refused between ``candidates`` (as the model fit refuses look-alikes; a dict gives each
    true ID its look-alike, the candidates then in ID order)."""
    real = locate_module.decode_manchester
    refused = (true_id,) if isinstance(true_id, int) else true_id

    def fake(profiles, readout, direction_known, camera, fixture_map):
        man = real(profiles, readout, direction_known, camera, fixture_map)
        decodes = list(man.decodes)
        for t in refused:
            k = [d.id for d in decodes].index(t)
            pair = tuple(sorted((t, candidates[t]))) if isinstance(candidates, dict) else None
            decodes[k] = _refusal(pair or candidates, man.rows_per_chip)
        return dataclasses.replace(man, decodes=tuple(decodes))

    return fake


def _refusal(candidates: tuple[int, ...], rows_per_chip: float) -> ModelDecode:
    """A model decode refused between look-alike ``candidates``."""
    return ModelDecode(
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
        rows_per_chip,
        1.5,
        candidates=candidates,
    )


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


def test_locate_assigns_look_alikes_when_no_fixture_is_identified(
    monkeypatch, small_camera, small_room, small_render
):
    ids = tuple(f.id for f in small_room.fixtures)
    monkeypatch.setattr(locate_module, "decode_manchester", _refused(ids, NEXT))
    res = locate(small_render.image, small_camera, small_room)
    assert res
    for f in res.fixtures:
        i = min(ids, key=lambda i: np.hypot(*(f.pixel - where(small_camera, small_room, i))))
        assert f.id == i and f.used and f.look_alikes == tuple(sorted((i, NEXT[i])))
    assert np.linalg.norm(res.position - POSE.position) < 0.01


def test_locate_refuses_look_alikes_that_two_assignments_fit(
    monkeypatch, small_camera, small_room, small_render
):
    ids = tuple(f.id for f in small_room.fixtures)
    monkeypatch.setattr(locate_module, "decode_manchester", _refused(ids, TURNED))
    res = locate(small_render.image, small_camera, small_room)
    assert not res and "at least 4 are needed" in res.reason
    assert all(f.id is None and "almost equally" in f.reason for f in res.fixtures)
