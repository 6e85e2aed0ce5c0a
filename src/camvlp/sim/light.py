"""A fixture's light before the sensor: its image's coverage and its LED's on-fraction.

The physics shared by :mod:`camvlp.sim.render` (photographs), :mod:`camvlp.sim.video`
(frames of a moving camera) and :mod:`camvlp.sim.bound` (the precision any measurement of
a light could reach): the anti-aliased coverage of a disc's image and where each pixel lies
on the disc's plane, the lamp's look (a hot core, centred or not, and a halo), the random
data an LED that is no beacon sends, and the fraction of each sensor line's exposure window
its LED is on.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from camvlp.model.camera import Camera
from camvlp.model.linecode import manchester_encode
from camvlp.model.readout import Readout

__all__ = [
    "CORE_SIGMA",
    "DATA_BITS",
    "blur_margin",
    "coverage",
    "data_chips",
    "glow_margin",
    "glow_reach",
    "lamp_shape",
    "on_fraction",
    "pixel_box",
    "sensor_lines",
    "shine",
]

#: Sigma of a hot core's Gaussian bump, radii.
CORE_SIGMA = 0.4

#: Random bits an LED sending data repeats: 2 ** 17 Manchester chips, 13 s at 10,000 chips/s,
#: longer than the readout of any photo at 0.1 sensor row a chip or more.
DATA_BITS = 1 << 16


def on_fraction(
    chips: np.ndarray,
    chip_s: float,
    t_start: np.ndarray,
    exposure_s: float,
    off_level: float = 0.0,
) -> np.ndarray:
    """Fraction of each exposure window ``[t, t + exposure]`` the LED is on (its light over
    its full light, for an LED that gives ``off_level`` of it when off).

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
    off_level : float
        Light the LED gives when off, fraction of on (0 to 1).

    Returns
    -------
    ndarray of float64, shape (K,)
        On fractions in [off_level, 1].
    """
    c = np.asarray(chips, dtype=np.float64)
    period = c.size * chip_s
    knots = np.arange(c.size + 1) * chip_s
    cumulative = np.concatenate([[0.0], np.cumsum(c) * chip_s])  # on-time up to each knot

    def on_time(t: np.ndarray) -> np.ndarray:
        cycles = np.floor(t / period)
        return cycles * cumulative[-1] + np.interp(t - cycles * period, knots, cumulative)

    t = np.asarray(t_start, dtype=np.float64)
    on = np.clip((on_time(t + exposure_s) - on_time(t)) / exposure_s, 0.0, 1.0)
    return off_level + (1.0 - off_level) * on if off_level > 0 else on


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
    camera: Camera,
    rotation: np.ndarray,
    position: np.ndarray,
    centre: np.ndarray,
    normal: np.ndarray,
    radius: float,
    box,
    sensor_row: np.ndarray | None = None,
    axes: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Anti-aliased disc coverage over a pixel box, each pixel's distance from the centre
    and, when asked, its place on the disc's plane.

    Each pixel's ray meets the disc's plane; its distance ``rho`` from the centre gives the
    coverage ``clip(0.5 - (rho - radius) / |grad rho|, 0, 1)``, and its offset from the
    centre along two axes in the plane its in-plane coordinates.

    Parameters
    ----------
    camera : Camera
    rotation, position : ndarray
        The camera's world-from-camera rotation (3, 3) and position (3,); or, for a moving
        camera, one per sensor row, (M, 3, 3) and (M, 3), with ``sensor_row`` indexing them.
    centre, normal : ndarray, shape (3,)
        The disc's centre and unit normal, map units.
    radius : float
        The disc's radius, map units.
    box : tuple of int
        Pixel box ``(u0, u1, v0, v1)``, end-exclusive.
    sensor_row : ndarray of int, shape (v1 - v0, u1 - u0), optional
        Each pixel's index into ``rotation`` and ``position`` (a moving camera).
    axes : ndarray, shape (2, 3), optional
        Two orthonormal vectors in the disc's plane (e.g.
        :func:`camvlp.geometry.disc.plane_basis` of ``normal``): with them, each pixel's
        in-plane coordinates are returned too.

    Returns
    -------
    coverage, rho : ndarray of float32, shape (v1 - v0, u1 - u0)
        The coverage in 0..1 and the distance from the centre in radii.
    xy : ndarray of float32, shape (v1 - v0, u1 - u0, 2), or None
        With ``axes``: where each pixel's ray meets the plane, from the centre along the two
        axes, in radii (far away, ``1e3`` radii and more, for a ray that misses the plane);
        else None.
    """
    u0, u1, v0, v1 = box
    uu, vv = np.meshgrid(np.arange(u0, u1, dtype=np.float64), np.arange(v0, v1, dtype=np.float64))
    xy = camera.undistort_pixels(np.stack([uu.ravel(), vv.ravel()], axis=1))
    rays = np.concatenate([xy, np.ones((xy.shape[0], 1))], axis=1)
    if sensor_row is None:
        rays = rays @ rotation.T
        origin = position
    else:
        idx = sensor_row.ravel()
        rays = np.einsum("nij,nj->ni", rotation[idx], rays)
        origin = position[idx]
    denom = rays @ normal
    offset = (centre - origin) @ normal
    with np.errstate(divide="ignore", invalid="ignore"):
        t = offset / denom
    valid = np.isfinite(t) & (t > 0)
    hit = origin + np.where(valid, t, 0.0)[:, None] * rays
    rho = np.linalg.norm(hit - centre, axis=1)
    far = 1e3 * radius + 1e3 * float(np.abs(position - centre).max())
    xy = None
    if axes is not None:
        xy = ((hit - centre) @ np.asarray(axes, dtype=np.float64).T) / radius
        xy = np.where(valid[:, None], xy, far / radius).reshape(*uu.shape, 2).astype(np.float32)
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
    return cov.astype(np.float32), (rho / radius).astype(np.float32), xy


