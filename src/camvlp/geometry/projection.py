"""Projection of many points for many poses at once, without OpenCV's per-call cost: one
pose per batch row (:func:`project_batch`), or one pose per point for a camera moving at
constant rates (:func:`project_moving`, a rolling shutter's rows).

Frames follow the package conventions (:mod:`camvlp.model.camera`): a pose is
``world_from_camera`` ``R`` (camera axes as columns) and the camera centre ``C``; a world
point ``X`` is at ``R^T (X - C)`` in camera coordinates.  The lens model is OpenCV's, up to
12 distortion coefficients (no tilted sensor).
"""

from __future__ import annotations

import numpy as np

from camvlp.model.camera import Camera, Pose, in_front
from camvlp.model.readout import Readout

__all__ = ["decodable_in_view", "in_view", "project_batch", "project_moving"]


def _distort(x: np.ndarray, y: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV's lens model on normalised coordinates (up to 12 coefficients)."""
    c = np.zeros(12)
    c[: d.size] = d
    k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = c
    r2 = x * x + y * y
    radial = (1 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1 + r2 * (k4 + r2 * (k5 + r2 * k6)))
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) + r2 * (s1 + s2 * r2)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y + r2 * (s3 + s4 * r2)
    return xd, yd


def project_batch(camera: Camera, R, C, points, *, distort: bool = False) -> np.ndarray:
    """Project the same world points for many camera poses at once.

    Pinhole projection ``K R^T (X - C)``; lens distortion is ignored unless ``distort`` is
    set (the error study uses a distortion-free camera, as the thesis does).  The image
    plane is infinite: points outside the sensor still get coordinates.

    Parameters
    ----------
    camera : Camera
        Intrinsics (and distortion, with ``distort=True``; up to 12 coefficients).
    R : array_like, shape (B, 3, 3) or (3, 3)
        ``world_from_camera`` rotations (camera axes as columns).
    C : array_like, shape (B, 3) or (3,)
        Camera centres, world coordinates (map units).
    points : array_like, shape (N, 3)
        World points (map units).
    distort : bool
        Apply the camera's OpenCV distortion model.

    Returns
    -------
    ndarray, shape (B, N, 2)
        Pixel coordinates ``[u, v]``; NaN for points on or behind the camera plane.

    Raises
    ------
    ValueError
        Bad shapes, or ``distort`` with a 14-coefficient (tilted sensor) model.
    """
    r = np.asarray(R, dtype=np.float64)
    c = np.asarray(C, dtype=np.float64)
    if r.ndim == 2:
        r = r[None]
    if c.ndim == 1:
        c = c[None]
    if r.ndim != 3 or r.shape[1:] != (3, 3):
        raise ValueError(f"R must have shape (B, 3, 3), got {np.shape(R)}")
    if c.ndim != 2 or c.shape[1] != 3:
        raise ValueError(f"C must have shape (B, 3), got {np.shape(C)}")
    if r.shape[0] != c.shape[0]:
        raise ValueError(f"R has {r.shape[0]} poses but C has {c.shape[0]}")
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {p.shape}")
    # camera coordinates: X_c = R^T (X - C), for every pose and point
    xc = np.einsum("bji,bnj->bni", r, p[None, :, :] - c[:, None, :])
    z = xc[..., 2]
    on_plane = ~in_front(xc)  # (within float64 rounding of the camera's plane: not imaged)
    with np.errstate(divide="ignore", invalid="ignore"):
        z_safe = np.where(on_plane, np.nan, z)
        x = xc[..., 0] / z_safe
        y = xc[..., 1] / z_safe
    if distort and camera.distortion.size and np.any(camera.distortion):
        if camera.distortion.size > 12:
            raise ValueError("project_batch supports at most 12 distortion coefficients")
        x, y = _distort(x, y, camera.distortion)
    k = camera.matrix
    u = k[0, 0] * x + k[0, 1] * y + k[0, 2]
    v = k[1, 1] * y + k[1, 2]
    return np.stack([u, v], axis=-1)


def _euler_matrices(euler_deg: np.ndarray) -> np.ndarray:
    """``Rx Ry Rz`` for many sets of the thesis' angles: (N, 3) degrees -> (N, 3, 3).

    The product written out element by element (no per-axis matrices): the tracker projects
    a few points from a few poses many times a frame, where building and multiplying the
    three matrices cost more than the projection."""
    a = np.deg2rad(np.asarray(euler_deg, dtype=np.float64).reshape(-1, 3))
    (cx, cy, cz), (sx, sy, sz) = np.cos(a).T, np.sin(a).T
    out = np.empty((a.shape[0], 3, 3))
    out[:, 0, 0], out[:, 0, 1], out[:, 0, 2] = cy * cz, -cy * sz, sy
    sx_sy, cx_sy = sx * sy, cx * sy
    out[:, 1, 0], out[:, 1, 1], out[:, 1, 2] = cx * sz + sx_sy * cz, cx * cz - sx_sy * sz, -sx * cy
    out[:, 2, 0], out[:, 2, 1], out[:, 2, 2] = sx * sz - cx_sy * cz, sx * cz + cx_sy * sz, cx * cy
    return out


