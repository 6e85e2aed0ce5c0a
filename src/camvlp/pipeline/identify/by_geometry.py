"""Fixtures told apart by their geometry, in a map whose IDs repeat (``FixtureMap.reuse``).

A site of thousands of fixtures with the thesis' 4-bit frame gives each ID to hundreds of
them: an ID read says which fixtures a light may be, not which one.  A photo shows several
lights and where they are in the picture, and only a few places of the site show those IDs
in that arrangement.  :func:`placed` finds them:

1. *Candidates*: each light whose stripes gave an ID may be any fixture of the map with it
   (within the prior's radius of its centre, when a prior ``near``/``within`` is given).
2. *Distances*: a disc's size in the photo says how far its fixture is
   (:func:`~camvlp.pipeline.identify.placement.disc_distances`, within the factors of
   :data:`DISTANCE_SLACK`, or of :data:`~camvlp.pipeline.identify.placement.PLAIN_SLACK`
   where every light of the photo was told plain), and the angle between two lights' rays
   then bounds the distance between their fixtures.
   Four seed lights' candidates are combined only where every pair's distance lies within
   those bounds at one scale common to the photo's lights (:data:`RELATIVE_SLACK`): the
   search starts from the light whose candidates make the fewest such pairs and adds the
   others nearest it first (:func:`_search_order`), each next one's fixtures paired with
   the first's by k-d trees within their greatest distance.
3. *Verification*: each combination is a hypothesis.  Those a rigid motion cannot explain
   (:func:`~camvlp.geometry.hypotheses.rigid_on_plane`: four fixtures on a plane and their
   rays are related by a homography whose first two columns are a rotation's) are dropped
   together; each one left is solved by PnP and stands when the four fixtures reproject
   within the outlier distance, in front of the camera and seen from the side they face.
   Its pose then tells the other lights (:func:`_explained`): a light is explained when one
   fixture of the map with its ID projects within the outlier distance of it and every
   other with that ID :data:`~camvlp.pipeline.identify.by_pose.TOLD_APART` times farther.
4. *Decision*: the correspondence (light -> fixture) that explains the most lights is taken
   when it explains more lights than a pose needs (a light beyond the seeds confirms them)
   and no correspondence that contradicts it explains as many, or one fewer.  Otherwise the
   photo is refused, its reason listing the places that fit (a wrong place is the worst
   answer: refused rather than guessed).

The place found gives the fixtures in the photo's view, their IDs unique there
(:attr:`Placement.local`): the identify and solve stages then run on that part of the map as
on any map.

A photo of two to four lights with an ID is placed with the direction of gravity, when it is
given (:mod:`~camvlp.pipeline.identify.by_gravity`); without it, it is refused.  What both
ways share (the lights, the prior, the local map) is
:mod:`~camvlp.pipeline.identify.placement`'s.
"""

from __future__ import annotations

import itertools

import numpy as np

from camvlp.geometry.hypotheses import (
    distance_bounds,
    least_triangle,
    rigid_on_plane,
)
from camvlp.geometry.pnp import solve_pnp
from camvlp.model.camera import Pose, project_points
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.identify.by_gravity import placed_with_gravity
from camvlp.pipeline.identify.by_pose import TOLD_APART
from camvlp.pipeline.identify.placement import (
    DISTANCE_SLACK,
    PLACES_LISTED,
    RELATIVE_SLACK,
    LightsWithIds,
    Placement,
    around,
    inside,
    lights_with_ids,
    listed,
    local_map,
    refused,
    search_scope,
    within_reach,
)
from camvlp.pipeline.solve import PoseProblem

__all__ = [
    "DISTANCE_SLACK",
    "GRAVITY_NEEDED",
    "HYPOTHESIS_SOLVER",
    "LIGHTS_NEEDED",
    "MAX_HYPOTHESES",
    "PLACES_LISTED",
    "RELATIVE_SLACK",
    "RIGID_SLACK",
    "SEED_SETS",
    "Placement",
    "placed",
]

#: Most sets of four seed lights tried (among the five lights with the fewest candidates).
SEED_SETS = 3

#: Most hypotheses (four fixtures) a seed set may give, and most rows any step of their
#: search may make (in the order :func:`_search_order` picks, which makes the fewest):
#: beyond, the photo is refused (its lights fit too many places to try; a prior narrows
#: them).  Those a rigid motion cannot explain are dropped together
#: (:func:`~camvlp.geometry.hypotheses.rigid_on_plane`), and each one left costs a PnP solve
#: (about a tenth of a millisecond); renders of the warehouse of
#: ``examples/make_warehouse.py`` give a few hundred.
MAX_HYPOTHESES = 20_000

#: Lights with an ID a photo needs to be placed: four for a pose, one more to confirm it.
LIGHTS_NEEDED = 5

