"""The coverage study's sweep: what a camera sees of the fixtures from every floor point at
every orientation, whether it gets a fix, and the error of that fix (solved with the usable
fixtures only, by PnP or, for a camera that knows gravity, by the gravity solver).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camvlp.analysis.study.common import (
    Progress,
    StudyInputs,
    observed_pixels,
    position_errors,
)
from camvlp.geometry.gravity import refine_gravity_batch
from camvlp.geometry.projection import project_batch
from camvlp.model.camera import Camera
from camvlp.model.readout import Readout

__all__ = ["KnownGravity", "decodable_in_view", "sweep_poses"]


@dataclass(frozen=True)
class KnownGravity:
    """What a camera that knows gravity changes in the sweep.

    ``up`` (3,) is the map's up (unit), ``sigma_deg`` the accelerometer's error per axis
    (degrees), ``min_fixtures`` the fixtures a fix needs.
    """

    up: np.ndarray
    sigma_deg: float
    min_fixtures: int


def sweep_poses(
    camera: Camera,
    inputs: StudyInputs,
    centres: np.ndarray,
    rots: np.ndarray,
    discs: tuple[np.ndarray, np.ndarray],
    min_rows: float,
    gravity: KnownGravity | None,
    progress: Progress | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every camera centre (G, 3) at every orientation (O, 3, 3): what it sees, and its error.

    ``discs`` are the fixtures' normals (N, 3) and rim points (N, K, 3), metres; with
    ``gravity`` the camera knows which way is down.

    Returns
    -------
    usable : ndarray of int, shape (G, O)
        Fixtures facing the camera, wholly in view and spanning ``min_rows`` rows.
    fix : ndarray of bool, shape (G, O)
        At least four usable fixtures, not all on a line (with gravity: at least
        ``gravity.min_fixtures``, not all on a line along up).
    fix_four : ndarray of bool, shape (G, O)
        At least four usable fixtures, not all on a line (a fix without gravity).
    errors : ndarray, shape (G, O, trials)
        Position error where there is a fix, metres; NaN elsewhere.
    """
    pts = inputs.fixtures_m
    normals, rims = discs
    g, o = centres.shape[0], rots.shape[0]
    usable = np.zeros((g, o), dtype=np.int64)
    fix = np.zeros((g, o), dtype=bool)
    fix_four = np.zeros((g, o), dtype=bool)
    errors = np.full((g, o, inputs.trials), np.nan)
    facing = np.einsum("ni,gni->gn", normals, centres[:, None, :] - pts[None, :, :]) > 0
    if gravity is not None:  # lights on one line along up look like one point from above
        flat = pts - np.outer(pts @ gravity.up, gravity.up)
    for j in range(o):
        ok = facing & decodable_in_view(camera, rots[j], centres, rims, min_rows)
        usable[:, j] = ok.sum(1)
        fix_four[:, j] = (usable[:, j] >= 4) & _not_collinear(pts, ok)
        if gravity is None:
            fix[:, j] = fix_four[:, j]
        else:
            spread = _not_collinear(flat, ok, point=True)
            fix[:, j] = (usable[:, j] >= gravity.min_fixtures) & spread
        errors[:, j] = _fix_errors(camera, inputs, rots[j], centres, ok, fix[:, j], gravity)
        if progress is not None:
            progress(j + 1, o)
    return usable, fix, fix_four, errors


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


def _fix_errors(
    camera: Camera,
    inputs: StudyInputs,
    rot: np.ndarray,
    centres: np.ndarray,
    usable: np.ndarray,
    fix: np.ndarray,
    gravity: KnownGravity | None = None,
) -> np.ndarray:
    """Position errors (G, trials), metres, where there is a fix; NaN elsewhere.

    The positions that share the same set of usable fixtures (``usable``, (G, N)) are
    solved together with those fixtures only; with ``gravity``, by the gravity solver.
    """
    trials = inputs.trials
    out = np.full((centres.shape[0], trials), np.nan)
    idx = np.flatnonzero(fix)
    if idx.size == 0:
        return out
    patterns, inverse = np.unique(usable[idx], axis=0, return_inverse=True)
    for q, pattern in enumerate(patterns):
        members = idx[inverse.reshape(-1) == q]
        cm = np.repeat(centres[members], trials, axis=0)
        rr = np.broadcast_to(rot, (cm.shape[0], 3, 3))
        sub = inputs.fixtures_m[pattern]
        if gravity is None:
            err = position_errors(camera, inputs, rr, cm, fixtures_m=sub)
        else:
            err = _gravity_errors(camera, inputs, sub, rr, cm, gravity)
        out[members] = err.reshape(-1, trials)
    return out


def _gravity_errors(
    camera: Camera,
    inputs: StudyInputs,
    fixtures_m: np.ndarray,
    rots: np.ndarray,
    centres: np.ndarray,
    gravity: KnownGravity,
) -> np.ndarray:
    """Position errors (B,), metres, of the gravity solver for poses ``rots`` (B, 3, 3),
    ``centres`` (B, 3) seeing ``fixtures_m`` (N, 3), with gravity measured with a Gaussian
    error of ``gravity.sigma_deg`` about each of two axes across it."""
    uv = project_batch(camera, rots, centres, fixtures_m, distort=camera.dist_or_none is not None)
    uv = observed_pixels(uv, inputs)
    bearings = camera.undistort_pixels(uv.reshape(-1, 2)).reshape(uv.shape)
    down_cam = np.einsum("bij,i->bj", rots, -gravity.up)
    helper = np.where(np.abs(down_cam[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    a1 = np.cross(down_cam, helper)
    a1 /= np.linalg.norm(a1, axis=1, keepdims=True)
    a2 = np.cross(down_cam, a1)
    t = np.radians(gravity.sigma_deg) * inputs.rng.normal(size=(rots.shape[0], 2))
    measured = down_cam + t[:, :1] * a1 + t[:, 1:] * a2
    _, c_est = refine_gravity_batch(
        rots,
        centres,
        fixtures_m,
        bearings,
        measured,
        gravity.up,
        focal_px=camera.focal_px,
        sigma_deg=gravity.sigma_deg,
    )
    return np.linalg.norm(c_est - centres, axis=1)


def _not_collinear(
    points: np.ndarray, mask: np.ndarray, tol_m: float = 1e-3, *, point: bool = False
) -> np.ndarray:
    """True where the masked points (B, N) of ``points`` (N, 3) do not all lie on one line
    (with ``point``: are not all at one point)."""
    w = mask.astype(float)
    cnt = w.sum(1).clip(1)
    mean = (w @ points) / cnt[:, None]
    d = points[None, :, :] - mean[:, None, :]
    scatter = np.einsum("bn,bni,bnj->bij", w, d, d) / cnt[:, None, None]
    ev = np.linalg.eigvalsh(scatter)  # ascending
    return ev[:, 2 if point else 1] > tol_m**2
