"""Look-alike IDs told apart by the pose.

Where the stripes cannot say an ID (at an exposure of a whole chip a single dark chip between
bright ones leaves no trace, and IDs whose frames differ only there read alike), the model
fit refuses the fixture and lists the IDs of the map that fit it almost equally
(:attr:`camvlp.pipeline.model_decode.ModelDecode.candidates`).  Once the pose is solved from
the fixtures that were decoded, each of those IDs' map positions projects to one place in the
photo: the fixture is the one that projects onto it, when exactly one does and every other
projects far away.  The stripes narrow the fixture to a few IDs and the geometry picks one;
neither alone would.

When the fixtures the stripes identified are too few for a pose, the pose comes from the
look-alikes themselves (:func:`assigned_by_pose`): every way of giving a few of them one of
their candidates is a hypothesis, solved and checked against the others.  An assignment is
taken when the fixtures it explains are more than a pose needs and no assignment that
contradicts it explains as many.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable

import numpy as np

from camvlp.model.camera import Camera, Pose, project_points
from camvlp.model.fixtures import FixtureMap

__all__ = ["HYPOTHESES", "TOLD_APART", "assigned_by_pose", "told_by_pose"]

#: A candidate ID is taken when its map position projects within the pose's outlier distance
#: of the fixture and every other candidate's farther than this many times that distance.
TOLD_APART = 4.0

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
        The pose's outlier distance, pixels.

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
        if (
            best not in taken
            and dist[order[0]] <= outlier_px
            and dist[order[1]] > TOLD_APART * outlier_px
        ):
            told[k] = best
    # an ID told for two fixtures: neither
    seen = list(told.values())
    return {k: i for k, i in told.items() if seen.count(i) == 1}


def _hypotheses(
    fixed: dict[int, int], candidates: list[tuple[int, ...]], needed: int
) -> list[dict[int, int]]:
    """Seeds of :func:`assigned_by_pose`: the fixed IDs and one candidate each for as many
    ambiguous fixtures as a pose needs besides (fewest candidates first), no ID twice; every
    way for a set of fixtures or none of them (so that an assignment and those that
    contradict it on those fixtures are all tried), at most :data:`HYPOTHESES` in all."""
    free = [k for k, c in enumerate(candidates) if len(c) >= 2 and k not in fixed]
    free.sort(key=lambda k: len(candidates[k]))
    m = needed - len(fixed)
    out: list[dict[int, int]] = []
    if m <= 0 or len(free) <= m:  # a fixture beyond the seeds must confirm them
        return out
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

    Returns
    -------
    dict
        Fixture index -> ID for the look-alike fixtures assigned (empty when none).
    """
    found: set[frozenset] = set()
    taken = set(fixed.values())
    for seed in _hypotheses(fixed, candidates, needed):
        pose = pose_of(seed)
        if pose is None:
            continue
        told = told_by_pose(camera, pose, fixture_map, pixels, candidates, taken, outlier_px)
        if all(told.get(k) == i for k, i in seed.items() if k not in fixed):
            found.add(frozenset(told.items()))
    if not found:
        return {}
    best = max(found, key=len)
    if len(best) + len(fixed) <= needed:
        return {}
    given = dict(best)
    by_id = {i: k for k, i in best}
    for other in found:
        contradicts = any(given.get(k, i) != i or by_id.get(i, k) != k for k, i in other)
        if contradicts and len(other) + len(fixed) > needed:
            return {}
    return given
