"""Large sites: a grid of ceiling fixtures that reuse a short frame's few IDs.

:func:`site_map` lays fixtures out on a rectangular grid of the ceiling and gives them IDs
either so that no two fixtures within two grid steps of each other share one (``"varied"``:
each place's neighbourhood then differs from the others', and a photo of a few fixtures says
where it was taken) or periodically (``"periodic"``: every four steps the same pattern, so
that no photo can tell its place from the others of the pattern).  The map says
``reuse: true`` (:attr:`camvlp.model.fixtures.FixtureMap.reuse`).
"""

from __future__ import annotations

import numpy as np

from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.model.linecode import FrameFormat

__all__ = ["PATTERNS", "site_map"]

#: How :func:`site_map` assigns IDs.
PATTERNS = ("varied", "periodic")


def _varied_ids(columns: int, rows: int, n_ids: int, rng: np.random.Generator) -> np.ndarray:
    """IDs for a ``rows`` x ``columns`` grid, shape (rows, columns): each drawn at random
    among those no fixture within two steps (along both axes) already has, in raster order."""
    ids = np.full((rows + 2, columns + 4), -1, dtype=np.int64)  # padded by two on three sides
    for r in range(rows):
        for c in range(columns):
            near = ids[r : r + 3, c : c + 5].ravel()  # the rows above and this row's left
            free = np.setdiff1d(np.arange(n_ids), near)
            ids[r + 2, c + 2] = rng.choice(free if free.size else np.arange(n_ids))
    return ids[2:, 2:-2]


def site_map(
    columns: int,
    rows: int,
    *,
    spacing: float = 1.0,
    height: float = 3.0,
    diameter: float = 0.4,
    pattern: str = "varied",
    frame: FrameFormat | None = None,
    seed: int = 0,
) -> FixtureMap:
    """A site's map: ``columns`` x ``rows`` fixtures on a ceiling grid, IDs reused.

    Parameters
    ----------
    columns, rows : int
        Fixtures along x and along y.
    spacing : float
        Distance between neighbouring fixtures, metres (the grid starts at x = y = 0).
    height : float
        The ceiling's z, metres: the fixtures face down (normal (0, 0, -1)), ``up`` is +z.
    diameter : float
        Each fixture's disc, metres.
    pattern : {"varied", "periodic"}
        ``"varied"``: random IDs (seeded), no two within two grid steps alike;
        ``"periodic"``: ``(column % 4) + 4 * (row % 4)`` taken modulo the frame's IDs, the
        same pattern every four steps.
    frame : FrameFormat, optional
        The frame (the thesis' 4-bit one by default): IDs run from 0 to ``2**id_bits - 1``.
    seed : int
        Seed of the varied pattern's draws.

    Returns
    -------
    FixtureMap
        ``columns * rows`` fixtures in metres, ``reuse`` True.

    Raises
    ------
    ValueError
        A grid side under 1, a spacing, height or diameter not positive, an unknown pattern.
    """
    if columns < 1 or rows < 1:
        raise ValueError(f"a site needs at least one fixture a side, got {columns} x {rows}")
    if not (spacing > 0 and diameter > 0 and np.isfinite(height)):
        raise ValueError("spacing and diameter must be positive, height finite")
    if pattern not in PATTERNS:
        raise ValueError(f"pattern must be one of {', '.join(PATTERNS)}, got {pattern!r}")
    frame = frame or FrameFormat()
    n_ids = 2**frame.id_bits
    if pattern == "varied":
        ids = _varied_ids(columns, rows, n_ids, np.random.default_rng(seed))
    else:
        r, c = np.mgrid[0:rows, 0:columns]
        ids = ((c % 4) + 4 * (r % 4)) % n_ids
    r, c = np.mgrid[0:rows, 0:columns]
    xyz = np.stack([c * spacing, r * spacing, np.full(c.shape, float(height))], axis=-1)
    down = np.array([0.0, 0.0, -1.0])
    fixtures = tuple(
        Fixture(int(i), p, float(diameter), down)
        for i, p in zip(ids.ravel().tolist(), xyz.reshape(-1, 3), strict=True)
    )
    return FixtureMap(fixtures, frame=frame, up=np.array([0.0, 0.0, 1.0]), reuse=True)
