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

import numpy as np

from camvlp.geometry.pose_sigma import pose_jacobian
from camvlp.model.camera import (
    Camera,
    Pose,
    project_points,
)
from camvlp.model.fixtures import FixtureMap

__all__ = [
    "HYPOTHESES",
    "SPREAD_SIGMAS",
    "TOLD_APART",
    "Spread",
    "assigned_by_pose",
    "told_by_pose",
]

#: A candidate ID is taken when its map position projects within the fixture's tolerance
#: (the pose's outlier distance, or more with a :class:`Spread`) and every other candidate's
#: farther than this many times that tolerance.
TOLD_APART = 4.0

#: A :class:`Spread`'s tolerance: this many standard deviations of the distance between a
#: fixture's centre and its map position projected by the pose.
SPREAD_SIGMAS = 3.0


@dataclass(frozen=True)
class Spread:
    """What the pose and each fixture's centre are unsure of (for :func:`told_by_pose`).

    Attributes
    ----------
    pose_cov : ndarray, shape (6, 6)
        The pose's covariance (:func:`~camvlp.geometry.pose_sigma.pose_covariance`): a
        rotation of the camera about its own axes (radians), then its centre (map units), as
        :func:`~camvlp.geometry.pose_sigma.pose_jacobian` takes them.
    centre_sigma_px : ndarray, shape (n,)
        Each fixture's centre uncertainty, pixels (1-sigma per axis; 0 when unknown).
    radius_px : ndarray, shape (n,)
        Each fixture's smaller radius in the photo, pixels: the tolerance never exceeds half
        of it (no other fixture's centre can lie within a disc of the ceiling).
    """

    pose_cov: np.ndarray
    centre_sigma_px: np.ndarray
    radius_px: np.ndarray


def _tolerance(
    camera: Camera, pose: Pose, where: np.ndarray, k: int, spread: Spread | None, outlier_px: float
) -> float:
    """Fixture ``k``'s tolerance for the map point ``where`` (shape (3,)), pixels: the
    outlier distance, or with ``spread`` :data:`SPREAD_SIGMAS` standard deviations of the
    distance (its centre's and the projection's) when that is more, up to half its radius."""
    if spread is None:
        return outlier_px
    jac = pose_jacobian(camera, pose, where[None])[0]
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
