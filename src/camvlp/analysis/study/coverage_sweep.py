"""The coverage study's sweep: what a camera sees of the fixtures from every floor point at
every orientation, whether it gets a fix, and the error of that fix (solved with the usable
fixtures only, by PnP or, for a camera that knows gravity, by the gravity solver).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from camvlp.analysis.study.common import (
    Progress,
    StudyInputs,
    observed_pixels,
    position_errors,
)
from camvlp.geometry.gravity import refine_gravity_batch
from camvlp.geometry.projection import decodable_in_view, in_view, project_batch
from camvlp.model.camera import Camera, Pose

__all__ = ["POINTS_AT_ONCE", "KnownGravity", "decodable_reach", "sweep_poses"]


@dataclass(frozen=True)
class KnownGravity:
    """What a camera that knows gravity changes in the sweep.

    ``up`` (3,) is the map's up (unit), ``sigma_deg`` the accelerometer's error per axis
    (degrees), ``min_fixtures`` the fixtures a fix needs.
    """

    up: np.ndarray
    sigma_deg: float
    min_fixtures: int


#: Projected rim points (camera centres x fixtures x rim points) a sweep works on at once:
#: a larger study (a site's floor and fixtures) is swept a block of centres at a time, each
#: against the fixtures that can be decodable from it (:func:`decodable_reach`).
POINTS_AT_ONCE = 4_000_000


def sweep_poses(
    camera: Camera,
    inputs: StudyInputs,
    centres: np.ndarray,
    rots: np.ndarray,
    discs: tuple[np.ndarray, np.ndarray],
    min_rows: float,
    gravity: KnownGravity | None,
    progress: Progress | None,
    told_apart: Callable[[np.ndarray], bool] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every camera centre (G, 3) at every orientation (O, 3, 3): what it sees, and its error.

    ``discs`` are the fixtures' normals (N, 3) and rim points (N, K, 3), metres; with
    ``gravity`` the camera knows which way is down.  ``told_apart``, given the indices of
    the fixtures a pose with a fix sees, says whether they tell where it is (a site whose
    IDs repeat: :func:`~camvlp.analysis.study.site_views.ambiguous_views`); a pose they do not
    has no fix.  Centres are swept in blocks of :data:`POINTS_AT_ONCE` projected points.

    Returns
    -------
    usable : ndarray of int, shape (G, O)
        Fixtures facing the camera, wholly in view and spanning ``min_rows`` rows.
    fix : ndarray of bool, shape (G, O)
        At least four usable fixtures, not all on a line (with gravity: at least
        ``gravity.min_fixtures``, not all on a line along up), told apart.
    fix_four : ndarray of bool, shape (G, O)
        At least four usable fixtures, not all on a line (a fix without gravity).
    errors : ndarray, shape (G, O, trials)
        Position error where there is a fix, metres; NaN elsewhere.
    untold : ndarray of bool, shape (G, O)
        Poses with fixtures enough for a fix that ``told_apart`` refused.
    """
    g, o = centres.shape[0], rots.shape[0]
    untold = np.zeros((g, o), dtype=bool)
    usable = np.zeros((g, o), dtype=np.int64)
    fix = np.zeros((g, o), dtype=bool)
    fix_four = np.zeros((g, o), dtype=bool)
    errors = np.full((g, o, inputs.trials), np.nan)
    n, k = discs[1].shape[:2]
    cells = _cells(camera, centres, discs[1], min_rows)
    for j in range(o):
        for rows, cols in _blocks(camera, rots[j], g, n, k, cells):
            sub = dataclasses.replace(inputs, fixtures_m=inputs.fixtures_m[cols])
            seen = (discs[0][cols], discs[1][cols])
            got = _sweep_block(camera, sub, centres[rows], rots[j], seen, min_rows, gravity)
            usable[rows, j], fix[rows, j], fix_four[rows, j], ok = got
            if told_apart is not None:
                for i in np.flatnonzero(fix[rows, j]):
                    fix[rows[i], j] = told_apart(cols[ok[i]])
                    untold[rows[i], j] = not fix[rows[i], j]
            errors[rows, j] = _fix_errors(
                camera, sub, rots[j], centres[rows], ok, fix[rows, j], gravity
            )
        if progress is not None:
            progress(j + 1, o)
    return usable, fix, fix_four, errors, untold


