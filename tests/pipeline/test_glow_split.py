"""Lights read from their glows taken apart (camvlp.pipeline.decode.glow_split)."""

from __future__ import annotations

import numpy as np
import pytest

import camvlp.pipeline.decode.stage as decode_stage
from camvlp import locate
from camvlp.pipeline.decode.glow_split import separated_waveforms
from conftest import stress_scene, stress_settings

pytestmark = pytest.mark.long  # seconds a test: run first (tests/conftest.py)


def _drawn(rng: np.random.Generator, clip: float):
    """Three lamps' glows drawn as the module's model has them, 400 lines x 600 px: each a
    disc with a halo decaying over half a radius, at its own random level on each line (a
    chip of 8 lines, on or at 10 %), summed on an ambient that drifts from line to line,
    clipped at ``clip``; returns the image, the centres, the radii and the true levels."""
    centres = np.array([[150.0, 200.0], [330.0, 170.0], [470.0, 260.0]])
    radii = np.array([60.0, 50.0, 55.0])
    yy, xx = np.mgrid[0:400, 0:600].astype(float)
    chips = rng.integers(0, 2, size=(3, 50))
    levels = np.where(np.repeat(chips, 8, axis=1) > 0, 1.0, 0.1)  # (3, 400)
    img = 0.03 + 0.01 * np.sin(np.arange(400) / 30.0)[:, None] + np.zeros_like(xx)
    for (cx, cy), r, s in zip(centres, radii, levels, strict=True):
        rho = np.hypot(xx - cx, yy - cy) / r
        shape = np.where(rho < 1, 1.0, 0.0) + 0.35 * np.exp(-np.maximum(rho - 1, 0) / 0.5)
        img += 4.0 * shape * s[:, None]
    img = np.minimum(img, clip) + rng.normal(0.0, 0.002, img.shape)
    return np.clip(img, 0.0, clip).astype(np.float32), centres, radii, levels


def test_each_lamps_level_is_taken_apart_from_its_neighbours_glows():
    """The lamps' discs clip on every line (4 times full scale, 10 % when off); their glows
    overlap.  Each lamp's level comes out line by line, correlating with the truth above
    0.99 where it has weight, and as zero in no line where it is on."""
    rng = np.random.default_rng(3)
    img, centres, radii, truth = _drawn(rng, 1.0)
    waves = separated_waveforms(img, centres, radii, "rows")
    for wave, s in zip(waves, truth, strict=True):
        lines = np.arange(wave.first, wave.first + wave.level.size)
        w = wave.weight / wave.weight.sum()  # each line by its precision
        got, want = wave.level - w @ wave.level, s[lines] - w @ s[lines]
        assert w @ (got * want) / np.sqrt((w @ got**2) * (w @ want**2)) > 0.99
        # on its lit lines too (its disc clipped there): its glow reaches beyond its disc
        assert np.count_nonzero(wave.weight[s[lines] == 1.0] > 0) > 100
    # along columns: the same photo turned a quarter turn
    turned = separated_waveforms(img.T.copy(), centres[:, ::-1], radii, "columns")
    for a, b in zip(waves, turned, strict=True):
        assert a.first == b.first
        np.testing.assert_allclose(a.level, b.level, rtol=1e-6, atol=1e-9)


def test_lights_out_of_reach_give_none_and_no_lights_nothing():
    img = np.ones((100, 100), np.float32)
    img[90:, 90:] = 0.5  # all clipped within the light's reach (4 radii): nothing to fit
    assert separated_waveforms(img, np.array([[30.0, 30.0]]), np.array([10.0]), "rows") == [None]
    assert separated_waveforms(img, np.zeros((0, 2)), np.zeros(0), "rows") == []


#: A stress photo of seed 11 (0.5 chip, 12 rows per chip): seven lamps ``(id, x, y,
#: diameter)``, metres, 2 m above a 1920 x 1080 camera, at 7.2 times full scale, 8 % when
#: off, hot cores (1.34) and halos (0.35) whose glows stripe the whole photo.
_SEVEN = (
    (6, -1.111, -0.335, 0.41),
    (9, 0.984, -0.561, 0.371),
    (10, 0.896, 0.251, 0.794),
    (2, 0.146, -0.376, 0.34),
    (14, -0.708, 0.39, 0.715),
    (0, -0.462, -0.381, 0.312),
    (4, 0.024, 0.073, 0.369),
)


@pytest.mark.parametrize(
    ("seed", "alone"), [(958737899, False), pytest.param(5, None, marks=pytest.mark.slow)]
)
def test_lamps_whose_discs_clip_in_their_dark_chips_are_read_from_their_glows(
    seed, alone, monkeypatch
):
    """Lamp 9's disc clips in almost every line, its dark chips drowned in its own off level
    and its neighbours' halos: its disc's profile fits no ID.  Its glow beyond the disc
    carries its code, mixed with the others': taken apart, it reads, and so do lamps 2 and
    4 (whose profiles fit no ID either) and 0 and 6 (look-alikes of each other's reverses).
    In the stress photo (its noise seed) lamp 9 is not read from its disc; with other noise
    (``alone`` None) it may be, and every lamp must read either way."""
    look = dict(brightness=7.18, off_level=0.082, core=1.34, halo=0.35, blur_px=1.18)
    cam, room, photo, image = stress_scene(
        (1920, 1080), _SEVEN, stress_settings(12.0, 0.5, seed=seed, **look), 88
    )

    def read(res) -> dict[int, int | None]:
        out = {}
        for f in res.fixtures:
            t = min(photo.fixtures, key=lambda t: np.hypot(*(t.pixel - f.pixel)))
            if np.hypot(*(t.pixel - f.pixel)) < 10:
                out[t.id] = f.id
        return out

    got = read(locate(image, cam, room))
    assert got == {i: i for i, *_ in _SEVEN}, got
    monkeypatch.setattr(
        decode_stage, "decode_from_glows", lambda img, b, man, fm, glows=True: (man, {})
    )
    before = read(locate(image, cam, room))
    if alone is not None:
        assert (before.get(9) is not None) == alone, before  # the disc alone does not tell it
    assert all(v in (None, k) for k, v in before.items()), before


def test_a_photo_of_more_lights_than_the_cap_is_not_taken_apart(monkeypatch):
    """The normal equations grow with the square of the lights: past MAX_LIGHTS the decodes
    stay as they are, and nothing is fitted."""
    import camvlp.pipeline.decode.glow_split as gs

    look = dict(brightness=7.18, off_level=0.082, core=1.34, halo=0.35, blur_px=1.18)
    cam, room, _, image = stress_scene(
        (1920, 1080), _SEVEN, stress_settings(12.0, 0.5, seed=958737899, **look), 88
    )
    called = []
    real = gs.separated_waveforms
    monkeypatch.setattr(
        gs, "separated_waveforms", lambda *a, **k: called.append(1) or real(*a, **k)
    )
    monkeypatch.setattr(gs, "MAX_LIGHTS", 6)  # the photo has 7 or 8 blobs
    res = locate(image, cam, room)
    assert not called
    assert 9 not in [f.id for f in res.fixtures]
