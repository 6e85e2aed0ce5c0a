"""Stage 2: read a fixture's ID from its stripes (thesis section 5.3 and 5.4, made robust).

Per fixture:

1. reduce each sensor row inside the disc to one value (the row profile,
   :mod:`camvlp.pipeline.decode.profile`);
2. binarise it with a threshold of the fixture's own (Otsu's two-class split of the profile,
   the principled form of the thesis' "two peaks of the histogram");
3. find the stripe edges to a fraction of a row, and the run lengths between them;
4. measure the chip length from edges of the same polarity (rising to rising, falling to
   falling: in Manchester they are 2, 3 or 4 chips apart whatever the bleeding), then the
   bleeding (how much wider bright runs are than dark ones), and decide one chip or two per
   run with separate thresholds for bright and dark runs;
5. decode the chips cyclically against every ID's frame (:meth:`FrameFormat.decode`), with
   the runs cut by the disc's edge entered only for the chips they surely hold.

The result says which ID, or why none, with the Hamming distance, the margin, and the
measured chip length and bleeding.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from camvlp.model.linecode import FrameFormat
from camvlp.pipeline.decode.profile import row_profile, shape_profile
from camvlp.pipeline.decode.result import StripeDecode

__all__ = [
    "Runs",
    "decode_profile",
    "find_runs",
    "row_profile",
    "shape_profile",
    "stripe_levels",
    "stripe_threshold",
]


def _otsu(values: np.ndarray) -> float:
    """Otsu's threshold of a 1-D sample (between its two classes)."""
    v = np.sort(np.asarray(values, dtype=float))
    n = v.size
    csum = np.cumsum(v)
    k = np.arange(1, n)
    w0 = k / n
    m0 = csum[:-1] / k
    m1 = (csum[-1] - csum[:-1]) / (n - k)
    between = w0 * (1 - w0) * (m0 - m1) ** 2
    i = int(np.argmax(between))
    return 0.5 * (v[i] + v[i + 1])


def stripe_levels(profile: np.ndarray) -> tuple[float, float]:
    """Dark and bright levels of a row profile: its 2nd and 98th percentiles."""
    lo, hi = _level_list([np.asarray(profile, dtype=float).reshape(-1)])
    return lo, hi


