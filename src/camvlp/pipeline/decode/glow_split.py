"""Each glowing light's waveform, taken apart from its neighbours' glows across the photo.

A lamp whose disc clips in its dark chips too (an LED that is not fully off, many times the
sensor's full scale) shows no stripes on its disc; its code is still in its glow beyond the
disc, where its neighbours' glows add their own codes.  Each line across the readout is
exposed at one instant, when each lamp gives its light at that instant's level, so the photo's
unclipped pixels near the lamps are

    value(x, line) = a(line) + sum over lamps k of  s_k(line) * g_k(rho_k(x, line))

with ``g_k`` each lamp's radial shape (its disc, hot core and halo, blurred; one per lamp,
the same on every line), ``rho_k`` the distance from its centre in radii, ``s_k`` its level
on each line (its waveform: the code through the exposure window) and ``a`` the rest of the
light on the line (the ambient and the glows of lamps not found).  :func:`separated_waveforms`
fits it by alternating least squares: on each line, the levels of every lamp that reaches it
and ``a`` (a small linear system per line, all lines at once); then each lamp's shape from
what the others leave.  Clipped pixels are left out: they say only that the sum reached full
scale.  The waveforms are decoded as row profiles (:mod:`camvlp.pipeline.decode.model`);
their weights are each line's precision of ``s_k`` (the inverse of the diagonal of the
line's normal equations' inverse), so that lines where two lamps' glows cannot be told apart
count for little.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import NamedTuple

import numpy as np

from camvlp.imaging.gray import luma
from camvlp.model.fixtures import FixtureMap
from camvlp.model.readout import Readout
from camvlp.pipeline.decode.manchester import Manchester
from camvlp.pipeline.decode.model import decode_profile_model, least_frames
from camvlp.pipeline.paths import path

__all__ = ["SeparatedWave", "decode_from_glows", "separated_waveforms"]

#: How far from its centre a lamp's shape is fitted, radii.
REACH_RADII = 4.0

#: Bins of a lamp's radial shape over :data:`REACH_RADII`.
SHAPE_BINS = 40

#: About this many pixels at most are fitted: every ``stride``-th pixel along each line
#: (every line is kept: each is one instant of the waveforms).
MAX_PIXELS = 250_000

#: Rounds of the alternating least squares.
ROUNDS = 20

#: Photos with more lights than this are not taken apart (the normal equations grow with the
#: square of the lights, the rounds with their pairs; a stress photo has at most 16).
MAX_LIGHTS = 24

#: A pixel at or above this fraction of the photo's brightest counts as clipped.
CLIP_FRACTION = 0.98


class SeparatedWave(NamedTuple):
    """One lamp's waveform from :func:`separated_waveforms`.

    Attributes
    ----------
    first : int
        The line (along the readout, in the photo's order) of ``level[0]``.
    level : ndarray, shape (n,)
        Its level on each line from ``first`` (any units; 0 where it has no pixels).
    weight : ndarray, shape (n,)
        Each line's precision of ``level`` (inverse variance, up to a constant).
    """

    first: int
    level: np.ndarray
    weight: np.ndarray


@path("glows taken apart")
def separated_waveforms(
    img: np.ndarray,
    centres: np.ndarray,
    radii: np.ndarray,
    axis: str,
    *,
    max_pixels: int = MAX_PIXELS,
    rounds: int = ROUNDS,
) -> list[SeparatedWave | None]:
    """Every lamp's level on each line, its neighbours' glows taken apart (see the module).

    Parameters
    ----------
    img : ndarray, shape (H, W) or (H, W, 3)
        The photo (gray or BGR, any depth), linear in the light.
    centres : ndarray, shape (K, 2)
        The lamps' centres ``[x, y]``, pixels.
    radii : ndarray, shape (K,)
        Their radii, pixels.
    axis : {"rows", "columns"}
        The readout axis: lines are rows (``"rows"``) or columns.
    max_pixels : int
        At most about this many pixels are fitted: every ``stride``-th along each line.
    rounds : int
        Rounds of the alternating least squares.

    Returns
    -------
    list of (SeparatedWave or None)
        Per lamp, in the photo's line order; None for a lamp with no unclipped pixel within
        its reach.
    """
    photo = np.asarray(img)
    c = np.asarray(centres, dtype=np.float64).reshape(-1, 2)
    r = np.asarray(radii, dtype=np.float64).reshape(-1)
    if axis == "columns":  # lines down axis 0 (a view)
        photo, c = photo.swapaxes(0, 1), c[:, ::-1]
    k_lamps = c.shape[0]
    if k_lamps == 0 or photo.size == 0:
        return []
    pix = _pixels(photo, c, r, max_pixels)
    if pix is None:
        return [None] * k_lamps
    line, value, near, bins = pix
    n_lines = photo.shape[0]
    shapes = np.array(
        [np.exp(-np.maximum(_bin_centres() - 1.0, 0.0) / 0.5) for _ in range(k_lamps)]
    )
    pairs = _pairs(near)
    level = np.zeros((n_lines, k_lamps + 1))
    normal = np.zeros((n_lines, k_lamps + 1, k_lamps + 1))
    for _ in range(rounds):
        x = [shapes[k][bins[k]] for k in range(k_lamps)]  # each lamp's shape at its pixels
        level, normal = _levels(line, value, near, x, pairs, n_lines)
        fitted = _fitted(line, near, x, level)
        for k in range(k_lamps):
            own = level[line[near[k]], k]
            alone = value[near[k]] - fitted[near[k]] + own * x[k]
            num = np.bincount(bins[k], own * alone, minlength=SHAPE_BINS)
            den = np.bincount(bins[k], own * own, minlength=SHAPE_BINS)
            g = np.divide(num, den, out=np.zeros(SHAPE_BINS), where=den > 0)
            top = float(np.max(np.abs(g)))
            if top > 0:
                shapes[k] = g / top
    return [_wave(level[:, k], normal, k) for k in range(k_lamps)]


def _bin_centres() -> np.ndarray:
    return (np.arange(SHAPE_BINS) + 0.5) * (REACH_RADII / SHAPE_BINS)


def _pixels(photo: np.ndarray, c: np.ndarray, r: np.ndarray, max_pixels: int):
    """The unclipped pixels within reach of a lamp, every ``stride``-th along each line:
    their lines, gray levels, which of them each lamp reaches (their indices) and each
    lamp's shape bin at those; None when there are none.  ``photo`` (lines down axis 0, gray
    or BGR) is made gray only where it is sampled (a 20 MP photo in floats would take 240 MB)."""
    h, w = photo.shape[:2]
    reach = REACH_RADII * np.maximum(r, 1.0)
    lo = np.clip(np.floor(c[:, 0] - reach), 0, w).astype(int)
    hi = np.clip(np.ceil(c[:, 0] + reach) + 1, 0, w).astype(int)
    top = np.clip(np.floor(c[:, 1] - reach), 0, h).astype(int)
    bottom = np.clip(np.ceil(c[:, 1] + reach) + 1, 0, h).astype(int)
    area = float(np.sum((hi - lo) * (bottom - top)))
    stride = max(1, math.ceil(area / max_pixels))
    x0, x1, y0, y1 = lo.min(), hi.max(), top.min(), bottom.max()
    if x0 >= x1 or y0 >= y1:
        return None
    xs = np.arange(x0, x1, stride)
    block = luma(np.ascontiguousarray(photo[y0:y1, xs]), np.float32)
    clip = CLIP_FRACTION * _brightest(photo)
    yy, jj = np.nonzero(block < clip)
    px, py = xs[jj].astype(np.float64), (yy + y0).astype(np.float64)
    rho = [np.hypot(px - c[k, 0], py - c[k, 1]) / max(r[k], 1.0) for k in range(c.shape[0])]
    within = np.array([q < REACH_RADII for q in rho])
    keep = within.any(axis=0)
    if not keep.any():
        return None
    within = within[:, keep]
    near = [np.flatnonzero(m) for m in within]
    bins = [
        np.minimum((q[keep][m] * (SHAPE_BINS / REACH_RADII)).astype(np.intp), SHAPE_BINS - 1)
        for q, m in zip(rho, within, strict=True)
    ]
    value = block[yy[keep], jj[keep]].astype(np.float64)
    return (yy[keep] + y0), value, near, bins


def _brightest(photo: np.ndarray, rows: int = 256) -> float:
    """The photo's brightest gray level, made gray a band of ``rows`` at a time."""
    return max(
        float(luma(np.ascontiguousarray(photo[a : a + rows]), np.float32).max())
        for a in range(0, photo.shape[0], rows)
    )


