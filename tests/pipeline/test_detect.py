"""Tests of the detection stage on simulated photographs of the small test room.

The known answers are the simulator's: each fixture's projected centre, whether its whole
disc is inside the image, and the readout axis it was rendered with.  For a tilted camera
the centre of a disc's image (an ellipse) is not the projection of the disc's centre; the
expected centre is then the centre of an ellipse fitted to the projected rim.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from camvlp import locate
from camvlp.imaging.gray import to_gray
from camvlp.imaging.levels import counted_percentiles, percentiles_u8
from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.pipeline.detect.candidates import (
    _blurred_peak,
    _close_lit,
    _decimated_gray,
    _median_u8,
    _outlines,
    detect_fixtures,
)
from camvlp.pipeline.detect.disc import _bridged
from camvlp.pipeline.detect.duplicates import drop_duplicates
from camvlp.sim.render import RenderSettings, render
from conftest import LOOK_UP, SMALL_DIAMETER, small_settings

# (position, thesis angles, readout, exposure s or None for half a chip, seed)
FACING_UP = {
    "rows": ((0.0, 0.0, 0.0), LOOK_UP, "rows", None, 1),
    "columns-roll73": ((0.1, 0.0, 0.2), (90.0, 0.0, 73.0), "columns", None, 2),
    "rows-roll200-long-exposure": ((0.0, 0.0, 0.0), (90.0, 0.0, 200.0), "rows", 1e-4, 3),
    "columns-roll300-short-exposure": ((0.0, 0.0, 0.0), (90.0, 0.0, 300.0), "columns", 1e-5, 4),
    "rows-1m-up": ((0.0, -1.0, 0.0), LOOK_UP, "rows", None, 7),
}
TILTED = {
    "rows": ((0.1, 0.0, -0.2), (96.0, -5.0, 20.0), "rows", None, 5),
    "columns": ((-0.1, 0.0, 0.1), (85.0, 4.0, 160.0), "columns", None, 6),
}


def render_case(camera, room, case):
    position, euler, readout, exposure, seed = case
    pose = Pose.from_euler(position, euler)
    return render(
        camera, room, pose, small_settings(readout=readout, exposure_s=exposure, seed=seed)
    )


@pytest.fixture(scope="module")
def facing_up(small_camera, small_room):
    return {k: render_case(small_camera, small_room, c) for k, c in FACING_UP.items()}


@pytest.fixture(scope="module")
def tilted(small_camera, small_room):
    return {k: render_case(small_camera, small_room, c) for k, c in TILTED.items()}


def ellipse_centre(camera, pose, fixture) -> np.ndarray:
    """Centre of the ellipse through the fixture's projected rim, pixels."""
    n = fixture.normal
    a = np.cross(n, [1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    t = np.linspace(0.0, 2 * np.pi, 720, endpoint=False)
    rim = fixture.position + 0.5 * fixture.diameter * (
        np.cos(t)[:, None] * a + np.sin(t)[:, None] * b
    )
    (cx, cy), _, _ = cv2.fitEllipse(camera.project(pose, rim).astype(np.float32))
    return np.array([cx, cy])


def match(blobs, pixel, radius_px) -> list:
    """The blobs whose centre is within ``radius_px`` of ``pixel``."""
    return [b for b in blobs if np.hypot(*(b.pixel - pixel)) < radius_px]


def radius_px(camera, distance_m) -> float:
    return 0.5 * SMALL_DIAMETER / distance_m * camera.focal_px


@pytest.mark.parametrize("name", list(FACING_UP))
def test_every_fixture_found_once_at_its_centre(name, facing_up, small_camera):
    r = facing_up[name]
    readout = FACING_UP[name][2]
    distance = 2.7 + r.pose.position[1]  # the ceiling is at y = -2.7 m
    radius = radius_px(small_camera, distance)
    det = detect_fixtures(r.image)
    assert all(t.fully_inside for t in r.fixtures)  # the scene is as intended
    assert len(det.blobs) == len(r.fixtures)
    for t in r.fixtures:
        found = match(det.blobs, t.pixel, radius)
        assert len(found) == 1, t.id
        b = found[0]
        assert np.hypot(*(b.pixel - t.pixel)) < 0.3, (t.id, b.pixel, t.pixel)
        assert b.axis == readout
        assert b.stripe_contrast > 2.0
        assert not b.touches_border, t.id
        # the diameter; a saturated disc's blurred rim reaches about a pixel further out
        assert b.axes_px == pytest.approx([2 * radius + 1.5, 2 * radius + 1.5], abs=1.5)
        # the mask is the disc with its stripes filled: its area is the disc's
        assert b.mask.sum() == pytest.approx(np.pi * radius**2, rel=0.05)
        x0, y0, x1, y1 = b.box
        assert b.mask.shape == (y1 - y0, x1 - x0)
        assert x0 <= t.pixel[0] < x1 and y0 <= t.pixel[1] < y1


@pytest.mark.parametrize("name", list(TILTED))
def test_tilted_view_centre_is_the_ellipse_centre(name, tilted, small_camera, small_room):
    r = tilted[name]
    det = detect_fixtures(r.image)
    checked = 0
    for t, f in zip(r.fixtures, small_room.fixtures, strict=True):
        if not t.fully_inside:
            continue
        found = match(det.blobs, t.pixel, 40.0)
        assert len(found) == 1, t.id
        centre = ellipse_centre(small_camera, r.pose, f)
        offset = np.hypot(*(centre - t.pixel))  # what perspective explains
        assert np.hypot(*(found[0].pixel - centre)) < 0.3
        assert np.hypot(*(found[0].pixel - t.pixel)) < 0.3 + offset
        assert found[0].axis == TILTED[name][2]
        checked += 1
    assert checked >= 4


def test_disc_cut_by_the_border_is_flagged(small_camera, small_room):
    # 0.85 m to the side: the two fixtures at x = -0.8 m are cut by the image's edge
    pose = Pose.from_euler([0.85, 0.0, 0.0], LOOK_UP)
    r = render(small_camera, small_room, pose, small_settings(seed=9))
    det = detect_fixtures(r.image)
    cut = [t for t in r.fixtures if not t.fully_inside]
    assert len(cut) == 2
    for t in r.fixtures:
        inside_image = 0 <= t.pixel[0] <= small_camera.width - 1
        assert inside_image  # every centre is in the picture
        found = match(det.blobs, t.pixel, radius_px(small_camera, 2.7))
        assert len(found) == 1, t.id
        assert found[0].touches_border == (not t.fully_inside), t.id


def test_fully_inside_disc_near_the_border_is_not_flagged(facing_up, small_camera):
    """From 1 m up the corner discs end a few pixels from the image's edge."""
    r = facing_up["rows-1m-up"]
    radius = radius_px(small_camera, 1.7)
    gaps = [
        min(
            t.pixel[0] - radius,
            small_camera.width - 1 - t.pixel[0] - radius,
            t.pixel[1] - radius,
            small_camera.height - 1 - t.pixel[1] - radius,
        )
        for t in r.fixtures
    ]
    assert 2.0 < min(gaps) < 20.0  # the scene is as intended
    det = detect_fixtures(r.image)
    assert not any(b.touches_border for b in det.blobs)


@pytest.mark.parametrize("readout", ["rows", "columns"])
def test_given_readout_is_used(facing_up, readout):
    det = detect_fixtures(facing_up["rows"].image, readout=readout)
    assert {b.axis for b in det.blobs} == {readout}


def test_black_image_has_no_blobs():
    det = detect_fixtures(np.zeros((960, 1280, 3), np.uint8))
    assert det.blobs == ()


def test_noise_without_lights_has_no_blobs(small_camera, small_room):
    # looking at the floor: no fixture in view, only ambient light and sensor noise
    r = render(
        small_camera,
        small_room,
        Pose.from_euler([0, 0, 0], (-90.0, 0.0, 0.0)),
        small_settings(seed=3),
    )
    assert r.image.max() > 0
    assert detect_fixtures(r.image).blobs == ()


def test_gray_and_16_bit_input(facing_up):
    r = facing_up["rows"]
    colour = detect_fixtures(r.image)
    gray8 = cv2.cvtColor(r.image, cv2.COLOR_BGR2GRAY)
    gray16 = gray8.astype(np.uint16) * 257
    assert to_gray(gray16).dtype == np.uint8
    assert np.array_equal(to_gray(gray16), gray8)
    for img in (gray8, gray16, r.image.astype(np.uint16) * 257):
        det = detect_fixtures(img)
        assert len(det.blobs) == len(colour.blobs)
        for a, b in zip(det.blobs, colour.blobs, strict=True):
            assert np.hypot(*(a.pixel - b.pixel)) < 0.05
    for t in r.fixtures:
        assert len(match(detect_fixtures(gray16).blobs, t.pixel, 0.3)) == 1


def test_bad_arguments_raise_value_error():
    with pytest.raises(ValueError, match="readout"):
        detect_fixtures(np.zeros((20, 20), np.uint8), readout="diagonal")
    with pytest.raises(ValueError, match="8 x 8"):
        detect_fixtures(np.zeros((4, 20), np.uint8))


def test_closing_around_lit_pixels_equals_whole_image_closing():
    """The candidate closing, done box by box around the lit pixels, gives the whole image's,
    and its outlines found box by box are the whole image's, in OpenCV's order."""
    rng = np.random.default_rng(4)
    boxed = 0
    for case in range(300):
        h, w = (int(v) for v in rng.integers(8, 160, 2))
        binary = np.zeros((h, w), np.uint8)
        for _ in range(int(rng.integers(0, 10))):
            centre = (int(rng.integers(0, w)), int(rng.integers(0, h)))
            cv2.circle(binary, centre, int(rng.integers(1, 12)), 255, -1)
        if case % 3 == 0:  # specks, and stripes cut through the discs
            binary[rng.random((h, w)) < 0.002] = 255
            binary[::4] = 0
        k = int(rng.choice([3, 5, 11, 13]))
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))
        whole = cv2.morphologyEx(binary, cv2.MORPH_CLOSE, kernel)
        closed, boxes = _close_lit(binary, k, max_boxes=1000)
        np.testing.assert_array_equal(closed, whole)
        np.testing.assert_array_equal(_close_lit(binary, k)[0], whole)
        # the outlines found box by box: OpenCV's, in its order
        outlines = cv2.findContours(whole, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)[0]
        got = _outlines(closed, boxes)
        assert len(got) == len(outlines)
        for a, b in zip(got, outlines, strict=True):
            np.testing.assert_array_equal(a, b)
        boxed += np.count_nonzero(binary) > 0
    assert boxed > 200


