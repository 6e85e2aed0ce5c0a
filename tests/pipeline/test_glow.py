"""Lights that glow: told from plain discs, and centred on their radial shape."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from camvlp import locate
from camvlp.geometry.disc import perspective_offsets
from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.pipeline.detect.candidates import detect_fixtures
from camvlp.pipeline.lamp.glow import GLOW_LEVEL, centred_on_glow, glow_level, glow_levels
from camvlp.sim.render import RenderSettings, render
from conftest import stress_scene

pytestmark = pytest.mark.long  # seconds a test: run first (tests/conftest.py)

CAM = Camera.from_focal(640, 480, 480.0, row_time_s=40e-6)
ROOM = FixtureMap(
    tuple(
        Fixture(i, np.array([x, -2.7, z]), 0.3, np.array([0.0, 1.0, 0.0]))
        for i, (x, z) in zip(
            (5, 6, 9, 10), ((0.6, 0.45), (0.6, -0.45), (-0.6, -0.45), (-0.6, 0.45)), strict=True
        )
    )
)


def _photo(seed: int, **look):
    pose = Pose.from_euler([0.02 * seed, -1.2, -0.01 * seed], [90.0 + seed, -0.5 * seed, 7.0])
    return render(CAM, ROOM, pose, RenderSettings(seed=seed, **look)), pose


@pytest.mark.parametrize(
    "look", [{}, {"blur_px": 2.0}, {"blur_px": 2.0, "brightness": 8.0}, {"core": 2.0}]
)
def test_a_plain_disc_does_not_glow(look):
    photo, _ = _photo(1, **look)
    blobs = detect_fixtures(photo.image).blobs
    assert len(blobs) == 4
    assert all(abs(glow_level(photo.image, b)) < 0.01 for b in blobs)


@pytest.mark.parametrize("halo", [0.05, 0.4])
def test_a_glow_is_seen(halo):
    photo, _ = _photo(2, halo=halo)
    blobs = detect_fixtures(photo.image).blobs
    assert len(blobs) == 4
    assert all(glow_level(photo.image, b) > 1.5 * GLOW_LEVEL for b in blobs)


def test_glow_levels_the_same_from_any_layout_of_the_photo():
    # samples are gathered by one flat index from a contiguous photo, by (row, column) pairs
    # from a view: the same pixels either way, also where the samples leave the photo
    photo, _ = _photo(2, halo=0.2)
    img = photo.image
    blobs = detect_fixtures(img).blobs
    h, w = img.shape[:2]
    moved = [
        dataclasses.replace(blobs[0], pixel=np.array([x, y]))
        for x, y in ((3.0, 5.0), (w - 2.0, h - 9.0))
    ]
    blobs = [*blobs, *moved]
    levels = glow_levels(img, blobs)
    padded = np.zeros((h, w + 5, 3), np.uint8)
    padded[:, :w] = img
    view = padded[:, :w]  # not contiguous
    assert not view.flags.c_contiguous
    np.testing.assert_array_equal(glow_levels(view, blobs), levels)
    assert np.all(np.isfinite(levels[:4]))
    gray = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    wide = np.zeros((h, w + 5), np.uint8)
    wide[:, :w] = gray
    np.testing.assert_array_equal(glow_levels(wide[:, :w], blobs), glow_levels(gray, blobs))


def _centre_errors(photo, blobs) -> np.ndarray:
    truth = np.array([t.pixel for t in photo.fixtures])
    return np.array([np.min(np.linalg.norm(truth - b.pixel, axis=1)) for b in blobs])


def test_a_glowing_light_is_centred_on_its_shape():
    # a glow that blinks with the LED pulls the outline's ellipse about; the radial shape
    # is centred (a light whose glow the border cuts is left as detected: not used)
    before, after = [], []
    for seed in range(3):
        photo, _ = _photo(seed, halo=0.4, brightness=1.0)
        blobs = [b for b in detect_fixtures(photo.image).blobs if not b.touches_border]
        before += list(_centre_errors(photo, blobs))
        after += list(_centre_errors(photo, centred_on_glow(photo.image, blobs, "rows")))
    assert np.median(after) < 0.25 < np.median(before)
    assert np.max(after) < 0.6


def test_a_radial_fit_that_leaves_its_disc_is_not_taken(monkeypatch):
    # a fit drawn to a neighbour's glow ends off the light's disc: the outline's centre stays
    import camvlp.pipeline.lamp.glow as glow

    photo, _ = _photo(1, halo=0.4, brightness=1.0)
    blobs = [b for b in detect_fixtures(photo.image).blobs if not b.touches_border]
    real = glow.radial_fit
    shift = np.array([0.0, 0.0])

    def moved(*args, **kwargs):
        fit = real(*args, **kwargs)
        return fit._replace(centre=fit.centre + shift)

    monkeypatch.setattr(glow, "radial_fit", moved)
    monkeypatch.setattr(glow, "rim_from_chords", lambda *a: None)  # (no rim to fall back on)
    near = centred_on_glow(photo.image, blobs, "rows")
    assert all(np.hypot(*(a.pixel - b.pixel)) < 2.0 for a, b in zip(near, blobs, strict=True))
    assert any(a is not b for a, b in zip(near, blobs, strict=True))
    checked = 0
    for b in blobs:  # a centre beyond the disc's semi-major axis, but within its box
        shift[:] = (0.0, 0.55 * float(max(b.axes_px)) + 2.0)
        if b.pixel[1] + shift[1] < b.box[3] - 1:
            (moved_blob,) = centred_on_glow(photo.image, [b], "rows")
            assert moved_blob is b
            checked += 1
    assert checked >= 2


def test_plain_discs_are_left_as_detected():
    photo, _ = _photo(0)
    blobs = detect_fixtures(photo.image).blobs
    moved = centred_on_glow(photo.image, blobs, "rows")
    assert all(a is b for a, b in zip(blobs, moved, strict=True))


def test_locate_centres_glowing_lights():
    photo, pose = _photo(1, halo=0.4, brightness=1.0)  # from the pose found too:
    res = locate(photo.image, CAM, ROOM)
    assert res, res.reason
    assert res.paths["radial fit"].calls >= 1, res.paths  # the path that ran is reported
    assert res.paths["radial fit"].ms <= res.timing_ms["detect"]
    errors = _centre_errors(photo, res.fixtures)
    assert np.median(errors) < 0.25
    assert np.linalg.norm(res.position - pose.position) < 2e-3  # 16 mm centred on outlines


def test_an_outline_that_misses_the_disc_somewhere_is_no_glow():
    # a plain disc of radius 50 px whose outline came out 16 % short across one axis: the
    # ring's inner samples there fall on the disc (8 of its 96), which is not a glow
    img = np.full((300, 300), 10, np.uint8)
    cv2.circle(img, (150, 150), 50, 230, -1)
    (blob,) = detect_fixtures(img).blobs
    assert glow_level(img, blob) < GLOW_LEVEL
    short = dataclasses.replace(blob, axes_px=np.array([100.0, 84.0]), angle_deg=30.0)
    assert glow_level(img, short) < GLOW_LEVEL
    # a glow lifts the whole ring: still seen
    yy, xx = np.mgrid[0:300, 0:300]
    rho = np.hypot(xx - 150, yy - 150)
    glowing = np.where(rho <= 50, 230, 10 + 40 * np.exp(-(rho - 50) / 15)).astype(np.uint8)
    assert glow_level(glowing, short) > 2 * GLOW_LEVEL


def _ellipse_centre_errors(brightness: float) -> tuple[np.ndarray, np.ndarray]:
    """Errors (px) of the outlines' and the centred lights' centres from the centres of the
    discs' images (the projected centre plus the perspective offset), seeds 0 to 3."""
    normals = np.array([f.normal for f in ROOM.fixtures])
    diameters = [f.diameter for f in ROOM.fixtures]
    outline, centred = [], []
    for seed in range(4):
        photo, pose = _photo(seed, halo=0.4, brightness=brightness)
        offsets = perspective_offsets(CAM, pose, ROOM.positions, diameters, normals)
        truth = np.array([t.pixel for t in photo.fixtures]) + offsets
        blobs = [b for b in detect_fixtures(photo.image).blobs if not b.touches_border]
        for b, c in zip(blobs, centred_on_glow(photo.image, blobs, "rows"), strict=True):
            k = np.argmin(np.linalg.norm(truth - b.pixel, axis=1))
            outline.append(np.linalg.norm(b.pixel - truth[k]))
            centred.append(np.linalg.norm(c.pixel - truth[k]))
    return np.array(outline), np.array(centred)


