"""IDs for sites of more fixtures than a frame has IDs: views told apart by geometry."""

from __future__ import annotations

import numpy as np

from camvlp.analysis.assign_ids import assign_ids, assignment_report
from camvlp.analysis.study.site_views import Views, ambiguous_views, identified_share, sample_views
from camvlp.model.camera import Camera, Pose
from camvlp.model.linecode import FrameFormat

UP = np.array([0.0, 0.0, 1.0])
#: A phone looking up from 1.0 to 1.6 m under a 3 m ceiling of lights 1.2 m apart sees some
#: three to six of them.
CAMERA = Camera.from_focal(1600, 1200, 1000.0)


def _grid(nx: int, ny: int, step: float = 1.2) -> np.ndarray:
    x, y = np.meshgrid(np.arange(nx) * step, np.arange(ny) * step)
    return np.stack([x.ravel(), y.ravel(), np.full(x.size, 3.0)], axis=1)


def _views(pos: np.ndarray, n: int, seed: int) -> Views:
    diam = np.full(len(pos), 0.15)
    return sample_views(CAMERA, pos, diam, UP, n_poses=n, rng=np.random.default_rng(seed))


def test_a_camera_looking_up_sees_the_lights_above_it():
    pos = _grid(12, 10)
    views = _views(pos, 400, 1)
    counts = views.counts()
    assert np.median(counts) >= 3, np.bincount(counts)
    for c, rot, seen in zip(views.positions_m, views.rotations, views.seen, strict=True):
        assert 1.0 <= c[2] <= 1.6
        assert rot[:, 2] @ UP >= np.cos(np.deg2rad(20.0)) - 1e-9  # tilted 20 degrees at most
        # the lights seen project into the image, and every light that does (its centre a
        # disc's radius, under 60 px, from the edges) is seen
        uv = CAMERA.project(Pose(rot, c), pos)
        inside = np.all((uv > 60) & (uv < [CAMERA.width - 60, CAMERA.height - 60]), axis=1)
        outside = np.any((uv < -1) | (uv > [CAMERA.width + 1, CAMERA.height + 1]), axis=1)
        assert set(np.flatnonzero(inside)) <= set(seen.tolist())
        assert not set(np.flatnonzero(outside)) & set(seen.tolist())


def test_lights_each_of_their_own_id_are_never_ambiguous_and_a_repeated_pattern_is():
    pos = _grid(4, 4)  # 16 lights: every one its own ID
    views = _views(pos, 300, 2)
    own = np.arange(16)
    several = views.counts() >= 2
    assert several.sum() > 100
    amb = ambiguous_views(pos, UP, own, 16, views)
    assert not amb[several].any()
    assert amb[~several].all()  # one light or none: nothing to tell the place by
    # a pattern of 2 x 2 IDs repeated: every view of it is somewhere else too
    tiled = (np.arange(16) % 2) + 2 * ((np.arange(16) // 4) % 2)
    assert ambiguous_views(pos, UP, tiled, 16, views).all()


def test_a_view_is_told_apart_once_its_twin_elsewhere_differs_in_one_light():
    pos = _grid(8, 2)
    ids = np.array([1, 2, 3, 4, 1, 2, 3, 5, 6, 7, 8, 9, 6, 7, 8, 10])  # columns 0-2 = 4-6
    views = Views(np.zeros((1, 3)), np.eye(3)[None], [np.array([0, 1, 8, 9])])
    assert ambiguous_views(pos, UP, ids, 16, views, one_missing=False).all()
    ids[12] = 11  # the twin's lower left light
    assert not ambiguous_views(pos, UP, ids, 16, views, one_missing=False).any()
    # ... but with a light missing (the one that differs) the view is its twin again
    assert ambiguous_views(pos, UP, ids, 16, views, one_missing=True).all()


def test_turned_copies_are_the_same_view():
    # two triangles of the same IDs, one turned a quarter round about the vertical
    pos = np.array(
        [[0, 0, 3], [1, 0, 3], [0, 2, 3], [10, 10, 3], [10, 11, 3], [8, 10, 3]], dtype=float
    )
    ids = np.array([1, 2, 3, 1, 2, 3])
    views = Views(np.zeros((1, 3)), np.eye(3)[None], [np.array([0, 1, 2])])
    assert ambiguous_views(pos, UP, ids, 16, views, one_missing=False).all()
    mirrored = pos.copy()
    mirrored[5] = [12, 10, 3]  # a mirror image: no camera sees it turned
    assert not ambiguous_views(mirrored, UP, ids, 16, views, one_missing=False).any()


def test_assigned_ids_tell_more_new_views_apart_than_random_ones():
    seed = 3
    pos = _grid(11, 8)
    frame = FrameFormat()
    searched = _views(pos, 3000, seed)
    ids = assign_ids(pos, UP, frame.reversed_ids, searched, rng=np.random.default_rng(seed))
    assert ids.shape == (len(pos),) and ids.min() >= 0 and ids.max() < frame.n_ids
    fresh = _views(pos, 500, seed + 100)  # poses the search never saw
    report = assignment_report(pos, UP, ids, frame.n_ids, fresh, rng=np.random.default_rng(0))
    n, share, share_random = report.shares(3)
    assert n >= 250
    # views left ambiguous: a third of the random assignment's or fewer
    assert 1.0 - share <= (1.0 - share_random) / 3.0, (share, share_random)
    assigned_rev, random_rev = report.reversed_neighbours(frame.reversed_ids)
    assert assigned_rev < random_rev / 4, (assigned_rev, random_rev)
    assert identified_share(report.ambiguous, fresh, 3) == share
    # lights seen together are given different IDs: a view of two of one ID reads it twice
    # (146 of 492 new views did, when only ambiguous views and reversal partners counted)
    twice = sum(1 for s in fresh.seen if s.size >= 2 and len(set(ids[s].tolist())) < s.size)
    assert twice <= 0.01 * n, twice
