"""A fixture's light before the sensor: its image's coverage and its LED's on-fraction.

The physics shared by :mod:`camvlp.sim.render` (photographs), :mod:`camvlp.sim.video`
(frames of a moving camera) and :mod:`camvlp.sim.bound` (the precision any measurement of
a light could reach): the anti-aliased coverage of a disc's image, and the fraction of each
sensor line's exposure window its LED is on.
"""

from __future__ import annotations

import math

import numpy as np

from camvlp.model.camera import Camera, Pose

__all__ = ["coverage", "on_fraction", "pixel_box"]


def on_fraction(
    chips: np.ndarray, chip_s: float, t_start: np.ndarray, exposure_s: float
) -> np.ndarray:
    """Fraction of each exposure window ``[t, t + exposure]`` the LED is on.

    Parameters
    ----------
    chips : ndarray of {0, 1}, shape (N,)
        One period of the LED's chips (1 = on), each ``chip_s`` seconds long.
    chip_s : float
        Chip duration, s.
    t_start : ndarray, shape (K,)
        Window starts, s, in the LED's own time (chip 0 starts at 0).
    exposure_s : float
        Window length, s.

    Returns
    -------
    ndarray of float64, shape (K,)
        On fractions in [0, 1].
    """
    c = np.asarray(chips, dtype=np.float64)
    period = c.size * chip_s
    knots = np.arange(c.size + 1) * chip_s
    cumulative = np.concatenate([[0.0], np.cumsum(c) * chip_s])  # on-time up to each knot

    def on_time(t: np.ndarray) -> np.ndarray:
        cycles = np.floor(t / period)
        return cycles * cumulative[-1] + np.interp(t - cycles * period, knots, cumulative)

    t = np.asarray(t_start, dtype=np.float64)
    return np.clip((on_time(t + exposure_s) - on_time(t)) / exposure_s, 0.0, 1.0)


def pixel_box(rim_px: np.ndarray, width: int, height: int, margin: int):
    """Pixel bounding box (u0, u1, v0, v1), end-exclusive, of a projected rim; None if empty."""
    if np.all(np.isfinite(rim_px)):
        u0 = math.floor(rim_px[:, 0].min()) - margin
        u1 = math.ceil(rim_px[:, 0].max()) + margin + 1
        v0 = math.floor(rim_px[:, 1].min()) - margin
        v1 = math.ceil(rim_px[:, 1].max()) + margin + 1
    else:  # the disc crosses the camera's plane: search the whole image
        u0, u1, v0, v1 = 0, width, 0, height
    u0, v0 = max(u0, 0), max(v0, 0)
    u1, v1 = min(u1, width), min(v1, height)
    if u1 <= u0 or v1 <= v0:
        return None
    return u0, u1, v0, v1


def coverage(
    camera: Camera, pose: Pose, centre: np.ndarray, normal: np.ndarray, radius: float, box
) -> tuple[np.ndarray, np.ndarray]:
    """Anti-aliased disc coverage over a pixel box, float32 shape (v1 - v0, u1 - u0), and
    each pixel's distance from the centre on the disc's plane in radii (same shape)."""
    u0, u1, v0, v1 = box
    uu, vv = np.meshgrid(np.arange(u0, u1, dtype=np.float64), np.arange(v0, v1, dtype=np.float64))
    xy = camera.undistort_pixels(np.stack([uu.ravel(), vv.ravel()], axis=1))
    rays = np.concatenate([xy, np.ones((xy.shape[0], 1))], axis=1) @ pose.world_from_camera.T
    denom = rays @ normal
    offset = (centre - pose.position) @ normal
    with np.errstate(divide="ignore", invalid="ignore"):
        t = offset / denom
    valid = np.isfinite(t) & (t > 0)
    hit = pose.position + np.where(valid, t, 0.0)[:, None] * rays
    rho = np.linalg.norm(hit - centre, axis=1)
    far = 1e3 * radius + 1e3 * float(np.abs(pose.position - centre).max())
    rho = np.where(valid, rho, far).reshape(uu.shape)
    if rho.shape[0] > 1 and rho.shape[1] > 1:
        gv, gu = np.gradient(rho)
        scale = np.hypot(gu, gv)
    elif rho.size > 1:
        scale = np.abs(np.gradient(rho.ravel())).reshape(rho.shape)
    else:
        scale = np.full(rho.shape, radius)
    scale = np.maximum(scale, 1e-12 * radius)
    cov = np.clip(0.5 - (rho - radius) / scale, 0.0, 1.0)
    cov[~valid.reshape(uu.shape)] = 0.0
    return cov.astype(np.float32), (rho / radius).astype(np.float32)
