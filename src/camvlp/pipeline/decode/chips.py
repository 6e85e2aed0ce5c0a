"""The chips a profile's runs hold: the chip length, the bleeding, and each run's count.

In Manchester code, edges of the same polarity (rising to rising, falling to falling) are 2,
3 or 4 chips apart whatever the bleeding: :func:`chip_lengths` measures the chip length from
those spacings.  Bright runs of a saturated sensor are longer, and dark runs shorter, than
their chips by the same amount (the bleeding): :func:`bleeds` measures it from the interior
runs, each of which must be one chip long or two.  :func:`read_chips` then counts each run's
chips, with separate thresholds for bright and dark runs, and enters the runs cut by the
disc's edge only for the chips they surely hold.  Each works on all of a photo's profiles
at once (:class:`~camvlp.pipeline.decode.runs.FlatRuns`), its grid searches costed by
running sums along the grid.
"""

from __future__ import annotations

import functools
import itertools
import math

import numpy as np

from camvlp.pipeline.decode.runs import FlatRuns

__all__ = ["bleeds", "chip_lengths", "read_chips"]


def _spacings(r: FlatRuns) -> tuple[np.ndarray, np.ndarray]:
    """Each profile's same-polarity edge spacings, as :func:`chip_lengths` takes them: the
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


def chip_lengths(r: FlatRuns, max_rows_per_chip: float) -> np.ndarray:
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
    ok, lo, hi = _chip_grid_ends(d, counts, max_rows_per_chip)
    if not ok:
        return out
    n_d = [counts[k] for k in ok]  # the spacings of each profile with a grid
    if len(ok) < n:  # the spacings of the profiles with a grid, q their grid's row
        slot = np.full(n, -1)
        slot[ok] = np.arange(len(ok))
        q = slot[p]
        keep = q >= 0
        d, q = d[keep], q[keep]
    else:
        q = p
    bounds = [0, *itertools.accumulate(n_d)]  # each grid row's spacings in d
    grid, cost, sum_d2 = _chip_costs(d, q, lo, hi, n_d)
    best = _grid_best(cost, sum_d2, functools.partial(_chip_costs_exact, grid, d, bounds))
    out[ok] = _least_squares(d, q, grid[range(len(ok)), best], bounds)
    return out


def _chip_grid_ends(
    d: np.ndarray, counts: list[int], max_rows_per_chip: float
) -> tuple[list[int], list[float], list[float]]:
    """The profiles with two spacings or more and a grid of chip lengths: their indices, and
    their grids' ends (rows): from the profile's shortest spacing over 4.6 (at least 0.8)
    to it over 1.6 (at most ``max_rows_per_chip``).  ``d``: the spacings sorted by profile,
    ``counts`` of each profile."""
    bounds = [0, *itertools.accumulate(counts)]
    dl = d.tolist()
    ok, lo, hi = [], [], []
    for k, (a, b) in enumerate(itertools.pairwise(bounds)):
        if b - a < 2:
            continue
        shortest = min(dl[a:b])
        low, high = max(0.8, shortest / 4.6), min(max_rows_per_chip, shortest / 1.6)
        if high > low:
            ok.append(k), lo.append(low), hi.append(high)
    return ok, lo, hi


def _chip_costs(
    d: np.ndarray, q: np.ndarray, lo: list[float], hi: list[float], n_d: list[int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cost of every chip length on each profile's grid (:func:`chip_lengths`), from
    running sums of the steps its spacings ``d`` (of grid row ``q``) make along it: the
    grids (rows, size), the costs (inf beyond a row's own grid) and each row's
    ``sum(d^2)``."""
    rows = len(lo)
    grid, sizes, lo_delta = _chip_grids(lo, hi)
    size = grid.shape[1]
    # where each spacing's count drops from 4 to 3 chips (row 0) and from 3 to 2 (row 1)
    # along its grid; what each drop takes from sum(m d) and from sum(m^2)
    low_q, delta_q = lo_delta[:, q]
    drops = np.floor((d / _DROPS - low_q) / delta_q) + 1
    at = (q * (size + 1) + np.minimum(np.maximum(drops, 0), size).astype(np.intp)).ravel()
    taken = _step_sums(
        np.concatenate([at, at + rows * (size + 1)]),
        np.concatenate([d, d, _DROP_WEIGHTS.repeat(d.size)]),
        size,
        2 * rows,
    )
    sum_d2 = np.bincount(q, weights=d * d, minlength=rows)
    sum_md = 4.0 * np.bincount(q, weights=d, minlength=rows)[:, None] - taken[:rows]
    sum_mm = 16.0 * np.array(n_d, dtype=float)[:, None] - taken[rows:]
    cost = sum_d2[:, None] - 2.0 * grid * sum_md + grid * grid * sum_mm
    for k, grid_size in enumerate(sizes):
        cost[k, grid_size:] = np.inf  # beyond the row's own grid
    return grid, cost, sum_d2


