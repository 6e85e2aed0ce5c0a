"""Tests of the rolling-shutter photograph simulator (thesis chapter 3, section 5.3)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from camvlp.io import load_camera, load_map
from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.model.linecode import FrameFormat
from camvlp.sim.light import on_fraction
from camvlp.sim.render import (
    RenderSettings,
    all_fully_inside,
    fixture_truths,
    render,
    tilt_limit,
)

ROW_TIME = 20e-6  # s per sensor row
CHIP_RATE = 10_000.0  # chips per s: 5 rows per chip
LOOK_UP = (90.0, 0.0, 0.0)  # the thesis' angles looking along world -y (at the ceiling)


@pytest.fixture(scope="module")
def thesis(thesis_camera_path, thesis_room_path):
    return load_camera(thesis_camera_path), load_map(thesis_room_path)


def small_camera(**kwargs) -> Camera:
    """A 640 x 480 camera, f = 500 px, principal point at the image centre."""
    return Camera.from_focal(640, 480, 500.0, row_time_s=ROW_TIME, **kwargs)


def one_fixture(fid=5, position=(0.0, -1.0, 0.0), diameter=0.6, **kwargs) -> FixtureMap:
    """One ceiling fixture facing down (+y), 1 m above a camera at the origin by default."""
    fixture = Fixture(fid, np.array(position), diameter, np.array([0, 1.0, 0]))
    return FixtureMap((fixture,), **kwargs)


def quiet(**kwargs) -> RenderSettings:
    """Settings without noise."""
    return RenderSettings(chip_rate_hz=CHIP_RATE, full_well_e=0.0, read_noise=0.0, **kwargs)


def gray(image: np.ndarray) -> np.ndarray:
    return image.astype(float).mean(axis=2)


def runs(binary: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Complete runs of a 0/1 profile: (start indices, lengths, values); edge runs dropped."""
    edges = np.flatnonzero(np.diff(binary.astype(int))) + 1
    return edges[:-1], np.diff(edges), binary[edges[:-1]]


def disc_column(result, camera: Camera, inner: float = 0.85) -> tuple[np.ndarray, np.ndarray]:
    """Rows and gray values down the disc's central column, within ``inner`` of its radius."""
    t = result.fixtures[0]
    u = round(t.pixel[0])
    half = inner * t.rows_spanned / 2
    rows = np.arange(int(np.ceil(t.pixel[1] - half)), int(np.floor(t.pixel[1] + half)) + 1)
    return rows, gray(result.image)[rows, u]


# ---------------------------------------------------------------------------------- geometry


def test_truth_matches_pinhole_projection(thesis):
    """Thesis room from the floor looking up: centres, sizes and frames spanned by hand."""
    camera, fmap = thesis
    truths = fixture_truths(camera, fmap, Pose.from_euler([0, 0, 0], LOOK_UP))
    f = 3912.0
    for t, fixture in zip(truths, fmap.fixtures, strict=True):
        x, _, z = fixture.position
        # camera x = world x, camera y (down the image) = world z, depth 2.7 m
        assert t.pixel == pytest.approx([2592 + f * x / 2.7, 1940 + f * z / 2.7], abs=1e-6)
        assert t.in_front and t.fully_inside
        assert t.rows_spanned == pytest.approx(f * 0.15 / 2.7, rel=1e-3)
        frame_s = 18 / 10_000.0
        assert t.frames_spanned == pytest.approx(t.rows_spanned * 20e-6 / frame_s, rel=1e-9)


def test_behind_camera_is_reported(thesis):
    camera, fmap = thesis
    truths = fixture_truths(camera, fmap, Pose.from_euler([0, 0, 0], (-90, 0, 0)))
    assert not any(t.in_front or t.fully_inside for t in truths)
    assert all(np.all(np.isnan(t.pixel)) for t in truths)


# The thesis, section 3.4: from the floor the camera can tilt about 12 degrees about x and
# 15 about y (both directions) keeping all four fixtures in the picture; from 1 m up, about
# 4 and 6.  Tilt about x is theta_x (90 + t); about y is theta_y (a rotation about the
# camera's own y axis: theta_z would roll about the optical axis, which never loses a
# fixture from the floor).
THESIS_LIMITS = [
    ((0.0, 0.0, 0.0), 0, 12.0),
    ((0.0, 0.0, 0.0), 1, 15.0),
    ((0.0, -1.0, 0.0), 0, 4.0),
    ((0.0, -1.0, 0.0), 1, 6.0),
]


