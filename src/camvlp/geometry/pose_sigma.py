"""How sure a solved pose is: the projections' Jacobian by the pose's six parameters, the
pose's covariance from its fixtures' reprojection errors, and the camera position's standard
deviation along the map's axes."""

from __future__ import annotations

import cv2
import numpy as np

from camvlp.geometry.disc import CENTRE_SIGMA_FLOOR_PX
from camvlp.model.camera import Camera, Pose, in_front, project_camera_points, project_points

__all__ = ["JACOBIAN_STEP", "pose_covariance", "pose_jacobian", "position_sigma"]

#: Steps of the numerical Jacobian of a projection: radians, and map units per unit of the
#: camera's distance to the points.
JACOBIAN_STEP = 1e-6


def pose_jacobian(camera: Camera, pose: Pose, points: np.ndarray) -> np.ndarray:
    """The projections' derivatives by the pose's six parameters, shape (m, 2, 6), pixels
    per radian and per map unit (central differences): a turn of the camera about its own
    axes (radians), then a move of its centre (map units).  The twelve moved poses' points
    are projected at once."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    r, c = pose.world_from_camera, pose.position
    scale = max(float(np.median(np.linalg.norm(points - c, axis=1))), 1e-9)
    steps = np.concatenate([np.full(3, JACOBIAN_STEP), np.full(3, JACOBIAN_STEP * scale)])
    rel = points - c
    cams = []
    for sign in (1.0, -1.0):
        for j in range(3):  # turned: R @ Rodrigues(step)
            e = np.zeros((3, 1))
            e[j] = sign * steps[j]
            cams.append(rel @ (r @ cv2.Rodrigues(e)[0]))
        for j in range(3):  # moved
            e = np.zeros(3)
            e[j] = sign * steps[3 + j]
            cams.append((points - (c + e)) @ r)
    cam = np.concatenate(cams)
    uv = project_camera_points(camera, cam)
    uv[~in_front(cam)] = np.nan
    plus, minus = uv.reshape(2, 6, -1, 2)
    return ((plus - minus) / (2 * steps)[:, None, None]).transpose(1, 2, 0)


def pose_covariance(
    camera: Camera, pose: Pose, points: np.ndarray, pixels: np.ndarray
) -> np.ndarray:
    """The covariance of a pose solved from these fixtures, shape (6, 6).

    Gauss-Newton's ``s^2 (J^T J)^-1``, ``J`` the projections' Jacobian (:func:`pose_jacobian`)
    and ``s^2`` the residuals' variance per coordinate over the degrees of freedom left (at
    least 1 px^2; a pose that fits its fixtures exactly is not known better than that).

    Parameters
    ----------
    camera, pose
        The camera and the solved pose.
    points : ndarray, shape (m, 3)
        The map positions the pose was solved from (m >= 3).
    pixels : ndarray, shape (m, 2)
        Their centres in the photo, pixels.
    """
    res = np.asarray(pixels, dtype=float).reshape(-1, 2) - project_points(camera, pose, points)
    return _covariance(camera, pose, points, float(np.sum(res**2)), 1.0)


def _covariance(
    camera: Camera, pose: Pose, points: np.ndarray, squares_px2: float, floor_px2: float
) -> np.ndarray:
    """:func:`pose_covariance` from the residuals' sum of squares (pixels squared), with
    ``floor_px2`` the least variance per coordinate (pixels squared)."""
    jac = pose_jacobian(camera, pose, points).reshape(-1, 6)
    s2 = max(squares_px2 / max(jac.shape[0] - 6, 1), floor_px2)
    return s2 * np.linalg.pinv(jac.T @ jac)


def position_sigma(
    camera: Camera, pose: Pose, points: np.ndarray, residuals_px: np.ndarray
) -> np.ndarray:
    """How sure a pose's position is: the standard deviation of the camera centre along the
    map's x, y and z, map units, shape (3,).

    From :func:`pose_covariance` with the residuals' variance per coordinate over the
    degrees of freedom left (2 m - 6: a rough figure from four fixtures, whose two are
    little to judge by), at least :data:`~camvlp.geometry.disc.CENTRE_SIGMA_FLOOR_PX`
    squared: the position is as unsure as the fixtures' fit says, times what their layout
    makes of a pixel (four fixtures on a narrow band of the photo leave a tilt and a shift
    almost alike: tens of millimetres a pixel at 2 m).

    Parameters
    ----------
    camera, pose
        The camera and the solved pose.
    points : ndarray, shape (m, 3)
        The map positions of the fixtures the pose uses (m >= 4).
    residuals_px : ndarray, shape (m,)
        Their reprojection errors with the pose, pixels.
    """
    r = np.asarray(residuals_px, dtype=float)
    cov = _covariance(camera, pose, points, float(r @ r), CENTRE_SIGMA_FLOOR_PX**2)
    return np.sqrt(np.maximum(np.diag(cov)[3:], 0.0))
