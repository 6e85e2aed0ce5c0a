"""Hypotheses of which fixtures a photo's lights are, checked by geometry before any PnP
(:mod:`camvlp.pipeline.identify.by_geometry` weighs them).

- :func:`distance_bounds`: how far apart two fixtures can be, given how far each is from the
  camera (within bounds) and the angle between their rays;
- :func:`triangles`, :func:`least_triangle`: how far four points are from three on a line;
- :func:`rigid_on_plane`: whether four fixtures on a plane can be where four rays see them,
  by a rotation and a translation (their homography's first two columns a rotation's).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "ON_A_LINE",
    "RIGID_COS",
    "RIGID_RATIO",
    "distance_bounds",
    "least_triangle",
    "rigid_on_plane",
    "triangles",
]

#: :func:`rigid_on_plane`: a triangle of a set's fixtures whose share (:func:`triangles`)
#: is under the first is taken as on a line; seen as one over the second, as off it (a
#: factor of 25 between the two: a view more oblique than a ceiling's changes a share less).
ON_A_LINE = (0.002, 0.05)


def distance_bounds(a, b, cos):
    """The least and greatest distance between two points seen at an angle ``arccos(cos)``
    apart from the camera, their distances from it within ``a`` and ``b``.

    Parameters
    ----------
    a, b : pair of float or of ndarray
        Each point's least and greatest distance from the camera, map units; arrays (any
        shapes that broadcast with ``cos``) give the bounds of many pairs at once.
    cos : float or ndarray
        The cosine of the angle between the two rays.

    Returns
    -------
    tuple of float or of ndarray
        The least and greatest distance between the points, map units (of the shape the
        inputs broadcast to; floats for floats); ``(0, inf)`` where a greatest distance is
        not finite.
    """
    ends = (np.asarray(v, dtype=float) for v in (*a, *b, cos))
    a_lo, a_hi, b_lo, b_hi, cos = np.broadcast_arrays(*ends)

    def d(r1, r2):
        return np.sqrt(np.maximum(r1 * r1 + r2 * r2 - 2 * r1 * r2 * cos, 0.0))

    with np.errstate(invalid="ignore", over="ignore"):  # (infinite ends: replaced below)
        # convex in each distance: the greatest at a corner, the least on an edge
        corners = [d(r1, r2) for r1 in (a_lo, a_hi) for r2 in (b_lo, b_hi)]
        edges = [d(r1, np.clip(r1 * cos, b_lo, b_hi)) for r1 in (a_lo, a_hi)]
        edges += [d(np.clip(r2 * cos, a_lo, a_hi), r2) for r2 in (b_lo, b_hi)]
    finite = np.isfinite(a_hi) & np.isfinite(b_hi)
    least = np.where(finite, np.minimum.reduce(edges), 0.0)
    greatest = np.where(finite, np.maximum.reduce(corners), np.inf)
    if least.ndim == 0:
        return float(least), float(greatest)
    return least, greatest


#: :func:`rigid_on_plane`'s tolerance: the columns of a plane's homography that a camera's
#: rotation makes (orthogonal, of one length) may differ in length by this factor and meet at
#: a cosine of at most :data:`RIGID_COS` (four fixtures' centres a few pixels off stay well
#: within).
RIGID_RATIO, RIGID_COS = 1.3, 0.25


def triangles(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The four triangles of each set of four points, each as a share of the set's size.

    Parameters
    ----------
    u, v : ndarray, shape (q, 4)
        The points' coordinates, any unit (one for both).

    Returns
    -------
    ndarray, shape (q, 4)
        The areas of the triangles of points (0, 1, 2), (0, 1, 3), (0, 2, 3) and (1, 2, 3)
        over the square of the set's size (the largest distance from its first point): 0
        for three points on a line.
    """
    size = np.hypot(u - u[:, :1], v - v[:, :1]).max(axis=1)
    area = [
        np.abs(
            (u[:, j] - u[:, i]) * (v[:, k] - v[:, i]) - (u[:, k] - u[:, i]) * (v[:, j] - v[:, i])
        )
        for i, j, k in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3))
    ]
    return np.stack(area, axis=1) / np.maximum(size**2, 1e-300)[:, None]


