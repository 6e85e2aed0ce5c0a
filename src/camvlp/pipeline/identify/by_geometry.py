"""Fixtures told apart by their geometry, in a map whose IDs repeat (``FixtureMap.reuse``).

A site of thousands of fixtures with the thesis' 4-bit frame gives each ID to hundreds of
them: an ID read says which fixtures a light may be, not which one.  A photo shows several
lights and where they are in the picture, and only a few places of the site show those IDs
in that arrangement.  :func:`placed` finds them:

1. *Candidates*: each light whose stripes gave an ID may be any fixture of the map with it
   (within the prior's radius of its centre, when a prior ``near``/``within`` is given).
2. *Distances*: a disc's size in the photo says how far its fixture is (the focal length
   times its diameter over its major axis, within the factors of :data:`DISTANCE_SLACK`), and
   the angle between two lights' rays then bounds the distance between their fixtures.
   Four seed lights' candidates are combined only where every pair's distance lies within
   those bounds at one scale common to the photo's lights (:data:`RELATIVE_SLACK`), each
   next one looked up in a k-d tree of the fixtures with its ID, within the greatest
   distance of the first.
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
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import cv2
import numpy as np

from camvlp.geometry.hypotheses import (
    distance_bounds,
    least_triangle,
    rigid_on_plane,
)
from camvlp.geometry.pnp import solve_pnp
from camvlp.model.camera import Pose, project_points
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.identify.by_pose import TOLD_APART
from camvlp.pipeline.solve import PoseProblem

__all__ = [
    "DISTANCE_SLACK",
    "HYPOTHESIS_SOLVER",
    "LIGHTS_NEEDED",
    "MAX_HYPOTHESES",
    "PLACES_LISTED",
    "RELATIVE_SLACK",
    "SEED_SETS",
    "Placement",
    "placed",
]

#: A light's distance from its disc's size (the estimate) is the true one over a scale that
#: lies between the first factor's inverse and the second: a glowing lamp's halo makes its
#: disc look larger, so the fixture farther (lamps of the stress benchmark's looks: up to
#: 2.2 times); a disc's major axis is hardly ever shorter than its diameter's image.
DISTANCE_SLACK = (2.0, 3.0)

#: The lights of one photo share that scale to within this factor (one look, one exposure):
#: each light's estimate times the common scale is within its square root either way.
RELATIVE_SLACK = 1.5

#: Most sets of four seed lights tried (among the five lights with the fewest candidates).
SEED_SETS = 3

#: Most hypotheses (four fixtures) a seed set may give: beyond, the photo is refused (its
#: lights fit too many places to try; a prior narrows them).  Those a rigid motion cannot
#: explain are dropped together (:func:`~camvlp.geometry.hypotheses.rigid_on_plane`), and
#: each one left costs a PnP solve (about a tenth of a millisecond); renders of the
#: warehouse of ``examples/make_warehouse.py`` give a few hundred.
MAX_HYPOTHESES = 20_000

#: Lights with an ID a photo needs to be placed: four for a pose, one more to confirm it.
LIGHTS_NEEDED = 5

#: Most candidate places a refusal lists.
PLACES_LISTED = 4

#: The PnP method each hypothesis is solved with: SQPnP, which finds the global minimum from
#: four points in a fraction of the time of the iterative method's (the pose of the place
#: found is then solved as the settings say).
HYPOTHESIS_SOLVER = "sqpnp"


@dataclass(frozen=True)
class Placement:
    """Where :func:`placed` puts a photo in a map whose IDs repeat.

    Attributes
    ----------
    local : FixtureMap or None
        The fixtures in the view of the place found, each ID once (a map without ``reuse``);
        None when the photo is refused.
    reason : str
        Why the photo was refused ("" when placed).
    places : ndarray, shape (m, 3)
        Camera positions of the correspondences weighed, the one taken (or the best) first,
        map units; (0, 3) when none fits.
    explained : tuple of int
        The numbers of lights those correspondences explain, in the same order.
    """

    local: FixtureMap | None
    reason: str
    places: np.ndarray
    explained: tuple[int, ...]


@dataclass(frozen=True)
class _Lights:
    """The lights with an ID: their indices among the photo's, IDs, pixels, rays (unit
    vectors in the camera's frame), distances from their discs' sizes (map units; inf
    unknown, without diameters) and the greatest distance each can be at."""

    index: np.ndarray
    ids: np.ndarray
    pixels: np.ndarray
    rays: np.ndarray
    rho: np.ndarray
    far: np.ndarray


def _lights(problem: PoseProblem, decodes) -> _Lights:
    """The photo's lights whose stripes gave an ID the map has (not cut by the border)."""
    fmap, camera = problem.fixture_map, problem.camera
    keep = [
        k
        for k, (b, d) in enumerate(zip(problem.blobs, decodes, strict=True))
        if d.id is not None and not d.reason and not b.touches_border and fmap.with_id(d.id).size
    ]
    ids = np.array([decodes[k].id for k in keep], dtype=np.int64)
    pixels = np.array([problem.blobs[k].pixel for k in keep], dtype=float).reshape(-1, 2)
    if keep:
        flat = cv2.undistortPoints(pixels[:, None, :], camera.matrix, camera.dist_or_none)
        rays = np.column_stack([flat.reshape(-1, 2), np.ones(len(keep))])
        rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    else:
        rays = np.zeros((0, 3))
    focal = 0.5 * float(camera.matrix[0, 0] + camera.matrix[1, 1])
    rho = np.full(len(keep), np.inf)
    for j, k in enumerate(keep):
        diameters = [fmap.fixtures[i].diameter for i in fmap.with_id(ids[j])]
        major = float(np.max(problem.blobs[k].axes_px))
        if all(diameters) and major > 0:
            rho[j] = focal * float(np.median(diameters)) / major
    far = rho * DISTANCE_SLACK[1] * np.sqrt(RELATIVE_SLACK)
    return _Lights(np.array(keep, dtype=np.int64), ids, pixels, rays, rho, far)