def test_a_clipped_glow_is_centred_on_the_pixels_that_tell_its_centre():
    # at 4 full scales the disc and the glow next to it clip in the bright stripes: the rim
    # shows only in the dim lines.  The outlines are 0.6 px off (median), a fit on every
    # k-th pixel with coarse bins was 0.36 px off; the informative pixels give 0.07 px
    outline, centred = _ellipse_centre_errors(4.0)
    assert len(centred) >= 12
    assert np.median(centred) < 0.15 < np.median(outline)
    assert np.mean(centred < 0.3) >= 0.75


def test_an_unclipped_glow_stays_centred():
    outline, centred = _ellipse_centre_errors(1.0)  # outlines 1 px off (median)
    assert len(centred) >= 12
    assert np.median(centred) < 0.03 < 0.5 < np.median(outline)
    assert np.max(centred) < 0.1


def _lamp_at(u: float, v: float, r_px: float, readout: str, **look):
    """One lamp of radius ``r_px`` centred at pixel (u, v) of CAM, facing it; its photo."""
    f = CAM.matrix[0, 0]
    ray = CAM.undistort_pixels(np.array([[u, v]]))[0]
    fx = Fixture(0, np.array([ray[0], ray[1], 1.0]) * 2.0, 4.0 * r_px / f, np.array([0, 0, -1.0]))
    settings = RenderSettings(seed=7, readout=readout, chip_rate_hz=5000.0, **look)
    return render(CAM, FixtureMap((fx,)), Pose(np.eye(3), np.zeros(3)), settings)


