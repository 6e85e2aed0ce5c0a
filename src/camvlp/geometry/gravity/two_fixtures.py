"""Two fixtures and gravity: the camera's pose in closed form (both solutions), and the ray
lengths it gives many pairs of fixtures seen along the same two rays at once."""

from __future__ import annotations

import numpy as np

from camvlp.geometry.gravity.tilt import check_gravity, tilt_rotation
from camvlp.model.camera import Pose, rotation_from_vector

__all__ = ["pair_ray_lengths", "solve_two_fixtures"]

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


def _leveled(bearings, gravity, up):
    """The two lights' unit rays (camera frame), the unit up, the tilt's rotation, the world
    basis (e1, e2, up) as columns, and the rays leveled in that basis (rows)."""
    rays = _rays(np.asarray(bearings, float).reshape(2, -1))
    g = check_gravity(gravity)
    u = np.asarray(up, float) / np.linalg.norm(up)
    r0 = tilt_rotation(g, u)
    w = _basis(u)
    v = (r0 @ rays.T).T @ w  # leveled rays in (e1, e2, up) coordinates
    return rays, u, r0, w, v


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
    x = np.asarray(points, float).reshape(2, 3)
    rays, u, r0, w, v = _leveled(bearings, gravity, up)
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


def pair_ray_lengths(bearings, deltas, gravity, up) -> np.ndarray:
    """How far along two rays each of many pairs of fixtures lies, with the measured tilt:
    :func:`solve_two_fixtures`' closed form for every pair at once, its poses left out.

    Two rays and gravity fix the camera's tilt; a pair of fixtures ``delta`` apart then lies
    on the rays at two lengths (or none) that fit its height difference and horizontal
    distance: the pair's candidates for the two lights, told apart from others before any
    pose is solved.

    Parameters
    ----------
    bearings : array_like, shape (2, 2) or (2, 3)
        The two lights' undistorted normalised image coordinates ``(x, y)`` (or rays
        ``(x, y, z)``), camera frame.
    deltas : array_like, shape (q, 3)
        Each pair's first fixture's position minus its second's, map units.
    gravity : array_like, shape (3,)
        Gravity in the camera frame, any length.
    up : array_like, shape (3,)
        The map's up, world frame.

    Returns
    -------
    ndarray, shape (q, 2, 2)
        Per pair, per solution (the larger root first), the lengths of the first and second
        ray (unit rays), map units; NaN where there is none (no solution, a pair on a line
        along gravity, rays that leave the lengths undetermined).  Negative lengths are
        fixtures behind the camera: the caller checks.
    """
    d = np.asarray(deltas, float).reshape(-1, 3)
    _, _, _, w, v = _leveled(bearings, gravity, up)
    out = np.full((d.shape[0], 2, 2), np.nan)
    a = np.array([v[0, 2], -v[1, 2]])  # lambda1 a1 - lambda2 a2 = dz
    m = np.column_stack([v[0, :2], -v[1, :2]])  # horizontal of lambda1 v1 - lambda2 v2
    aa = float(a @ a)
    if aa < 1e-18:
        return out
    nvec = np.array([-a[1], a[0]]) / np.sqrt(aa)
    mn, ma = m @ nvec, m @ a / aa
    qa = float(mn @ mn)
    if qa < 1e-12:
        return out
    local = d @ w
    dz, dh2 = local[:, 2], np.einsum("ij,ij->i", local[:, :2], local[:, :2])
    sep2 = dh2 + dz * dz
    qb, qc = dz * float(ma @ mn), dz * dz * float(ma @ ma) - dh2
    disc = qb * qb - qa * qc
    ok = (dh2 > (_VERTICAL_LINE_TOL**2) * sep2) & (disc >= -1e-6 * (qb * qb + np.abs(qa * qc)))
    root = np.sqrt(np.maximum(disc, 0.0))
    t = (-qb[:, None] + np.array([1.0, -1.0]) * root[:, None]) / qa  # (q, 2)
    lam = (dz / aa)[:, None, None] * a + t[..., None] * nvec
    out[ok] = lam[ok]
    return out
