"""What a camera sees of a site, and which views the site's IDs leave ambiguous.

A 4-bit frame names 16 fixtures; a shop or a warehouse has hundreds.  IDs are then reused,
and a photo is identified by what it shows together: the IDs it decodes *and where those
lights lie from each other*.  A view is **ambiguous** when the same IDs in the same
arrangement (the same distances, any turn about the vertical: a camera may be held at any
heading) lie somewhere else in the site too; it is then refused, not guessed.

:func:`sample_views` draws camera poses over a site (positions over its floor, heights above
the floor, tilts up to a limit, any heading) and lists the fixtures each sees whole and
large enough to decode (:func:`~camvlp.geometry.projection.decodable_in_view`).
:func:`ambiguous_views` tells which views have another placement in the site (optionally
also with any one of their lights missing: a light the decoder misses must not make a view
ambiguous).  :mod:`camvlp.analysis.assign_ids` chooses IDs that leave few of them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from camvlp.analysis.study.common import Progress
from camvlp.geometry.disc import rim_points
from camvlp.geometry.projection import decodable_in_view
from camvlp.model.camera import Camera

__all__ = [
    "SiteGeometry",
    "Views",
    "ambiguous_views",
    "identified_share",
    "sample_views",
    "seen_together",
    "up_basis",
    "view_ambiguous",
]


@dataclass(frozen=True)
class Views:
    """Camera poses over a site and the fixtures each sees (:func:`sample_views`).

    Attributes
    ----------
    positions_m : ndarray, shape (P, 3)
        Camera centres, metres (map frame).
    rotations : ndarray, shape (P, 3, 3)
        ``world_from_camera`` rotations.
    seen : list of ndarray of int
        Per pose, the indices of the fixtures it sees whole and can decode.
    """

    positions_m: np.ndarray
    rotations: np.ndarray
    seen: list[np.ndarray]

    def counts(self) -> np.ndarray:
        """Fixtures seen per pose, shape (P,)."""
        return np.array([s.size for s in self.seen], dtype=np.int64)


def up_basis(up: np.ndarray) -> np.ndarray:
    """An orthonormal basis (3, 3) whose rows are two horizontal axes and ``up`` (3,): the
    first along the world axis most across ``up`` (x for a map whose up is z), the second
    ``up`` cross the first."""
    u = np.asarray(up, dtype=float) / np.linalg.norm(up)
    axis = np.eye(3)[int(np.argmin(np.abs(u)))]
    a = axis - (axis @ u) * u
    a /= np.linalg.norm(a)
    return np.stack([a, np.cross(u, a), u])


def _looking_up(basis: np.ndarray, heading: np.ndarray, tilt: np.ndarray, azimuth: np.ndarray):
    """``world_from_camera`` rotations (P, 3, 3) of cameras looking up (along ``basis[2]``),
    turned by ``heading`` about their optical axis, then tilted by ``tilt`` towards the
    horizontal direction ``azimuth`` (radians, shape (P,) each)."""
    a, b, u = basis
    ch, sh = np.cos(heading)[:, None], np.sin(heading)[:, None]
    x = ch * a + sh * b  # camera x, horizontal
    y = np.cross(u, x)  # camera y: x cross y is the optical axis, up
    z = np.broadcast_to(u, x.shape)
    base = np.stack([x, y, z], axis=2)  # (P, 3, 3): axes as columns
    # tilt: a rotation by ``tilt`` about the horizontal axis perpendicular to ``azimuth``
    d = np.cos(azimuth)[:, None] * a + np.sin(azimuth)[:, None] * b
    k = np.cross(u, d)  # rotation axis
    ct, st = np.cos(tilt)[:, None, None], np.sin(tilt)[:, None, None]
    kx = np.zeros((k.shape[0], 3, 3))
    kx[:, 0, 1], kx[:, 0, 2], kx[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    kx -= kx.transpose(0, 2, 1)
    rot = np.eye(3) + st * kx + (1 - ct) * (kx @ kx)
    return rot @ base


def sample_views(
    camera: Camera,
    positions_m: np.ndarray,
    diameters_m: np.ndarray,
    up: np.ndarray,
    *,
    n_poses: int = 2000,
    floor_m: float = 0.0,
    heights_m: tuple[float, float] = (1.0, 1.6),
    tilt_max_deg: float = 20.0,
    min_rows: float = 0.0,
    rng: np.random.Generator,
    progress: Progress | None = None,
) -> Views:
    """Random camera poses over a site and the fixtures each sees.

    Parameters
    ----------
    camera : Camera
        Intrinsics, image size, readout axis (rows are counted along it).
    positions_m : ndarray, shape (N, 3)
        Fixture centres, metres; the fixtures face down (against ``up``).
    diameters_m : ndarray, shape (N,)
        Disc diameters, metres.
    up : ndarray, shape (3,)
        The map's up direction.
    n_poses : int
        Poses drawn: centres uniform over the fixtures' extent seen from above, at a height
        uniform in ``heights_m`` above the floor (``floor_m`` along ``up``).
    heights_m : (float, float)
        Camera heights above the floor, metres.
    tilt_max_deg : float
        Largest tilt from looking straight up, degrees (uniform in solid angle up to it);
        the heading is uniform.
    min_rows : float
        Rows along the readout a disc must span to count as decodable.
    rng : numpy.random.Generator
        The draws' source.
    progress : callable, optional
        Called with (poses done, poses).

    Returns
    -------
    Views
    """
    pts = np.asarray(positions_m, dtype=float).reshape(-1, 3)
    basis = up_basis(up)
    flat = pts @ basis[:2].T  # (N, 2) horizontal
    lo, hi = flat.min(axis=0), flat.max(axis=0)
    p = int(n_poses)
    uv = lo + (hi - lo) * rng.random((p, 2))
    h = floor_m + rng.uniform(heights_m[0], heights_m[1], p)
    centres = uv @ basis[:2] + h[:, None] * basis[2]
    cos_max = np.cos(np.deg2rad(tilt_max_deg))
    tilt = np.arccos(1.0 - rng.random(p) * (1.0 - cos_max))
    rots = _looking_up(basis, rng.uniform(0, 2 * np.pi, p), tilt, rng.uniform(0, 2 * np.pi, p))
    rims = rim_points(pts, diameters_m, np.broadcast_to(-basis[2], pts.shape), 12)
    tree = cKDTree(flat)
    # a fixture can be in view only within the widest half-angle (plus the tilt) of the
    # camera, from the highest camera to the ceiling
    corners = np.array([[0, 0], [camera.width, 0], [0, camera.height], [camera.width] * 2])
    half = np.max(np.hypot(*(corners - camera.matrix[:2, 2]).T)) / camera.focal_px
    rise = float(np.max(pts @ basis[2]) - floor_m - heights_m[0])
    reach = rise * np.tan(np.arctan(half) + np.deg2rad(tilt_max_deg)) + float(np.max(diameters_m))
    seen = []
    for k in range(p):
        near = np.asarray(tree.query_ball_point(uv[k], reach), dtype=np.intp)
        ok = decodable_in_view(camera, rots[k], centres[k : k + 1], rims[near], min_rows)[0]
        seen.append(np.sort(near[ok]))
        if progress is not None and (k + 1) % 200 == 0:
            progress(k + 1, p)
    return Views(centres, rots, seen)


class SiteGeometry:
    """A site's fixtures seen from above: horizontal positions, a tree over them, and
    the fixtures of each ID."""

    def __init__(self, positions_m: np.ndarray, up: np.ndarray, ids: np.ndarray, n_ids: int):
        basis = up_basis(up)
        self.flat = np.asarray(positions_m, dtype=float) @ basis[:2].T  # (N, 2)
        self.height = np.asarray(positions_m, dtype=float) @ basis[2]
        self.tree = cKDTree(self.flat)
        self.ids = np.asarray(ids, dtype=np.int64)
        self.by_id = [np.flatnonzero(self.ids == i) for i in range(n_ids)]


def _other_placement(site: SiteGeometry, members: np.ndarray, tol_m: float) -> bool:
    """Whether the fixtures ``members`` (indices, two or more) have the same IDs in the same
    arrangement elsewhere in the site: another set of fixtures their IDs, distances and
    heights match within ``tol_m`` after a turn about the vertical and a shift."""
    xy, z, ids = site.flat[members], site.height[members], site.ids[members]
    # anchors: the two members furthest apart
    d2 = np.sum((xy[:, None] - xy[None]) ** 2, axis=2)
    i, j = np.unravel_index(int(np.argmax(d2)), d2.shape)
    dist = float(np.sqrt(d2[i, j]))
    first = site.by_id[ids[i]]
    near = site.tree.query_ball_point(site.flat[first], dist + tol_m)
    a_idx, b_idx = [], []
    for a, around in zip(first, near, strict=True):
        b = np.asarray(around, dtype=np.intp)
        b = b[site.ids[b] == ids[j]]
        a_idx.append(np.full(b.size, a))
        b_idx.append(b)
    a2, b2 = np.concatenate(a_idx), np.concatenate(b_idx)
    span = np.hypot(*(site.flat[b2] - site.flat[a2]).T)
    keep = (np.abs(span - dist) <= tol_m) & ~((a2 == members[i]) & (b2 == members[j]))
    a2, b2 = a2[keep], b2[keep]
    if not a2.size:
        return False
    # the turn taking the anchors' direction to each candidate's, and the members moved by it
    v0 = xy[j] - xy[i]
    v1 = site.flat[b2] - site.flat[a2]
    ang = np.arctan2(v1[:, 1], v1[:, 0]) - np.arctan2(v0[1], v0[0])
    c, s = np.cos(ang)[:, None], np.sin(ang)[:, None]
    rel = xy - xy[i]  # (m, 2)
    moved = site.flat[a2][:, None, :] + np.stack(
        [c * rel[:, 0] - s * rel[:, 1], s * rel[:, 0] + c * rel[:, 1]], axis=2
    )  # (K, m, 2)
    gap, hit = site.tree.query(moved.reshape(-1, 2), distance_upper_bound=tol_m)
    hit = hit.reshape(moved.shape[:2])
    found = np.isfinite(gap.reshape(hit.shape))
    hit_c = np.where(found, hit, 0)
    dz = site.height[hit_c] - site.height[a2][:, None] - (z - z[i])
    same = found & (site.ids[hit_c] == ids) & (np.abs(dz) <= tol_m)
    return bool(np.any(np.all(same, axis=1)))


def ambiguous_views(
    positions_m: np.ndarray,
    up: np.ndarray,
    ids: np.ndarray,
    n_ids: int,
    views: Views,
    *,
    tol_m: float = 0.05,
    one_missing: bool = True,
    least: int = 2,
) -> np.ndarray:
    """Which views the site's IDs leave ambiguous.

    Parameters
    ----------
    positions_m : ndarray, shape (N, 3)
        Fixture centres, metres.
    up : ndarray, shape (3,)
        The map's up.
    ids : ndarray of int, shape (N,)
        Each fixture's ID.
    n_ids : int
        IDs the frame has.
    views : Views
        The views.
    tol_m : float
        How closely another placement must match, metres.
    one_missing : bool
        A view of four or more lights is also ambiguous when it is without any one of them
        (three lights then still tell it; two lights in a regular layout seldom can).
    least : int
        Views of fewer lights are ambiguous (nothing to tell them by).

    Returns
    -------
    ndarray of bool, shape (P,)
    """
    site = SiteGeometry(positions_m, up, ids, n_ids)
    out = np.zeros(len(views.seen), dtype=bool)
    for k, members in enumerate(views.seen):
        out[k] = view_ambiguous(site, members, tol_m, one_missing, least)
    return out


def view_ambiguous(
    site: SiteGeometry, members: np.ndarray, tol_m: float, one_missing: bool, least: int
) -> bool:
    """Whether one view (the indices of the fixtures it sees, shape (K,)) is ambiguous in
    ``site``: the arguments as :func:`ambiguous_views` takes them."""
    if members.size < max(least, 2):
        return True
    if _other_placement(site, members, tol_m):
        return True
    if one_missing and members.size >= 4:
        drop = np.ones(members.size, dtype=bool)
        for m in range(members.size):
            drop[m] = False
            if _other_placement(site, members[drop], tol_m):
                return True
            drop[m] = True
    return False


def identified_share(ambiguous: np.ndarray, views: Views, least: int) -> float:
    """Share of the views of ``least`` or more lights that are not ambiguous."""
    counted = views.counts() >= least
    return float(np.mean(~ambiguous[counted])) if counted.any() else float("nan")


def seen_together(views: Views, n: int) -> list[np.ndarray]:
    """Per fixture, the fixtures some view sees together with it (indices, shape (K,))."""
    pairs = [np.stack(np.meshgrid(s, s), axis=-1).reshape(-1, 2) for s in views.seen if s.size]
    if not pairs:
        return [np.zeros(0, dtype=np.intp) for _ in range(n)]
    both = np.unique(np.concatenate(pairs), axis=0)
    both = both[both[:, 0] != both[:, 1]]
    cut = np.searchsorted(both[:, 0], np.arange(n + 1))
    return [both[cut[f] : cut[f + 1], 1] for f in range(n)]