def test_median_by_counting_is_the_histograms():
    """The reduced image's median, guessed from every 16th row and found by counting, is
    the level the whole histogram gives: noise, flat images, half-and-half images, a guess
    far off (rows that differ)."""
    rng = np.random.default_rng(8)
    for k in range(400):
        h, w = (int(v) for v in rng.integers(64, 400, 2))
        kind = k % 4
        if kind == 0:
            g = np.clip(rng.normal(rng.uniform(0, 255), rng.uniform(0, 40), (h, w)), 0, 255)
        elif kind == 1:
            g = np.full((h, w), rng.integers(0, 256))
        elif kind == 2:  # half bright, half dark: the median sits on the split
            g = np.zeros((h, w))
            g[: h // 2] = 255
        else:  # every 16th row unlike the others: the guess is far off
            g = rng.integers(100, 140, (h, w)).astype(float)
            g[::16] = rng.integers(0, 20)
        g = g.astype(np.uint8)
        assert _median_u8(g) == percentiles_u8(g, [50])[0]


def test_blurred_peak_is_the_blurs_maximum():
    """The reduced image's peak without the blur is the blur's maximum: saturated blocks
    inside, on the edges and corners, saturated stripes one or two rows thick (no 3 x 3
    block: blurred whole), single saturated pixels, images below saturation, tiny ones."""
    rng = np.random.default_rng(21)
    for k in range(600):
        h, w = (int(v) for v in rng.integers(1, 60, 2))
        g = rng.integers(0, 256 if k % 3 else 200, (h, w)).astype(np.uint8)
        kind = k % 5
        if kind == 1:  # a saturated block anywhere, edges and corners too
            y, x = int(rng.integers(0, h)), int(rng.integers(0, w))
            g[max(0, y - 1) : y + 2, max(0, x - 1) : x + 2] = 255
        elif kind == 2:  # saturated stripes, one or two rows: no 3 x 3 block
            g[:: int(rng.integers(3, 5))] = 255
            g[1::4] = 255
        elif kind == 3:  # a few single saturated pixels
            g.flat[rng.integers(0, g.size, 3)] = 255
        elif kind == 4:  # flat
            g[:] = rng.choice([200, 255])
        want = float(cv2.GaussianBlur(g, (3, 3), 0).max())
        assert _blurred_peak(g) == want, (k, g.shape)


def test_percentiles_by_counting_are_the_histograms():
    """Percentiles found by counting pixels from a guess (the regions' background and peak)
    are the histogram's levels, whatever the guess (below, above, out of range) and the
    image (noise, two levels, one level, a strided view)."""
    rng = np.random.default_rng(9)
    for k in range(600):
        h, w = (int(v) for v in rng.integers(1, 90, 2))
        kind = k % 4
        if kind == 0:
            g = rng.integers(0, 256, (h, w))
        elif kind == 1:
            g = np.clip(rng.normal(rng.uniform(0, 255), rng.uniform(0.1, 30), (h, w)), 0, 255)
        elif kind == 2:
            g = rng.choice([0, 255, int(rng.integers(0, 256))], (h, w))
        else:
            g = np.full((h, w), int(rng.integers(0, 256)))
        g = g.astype(np.uint8)[:, :: int(rng.integers(1, 3))]
        qs = [float(rng.choice([0.0, 10.0, 50.0, 99.5, 100.0, rng.uniform(0, 100)])), 99.5]
        guesses = [int(v) for v in rng.integers(-10, 300, 2)]
        expected = percentiles_u8(np.ascontiguousarray(g), qs)
        assert counted_percentiles(g, qs, guesses) == expected


@pytest.mark.parametrize("s", [1, 2, 3, 8])
def test_decimated_gray_is_the_resized_photos_gray(s):
    """The reduced photo's gray levels, gathered 4 bytes a pixel where ``s`` divides its
    sides, are those of OpenCV's nearest-neighbour resize then gray conversion: every colour
    once, and photos whose sides ``s`` does not divide (the resize's own pixels)."""
    rng = np.random.default_rng(s)
    colours = np.arange(1 << 24, dtype=np.uint32).view(np.uint8).reshape(-1, 4)[:, :3]
    every = colours[rng.permutation(1 << 24)[: 1 << 18]].reshape(512, 512, 3)
    photo = np.repeat(np.repeat(every, s, axis=0), s, axis=1)
    np.testing.assert_array_equal(_decimated_gray(photo, s), to_gray(every))
    for h, w in ((8 * s + 1, 12 * s), (12 * s, 8 * s + 2), (97, 101)):
        img = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        size = (-(-w // s), -(-h // s))
        resized = cv2.resize(img, size, interpolation=cv2.INTER_NEAREST) if s > 1 else img
        np.testing.assert_array_equal(_decimated_gray(img, s), to_gray(resized))


@pytest.mark.parametrize(("side_m", "cut"), [(0.7, False), (0.8, True)])
def test_a_glow_at_the_border_is_not_a_cut_disc(small_camera, small_room, side_m, cut):
    # 0.7 m to the side the discs at x = -0.8 m end 10 px from the image's edge and their
    # glow reaches it; 0.8 m to the side the discs themselves are cut
    pose = Pose.from_euler([side_m, 0.0, 0.0], LOOK_UP)
    settings = dataclasses.replace(small_settings(seed=9), halo=0.3, brightness=2.0)
    r = render(small_camera, small_room, pose, settings)
    det = detect_fixtures(r.image)
    near = [t for t in r.fixtures if t.id in (9, 10)]
    assert all(t.fully_inside != cut for t in near)  # the scene is as intended
    for t in near:
        found = match(det.blobs, t.pixel, radius_px(small_camera, 2.7))
        assert len(found) == 1 and found[0].touches_border == cut, t.id


def test_disc_closing_of_the_lit_box_equals_the_whole_regions():
    """A disc's closings, done on the box of its lit pixels and the closings' reach, give the
    whole padded region's: striped discs of both axes anywhere (near the edge or not),
    specks, several discs, both closing lengths."""
    rng = np.random.default_rng(12)
    cropped = 0
    for case in range(400):
        h, w = (int(v) for v in rng.integers(20, 160, 2))
        lit = np.zeros((h, w), np.uint8)
        yy, xx = np.mgrid[:h, :w]
        rows = case % 2 == 0
        edge = case % 4 < 2  # anywhere, else well inside the region
        for _ in range(int(rng.integers(1, 4))):
            if edge:
                cy, cx, ry, rx = (
                    rng.uniform(-5, h + 5),
                    rng.uniform(-5, w + 5),
                    *rng.uniform(2, 50, 2),
                )
            else:
                cy, cx = rng.uniform(0.4, 0.6) * h, rng.uniform(0.4, 0.6) * w
                ry, rx = rng.uniform(0.05, 0.2) * h, rng.uniform(0.05, 0.2) * w
            period = int(rng.integers(3, 20))
            stripes = ((yy if rows else xx) % period) < period // 2
            lit |= ((((yy - cy) / ry) ** 2 + ((xx - cx) / rx) ** 2 <= 1) & stripes).view(np.uint8)
        if case % 3 == 0:
            specks = rng.random((h, w)) < 0.005
            specks[:20], specks[-20:], specks[:, :20], specks[:, -20:] = False, False, False, False
            lit[specks] = 1
        length = int(rng.choice([5, 17, 25]))
        whole, at = _bridged(lit, length, rows, crop=False)
        part, (x, y) = _bridged(lit, length, rows)
        full = np.zeros_like(lit)
        full[y : y + part.shape[0], x : x + part.shape[1]] = part
        assert at == (0, 0)
        np.testing.assert_array_equal(full, whole)
        cropped += (x, y) != (0, 0)
    assert cropped > 100


def _candidate(box, centre, axes, radii, cell=True, pixel=None):
    """A refined candidate's fields for ``drop_duplicates``: an elliptical mask of ``radii``
    (x, y) about ``centre`` (photo px) in ``box`` ``(x0, y0, x1, y1)``, its outline ``axes``
    about ``pixel`` (default ``centre``)."""
    x0, y0, x1, y1 = box
    yy, xx = np.mgrid[y0:y1, x0:x1]
    mask = ((xx - centre[0]) / radii[0]) ** 2 + ((yy - centre[1]) / radii[1]) ** 2 < 1.0
    fields = dict(
        pixel=np.array(centre if pixel is None else pixel, float),
        box=box,
        mask=mask,
        cell=np.ones(mask.shape, bool) if cell else None,
        axes_px=np.array(axes, float),
    )
    return fields, None


def _areas(found) -> list[float]:
    """The candidates' discs' pixels, as ``drop_duplicates`` is given them."""
    return [float(np.count_nonzero(fields["mask"])) for fields, _ in found]


def test_a_split_regions_round_light_is_not_a_wild_neighbours_duplicate():
    # lamps 8 and 1 of a joined region (stress_decode --seed 29 --phone): lamp 8's outline,
    # fitted to its cell's straight edge too, came out 544 x 229 px; lamp 1's round disc lay
    # within half that outline's smaller axis and was dropped
    wild = _candidate((0, 0, 240, 400), (120, 200), (544, 229), (110, 160), pixel=(230, 200))
    round_ = _candidate((200, 60, 460, 340), (330, 200), (106, 96), (50, 48))
    kept = drop_duplicates([wild, round_], _areas([wild, round_]))
    assert len(kept) == 2
    # the same two without cells (two regions of one lamp, or glow): as before, one
    alone = [(dict(c[0], cell=None), None) for c in (wild, round_)]
    assert len(drop_duplicates(alone, _areas(alone))) == 1


def test_a_sliver_of_glow_a_split_took_for_a_light_stays_a_duplicate():
    # a photo of stress_centres --seed 11 --phone: a sliver of glow 315 x 76 px beside a lamp
    # of 458 x 347, both cells of one joined region; kept, it drew the glows' joint fit 11 px
    # off the lamp
    lamp = _candidate((300, 300, 800, 700), (550, 515), (458, 347), (220, 170))
    sliver = _candidate((340, 650, 680, 720), (505, 682), (315, 76), (150, 30))
    kept = drop_duplicates([lamp, sliver], _areas([lamp, sliver]))
    assert len(kept) == 1 and kept[0][0] is lamp[0]


@pytest.mark.parametrize(("diameter_px", "seed"), [(200, 3), (250, 3), (300, 4)])
def test_a_light_of_wide_bands_is_one_light(diameter_px, seed):
    """A 1000 Hz light read every 15 us shows bands 33 rows wide: its bright bands were
    taken for lights of their own (three or four lights, none identified, where there was
    one).  One region shaped as one disc (its convex hull: the dark bands notch its rim) is
    one light, and two cells whose outlines are one ellipse are one light: found once, at
    its centre, and its frequency read."""
    row_time = 15e-6
    cam = Camera.from_focal(1920, 1080, 1400.0, row_time_s=row_time)
    d = diameter_px * 2.0 / 1400.0
    down = np.array([0.0, 0.0, -1.0])
    light = Fixture(1, np.array([0.0, 0.0, 2.0]), d, down, frequency_hz=1000.0)
    room = FixtureMap((light,), mode="frequency")
    pose = Pose.from_euler([0.1, 0.05, 0.0], [0.0, 0.0, 0.0])
    settings = RenderSettings(row_time_s=row_time, exposure_s=2e-4, seed=seed, brightness=1.0)
    photo = render(cam, room, pose, settings)
    (blob,) = detect_fixtures(photo.image).blobs
    assert np.hypot(*(blob.pixel - photo.fixtures[0].pixel)) < 2.0
    (light,) = locate(photo.image, cam, room).fixtures
    assert light.id == 1, light.reason
    assert light.frequency_hz == pytest.approx(1000.0, rel=0.01)


def test_a_disc_the_border_cuts_under_a_dark_stripe_touches_it():
    # plain discs of 77 px under a site's ceiling: at the top, one cut by the border whose
    # top rows are a dark stripe (its bright part starts 4 rows down), and one whole whose
    # cap is in a dark stripe 5 rows from the border
    from camvlp.model.camera import Pose
    from camvlp.sim.render import RenderSettings, render
    from camvlp.sim.site import site_map

    site = site_map(20, 10, pattern="varied", seed=0, spacing=1.0, height=4.0, diameter=0.5)
    cam = Camera.from_focal(640, 480, 400.0, row_time_s=25e-6, readout="rows")
    pose = Pose.from_euler([4.525, 3.3, 1.3125], [0.5, -1.0, 37.5])
    settings = RenderSettings(chip_rate_hz=16_000.0, row_time_s=25e-6, seed=4)
    photo = render(cam, site, pose, settings)
    blobs = detect_fixtures(photo.image, readout="rows").blobs
    truths = [t for t in photo.fixtures if np.all(np.isfinite(t.pixel))]
    for b in blobs:
        t = min(truths, key=lambda t: np.hypot(*(t.pixel - b.pixel)))
        assert b.touches_border == (not t.fully_inside), (b.pixel, b.box, t.pixel)
    assert sum(b.touches_border for b in blobs) >= 4


@pytest.mark.parametrize("tilt", [20.0, 65.0, 115.0, 160.0])
def test_the_glow_check_draws_its_ring_on_the_outline_as_it_lies(tilt):
    # cv2.fitEllipse gives the angle of the first axis it returns, the minor one as often as
    # not: paired with the major axis, the outline was turned a quarter turn, and the glow
    # check's ring ran through a plain disc seen at a slant (48 of 165 plain lights of the
    # supermarket's photos of sites_few.py --lights 4,99 told glowing)
    from camvlp.pipeline.lamp.glow import glowing

    rng = np.random.default_rng(int(tilt))
    img = np.full((400, 500), 20, np.uint8)
    cv2.ellipse(img, (250, 200), (90, 45), tilt, 0, 360, 250, -1, lineType=cv2.LINE_AA)
    rows = np.arange(img.shape[0])[:, None]
    img[((rows // 6) % 2 == 1) & (img > 100)] = 60  # dark stripes along the rows
    img = cv2.add(img, rng.integers(0, 4, img.shape, dtype=np.uint8))
    (blob,) = detect_fixtures(img, readout="rows").blobs
    turn = abs((blob.major_angle - tilt + 90.0) % 180.0 - 90.0)
    assert turn < 5.0, blob.major_angle
    assert abs(blob.axes_px[0] - 180.0) < 12.0 and abs(blob.axes_px[1] - 90.0) < 12.0
    glows, told = glowing(img, [blob])
    assert told[0] and not glows[0]