def _chip_costs_exact(
    grid: np.ndarray, d: np.ndarray, bounds: list[int], k: int, j: np.ndarray
) -> np.ndarray:
    """The costs of grid row ``k``'s chip lengths ``j``, term by term as the grid's terms
    were first summed: ``(d / g - m) g``, squared, over the row's spacings."""
    g = grid[k, j][:, None]
    x = d[bounds[k] : bounds[k + 1]] / g
    x -= np.minimum(np.rint(x), 4.0)
    x *= g
    return np.square(x).sum(axis=1)


def _least_squares(d: np.ndarray, q: np.ndarray, t: np.ndarray, bounds: list[int]) -> list:
    """Each grid row's chip length refined by least squares: each spacing's chips ``m``
    counted at the grid's best ``t``, then ``sum(m d) / sum(m^2)``."""
    m = np.minimum(np.maximum(np.rint(d / t[q]), 2.0), 4.0)
    mm = np.bincount(q, weights=m * m, minlength=t.size)  # (whole numbers: exact sums)
    vm = d * m
    sums = zip(bounds[:-1], bounds[1:], mm.tolist(), strict=True)
    return [vm[a:b].sum() / c for a, b, c in sums]


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
    return np.cumsum(placed.reshape(rows, size + 1)[:, :size], axis=1)


#: Costs within this fraction of their scale of a grid's least are computed again, term by
#: term, before one is taken (the grid's running sums round otherwise than a sum of terms).
_TIE = 1e-9


def _grid_best(cost: np.ndarray, scale: np.ndarray, exact) -> np.ndarray:
    """Each row's grid index of least ``cost`` (rows, grid): where several come within
    :data:`_TIE` times the row's ``scale`` of the least (a tie, up to rounding), the first
    least of ``exact(row, indices)``, their costs computed term by term."""
    best = cost.argmin(axis=1)
    near = cost <= (cost.min(axis=1) + _TIE * scale)[:, None]
    for q in (near.sum(axis=1) > 1).nonzero()[0].tolist():
        j = near[q].nonzero()[0]
        best[q] = j[int(exact(q, j).argmin())]
    return best


def bleeds(r: FlatRuns, t: np.ndarray, which: np.ndarray) -> np.ndarray:
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


def read_chips(r: FlatRuns, t: np.ndarray, b: np.ndarray, which: np.ndarray):
    """The chips read from the runs of the profiles ``which`` (chip length ``t`` and
    bleeding ``b`` each, rows): per profile its chips (uint8), which of them are sure, the
    chips as text (``?`` where unsure), its run margin (its worst interior run's), and each
    chip's confidence, float (its run's margin: ``1 - 2 |x - round(x)|`` of its length ``x``
    in chips, clipped to 0 to 1; 1 for the runs the disc's edge cuts, counted only for the
    chips surely inside)."""
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
    conf = np.clip(1.0 - 2.0 * dev, 0.0, 1.0)
    if which.size < n:
        conf = conf[kept]
    chip_vals = bright.astype(np.uint8).repeat(counts)
    known = sure.repeat(counts)
    chip_conf = conf.repeat(counts)
    text = np.where(known, chip_vals + ord("0"), ord("?")).astype(np.uint8).tobytes().decode()
    return [
        (
            chip_vals[c0:c1],
            known[c0:c1],
            text[c0:c1],
            min(max(1.0 - 2.0 * w, 0.0), 1.0),
            chip_conf[c0:c1],
        )
        for c0, c1, w in zip(bounds[:-1], bounds[1:], worst.tolist(), strict=True)
    ]