#: Lights with an ID a photo needs to be placed with the direction of gravity
#: (:mod:`~camvlp.pipeline.identify.by_gravity`, which places photos of fewer than
#: :data:`LIGHTS_NEEDED`).
GRAVITY_NEEDED = 2

#: A hypothesis is solved by PnP only when the rigid pose nearest its homography (made a
#: rotation's, :func:`~camvlp.geometry.hypotheses.rigid_on_plane`) puts its four fixtures
#: within this many outlier distances of the seed lights: that pose is not the least-squares
#: one, so more room than the outlier distance PnP's pose is held to.
RIGID_SLACK = 3.0

#: The PnP method each hypothesis is solved with: SQPnP, which finds the global minimum from
#: four points in a fraction of the time of the iterative method's (the pose of the place
#: found is then solved as the settings say).
HYPOTHESIS_SOLVER = "sqpnp"


def _pair_bounds(lights: LightsWithIds) -> tuple[np.ndarray, np.ndarray]:
    """The least and greatest distance between the fixtures of every two lights, their
    distances within :data:`RELATIVE_SLACK` of ``rho`` at one common scale
    (:func:`~camvlp.geometry.hypotheses.distance_bounds`), map units over that scale: each
    shape (n, n), symmetric."""
    k, rho = np.sqrt(RELATIVE_SLACK), lights.rho
    cos = np.einsum("ik,jk->ij", lights.rays, lights.rays)
    near, far = (rho[:, None] / k, rho[:, None] * k), (rho[None, :] / k, rho[None, :] * k)
    return distance_bounds(near, far, cos)


def _search_order(counts: np.ndarray, reach: np.ndarray) -> list[int]:
    """The order four seed lights are searched in (positions among them), the one that makes
    the fewest rows on the way (every order gives the same hypotheses).  Two lights pair
    about ``counts[i] * counts[j] * reach[i, j] ** 2`` fixtures (their candidates, shape
    (4,), and how far apart their fixtures may be, shape (4, 4): the area that holds a
    partner): first the light with the fewest such pairs, then the others by the pairs they
    make with it (the search extends around the first light's fixture)."""
    pairs = counts[:, None] * counts[None, :] * np.where(np.isfinite(reach), reach, 1e100) ** 2
    np.fill_diagonal(pairs, 0.0)
    first = int(np.argmin(pairs.sum(axis=1)))
    rest = sorted(set(range(len(counts))) - {first}, key=lambda j: (pairs[first, j], j))
    return [first, *rest]


def _quads(
    fmap: FixtureMap, lights: LightsWithIds, seeds, allowed: np.ndarray, bounds
) -> np.ndarray | None:
    """Every four fixtures, one a seed light, whose IDs are the seeds' and whose distances
    fit what the photo sees (:func:`_extended`, ``bounds`` as :func:`_pair_bounds` gives
    them); shape (q, 4) of fixture indices, its columns the seeds', its rows in lexical
    order; or None when a step of the search makes more than :data:`MAX_HYPOTHESES`."""
    ok = [allowed & (fmap.id_array == lights.ids[s]) for s in seeds]
    counts = np.array([np.count_nonzero(o) for o in ok])
    order = _search_order(counts, bounds[1][np.ix_(seeds, seeds)])
    rows = np.flatnonzero(ok[order[0]])[:, None]
    scale = np.tile([1 / lights.slack[0], lights.slack[1]], (len(rows), 1))
    for m in range(1, len(seeds)):
        path = [seeds[o] for o in order[: m + 1]]
        rows, scale = _extended(fmap, path, rows, scale, ok[order[m]], bounds)
        if len(rows) > MAX_HYPOTHESES:
            return None
    rows = rows[:, np.argsort(order)]  # (back in the seeds' order)
    return rows[np.lexsort(rows.T[::-1])]


def _extended(fmap: FixtureMap, seeds, rows, scale, ok, bounds):
    """``rows`` (shape (r, m), fixtures of the first m ``seeds``) each extended by every
    fixture ``ok`` allows for the last seed whose distance to each of the row's fixtures
    fits the rays' angle and the lights' distances (``bounds``, :func:`_pair_bounds`) at one
    scale common to the row (``scale``, shape (r, 2): the least and greatest, narrowed as
    fixtures are added).  Returns the new rows and their scales."""
    pos, s = fmap.positions, seeds[-1]
    pool = np.flatnonzero(ok)
    if np.isfinite(bounds[1][seeds[0], s]) and pool.size:
        reach = scale[:, 1] * bounds[1][seeds[0], s]
        which, cand = within_reach(pos, pool, rows[:, 0], reach)
    else:
        which, cand = np.repeat(np.arange(len(rows)), pool.size), np.tile(pool, len(rows))
    keep = np.ones(len(cand), dtype=bool)
    lo, hi = scale[which, 0].copy(), scale[which, 1].copy()
    for j, seed in enumerate(seeds[:-1]):
        d_lo, d_hi = bounds[0][seed, s], bounds[1][seed, s]
        dist = np.linalg.norm(pos[cand] - pos[rows[which, j]], axis=1)
        keep &= cand != rows[which, j]
        lo = np.maximum(lo, dist / d_hi)  # (a distance d at scale s: d_lo <= d / s <= d_hi)
        hi = np.minimum(hi, np.divide(dist, d_lo, out=np.full_like(dist, np.inf), where=d_lo > 0))
    keep &= lo <= hi
    rows = np.column_stack([rows[which[keep]], cand[keep]])
    return rows, np.column_stack([lo[keep], hi[keep]])