def _prior_mask(fmap: FixtureMap, near, within, reach: float) -> np.ndarray:
    """The fixtures within ``within + reach`` of the prior ``near`` (its x, y only when it
    gives two numbers); every fixture without a prior."""
    if near is None:
        return np.ones(len(fmap.fixtures), dtype=bool)
    c = np.asarray(near, dtype=float)
    off = fmap.positions[:, : c.size] - c
    return np.einsum("ij,ij->i", off, off) <= (within + reach) ** 2


def _quads(fmap: FixtureMap, lights: _Lights, seeds, allowed: np.ndarray) -> np.ndarray | None:
    """Every four fixtures, one a seed light, whose IDs are the seeds' and whose distances
    fit what the photo sees (:func:`_extended`); shape (q, 4) of fixture indices, or None
    when more than :data:`MAX_HYPOTHESES`."""
    first = fmap.with_id(lights.ids[seeds[0]])
    rows = first[allowed[first]][:, None]
    scale = np.tile([1 / DISTANCE_SLACK[0], DISTANCE_SLACK[1]], (len(rows), 1))
    ids = np.array([f.id for f in fmap.fixtures])
    for m in range(1, len(seeds)):
        ok = allowed & (ids == lights.ids[seeds[m]])
        rows, scale = _extended(fmap, lights, seeds[: m + 1], rows, scale, ok)
        if len(rows) > MAX_HYPOTHESES:
            return None
    return rows


def _extended(fmap: FixtureMap, lights: _Lights, seeds, rows, scale, ok):
    """``rows`` (shape (r, m), fixtures of the first m ``seeds``) each extended by every
    fixture ``ok`` allows for the last seed whose distance to each of the row's fixtures
    fits the rays' angle and the lights' distances (:func:`~camvlp.geometry.hypotheses.
    distance_bounds`) at one scale common to the row (``scale``, shape (r, 2): the least and
    greatest, narrowed as fixtures are added).  Returns the new rows and their scales."""
    pos, s, k = fmap.positions, seeds[-1], np.sqrt(RELATIVE_SLACK)
    bounds = [
        distance_bounds(
            (lights.rho[j] / k, lights.rho[j] * k),
            (lights.rho[s] / k, lights.rho[s] * k),
            float(lights.rays[j] @ lights.rays[s]),
        )
        for j in seeds[:-1]
    ]
    pool = np.flatnonzero(ok)
    if np.isfinite(bounds[0][1]) and pool.size:  # a k-d tree of the fixtures with that ID
        from scipy.spatial import cKDTree  # here: SciPy's import costs half a second

        near = cKDTree(pos[pool]).query_ball_point(pos[rows[:, 0]], scale[:, 1] * bounds[0][1])
        counts = np.fromiter(map(len, near), np.int64, len(near))
        cand = pool[np.fromiter(itertools.chain.from_iterable(near), np.int64, counts.sum())]
    else:
        counts, cand = np.full(len(rows), pool.size), np.tile(pool, len(rows))
    which = np.repeat(np.arange(len(rows)), counts)
    keep = np.ones(len(cand), dtype=bool)
    lo, hi = scale[which, 0].copy(), scale[which, 1].copy()
    for j, (d_lo, d_hi) in enumerate(bounds):
        dist = np.linalg.norm(pos[cand] - pos[rows[which, j]], axis=1)
        keep &= cand != rows[which, j]
        lo = np.maximum(lo, dist / d_hi)  # (a distance d at scale s: d_lo <= d / s <= d_hi)
        hi = np.minimum(hi, np.divide(dist, d_lo, out=np.full_like(dist, np.inf), where=d_lo > 0))
    keep &= lo <= hi
    rows = np.column_stack([rows[which[keep]], cand[keep]])
    return rows, np.column_stack([lo[keep], hi[keep]])


