"""Two to four lights placed with the direction of gravity, in a map whose IDs repeat.

Four lights place a camera and a fifth confirms the place
(:mod:`~camvlp.pipeline.identify.by_geometry`); with gravity two place it, and a prior
(``near``, ``within``) or the rarity of the lights' IDs and arrangement confirms it.
:func:`placed_with_gravity` weighs every place the lights may be at:

1. *Candidates*: each light may be any fixture with its ID (with a prior, only those within
   ``within`` plus the farthest a light can be of ``near``, by the map's k-d tree).
2. *Pairs*: gravity fixes the camera's tilt, so two lights' rays put a pair of fixtures at
   two lengths along them, or none (:func:`~camvlp.geometry.gravity.pair_ray_lengths`, for
   every pair of the two seed lights' candidates at once).  The pairs whose lengths are
   not in front of the camera or do not fit the discs' sizes (one scale for the photo's
   lights, as :mod:`~camvlp.pipeline.identify.by_geometry` takes it) are dropped.
3. *Hypotheses*: each pair left is solved with gravity
   (:func:`~camvlp.geometry.gravity.solve_pose_gravity`); its pose tells which fixture each
   other light may be (those of its ID within :func:`tolerance_px` of it), and every such
   set of fixtures, one a light, is solved again with all of them.  It **stands** when all
   its lights reproject within the outlier distance, in front of the camera and seen from
   the side they face, their distances fit the discs' sizes, its camera lies within the
   prior (when one is given), and no more than :data:`UNSEEN_ALLOWED` fixtures its pose
   puts whole and large in the photo are missing from it (:func:`unseen`).
4. *Decision*: one standing correspondence (light -> fixture), or several whose cameras lie
   within :data:`SAME_PLACE_M` of each other, places the photo; more refuse it, the reason
   listing the places (a wrong place is the worst answer: refused rather than guessed).
"""

from __future__ import annotations

import itertools

import numpy as np

from camvlp.geometry.gravity import (
    MAX_TILT_SIGMAS,
    GravityPose,
    pair_ray_lengths,
    solve_pose_gravity,
)
from camvlp.geometry.hypotheses import distance_bounds
from camvlp.model.camera import Pose, project_points
from camvlp.pipeline.identify.placement import (
    RELATIVE_SLACK,
    LightsWithIds,
    Placement,
    around,
    inside,
    listed,
    local_map,
    refused,
    search_scope,
    within_reach,
)
from camvlp.pipeline.solve import PoseProblem, centre_sigmas

__all__ = [
    "MAX_PAIRS",
    "SAME_PLACE_M",
    "UNSEEN_ALLOWED",
    "placed_with_gravity",
    "tolerance_px",
    "unseen",
]

#: Most pairs of fixtures the two seed lights may be (after the discs' sizes and gravity
#: have dropped the others), each solved with gravity (about 0.4 ms): beyond, the photo is
#: refused (a prior narrows them).
MAX_PAIRS = 5_000

#: Standing correspondences whose cameras lie this close together, metres, are one place.
SAME_PLACE_M = 0.05

#: Most fixtures a hypothesis' pose may put whole and large in the photo that it does not
#: show (:func:`unseen`): one (a lamp that is off, or hidden), not two.
UNSEEN_ALLOWED = 1


def tolerance_px(problem: PoseProblem) -> float:
    """How far (pixels) a pose solved from two lights and gravity may put a third light's
    fixture from it: the outlier distance plus the focal length times the tangent of
    :data:`~camvlp.geometry.gravity.MAX_TILT_SIGMAS` gravity sigmas (the gravity solver's
    greatest tilt error)."""
    tilt = np.radians(min(MAX_TILT_SIGMAS * problem.settings.gravity_sigma_deg, 45.0))
    return float(problem.outlier_px + problem.camera.focal_px * np.tan(tilt))


def _scale_fits(lights: LightsWithIds, which, lengths: np.ndarray) -> np.ndarray:
    """Which rows of ``lengths`` (shape (q, k): the distances of lights ``which``' fixtures
    from the camera) are in front of it and fit the discs' sizes at one scale common to the
    lights (their ``slack``, :data:`RELATIVE_SLACK`); shape (q,)."""
    ok = np.all(lengths > 0, axis=1)
    rho = lights.rho[list(which)]
    if not np.isfinite(rho).all():
        return ok
    s = lengths / rho  # each light's scale: within sqrt(RELATIVE_SLACK) of the common one
    k = np.sqrt(RELATIVE_SLACK)
    lo, hi = lights.slack
    ok &= np.all((s >= 1 / (lo * k)) & (s <= hi * k), axis=1)
    return ok & (s.max(axis=1) <= RELATIVE_SLACK * s.min(axis=1))


