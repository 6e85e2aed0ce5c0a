"""What placing a photo in a map whose IDs repeat needs, whichever way it is placed: the
photo's lights with an ID and how far each can be (:func:`lights_with_ids`), a prior's
candidates (:func:`search_scope`, :func:`prior_mask`, :func:`inside`), the place found as
the fixtures in its view (:func:`local_map`, :func:`view_map`) and the answer
(:class:`Placement`, :func:`refused`, :func:`listed`).

:mod:`~camvlp.pipeline.identify.by_geometry` places a photo of five lights or more by their
arrangement, :mod:`~camvlp.pipeline.identify.by_gravity` one of two to four with the
direction of gravity.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import cv2
import numpy as np

from camvlp.model.camera import Camera, Pose, project_points
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.solve import PoseProblem

__all__ = [
    "DISTANCE_SLACK",
    "PLACES_LISTED",
    "PLAIN_SLACK",
    "RELATIVE_SLACK",
    "LightsWithIds",
    "Placement",
    "around",
    "disc_distances",
    "inside",
    "lights_with_ids",
    "listed",
    "local_map",
    "prior_mask",
    "refused",
    "search_scope",
    "view_map",
    "within_reach",
]

#: A light's distance from its disc's size (the estimate: the focal length times the
#: diameter over the major axis) is the true one over a scale that lies between the first
#: factor's inverse and the second: a glowing lamp's halo makes its disc look larger, so the
#: fixture farther (the lamps of ``sites_locate.py``: up to 3.2 times), and a disc off the
#: optical axis is stretched along the radial direction (1.8 times in the warehouse's
#: corners).
DISTANCE_SLACK = (2.0, 3.0)

#: The same for a photo whose lights were all told plain (none glows: each outline is its
#: disc's rim), the estimate the disc model's (:func:`disc_distances`): on the renders of
#: ``sites_locate.py`` (its sites of plain discs and of lamps, tilts to 20 degrees) and
#: ``bench_sites.py`` (the warehouse) it was 0.99 to 1.07 of the truth.
PLAIN_SLACK = (1.15, 1.25)

#: The lights of one photo share that scale to within this factor (one look, one exposure):
#: each light's estimate times the common scale is within its square root either way.
RELATIVE_SLACK = 1.5

#: Most candidate places a refusal lists.
PLACES_LISTED = 4


@dataclass(frozen=True)
class Placement:
    """Where a photo is put in a map whose IDs repeat
    (:func:`~camvlp.pipeline.identify.by_geometry.placed`).

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
    withheld : tuple of (int, int)
        Lights (their indices among the photo's) and the IDs they send, that the place found
        gives a fixture ``local`` leaves out, another light's fixture having that ID: the
        identify stage takes them as lights without an ID (a photo of few lights, whose pose
        cannot tell two lights of one ID apart).
    """

    local: FixtureMap | None
    reason: str
    places: np.ndarray
    explained: tuple[int, ...]
    withheld: tuple[tuple[int, int], ...] = ()


@dataclass(frozen=True)
class LightsWithIds:
    """The photo's lights with an ID of the map (:func:`lights_with_ids`).

    Attributes
    ----------
    index : ndarray of int, shape (n,)
        Their indices among the photo's lights.
    ids : ndarray of int, shape (n,)
        Their IDs.
    pixels : ndarray, shape (n, 2)
        Their centres, pixels.
    rays : ndarray, shape (n, 3)
        Their unit rays in the camera's frame (undistorted).
    rho : ndarray, shape (n,)
        Their distances from their discs' sizes, map units (inf: unknown, without diameters):
        :func:`disc_distances` where every light of the photo was told plain, else the
        focal length times the diameter over the outline's major axis (a glowing lamp's
        outline is its halo's).
    far : ndarray, shape (n,)
        The greatest distance each can be at, map units.
    slack : tuple of float
        The factors of the scale between the true distances and ``rho``
        (:data:`PLAIN_SLACK` where every light of the photo was told plain, else
        :data:`DISTANCE_SLACK`).
    """

    index: np.ndarray
    ids: np.ndarray
    pixels: np.ndarray
    rays: np.ndarray
    rho: np.ndarray
    far: np.ndarray
    slack: tuple[float, float] = DISTANCE_SLACK


def lights_with_ids(problem: PoseProblem, decodes) -> LightsWithIds:
    """The photo's lights whose stripes gave an ID the map has (not cut by the border).

    Parameters
    ----------
    problem : PoseProblem
        The photo's camera and lights, and the map.
    decodes : sequence, length n
        Each light's decode (its ``id`` and ``reason``).

    Returns
    -------
    LightsWithIds
        Those lights, their rays and how far each is (:data:`DISTANCE_SLACK`,
        :data:`RELATIVE_SLACK`).
    """
    fmap, camera = problem.fixture_map, problem.camera
    keep = [
        k
        for k, (b, d) in enumerate(zip(problem.blobs, decodes, strict=True))
        if d.id is not None and not d.reason and not b.touches_border and fmap.with_id(d.id).size
    ]
    ids = np.array([decodes[k].id for k in keep], dtype=np.int64)
    pixels = np.array([problem.blobs[k].pixel for k in keep], dtype=float).reshape(-1, 2)
    if keep:
        rays = np.column_stack([camera.undistort_pixels(pixels), np.ones(len(keep))])
        rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    else:
        rays = np.zeros((0, 3))
    diameters = np.zeros(len(keep))
    for j in range(len(keep)):
        each = fmap.diameters[fmap.with_id(ids[j])]  # (NaN where not given)
        diameters[j] = float(np.median(each)) if np.all(each > 0) else 0.0
    blobs = [problem.blobs[k] for k in keep]
    flags = problem.glowing
    if len(flags) == len(problem.blobs) and not any(flags):
        # every outline is its disc's rim: the disc model reads the distance
        rho, slack = disc_distances(camera, blobs, rays, diameters), PLAIN_SLACK
    else:
        # a halo's outline says the distance only roughly: the focal length times the
        # diameter over the major axis, within the wide slack
        focal = 0.5 * float(camera.matrix[0, 0] + camera.matrix[1, 1])
        major = np.array([float(np.max(b.axes_px)) for b in blobs])
        with np.errstate(divide="ignore", invalid="ignore"):
            rho = np.where((diameters > 0) & (major > 0), focal * diameters / major, np.inf)
        slack = DISTANCE_SLACK
    far = rho * slack[1] * np.sqrt(RELATIVE_SLACK)
    return LightsWithIds(np.array(keep, dtype=np.int64), ids, pixels, rays, rho, far, slack)


def disc_distances(camera: Camera, blobs, rays: np.ndarray, diameters) -> np.ndarray:
    """Each light's distance along its ray from its disc's size, map units, shape (n,).

    A small disc of diameter ``D`` at distance ``d`` is, on the plane across its ray at
    unit distance, an ellipse whose major axis is ``D / d`` whichever way the disc faces.
    The blob's outline (its axes, along the orientation of its pixels' second moments) is
    taken there: to the normalised image plane by the camera's local map at its centre
    (the focal lengths and the distortion there), then across the ray, which shrinks
    lengths in the image plane by ``cos(theta)`` across the radial direction and by
    ``cos(theta) ** 2`` along it (``theta`` the ray's angle from the optical axis).  A disc
    parallel to the image plane (a ceiling's, seen from below) is thus not taken for one
    nearer than it is by its image's radial stretch (up to 1.8 times in a wide view).

    Parameters
    ----------
    camera : Camera
        The photo's camera.
    blobs : sequence of Blob, length n
        The lights.
    rays : ndarray, shape (n, 3)
        Their unit rays in the camera's frame (undistorted).
    diameters : array_like, shape (n,)
        Their fixtures' diameters, map units (0: unknown).

    Returns
    -------
    ndarray, shape (n,)
        inf where the diameter is unknown or the outline has no size.
    """
    n = len(blobs)
    out = np.full(n, np.inf)
    if n == 0:
        return out
    centres = np.array([b.pixel for b in blobs], dtype=np.float64).reshape(n, 1, 2)
    steps = centres + np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])  # (n, 3, 2)
    flat = camera.undistort_pixels(steps.reshape(-1, 2)).reshape(n, 3, 2)
    local = np.stack([flat[:, 1] - flat[:, 0], flat[:, 2] - flat[:, 0]], axis=2)  # (n, 2, 2)
    angle = np.empty(n)
    for j, b in enumerate(blobs):  # the major axis' direction, from the pixels' moments
        m = cv2.moments(np.asarray(b.mask, dtype=np.uint8), binaryImage=True)
        angle[j] = 0.5 * np.arctan2(2.0 * m["mu11"], m["mu20"] - m["mu02"])
    half = 0.5 * np.array([np.sort(np.asarray(b.axes_px, dtype=float))[::-1] for b in blobs])
    c, s = np.cos(angle), np.sin(angle)
    rot = np.stack([np.stack([c, -s], axis=1), np.stack([s, c], axis=1)], axis=1)  # (n, 2, 2)
    spread = rot @ (half[:, :, None] ** 2 * np.swapaxes(rot, 1, 2))  # the outline, pixels^2
    cos = rays[:, 2]
    across = np.linalg.norm(rays[:, :2], axis=1)
    radial = np.where(
        across[:, None] > 1e-12, rays[:, :2] / np.maximum(across, 1e-300)[:, None], [1.0, 0.0]
    )
    onto = cos[:, None, None] * (
        np.eye(2) - (1.0 - cos)[:, None, None] * np.einsum("ni,nj->nij", radial, radial)
    )
    to_plane = onto @ local
    seen = to_plane @ spread @ np.swapaxes(to_plane, 1, 2)
    size = 2.0 * np.sqrt(np.maximum(np.linalg.eigvalsh(seen)[:, -1], 0.0))
    known = (np.asarray(diameters, dtype=float) > 0) & (size > 0)
    out[known] = np.asarray(diameters, dtype=float)[known] / size[known]
    return out


def prior_mask(fmap: FixtureMap, near, within, reach: float) -> np.ndarray:
    """Which fixtures lie within ``within + reach`` of the prior ``near``.

    Parameters
    ----------
    fmap : FixtureMap
        The map.
    near : sequence of float or None
        The prior: ``(x, y)`` (the map's x and y compared) or ``(x, y, z)``, map units.
    within, reach : float
        The prior's radius and how far beyond it a fixture may be, map units.

    Returns
    -------
    ndarray of bool, shape (N,)
        True for those fixtures (looked up in the map's k-d tree); every fixture without a
        prior or with an unbounded reach.
    """
    n = len(fmap.fixtures)
    if near is None or not np.isfinite(reach):
        return np.ones(n, dtype=bool)
    c = np.asarray(near, dtype=float)
    radius = within + reach
    centre, ball = c, radius
    if c.size == 2:  # a ball of the map's k-d tree around the cylinder's part over the map
        z = fmap.positions[:, 2]
        half = 0.5 * float(z.max() - z.min())
        centre, ball = np.array([*c, 0.5 * float(z.max() + z.min())]), np.hypot(radius, half)
    near_idx = np.asarray(fmap.index.query_ball_point(centre, ball), dtype=np.int64)
    off = fmap.positions[near_idx, : c.size] - c
    mask = np.zeros(n, dtype=bool)
    mask[near_idx[np.einsum("ij,ij->i", off, off) <= radius**2]] = True
    return mask


class Scope(NamedTuple):
    """Where a photo is looked for in the map (:func:`search_scope`)."""

    prior: tuple | None  # (near, within), or None without a prior
    allowed: np.ndarray  # bool, shape (N,): the fixtures a light may be
    words: str  # how a refusal names the scope ("" without a prior)


def search_scope(fmap: FixtureMap, lights: LightsWithIds, near, within) -> Scope:
    """The prior (``near`` and ``within``, map units; None for neither), the fixtures a light
    may be with it (:func:`prior_mask`, reaching as far as the farthest light can be), and
    the words a refusal names it by (" within R m of the prior")."""
    reach = float(lights.far.max()) if np.isfinite(lights.far).all() else np.inf
    prior = None if near is None else (near, float(within))
    words = "" if prior is None else f" within {within:g} {fmap.units} of the prior"
    return Scope(prior, prior_mask(fmap, near, within, reach), words)


def inside(position: np.ndarray, near, within: float) -> bool:
    """The camera's ``position`` (shape (3,), map units) lies within ``within`` of the prior
    ``near`` (over the axes it gives)."""
    c = np.asarray(near, dtype=float)
    return float(np.linalg.norm(position[: c.size] - c)) <= within


def around(fmap: FixtureMap, lights: LightsWithIds, pose: Pose, factor: float) -> np.ndarray:
    """Indices of the fixtures within ``factor`` times the farthest a light can be of the
    camera (by the map's k-d tree); every fixture when a light's distance is not bounded."""
    if not np.isfinite(lights.far).all():
        return np.arange(len(fmap.fixtures))
    reach = factor * float(lights.far.max())
    return np.asarray(fmap.index.query_ball_point(pose.position, reach), dtype=np.int64)


def listed(ranked: list, units: str) -> str:
    """The first :data:`PLACES_LISTED` camera positions of ``ranked`` (a list of
    ``(pairs, (rms, pose))``), as a refusal lists them."""
    text = [
        "(" + ", ".join(f"{v:.2f}" for v in pose.position) + ")"
        for _, (_, pose) in ranked[:PLACES_LISTED]
    ]
    more = len(ranked) - PLACES_LISTED
    return ", ".join(text) + (f" and {more} more" if more > 0 else "") + f" ({units})"


def local_map(
    problem: PoseProblem, lights: LightsWithIds, pairs: frozenset, pose: Pose
) -> FixtureMap:
    """The fixtures ``pose`` puts in front of the camera and in the photo (or within a tenth
    of its width of it) and those ``pairs`` ((light, fixture) indices) gives the lights, each
    ID once (:func:`view_map`), among those near the camera (:func:`around`)."""
    idx = around(problem.fixture_map, lights, pose, 2.0)
    return view_map(problem.fixture_map, problem.camera, pose, idx, [f for _, f in pairs])


def view_map(fmap: FixtureMap, camera: Camera, pose: Pose, idx: np.ndarray, taken=()) -> FixtureMap:
    """The fixtures of ``idx`` that ``pose`` puts in front of the camera and in the photo (or
    within a tenth of its width of it), and those of ``taken``, each ID once: where two have
    one ID, the one of ``taken``, else the one in the photo when the other lies outside it;
    else neither.

    Parameters
    ----------
    fmap : FixtureMap
        The whole map (its IDs may repeat).
    camera : Camera
    pose : Pose
        The camera's pose, map frame and units.
    idx : ndarray of int, shape (m,)
        Indices into ``fmap.fixtures`` of the fixtures to weigh.
    taken : iterable of int
        Indices of fixtures a light was found to be (kept before any other of their ID).

    Returns
    -------
    FixtureMap
        Those fixtures, a map without ``reuse`` (its IDs unique), of ``fmap``'s frame and
        units.
    """
    idx = np.asarray(idx, dtype=np.int64).reshape(-1)
    where = project_points(camera, pose, fmap.positions[idx]).reshape(-1, 2)
    ahead = (fmap.positions[idx] - pose.position) @ pose.world_from_camera[:, 2] > 0
    tier = np.full(len(idx), 3)  # 1: in the photo, 2: within the margin, 3: neither
    for t, pad in ((2, 0.1 * camera.width), (1, 0.0)):
        within_photo = ahead & np.all(np.isfinite(where), axis=1)
        within_photo &= (where[:, 0] >= -pad) & (where[:, 0] <= camera.width - 1 + pad)
        within_photo &= (where[:, 1] >= -pad) & (where[:, 1] <= camera.height - 1 + pad)
        tier[within_photo] = t
    rank = dict(zip(idx.tolist(), tier.tolist(), strict=True))
    rank.update({int(f): 0 for f in taken})  # 0: a light's
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


def refused(reason: str, ranked: list | None = None) -> Placement:
    """A refusal: no place, ``reason``, and the places of ``ranked`` (a list of
    ``(pairs, (rms, pose))``) weighed."""
    ranked = ranked or []
    places = np.array([pose.position for _, (_, pose) in ranked]).reshape(-1, 3)
    return Placement(None, reason, places, tuple(len(p) for p, _ in ranked))


def within_reach(
    pos: np.ndarray, pool: np.ndarray, first: np.ndarray, reach: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The fixtures of ``pool`` (indices into ``pos``, shape (F, 3) map units) within
    ``reach`` (map units, shape (r,)) of each row's fixture ``first`` (shape (r,)):
    ``(which, cand)``, each candidate's row and fixture, a row's candidates in the order of
    ``pool``.  The distinct fixtures of ``first`` (rows share them: hundreds of fixtures
    start thousands of rows) and ``pool`` are paired by two k-d trees in one call, as far as
    the farthest reach; each row then keeps those within its own."""
    from scipy.spatial import cKDTree  # here: SciPy's import costs half a second

    if first.size == 0 or pool.size == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=pool.dtype)
    starts, at = np.unique(first, return_inverse=True)
    near = cKDTree(pos[starts]).sparse_distance_matrix(
        cKDTree(pos[pool]), float(reach.max()), output_type="ndarray"
    )
    near = near[np.lexsort((near["j"], near["i"]))]  # by start, then in the order of pool
    count = np.bincount(near["i"], minlength=starts.size)
    offset = np.cumsum(count) - count  # where each start's candidates begin
    which = np.repeat(np.arange(first.size), count[at])
    begin = np.cumsum(count[at]) - count[at]  # each row's first candidate, in `which`
    cand = pool[near["j"][offset[at[which]] + np.arange(which.size) - begin[which]]]
    gap = pos[cand] - pos[first[which]]
    inside = np.einsum("ij,ij->i", gap, gap) <= reach[which] ** 2  # (the row's own reach)
    return which[inside], cand[inside]