def _levels(profiles: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """:func:`stripe_levels` of several non-empty 1-D profiles: (dark, bright) arrays."""
    out = _level_list(profiles)
    return np.array(out[0::2]), np.array(out[1::2])


def _level_list(profiles: list[np.ndarray]) -> list[float]:
    """:func:`stripe_levels` of several non-empty 1-D profiles, one after another in a list
    of Python floats (dark, bright, dark, ...).

    NumPy's default (linear) percentiles, each profile sorted in a row of its own (NaN
    after its values, where NaN sorts); the few values each needs gathered at once and
    worked in Python floats (the same operations as NumPy's)."""
    sizes = [p.size for p in profiles]
    v = np.full((len(sizes), max(sizes)), np.nan)
    for row, p in zip(v, profiles, strict=True):
        row[: p.size] = p
    v.sort(axis=1)
    # per profile and percentile: the fraction x, the values at floor(x) and the next
    at = [
        (x, i, min(i + 1, n - 1))
        for n in sizes
        for x in (0.02 * (n - 1), 0.98 * (n - 1))
        for i in (min(math.floor(x), n - 1),)
    ]
    rows = [k // 2 for k in range(len(at))]
    a = v[rows, [i for _, i, _ in at]].tolist()
    b = v[rows, [j for _, _, j in at]].tolist()
    return [a0 + (x - i) * (b0 - a0) for (x, i, _), a0, b0 in zip(at, a, b, strict=True)]


def stripe_threshold(profile: np.ndarray, level: float = 0.6) -> float:
    """Binarisation threshold ``level`` of the way from the dark to the bright level.

    Above one half by default, so that dark stripes narrowed by a saturated neighbour's
    bleeding still cross it.
    """
    lo, hi = stripe_levels(profile)
    return lo + level * (hi - lo)


@dataclass(frozen=True)
class Runs:
    """Bright and dark runs of a binarised row profile.

    Attributes
    ----------
    edges : ndarray, shape (E,)
        Sub-row positions of the threshold crossings.
    rising : ndarray of bool, shape (E,)
        True where the profile goes from dark to bright.
    lengths : ndarray, shape (E + 1,)
        Run lengths in rows; the first and last are cut by the disc's edge.
    bright : ndarray of bool, shape (E + 1,)
        Which runs are bright.
    threshold : float
        The binarisation threshold, profile units.
    """

    edges: np.ndarray
    rising: np.ndarray
    lengths: np.ndarray
    bright: np.ndarray
    threshold: float


def find_runs(profile: np.ndarray, threshold: float | None = None) -> Runs:
    """Binarise a row profile and measure its runs to a fraction of a row.

    Parameters
    ----------
    profile : ndarray, shape (n,)
        Row profile (see :func:`row_profile`).
    threshold : float, optional
        Binarisation threshold; Otsu's by default.

    Returns
    -------
    Runs
    """
    p = np.asarray(profile, dtype=float).reshape(-1)
    thr = _otsu(p) if threshold is None else float(threshold)
    r = _flat_runs([p], np.array([thr]))
    return Runs(r.edges, r.rising, r.lengths, r.bright, thr)


@dataclass(frozen=True)
class _FlatRuns:
    """The runs of several profiles, one profile's after another's (internal).

    ``edges``, ``rising`` and ``edge_of`` (the profile) per threshold crossing; ``lengths``,
    ``bright`` and ``run_of`` per run (``n_edges + 1`` a profile, the first and last cut by
    the disc's edge); ``run_starts``, each profile's first run."""

    edges: np.ndarray
    rising: np.ndarray
    edge_of: np.ndarray
    n_edges: np.ndarray
    lengths: np.ndarray
    bright: np.ndarray
    run_of: np.ndarray
    run_starts: np.ndarray


def _flat_runs(profiles: list[np.ndarray], thresholds: np.ndarray) -> _FlatRuns:
    """:func:`find_runs` of several non-empty 1-D profiles at given thresholds, worked on
    the profiles laid end to end (no crossing between two profiles).

    (The profiles are few: their own bounds, and their runs' lengths and levels, are laid
    out profile by profile in Python, by slices, rather than by scattering index arrays.)"""
    n = len(profiles)
    sizes = [p.size for p in profiles]
    begin = [0, *itertools.accumulate(sizes)]  # each profile's first value, and the end
    flat = np.concatenate(profiles)
    above = flat > thresholds.repeat(sizes)
    change = above[1:] != above[:-1]  # between i and i + 1
    change[[b - 1 for b in begin[1:-1]]] = False  # not from one profile's last to the next's
    i = change.nonzero()[0]
    cut = i.searchsorted(begin).tolist()  # each profile's first crossing, and the last's end
    n_e = np.array([b - a for a, b in itertools.pairwise(cut)])
    eo = np.arange(n).repeat(n_e)
    a, b = flat[i], flat[1:][i]
    edges = (i - np.array(begin[:-1])[eo]) + (thresholds[eo] - a) / np.where(b != a, b - a, 1.0)
    rising = above[1:][i]
    # each profile's runs: from -0.5 to its first edge, between its edges, from its last
    # edge to its size - 0.5 (one run from -0.5 to size - 0.5 without edges)
    gaps = edges[1:] - edges[:-1]
    ends = edges.tolist()
    lengths = np.empty(edges.size + n)
    bright = np.empty(edges.size + n, bool)
    for k, (e0, e1) in enumerate(itertools.pairwise(cut)):
        r0, r1 = e0 + k, e1 + k  # its first run and its last
        bright[r0] = above[begin[k]]
        if e1 == e0:
            lengths[r0] = (sizes[k] - 0.5) - -0.5
            continue
        lengths[r0] = ends[e0] - -0.5
        lengths[r0 + 1 : r1] = gaps[e0 : e1 - 1]
        lengths[r1] = (sizes[k] - 0.5) - ends[e1 - 1]
        bright[r0 + 1 : r1 + 1] = rising[e0:e1]
    run_starts = np.array([a + k for k, a in enumerate(cut[:-1])])
    run_of = np.arange(n).repeat(n_e + 1)
    return _FlatRuns(edges, rising, eo, n_e, lengths, bright, run_of, run_starts)


def _spacings(r: _FlatRuns) -> tuple[np.ndarray, np.ndarray]:
    """Each profile's same-polarity edge spacings, as :func:`_chip_lengths` takes them: the
    rising edges' first, then the falling edges' (crossings alternate, so those are two
    crossings apart), the positive ones; returns the spacings and their profiles."""
    k = (r.edge_of[2:] == r.edge_of[:-2]).nonzero()[0]  # edge k to edge k + 2
    two = (r.edges[2:] - r.edges[:-2])[k]
    p = r.edge_of[k]
    order = (2 * p + ~r.rising[k]).argsort(kind="stable")  # by profile, rising ones first
    d, p = two[order], p[order]
    keep = d > 0
    return d[keep], p[keep]


#: Chip lengths tried per profile: steps of this many rows, from the profile's shortest
#: spacing over 4.6 to it over 1.6 (2 to 4 chips each).
_CHIP_STEP = 0.01


def _chip_grids(lo: list[float], hi: list[float]) -> tuple[np.ndarray, list[int], np.ndarray]:
    """``np.arange(lo, hi, 0.01)`` of each profile (its ``lo`` and ``hi`` Python floats), one
    row each (as NumPy fills it: ``lo`` plus ``i`` times the step it takes,
    ``(lo + 0.01) - lo``), continued beyond ``hi`` to the longest; each row's length, and
    each row's ``lo`` and step (an array (2, rows))."""
    sizes = [math.ceil((h - low) / _CHIP_STEP) for low, h in zip(lo, hi, strict=True)]
    lo_delta = np.array([lo, [(low + _CHIP_STEP) - low for low in lo]])
    grid = np.arange(max(sizes), dtype=float)[None, :] * lo_delta[1][:, None]
    grid += lo_delta[0][:, None]
    return grid, sizes, lo_delta


def _chip_lengths(r: _FlatRuns, max_rows_per_chip: float) -> np.ndarray:
    """Chip length in rows of each profile from same-polarity edge spacings (2, 3 or 4
    chips each): the grid's best, refined by least squares; NaN where it cannot be told.

    A spacing of ``d`` rows holds ``m = min(round(d / g), 4)`` chips of ``g`` rows (2 at
    least on the grid), 3 or more while ``g < d / 2.5`` and 4 while ``g <= d / 3.5`` (where
    ``m`` changes, both counts are half a chip off: the cost is continuous).  So each grid
    value's cost, ``sum(d^2) - 2 g sum(m d) + g^2 sum(m^2)``, follows from running sums of
    the steps each spacing makes along the grid, not a (spacings, grid) array.  (The few
    values a profile has, its shortest spacing and its grid's ends, are Python floats.)
    """
    n = r.n_edges.size
    d, p = _spacings(r)
    out = np.full(n, np.nan)
    counts = np.bincount(p, minlength=n).tolist()
    if max(counts) < 2:
        return out
    # each profile's spacings in d (sorted by profile), its shortest, and its grid's ends
    bounds = [0, *itertools.accumulate(counts)]
    dl = d.tolist()
    ok, lo, hi, n_d = [], [], [], []
    for k, (a, b) in enumerate(itertools.pairwise(bounds)):
        if b - a < 2:
            continue
        shortest = min(dl[a:b])
        low, high = max(0.8, shortest / 4.6), min(max_rows_per_chip, shortest / 1.6)
        if high > low:  # two spacings or more, and a grid
            ok.append(k), lo.append(low), hi.append(high), n_d.append(b - a)
    if not ok:
        return out
    if len(ok) < n:  # the spacings of the profiles with a grid, q their grid's row
        slot = np.full(n, -1)
        slot[ok] = np.arange(len(ok))
        q = slot[p]
        keep = q >= 0
        d, q = d[keep], q[keep]
        bounds = [0, *itertools.accumulate(n_d)]
    else:
        q = p
    rows = len(ok)
    grid, sizes, lo_delta = _chip_grids(lo, hi)
    size = grid.shape[1]
    # where each spacing's count drops from 4 to 3 chips (row 0) and from 3 to 2 (row 1)
    # along its grid; what each drop takes from sum(m d) and from sum(m^2)
    low_q, delta_q = lo_delta[:, q]
    drops = np.floor((d / _DROPS - low_q) / delta_q) + 1
    at = (q * (size + 1) + np.minimum(np.maximum(drops, 0), size).astype(np.intp)).ravel()
    sums = np.bincount(
        np.concatenate([at, at + rows * (size + 1)]),
        weights=np.concatenate([d, d, _DROP_WEIGHTS.repeat(d.size)]),
        minlength=2 * rows * (size + 1),
    )
    taken = np.add.accumulate(sums.reshape(2, rows, size + 1)[:, :, :size], axis=2)
    sum_d2 = np.bincount(q, weights=d * d, minlength=rows)
    sum_md = 4.0 * np.bincount(q, weights=d, minlength=rows)[:, None] - taken[0]
    sum_mm = 16.0 * np.array(n_d, dtype=float)[:, None] - taken[1]
    cost = sum_d2[:, None] - 2.0 * grid * sum_md + grid * grid * sum_mm
    for k, grid_size in enumerate(sizes):
        cost[k, grid_size:] = np.inf  # beyond the row's own grid

    def exact(k: int, j: np.ndarray) -> np.ndarray:
        # as the grid's terms were first summed: (d / g - m) g, squared
        g = grid[k, j][:, None]
        x = d[bounds[k] : bounds[k + 1]] / g
        x -= np.minimum(np.rint(x), 4.0)
        x *= g
        return np.square(x).sum(axis=1)

    t = grid[range(rows), _grid_best(cost, sum_d2, exact)]
    # least squares refinement: each spacing's chips at the grid's best
    m = np.minimum(np.maximum(np.rint(d / t[q]), 2.0), 4.0)
    mm = np.bincount(q, weights=m * m, minlength=rows)  # (whole numbers: exact sums)
    vm = d * m
    sums = zip(bounds[:-1], bounds[1:], mm.tolist(), strict=True)
    out[ok] = [np.add.reduce(vm[a:b]) / c for a, b, c in sums]
    return out


#: The ratios of a spacing to the chip length at which its count drops from 4 chips to 3,
#: and from 3 to 2 (a column: per spacing, one row each).
_DROPS = np.array([[3.5], [2.5]])
#: What each drop takes from sum(m^2): 16 - 9, then 9 - 4.
_DROP_WEIGHTS = np.array([7.0, 5.0])


#: Bleeding values tried per profile (-0.95 to 0.95 chip).
_BLEED_STEPS = 191


def _bleed_grids(t: np.ndarray) -> np.ndarray:
    """``np.linspace(-0.95 t, 0.95 t, 191)`` of each chip length ``t`` (rows), one row each:
    steps of ``(stop - start) / 190`` from ``start``, ``stop`` itself last."""
    start, stop = -0.95 * t, 0.95 * t
    y = (
        np.arange(_BLEED_STEPS, dtype=float)[None, :]
        * ((stop - start) / (_BLEED_STEPS - 1))[:, None]
    )
    y += start[:, None]
    y[:, -1] = stop
    return y


def _step_sums(at: np.ndarray, weights: np.ndarray, size: int, rows: int) -> np.ndarray:
    """Per row and grid value ``j``, the sum of the weights of the steps ``at`` (flat
    ``row * (size + 1) + k``) with ``k <= j``: steps placed on a grid of ``size`` values,
    summed along it (a (rows, size) array)."""
    placed = np.bincount(at, weights=weights, minlength=rows * (size + 1))
    return np.add.accumulate(placed.reshape(rows, size + 1)[:, :size], axis=1)


#: Costs within this fraction of their scale of a grid's least are computed again, term by
#: term, before one is taken (the grid's running sums round otherwise than a sum of terms).
_TIE = 1e-9


def _grid_best(cost: np.ndarray, scale: np.ndarray, exact) -> np.ndarray:
    """Each row's grid index of least ``cost`` (rows, grid): where several come within
    :data:`_TIE` times the row's ``scale`` of the least (a tie, up to rounding), the first
    least of ``exact(row, indices)``, their costs computed term by term."""
    best = cost.argmin(axis=1)
    near = cost <= (np.minimum.reduce(cost, axis=1) + _TIE * scale)[:, None]
    for q in (np.add.reduce(near, axis=1) > 1).nonzero()[0].tolist():
        j = near[q].nonzero()[0]
        best[q] = j[int(exact(q, j).argmin())]
    return best


def _bleeds(r: _FlatRuns, t: np.ndarray, which: np.ndarray) -> np.ndarray:
    """Bleeding of the profiles ``which`` (four edges or more), rows: bright runs are b rows
    longer, dark ones b rows shorter, than n chips; the b of the grid that makes every
    interior run closest to one or two chips (both kinds occur in every frame, which pins b
    down).

    A run of ``l`` rows holds ``n = 1 + (x >= 1.5)`` chips, ``x = (l - b) / t`` for a
    bright run, ``(l + b) / t`` for a dark one; its squared residual ``(x - n)^2`` is
    ``(c - b)^2 / t^2`` with ``c = l - n t`` (bright) or ``n t - l`` (dark), and ``n``
    changes once along the grid, where ``x = 1.5`` (continuously: there both counts are
    half a chip off): ``c`` grows by ``t`` there.  So each grid value's cost,
    ``sum(c^2) - 2 b sum(c) + runs b^2`` (over ``t^2``, the same for the whole grid),
    follows from running sums of those steps along the grid, not a (runs, grid) array.
    """
    first = r.run_starts
    interior = np.ones(r.lengths.size, bool)
    interior[first] = False
    interior[first + r.n_edges] = False
    if which.size < r.n_edges.size:  # q: the run's profile's place in which
        slot = np.full(r.n_edges.size, -1)
        slot[which] = np.arange(which.size)
        q = slot[r.run_of]
        interior &= q >= 0
    else:
        q = r.run_of
    q, lengths, bright = q[interior], r.lengths[interior], r.bright[interior]
    n_q, tt = which.size, t[which]
    grid = _bleed_grids(tt)
    tq = tt[q]
    sign = np.where(bright, 1.0, -1.0)
    c_low = sign * (lengths - np.where(bright, 2.0, 1.0) * tq)  # c on the grid's low side
    c_high = c_low + tq
    # the grid index from which x < 1.5 (bright) or x >= 1.5 (dark)
    start, step = grid[:, 0], (grid[:, -1] - grid[:, 0]) / (_BLEED_STEPS - 1)
    at = np.floor((sign * (lengths - 1.5 * tq) - start[q]) / step[q]) + 1
    at = q * (_BLEED_STEPS + 1) + np.minimum(np.maximum(at, 0), _BLEED_STEPS).astype(np.intp)
    # the steps of sum(c) and of sum(c^2), summed along the grid in one go (each row alone)
    steps = _step_sums(
        np.concatenate([at, at + n_q * (_BLEED_STEPS + 1)]),
        np.concatenate([tq, c_high * c_high - c_low * c_low]),
        _BLEED_STEPS,
        2 * n_q,
    )
    sum_c = np.bincount(q, weights=c_low, minlength=n_q)[:, None] + steps[:n_q]
    low2 = np.bincount(q, weights=c_low * c_low, minlength=n_q)
    sum_c2 = low2[:, None] + steps[n_q:]
    runs = r.n_edges[which] - 1  # (a profile's runs but its two cut ones)
    cost = sum_c2 - 2.0 * grid * sum_c + runs[:, None] * (grid * grid)

    def exact(k: int, j: np.ndarray) -> np.ndarray:
        # as the grid's terms were first summed: (l - g) / t for a bright run, (-l - g) / -t
        # for a dark one, then its squared distance from one or two chips
        a = int(np.searchsorted(q, k))
        s, ls = sign[a : a + runs[k]], lengths[a : a + runs[k]]
        x = (s * ls - grid[k, j][:, None]) / (s * tt[k])
        x -= np.clip(np.rint(x), 1.0, 2.0)
        return np.square(x).sum(axis=1)

    scale = low2 + 4.0 * runs * tt * tt
    return grid[np.arange(n_q), _grid_best(cost, scale, exact)]


def _chips(r: _FlatRuns, t: np.ndarray, b: np.ndarray, which: np.ndarray):
    """The chips read from the runs of the profiles ``which`` (chip length ``t`` and
    bleeding ``b`` each, rows): per profile its chips (uint8), which of them are sure, the
    chips as text (``?`` where unsure) and its run margin."""
    n = r.n_edges.size
    if which.size < n:  # (the other profiles' runs read at t = 1, b = 0, then left out)
        tt, bb = np.ones(n), np.zeros(n)
        tt[which], bb[which] = t, b
        t_run, b_run = tt[r.run_of], bb[r.run_of]
    else:
        t_run, b_run = t[r.run_of], b[r.run_of]
    x = np.where(r.bright, r.lengths - b_run, r.lengths + b_run) / t_run
    whole = np.rint(x)
    counts = whole.astype(int)
    sure = (counts >= 1) & (counts <= 2)
    np.minimum(np.maximum(counts, 1), 2, out=counts)  # one chip or two
    # runs cut by the disc's edge: count only the chips surely inside
    first = r.run_starts
    ends = np.concatenate([first, first + r.n_edges])
    counts[ends] = np.minimum(np.maximum(np.floor(x[ends] + 0.25), 0), 2)
    sure[ends] = True
    dev = np.abs(x - whole)
    dev[ends] = -1.0
    worst = np.maximum.reduceat(dev, first)[which]
    bounds = [0, *np.add.reduceat(counts, first)[which].cumsum().tolist()]
    bright = r.bright
    if which.size < n:  # the runs of the profiles read only
        kept = np.zeros(n, bool)
        kept[which] = True
        kept = kept[r.run_of]
        bright, counts, sure = bright[kept], counts[kept], sure[kept]
    chip_vals = bright.astype(np.uint8).repeat(counts)
    known = sure.repeat(counts)
    text = np.where(known, chip_vals + ord("0"), ord("?")).astype(np.uint8).tobytes().decode()
    return [
        (
            chip_vals[c0:c1],
            known[c0:c1],
            text[c0:c1],
            min(max(1.0 - 2.0 * w, 0.0), 1.0),
        )
        for c0, c1, w in zip(bounds[:-1], bounds[1:], worst.tolist(), strict=True)
    ]


def _refused(reason: str, **kw) -> StripeDecode:
    fields = dict(method="runs", run_margin=0.0, frames=0.0)
    fields.update(kw)
    return StripeDecode(None, reason, **fields)


def _verdicts(read, t: np.ndarray, b: np.ndarray, frame: FrameFormat) -> list[StripeDecode]:
    """Each profile's decode from its chips (``read`` as :func:`_chips` gives them): the
    ID of the whole stretch, which every whole copy of the frame must agree with.

    Only the copies of a stretch read as an ID with chips in error are decoded: where none
    is, each copy's known chips are a rotation of that ID's frame, so a copy reads as that ID
    (every chip known) or as none (one unknown, not a whole frame), never another."""
    n = frame.n_chips
    whole = frame.decode_many([(chips, known) for chips, known, _, _ in read])
    checked = [k for k, res in enumerate(whole) if res and res.distance > 0]
    spans = [range(0, read[k][0].size - n + 1, n) for k in checked]
    copies = [
        (read[k][0][j : j + n], read[k][1][j : j + n])
        for k, span in zip(checked, spans, strict=True)
        for j in span
    ]
    decoded = iter(frame.decode_many(copies))
    others = dict.fromkeys(range(len(read)))
    for k, span in zip(checked, spans, strict=True):
        subs = [next(decoded) for _ in span]
        others[k] = next((s.id for s in subs if s.id is not None and s.id != whole[k].id), None)
    out = []
    for k, ((chips, _, text, margin), rpc, bleed) in enumerate(
        zip(read, t.tolist(), b.tolist(), strict=True)
    ):
        res, other = whole[k], others[k]
        frames = chips.size / n
        common = dict(rows_per_chip=rpc, bleed_rows=bleed, chips=text, frames=frames)
        if not res:
            out.append(_refused(res.reason, hamming=res.distance, **common))
        elif other is not None:
            reason = f"copies of the frame disagree ({res.id} and {other})"
            out.append(_refused(reason, hamming=res.distance, **common))
        else:
            out.append(
                StripeDecode(res.id, "", "runs", run_margin=margin, hamming=res.distance, **common)
            )
    return out


def decode_profile(
    profile: np.ndarray,
    frame: FrameFormat,
    *,
    rows_per_chip: float | None = None,
    max_rows_per_chip: float = 64.0,
    threshold_level: float = 0.6,
) -> StripeDecode:
    """Decode the ID carried by a fixture's row profile.

    Parameters
    ----------
    profile : ndarray, shape (n,)
        Mean intensity per sensor row across the disc, in readout order.
    frame : FrameFormat
        The frame format of the map.
    rows_per_chip : float, optional
        Known chip length in rows (chip duration / row time); measured when None.
    max_rows_per_chip : float
        Longest chip length considered when measuring it.
    threshold_level : float
        Binarisation threshold (see :func:`stripe_threshold`).

    Returns
    -------
    StripeDecode
        Falsy, with a reason, when the stripes do not give one ID with confidence.
    """
    return decode_profiles(
        [profile],
        frame,
        rows_per_chip=rows_per_chip,
        max_rows_per_chip=max_rows_per_chip,
        threshold_level=threshold_level,
    )[0]


def decode_profiles(
    profiles,
    frame: FrameFormat,
    *,
    rows_per_chip: float | None = None,
    max_rows_per_chip: float = 64.0,
    threshold_level: float = 0.6,
) -> list[StripeDecode]:
    """:func:`decode_profile` of several profiles (sequence of 1-D arrays), the same
    decodes, each step worked for all of them at once."""
    ps = [np.asarray(p, dtype=float).reshape(-1) for p in profiles]
    out: list[StripeDecode | None] = [None] * len(ps)
    live = [k for k, p in enumerate(ps) if p.size >= 8]
    for k, p in enumerate(ps):
        if p.size < 8:
            out[k] = _refused(f"too small to decode ({p.size} rows)")
    if live:
        levels = _level_list([ps[k] for k in live])
        thresholds = []
        for k, lo, hi in zip(live, levels[0::2], levels[1::2], strict=True):
            if hi - lo < 8:
                out[k] = _refused("no stripes (a steady light, or too little contrast)")
            else:
                thresholds.append(lo + threshold_level * (hi - lo))
        live = [k for k in live if out[k] is None]
    if not live:
        return out
    r = _flat_runs([ps[k] for k in live], np.array(thresholds))
    if rows_per_chip:
        t = np.full(len(live), float(rows_per_chip))
    else:
        t = _chip_lengths(r, max_rows_per_chip)
    few = r.n_edges < 4
    irregular = ~few & ~(np.isfinite(t) & (t > 0))
    for q, k in enumerate(live):
        if few[q]:
            out[k] = _refused("no stripes (a steady light, or too few stripes)")
        elif irregular[q]:
            out[k] = _refused("stripes too irregular to measure the chip length")
    which = (~few & ~irregular).nonzero()[0]
    if which.size:
        b = _bleeds(r, t, which)
        read = _chips(r, t[which], b, which)
        for q, d in zip(which.tolist(), _verdicts(read, t[which], b, frame), strict=True):
            out[live[q]] = d
    return out