def shine(
    cov: np.ndarray,
    rho: np.ndarray,
    core: float,
    halo: float,
    xy: np.ndarray | None = None,
    core_at: tuple[float, float] = (0.0, 0.0),
) -> np.ndarray:
    """A light's look from its disc coverage and its pixels' places on the disc's plane.

    A hot core: a Gaussian bump of sigma :data:`CORE_SIGMA` (0.4 radius) centred on the
    disc, or at ``core_at``, making its centre ``1 + core`` times as bright as the disc
    without it; a glow outside the rim, ``halo`` times the disc's level just outside it,
    decaying over half a radius (see :class:`camvlp.sim.render.RenderSettings`).

    Parameters
    ----------
    cov, rho : ndarray of float32, shape (h, w)
        The disc's coverage (0..1) and each pixel's distance from its centre, radii
        (:func:`coverage`).
    core, halo : float
        The core's and the glow's strength (0 for none).
    xy : ndarray of float32, shape (h, w, 2), optional
        Each pixel's in-plane coordinates, radii (:func:`coverage` with ``axes``); needed
        for a core off the centre.
    core_at : (float, float)
        The core's centre along the same axes, radii; (0, 0) centres it on the disc.

    Returns
    -------
    ndarray of float32, shape (h, w)
    """
    if core > 0:
        if xy is None or not any(core_at):
            d2 = (rho / np.float32(CORE_SIGMA)) ** 2
        else:
            dx = xy[..., 0] - np.float32(core_at[0])
            dy = xy[..., 1] - np.float32(core_at[1])
            d2 = (dx * dx + dy * dy) / np.float32(CORE_SIGMA**2)
        cov = cov * (1.0 + np.float32(core) * np.exp(-d2))
    if halo > 0:
        glow = np.float32(halo) * np.exp(-np.maximum(rho - 1.0, 0.0) / np.float32(0.5))
        cov = cov + (1.0 - np.minimum(cov, 1.0)) * glow
    return cov


def blur_margin(blur_px: float) -> int:
    """Pixels a light's box needs around its projected rim for the optical blur (sigma
    ``blur_px`` pixels): four sigmas and two pixels."""
    return math.ceil(4.0 * blur_px) + 2


def lamp_shape(
    cov: np.ndarray,
    rho: np.ndarray,
    xy: np.ndarray | None,
    core_at: tuple[float, float],
    *,
    core: float,
    halo: float,
    blur_px: float,
) -> np.ndarray:
    """A lamp's light over its box when fully on, in units of its brightness: its look
    (:func:`shine`, with the same arguments), blurred by the optics (a Gaussian of sigma
    ``blur_px`` pixels, 0 for none; nothing comes in from beyond the box).

    Returns
    -------
    ndarray of float32, shape (h, w)
    """
    shape = shine(cov, rho, core, halo, xy, core_at)
    if blur_px > 0:
        shape = cv2.GaussianBlur(shape, (0, 0), blur_px, borderType=cv2.BORDER_CONSTANT)
    return shape


def sensor_lines(
    box: tuple[int, int, int, int], width: int, height: int, readout: Readout
) -> np.ndarray:
    """The sensor line (in readout order) of each row of a pixel box, or of each column for a
    readout along columns.

    Parameters
    ----------
    box : tuple of int
        ``(u0, u1, v0, v1)``, end-exclusive, pixels.
    width, height : int
        The picture's size, pixels.
    readout : Readout
        The sensor's readout: line 0 is the first image row (column), or the last one for
        a ``-reversed`` readout.

    Returns
    -------
    ndarray of int, shape (v1 - v0,) or (u1 - u0,)
    """
    u0, u1, v0, v1 = box
    k = np.arange(v0, v1) if readout.by_rows else np.arange(u0, u1)
    if readout.reversed:
        k = (height if readout.by_rows else width) - 1 - k
    return k


def data_chips(seed: int, index: int, n_bits: int = DATA_BITS) -> np.ndarray:
    """The chips an LED sending data (no beacon: no ID, no square wave) repeats: Manchester
    chips of ``n_bits`` random bits, drawn from ``default_rng([seed, 4, index])`` (the
    render's seed and the fixture's index in the map).  Returns uint8 of {0, 1}, shape
    (2 n_bits,)."""
    bits = np.random.default_rng([int(seed), 4, int(index)]).integers(0, 2, n_bits, np.uint8)
    return manchester_encode(bits)


def glow_reach(halo: float, brightness: float = 1.0) -> float:
    """How far a light's halo reaches beyond its rim, in radii of its disc: as far as the
    glow (``halo * brightness`` full scale at the rim, decaying over half a radius, see
    :func:`shine`) is brighter than half an 8-bit step; 0 for a glow fainter than that."""
    level = 510.0 * halo * brightness  # the glow at the rim, in half 8-bit steps
    return 0.5 * math.log(level) if level > 1.0 else 0.0


def glow_margin(rim_px: np.ndarray, halo: float, brightness: float = 1.0) -> int:
    """Extra pixels a light's box needs around its projected rim (N, 2) for its halo
    (:func:`glow_reach`).  A box that ended sooner would draw the glow's cut as a straight
    edge, which no camera sees."""
    radii = glow_reach(halo, brightness)
    if radii > 0.0 and np.all(np.isfinite(rim_px)):
        return math.ceil(radii * 0.5 * float(np.ptp(rim_px, axis=0).max()))
    return 0
