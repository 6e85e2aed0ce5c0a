"""Look-alike IDs told apart by the pose.

Where the stripes cannot say an ID (at an exposure of a whole chip a single dark chip between
bright ones leaves no trace, and IDs whose frames differ only there read alike), the model
fit refuses the fixture and lists the IDs of the map that fit it almost equally
(:attr:`camvlp.pipeline.decode.result.StripeDecode.candidates`).  Once the pose is solved from
the fixtures that were decoded, each of those IDs' map positions projects to one place in the
photo: the fixture is the one that projects onto it, when exactly one does and every other
projects far away.  The stripes narrow the fixture to a few IDs and the geometry picks one;
neither alone would.  "Onto it" allows for what the pose and the fixture's centre are unsure
of (:class:`Spread`): a pose solved from a few fixtures on one side of the photo projects
points on the other side tens of pixels off, and a glowing lamp whose stripes say little is
often centred 10 to 30 px off too; but never farther than half the disc's radius, within
which no other fixture of the ceiling can be centred.

When the fixtures the stripes identified are too few for a pose, the pose comes from the
look-alikes themselves (:func:`assigned_by_pose`): every way of giving a few of them one of
their candidates is a hypothesis, solved and checked against the others.  An assignment is
taken when the fixtures it explains are more than a pose needs and no assignment that
contradicts it explains as many.  A fixture whose stripes fit no ID (or only look-alikes the
pose does not tell) still explains a pose where exactly one fixture of the map the
assignment left free projects onto it (:func:`_witnessed`); it witnesses the pose and is
given no ID (the geometry alone never names a fixture).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from camvlp.geometry.disc import CENTRE_SIGMA_FLOOR_PX
from camvlp.model.camera import (
    Camera,
    Pose,
    in_front,
    project_camera_points,
    project_points,
)
from camvlp.model.fixtures import FixtureMap

__all__ = [
    "HYPOTHESES",
    "SPREAD_SIGMAS",
    "TOLD_APART",
    "Spread",
    "assigned_by_pose",
    "pose_covariance",
    "position_sigma",
    "told_by_pose",
]

#: A candidate ID is taken when its map position projects within the fixture's tolerance
#: (the pose's outlier distance, or more with a :class:`Spread`) and every other candidate's
#: farther than this many times that tolerance.
TOLD_APART = 4.0

#: A :class:`Spread`'s tolerance: this many standard deviations of the distance between a
#: fixture's centre and its map position projected by the pose.
SPREAD_SIGMAS = 3.0

#: Steps of the numerical Jacobian of a projection: radians, and map units per unit of the
#: camera's distance to the points.
_STEP = 1e-6


@dataclass(frozen=True)
class Spread:
    """What the pose and each fixture's centre are unsure of (for :func:`told_by_pose`).

    Attributes
    ----------
    pose_cov : ndarray, shape (6, 6)
        The pose's covariance (:func:`pose_covariance`): a rotation of the camera about its
        own axes (radians), then its centre (map units), as :func:`_jacobian` takes them.
    centre_sigma_px : ndarray, shape (n,)
        Each fixture's centre uncertainty, pixels (1-sigma per axis; 0 when unknown).
    radius_px : ndarray, shape (n,)
        Each fixture's smaller radius in the photo, pixels: the tolerance never exceeds half
        of it (no other fixture's centre can lie within a disc of the ceiling).
    """

    pose_cov: np.ndarray
    centre_sigma_px: np.ndarray
    radius_px: np.ndarray


def _jacobian(camera: Camera, pose: Pose, points: np.ndarray) -> np.ndarray:
    """The projections' derivatives by the pose's six parameters, shape (m, 2, 6), pixels
    per radian and per map unit (central differences): a turn of the camera about its own
    axes (radians), then a move of its centre (map units).  The twelve moved poses' points
    are projected at once."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    r, c = pose.world_from_camera, pose.position
    scale = max(float(np.median(np.linalg.norm(points - c, axis=1))), 1e-9)
    steps = np.concatenate([np.full(3, _STEP), np.full(3, _STEP * scale)])
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

    Gauss-Newton's ``s^2 (J^T J)^-1``, ``J`` the projections' Jacobian (:func:`_jacobian`)
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
    jac = _jacobian(camera, pose, points).reshape(-1, 6)
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


def _tolerance(
    camera: Camera, pose: Pose, where: np.ndarray, k: int, spread: Spread | None, outlier_px: float
) -> float:
    """Fixture ``k``'s tolerance for the map point ``where`` (shape (3,)), pixels: the
    outlier distance, or with ``spread`` :data:`SPREAD_SIGMAS` standard deviations of the
    distance (its centre's and the projection's) when that is more, up to half its radius."""
    if spread is None:
        return outlier_px
    jac = _jacobian(camera, pose, where[None])[0]
    var_p = float(np.trace(jac @ spread.pose_cov @ jac.T)) / 2
    sigma_c = float(spread.centre_sigma_px[k])
    sigma = np.sqrt(max(var_p, 0.0) + (sigma_c**2 if np.isfinite(sigma_c) else 0.0))
    cap = 0.5 * float(spread.radius_px[k])
    return max(outlier_px, min(SPREAD_SIGMAS * sigma, cap))


#: The most hypotheses :func:`assigned_by_pose` solves (each one a pose).
HYPOTHESES = 300


def told_by_pose(
    camera: Camera,
    pose: Pose,
    fixture_map: FixtureMap,
    pixels: np.ndarray,
    candidates: list[tuple[int, ...]],
    taken: set[int],
    outlier_px: float,
    spread: Spread | None = None,
) -> dict[int, int]:
    """The IDs the pose tells apart among each fixture's look-alikes.

    Parameters
    ----------
    camera : Camera
        The camera (intrinsics and distortion).
    pose : Pose
        The camera's pose, solved from the decoded fixtures.
    fixture_map : FixtureMap
        The map the candidates' positions come from.
    pixels : ndarray, shape (n, 2)
        Each fixture's centre in the photo, pixels (the frame the pose was solved in).
    candidates : list of tuple of int, length n
        Each fixture's candidate IDs (empty or one: nothing to tell apart).
    taken : set of int
        IDs already given to a fixture (a map's IDs are unique: none of them is a candidate).
    outlier_px : float
        The pose's outlier distance, pixels: the tolerance of "projects onto the fixture".
    spread : Spread, optional
        The pose's and the centres' uncertainty: the tolerance grows to
        :data:`SPREAD_SIGMAS` standard deviations of each fixture's distance (up to half its
        radius) when that is more than ``outlier_px``.

    Returns
    -------
    dict
        Fixture index -> the ID whose map position alone projects onto it, for the fixtures
        told apart (each ID at most once).
    """
    told: dict[int, int] = {}
    for k, ids in enumerate(candidates):
        ids = tuple(i for i in ids if fixture_map.get(i) is not None)
        if len(ids) < 2:
            continue
        where = project_points(camera, pose, [fixture_map.get(i).position for i in ids])
        dist = np.hypot(*(where - np.asarray(pixels[k], dtype=float)).T)
        dist = np.where(np.isfinite(dist), dist, np.inf)  # behind the camera: not there
        order = np.argsort(dist)
        best = ids[int(order[0])]
        if best in taken or not np.isfinite(dist[order[0]]):
            continue
        position = np.asarray(fixture_map.get(best).position, dtype=float)
        tol = _tolerance(camera, pose, position, k, spread, outlier_px)
        if dist[order[0]] <= tol and dist[order[1]] > TOLD_APART * tol:
            told[k] = best
    # an ID told for two fixtures: neither
    seen = list(told.values())
    return {k: i for k, i in told.items() if seen.count(i) == 1}


def _hypotheses(
    fixed: dict[int, int], candidates: list[tuple[int, ...]], needed: int, spare: int = 0
) -> list[dict[int, int]]:
    """Seeds of :func:`assigned_by_pose`: the fixed IDs and one candidate each for as many
    ambiguous fixtures as a pose needs besides (fewest candidates first), no ID twice; every
    way for a set of fixtures or none of them (so that an assignment and those that
    contradict it on those fixtures are all tried), at most :data:`HYPOTHESES` in all.
    ``spare`` fixtures besides the ambiguous ones may witness a pose."""
    free = [k for k, c in enumerate(candidates) if len(c) >= 2 and k not in fixed]
    free.sort(key=lambda k: len(candidates[k]))
    m = needed - len(fixed)
    out: list[dict[int, int]] = []
    if m <= 0 or len(free) < m or len(free) + spare <= m:  # a fixture beyond the seeds
        return out  # must confirm them
    used = set(fixed.values())
    for seeds in itertools.combinations(free, m):
        ways = [
            {**fixed, **dict(zip(seeds, ids, strict=True))}
            for ids in itertools.product(*(candidates[k] for k in seeds))
            if len(set(ids)) == m and not used.intersection(ids)
        ]
        if len(out) + len(ways) > HYPOTHESES:
            return out
        out += ways
    return out


def assigned_by_pose(
    camera: Camera,
    fixture_map: FixtureMap,
    pixels: np.ndarray,
    fixed: dict[int, int],
    candidates: list[tuple[int, ...]],
    outlier_px: float,
    pose_of: Callable[[dict[int, int]], Pose | None],
    needed: int = 4,
    witnesses: Sequence[bool] | None = None,
) -> dict[int, int]:
    """IDs for look-alike fixtures when those the stripes identified are too few for a pose.

    Each hypothesis gives as many ambiguous fixtures as the pose needs besides the identified
    ones (``fixed``) one of their candidates; ``pose_of`` solves it, and the other
    fixtures are told by that pose (:func:`told_by_pose`; a seed must be told as it was
    guessed).  The assignment that explains the most fixtures is returned when it explains
    more than ``needed`` and no assignment that gives a fixture another ID explains more
    than ``needed``; otherwise nothing (the photo is ambiguous, not located).

    Parameters
    ----------
    camera, fixture_map, pixels, candidates, outlier_px
        As in :func:`told_by_pose` (``pixels`` shape (n, 2), ``candidates`` length n).
    fixed : dict
        Fixture index -> ID, the fixtures the stripes identified (fewer than ``needed``).
    pose_of : callable
        Fixture index -> ID assignment -> the pose that every one of them fits, or None.
    needed : int
        Fixtures a pose needs (4; 2 with gravity).
    witnesses : sequence of bool, length n, optional
        The fixtures that may witness a pose (:func:`_witnessed`) when the stripes told
        nothing of them, or only look-alikes the pose does not tell: fixtures whose stripes
        fit no ID, not cut by the border.  None: no fixture does.

    Returns
    -------
    dict
        Fixture index -> ID for the look-alike fixtures assigned (empty when none).
    """
    found: dict[frozenset, int] = {}  # assignment -> the most fixtures it explains
    taken = set(fixed.values())
    may = [False] * len(candidates) if witnesses is None else [bool(w) for w in witnesses]
    spare = sum(w and k not in fixed and len(candidates[k]) < 2 for k, w in enumerate(may))
    for seed in _hypotheses(fixed, candidates, needed, spare):
        pose = pose_of(seed)
        if pose is None:
            continue
        told = told_by_pose(camera, pose, fixture_map, pixels, candidates, taken, outlier_px)
        if all(told.get(k) == i for k, i in seed.items() if k not in fixed):
            seen = [w and k not in fixed and k not in told for k, w in enumerate(may)]
            n = len(told) + _witnessed(
                camera, pose, fixture_map, pixels, seen, taken | set(told.values()), outlier_px
            )
            key = frozenset(told.items())
            found[key] = max(found.get(key, 0), n)
    if not found:
        return {}
    best = max(found, key=lambda a: (found[a], len(a)))
    if found[best] + len(fixed) <= needed:
        return {}
    given = dict(best)
    by_id = {i: k for k, i in best}
    for other, n in found.items():
        contradicts = any(given.get(k, i) != i or by_id.get(i, k) != k for k, i in other)
        if contradicts and n + len(fixed) > needed:
            return {}
    return given


def _witnessed(
    camera: Camera,
    pose: Pose,
    fixture_map: FixtureMap,
    pixels: np.ndarray,
    seen: Sequence[bool],
    taken: set[int],
    outlier_px: float,
) -> int:
    """How many of the fixtures ``seen`` flags lie where ``pose`` projects a fixture of the
    map not ``taken``: within ``outlier_px`` of it, every other fixture of the map projecting
    farther than :data:`TOLD_APART` times that, each such ID onto one fixture at most.
    Fixtures whose stripes say nothing of their ID still lie where the map has a fixture, and
    so witness the pose without being given an ID."""
    k = np.flatnonzero(np.asarray(seen, dtype=bool))
    if k.size == 0 or len(fixture_map.fixtures) < 2:
        return 0
    ids = np.array([f.id for f in fixture_map.fixtures])
    where = project_points(camera, pose, [f.position for f in fixture_map.fixtures])
    dist = np.hypot(*(where[None, :, :] - np.asarray(pixels, dtype=float)[k, None, :]).T).T
    dist = np.where(np.isfinite(dist), dist, np.inf)  # (K, M); behind the camera: not there
    two = np.sort(dist, axis=1)[:, :2]
    near = ids[np.argmin(dist, axis=1)]
    free = ~np.isin(near, list(taken))
    ok = free & (two[:, 0] <= outlier_px) & (two[:, 1] > TOLD_APART * outlier_px)
    count = np.unique(near[ok], return_counts=True)[1]
    return int(np.sum(count == 1))
