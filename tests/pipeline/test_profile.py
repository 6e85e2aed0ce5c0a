"""Row profiles' weights (camvlp.pipeline.decode.profile): each line's inverse variance."""

from __future__ import annotations

import numpy as np

from camvlp.pipeline.decode.profile import _trimmed, row_profile, shape_profiles


def _disc(radius: float, size: int = 120) -> np.ndarray:
    """Each pixel's distance from the disc's centre (59.6, 60.3), in radii, shape (size, size)."""
    yy, xx = np.mgrid[0:size, 0:size].astype(float)
    return np.hypot(xx - 59.6, yy - 60.3) / radius


def test_a_flat_lights_lines_weigh_as_many_as_their_pixels():
    # a row mean of c pixels of equal noise has 1 / c of their variance
    rho = _disc(40.0)
    img = np.where(rho <= 1, 200, 10).astype(np.uint8)  # flat
    mask = rho <= 1
    ((prof, first, weight),) = shape_profiles(
        [img], [mask], "rows", [np.array([59.6, 60.3])], [np.full(2, 80.0)], [0.0]
    )
    ref, ref_first = row_profile(img, mask, "rows")
    np.testing.assert_array_equal(prof, ref)  # the profile itself as before
    assert first == ref_first
    # the pixels each line keeps (the disc's rim trimmed as the profile trims it)
    pixels = _trimmed(mask).sum(axis=1)[first : first + prof.size]
    np.testing.assert_array_equal(weight, pixels)
    assert weight[2] < 0.5 * weight[prof.size // 2]  # the ends weigh less than the middle


def test_a_shaped_lights_lines_weigh_as_their_on_levels_squared_over_pixels():
    # value = sum(pixels) / sum(on-levels): with pixels of equal noise its variance is
    # pixels / sum(on-levels)^2, so a line through a hot core weighs more than one as long
    # through the rim only
    rho = _disc(40.0)
    shape = np.where(rho <= 1, 60.0 + 180.0 * np.exp(-((rho / 0.35) ** 2)), 0.0)
    img = np.round(shape).astype(np.uint8)
    mask = rho <= 1
    ((prof, first, weight),) = shape_profiles(
        [img], [mask], "rows", [np.array([59.6, 60.3])], [np.full(2, 80.0)], [0.0]
    )
    assert weight.shape == prof.shape and np.all(weight >= 0)
    line = np.arange(prof.size) + first
    centre_line = int(np.argmin(np.abs(line - 60.3)))
    off_line = int(np.argmin(np.abs(line - (60.3 + 30.0))))
    # the centre line crosses the core: its on-levels' sum grows faster than its pixels
    pixels_ratio = np.sqrt(40.0**2 - 0.3**2) / np.sqrt(40.0**2 - 30.0**2)
    assert weight[centre_line] / weight[off_line] > 2.0 * pixels_ratio