def _sweep_block(
    camera: Camera,
    inputs: StudyInputs,
    centres: np.ndarray,
    rot: np.ndarray,
    discs: tuple[np.ndarray, np.ndarray],
    min_rows: float,
    gravity: KnownGravity | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`sweep_poses` for centres (B, 3) at one orientation against the fixtures of
    ``inputs`` (M of them): usable counts (B,), fix and fix without gravity (B,), and which
    fixtures each centre can use (B, M)."""
    pts = inputs.fixtures_m
    normals, rims = discs
    facing = np.einsum("ni,gni->gn", normals, centres[:, None, :] - pts[None, :, :]) > 0
    ok = facing & decodable_in_view(camera, rot, centres, rims, min_rows)
    usable = ok.sum(1)
    four = (usable >= 4) & _not_collinear(pts, ok)
    if gravity is None:
        return usable, four, four, ok
    # lights on one line along up look like one point from above
    flat = pts - np.outer(pts @ gravity.up, gravity.up)
    fix = (usable >= gravity.min_fixtures) & _not_collinear(flat, ok, point=True)
    return usable, fix, four, ok


def decodable_reach(camera: Camera, diameter_m: float, min_rows: float) -> float:
    """The farthest a disc of ``diameter_m`` can be from the camera and still span
    ``min_rows`` rows anywhere in its picture, metres (inf for ``min_rows`` 0).

    A small disc ``d`` at a distance ``D`` spans at most ``f d (1 + r ** 2) / D`` pixels,
    ``r`` the picture's largest normalised radius (its corners, undistorted): the
    magnification grows off the axis as ``1 + tan ** 2`` of the angle.  A tenth more and a
    diameter are added for discs that are not small.
    """
    if not min_rows > 0:
        return float("inf")
    w, h = camera.width - 1.0, camera.height - 1.0
    corners = np.array([[0.0, 0.0], [w, 0.0], [0.0, h], [w, h], [w / 2, 0.0], [0.0, h / 2]])
    r2 = float(np.max(np.sum(camera.undistort_pixels(corners) ** 2, axis=1)))
    f = float(np.max(np.diag(camera.matrix)[:2]))
    return 1.1 * f * diameter_m * (1.0 + r2) / min_rows + diameter_m


class _Cells(NamedTuple):
    """The camera centres of a large sweep in cubes (:func:`_cells`), and what in each does
    not depend on the orientation."""

    members: list[np.ndarray]  # per cube, its centres' indices
    middle: np.ndarray  # (C, 3): each cube's middle, metres
    half: np.ndarray  # (C,): its half-diagonal, metres
    near: np.ndarray  # (C, N): the fixtures within decodable_reach of it
    discs: np.ndarray  # (N, 3): the discs' centres
    radius: float  # the largest disc's radius, metres


def _cells(camera: Camera, centres: np.ndarray, rims: np.ndarray, min_rows: float) -> _Cells | None:
    """The camera centres (G, 3) in cubes of about 16 (a floor grid's 4 x 4), each with the
    fixtures (rims (N, K, 3)) within :func:`decodable_reach` of it, for a sweep too large for
    :data:`POINTS_AT_ONCE`; None when it is not."""
    g, n, k = centres.shape[0], rims.shape[0], rims.shape[1]
    if g * n * k <= POINTS_AT_ONCE:
        return None
    extent = np.sort(np.ptp(centres, axis=0))[::-1]
    if extent[1] > 0:  # a floor: 16 grid cells of its area
        side = 4.0 * float(np.sqrt(extent[0] * extent[1] / g))
    else:  # a line, or one point
        side = 16.0 * float(extent[0]) / g if extent[0] > 0 else 1.0
    _, cell_of = np.unique(np.floor(centres / side), axis=0, return_inverse=True)
    cell_of = cell_of.reshape(-1)
    members = [np.flatnonzero(cell_of == c) for c in range(int(cell_of.max()) + 1)]
    lo = np.array([centres[m].min(axis=0) for m in members])
    hi = np.array([centres[m].max(axis=0) for m in members])
    middle, half = 0.5 * (lo + hi), 0.5 * np.linalg.norm(hi - lo, axis=1)
    discs = rims.mean(axis=1)
    radius = float(np.max(np.linalg.norm(rims - discs[:, None, :], axis=2)))
    reach = decodable_reach(camera, 2.0 * radius, min_rows)
    gap = np.linalg.norm(discs[None, :, :] - middle[:, None, :], axis=2)
    return _Cells(members, middle, half, gap <= reach + half[:, None], discs, radius)


def _blocks(
    camera: Camera, rot: np.ndarray, g: int, n: int, k: int, cells: _Cells | None
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The sweep's blocks at one orientation ``rot`` (world from camera) of ``g`` centres
    against ``n`` fixtures of ``k`` rim points: (centres' indices, fixtures' indices)
    pairs.  All against all when ``cells`` is None; else each cube of centres against the
    fixtures it may see (within :func:`decodable_reach` and
    :func:`~camvlp.geometry.projection.in_view` of the cube's middle, widened by its
    half-diagonal), as many centres a block as :data:`POINTS_AT_ONCE` allows."""
    everything = np.arange(n)
    if cells is None:
        return [(np.arange(g), everything)]
    out = []
    for c, members in enumerate(cells.members):
        pose = Pose(rot, cells.middle[c])
        view = in_view(camera, pose, cells.discs, np.full(n, cells.radius + cells.half[c]), 1.0)
        cols = everything[cells.near[c] & view]
        if not cols.size:  # nothing in view from this cube: no fixture usable, no fix
            continue
        per = max(1, POINTS_AT_ONCE // (cols.size * k))
        out += [(members[i : i + per], cols) for i in range(0, members.size, per)]
    return out


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