def _pose_of(problem: PoseProblem, lights: LightsWithIds, seeds, quad: np.ndarray) -> Pose | None:
    """The pose of the seed lights taken as the fixtures ``quad``, or None when they do not
    reproject within the outlier distance, lie behind the camera or face away from it."""
    fmap, camera = problem.fixture_map, problem.camera
    obj = fmap.positions[quad]
    img = lights.pixels[list(seeds)]
    try:
        pose = solve_pnp(obj, img, camera, HYPOTHESIS_SOLVER)
    except ValueError:
        return None
    if pose is None or np.any((obj - pose.position) @ pose.world_from_camera[:, 2] <= 0):
        return None  # (or a fixture behind the camera)
    where = project_points(camera, pose, obj)
    err = np.hypot(*(where - img).T)
    if not np.all(np.isfinite(err)) or err.max() > problem.outlier_px:
        return None
    for i in quad.tolist():  # seen from the side a fixture faces
        n = fmap.fixtures[i].normal
        if n is not None and n @ (pose.position - fmap.positions[i]) <= 0:
            return None
    return pose


def _explained(problem: PoseProblem, lights: LightsWithIds, pose: Pose) -> tuple[frozenset, float]:
    """The lights ``pose`` explains: (light, fixture) pairs, each light's fixture the one of
    the map with its ID that projects within the outlier distance of it, every other with
    that ID :data:`TOLD_APART` times farther, no fixture twice; and their RMS distance (px)."""
    fmap, tol = problem.fixture_map, problem.outlier_px
    idx = around(fmap, lights, pose, 1.0)
    if idx.size == 0:
        return frozenset(), np.inf
    where = project_points(problem.camera, pose, fmap.positions[idx])
    dist = np.hypot(*(where[None, :, :] - lights.pixels[:, None, :]).transpose(2, 0, 1))
    same = fmap.id_array[idx]
    dist = np.where((same[None, :] == lights.ids[:, None]) & np.isfinite(dist), dist, np.inf)
    order = np.argsort(dist, axis=1)[:, :2]
    best = np.take_along_axis(dist, order, axis=1)
    second = best[:, 1] if best.shape[1] > 1 else np.full(len(best), np.inf)
    ok = (best[:, 0] <= tol) & (second > TOLD_APART * tol)
    fixture = idx[order[:, 0]]
    taken, count = np.unique(fixture[ok], return_counts=True)
    ok &= ~np.isin(fixture, taken[count > 1])
    pairs = frozenset(zip(lights.index[ok].tolist(), fixture[ok].tolist(), strict=True))
    rms = float(np.sqrt(np.mean(best[ok, 0] ** 2))) if ok.any() else np.inf
    return pairs, rms


def _seed_sets(
    fmap: FixtureMap, lights: LightsWithIds, allowed: np.ndarray
) -> list[tuple[int, ...]]:
    """Up to :data:`SEED_SETS` sets of four lights (indices into ``lights``), drawn from the
    five with the fewest candidate fixtures (ties: the lights farther apart in the photo
    first), the sets whose smallest triangle is the largest (:func:`least_triangle`)
    first, each set ordered by its lights' candidates."""
    count = np.array([np.count_nonzero(allowed[fmap.with_id(i)]) for i in lights.ids])
    spread = np.linalg.norm(lights.pixels - lights.pixels.mean(axis=0), axis=1)
    order = np.lexsort((-spread, count))[:5]
    sets = list(itertools.combinations(order.tolist(), 4))
    flat = least_triangle(*np.moveaxis(lights.rays[sets, :2] / lights.rays[sets, 2:], 2, 0))
    # (sorted: the sets farthest from three lights on a line first; a stable sort)
    return [sets[k] for k in np.argsort(-flat, kind="stable")[:SEED_SETS]]