def _pairs(near: list[np.ndarray]) -> dict[tuple[int, int], tuple[np.ndarray, np.ndarray]]:
    """For each two lamps whose reaches share pixels, where those pixels are among each
    one's pixels."""
    out = {}
    for i in range(len(near)):
        for j in range(i + 1, len(near)):
            _, a, b = np.intersect1d(near[i], near[j], assume_unique=True, return_indices=True)
            if a.size:
                out[i, j] = (a, b)
    return out


def _levels(line, value, near, x, pairs, n_lines: int):
    """Each line's least-squares levels of the lamps and of the rest, (n_lines, K + 1), and
    its normal equations, (n_lines, K + 1, K + 1)."""
    k_lamps = len(near)
    p = k_lamps + 1
    a = np.zeros((n_lines, p, p))
    b = np.zeros((n_lines, p))
    a[:, k_lamps, k_lamps] = np.bincount(line, minlength=n_lines)
    b[:, k_lamps] = np.bincount(line, value, minlength=n_lines)
    for k in range(k_lamps):
        lk = line[near[k]]
        a[:, k, k] = np.bincount(lk, x[k] * x[k], minlength=n_lines)
        a[:, k, k_lamps] = a[:, k_lamps, k] = np.bincount(lk, x[k], minlength=n_lines)
        b[:, k] = np.bincount(lk, x[k] * value[near[k]], minlength=n_lines)
    for (i, j), (ii, jj) in pairs.items():
        a[:, i, j] = a[:, j, i] = np.bincount(
            line[near[i][ii]], x[i][ii] * x[j][jj], minlength=n_lines
        )
    ridge = 1e-9 * np.maximum(np.trace(a, axis1=1, axis2=2), 1e-12)
    a_r = a + ridge[:, None, None] * np.eye(p)
    return np.linalg.solve(a_r, b[:, :, None])[:, :, 0], a_r


