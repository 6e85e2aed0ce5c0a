"""Tests of the prior-aided pose fit and of projection from a moving camera."""

from __future__ import annotations

import numpy as np
import pytest

from camvlp.geometry.pose_prior import refine_pose
from camvlp.geometry.projection import project_moving
from camvlp.model.camera import Camera, Pose

CAM = Camera.from_focal(1920, 1080, 1450.0, distortion=[0.05, -0.02, 0.0, 0.0, 0.0])
POINTS = np.array([[0.8, -2.7, 0.6], [0.8, -2.7, -0.6], [-0.8, -2.7, -0.6], [-0.8, -2.7, 0.6]])
TRUE = np.array([0.1, -0.2, 0.05, 91.0, -1.5, 20.0])


def test_project_moving_matches_the_camera_model():
    pose = Pose.from_euler(TRUE[:3], TRUE[3:])
    still = project_moving(CAM, TRUE, np.ones(6), POINTS, np.zeros(4))
    assert np.allclose(still, CAM.project(pose, POINTS), atol=1e-9)
    rates = np.array([1.0, 0.0, 0.5, 10.0, 0.0, -5.0])
    dt = np.array([0.0, 0.01, -0.01, 0.02])
    moved = project_moving(CAM, TRUE, rates, POINTS, dt)
    for k in range(4):
        at = TRUE + dt[k] * rates
        expect = CAM.project(Pose.from_euler(at[:3], at[3:]), POINTS[k : k + 1])[0]
        assert np.allclose(moved[k], expect, atol=1e-9)


def test_four_points_and_a_loose_prior_give_the_pose():
    pixels = project_moving(CAM, TRUE, np.zeros(6), POINTS, np.zeros(4))
    fit = refine_pose(
        POINTS,
        pixels,
        CAM,
        TRUE[:3] + 0.2,
        TRUE[3:] + 3.0,
        sigma_position=1.0,
        sigma_euler_deg=30.0,
        sigma_px=0.5,
    )
    assert fit is not None
    assert np.allclose(fit.values, TRUE, atol=1e-4)
    assert fit.reprojection_rms_px < 1e-3


def test_two_points_and_a_tight_tilt_prior_pin_the_position():
    # two fixtures alone leave the camera free to slide along a tilt; a prior on the angles
    # (here exact) and a loose one on the position bring it back to the truth
    pixels = project_moving(CAM, TRUE, np.zeros(6), POINTS[:2], np.zeros(2))
    start = TRUE + np.array([0.03, -0.02, 0.04, 0.0, 0.0, 0.0])
    fit = refine_pose(
        POINTS[:2],
        pixels,
        CAM,
        start[:3],
        start[3:],
        sigma_position=[0.1, 0.1, 0.1],
        sigma_euler_deg=[1e-3, 1e-3, 1.0],
    )
    assert np.linalg.norm(fit.values[:3] - TRUE[:3]) < 1e-3
    assert fit.jacobian_px.shape == (4, 6)


def test_rolling_shutter_with_known_rates_removes_the_bias():
    # each point seen 12 ms before or after the pose's time, the camera at 1 m/s
    rates = np.array([1.0, 0.0, 0.3, 5.0, -3.0, 2.0])
    dt = np.array([-0.012, -0.004, 0.004, 0.012])
    pixels = project_moving(CAM, TRUE, rates, POINTS, dt)
    kw = {"sigma_position": 1.0, "sigma_euler_deg": 20.0}
    aware = refine_pose(
        POINTS,
        pixels,
        CAM,
        TRUE[:3] + 0.01,
        TRUE[3:] + 0.3,
        **kw,
        dt_s=dt,
        prior_rates=rates,
        sigma_rates=np.full(6, 1e-6),
    )
    assert np.allclose(aware.values, TRUE, atol=1e-4)
    assert aware.jacobian_px.shape == (8, 12)
    naive = refine_pose(POINTS, pixels, CAM, TRUE[:3] + 0.01, TRUE[3:] + 0.3, **kw)
    assert np.linalg.norm(naive.values[:3] - TRUE[:3]) > 0.005


def test_bad_arguments():
    with pytest.raises(ValueError, match="same number"):
        refine_pose(POINTS, np.zeros((3, 2)), CAM, TRUE[:3], TRUE[3:])
    with pytest.raises(ValueError, match="needs prior_rates"):
        refine_pose(POINTS, np.zeros((4, 2)), CAM, TRUE[:3], TRUE[3:], dt_s=np.zeros(4))