@pytest.mark.parametrize(("position", "axis", "thesis_deg"), THESIS_LIMITS)
@pytest.mark.parametrize("direction", [1, -1])
def test_tilt_limits_of_section_3_4(thesis, position, axis, thesis_deg, direction):
    camera, fmap = thesis

    def pose(t):
        e = np.array(LOOK_UP)
        e[axis] += direction * t
        return Pose.from_euler(position, e)

    assert all_fully_inside(camera, fmap, pose(thesis_deg - 1.0))
    assert not all_fully_inside(camera, fmap, pose(thesis_deg + 1.5))
    limit = tilt_limit(camera, fmap, position, LOOK_UP, axis, direction)
    assert abs(limit - thesis_deg) < 1.5
    assert all_fully_inside(camera, fmap, pose(limit - 0.01))
    assert not all_fully_inside(camera, fmap, pose(limit + 0.01))


def test_roll_about_optical_axis_keeps_all_fixtures(thesis):
    camera, fmap = thesis
    assert tilt_limit(camera, fmap, (0, 0, 0), LOOK_UP, 2, 1, max_deg=45) == 45


def test_limits_without_normals_use_the_fixtures_plane(thesis):
    """Normals absent: the discs lie in the plane of the centres (horizontal here)."""
    camera, fmap = thesis
    bare = FixtureMap(
        tuple(Fixture(f.id, f.position, f.diameter) for f in fmap.fixtures), frame=fmap.frame
    )
    for euler in [(90, 0, 0), (81, 14, 0), (60, 0, 0), (100, 5, 0)]:
        pose = Pose.from_euler((0, 0, -0.9), euler)
        a = fixture_truths(camera, fmap, pose)
        b = fixture_truths(camera, bare, pose)
        for ta, tb in zip(a, b, strict=True):
            assert ta.fully_inside == tb.fully_inside
            assert ta.rows_spanned == pytest.approx(tb.rows_spanned)


# ---------------------------------------------------------------------------------- timing


def test_on_fraction_matches_numerical_integration():
    chips = FrameFormat().chips(9)
    chip_s = 1e-4
    rng = np.random.default_rng(1)
    starts = rng.uniform(-0.01, 0.01, 50)
    for exposure in (3e-6, 37e-6, 250e-6, 5e-3):
        got = on_fraction(chips, chip_s, starts, exposure)
        tt = starts[:, None] + np.linspace(0, exposure, 20001)[None, :]
        state = chips[np.floor(tt / chip_s).astype(int) % chips.size]
        want = np.trapezoid(state, dx=1.0, axis=1) / 20000
        np.testing.assert_allclose(got, want, atol=2e-3)


@pytest.fixture(scope="module")
def sharp_stripes():
    """Exposure << chip, brightness 1: no bleeding.  Disc of 300 rows (3.3 frames)."""
    camera = small_camera()
    fmap = one_fixture()
    result = render(
        camera,
        fmap,
        Pose.from_euler([0, 0, 0], LOOK_UP),
        quiet(exposure_s=2e-6, brightness=1.0, seed=3),
    )
    return camera, fmap, result


def test_stripe_widths_match_row_time(sharp_stripes):
    camera, fmap, result = sharp_stripes
    _, g = disc_column(result, camera)
    on = g > 0.5 * 255
    starts, lengths, _ = runs(on)
    rows_per_chip = (1 / CHIP_RATE) / ROW_TIME  # 5.0
    # Manchester runs are one or two chips long
    chips_per_run = np.round(lengths / rows_per_chip)
    assert set(chips_per_run) == {1.0, 2.0}
    assert np.all(np.abs(lengths - chips_per_run * rows_per_chip) <= 1)
    # one frame later the same transition comes back: rows per frame / 18 = rows per chip
    frame = fmap.frame.chips(5)
    per_frame = int(np.count_nonzero(frame != np.roll(frame, 1)))
    edges = starts
    span = edges[per_frame:] - edges[:-per_frame]
    assert span.size >= 3
    assert np.mean(span) / frame.size == pytest.approx(rows_per_chip, rel=0.05)
    # no bleeding: bright and dark runs alike (equal on and off chips per frame)
    _, lengths, values = runs(on)
    assert abs(lengths[values].mean() - lengths[~values].mean()) < 0.6


