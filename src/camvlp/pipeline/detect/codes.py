"""Whether two peaks of one lit region are two lights by their codes: every sensor line along
the readout is exposed at the same instants, so one light's stripes are the same on every line
through it, and two lights (two IDs, or two frequencies) make different ones.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["CODES_APART", "CODES_CLEAR", "codes_differ"]

#: Two peaks are two lights when the stripes along the readout through them correlate less
#: than this fraction of what each one's stripes correlate with a line nearby in its own light.
CODES_APART = 0.5
#: Least correlation of a line's stripes with a nearby line of its own light for the stripes
#: to tell two lights apart (below it, noise would).
CODES_CLEAR = 0.8
#: Fewest stripes (runs) two lines along the readout must share to be compared.
_CODE_RUNS = 6


def _correlation(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson correlation of two 1-D arrays (0 when one is constant)."""
    a, b = a - a.mean(), b - b.mean()
    den = float(np.sqrt(np.dot(a, a) * np.dot(b, b)))
    return float(np.dot(a, b)) / den if den > 0 else 0.0


def codes_differ(
    gray: np.ndarray, inside: np.ndarray, a: np.ndarray, b: np.ndarray, axis: str, scale: int
) -> bool:
    """Whether two peaks of one lit region show different codes in their stripes.

    Every line along the readout is exposed at the same instants, so one light's stripes
    are the same on every line through it, and two lights (two IDs, or two frequencies)
    make different ones.  The lines through the two peaks (three lines each, averaged) are
    compared over the stretch of the readout both lie in the region, their smooth shape
    (the light's envelope) taken out; they differ when their correlation is under
    :data:`CODES_APART` times the least of each line's correlation with a line half its
    peak's radius towards the other peak (within its own light), and that is at least
    :data:`CODES_CLEAR`.  Peaks apart along the readout share too little of it: False.

    Parameters
    ----------
    gray : ndarray of uint8, shape (h * scale, w * scale) or larger
        The region at full resolution, gray levels.
    inside : ndarray of uint8, shape (h, w)
        The region (nonzero) in the reduced photo's pixels.
    a, b : ndarray, shape (3,)
        The peaks ``[x, y, r]`` in ``inside``'s pixels.
    axis : {"rows", "columns"}
        The readout axis.
    scale : int
        Full-resolution pixels per reduced pixel.
    """
    g = gray if axis == "columns" else gray.T  # g[line, t]: t along the readout
    m = inside if axis == "columns" else inside.T
    ia = 1 if axis == "columns" else 0  # the peaks' coordinate across the readout
    n_lines, n_t = g.shape

    def lines(p: np.ndarray, toward: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """The line through ``p`` and the line half its radius towards ``toward`` (each
        three lines averaged), and where each lies in the region, along the readout."""
        step = 0.5 * float(p[2]) * np.sign(toward[ia] - p[ia])
        at = [float(p[ia]), float(p[ia]) + step]  # reduced pixels
        full = [round(a * scale) for a in at]
        if not all(1 <= f < n_lines - 1 for f in full):
            return None
        rows = [min(round(a), m.shape[0] - 1) for a in at]
        lit = np.repeat(m[rows] > 0, scale, axis=1)[:, :n_t]
        lit = np.pad(lit, ((0, 0), (0, n_t - lit.shape[1])))
        return np.stack([g[f - 1 : f + 2].mean(axis=0) for f in full]), lit

    got_a, got_b = lines(a, b), lines(b, a)
    if got_a is None or got_b is None:
        return False
    (pair_a, lit_a), (pair_b, lit_b) = got_a, got_b
    common = np.all(lit_a, axis=0) & np.all(lit_b, axis=0)
    if np.count_nonzero(common) < 4 * _CODE_RUNS:
        return False
    la = pair_a[0][common]
    cut = la > 0.5 * (la.min() + la.max())  # (a median is the clipping level where it clips)
    runs = np.count_nonzero(cut[1:] != cut[:-1]) + 1
    if runs < _CODE_RUNS:
        return False
    sigma = 2.0 * np.count_nonzero(common) / runs  # two runs' length
    four = np.concatenate([pair_a, pair_b]).astype(np.float32)
    smooth = cv2.GaussianBlur(four, (0, 0), sigmaX=sigma, sigmaY=1e-3)
    hp = (four - smooth)[:, common]
    ref = min(_correlation(hp[0], hp[1]), _correlation(hp[2], hp[3]))
    return ref >= CODES_CLEAR and _correlation(hp[0], hp[2]) < CODES_APART * ref