def _seed_pair(lights: LightsWithIds) -> tuple[int, int]:
    """The two lights (indices into ``lights``) whose rays are the farthest apart."""
    pairs = list(itertools.combinations(range(len(lights.ids)), 2))
    cos = [float(lights.rays[i] @ lights.rays[j]) for i, j in pairs]
    return pairs[int(np.argmin(cos))]


def _pairs(problem: PoseProblem, lights: LightsWithIds, seeds, allowed) -> np.ndarray | None:
    """Every pair of fixtures (shape (q, 2), fixture indices) the two ``seeds`` may be: their
    IDs, allowed by the prior, and lying on the lights' rays with the measured tilt at
    distances that fit the discs' sizes; None when more than :data:`MAX_PAIRS`."""
    fmap = problem.fixture_map
    i, j = seeds
    first, second = (fmap.with_id(lights.ids[s]) for s in seeds)
    first, second = first[allowed[first]], second[allowed[second]]
    k = np.sqrt(RELATIVE_SLACK)
    lo = lights.rho / (lights.slack[0] * k)
    hi = distance_bounds(
        (lo[i], lights.far[i]), (lo[j], lights.far[j]), float(lights.rays[i] @ lights.rays[j])
    )[1]
    if np.isfinite(hi) and first.size and second.size:
        which, b = within_reach(fmap.positions, second, first, np.full(first.size, hi))
        a = first[which]
    else:
        a, b = np.repeat(first, second.size), np.tile(second, first.size)
    a, b = a[a != b], b[a != b]
    g, up = problem.gravity
    lengths = pair_ray_lengths(
        lights.rays[[i, j]], fmap.positions[a] - fmap.positions[b], g, up
    )  # (q, 2 solutions, 2 lights)
    fits = _scale_fits(lights, seeds, lengths.reshape(-1, 2)).reshape(-1, 2).any(axis=1)
    if np.count_nonzero(fits) > MAX_PAIRS:
        return None
    return np.column_stack([a[fits], b[fits]])


def _solved(problem: PoseProblem, lights: LightsWithIds, which, fixtures) -> GravityPose:
    """The pose, with gravity, of lights ``which`` (indices into ``lights``) taken as the
    map's ``fixtures``, as the solve stage solves it (its sigmas and outlier distance)."""
    fmap, st = problem.fixture_map, problem.settings
    which, fixtures = list(which), list(fixtures)
    normals = fmap.normals[fixtures]
    normals = None if np.isnan(normals).all() else normals
    g, up = problem.gravity
    return solve_pose_gravity(
        lights.pixels[which],
        fmap.positions[fixtures],
        problem.camera,
        g,
        up=up,
        normals=normals,
        sigma_deg=st.gravity_sigma_deg,
        pixel_sigma_px=centre_sigmas(problem.blobs, tuple(lights.index[which].tolist()), st),
        outlier_px=problem.outlier_px,
    )


def unseen(problem: PoseProblem, lights: LightsWithIds, pose: Pose, tol_px: float) -> int:
    """How many fixtures ``pose`` puts whole in the photo (their discs ``tol_px`` in from its
    border), in front of the camera and facing it, at least twice the smallest fixture image
    the detector takes (``min_diameter_px``) across, with no light of the photo (any,
    with an ID or not) within ``tol_px`` of its region.

    Parameters
    ----------
    problem : PoseProblem
        The photo's camera and lights (every one detected), the map and settings.
    lights : LightsWithIds
        The lights with an ID (how far a fixture in view can be).
    pose : Pose
        The hypothesis' pose.
    tol_px : float
        How far off the pose may put a fixture, pixels (:func:`tolerance_px`).

    Returns
    -------
    int
        Those fixtures' count; fixtures without a diameter are not counted.
    """
    fmap, camera = problem.fixture_map, problem.camera
    idx = around(fmap, lights, pose, 2.0)
    idx = idx[np.isfinite(fmap.diameters[idx])]
    if not idx.size:
        return 0
    pos = fmap.positions[idx]
    off = pos - pose.position
    size = camera.focal_px * fmap.diameters[idx] / np.linalg.norm(off, axis=1)
    facing = ~(np.einsum("ij,ij->i", fmap.normals[idx], off) >= 0)  # (no normal: facing)
    where = project_points(camera, pose, pos).reshape(-1, 2)
    pad = 0.5 * size[:, None] + tol_px
    limit = np.array([camera.width - 1, camera.height - 1], dtype=float)
    whole = np.all((where >= pad) & (where <= limit - pad), axis=1)
    should = (off @ pose.world_from_camera[:, 2] > 0) & facing & whole
    should &= size >= 2 * problem.settings.min_diameter_px
    if not should.any():
        return 0
    boxes = np.array([b.box for b in problem.blobs], dtype=float).reshape(-1, 4)
    u, v = where[should, 0:1], where[should, 1:2]
    seen = (u >= boxes[:, 0] - tol_px) & (u <= boxes[:, 2] + tol_px)
    seen &= (v >= boxes[:, 1] - tol_px) & (v <= boxes[:, 3] + tol_px)
    return int(np.count_nonzero(~seen.any(axis=1)))