def test_saturation_makes_bright_stripes_wider(sharp_stripes):
    """The thesis' bleeding (section 5.3): long exposure and a bright LED widen white stripes."""
    camera, fmap, _ = sharp_stripes
    result = render(
        camera,
        fmap,
        Pose.from_euler([0, 0, 0], LOOK_UP),
        RenderSettings(chip_rate_hz=CHIP_RATE, exposure_s=0.8 / CHIP_RATE, brightness=4.0, seed=3),
    )
    _, g = disc_column(result, camera)
    _, lengths, values = runs(g > 0.5 * 255)
    bright, dark = lengths[values].mean(), lengths[~values].mean()
    # threshold crossed at on-fraction 0.47 / 4 of the 4-row exposure: about 3 rows each side
    assert bright - dark > 4.0
    assert g.max() == 255  # saturated


@pytest.mark.parametrize(("fid", "seed"), [(5, 3), (10, 11), (0, 7)])
def test_rows_decode_to_the_fixture_id(fid, seed):
    camera = small_camera()
    fmap = one_fixture(fid)
    exposure = 2e-6
    result = render(
        camera,
        fmap,
        Pose.from_euler([0, 0, 0], LOOK_UP),
        quiet(exposure_s=exposure, brightness=1.0, seed=seed),
    )
    rows, g = disc_column(result, camera)
    truth = result.fixtures[0]
    chip_s = 1 / CHIP_RATE
    # chip j of the LED's stream is at the centre of its time slot in row
    # ((j + 0.5) chip - phase - exposure / 2) / row time
    j0 = int(np.ceil((rows[0] * ROW_TIME + truth.phase_s) / chip_s))
    j = np.arange(j0, j0 + 60)
    centre_rows = np.round(((j + 0.5) * chip_s - truth.phase_s - exposure / 2) / ROW_TIME)
    j, centre_rows = j[centre_rows <= rows[-1]], centre_rows[centre_rows <= rows[-1]].astype(int)
    assert j.size >= 36  # two frames
    seen = (g[centre_rows - rows[0]] > 0.5 * 255).astype(np.uint8)
    frame = fmap.frame.chips(fid)
    np.testing.assert_array_equal(seen, frame[j % frame.size])
    decoded = fmap.frame.decode(seen)
    assert decoded.id == fid and decoded.distance == 0


def test_frequency_mode_stripe_period():
    camera = small_camera()
    f_hz = 2000.0
    fmap = FixtureMap(
        (Fixture(0, np.array([0, -1.0, 0]), 0.6, np.array([0, 1.0, 0]), frequency_hz=f_hz),),
        mode="frequency",
    )
    result = render(
        camera, fmap, Pose.from_euler([0, 0, 0], LOOK_UP), quiet(exposure_s=2e-6, brightness=1.0)
    )
    _, g = disc_column(result, camera)
    starts, _, values = runs(g > 0.5 * 255)
    rising = starts[values.astype(bool)]
    assert rising.size >= 8
    assert np.mean(np.diff(rising)) == pytest.approx(1 / (f_hz * ROW_TIME), rel=0.02)  # 25 rows
    t = result.fixtures[0]
    assert t.frames_spanned == pytest.approx(t.rows_spanned * ROW_TIME * f_hz)


def test_columns_readout_gives_vertical_stripes():
    camera = small_camera()
    result = render(
        camera,
        one_fixture(),
        Pose.from_euler([0, 0, 0], LOOK_UP),
        quiet(exposure_s=2e-6, brightness=1.0, readout="columns"),
    )
    t = result.fixtures[0]
    g = gray(result.image)
    u, v = round(t.pixel[0]), round(t.pixel[1])
    half = int(0.8 * t.rows_spanned / 2)
    row_profile = g[v, u - half : u + half] > 127
    col_profile = g[v - half : v + half, u] > 127
    assert np.count_nonzero(np.diff(row_profile.astype(int))) >= 20  # stripes across a row
    assert np.count_nonzero(np.diff(col_profile.astype(int))) == 0  # none down a column


