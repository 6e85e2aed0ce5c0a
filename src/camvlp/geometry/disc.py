"""The geometry of a fixture's disc: its plane, its rim, and where its image's centre lies.

Used by the simulator (to draw discs), the locator (to correct a detected ellipse's centre to
the projected centre of its disc) and the coverage study (to test whether a disc is in view).
"""

from __future__ import annotations

import cv2
import numpy as np

from camvlp.model.camera import Camera, Pose

__all__ = ["disc_normals", "perspective_offset", "plane_basis", "rim_points"]


def plane_basis(normals) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors spanning the plane of each normal.

    Parameters
    ----------
    normals : array_like, shape (N, 3) or (3,)
        Plane normals (need not be unit length, must not be zero).

    Returns
    -------
    a, b : ndarray, shape like ``normals``
        Orthonormal, both perpendicular to the normal, ``b = n x a`` (right-handed).
    """
    n = np.asarray(normals, dtype=float)
    flat = n.ndim == 1
    n = np.atleast_2d(n)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    helper = np.eye(3)[np.argmin(np.abs(n), axis=1)]  # the axis least aligned with n
    a = np.cross(n, helper)
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b = np.cross(n, a)
    return (a[0], b[0]) if flat else (a, b)


def rim_points(centres, diameters, normals, n_rim: int) -> np.ndarray:
    """Points on each disc's rim.

    Parameters
    ----------
    centres : array_like, shape (N, 3)
        Disc centres (any length unit).
    diameters : array_like, shape (N,)
        Disc diameters, same unit.
    normals : array_like, shape (N, 3)
        Disc normals.
    n_rim : int
        Points per rim, evenly spaced in angle.

    Returns
    -------
    ndarray, shape (N, n_rim, 3)
    """
    c = np.asarray(centres, dtype=float).reshape(-1, 3)
    d = np.asarray(diameters, dtype=float).reshape(-1)
    a, b = plane_basis(np.asarray(normals, dtype=float).reshape(-1, 3))
    t = 2 * np.pi * np.arange(int(n_rim)) / int(n_rim)
    r = 0.5 * d[:, None, None]
    return c[:, None, :] + r * (
        np.cos(t)[None, :, None] * a[:, None, :] + np.sin(t)[None, :, None] * b[:, None, :]
    )


def disc_normals(centres, normals, toward) -> np.ndarray:
    """Unit normal of each disc, facing the point ``toward``.

    A normal given in ``normals`` is kept as it is (a disc can face away: the camera is then
    behind it).  Rows of NaN (unknown) take the normal of the plane through all the centres
    when they lie on one (three or more, not on a line), signed to face ``toward``; otherwise the
    direction from the disc to ``toward`` (a disc that faces the camera).

    Parameters
    ----------
    centres : array_like, shape (N, 3)
        Disc centres.
    normals : array_like, shape (N, 3), or None
        Known normals, NaN rows where unknown; None when none is known.
    toward : array_like, shape (3,)
        The camera's centre, same frame.

    Returns
    -------
    ndarray, shape (N, 3)
        Unit normals.
    """
    c = np.asarray(centres, dtype=float).reshape(-1, 3)
    cam = np.asarray(toward, dtype=float).reshape(3)
    out = np.full_like(c, np.nan) if normals is None else np.array(normals, float).reshape(-1, 3)
    known = np.all(np.isfinite(out), axis=1)
    out[known] /= np.linalg.norm(out[known], axis=1, keepdims=True)
    if np.all(known):
        return out
    to_cam = cam - c
    plane = None
    if c.shape[0] >= 3:
        _, s, vt = np.linalg.svd(c - c.mean(axis=0))
        # a plane: not all on a line, and every centre on it (within 1 % of the spread)
        if s[1] > 1e-9 * max(s[0], 1e-300) and s[2] <= 0.01 * s[0]:
            plane = vt[2]
    if plane is not None:
        sign = np.where(to_cam @ plane >= 0, 1.0, -1.0)
        out[~known] = sign[~known, None] * plane
    else:
        dist = np.linalg.norm(to_cam, axis=1, keepdims=True)
        facing = np.divide(to_cam, dist, out=np.tile([0.0, 0.0, 1.0], (len(c), 1)), where=dist > 0)
        out[~known] = facing[~known]
    return out


def perspective_offset(camera: Camera, pose: Pose, centre, diameter: float, normal) -> np.ndarray:
    """Offset of a disc's image (an ellipse) centre from its centre's projection, pixels.

    Under perspective the centre of a circle's image is not the image of its centre; the
    locator subtracts this offset from each detected centre before the final solve.

    Parameters
    ----------
    camera, pose : Camera, Pose
        The camera and its pose in the map frame.
    centre : array_like, shape (3,)
        The disc's centre, map units.
    diameter : float
        Its diameter, map units.
    normal : array_like, shape (3,)
        Its normal.

    Returns
    -------
    ndarray, shape (2,)
        ``ellipse centre - projected centre``, pixels; zeros when the rim is not all in front.
    """
    c = np.asarray(centre, dtype=float).reshape(1, 3)
    rim = rim_points(c, [diameter], np.asarray(normal, float).reshape(1, 3), 72)[0]
    uv = camera.project(pose, np.vstack([c, rim]))
    if not np.all(np.isfinite(uv)):
        return np.zeros(2)
    (cx, cy), _, _ = cv2.fitEllipse(uv[1:].astype(np.float32))
    return np.array([cx, cy]) - uv[0]