@pytest.mark.parametrize(
    ("readout", "side", "look"),
    [
        ("rows", "left", {"halo": 0.3, "brightness": 6.0}),
        ("columns", "bottom", {"halo": 0.4, "brightness": 4.0}),
        ("rows-reversed", "top", {"halo": 0.25, "brightness": 8.0, "core": 1.5}),
    ],
)
def test_a_lamp_whose_glow_the_border_cuts_is_centred_and_used(readout, side, look):
    # the disc's edge 0.25 radius from the border, the glow bright well beyond it: the
    # outline is pulled away from the border by some px, the radial shape is fitted to the
    # pixels in the photo
    r = 40.0
    d = 1.25 * r
    u, v = {"left": (d, 240.0), "bottom": (320.0, 479.0 - d), "top": (320.0, d)}[side]
    photo = _lamp_at(u, v, r, readout, **look)
    axis = "rows" if readout.startswith("rows") else "columns"
    (blob,) = detect_fixtures(photo.image, readout=axis).blobs
    assert blob.touches_border  # the glow's bright part reaches the border
    (moved,) = centred_on_glow(photo.image, [blob], axis)
    truth = photo.fixtures[0].pixel
    assert not moved.touches_border
    assert np.linalg.norm(moved.pixel - truth) < 0.3 < np.linalg.norm(blob.pixel - truth)


@pytest.mark.parametrize("gap", [-0.3, -0.05])
def test_a_lamp_whose_disc_the_border_cuts_stays_set_aside(gap):
    r = 40.0
    photo = _lamp_at(r * (1.0 + gap), 240.0, r, "rows", halo=0.3, brightness=4.0)
    (blob,) = detect_fixtures(photo.image, readout="rows").blobs
    assert blob.touches_border
    (moved,) = centred_on_glow(photo.image, [blob], "rows")
    assert moved.touches_border