# ---------------------------------------------------------------------------------- optics


def test_distortion_moves_disc_as_projectpoints_says():
    dist = np.array([-0.25, 0.05, 0.001, -0.002, 0.0])
    camera = small_camera(distortion=dist)
    centre = np.array([0.35, -1.0, 0.25])
    fmap = one_fixture(position=centre, diameter=0.04)  # 20 px disc, far off-axis
    pose = Pose.from_euler([0, 0, 0], LOOK_UP)
    frame_s = 18 / CHIP_RATE
    result = render(
        camera, fmap, pose, quiet(exposure_s=frame_s, brightness=1.0, ambient=0.0)
    )  # unstriped
    g = gray(result.image)
    assert g.max() == pytest.approx(0.5 * 255, abs=1)  # half the frame's chips are on
    vv, uu = np.mgrid[0 : g.shape[0], 0 : g.shape[1]]
    centroid = np.array([(g * uu).sum(), (g * vv).sum()]) / g.sum()
    rvec, tvec = pose.rvec_tvec()
    expected = cv2.projectPoints(centre[None, :], rvec, tvec, camera.matrix, dist)[0].reshape(2)
    pinhole = cv2.projectPoints(centre[None, :], rvec, tvec, camera.matrix, None)[0].reshape(2)
    assert np.linalg.norm(expected - pinhole) > 5  # the distortion matters here
    assert np.linalg.norm(centroid - expected) < 0.3
    assert np.linalg.norm(result.fixtures[0].pixel - expected) < 1e-6


def test_distortion_fold_back_is_not_inside():
    """OpenCV's distortion polynomial folds far off-axis points back into the image."""
    camera = Camera.from_focal(640, 480, 800.0, distortion=np.array([-0.5, 0, 0, 0, 0]))
    fmap = one_fixture(position=(1.3, -1.0, 0.0), diameter=0.05)  # 52 degrees off axis
    pose = Pose.from_euler([0, 0, 0], LOOK_UP)
    naive = camera.project(pose, fmap.positions)[0]
    assert 0 <= naive[0] < 640 and 0 <= naive[1] < 480  # folded into the picture
    (truth,) = fixture_truths(camera, fmap, pose)
    assert truth.in_front and not truth.fully_inside
    image = render(camera, fmap, pose, quiet(brightness=1.0)).image
    assert image.max() <= round(0.03 * 255) + 1  # nothing drawn


def test_sensor_noise_level():
    """Background only: mean = ambient, sigma = sqrt(ambient / full well + read^2)."""
    camera = small_camera()
    pose = Pose.from_euler([0, 0, 0], (-90, 0, 0))  # looking away from the fixture
    s = RenderSettings(ambient=0.2, full_well_e=2000.0, read_noise=0.01, seed=5)
    img = render(camera, one_fixture(), pose, s).image.astype(float)
    sigma = np.sqrt(0.2 / 2000.0 + 0.01**2) * 255
    assert img.mean() == pytest.approx(0.2 * 255, abs=0.1)
    assert img.std() == pytest.approx(np.sqrt(sigma**2 + 1 / 12), rel=0.05)


# ---------------------------------------------------------------------------------- images


def test_same_seed_same_image_other_seed_other_noise():
    camera = small_camera()
    pose = Pose.from_euler([0.1, 0, 0], LOOK_UP)
    a = render(camera, one_fixture(), pose, RenderSettings(seed=4)).image
    b = render(camera, one_fixture(), pose, RenderSettings(seed=4)).image
    c = render(camera, one_fixture(), pose, RenderSettings(seed=5)).image
    assert a.shape == (480, 640, 3) and a.dtype == np.uint8
    np.testing.assert_array_equal(a, b)
    assert np.count_nonzero(a != c) > 0.3 * a.size


