"""The offset of a disc's image centre from its centre's projection, against a dense fit."""

from __future__ import annotations

import numpy as np

from camvlp.geometry.disc import perspective_offsets, rim_points
from camvlp.model.camera import Camera, Pose


def _conic_centre(uv: np.ndarray) -> np.ndarray:
    """Centre of the conic through points (M, 2), an algebraic least-squares fit in float64."""
    mean = uv.mean(axis=0)
    x, y = (uv - mean).T
    design = np.stack([x * x, x * y, y * y, x, y, np.ones_like(x)], axis=1)
    a, b, c, d, e, _ = np.linalg.svd(design, full_matrices=False)[2][-1]
    return np.linalg.solve([[2 * a, b], [b, 2 * c]], [-d, -e]) + mean


def test_closed_form_matches_the_centre_of_the_projected_rim() -> None:
    rng = np.random.default_rng(3)
    camera = Camera.from_focal(1920, 1080, 1200.0)
    diameters = [0.2, 0.15, 0.25]
    checked = 0
    for _ in range(20):
        pose = Pose.from_euler(rng.uniform(-1, 1, 3), rng.uniform(-180, 180, 3))
        r = pose.world_from_camera
        # discs 1.5 to 3 m ahead, off the axis, facing the camera within 40 degrees
        ahead = np.column_stack([rng.uniform(-0.6, 0.6, (3, 2)), rng.uniform(1.5, 3.0, 3)])
        facing = np.column_stack([rng.uniform(-0.8, 0.8, (3, 2)), -np.ones(3)])
        centres, normals = pose.position + ahead @ r.T, facing @ r.T
        got = perspective_offsets(camera, pose, centres, diameters, normals)
        rim = rim_points(centres, diameters, normals, 720)
        for k in range(3):
            uv = camera.project(pose, rim[k])
            want = _conic_centre(uv) - camera.project(pose, centres[k : k + 1])[0]
            np.testing.assert_allclose(got[k], want, atol=1e-6)
            checked += np.abs(want).max() > 0.05  # offsets large enough to matter
    assert checked > 10


def test_a_disc_reaching_behind_the_camera_gets_no_offset() -> None:
    camera = Camera.from_focal(640, 480, 500.0)
    pose = Pose.from_euler([0, 0, 0], [0, 0, 0])
    looking = pose.world_from_camera[:, 2]  # the optical axis in the map frame
    # a disc of 1 m across, 0.3 m ahead, seen edge on: its rim reaches behind the camera
    side = pose.world_from_camera[:, 0]
    offsets = perspective_offsets(
        camera, pose, [0.3 * looking, 3.0 * looking], [1.0, 0.1], [side, looking]
    )
    assert np.all(offsets[0] == 0)
    assert np.all(np.isfinite(offsets[1]))