def _two_lamps(apart_radii: float, seed: int):
    """Two lamps of radius 40 px, ``apart_radii`` radii apart on a slant, their glows
    clipping about their rims (halo 0.33 at 2.9 times full scale, the LED fully off in its
    dark chips); the photo."""
    f, r = CAM.matrix[0, 0], 40.0
    d = apart_radii * r * np.array([np.cos(0.45), np.sin(0.45)])
    fixtures = []
    for i, (u, v) in enumerate(
        (np.array([320.0, 240.0]) - 0.5 * d, np.array([320.0, 240.0]) + 0.5 * d)
    ):
        ray = CAM.undistort_pixels(np.array([[u, v]]))[0]
        fixtures.append(
            Fixture(i, np.array([ray[0], ray[1], 1.0]) * 2.0, 4.0 * r / f, np.array([0, 0, -1.0]))
        )
    settings = RenderSettings(
        seed=seed,
        chip_rate_hz=5000.0,
        exposure_s=0.3 / 5000.0,
        halo=0.33,
        brightness=2.9,
        off_level=0.003,
    )
    return render(CAM, FixtureMap(tuple(fixtures)), Pose(np.eye(3), np.zeros(3)), settings)


def _grown(blob, img: np.ndarray, by: int):
    """The blob with its region of interest grown by ``by`` px on every side, as a decimated
    search's padding makes it (its mask padded, its gray levels taken again)."""
    x0, y0, x1, y1 = blob.box
    h, w = img.shape[:2]
    box = (max(0, x0 - by), max(0, y0 - by), min(w, x1 + by), min(h, y1 + by))
    mask = np.zeros((box[3] - box[1], box[2] - box[0]), bool)
    mask[y0 - box[1] : y1 - box[1], x0 - box[0] : x1 - box[0]] = blob.mask
    return dataclasses.replace(blob, box=box, mask=mask, gray=None)


def test_a_light_whose_region_holds_a_neighbours_glow_is_centred_on_its_own_shape():
    # two lamps whose regions stay apart, each region of interest grown over the other's
    # glow and rim: each is fitted within its own cell of the two (the whole region drew
    # the fit 0.3 to 15 px towards or away from the other)
    errors = []
    for seed in range(4):
        photo = _two_lamps(4.6, seed)
        blobs = detect_fixtures(photo.image, readout="rows").blobs
        assert len(blobs) == 2 and all(b.cell is None for b in blobs)
        moved = centred_on_glow(photo.image, [_grown(b, photo.image, 50) for b in blobs], "rows")
        errors += list(_centre_errors(photo, moved))
    assert np.max(errors) < 0.2


#: Six lamps of a 1080p photo at an exposure of a whole chip (a drawn scene of
#: ``benchmarks/stress_decode.py``): ``(id, x, y, diameter)``, metres, 2 m above the camera.
_SIX = (
    (0, -0.2900929, 0.46426791, 0.2630701518044549),
    (2, 0.75069164, -0.56201829, 0.2951784809711555),
    (14, -0.63758367, 0.01534708, 0.3899603020015486),
    (10, 0.65054525, -0.03412685, 0.3423608015779199),
    (6, 0.26788705, -0.1686601, 0.21828197262226703),
    (4, 0.66191538, 0.38198573, 0.1975911404044686),
)


CHIP_RATE = 1e5 / 9  # Hz: 6 rows of 15 us per chip


@pytest.mark.parametrize("seed", [745061531, pytest.param(4, marks=pytest.mark.slow)])
def test_a_radial_fit_whose_disc_leaves_the_outline_is_not_taken(seed):
    # lamp 6's radial fit ran 98 and 73 px off (onto lamp 10's glow, a rim of 240 px
    # where the outline is 210 px across): a disc wider than its light's outline, or
    # reaching beyond it, is another feature's, and the outline's centre (3 px off) stays
    settings = RenderSettings(
        chip_rate_hz=CHIP_RATE,
        exposure_s=1.0 / CHIP_RATE,  # a whole chip
        brightness=4.455268144677289,
        off_level=0.004029935574773636,
        halo=0.13713920018937598,
        blur_px=1.3419953248473957,
        readout="rows",
        seed=seed,
    )
    _, _, photo, image = stress_scene((1920, 1080), _SIX, settings, 90, CHIP_RATE)
    blobs = detect_fixtures(image).blobs
    truth = next(f.pixel for f in photo.fixtures if f.id == 6)
    k = int(np.argmin([np.hypot(*(b.pixel - truth)) for b in blobs]))
    assert np.hypot(*(blobs[k].pixel - truth)) < 5.0
    moved = centred_on_glow(image, blobs, "rows")
    assert np.hypot(*(moved[k].pixel - truth)) < 5.0