def least_triangle(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """How far each set of four points (``u``, ``v`` as :func:`triangles` takes them, shape
    (q, 4)) is from three on a line: the smallest of its triangles' shares, shape (q,), 0
    when three lie on a line."""
    return triangles(u, v).min(axis=1)


def rigid_on_plane(
    points: np.ndarray, rays: np.ndarray, max_error: float | None = None
) -> np.ndarray:
    """Which sets of four fixtures a rotation and a translation can put where four rays see
    them, before any PnP.

    Four points of a plane and their images are related by a homography whose first two
    columns (in the plane's own axes) are a rotation's, of one length and orthogonal; a
    wrong set of fixtures gives columns of other lengths or angles (within
    :data:`RIGID_RATIO` and :data:`RIGID_COS` is taken as right).  Three fixtures on a line
    are seen on a line, and three off a line off it (:data:`ON_A_LINE`): a set whose
    triangles do not match the rays' is not theirs either.

    Parameters
    ----------
    points : ndarray, shape (q, 4, 3)
        Each hypothesis' four fixture positions, map units.
    rays : ndarray, shape (4, 3)
        The four lights' rays in the camera's frame (z forward; any length, z > 0).
    max_error : float, optional
        Also drop the sets that the rigid pose nearest their homography (its first two
        columns made a rotation's, :func:`_rigid_errors`) leaves a ray farther than this from
        its fixture's image, in normalised image units (pixels over the focal length), or
        puts a fixture behind the camera.

    Returns
    -------
    ndarray of bool, shape (q,)
        True where the set may be the lights' (kept for PnP): also every set whose points
        are not on a plane, or whose homography three points on a line leave undetermined
        (rays near a line).
    """
    rel = points - points[:, :1, :]
    # the plane's axes from all four points (three on a line leave no normal of their own)
    _, sv, axes = np.linalg.svd(rel - rel.mean(axis=1, keepdims=True))
    size = np.linalg.norm(rel, axis=2).max(axis=1)
    planar = sv[:, 2] <= 1e-3 * np.maximum(size, 1e-300)
    u, v = np.einsum("qkj,qj->qk", rel, axes[:, 0]), np.einsum("qkj,qj->qk", rel, axes[:, 1])
    x, y = rays[:, 0] / rays[:, 2], rays[:, 1] / rays[:, 2]
    flat = triangles(u, v)
    seen = triangles(x[None], y[None])[0]
    line, off = ON_A_LINE
    mismatch = ((flat < line) & (seen > off)) | ((flat > off) & (seen < line))
    ok = ~(planar & mismatch.any(axis=1))
    # (three on a line leave the homography undetermined: those sets are kept for PnP)
    determined = np.flatnonzero(planar & (flat.min(axis=1) > off))
    if determined.size:
        h = _homographies(u[determined], v[determined], x, y)
        c1, c2 = h[:, [0, 3, 6]], h[:, [1, 4, 7]]
        l1, l2 = np.linalg.norm(c1, axis=1), np.linalg.norm(c2, axis=1)
        cos = np.abs(np.einsum("qj,qj->q", c1, c2)) / np.maximum(l1 * l2, 1e-300)
        ratio = np.maximum(l1, l2) / np.maximum(np.minimum(l1, l2), 1e-300)
        rigid = (ratio <= RIGID_RATIO) & (cos <= RIGID_COS)
        if max_error is not None:
            rigid &= ~(_rigid_errors(h, u[determined], v[determined], x, y) > max_error)
        ok[determined] &= rigid
    return ok


def _homographies(u: np.ndarray, v: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The homography taking each set's four plane points ``u``, ``v`` (shape (q, 4)) to the
    four rays ``x``, ``y`` (shape (4,), normalised image units), its last entry 1: shape
    (q, 8), the rows of the 3 x 3 matrix.  Eight equations in eight unknowns, solved (a set
    whose rays or points leave them singular: least squares, the pseudo-inverse's)."""
    q = u.shape[0]
    a = np.zeros((q, 8, 8))
    one, zero = np.ones((q, 4)), np.zeros((q, 4))
    a[:, 0::2] = np.stack([u, v, one, zero, zero, zero, -u * x, -v * x], axis=2)
    a[:, 1::2] = np.stack([zero, zero, zero, u, v, one, -u * y, -v * y], axis=2)
    b = np.stack([x * one, y * one], axis=2).reshape(q, 8)
    try:
        return np.linalg.solve(a, b[:, :, None])[:, :, 0]
    except np.linalg.LinAlgError:
        return np.einsum("qij,qj->qi", np.linalg.pinv(a), b)


def _rigid_errors(h, u, v, x, y) -> np.ndarray:
    """The largest distance (normalised image units) between each of four rays ``x``, ``y``
    (4,) and its point ``u``, ``v`` (q, 4) of a plane seen from the rigid pose nearest the
    homography ``h`` (q, 8; its last entry 1) mapping the plane to the image, shape (q,); inf
    where that pose puts a point behind the camera.  The pose: the homography scaled so its
    first two columns have unit length on average, those made a rotation's (the nearest, by
    SVD), its third column the translation, turned to put the points in front."""
    m = np.concatenate([h, np.ones((h.shape[0], 1))], axis=1).reshape(-1, 3, 3)
    c1, c2, c3 = m[:, :, 0], m[:, :, 1], m[:, :, 2]
    scale = 2.0 / np.maximum(np.linalg.norm(c1, axis=1) + np.linalg.norm(c2, axis=1), 1e-300)
    scale = np.where(scale * c3[:, 2] < 0, -scale, scale)[:, None]  # the plane in front
    r = np.stack([scale * c1, scale * c2, np.cross(scale * c1, scale * c2)], axis=2)
    left, _, right = np.linalg.svd(r)
    fix = np.where(np.linalg.det(left @ right) < 0, -1.0, 1.0)
    left[:, :, 2] *= fix[:, None]
    rot = left @ right
    cam = np.einsum("qij,qkj->qki", rot[:, :, :2], np.stack([u, v], axis=2)) + (scale * c3)[:, None]
    z = cam[:, :, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        err = np.hypot(cam[:, :, 0] / z - x, cam[:, :, 1] / z - y).max(axis=1)
    return np.where(np.all(z > 0, axis=1), err, np.inf)
