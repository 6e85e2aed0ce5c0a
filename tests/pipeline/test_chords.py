"""The clipped chords of a region's lines (camvlp.pipeline.detect.chords)."""

from __future__ import annotations

import numpy as np
import pytest

from camvlp.pipeline.detect.chords import _clipped_chords, chord_seeds


def _clipped_disc(holes: float, seed: int = 0) -> tuple[np.ndarray, int, int, int]:
    """A 240 x 240 gray region holding one disc (centre (120, 110), radius 60 px) clipped
    in every other band of 6 lines along the rows, its glow under the clipping level, and a
    share ``holes`` of the disc's clipped pixels set under it (a phone's mosaic and JPEG)."""
    yy, xx = np.mgrid[0:240, 0:240]
    r = np.hypot(xx - 120, yy - 110)
    gray = np.clip(180 * np.exp(-np.maximum(r - 60, 0) / 30), 0, 180).astype(np.uint8)
    on = (yy // 6) % 2 == 0
    disc = (r <= 60) & on
    gray[disc] = 255
    rng = np.random.default_rng(seed)
    hole = disc & (rng.random(gray.shape) < holes)
    gray[hole] = 200
    return gray, 120, 110, 60


@pytest.mark.parametrize("holes", [0.0, 0.03])
def test_each_line_of_a_clipped_disc_is_one_chord_whatever_pixels_dip(holes):
    gray, cx, cy, radius = _clipped_disc(holes)
    line, middle, half = _clipped_chords(gray, "rows", 4.0)  # a line per row
    assert np.unique(line).size == line.size  # one chord per line
    np.testing.assert_allclose(middle, cx, atol=1.0)
    want = np.sqrt(np.maximum(radius**2 - (line - cy) ** 2, 0))
    assert np.all(np.abs(half - want) <= 1.5)


@pytest.mark.parametrize("holes", [0.0, 0.03])
def test_a_clipped_disc_with_dips_is_one_light(holes):
    # (with its clipped runs broken by the dips, one disc was four lights: a phone photo's
    # lamp read as five)
    gray, cx, cy, radius = _clipped_disc(holes, seed=1)
    inside = np.ones((80, 80), np.uint8)  # the region, reduced 3 times
    lights = chord_seeds(gray, inside, "rows", 3, 3.0)
    assert len(lights) == 1
    assert np.hypot(lights[0, 0] * 3 - cx, lights[0, 1] * 3 - cy) < 3
    assert abs(lights[0, 2] * 3 - radius) < 3
