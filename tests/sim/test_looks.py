"""Tests of what real photos show beyond plain beacons: hot cores off the disc's centre, lights
sending random data, and text burned into the photo."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.sim.light import data_chips
from camvlp.sim.render import RenderSettings, fixture_truths, render
from camvlp.sim.sensor import PHONE, STAMP_HEIGHT

ROW_TIME = 20e-6  # s per sensor row
CHIP_RATE = 10_000.0  # chips per s: 5 rows per chip
UP = Pose.from_euler([0.0, 0.0, 0.0], [90.0, 0.0, 0.0])  # looking along world -y
STAMP = "2017-02-15 17:47:52"


def camera(width: int = 640, height: int = 480, **kwargs) -> Camera:
    return Camera.from_focal(width, height, 500.0, row_time_s=ROW_TIME, **kwargs)


def fixtures(*where, diameter=0.6, frequency=False) -> FixtureMap:
    """Ceiling fixtures facing down (+y) at ``(id, x, height)`` each; frequency-coded ones
    blink at 2000, 2500 ... Hz."""
    out = tuple(
        Fixture(
            fid,
            np.array([x, -height, 0.0]),
            diameter,
            np.array([0, 1.0, 0]),
            frequency_hz=2000.0 + 500 * k if frequency else None,
        )
        for k, (fid, x, height) in enumerate(where)
    )
    return FixtureMap(out, mode="frequency" if frequency else "manchester")


def quiet(**kwargs) -> RenderSettings:
    """No noise, no ambient light."""
    base = dict(chip_rate_hz=CHIP_RATE, full_well_e=0.0, read_noise=0.0, ambient=0.0)
    return RenderSettings(**(base | kwargs))


def gray(image: np.ndarray) -> np.ndarray:
    return image.astype(float).mean(axis=2)


# ------------------------------------------------------------------------- off-centre cores


def brightest(image: np.ndarray) -> np.ndarray:
    """[u, v] of the centroid of the pixels within one level of the brightest."""
    g = gray(image)
    v, u = np.nonzero(g >= g.max() - 1)
    return np.array([u.mean(), v.mean()])


STEADY = dict(exposure_s=18 / CHIP_RATE, brightness=0.25, blur_px=0.0)  # a whole frame: no stripes


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_core_off_the_centre_is_brightest_where_the_truth_says(seed):
    cam, fmap = camera(), fixtures((5, 0.0, 1.0))
    photo = render(cam, fmap, UP, quiet(core=2.0, core_offset=0.5, seed=seed, **STEADY))
    (t,) = photo.fixtures
    radius = t.rows_spanned / 2  # 150 px
    offset = t.core_pixel - t.pixel
    assert np.hypot(*offset) == pytest.approx(0.5 * radius, abs=0.5)  # half a radius off
    assert np.linalg.norm(brightest(photo.image) - t.core_pixel) < 2.0
    # the centre is dimmer than the core's centre: about 1 + 2 exp(-(0.5 / 0.4)^2) against 3
    g = gray(photo.image)
    u, v = np.round(t.pixel).astype(int)
    cu, cv = np.round(t.core_pixel).astype(int)
    assert g[v, u] / g[cv, cu] == pytest.approx((1 + 2 * np.exp(-(1.25**2))) / 3, abs=0.03)
    # centred (the default): brightest at the centre, and the truth says so
    centred = render(cam, fmap, UP, quiet(core=2.0, seed=seed, **STEADY))
    assert np.linalg.norm(brightest(centred.image) - t.pixel) < 2.0
    np.testing.assert_allclose(centred.fixtures[0].core_pixel, t.pixel)


def test_core_directions_are_drawn_per_fixture_and_seed():
    cam, fmap = camera(), fixtures((5, -0.33, 1.0), (9, 0.33, 1.0), diameter=0.5)
    directions = []
    for seed in (1, 2):
        s = quiet(core=2.0, core_offset=0.4, seed=seed, **STEADY)
        truths = fixture_truths(cam, fmap, UP, s)
        assert all(t.core_pixel is not None for t in truths)
        d = [(t.core_pixel - t.pixel) / np.hypot(*(t.core_pixel - t.pixel)) for t in truths]
        assert d[0] @ d[1] < 0.98  # each fixture its own direction
        directions.append(d[0])
        again = render(cam, fmap, UP, s)  # reproducible: the render draws the same
        np.testing.assert_allclose(again.fixtures[0].core_pixel, truths[0].core_pixel)
    assert directions[0] @ directions[1] < 0.98  # another seed, another direction
    # no core, no core pixel
    assert np.all(np.isnan(fixture_truths(cam, fmap, UP, quiet(core_offset=0.4))[0].core_pixel))


def test_an_off_centre_core_is_drawn_in_the_disc_plane():
    """Seen obliquely, the core's brightest pixel is where a point half a radius from the
    centre on the disc's own plane projects (foreshortened), not half the image's radius."""
    cam = camera()
    fmap = fixtures((5, 0.0, 1.0), diameter=0.4)
    # from 0.8 m aside, turned (about world z) to look at it: 39 degrees off its axis
    a = np.arctan(0.8)
    turn = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    pose = Pose(turn @ UP.world_from_camera, np.array([-0.8, 0.0, 0.0]))
    for seed in (1, 4):
        photo = render(cam, fmap, pose, quiet(core=2.0, core_offset=0.6, seed=seed, **STEADY))
        (t,) = photo.fixtures
        assert t.fully_inside
        assert np.linalg.norm(brightest(photo.image) - t.core_pixel) < 2.0
        # back onto the ceiling (y = -1): 0.6 radius (0.12 m) from the centre
        ray = pose.world_from_camera @ np.append(cam.undistort_pixels(t.core_pixel[None])[0], 1)
        hit = pose.position + ray * (-1.0 - pose.position[1]) / ray[1]
        assert np.linalg.norm(hit - fmap.fixtures[0].position) == pytest.approx(0.12, abs=2e-3)


# ------------------------------------------------------------------------ lights sending data


def profile(photo, k: int = 0, inner: float = 0.85) -> np.ndarray:
    """On (1) or off (0) down the central column of fixture ``k``'s disc, within ``inner``
    of its radius."""
    t = photo.fixtures[k]
    u, half = round(t.pixel[0]), inner * t.rows_spanned / 2
    rows = np.arange(int(np.ceil(t.pixel[1] - half)), int(np.floor(t.pixel[1] + half)) + 1)
    return (gray(photo.image)[rows, u] > 127).astype(int)


def best_agreement(a: np.ndarray, b: np.ndarray, lags) -> float:
    """The largest share of rows on which ``a`` and ``b`` shifted by a lag agree."""
    return max(float(np.mean(a[: a.size - lag] == b[lag:])) for lag in lags)


SHARP = dict(exposure_s=2e-6, brightness=1.0, blur_px=0.5)
#: A tall picture of one big disc: 750 rows, 150 chips, 8 Manchester frames.
TALL = dict(width=480, height=960)


@pytest.mark.parametrize("frequency", [False, True])
def test_a_data_light_repeats_at_no_period(frequency):
    cam, fmap = camera(**TALL), fixtures((1, 0.0, 0.4), frequency=frequency)
    beacon = render(cam, fmap, UP, quiet(seed=1, **SHARP))
    data = render(cam, fmap, UP, quiet(seed=1, data_lights=(1,), **SHARP))
    p, q = profile(beacon), profile(data)
    assert p.size > 600
    lags = range(20, p.size // 2)
    assert best_agreement(p, p, lags) > 0.97  # the beacon repeats (a frame, or a period)
    assert best_agreement(q, q, lags) < 0.8  # the data does not, at any period
    # Manchester chips at the chip rate: every run is one or two chips (5 or 10 rows) long
    edges = np.flatnonzero(np.diff(q)) + 1
    chips = np.diff(edges) / (1 / CHIP_RATE / ROW_TIME)
    assert set(np.round(chips)) == {1.0, 2.0}
    assert np.all(np.abs(chips - np.round(chips)) < 0.25)
    # another seed draws other data (not the same data at another phase), the same seed the same
    other = profile(render(cam, fmap, UP, quiet(seed=2, data_lights=(1,), **SHARP)))
    assert best_agreement(q, other, range(0, q.size // 2)) < 0.8
    assert best_agreement(other, q, range(0, q.size // 2)) < 0.8
    again = render(cam, fmap, UP, quiet(seed=1, data_lights=(1,), **SHARP))
    np.testing.assert_array_equal(again.image, data.image)
    np.testing.assert_array_equal(data_chips(1, 0), data_chips(1, 0))


def test_the_truth_says_which_lights_send_data_and_the_others_are_unchanged():
    cam = camera()
    fmap = fixtures((5, -0.33, 1.0), (9, 0.33, 1.0), diameter=0.5)
    plain = render(cam, fmap, UP, quiet(seed=3, **SHARP))
    mixed = render(cam, fmap, UP, quiet(seed=3, data_lights=(9,), **SHARP))
    assert [t.sends_data for t in mixed.fixtures] == [False, True]
    assert [t.sends_data for t in plain.fixtures] == [False, False]
    for a, b in zip(plain.fixtures, mixed.fixtures, strict=True):  # geometry and phase kept
        assert (a.frames_spanned, a.phase_s) == (b.frames_spanned, b.phase_s)
    left, right = slice(0, 320), slice(320, 640)
    np.testing.assert_array_equal(mixed.image[:, left], plain.image[:, left])  # the beacon
    assert np.count_nonzero(mixed.image[:, right] != plain.image[:, right]) > 1000  # the data
    d = mixed.truth_dict()
    assert d["settings"]["data_lights"] == [9]
    assert [f["sends_data"] for f in d["fixtures"]] == [False, True]
    with pytest.raises(ValueError, match="data_lights names ID 7"):
        render(cam, fmap, UP, quiet(data_lights=(7,)))
    with pytest.raises(ValueError, match="data_lights names ID 7"):
        fixture_truths(cam, fmap, UP, quiet(data_lights=(9, 7)))


# ------------------------------------------------------------------------------- the stamp


def test_a_stamp_lights_its_text_and_nothing_else():
    cam, fmap = camera(), fixtures((5, 0.0, 1.0))
    s = RenderSettings(chip_rate_hz=CHIP_RATE, seed=4)
    plain = render(cam, fmap, UP, s)
    stamped = render(cam, fmap, UP, dataclasses.replace(s, stamp=STAMP))
    u0, v0, u1, v1 = stamped.stamp_box
    assert plain.stamp_box is None and stamped.truth_dict()["stamp_box"] == [u0, v0, u1, v1]
    changed = np.any(stamped.image != plain.image, axis=2)
    vv, uu = np.nonzero(changed)
    assert (uu.min(), vv.min(), uu.max() + 1, vv.max() + 1) == (u0, v0, u1, v1)  # only there
    # bottom right, a digit's height about 3 % of the photo's (480 rows: 14 px)
    assert 0.95 * 640 < u1 <= 640 and 0.95 * 480 < v1 <= 480
    assert v1 - v0 == pytest.approx(STAMP_HEIGHT * 480, abs=3)
    assert 0.25 * 640 < u1 - u0 < 0.5 * 640  # 19 characters
    # lit: white strokes over the dark background
    box = stamped.image[v0:v1, u0:u1]
    assert box.max() == 255 and np.all(box[box.max(axis=2) == 255] == 255)
    assert 0.15 < np.mean(box.min(axis=2) > 200) < 0.7


def test_a_stamp_comes_after_the_phone_processing_and_reads_the_right_way_when_mirrored():
    fmap = fixtures((5, 0.0, 1.0))
    s = RenderSettings(chip_rate_hz=CHIP_RATE, seed=4, stamp=STAMP, **PHONE)
    photo = render(camera(), fmap, UP, s)
    u0, v0, u1, v1 = photo.stamp_box
    assert photo.image[v0:v1, u0:u1].max() == 255  # white, not toned or vignetted
    mirror = render(camera(mirrored=True), fmap, UP, s)
    # the stored photo shows the same text in the same place (bottom right) ...
    text = [p.image[v0:v1, u0:u1].min(axis=2) > 128 for p in (photo, mirror)]
    assert text[0].mean() > 0.15
    np.testing.assert_array_equal(text[0], text[1])
    # ... which the truth gives in the camera model's pixels, like the fixtures'
    assert mirror.stamp_box == (640 - u1, v0, 640 - u0, v1)


def test_a_long_stamp_is_made_to_fit():
    cam, fmap = camera(), fixtures((5, 0.0, 1.0))
    photo = render(cam, fmap, UP, quiet(stamp="W" * 100))
    u0, v0, u1, v1 = photo.stamp_box
    assert 0 <= u0 and u1 <= 640 and v1 - v0 < STAMP_HEIGHT * 480


# ------------------------------------------------------------------------------ bad values


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"core_offset": -0.1}, "core_offset must be a number from 0 to 1"),
        ({"core_offset": 1.5}, "core_offset must be a number from 0 to 1"),
        ({"core_offset": float("nan")}, "core_offset"),
        ({"core_offset": True}, "core_offset"),
        ({"data_lights": (-1,)}, "data_lights must be distinct fixture IDs"),
        ({"data_lights": (5, 5)}, "an ID twice"),
        ({"data_lights": (1.5,)}, "data_lights"),
        ({"data_lights": "5"}, "data_lights"),
        ({"data_lights": 5}, "data_lights"),
        ({"stamp": ""}, "stamp must be 1 to 100 characters"),
        ({"stamp": "   "}, "not all spaces"),
        ({"stamp": "x" * 101}, "stamp must be 1 to 100"),
        ({"stamp": "17:47 \u00b0C"}, "printable ASCII"),
        ({"stamp": "a\nb"}, "printable ASCII"),
        ({"stamp": 2017}, "stamp must be text"),
    ],
)
def test_bad_looks_are_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        RenderSettings(**kwargs)


def test_good_looks_are_kept():
    s = RenderSettings(core_offset=1, data_lights=[3, np.int64(5)], stamp="~ok~")
    assert (s.core_offset, s.data_lights, s.stamp) == (1, (3, 5), "~ok~")
