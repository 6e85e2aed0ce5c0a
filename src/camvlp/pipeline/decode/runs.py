"""A row profile binarised, and its bright and dark runs measured to a fraction of a row.

A profile's dark and bright levels are its 2nd and 98th percentiles (:func:`stripe_levels`);
it is cut at a threshold between them (:func:`stripe_threshold`, or Otsu's two-class split
of the profile, the principled form of the thesis' "two peaks of the histogram"), and each
threshold crossing is placed between its two rows by linear interpolation: the stripes'
edges, and the runs' lengths between them (:func:`find_runs`).  :func:`flat_runs` does so
for all of a photo's profiles at once.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "FlatRuns",
    "Runs",
    "find_runs",
    "flat_runs",
    "stripe_levels",
    "stripe_levels_many",
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


def stripe_levels_many(profiles: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """:func:`stripe_levels` of several non-empty 1-D profiles: (dark, bright) arrays."""
    out = _level_list(profiles)
    return np.array(out[0::2]), np.array(out[1::2])


def _level_list(profiles: list[np.ndarray]) -> list[float]:
    """:func:`stripe_levels` of several non-empty 1-D profiles, one after another in a list
    of Python floats (dark, bright, dark, ...).

    Linear percentiles (NumPy's default method), each profile sorted in a row of its own
    (NaN after its values, where NaN sorts); the few values each needs gathered at once and
    interpolated up from the lower one.  (``np.percentile`` interpolates down from the upper
    one past half-way, so the two can differ in the last bit; one ``np.percentile`` call per
    profile would cost about half again the whole run-length decode.)"""
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
    r = flat_runs([p], np.array([thr]))
    return Runs(r.edges, r.rising, r.lengths, r.bright, thr)


@dataclass(frozen=True)
class FlatRuns:
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


def flat_runs(profiles: list[np.ndarray], thresholds: np.ndarray) -> FlatRuns:
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
    return FlatRuns(edges, rising, eo, n_e, lengths, bright, run_of, run_starts)
