"""Groups of values laid one after another in one flat array (a photo's lights, profiles or
runs worked at once): where each group begins, and the pieces back."""

from __future__ import annotations

import itertools

import numpy as np

__all__ = ["pieces", "starts"]


def starts(counts: np.ndarray) -> np.ndarray:
    """Where each group begins, given how many values each has (``counts``, (G,))."""
    out = np.zeros(counts.size, np.intp)
    np.add.accumulate(counts[:-1], out=out[1:])  # (ndarray.cumsum's wrapping costs as much)
    return out


def pieces(cuts: np.ndarray, size: int) -> list[tuple[int, int]]:
    """``(start, end)`` of the pieces ``np.split`` cuts ``size`` values into at ``cuts``
    (without its cost: slice with them)."""
    return list(itertools.pairwise([0, *cuts.tolist(), size]))