def _fitted(line, near, x, level) -> np.ndarray:
    """The model's value at every pixel."""
    k_lamps = len(near)
    out = level[line, k_lamps].copy()
    for k in range(k_lamps):
        out[near[k]] += level[line[near[k]], k] * x[k]
    return out


def _wave(level: np.ndarray, normal: np.ndarray, k: int) -> SeparatedWave | None:
    """Lamp ``k``'s waveform over the lines where it has pixels, with each line's precision
    (1 / the diagonal of the inverse of its normal equations)."""
    has = normal[:, k, k] > 0
    if not has.any():
        return None
    precision = np.zeros(level.size)
    precision[has] = 1.0 / np.linalg.inv(normal[has])[:, k, k]
    strong = np.flatnonzero(precision > 1e-3 * precision.max())
    a, b = int(strong[0]), int(strong[-1]) + 1
    return SeparatedWave(a, level[a:b].copy(), precision[a:b].copy())


def decode_from_glows(
    img: np.ndarray, blobs, man: Manchester, fixture_map: FixtureMap, glows: bool = True
) -> tuple[Manchester, dict[int, SeparatedWave]]:
    """The photo's decodes with each light whose stripes gave no ID read again from its
    waveform taken apart from its neighbours' glows (:func:`separated_waveforms`).

    A light is read again only when its own profile gave no ID (in a photo whose lamps glow,
    even one too short for a frame: its glow spans more lines than its disc; where none
    glows, one that spans a frame and was not read as an ID the map lacks), not when the
    border cuts its disc (it is not used), and in a photo of at most :data:`MAX_LIGHTS`
    lights; under each readout
    direction the decode keeps (``man.readout``, and the other one when the pose is to
    decide), with that direction's photo-wide parameters
    (:class:`~camvlp.pipeline.decode.stripe_model.SensorModel`; the knee at 1: the clipped pixels
    are left out of the waveforms).  Its new decode is taken when it names an ID that no
    other light of that direction has; otherwise its first decode stays, with its reason.

    Parameters
    ----------
    img : ndarray, shape (H, W, 3) or (H, W)
        The photo, linear in the light.
    blobs : sequence of Blob
        The detected lights, in the order of ``man.decodes``.
    man : Manchester
        The photo's decode (:func:`~camvlp.pipeline.decode.manchester.decode_manchester`).
    fixture_map : FixtureMap
        The map (its frame format and IDs).
    glows : bool
        Whether some light of the photo glows (:attr:`~camvlp.pipeline.lights.Lights.glowing`;
        a light's own glow test may miss a glow its neighbours' cover).

    Returns
    -------
    Manchester
        ``man`` with the lights read again where they gave an ID.
    dict of int to SeparatedWave
        The waveforms of the lights read again (by index), in the photo's line order.
    """
    sets = [(man.decodes, man.readout, man.model)]
    if man.other is not None:
        flipped = Readout.of(man.readout.axis, not man.readout.reversed)
        sets.append((man.other, flipped, man.other_model))
    least = least_frames(fixture_map.frame)
    todo = {
        k
        for decodes, _, model in sets
        if model is not None
        for k, d in enumerate(decodes)
        if d.id is None
        and not blobs[k].touches_border
        and (glows or (not d.frames < least and d.outside_id is None))
    }
    if not todo or len(blobs) > MAX_LIGHTS:
        return man, {}
    waves = separated_waveforms(
        img,
        np.array([b.pixel for b in blobs]),
        np.array([0.25 * float(b.axes_px[0] + b.axes_px[1]) for b in blobs]),
        man.readout.axis,
    )
    out, used = [], {}
    for decodes, readout, model in sets:
        new = list(decodes)
        taken = {d.id for d in decodes if d.id is not None}
        step = -1 if readout.reversed else 1
        for k in sorted(todo):
            wave = waves[k]
            if model is None or new[k].id is not None or wave is None:
                continue
            got = decode_profile_model(
                wave.level[::step],
                fixture_map.frame,
                fixture_map.distinct_ids,
                replace(model, knee=1.0),
                weights=wave.weight[::step],
            )
            if got.id is not None and got.id not in taken:
                new[k] = got
                taken.add(got.id)
                used[k] = wave
        out.append(tuple(new))
    return replace(man, decodes=out[0], other=out[1] if len(out) > 1 else None), used
