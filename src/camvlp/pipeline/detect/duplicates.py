"""Two candidate regions whose refined discs are one fixture: the larger is kept, unless
both are lights that a region of joined glows was split into and each keeps a disc of its own.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["MIN_AXIS_RATIO", "SAME_OUTLINE", "drop_duplicates"]


def drop_duplicates(
    found: list[tuple[dict, tuple | None]], areas: list[float]
) -> list[tuple[dict, tuple | None]]:
    """Two candidates whose refined discs are the same fixture: keep the larger (each blob's
    fields with its ellipse fit; ``areas``: each one's disc's pixels), the larger first.

    Two candidates are one fixture when their centres lie within either's half smaller axis
    of each other, unless :func:`_two_cells` tells them apart."""
    order = sorted(range(len(found)), key=lambda i: -areas[i])
    xy = [b["pixel"].tolist() for b, _ in found]
    r = [0.5 * float(b["axes_px"][1]) for b, _ in found]
    keep: list[int] = []
    for i in order:
        (x, y), ri = xy[i], r[i]
        if all(
            math.hypot(x - xy[j][0], y - xy[j][1]) > max(ri, r[j])
            or _two_cells(found[i][0], found[j][0])
            for j in keep
        ):
            keep.append(i)
    return [found[i] for i in keep]


#: Least ratio of a disc's outline's axes: a round fixture seen at most 60 degrees from
#: face-on (the ratio is the cosine of that angle).
MIN_AXIS_RATIO = 0.5


#: Two outlines are one disc when their centres lie within this share of its radius and
#: their axes differ by at most this share.
SAME_OUTLINE = 0.1


def _one_outline(a: dict, b: dict) -> bool:
    """Whether two candidates' fitted outlines are one ellipse (:data:`SAME_OUTLINE`): a
    light whose wide bands were taken for several lights, each cell of it fitted with the
    whole light's edges."""
    ra, rb = np.asarray(a["axes_px"], dtype=float), np.asarray(b["axes_px"], dtype=float)
    if not (np.all(np.isfinite(ra)) and np.all(np.isfinite(rb))):
        return False
    radius = 0.25 * float(ra.sum() + rb.sum()) / 2.0
    near = math.dist(a["pixel"].tolist(), b["pixel"].tolist()) <= SAME_OUTLINE * radius
    return near and bool(np.all(np.abs(ra - rb) <= SAME_OUTLINE * np.maximum(ra, rb)))


def _two_cells(a: dict, b: dict) -> bool:
    """Whether candidate ``a`` is a light of its own beside ``b``, however close their
    centres: both are lights that a joined region was split into (each has a
    :attr:`~camvlp.pipeline.detect.blob.Blob.cell`), their discs share less than half the
    smaller one's pixels, and ``a``'s outline is a disc's (its axes' ratio at least
    :data:`MIN_AXIS_RATIO`).

    An outline fitted to a cell's edge, where the cell cut its light off from the other, may
    come out far too large: half its smaller axis reached past the other light's centre, and
    the other light, 7 px from its lamp, was dropped as its duplicate.  A piece of glow that
    a split took for a light stays dropped (a sliver 315 x 76 px beside a lamp of 458 x 347:
    kept, it drew the joint fit of the glows 11 px off that lamp)."""
    if a["cell"] is None or b["cell"] is None:
        return False
    if a["axes_px"][1] < MIN_AXIS_RATIO * a["axes_px"][0]:
        return False
    if _one_outline(a, b):  # each cell's edge points drew the whole of one light
        return False
    (ax0, ay0, ax1, ay1), (bx0, by0, bx1, by1) = a["box"], b["box"]
    x0, y0, x1, y1 = max(ax0, bx0), max(ay0, by0), min(ax1, bx1), min(ay1, by1)
    shared = 0
    if x0 < x1 and y0 < y1:
        ma = a["mask"][y0 - ay0 : y1 - ay0, x0 - ax0 : x1 - ax0]
        mb = b["mask"][y0 - by0 : y1 - by0, x0 - bx0 : x1 - bx0]
        shared = np.count_nonzero(ma & mb)
    return shared < 0.5 * min(np.count_nonzero(a["mask"]), np.count_nonzero(b["mask"]))
