"""Sets of four fixtures tested against four rays before any PnP (rigid_on_plane)."""

from __future__ import annotations

import numpy as np

from camvlp.geometry.hypotheses import rigid_on_plane
from camvlp.model.camera import Pose


def _seen(points: np.ndarray, pose: Pose, rng, noise: float) -> np.ndarray:
    """The rays (4, 3) of ``points`` (4, 3) from ``pose``, their images moved by Gaussian
    noise of ``noise`` (normalised image units)."""
    cam = pose.to_camera(points)
    xy = cam[:, :2] / cam[:, 2:] + noise * rng.standard_normal((4, 2))
    return np.column_stack([xy, np.ones(4)])


def test_the_true_fixtures_pass_and_sets_no_rigid_motion_explains_are_dropped():
    rng = np.random.default_rng(3)
    ceiling = np.array([[0, 0, 3.0], [1.5, 0, 3.0], [0, 1.5, 3.0], [1.5, 1.5, 3.0]])
    # the same square larger by a tenth: seen from farther away it looks the same
    larger = ceiling * [1.1, 1.1, 1.0]
    # a rectangle and a parallelogram within the homography's ratio (1.3) and angle (0.25)
    # checks: no rotation takes the square there
    stretched = ceiling * [1.2, 1.0, 1.0]
    sheared = ceiling + np.array([[0, 0, 0], [0, 0.35, 0], [0, 0, 0], [0, 0.35, 0]])
    sets = np.stack([ceiling, larger, stretched, sheared])
    loose_kept, tight_kept = np.zeros(4, int), np.zeros(4, int)
    for _ in range(200):
        pose = Pose.from_euler(
            [*rng.uniform(-0.5, 2.0, 2), rng.uniform(0.5, 1.5)], [*rng.uniform(-20, 20, 2), 0]
        )
        rays = _seen(ceiling, pose, rng, 0.5 / 800)  # half a pixel at f = 800 px
        loose = rigid_on_plane(sets, rays)
        tight = rigid_on_plane(sets, rays, max_error=3 * 8.0 / 800)
        assert not np.any(tight & ~loose)  # the check only ever drops more
        loose_kept += loose
        tight_kept += tight
    assert loose_kept[0] == tight_kept[0] == 200  # the true set always stands
    assert tight_kept[1] == 200  # and so does one a rigid motion explains
    assert loose_kept[2:].min() >= 100  # the ratio and the angle let most through...
    assert tight_kept[2:].max() <= 10  # ...the rigid pose few


def test_sets_whose_equations_are_singular_fall_back_to_least_squares(monkeypatch):
    # each set's homography solves eight equations in eight unknowns; where LAPACK finds
    # them singular the pseudo-inverse's least squares answers instead of an error, and
    # the sets are judged as with the solve
    rng = np.random.default_rng(5)
    ceiling = np.array([[0, 0, 3.0], [1.5, 0, 3.0], [0, 1.5, 3.0], [1.5, 1.5, 3.0]])
    sets = np.stack([ceiling, ceiling * [1.2, 1.0, 1.0], ceiling[[1, 0, 2, 3]]])
    pose = Pose.from_euler([0.7, 0.4, 1.0], [8.0, -5.0, 0.0])
    rays = _seen(ceiling, pose, rng, 0.5 / 800)
    solved = rigid_on_plane(sets, rays, max_error=3 * 8.0 / 800)

    def singular(*args, **kwargs):
        raise np.linalg.LinAlgError("Singular matrix")

    monkeypatch.setattr(np.linalg, "solve", singular)
    assert np.array_equal(rigid_on_plane(sets, rays, max_error=3 * 8.0 / 800), solved)
    assert solved[0] and not solved[1:].any()