def _pose_of(problem: PoseProblem, lights: _Lights, seeds, quad: np.ndarray) -> Pose | None:
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


def _around(fmap: FixtureMap, lights: _Lights, pose: Pose, factor: float) -> np.ndarray:
    """Indices of the fixtures within ``factor`` times the farthest a light can be of the
    camera (by the map's k-d tree); every fixture when a light's distance is not bounded."""
    if not np.isfinite(lights.far).all():
        return np.arange(len(fmap.fixtures))
    reach = factor * float(lights.far.max())
    return np.asarray(fmap.index.query_ball_point(pose.position, reach), dtype=np.int64)


def _explained(problem: PoseProblem, lights: _Lights, pose: Pose) -> tuple[frozenset, float]:
    """The lights ``pose`` explains: (light, fixture) pairs, each light's fixture the one of
    the map with its ID that projects within the outlier distance of it, every other with
    that ID :data:`TOLD_APART` times farther, no fixture twice; and their RMS distance (px)."""
    fmap, tol = problem.fixture_map, problem.outlier_px
    idx = _around(fmap, lights, pose, 1.0)
    if idx.size == 0:
        return frozenset(), np.inf
    where = project_points(problem.camera, pose, fmap.positions[idx])
    dist = np.hypot(*(where[None, :, :] - lights.pixels[:, None, :]).transpose(2, 0, 1))
    same = np.array([f.id for f in (fmap.fixtures[i] for i in idx.tolist())])
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


def _seed_sets(fmap: FixtureMap, lights: _Lights, allowed: np.ndarray) -> list[tuple[int, ...]]:
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


def _correspondences(problem: PoseProblem, lights: _Lights, allowed, prior) -> dict | str:
    """Every correspondence the seed sets' hypotheses give: (light, fixture) pairs -> (the
    RMS distance, px, the pose); or why none could be weighed."""
    fmap = problem.fixture_map
    found: dict[frozenset, tuple[float, Pose]] = {}
    for seeds in _seed_sets(fmap, lights, allowed):
        quads = _quads(fmap, lights, seeds, allowed)
        if quads is None:
            return (
                f"its {len(lights.ids)} lights' IDs fit more than {MAX_HYPOTHESES:,} sets of "
                "fixtures of the map: give a prior (near and within) to narrow the search"
            )
        for quad in quads[rigid_on_plane(fmap.positions[quads], lights.rays[list(seeds)])]:
            pose = _pose_of(problem, lights, seeds, quad)
            if pose is None or (prior is not None and not _inside(pose.position, *prior)):
                continue
            pairs, rms = _explained(problem, lights, pose)
            seeded = set(zip(lights.index[list(seeds)].tolist(), quad.tolist(), strict=True))
            if seeded <= pairs and rms < found.get(pairs, (np.inf,))[0]:
                found[pairs] = (rms, pose)
    return found


def _inside(position: np.ndarray, near, within: float) -> bool:
    """The camera's ``position`` lies within ``within`` of the prior ``near`` (over the
    axes it gives)."""
    c = np.asarray(near, dtype=float)
    return float(np.linalg.norm(position[: c.size] - c)) <= within


def _contradicts(a: frozenset, b: frozenset) -> bool:
    """Two correspondences give one light two fixtures, or one fixture two lights."""
    la, fa = dict(a), {f: k for k, f in a}
    return any(la.get(k, f) != f or fa.get(f, k) != k for k, f in b)


def _places(ranked: list, units: str) -> str:
    """The first :data:`PLACES_LISTED` camera positions of ``ranked`` ((pairs, (rms, pose)))."""
    text = [
        "(" + ", ".join(f"{v:.2f}" for v in pose.position) + ")"
        for _, (_, pose) in ranked[:PLACES_LISTED]
    ]
    more = len(ranked) - PLACES_LISTED
    return ", ".join(text) + (f" and {more} more" if more > 0 else "") + f" ({units})"


