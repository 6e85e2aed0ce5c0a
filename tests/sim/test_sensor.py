"""Tests of the sensor and a phone's processing (camvlp.sim.sensor)."""

from __future__ import annotations

import numpy as np
import pytest

from camvlp.sim.render import RenderSettings
from camvlp.sim.sensor import RAW_WHITE, develops, expose

QUIET = dict(ambient=0.0, full_well_e=0.0, read_noise=0.0)


def _flat(level, size=(48, 64)) -> tuple:
    """One patch covering a (height, width) photo with BGR light ``level``."""
    h, w = size
    return (0, h, 0, w, np.ones((h, w, 3), np.float32) * np.asarray(level, np.float32))


def test_default_settings_keep_the_plain_sensor():
    assert not develops(RenderSettings())
    for kw in (
        dict(bayer=True),
        dict(gamma=2.2),
        dict(sharpen=0.5),
        dict(vignetting=0.2),
        dict(black_point=0.04),
    ):
        assert develops(RenderSettings(**kw))


@pytest.mark.parametrize("colour", [(0.2, 0.5, 0.8), (0.9, 0.3, 0.1), (0.4, 0.4, 0.4)])
def test_the_mosaic_demosaiced_gives_back_a_uniform_colour(colour):
    """A wrong pairing of the mosaic's layout with OpenCV's demosaicing swaps red and blue."""
    img = expose([_flat(colour)], 64, 48, RenderSettings(bayer=True, **QUIET))
    got = img[8:-8, 8:-8].reshape(-1, 3).mean(axis=0) / 255.0
    np.testing.assert_allclose(got, colour, atol=1.5 / 255)


def test_the_tone_curve_raises_mid_greys():
    img = expose([_flat(0.25)], 64, 48, RenderSettings(gamma=2.0, **QUIET))
    assert np.all(np.abs(img.astype(float) - 255 * 0.5) <= 0.5 + 1e-9)


def test_the_black_point_stores_dim_light_black_and_stretches_the_rest():
    """Light at or under the black point stores 0; above it, (x - b) / (1 - b) is toned."""
    w, h = 64, 48
    s = dict(black_point=0.1, gamma=2.0, **QUIET)
    dim = expose([_flat(0.08)], w, h, RenderSettings(**s))
    assert np.all(dim == 0)
    mid = expose([_flat(0.325)], w, h, RenderSettings(**s))  # (0.325 - 0.1) / 0.9 = 0.25
    assert np.all(np.abs(mid.astype(float) - 255 * 0.5) <= 0.5 + 1e-9)
    full = expose([_flat(1.0)], w, h, RenderSettings(**s))
    assert np.all(full == 255)


def test_white_light_comes_out_grey_and_clips_at_full_scale():
    img = expose([_flat(0.4)], 64, 48, RenderSettings(bayer=True, **QUIET))
    np.testing.assert_allclose(img[8:-8, 8:-8].reshape(-1, 3).mean(axis=0), 0.4 * 255, atol=1.0)
    bright = expose([_flat(3.0)], 64, 48, RenderSettings(bayer=True, **QUIET))
    assert np.all(bright == 255)


def test_balanced_blue_and_red_are_noisier_than_green():
    """The colour filters pass less of a white lamp to blue and red: more noise once balanced."""
    s = RenderSettings(bayer=True, ambient=0.0, full_well_e=2000.0, read_noise=0.0, seed=3)
    img = expose([_flat(0.3, (128, 128))], 128, 128, s).astype(float)
    sd = img[8:-8, 8:-8].reshape(-1, 3).std(axis=0)
    assert RAW_WHITE[1] > RAW_WHITE[0] > RAW_WHITE[2]
    assert sd[0] > 1.1 * sd[1] and sd[2] > 1.1 * sd[1]


def test_vignetting_darkens_the_corners_by_its_fraction():
    w, h = 101, 61
    img = expose([_flat(0.8, (h, w))], w, h, RenderSettings(vignetting=0.4, **QUIET))
    g = img[..., 1].astype(float) / 255.0
    assert g[h // 2, w // 2] == pytest.approx(0.8, abs=1 / 255)
    for v, u in ((0, 0), (0, w - 1), (h - 1, 0), (h - 1, w - 1)):
        assert g[v, u] == pytest.approx(0.8 * 0.6, abs=1 / 255)


def test_sharpening_overshoots_at_an_edge():
    h, w = 32, 40
    step = np.zeros((h, w, 3), np.float32)
    step[h // 2 :] = 0.5  # a dark half above a lit one
    base = dict(gamma=1.0 + 1e-9, ambient=0.2, full_well_e=0.0, read_noise=0.0)
    flat = expose([(0, h, 0, w, step)], w, h, RenderSettings(**base))[:, w // 2, 1]
    sharp = expose([(0, h, 0, w, step)], w, h, RenderSettings(sharpen=1.0, **base))[:, w // 2, 1]
    assert flat.min() == pytest.approx(0.2 * 255, abs=1) and flat.max() == pytest.approx(178, abs=1)
    assert sharp.min() < flat.min() - 20 and sharp.max() > flat.max() + 20  # both sides overshoot
    np.testing.assert_array_equal(sharp[:4], flat[:4])  # far from the edge: unchanged


def test_settings_of_the_processing_are_checked():
    for bad in (
        dict(vignetting=1.0),
        dict(vignetting=-0.1),
        dict(gamma=0.0),
        dict(sharpen=-1),
        dict(black_point=1.0),
        dict(black_point=-0.01),
        dict(black_point=True),
    ):
        with pytest.raises(ValueError):
            RenderSettings(**bad)
    with pytest.raises(ValueError, match="bayer"):
        RenderSettings(bayer=1)
