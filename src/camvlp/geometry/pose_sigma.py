"""How sure a solved pose is: the projections' Jacobian by the pose's six parameters, the
pose's covariance from its fixtures' reprojection errors, and the camera position's standard
deviation along the map's axes."""

from __future__ import annotations

import cv2
import numpy as np

from camvlp.geometry.disc import CENTRE_SIGMA_FLOOR_PX
from camvlp.model.camera import Camera, Pose, in_front, project_camera_points, project_points

__all__ = [
    "JACOBIAN_STEP",
    "gravity_position_sigma",
    "pose_covariance",
    "pose_jacobian",
    "position_sigma",
]

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
    return s2 * _inverse(jac.T @ jac)


def _inverse(info: np.ndarray) -> np.ndarray:
    """The pseudo-inverse of an information matrix (6, 6); NaN where it is not finite (a
    fixture behind the camera has no projection), which SVD does not take."""
    if not np.all(np.isfinite(info)):
        return np.full(info.shape, np.nan)
    return np.linalg.pinv(info)


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


def gravity_position_sigma(
    camera: Camera,
    pose: Pose,
    points: np.ndarray,
    pixel_sigma_px,
    gravity,
    sigma_deg: float,
    residuals_px=None,
    gravity_residual_deg: float = 0.0,
) -> np.ndarray:
    """How sure a pose solved with gravity is (:func:`~camvlp.geometry.gravity.
    solve_pose_gravity`): the standard deviation of the camera centre along the map's x, y
    and z, map units, shape (3,).

    The covariance of the solver's own least squares: the fixtures' projections weighed by
    their centres' sigmas (:func:`pose_jacobian`), and the gravity's direction by
    ``sigma_deg``, which holds the camera's tilt (two of its three turns: the heading is the
    fixtures' alone).  From two fixtures the six unknowns are exactly determined, and their
    spread is what the centres' and the gravity's sigmas make of it; with more, scaled up by
    the fit's reduced chi-square when it is over 1 (the fixtures miss by more than their
    sigmas say).

    Parameters
    ----------
    camera, pose
        The camera and the solved pose.
    points : ndarray, shape (m, 3)
        The map positions of the fixtures the pose uses (m >= 2).
    pixel_sigma_px : float or ndarray, shape (m,)
        Their centres' sigmas, pixels (each at least
        :data:`~camvlp.geometry.disc.CENTRE_SIGMA_FLOOR_PX`).
    gravity : array_like, shape (3,)
        The measured gravity in the camera's frame, any length.
    sigma_deg : float
        The gravity's direction's sigma, degrees.
    residuals_px : ndarray, shape (m,), optional
        The fixtures' reprojection errors with the pose, pixels (for the chi-square).
    gravity_residual_deg : float
        The angle between the pose's down and the gravity, degrees (for the chi-square).
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    m = points.shape[0]
    sigma_px = np.maximum(np.broadcast_to(pixel_sigma_px, (m,)), CENTRE_SIGMA_FLOOR_PX)
    jac = (pose_jacobian(camera, pose, points) / sigma_px[:, None, None]).reshape(-1, 6)
    # a turn e of the camera about its axes moves the down it sees, d, by d x e
    d = np.asarray(gravity, dtype=float) / np.linalg.norm(gravity)
    turn = np.zeros((3, 6))
    turn[:, :3] = np.array([[0, -d[2], d[1]], [d[2], 0, -d[0]], [-d[1], d[0], 0]])
    turn /= np.radians(sigma_deg)
    scale, dof = 1.0, 2 * m + 2 - 6
    if residuals_px is not None and dof > 0:
        r = np.asarray(residuals_px, dtype=float) / sigma_px
        chi2 = float(r @ r) + (gravity_residual_deg / sigma_deg) ** 2
        scale = max(chi2 / dof, 1.0)
    cov = scale * _inverse(jac.T @ jac + turn.T @ turn)
    return np.sqrt(np.maximum(np.diag(cov)[3:], 0.0))
