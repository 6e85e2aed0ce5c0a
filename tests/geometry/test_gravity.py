"""Locating from two, three or more fixtures with the direction of gravity."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import camvlp
from camvlp.geometry.gravity import (
    check_gravity,
    check_gravity_view,
    map_up,
    solve_pose_gravity,
    solve_two_fixtures,
    tilt_error_deg,
    tilt_rotation,
)
from camvlp.geometry.pose_sigma import gravity_position_sigma, position_sigma
from camvlp.model.camera import Camera, Pose, project_points

ROOT = Path(__file__).resolve().parents[2]
CAMERA = camvlp.load_camera(ROOT / "examples" / "thesis_camera.yaml")
ROOM = camvlp.load_map(ROOT / "examples" / "thesis_room.yaml")
PTS = ROOM.positions
NORMALS = np.array([f.normal for f in ROOM.fixtures])
UP = np.array([0.0, -1.0, 0.0])


def _random_pose(rng: np.random.Generator) -> camvlp.Pose:
    """Floor or 1 m up, tilts up to 10 degrees, any heading (the thesis' room)."""
    height = rng.choice([0.0, 1.0])
    position = [rng.uniform(-1, 1), -height, rng.uniform(-1, 1)]
    euler = [90 + rng.uniform(-10, 10), rng.uniform(-10, 10), rng.uniform(-180, 180)]
    return camvlp.Pose.from_euler(position, euler)


def _gravity(pose: camvlp.Pose, error_deg: float, rng: np.random.Generator) -> np.ndarray:
    """Gravity in the camera frame, 9.81 long, turned by ``error_deg`` in a random direction."""
    g = pose.world_from_camera.T @ -UP
    axis = rng.normal(size=3)
    axis -= (axis @ g) * g
    axis /= np.linalg.norm(axis)
    return 9.81 * Rotation.from_rotvec(np.radians(error_deg) * axis).apply(g)


@pytest.mark.parametrize("n", [2, 3, 4])
def test_exact_round_trip(n: int) -> None:
    rng = np.random.default_rng(11 + n)
    for _ in range(20):
        pose = _random_pose(rng)
        uv = CAMERA.project(pose, PTS)
        res = solve_pose_gravity(
            uv[:n], PTS[:n], CAMERA, _gravity(pose, 0.0, rng), up=UP, normals=NORMALS[:n]
        )
        assert res, res.reason
        assert res.n_fixtures == n
        assert res.solver == {2: "gravity-2", 3: "gravity-3", 4: "pnp+gravity"}[n]
        np.testing.assert_allclose(res.pose.position, pose.position, atol=1e-9)
        np.testing.assert_allclose(res.pose.world_from_camera, pose.world_from_camera, atol=1e-9)
        assert res.reprojection_rms_px < 1e-6


def test_distorted_camera_round_trip() -> None:
    cam = camvlp.Camera(5184, 3880, CAMERA.matrix, np.array([0.08, -0.15, 0.001, -0.002, 0.05]))
    rng = np.random.default_rng(3)
    for _ in range(10):
        pose = _random_pose(rng)
        uv = cam.project(pose, PTS)
        for n in (2, 3):
            res = solve_pose_gravity(uv[:n], PTS[:n], cam, _gravity(pose, 0, rng), up=UP)
            assert res, res.reason
            np.testing.assert_allclose(res.pose.position, pose.position, atol=1e-7)


def _mean_errors(n: int, pixel_noise: float, gravity_deg: float, trials: int = 60) -> np.ndarray:
    rng = np.random.default_rng(100 * n + int(10 * gravity_deg))
    errors = []
    for _ in range(trials):
        pose = _random_pose(rng)
        uv = CAMERA.project(pose, PTS[:n]) + rng.normal(0, pixel_noise, (n, 2))
        g = _gravity(pose, gravity_deg, rng)
        res = solve_pose_gravity(uv, PTS[:n], CAMERA, g, up=UP, normals=NORMALS[:n])
        errors.append(np.linalg.norm(res.pose.position - pose.position) if res else np.nan)
    return np.array(errors)


def test_two_fixtures_noise() -> None:
    # pixel noise alone: sub-millimetre, every pose located
    e = _mean_errors(2, 0.1, 0.0)
    assert np.all(np.isfinite(e))
    assert np.mean(e) < 1e-3
    # a tilt error moves the camera about its distance to the fixtures times the angle
    # (1.7 to 2.9 m here): 1 degree costs centimetres, and it grows with the error
    e1 = _mean_errors(2, 0.1, 1.0)
    e2 = _mean_errors(2, 0.1, 2.0)
    assert 0.01 < np.mean(e1) < 0.06
    assert 1.6 < np.mean(e2) / np.mean(e1) < 2.4


def test_three_fixtures_use_the_pixels() -> None:
    # with a third fixture the pixels fix the tilt too: a 2-degree gravity error costs far
    # less than with two fixtures
    e3 = _mean_errors(3, 0.1, 2.0)
    e2 = _mean_errors(2, 0.1, 2.0)
    assert np.all(np.isfinite(e3))
    assert np.median(e3) < 0.25 * np.median(e2)


def test_both_solutions_of_two_fixtures() -> None:
    rng = np.random.default_rng(5)
    pose = _random_pose(rng)
    rays = CAMERA.undistort_pixels(CAMERA.project(pose, PTS[:2]))
    g = _gravity(pose, 0, rng)
    poses, reason = solve_two_fixtures(rays, PTS[:2], g, UP)
    assert reason == "" and len(poses) == 2
    found = [np.linalg.norm(p.position - pose.position) < 1e-9 for p in poses]
    assert sum(found) == 1
    for p in poses:
        # each puts both fixtures on the lines of their rays, with the measured tilt
        dirs = (p.world_from_camera @ np.column_stack([rays, np.ones(2)]).T).T
        to_fixtures = PTS[:2] - p.position
        cross = np.cross(dirs, to_fixtures)
        assert np.max(np.abs(cross)) < 1e-9
        assert tilt_error_deg(p.world_from_camera, g, UP) < 1e-9
    # on a level ceiling the other solution puts the fixtures behind the camera
    other = poses[found.index(False)]
    assert np.all(other.to_camera(PTS[:2])[:, 2] < 0)


def test_two_valid_solutions_are_refused() -> None:
    # fixtures at different heights, the camera between them: both solutions put the
    # fixtures in front; without normals to tell them apart, a failure that names both
    pts = np.array([[1.5252, -1.7768, -0.6228], [1.9797, -1.2899, -1.2692]])
    pose = camvlp.Pose.from_euler([0.7602, -1.2185, 0.3358], [172.51, 51.09, 89.37])
    uv = CAMERA.project(pose, pts)
    g = pose.world_from_camera.T @ -UP
    poses, _ = solve_two_fixtures(CAMERA.undistort_pixels(uv), pts, g, UP)
    assert len(poses) == 2
    assert all(np.all(p.to_camera(pts)[:, 2] > 0) for p in poses)
    res = solve_pose_gravity(uv, pts, CAMERA, g, up=UP)
    assert not res and "two poses fit" in res.reason
    assert res.alternative is not None
    assert min(np.linalg.norm(p.position - pose.position) for p in res.candidates) < 1e-9


def test_lit_side_picks_the_solution() -> None:
    # fixtures facing up (a floor of lights seen from above) flip which solution is valid
    rng = np.random.default_rng(2)
    pose = camvlp.Pose.from_euler([0.1, -2.0, 0.2], [-90 + 3, 4, 30])  # looks down (+y)
    pts = np.array([[0.5, 0.0, 0.3], [-0.4, 0.0, -0.5]])
    uv = CAMERA.project(pose, pts)
    g = _gravity(pose, 0, rng)
    up = np.array([0.0, -1.0, 0.0])
    res = solve_pose_gravity(uv, pts, CAMERA, g, up=up, normals=[[0, -1, 0], [0, -1, 0]])
    assert res, res.reason
    np.testing.assert_allclose(res.pose.position, pose.position, atol=1e-9)
    wrong = solve_pose_gravity(uv, pts, CAMERA, g, up=up, normals=[[0, 1, 0], [0, 1, 0]])
    assert not wrong and "lit side" in wrong.reason


def test_vertical_pair_is_a_failure() -> None:
    pts = np.array([[0.3, -2.7, 0.2], [0.3, -2.2, 0.2]])  # one above the other
    pose = camvlp.Pose.from_euler([0.0, 0.0, 0.0], [95, 3, 0])
    uv = CAMERA.project(pose, pts)
    g = pose.world_from_camera.T @ -UP
    res = solve_pose_gravity(uv, pts, CAMERA, g, up=UP)
    assert not res and res.pose is None
    assert "line along gravity" in res.reason


@pytest.mark.parametrize(
    "gravity, words",
    [
        ([0, 0, 0], "zero length"),
        ([np.nan, 1, 0], "finite"),
        ([np.inf, 1, 0], "finite"),
        ([1, 2], "three numbers"),
        ("down", "three numbers"),
    ],
)
def test_bad_gravity(gravity, words: str) -> None:
    with pytest.raises(camvlp.InputError, match=words) as err:
        check_gravity(gravity)
    assert "\n" not in str(err.value)
    uv = CAMERA.project(camvlp.Pose.from_euler([0, 0, 0], [90, 0, 0]), PTS[:2])
    with pytest.raises(camvlp.InputError, match=words):
        solve_pose_gravity(uv, PTS[:2], CAMERA, gravity, up=UP)


def test_gravity_along_the_optical_axis() -> None:
    # looking straight down at the floor: the ceiling's lights face down, out of view
    with pytest.raises(camvlp.InputError, match="optical axis") as err:
        check_gravity_view([0, 0, 9.8], CAMERA, UP, NORMALS)
    assert "\n" not in str(err.value)
    # looking straight up at them is the usual case; a level camera sees above the horizon
    check_gravity_view([0, 0, -9.8], CAMERA, UP, NORMALS)
    check_gravity_view([0, 9.8, 0], CAMERA, UP, NORMALS)
    # lights facing up (on the floor) can be seen looking down
    check_gravity_view([0, 0, 9.8], CAMERA, UP, -NORMALS)


def test_wrong_id_with_three_fixtures_is_refused() -> None:
    rng = np.random.default_rng(4)
    refused = 0
    for _ in range(20):
        pose = _random_pose(rng)
        uv = CAMERA.project(pose, PTS[:3])
        wrong = PTS[[0, 1, 3]]  # the third fixture's ID decoded as the fourth's
        res = solve_pose_gravity(
            uv, wrong, CAMERA, _gravity(pose, 0.5, rng), up=UP, normals=NORMALS[:3]
        )
        refused += not res
        if res:  # never a position far from the truth
            assert np.linalg.norm(res.pose.position - pose.position) < 0.01
    assert refused == 20


def test_four_fixtures_report_the_tilt_disagreement() -> None:
    rng = np.random.default_rng(9)
    for error in (0.0, 2.0, 4.0):
        pose = _random_pose(rng)
        uv = CAMERA.project(pose, PTS)
        res = solve_pose_gravity(
            uv, PTS, CAMERA, _gravity(pose, error, rng), up=UP, normals=NORMALS
        )
        assert res and res.solver == "pnp+gravity" and res.n_fixtures == 4
        assert abs(res.tilt_disagreement_deg - error) < 1e-6
        np.testing.assert_allclose(res.pose.position, pose.position, atol=1e-3)


def test_five_fixtures_drop_a_wrong_one() -> None:
    pts = np.vstack([PTS, [[0.0, -2.7, 0.0]]])
    rng = np.random.default_rng(6)
    pose = camvlp.Pose.from_euler([0.1, 0.0, -0.2], [91, 2, 40])
    uv = CAMERA.project(pose, pts)
    uv[4] += [150.0, -80.0]  # a misplaced light
    res = solve_pose_gravity(uv, pts, CAMERA, _gravity(pose, 0.3, rng), up=UP)
    assert res and res.n_fixtures == 4
    assert list(res.used) == [True, True, True, True, False]
    assert res.residuals_px[4] > 100
    np.testing.assert_allclose(res.pose.position, pose.position, atol=1e-3)


def test_map_up() -> None:
    np.testing.assert_allclose(map_up(PTS, normals=NORMALS), UP)
    np.testing.assert_allclose(map_up(PTS), UP)  # no normals: away from the floor's origin
    zup = PTS[:, [0, 2, 1]] * [1, 1, -1]  # z up, ceiling at z = 2.7
    np.testing.assert_allclose(map_up(zup), [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(map_up(zup, up=[0, 0, 2]), [0, 0, 1])
    with pytest.raises(camvlp.InputError, match="up"):
        map_up(zup - [0, 0, 2.7])  # plane through the origin, no normals
    with pytest.raises(camvlp.InputError, match="up"):
        map_up(zup, up=[0, 0, 0])
    with pytest.raises(camvlp.InputError, match="up"):
        map_up(PTS[:2])


def test_tilt_rotation() -> None:
    rng = np.random.default_rng(0)
    for _ in range(20):
        g, up = rng.normal(size=3), rng.normal(size=3)
        r = tilt_rotation(g, up)
        np.testing.assert_allclose(r @ g / np.linalg.norm(g), -up / np.linalg.norm(up), atol=1e-12)
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    for g in ([0, 0, 1], [0, 0, -1]):
        r = tilt_rotation(g, [0, 0, 1])
        np.testing.assert_allclose(r @ g, [0, 0, -1], atol=1e-12)


def test_gravity_far_from_the_photo_is_refused() -> None:
    # four fixtures fix the tilt by themselves: a gravity 8 degrees off (sigma 1) is wrong
    rng = np.random.default_rng(12)
    pose = _random_pose(rng)
    uv = CAMERA.project(pose, PTS)
    res = solve_pose_gravity(uv, PTS, CAMERA, _gravity(pose, 8.0, rng), up=UP, normals=NORMALS)
    assert not res and "degrees from gravity" in res.reason
    ok = solve_pose_gravity(uv, PTS, CAMERA, _gravity(pose, 8.0, rng), up=UP, sigma_deg=2.0)
    assert ok and abs(ok.tilt_disagreement_deg - 8.0) < 1e-6


def test_conventions_worked_example() -> None:
    # docs/conventions.md: theta = (90, 0, 0) has g = (0, 0, -9.81); (100, 0, 0) has
    # g = 9.81 (0, -sin 10, -cos 10)
    for euler, g in (
        ((90, 0, 0), [0, 0, -9.81]),
        ((100, 0, 0), 9.81 * np.array([0, -np.sin(np.radians(10)), -np.cos(np.radians(10))])),
    ):
        r = camvlp.euler_to_matrix(euler)
        assert tilt_error_deg(r, g, UP) < 1e-9
        assert tilt_error_deg(r, -np.asarray(g), UP) > 179.9


def test_per_fixture_centre_sigmas() -> None:
    """A fixture whose centre is 2 px off: weighed as uncertain it barely moves the pose."""
    rng = np.random.default_rng(8)
    pose = _random_pose(rng)
    uv = CAMERA.project(pose, PTS)
    uv[0] += [2.0, -1.0]
    g = _gravity(pose, 0.0, rng)
    errors = []
    for sigma in ([20.0, 0.05, 0.05, 0.05], [0.05, 0.05, 0.05, 0.05]):
        res = solve_pose_gravity(uv, PTS, CAMERA, g, up=UP, pixel_sigma_px=sigma, outlier_px=10)
        assert res and res.n_fixtures == 4
        errors.append(np.linalg.norm(res.pose.position - pose.position))
    assert errors[0] < 0.2 * errors[1]
    for bad in ([1.0, 1.0], [1.0, 1.0, 0.0, 1.0], [np.nan] * 4):
        with pytest.raises(ValueError, match="pixel_sigma_px"):
            solve_pose_gravity(uv, PTS, CAMERA, g, up=UP, pixel_sigma_px=bad)


@pytest.mark.parametrize("n", [2, 3])
def test_the_position_sigma_of_a_gravity_pose_is_its_spread_under_noise(n):
    """``gravity_position_sigma`` against the spread of the positions solved from centres
    and a gravity drawn with the sigmas it is given (each of the gravity's two axes across
    it 1 degree, the centres 0.5 px): within 12 % along each axis (300 draws); and as the
    pipeline works it out, each solve's from its own residuals (scaled up by the fit's
    reduced chi-square when over 1), its median within 20 % of the spread."""
    rng = np.random.default_rng(n)
    camera = Camera.from_focal(1296, 970, 978.0)
    up = np.array([0.0, 0.0, 1.0])
    turn = Rotation.from_euler("zxy", [rng.uniform(0, 360), *rng.uniform(-20, 20, 2)], True)
    pose = Pose(turn.as_matrix(), np.array([0.0, 0.0, 1.3]))
    points = []
    while len(points) < n:  # fixtures in the picture, on a 3.5 m ceiling
        q = np.array([*rng.uniform(-2.5, 2.5, 2), 3.5])
        uv = project_points(camera, pose, q[None])[0]
        if np.all((uv > 50) & (uv < [1246, 920])):
            points.append(q)
    points = np.array(points)
    pixels = project_points(camera, pose, points)
    down = pose.world_from_camera.T @ -up
    across = np.linalg.svd(down[None])[2][1:]  # (two axes across the gravity)
    solved, own = [], []
    for _ in range(300):
        gravity = down + np.radians(1.0) * rng.normal(size=2) @ across
        noisy = pixels + rng.normal(0.0, 0.5, pixels.shape)
        res = solve_pose_gravity(noisy, points, camera, gravity, up=up, pixel_sigma_px=0.5)
        assert res, res.reason
        solved.append(res.pose.position)
        own.append(
            gravity_position_sigma(
                camera,
                res.pose,
                points,
                0.5,
                gravity,
                1.0,
                res.residuals_px,
                res.gravity_residual_deg,
            )
        )
    spread = np.std(solved, axis=0)
    sigma = gravity_position_sigma(camera, pose, points, 0.5, down, 1.0)
    np.testing.assert_allclose(spread, sigma, rtol=0.12)
    np.testing.assert_allclose(np.median(own, axis=0), spread, rtol=0.2)


def test_the_sigma_of_a_pose_with_a_fixture_behind_it_is_not_finite_not_an_error():
    camera = Camera.from_focal(1296, 970, 978.0)
    pose = Pose(np.eye(3), np.zeros(3))  # looking along +z
    points = np.array([[0.2, 0.1, 2.0], [-0.3, 0.2, 2.5], [0.1, -0.2, -1.0]])  # one behind
    sigma = gravity_position_sigma(camera, pose, points, 0.5, [0.0, 1.0, 0.0], 1.0)
    assert sigma.shape == (3,) and np.all(np.isnan(sigma))
    sigma = position_sigma(camera, pose, points, np.zeros(3))
    assert sigma.shape == (3,) and np.all(np.isnan(sigma))