def _correspondences(problem: PoseProblem, lights: LightsWithIds, allowed, prior) -> dict | str:
    """Every correspondence the seed sets' hypotheses give: (light, fixture) pairs -> (the
    RMS distance, px, the pose); or why none could be weighed."""
    fmap = problem.fixture_map
    found: dict[frozenset, tuple[float, Pose]] = {}
    bounds = _pair_bounds(lights)
    for seeds in _seed_sets(fmap, lights, allowed):
        quads = _quads(fmap, lights, seeds, allowed, bounds)
        if quads is None:
            return (
                f"its {len(lights.ids)} lights' IDs fit more than {MAX_HYPOTHESES:,} sets of "
                "fixtures of the map: give a prior (near and within) to narrow the search"
            )
        rays = lights.rays[list(seeds)]
        reach = RIGID_SLACK * problem.outlier_px / problem.camera.focal_px
        for quad in quads[rigid_on_plane(fmap.positions[quads], rays, reach)]:
            pose = _pose_of(problem, lights, seeds, quad)
            if pose is None or (prior is not None and not inside(pose.position, *prior)):
                continue
            pairs, rms = _explained(problem, lights, pose)
            seeded = set(zip(lights.index[list(seeds)].tolist(), quad.tolist(), strict=True))
            if seeded <= pairs and rms < found.get(pairs, (np.inf,))[0]:
                found[pairs] = (rms, pose)
    return found


def _contradicts(a: frozenset, b: frozenset) -> bool:
    """Two correspondences give one light two fixtures, or one fixture two lights."""
    la, fa = dict(a), {f: k for k, f in a}
    return any(la.get(k, f) != f or fa.get(f, k) != k for k, f in b)


def placed(problem: PoseProblem, decodes, near=None, within: float | None = None) -> Placement:
    """Where in a map whose IDs repeat the photo was taken (see the module's words).

    Parameters
    ----------
    problem : PoseProblem
        The photo's camera, lights and settings, and the whole map (``reuse`` True).
    decodes : sequence, length n
        Each light's decode (its ``id`` and ``reason``), as the decode stage gives them.
    near : sequence of float, optional
        A prior: the camera's ``(x, y)`` or ``(x, y, z)``, map units.
    within : float, optional
        The prior's radius, map units (with ``near``).

    Returns
    -------
    Placement
        The fixtures in view of the place found, or why the photo is refused: too few
        lights with an ID, no place that fits, or more than one place that fits about
        equally (the reason lists them).  With gravity (``problem.gravity``), a photo of
        :data:`GRAVITY_NEEDED` to four lights with an ID is placed by
        :func:`~camvlp.pipeline.identify.by_gravity.placed_with_gravity`.
    """
    fmap = problem.fixture_map
    lights = lights_with_ids(problem, decodes)
    n, confirm = len(lights.ids), LIGHTS_NEEDED
    if n < confirm and problem.gravity is not None and n >= GRAVITY_NEEDED:
        return placed_with_gravity(problem, lights, decodes, near, within)
    if n < confirm:
        lit = f"{n} light{'s' if n != 1 else ''} with an ID of the map"
        if problem.gravity is not None:
            return refused(
                f"{lit}; the map gives its IDs to many fixtures, and {GRAVITY_NEEDED} are "
                "needed with gravity to tell which"
            )
        return refused(
            f"{lit}; the map gives its IDs to many fixtures, and {confirm} are needed to tell "
            "which (four to place the camera, one more to confirm the place), or "
            f"{GRAVITY_NEEDED} with the direction of gravity (which fixes the camera's tilt)"
        )
    prior, allowed, scope = search_scope(fmap, lights, near, within)
    found = _correspondences(problem, lights, allowed, prior)
    if isinstance(found, str):
        return refused(found)
    ranked = sorted(found.items(), key=lambda kv: (-len(kv[0]), kv[1][0]))
    if not ranked or len(ranked[0][0]) < confirm:
        best = (
            f" (at best {len(ranked[0][0])} of them, the camera at "
            f"{listed(ranked[:1], fmap.units)})"
            if ranked
            else ""
        )
        return refused(
            f"no place of the map{scope} fits its {n} lights' IDs and geometry{best}",
            ranked[:1],
        )
    top = len(ranked[0][0])
    rivals = [r for r in ranked[1:] if len(r[0]) >= top - 1 and _contradicts(ranked[0][0], r[0])]
    if rivals:
        places = [ranked[0], *rivals]
        return refused(
            f"ambiguous: {len(places)} places of the map{scope} fit its {n} lights' IDs and "
            f"geometry about equally, the camera at {listed(places, fmap.units)}; a prior "
            "(near and within) tells them apart",
            places,
        )
    pairs, (_, pose) = ranked[0]
    local = local_map(problem, lights, pairs, pose)
    return Placement(local, "", pose.position[None, :].copy(), (top,))