def _local_map(problem: PoseProblem, lights: _Lights, pairs: frozenset, pose: Pose) -> FixtureMap:
    """The fixtures ``pose`` puts in front of the camera and in the photo (or within a tenth
    of its width of it) and those ``pairs`` gives the lights, each ID once: where two have
    one ID, the one a light was found to be, else the one in the photo when the other lies
    outside it; else neither."""
    fmap, camera = problem.fixture_map, problem.camera
    idx = _around(fmap, lights, pose, 2.0)
    where = project_points(camera, pose, fmap.positions[idx]).reshape(-1, 2)
    ahead = (fmap.positions[idx] - pose.position) @ pose.world_from_camera[:, 2] > 0
    tier = np.full(len(idx), 3)  # 1: in the photo, 2: within the margin, 3: neither
    for t, pad in ((2, 0.1 * camera.width), (1, 0.0)):
        inside = ahead & np.all(np.isfinite(where), axis=1)
        inside &= (where[:, 0] >= -pad) & (where[:, 0] <= camera.width - 1 + pad)
        inside &= (where[:, 1] >= -pad) & (where[:, 1] <= camera.height - 1 + pad)
        tier[inside] = t
    rank = dict(zip(idx.tolist(), tier.tolist(), strict=True))
    rank.update({f: 0 for _, f in pairs})  # 0: a light's
    best: dict[int, tuple[int, list[int]]] = {}  # ID -> its best tier, the fixtures of it
    for i, t in sorted(rank.items(), key=lambda it: it[1]):
        fid = fmap.fixtures[i].id
        if t < 3 and (fid not in best or best[fid][0] == t):
            best.setdefault(fid, (t, []))[1].append(i)
    keep = sorted(f[0] for t, f in best.values() if len(f) == 1 or t == 0)
    return FixtureMap(
        tuple(fmap.fixtures[i] for i in keep),
        units=fmap.units,
        mode=fmap.mode,
        frame=fmap.frame,
        source=fmap.source,
        up=fmap.up,
        chip_rate_hz=fmap.chip_rate_hz,
    )


def _refused(reason: str, ranked: list | None = None) -> Placement:
    ranked = ranked or []
    places = np.array([pose.position for _, (_, pose) in ranked]).reshape(-1, 3)
    return Placement(None, reason, places, tuple(len(p) for p, _ in ranked))


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
        equally (the reason lists them).
    """
    fmap = problem.fixture_map
    lights = _lights(problem, decodes)
    n, confirm = len(lights.ids), LIGHTS_NEEDED
    if n < confirm:
        return _refused(
            f"{n} light{'s' if n != 1 else ''} with an ID of the map; the map gives its IDs "
            f"to many fixtures, and {confirm} are needed to tell which (four to place the "
            "camera, one more to confirm the place)"
        )
    reach = float(lights.far.max()) if np.isfinite(lights.far).all() else np.inf
    prior = None if near is None else (near, float(within))
    allowed = _prior_mask(fmap, near, within, reach)
    found = _correspondences(problem, lights, allowed, prior)
    if isinstance(found, str):
        return _refused(found)
    ranked = sorted(found.items(), key=lambda kv: (-len(kv[0]), kv[1][0]))
    scope = "" if prior is None else f" within {within:g} {fmap.units} of the prior"
    if not ranked or len(ranked[0][0]) < confirm:
        best = (
            f" (at best {len(ranked[0][0])} of them, the camera at "
            f"{_places(ranked[:1], fmap.units)})"
            if ranked
            else ""
        )
        return _refused(
            f"no place of the map{scope} fits its {n} lights' IDs and geometry{best}",
            ranked[:1],
        )
    top = len(ranked[0][0])
    rivals = [r for r in ranked[1:] if len(r[0]) >= top - 1 and _contradicts(ranked[0][0], r[0])]
    if rivals:
        places = [ranked[0], *rivals]
        return _refused(
            f"ambiguous: {len(places)} places of the map{scope} fit its {n} lights' IDs and "
            f"geometry about equally, the camera at {_places(places, fmap.units)}; a prior "
            "(near and within) tells them apart",
            places,
        )
    pairs, (_, pose) = ranked[0]
    local = _local_map(problem, lights, pairs, pose)
    return Placement(local, "", pose.position[None, :].copy(), (top,))