def test_mirrored_camera_flips_left_right():
    pose = Pose.from_euler([0.2, 0, 0], LOOK_UP)  # disc left of centre
    s = RenderSettings(seed=2)
    plain = render(small_camera(), one_fixture(), pose, s)
    mirror = render(small_camera(mirrored=True), one_fixture(), pose, s)
    np.testing.assert_array_equal(mirror.image, plain.image[:, ::-1])
    assert not np.array_equal(mirror.image, plain.image)
    g = gray(mirror.image)
    assert np.argmax(g.sum(axis=0)) > 320 > plain.fixtures[0].pixel[0]
    assert mirror.truth_dict()["mirrored"] is True


def test_colours_per_fixture(thesis):
    _, fmap = thesis
    small = Camera.from_focal(1296, 970, 3912 / 4, row_time_s=ROW_TIME * 4)
    colours = ((0, 0, 1.0), (0, 1.0, 0), (1.0, 0, 0), (0, 1.0, 1.0))
    result = render(
        small,
        fmap,
        Pose.from_euler([0, 0, 0], LOOK_UP),
        quiet(colours=colours, exposure_s=18 / CHIP_RATE, brightness=1.0),
    )
    for t, colour in zip(result.fixtures, colours, strict=True):
        u, v = np.round(t.pixel).astype(int)
        np.testing.assert_allclose(
            result.image[v, u], np.array(colour) * 0.5 * 255 + 0.03 * 255, atol=1.5
        )
    with pytest.raises(ValueError, match="colours"):
        render(
            small, fmap, Pose.from_euler([0, 0, 0], LOOK_UP), RenderSettings(colours=colours[:2])
        )


def test_truth_dict_fields():
    result = render(small_camera(), one_fixture(), Pose.from_euler([0, 0, 0], LOOK_UP))
    d = result.truth_dict()
    assert d["image_size"] == [640, 480]
    assert np.allclose(d["rotation"], result.pose.world_from_camera)
    assert d["euler_deg"] == pytest.approx(list(LOOK_UP))
    assert d["settings"]["row_time_s"] == ROW_TIME
    assert d["settings"]["exposure_s"] == pytest.approx(0.5 / CHIP_RATE)
    (f,) = d["fixtures"]
    assert set(f) == {
        "id",
        "pixel",
        "in_front",
        "fully_inside",
        "rows_spanned",
        "frames_spanned",
        "phase_s",
        "sends_data",
        "core_pixel",
    }
    assert f["pixel"] == pytest.approx([319.5, 239.5])
    assert 0 <= f["phase_s"] < 18 / CHIP_RATE
    assert f["sends_data"] is False and f["core_pixel"] is None  # no core
    assert d["stamp_box"] is None
    assert d["settings"]["data_lights"] == [] and d["settings"]["stamp"] is None
    assert d["settings"]["core_offset"] == 0


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"chip_rate_hz": 0}, "chip_rate_hz"),
        ({"exposure_s": -1e-6}, "exposure_s"),
        ({"brightness": -1}, "brightness"),
        ({"readout": "diagonal"}, "readout"),
        ({"seed": -1}, "seed"),
        ({"colours": ((2, 0, 0),)}, "colours"),
    ],
)
def test_bad_settings_name_the_argument(kwargs, name):
    with pytest.raises(ValueError, match=name):
        RenderSettings(**kwargs)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"row_time_s": 1.0}, "row_time_s must be below 1 s, got 1.0"),
        ({"halo": "a"}, "halo must be a non-negative number, got 'a'"),
        ({"sharpen": float("inf")}, "sharpen must be finite, got inf"),
        ({"blur_px": 101.0}, "blur_px must be at most 100 px"),
        ({"off_level": True}, "off_level must be a number from 0 to 1, got True"),
        ({"vignetting": 1.0}, "vignetting must be a number from 0 to below 1, got 1.0"),
        ({"black_point": "x"}, "black_point must be a number from 0 to below 1, got 'x'"),
        ({"core_offset": 2}, r"core_offset must be a number from 0 to 1 \(radii\), got 2"),
        ({"gamma": 0}, "gamma must be a positive number, got 0"),
        ({"bayer": 1}, "bayer must be true or false, got 1"),
        ({"data_lights": (1, 1)}, "an ID twice"),
        ({"colours": "red"}, "colours must be BGR triples"),
    ],
)
def test_each_bad_setting_gets_its_own_message(kwargs, message):
    with pytest.raises(ValueError, match=message):
        RenderSettings(**kwargs)


