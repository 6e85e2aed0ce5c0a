"""Two fixtures and gravity: the camera's pose in closed form (both solutions)."""

from __future__ import annotations

import numpy as np

from camvlp.geometry.gravity.tilt import check_gravity, tilt_rotation
from camvlp.model.camera import Pose, rotation_from_vector

__all__ = ["solve_two_fixtures"]

# Two fixtures are taken to lie on a line along gravity when the horizontal part of their
# separation is below this fraction of the whole.
_VERTICAL_LINE_TOL = 1e-3


def _rays(bearings: np.ndarray) -> np.ndarray:
    """Unit rays (N, 3) of bearings (N, 2) (normalised image coordinates) or rays (N, 3)."""
    b = np.column_stack([bearings, np.ones(len(bearings))]) if bearings.shape[1] == 2 else bearings
    return b / np.linalg.norm(b, axis=1, keepdims=True)


def _basis(up: np.ndarray) -> np.ndarray:
    """Columns e1, e2, up: a right-handed world basis with up as its third axis."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(helper, up)
    e1 /= np.linalg.norm(e1)
    return np.column_stack([e1, np.cross(up, e1), up])


def _about_up(up: np.ndarray, psi: float) -> np.ndarray:
    return rotation_from_vector(psi * up)


def solve_two_fixtures(bearings, points, gravity, up) -> tuple[list[Pose], str]:
    """Both poses that put two fixtures on their bearing rays with the measured tilt.

    Parameters
    ----------
    bearings : array_like, shape (2, 2) or (2, 3)
        Undistorted normalised image coordinates ``(x, y)`` (or rays ``(x, y, z)``) of the
        two fixtures, camera frame.
    points : array_like, shape (2, 3)
        Their map positions, map units.
    gravity : array_like, shape (3,)
        Gravity in the camera frame, any length.
    up : array_like, shape (3,)
        The map's up, world frame.

    Returns
    -------
    poses : list of Pose
        Zero, one or two poses, each with ``R @ gravity`` along ``-up``; the rays may point
        away from a fixture (behind the camera): the caller checks.
    reason : str
        Why there are none ("" otherwise).
    """
    rays = _rays(np.asarray(bearings, float).reshape(2, -1))
    x = np.asarray(points, float).reshape(2, 3)
    g = check_gravity(gravity)
    u = np.asarray(up, float) / np.linalg.norm(up)
    r0 = tilt_rotation(g, u)
    w = _basis(u)
    v = (r0 @ rays.T).T @ w  # leveled rays in (e1, e2, up) coordinates
    delta = (x[0] - x[1]) @ w
    sep = float(np.linalg.norm(delta))
    if sep == 0:
        return [], "the two fixtures are at the same place"
    dh = delta[:2]
    if np.linalg.norm(dh) <= _VERTICAL_LINE_TOL * sep:
        return [], (
            "the two fixtures are on a line along gravity: the heading is not determined "
            "(a third fixture is needed)"
        )
    a = np.array([v[0, 2], -v[1, 2]])  # lambda1 a1 - lambda2 a2 = dz
    if np.linalg.norm(a) < 1e-9:
        return [], "both fixtures are on the camera's horizon: their distances are not determined"
    l0 = a * delta[2] / (a @ a)
    nvec = np.array([-a[1], a[0]]) / np.linalg.norm(a)
    m = np.column_stack([v[0, :2], -v[1, :2]])  # horizontal of lambda1 v1 - lambda2 v2
    mn, ml = m @ nvec, m @ l0
    qa, qb, qc = mn @ mn, ml @ mn, ml @ ml - dh @ dh
    if qa < 1e-12:
        return [], "the two fixtures are seen in the same direction: the pose is not determined"
    disc = qb * qb - qa * qc
    if disc < 0:
        # measurement noise near a double root: keep it when it is within the noise
        if disc < -1e-6 * (qb * qb + abs(qa * qc)):
            return [], "no pose puts both fixtures on their rays with this gravity"
        disc = 0.0
    roots = {(-qb + np.sqrt(disc)) / qa, (-qb - np.sqrt(disc)) / qa}
    poses = []
    for t in sorted(roots):
        lam = l0 + t * nvec
        wh = m @ lam
        psi = float(np.arctan2(wh[0] * dh[1] - wh[1] * dh[0], wh @ dh))
        rot = _about_up(u, psi) @ r0
        centre = x[0] - lam[0] * (rot @ rays[0])
        poses.append(Pose(rot, centre))
    return poses, ""