def test_centring_glowing_lights_leaves_the_centres_covariances_unread(monkeypatch):
    """The glowing lights moved to their shapes' centres keep their ellipse fits, whose
    covariances are still to be worked out: ``locate`` works none out, and the first read
    gives the detector's values, once per light."""
    import camvlp.pipeline.detect.blob as blob_module

    photo, _ = _photo(1, halo=0.4, brightness=1.0)
    calls = []
    real = blob_module.ellipse_centre_covariance
    monkeypatch.setattr(
        blob_module, "ellipse_centre_covariance", lambda *a: calls.append(1) or real(*a)
    )
    blobs = detect_fixtures(photo.image).blobs
    moved = centred_on_glow(photo.image, blobs, "rows")
    assert all(a is not b for a, b in zip(blobs, moved, strict=True))  # every light moved
    res = locate(photo.image, CAM, ROOM)
    assert res and calls == []
    sigmas = [f.centre_sigma_px for f in res.fixtures]
    assert len(calls) == len(res.fixtures)
    assert [f.centre_sigma_px for f in res.fixtures] == sigmas and len(calls) == len(sigmas)
    expected = sorted(b.centre_sigma_px for b in blobs)
    assert sorted(sigmas) == expected and all(np.isfinite(expected))


def test_a_shape_that_falls_nowhere_has_no_rim():
    """A radial shape that grows outward (a light dark at its centre, or a glow fitted where
    its rim lies outside the region), or holds a NaN, has no steep fall: no rim, where the
    search for the outermost steep fall indexed an empty array (IndexError) before."""
    from camvlp.pipeline.lamp.radial import rim_extents

    knots = np.arange(80) * 0.5
    counts = np.full(knots.size, 50)
    rising = np.clip(knots / 20.0, 0.0, 1.0)
    assert np.isnan(rim_extents(rising, counts, 0.0)).all()
    assert np.isnan(rim_extents(np.ones(knots.size), counts, 0.0)).all()
    with_nan = np.where(knots < 15.0, 1.0, 0.0)
    with_nan[3] = np.nan
    assert np.isnan(rim_extents(with_nan, counts, 0.0)).all()
    # a disc of radius 15 px (its fall over a pixel): a rim, the same both ways, within the
    # knots' smoothing (a pixel and a half) of it
    rim = rim_extents(np.clip(15.0 - knots, 0.0, 1.0), counts, 0.0)
    assert rim[0] == rim[1] and abs(rim[0] - 15.0) <= 1.5


def test_discs_the_border_cuts_are_plain_when_the_photos_other_discs_are():
    # a site's plain discs, four of them cut by the border: a cut disc's rim lifts the ring
    # about its round outline as a glow would, but the photo's lamps are alike
    from camvlp.pipeline.lamp.glow import glowing
    from camvlp.sim.site import site_map

    site = site_map(20, 10, pattern="varied", seed=0, spacing=1.0, height=4.0, diameter=0.5)
    cam = Camera.from_focal(640, 480, 400.0, row_time_s=25e-6, readout="rows")
    pose = Pose.from_euler([8.3, 3.2, 1.3], [1.0, -2.0, 35.0])
    settings = RenderSettings(chip_rate_hz=16_000.0, row_time_s=25e-6, seed=4)
    image = render(cam, site, pose, settings).image
    blobs = detect_fixtures(image, readout="rows").blobs
    glows, told = glowing(image, blobs)
    cut = [b.touches_border for b in blobs]
    assert told.sum() >= 8 and sum(cut) >= 3
    assert not glows.any()
    res = locate(image, cam, site)
    assert res, res.reason
    assert "radial fit" not in res.paths and "rim from chords" not in res.paths, res.paths