def test_fixture_without_diameter_cannot_be_rendered():
    fmap = FixtureMap((Fixture(5, np.array([0, -1.0, 0])),))
    with pytest.raises(ValueError, match="fixture 5 has no diameter"):
        render(small_camera(), fmap, Pose.from_euler([0, 0, 0], LOOK_UP))


# -------------------------------------------------------------- off level, core, halo, soft


def _up() -> Pose:
    return Pose.from_euler([0.0, 0.0, 0.0], [90.0, 0.0, 0.0])


def test_off_level_lifts_the_dark_stripes():
    camera, fmap = small_camera(), one_fixture()
    common = dict(exposure_s=2e-6, brightness=0.8, ambient=0.0)
    _, dark = disc_column(render(camera, fmap, _up(), quiet(**common)), camera)
    _, lifted = disc_column(render(camera, fmap, _up(), quiet(off_level=0.1, **common)), camera)
    # off stripes: 0 -> 10 % of on; on stripes unchanged
    assert dark.min() < 2 and lifted.min() == pytest.approx(0.1 * 0.8 * 255, abs=3)
    assert lifted.max() == pytest.approx(dark.max(), abs=2)
    with pytest.raises(ValueError, match="off_level"):
        RenderSettings(off_level=1.5)


def test_hot_core_halo_and_soft_stripes():
    camera, fmap = small_camera(), one_fixture()
    # a steady light (exposure of a whole frame) to see the shading alone
    steady = dict(exposure_s=18 / CHIP_RATE, brightness=0.3, ambient=0.0)
    flat = gray(render(camera, fmap, _up(), quiet(**steady)).image)
    hot = gray(render(camera, fmap, _up(), quiet(core=2.0, halo=0.3, **steady)).image)
    t = render(camera, fmap, _up(), quiet(**steady)).fixtures[0]
    u, v = np.round(t.pixel).astype(int)
    r = int(t.rows_spanned / 2)
    assert hot[v, u] == pytest.approx(3.0 * flat[v, u], rel=0.05)  # centre: 1 + core
    assert hot[v, u + int(0.9 * r)] < 1.5 * flat[v, u + int(0.9 * r)]  # near the rim: ~1
    outside = (v, u + int(1.2 * r))
    assert flat[outside] < 1 and hot[outside] > 0.1 * flat[v, u]  # the glow beyond the rim
    # soft stripes: ramps between on and off instead of steps
    sharp = dict(exposure_s=2e-6, brightness=0.8, ambient=0.0)
    _, a = disc_column(render(camera, fmap, _up(), quiet(**sharp)), camera)
    _, b = disc_column(render(camera, fmap, _up(), quiet(soft=0.8, **sharp)), camera)

    def between(x: np.ndarray) -> float:
        return float(np.mean((x > 0.1 * x.max()) & (x < 0.9 * x.max())))

    assert between(a) < 0.1 and between(b) > 0.3


def test_a_bright_glow_fades_out_without_an_edge():
    """A glow far brighter than full scale fades to the background; its box must not cut it
    off in a straight edge (a step of several gray levels no camera shows)."""
    camera, fmap = small_camera(), one_fixture(diameter=0.1)
    steady = dict(exposure_s=18 / CHIP_RATE, brightness=8.0, ambient=0.0)
    img = gray(render(camera, fmap, _up(), quiet(halo=0.4, **steady)).image).astype(float)
    t = render(camera, fmap, _up(), quiet(**steady)).fixtures[0]
    u, v = np.round(t.pixel).astype(int)
    r = t.rows_spanned / 2
    right = img[v, u + int(1.2 * r) : u + int(7.0 * r)]  # the row through the centre, beyond
    assert right.size > 3 * r and right[0] > 50  # the glow is bright near the rim
    gone = int(np.argmax(right < 1))  # the first pixel at the dark background
    assert gone > 0 and right[gone - 1] <= 2  # reached by fading, not by a cut