def _border_lights(problem: PoseProblem, decodes) -> list[tuple[int, int]]:
    """The lights cut by the image border whose stripes gave an ID of the map: (light, ID)."""
    fmap = problem.fixture_map
    return [
        (k, d.id)
        for k, (b, d) in enumerate(zip(problem.blobs, decodes, strict=True))
        if b.touches_border and d.id is not None and not d.reason and fmap.with_id(d.id).size
    ]


def unexplained_border(
    problem: PoseProblem, lights: LightsWithIds, border, pose: Pose, tol_px: float
) -> int:
    """How many of the ``border`` lights ((light, ID) pairs: lights cut by the image border,
    their centres biased) ``pose`` puts no fixture of their ID near: in front of the camera,
    its disc's centre within the light's region widened by the disc's radius and ``tol_px``.

    Parameters
    ----------
    problem : PoseProblem
        The photo's camera and lights, and the map.
    lights : LightsWithIds
        The lights with an ID (how far a fixture in view can be).
    border : sequence of (int, int)
        The lights cut by the border and the IDs they send.
    pose : Pose
        The hypothesis' pose.
    tol_px : float
        How far off the pose may put a fixture, pixels (:func:`tolerance_px`).

    Returns
    -------
    int
        Those lights' count.
    """
    if not border:
        return 0
    fmap, camera = problem.fixture_map, problem.camera
    idx = around(fmap, lights, pose, 2.0)
    ids = fmap.id_array[idx]
    off = fmap.positions[idx] - pose.position
    dist = np.linalg.norm(off, axis=1)
    ahead = off @ pose.world_from_camera[:, 2] > 0
    diam = np.nan_to_num(fmap.diameters[idx])
    pad = 0.5 * camera.focal_px * diam / np.maximum(dist, 1e-12) + tol_px
    where = project_points(camera, pose, fmap.positions[idx]).reshape(-1, 2)
    missing = 0
    for k, fid in border:
        x0, y0, x1, y1 = problem.blobs[k].box
        near = (where[:, 0] >= x0 - pad) & (where[:, 0] <= x1 + pad)
        near &= (where[:, 1] >= y0 - pad) & (where[:, 1] <= y1 + pad)
        missing += not np.any(near & ahead & (ids == fid))
    return int(missing)


def _completions(problem, lights: LightsWithIds, seeds, pair, pose: Pose, tol_px: float):
    """Every way (tuples of fixture indices, one per light of ``lights``) of completing the
    seeds' ``pair`` with, for each other light, a fixture of its ID that ``pose`` projects
    within ``tol_px`` of it; no fixture twice."""
    fmap = problem.fixture_map
    idx = around(fmap, lights, pose, 1.0)
    ids = fmap.id_array[idx]
    where = project_points(problem.camera, pose, fmap.positions[idx]).reshape(-1, 2)
    ahead = (fmap.positions[idx] - pose.position) @ pose.world_from_camera[:, 2] > 0
    options = []
    for k in range(len(lights.ids)):
        if k in seeds:
            options.append([pair[seeds.index(k)]])
            continue
        off = np.hypot(*(where - lights.pixels[k]).T)
        options.append(idx[(ids == lights.ids[k]) & ahead & (off <= tol_px)].tolist())
    return [c for c in itertools.product(*options) if len(set(c)) == len(c)]


