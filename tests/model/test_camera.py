"""Tests for the camera model: the thesis' angles, poses, projection and undistortion."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from camvlp.model.camera import (
    Camera,
    Pose,
    euler_to_matrix,
    matrix_to_euler,
    rotation_from_vector,
    rotation_z,
)


def _rx(t: float) -> np.ndarray:
    """Thesis eq. 3.5, R_x, written out (radians), 4 x 4 homogeneous."""
    return np.array(
        [[1, 0, 0, 0], [0, np.cos(t), -np.sin(t), 0], [0, np.sin(t), np.cos(t), 0], [0, 0, 0, 1]]
    )


def _ry(t: float) -> np.ndarray:
    """Thesis eq. 3.5, R_y, written out (radians), 4 x 4 homogeneous."""
    return np.array(
        [[np.cos(t), 0, np.sin(t), 0], [0, 1, 0, 0], [-np.sin(t), 0, np.cos(t), 0], [0, 0, 0, 1]]
    )


def _rz(t: float) -> np.ndarray:
    """Thesis eq. 3.5, R_z, written out (radians), 4 x 4 homogeneous."""
    return np.array(
        [[np.cos(t), -np.sin(t), 0, 0], [np.sin(t), np.cos(t), 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    )


def _translation(t) -> np.ndarray:
    """Thesis eq. 3.4, T(t), 4 x 4 homogeneous."""
    m = np.eye(4)
    m[:3, 3] = t
    return m


def _random_poses(rng: np.random.Generator, n: int) -> list[Pose]:
    angles = np.column_stack(
        [rng.uniform(-180, 180, n), rng.uniform(-89, 89, n), rng.uniform(-180, 180, n)]
    )
    positions = rng.uniform(-3, 3, (n, 3))
    return [Pose.from_euler(c, a) for c, a in zip(positions, angles, strict=True)]


@pytest.fixture
def small_camera() -> Camera:
    return Camera(640, 480, [[500.0, 0, 321.5], [0, 505.0, 238.0], [0, 0, 1]])


DISTORTION = np.array([-0.12, 0.03, 0.0015, -0.0008, 0.004])


# --- the thesis' Euler angles ---------------------------------------------------------------


def test_euler_to_matrix_is_rx_ry_rz_of_thesis_eq_3_5():
    rng = np.random.default_rng(1)
    for tx, ty, tz in rng.uniform(-180, 180, (50, 3)):
        by_hand = (_rx(np.deg2rad(tx)) @ _ry(np.deg2rad(ty)) @ _rz(np.deg2rad(tz)))[:3, :3]
        np.testing.assert_allclose(euler_to_matrix([tx, ty, tz]), by_hand, atol=1e-12)


def test_euler_90_0_0_looks_along_world_minus_y():
    r = euler_to_matrix([90, 0, 0])
    np.testing.assert_allclose(r[:, 2], [0, -1, 0], atol=1e-12)  # optical axis (camera z)
    np.testing.assert_allclose(r[:, 0], [1, 0, 0], atol=1e-12)  # image x stays world x
    # a point on the thesis' ceiling, straight above a camera on the floor, is in front of it
    pose = Pose.from_euler([0, 0, 0], [90, 0, 0])
    np.testing.assert_allclose(pose.to_camera([[0, -2.7, 0]]), [[0, 0, 2.7]], atol=1e-12)


def test_matrix_to_euler_round_trip():
    rng = np.random.default_rng(2)
    angles = np.column_stack(
        [rng.uniform(-179, 179, 500), rng.uniform(-89, 89, 500), rng.uniform(-179, 179, 500)]
    )
    for a in angles:
        np.testing.assert_allclose(matrix_to_euler(euler_to_matrix(a)), a, atol=1e-9)


def test_matrix_to_euler_at_gimbal_lock_reproduces_the_matrix():
    for a in ([30, 90, 20], [-40, -90, 10]):
        r = euler_to_matrix(a)
        back = matrix_to_euler(r)
        assert abs(back[1]) == pytest.approx(90)
        np.testing.assert_allclose(euler_to_matrix(back), r, atol=1e-9)


def test_thesis_eq_3_8_world_to_camera_equals_to_camera():
    # eq. 3.7/3.8: X_cam = Rz(-tz) Ry(-ty) Rx(-tx) T(-t) X
    rng = np.random.default_rng(3)
    pts = rng.uniform(-5, 5, (20, 3))
    for pose in _random_poses(rng, 30):
        tx, ty, tz = np.deg2rad(pose.euler_deg)
        m = _rz(-tz) @ _ry(-ty) @ _rx(-tx) @ _translation(-pose.position)
        by_thesis = (m @ np.c_[pts, np.ones(len(pts))].T).T[:, :3]
        np.testing.assert_allclose(pose.to_camera(pts), by_thesis, atol=1e-9)


def test_thesis_eq_3_6_camera_location_is_the_position():
    t = np.array([0.4, -0.2, 1.1])
    tx, ty, tz = np.deg2rad([10.0, -20.0, 35.0])
    p_c = _translation(t) @ _rx(tx) @ _ry(ty) @ _rz(tz) @ np.array([0, 0, 0, 1.0])
    pose = Pose.from_euler(t, [10.0, -20.0, 35.0])
    np.testing.assert_allclose(pose.position, p_c[:3])


# --- poses ----------------------------------------------------------------------------------


def test_pose_rvec_tvec_round_trip():
    rng = np.random.default_rng(4)
    for pose in _random_poses(rng, 100):
        rvec, tvec = pose.rvec_tvec()
        back = Pose.from_rvec_tvec(rvec, tvec)
        np.testing.assert_allclose(back.world_from_camera, pose.world_from_camera, atol=1e-9)
        np.testing.assert_allclose(back.position, pose.position, atol=1e-9)


def test_pose_rvec_tvec_is_opencv_camera_from_world():
    rng = np.random.default_rng(5)
    pts = rng.uniform(-2, 2, (10, 3))
    pose = _random_poses(rng, 1)[0]
    rvec, tvec = pose.rvec_tvec()
    r_cw, _ = cv2.Rodrigues(rvec)
    np.testing.assert_allclose((r_cw @ pts.T).T + tvec, pose.to_camera(pts), atol=1e-9)
    np.testing.assert_allclose(pose.camera_from_world, r_cw, atol=1e-9)


def test_a_rotation_vector_turns_about_its_axis_by_its_length():
    np.testing.assert_allclose(rotation_from_vector([0.0, 0.0, np.radians(30.0)]), rotation_z(30.0))
    np.testing.assert_array_equal(rotation_from_vector(np.zeros(3)), np.eye(3))


def test_pose_rejects_non_rotations():
    with pytest.raises(ValueError, match="rotation"):
        Pose(np.diag([1.0, 1.0, -1.0]), [0, 0, 0])
    with pytest.raises(ValueError, match="rotation"):
        Pose(2 * np.eye(3), [0, 0, 0])
    with pytest.raises(ValueError, match="world_from_camera"):
        Pose(np.eye(2), [0, 0, 0])
    with pytest.raises(ValueError, match="position"):
        Pose(np.eye(3), [0, 0])
    with pytest.raises(ValueError, match="euler_deg"):
        euler_to_matrix([1, 2])
    with pytest.raises(ValueError, match="rotation"):
        matrix_to_euler(np.eye(4))


# --- projection -----------------------------------------------------------------------------


def _points_in_front(rng: np.random.Generator, pose: Pose, n: int) -> np.ndarray:
    """World points inside a 60-degree cone in front of the camera, 0.5 to 5 units away."""
    cam = (
        np.column_stack([rng.uniform(-0.5, 0.5, (n, 2)), np.ones(n)])
        * rng.uniform(0.5, 5, n)[:, None]
    )
    return cam @ pose.world_from_camera.T + pose.position


def test_project_matches_hand_written_pinhole(small_camera: Camera):
    rng = np.random.default_rng(6)
    k = small_camera.matrix
    for pose in _random_poses(rng, 20):
        pts = _points_in_front(rng, pose, 30)
        x_cam = (pose.world_from_camera.T @ (pts - pose.position).T).T  # R^T (X - C)
        uvw = (k @ x_cam.T).T
        by_hand = uvw[:, :2] / uvw[:, 2:]
        np.testing.assert_allclose(small_camera.project(pose, pts), by_hand, atol=1e-7)


def test_project_with_distortion_matches_opencv_and_brown_model(small_camera: Camera):
    cam = Camera(640, 480, small_camera.matrix, DISTORTION)
    rng = np.random.default_rng(7)
    k1, k2, p1, p2, k3 = DISTORTION
    for pose in _random_poses(rng, 10):
        pts = _points_in_front(rng, pose, 30)
        uv = cam.project(pose, pts)
        r_cw = pose.world_from_camera.T
        ref, _ = cv2.projectPoints(
            pts, cv2.Rodrigues(r_cw)[0], -r_cw @ pose.position, cam.matrix, DISTORTION
        )
        np.testing.assert_allclose(uv, ref.reshape(-1, 2), atol=1e-7)
        # the Brown-Conrady model written out
        xc = pose.to_camera(pts)
        x, y = xc[:, 0] / xc[:, 2], xc[:, 1] / xc[:, 2]
        r2 = x**2 + y**2
        radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
        xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x**2)
        yd = y * radial + p1 * (r2 + 2 * y**2) + 2 * p2 * x * y
        k = cam.matrix
        by_hand = np.column_stack([k[0, 0] * xd + k[0, 2], k[1, 1] * yd + k[1, 2]])
        np.testing.assert_allclose(uv, by_hand, atol=1e-7)


def test_project_points_behind_the_camera_are_nan(small_camera: Camera):
    pose = Pose.from_euler([0, 0, 0], [90, 0, 0])  # looking along world -y
    pts = np.array([[0, -2, 0], [0.1, 2, 0.2], [0, 0, 0], [0.3, -1, 0.1]])
    uv = small_camera.project(pose, pts)
    assert uv.shape == (4, 2)
    assert np.all(np.isfinite(uv[[0, 3]]))
    assert np.all(np.isnan(uv[[1, 2]]))
    assert small_camera.project(pose, np.zeros((0, 3))).shape == (0, 2)


def test_principal_point_is_where_the_optical_axis_lands(small_camera: Camera):
    pose = Pose.from_euler([1, 2, 3], [90, 10, -30])
    on_axis = pose.position + 4 * pose.world_from_camera[:, 2]
    np.testing.assert_allclose(small_camera.project(pose, [on_axis])[0], [321.5, 238.0])


# --- undistortion ---------------------------------------------------------------------------


@pytest.mark.parametrize("distortion", [np.zeros(0), np.zeros(5), DISTORTION])
def test_undistort_pixels_inverts_projection(small_camera: Camera, distortion):
    cam = Camera(640, 480, small_camera.matrix, distortion)
    rng = np.random.default_rng(8)
    pose = _random_poses(rng, 1)[0]
    pts = _points_in_front(rng, pose, 200)
    xc = pose.to_camera(pts)
    normalised = xc[:, :2] / xc[:, 2:]
    back = cam.undistort_pixels(cam.project(pose, pts))
    assert back.shape == (200, 2)
    assert np.abs(back - normalised).max() < 1e-6


# --- validation -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"matrix": np.eye(2)}, "3 x 3"),
        ({"matrix": [[500, 0, 320], [0, 500, 240], [0, 0, 2]]}, "last row"),
        ({"matrix": [[-500, 0, 320], [0, 500, 240], [0, 0, 1]]}, "focal"),
        ({"matrix": [[500, 0, 320], [0, np.nan, 240], [0, 0, 1]]}, "finite"),
        ({"matrix": [[500, 2, 320], [0, 500, 240], [0, 0, 1]]}, "skew"),
        ({"distortion": [0.1, 0.0, 0.0]}, "distortion"),
        ({"distortion": [0.1, 0.0, 0.0, 0.0, 0.0, 0.0]}, "distortion"),
        ({"distortion": [0.1, np.inf, 0.0, 0.0]}, "distortion"),
        ({"row_time_s": 0.0}, "row_time_s"),
        ({"row_time_s": -2e-5}, "row_time_s"),
        ({"row_time_s": 5.0}, "row_time_s"),
        ({"readout": "diagonal"}, "readout"),
        ({"width": 0}, "image size"),
    ],
)
def test_camera_rejects_invalid_values(kwargs, message):
    args = {"width": 640, "height": 480, "matrix": [[500, 0, 320], [0, 500, 240], [0, 0, 1]]}
    args.update(kwargs)
    with pytest.raises(ValueError, match=message):
        Camera(**args)


def test_camera_accepts_every_opencv_distortion_length():
    for n in (4, 5, 8, 12, 14):
        cam = Camera(64, 48, [[50, 0, 32], [0, 50, 24], [0, 0, 1]], np.full(n, 1e-3))
        assert cam.distortion.shape == (n,)


def test_from_focal_centres_the_principal_point_on_the_middle_pixel():
    cam = Camera.from_focal(5184, 3880, 3912.0)
    np.testing.assert_allclose(cam.matrix[:2, 2], [2591.5, 1939.5])  # pixel centres at integers
    assert cam.focal_px == 3912.0
    assert cam.with_size(100, 80).size == (100, 80)


@pytest.mark.parametrize("angle_rad", [0.0, 3e-7, 3e-6, 3e-5])
def test_project_keeps_rotations_below_opencvs_rodrigues_rounding(angle_rad):
    """A camera turned by less than 1e-5 rad projects as turned: cv2.Rodrigues rounds such
    rotations to none, which moved points by up to 0.04 px at 20 MP."""
    cam = Camera.from_focal(5184, 3880, 3912.0)
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    turn = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    pose = Pose(turn, np.array([0.01, -0.02, 0.0]))
    world = np.array([[1.5, -0.8, 2.0], [-1.2, 0.9, 2.5], [0.3, 0.2, 1.8]])
    local = (world - pose.position) @ turn  # the camera frame, by hand
    pinhole = local[:, :2] / local[:, 2:] * 3912.0 + cam.matrix[:2, 2]
    np.testing.assert_allclose(cam.project(pose, world), pinhole, rtol=0, atol=1e-9)


@pytest.mark.parametrize("angle", [3e-7, 3e-6, 1e-4, 0.5, 3.0])
def test_rvec_of_a_small_rotation_is_exact(angle):
    # OpenCV 5's Rodrigues turns rotations below about 1e-5 rad into none at all
    rng = np.random.default_rng(4)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    r_cw = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k
    rvec, tvec = Pose(r_cw.T, np.array([1.0, 2.0, 3.0])).rvec_tvec()
    np.testing.assert_allclose(rvec, axis * angle, rtol=1e-12, atol=0)
    np.testing.assert_allclose(tvec, -r_cw @ [1.0, 2.0, 3.0], rtol=1e-12)