def project_moving(camera: Camera, values, rates, points, dt_s) -> np.ndarray:
    """Project points, each seen from the pose the camera has at its own time.

    The pose at time ``dt`` is ``values + dt * rates`` in (camera centre, thesis angles):
    a camera moving at constant velocity, as a rolling shutter sees it row by row.

    Parameters
    ----------
    camera : Camera
        Intrinsics and distortion (up to 12 coefficients).
    values : array_like, shape (6,) or (B, 6)
        ``(x, y, z, theta_x, theta_y, theta_z)`` at ``dt = 0``, map units and degrees; or B
        such poses at once.
    rates : array_like, shape (6,) or (B, 6)
        Their rates, per s.
    points : array_like, shape (N, 3)
        World points, map units.
    dt_s : array_like, shape (N,)
        Each point's time, s.

    Returns
    -------
    ndarray, shape (N, 2) or (B, N, 2)
        Pixels; NaN for points behind the camera.
    """
    v = np.asarray(values, dtype=np.float64)
    single = v.ndim == 1
    v = v.reshape(-1, 6)
    r = np.broadcast_to(np.asarray(rates, dtype=np.float64).reshape(-1, 6), v.shape)
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    dt = np.asarray(dt_s, dtype=np.float64).reshape(1, -1, 1)
    pose = v[:, None, :] + dt * r[:, None, :]  # (B, N, 6)
    b, n = pose.shape[:2]
    rot = _euler_matrices(pose[..., 3:].reshape(-1, 3)).reshape(b, n, 3, 3)
    xc = np.einsum("bnji,bnj->bni", rot, p[None] - pose[..., :3])
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(xc[..., 2] > 0, xc[..., 2], np.nan)
        x, y = xc[..., 0] / z, xc[..., 1] / z
    if camera.distortion.size and np.any(camera.distortion):
        x, y = _distort(x, y, camera.distortion)
    k = camera.matrix
    uv = np.stack([k[0, 0] * x + k[0, 1] * y + k[0, 2], k[1, 1] * y + k[1, 2]], axis=-1)
    return uv[0] if single else uv


def in_view(camera: Camera, pose: Pose, centres, reach, margin_px: float = 0.0) -> np.ndarray:
    """Whether anything within ``reach`` of each point can show in the picture: the sphere
    about it meets the camera's view (the pyramid through the picture's border, pixels
    ``margin_px`` beyond it).  Conservative: a sphere that meets the pyramid may still show
    nothing, one outside it never shows.

    Parameters
    ----------
    camera : Camera
    pose : Pose
        The camera's pose, map frame and units.
    centres : array_like, shape (N, 3)
        The points (a disc's centre), map units.
    reach : array_like, shape (N,)
        Each sphere's radius (a disc's radius and its glow's reach), map units.
    margin_px : float
        Pixels beyond the border that still count (a blur's reach).

    Returns
    -------
    ndarray of bool, shape (N,)
    """
    p = pose.to_camera(np.asarray(centres, dtype=float).reshape(-1, 3))
    r = np.asarray(reach, dtype=float).reshape(-1)
    w, h = camera.width - 1.0, camera.height - 1.0
    t = np.linspace(0.0, 1.0, 33)
    zero, one = np.zeros_like(t), np.ones_like(t)
    border = np.concatenate(
        [
            np.stack(side, axis=1)
            for side in ((t * w, zero), (w * one, t * h), (t * w, h * one), (zero, t * h))
        ]
    )
    xy = camera.undistort_pixels(border)
    pad = margin_px / np.array([camera.matrix[0, 0], camera.matrix[1, 1]])
    lo, hi = xy.min(axis=0) - pad, xy.max(axis=0) + pad
    seen = np.ones(p.shape[0], dtype=bool)
    for k in range(2):  # the pyramid's sides: lo z <= x <= hi z, the same for y
        seen &= (p[:, k] - hi[k] * p[:, 2]) <= r * np.hypot(1.0, hi[k])
        seen &= (lo[k] * p[:, 2] - p[:, k]) <= r * np.hypot(1.0, lo[k])
    return seen


def decodable_in_view(
    camera: Camera, rot: np.ndarray, centres: np.ndarray, rims: np.ndarray, min_rows: float
) -> np.ndarray:
    """Which fixtures (G, N) have their whole rim in the image and span ``min_rows`` rows.

    ``rot`` (3, 3) is the orientation shared by the camera centres (G, 3); ``rims``
    (N, K, 3) are the fixtures' rim points, metres.  Rows are counted along the camera's
    readout axis.
    """
    g, n = centres.shape[0], rims.shape[0]
    read_axis = (camera.readout or Readout.ROWS).pixel_index
    distort = camera.dist_or_none is not None
    rr = np.broadcast_to(rot, (g, 3, 3))
    uv = project_batch(camera, rr, centres, rims.reshape(-1, 3), distort=distort)
    uv = uv.reshape(g, n, -1, 2)
    w, h = camera.width, camera.height
    with np.errstate(invalid="ignore"):
        inside = np.all(
            (uv[..., 0] >= -0.5)
            & (uv[..., 0] <= w - 0.5)
            & (uv[..., 1] >= -0.5)
            & (uv[..., 1] <= h - 0.5),
            axis=2,
        )
        span = np.ptp(uv[..., read_axis], axis=2)
        return inside & (span >= min_rows)