def _standing(problem, lights: LightsWithIds, pair, seeds, prior, border, tol_px) -> dict:
    """The hypotheses that stand (see the module's words) among those the seeds' ``pair`` of
    fixtures gives: (light, fixture) pairs -> (RMS reprojection error, px; the pose)."""
    fmap, n = problem.fixture_map, len(lights.ids)
    est = _solved(problem, lights, seeds, pair)
    if not est:
        return {}
    found = {}
    for fixtures in _completions(problem, lights, list(seeds), pair, est.pose, tol_px):
        full = est if n == 2 else _solved(problem, lights, range(n), fixtures)
        if not full or not full.used.all() or full.residuals_px.max() > problem.outlier_px:
            continue
        pose, order = full.pose, list(range(n))
        lengths = np.linalg.norm(fmap.positions[list(fixtures)] - pose.position, axis=1)
        if not _scale_fits(lights, order, lengths[None, :])[0]:
            continue
        if prior is not None and not inside(pose.position, *prior):
            continue
        if unseen(problem, lights, pose, tol_px) > UNSEEN_ALLOWED:
            continue
        if unexplained_border(problem, lights, border, pose, tol_px):
            continue
        key = frozenset(zip(lights.index[order].tolist(), list(fixtures), strict=True))
        found[key] = (full.reprojection_rms_px, pose)
    return found


def placed_with_gravity(
    problem: PoseProblem,
    lights: LightsWithIds,
    decodes,
    near=None,
    within: float | None = None,
) -> Placement:
    """Where in a map whose IDs repeat a photo of two to four lights with an ID was taken,
    with the direction of gravity (see the module's words).

    Parameters
    ----------
    problem : PoseProblem
        The photo's camera, lights, settings and gravity (not None), and the whole map.
    lights : LightsWithIds
        Its lights with an ID (two to four), not cut by the border.
    decodes : sequence, length n
        Each of the photo's lights' decode (its ``id`` and ``reason``): the lights cut by
        the border with an ID are held against each hypothesis too.
    near : sequence of float, optional
        A prior: the camera's ``(x, y)`` or ``(x, y, z)``, map units.
    within : float, optional
        The prior's radius, map units (with ``near``).

    Returns
    -------
    Placement
        The fixtures in view of the place found, or why the photo is refused: no place that
        fits, more than one (the reason lists them), or too many pairs to weigh.
    """
    fmap, n = problem.fixture_map, len(lights.ids)
    if len(set(lights.ids.tolist())) < 2:
        return refused(
            f"its {n} lights with an ID all send ID {lights.ids[0]}: with gravity, two lights "
            "of different IDs are needed (the fixtures in view of a place keep each ID once)"
        )
    prior, allowed, scope = search_scope(fmap, lights, near, within)
    seeds = _seed_pair(lights)
    pairs = _pairs(problem, lights, seeds, allowed)
    if pairs is None:
        return refused(
            f"its {n} lights' IDs fit more than {MAX_PAIRS:,} pairs of fixtures of the map: "
            "give a prior (near and within) to narrow the search"
        )
    tol, border = tolerance_px(problem), _border_lights(problem, decodes)
    found: dict[frozenset, tuple[float, Pose]] = {}
    for pair in pairs.tolist():
        for key, value in _standing(problem, lights, pair, seeds, prior, border, tol).items():
            if value[0] < found.get(key, (np.inf,))[0]:
                found[key] = value
    ranked = sorted(found.items(), key=lambda kv: kv[1][0])
    if not ranked:
        return refused(f"no place of the map{scope} fits its {n} lights' IDs and gravity")
    places = np.array([pose.position for _, (_, pose) in ranked])
    if np.linalg.norm(places - places[0], axis=1).max() > SAME_PLACE_M / fmap.unit_m:
        narrow = "a prior (near and within)" if prior is None else "a narrower prior"
        return refused(
            f"ambiguous: {len(ranked)} places of the map{scope} fit its {n} lights' IDs and "
            f"gravity, the camera at {listed(ranked, fmap.units)}; {narrow} or more lights "
            "tell them apart",
            ranked,
        )
    pairs_taken, (_, pose) = ranked[0]
    local = local_map(problem, lights, pairs_taken, pose)
    return Placement(
        local, "", pose.position[None, :].copy(), (n,), _left_out(fmap, local, pairs_taken)
    )


def _left_out(fmap, local, pairs: frozenset) -> tuple[tuple[int, int], ...]:
    """The (light, ID) of ``pairs`` ((light, fixture) indices into ``fmap``) whose fixture the
    ``local`` map leaves out (another light's fixture has its ID there)."""
    out = []
    for k, f in sorted(pairs):
        kept = local.get(fmap.fixtures[f].id)
        if kept is None or not np.array_equal(kept.position, fmap.positions[f]):
            out.append((k, fmap.fixtures[f].id))
    return tuple(out)
