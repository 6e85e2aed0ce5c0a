"""Tests of the whole locator, ``camvlp.locate``, on simulated photographs of the small room.

Accuracy: with this small camera (f = 1000 px) rounding the fixtures' centres to whole
pixels costs about 7 mm of camera position from the floor and 2 mm from 1 m up (measured
with ``estimate_pose`` on rounded truth pixels); the locator's sub-pixel centres do far
better, so 3 mm is a bound that a locator working to a fraction of a pixel meets and one
working to whole pixels does not.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import camvlp.pipeline.solve as solve_module
from camvlp.geometry.pose import estimate_pose
from camvlp.io import InputError
from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.locate import LocateSettings, locate
from camvlp.sim.render import render
from conftest import LOOK_UP, make_small_camera, make_small_room, small_settings

MAX_ERROR_M = 3e-3

# name: (position m, thesis angles deg, readout, exposure s (None: half a chip),
#        row time s (rows per chip at 10 kHz), seed)
CASES = {
    "floor-up-rows": ((0.0, 0.0, 0.0), LOOK_UP, "rows", None, 25e-6, 1),
    "floor-tilt-rows-short-exposure": (
        (0.1, 0.0, -0.1),
        (94.0, 4.0, 137.0),
        "rows",
        1e-5,
        25e-6,
        2,
    ),
    "floor-tilt-columns-one-chip-exposure": (
        (0.1, 0.0, 0.1),
        (93.0, -3.0, 215.0),
        "columns",
        1e-4,
        1 / 55_000,
        3,
    ),
    "floor-tilt-columns": ((0.3, 0.0, -0.2), (88.0, -4.0, 10.0), "columns", 2e-5, 25e-6, 4),
    "1m-up-roll180-rows": ((0.0, -1.0, 0.0), (90.0, 0.0, 180.0), "rows", 5e-5, 30e-6, 5),
    "half-m-up-roll270-columns": ((0.0, -0.5, 0.0), (91.0, 1.0, 270.0), "columns", 1e-4, 20e-6, 6),
    "floor-roll320-few-frames": ((0.0, 0.0, 0.0), (90.0, 0.0, 320.0), "rows", None, 15e-6, 7),
    "floor-tilt-three-rows-per-chip": ((0.1, 0.0, 0.1), (92.0, 3.0, 30.0), "rows", 7e-5, 33e-6, 8),
}


def render_case(camera, room, case):
    position, euler, readout, exposure, row_time, seed = case
    pose = Pose.from_euler(position, euler)
    settings = small_settings(readout=readout, exposure_s=exposure, row_time_s=row_time, seed=seed)
    return render(camera, room, pose, settings)


@pytest.fixture(scope="module")
def renders(small_camera, small_room):
    return {name: render_case(small_camera, small_room, c) for name, c in CASES.items()}


def by_truth(result, truth, tol_px: float = 1.0):
    """The result's fixture at a truth pixel (within ``tol_px``), or None."""
    for f in result.fixtures:
        if np.hypot(*(f.pixel - truth.pixel)) < tol_px:
            return f
    return None


def rotation_error_deg(a: np.ndarray, b: np.ndarray) -> float:
    c = (np.trace(a.T @ b) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


@pytest.mark.parametrize("name", list(CASES))
def test_locates_within_millimetres(name, renders, small_camera, small_room):
    r = renders[name]
    assert all(t.fully_inside for t in r.fixtures)  # the scene is as intended
    assert min(t.frames_spanned for t in r.fixtures) >= 1.2
    res = locate(r.image, small_camera, small_room)
    assert res, res.error
    assert res.error == ""
    assert res.readout == CASES[name][2]
    assert len(res.fixtures) == len(r.fixtures)
    for t in r.fixtures:
        f = by_truth(res, t)
        assert f is not None, t.id
        assert f.id == t.id
        assert f.used, f.reason
        assert f.reason == ""
        assert f.residual_px < 0.5
    assert np.linalg.norm(res.position - r.pose.position) < MAX_ERROR_M
    assert rotation_error_deg(res.rotation, r.pose.world_from_camera) < 0.05
    assert res.pose is not None
    assert res.reprojection_rms_px < 0.5


def test_pixel_rounding_would_not_meet_the_bound(renders, small_camera, small_room):
    """The 3 mm bound is below what whole-pixel centres give (so it tests sub-pixel work)."""
    r = renders["floor-up-rows"]
    pixels = np.array([t.pixel for t in r.fixtures])
    rng = np.random.default_rng(0)
    errors = []
    for _ in range(50):
        est = estimate_pose(
            pixels + rng.uniform(-0.5, 0.5, pixels.shape), small_room.positions, small_camera
        )
        errors.append(np.linalg.norm(est.pose.position - r.pose.position))
    assert np.mean(errors) > 2 * MAX_ERROR_M


def test_to_dict_has_the_documented_keys(small_render, small_camera, small_room):
    res = locate(small_render.image, small_camera, small_room)
    d = res.to_dict()
    json.dumps(d)  # JSON-ready
    for key in (
        "position",
        "rotation",
        "euler_deg",
        "reprojection_rms_px",
        "fixtures",
        "timing_ms",
        "paths",
    ):
        assert key in d
    assert len(d["position"]) == 3
    assert np.array(d["rotation"]).shape == (3, 3)
    assert d["euler_deg"] == pytest.approx(list(small_render.pose.euler_deg), abs=0.05)
    assert d["position"] == pytest.approx(list(small_render.pose.position), abs=MAX_ERROR_M)
    assert {"prepare", "detect", "profile", "decode", "pose", "total"} == set(d["timing_ms"])
    assert all(v >= 0 for v in d["timing_ms"].values())
    # plain discs: no glowing lamp's radial fit, no joint fit, no glows taken apart
    assert not {"radial fit", "joint fit", "glows taken apart"} & set(d["paths"]), d["paths"]
    assert len(d["fixtures"]) == 5
    for f in d["fixtures"]:
        assert {"id", "pixel", "used", "margin", "reason"} <= set(f)
        assert len(f["pixel"]) == 2
        assert f["margin"] is None or f["margin"] >= 0.0
        if f["id"] is not None and f["used"] and f["hamming"] == -1:
            assert f["margin"] >= 4.0  # the likelihood ratio the model fit needs
            assert f["run_margin"] is None
        elif f["id"] is not None and f["used"]:  # read by the run-length decoder
            assert f["hamming"] == 0
            assert f["margin"] is None  # it weighs no likelihoods
            assert 0.3 <= f["run_margin"] <= 1.0
    assert sorted(f["id"] for f in d["fixtures"]) == sorted(small_room.ids)
    assert "error" not in d
    # how sure the position is: the pixels' rounding at most, so well under MAX_ERROR_M
    assert np.array(d["position_sigma"]) == pytest.approx(res.position_sigma, abs=1e-6)
    assert 0 < max(res.position_sigma) < MAX_ERROR_M


def test_no_position_sigma_without_a_position(small_render, small_camera, small_room):
    few = dataclasses.replace(small_room, fixtures=small_room.fixtures[:3])
    res = locate(small_render.image, small_camera, few)
    assert not res and res.position_sigma is None and res.to_dict()["position_sigma"] is None


def test_fixture_not_in_the_map_is_reported_and_not_used(small_render, small_camera):
    room4 = make_small_room(
        ids=(5, 6, 9, 10), xz=((0.8, 0.6), (0.8, -0.6), (-0.8, -0.6), (-0.8, 0.6))
    )
    res = locate(small_render.image, small_camera, room4)
    assert res, res.error
    assert np.linalg.norm(res.position - small_render.pose.position) < MAX_ERROR_M
    stranger = by_truth(res, small_render.fixtures[4])  # ID 12, not in room4
    assert stranger is not None
    assert not stranger.used
    assert "not in the map" in stranger.reason
    assert "12" in stranger.reason
    assert sum(f.used for f in res.fixtures) == 4


def test_disc_cut_by_the_border_is_not_used(small_camera, small_room):
    pose = Pose.from_euler([0.3, 0.0, 0.5], (90.0, 0.0, 20.0))
    r = render(small_camera, small_room, pose, small_settings(seed=11))
    cut = [t for t in r.fixtures if not t.fully_inside]
    assert [t.id for t in cut] == [6]  # ID 6's disc is cut by the top edge, centre inside
    assert 0 < cut[0].pixel[1] < 60
    res = locate(r.image, small_camera, small_room)
    assert res, res.error
    assert np.linalg.norm(res.position - pose.position) < MAX_ERROR_M
    f = by_truth(res, cut[0], tol_px=40.0)
    assert f is not None
    assert f.id == 6
    assert not f.used
    assert "border" in f.reason
    assert sum(g.used for g in res.fixtures) == 4


@pytest.mark.parametrize("how", ["camera", "settings"])
def test_mirrored_photo_is_located_with_mirroring(how, small_room):
    mirrored_camera = make_small_camera(mirrored=True)
    pose = Pose.from_euler([0.1, 0.0, -0.1], (94.0, 4.0, 137.0))
    r = render(mirrored_camera, small_room, pose, small_settings(seed=12))
    if how == "camera":
        res = locate(r.image, mirrored_camera, small_room)
    else:
        res = locate(r.image, make_small_camera(), small_room, LocateSettings(mirrored=True))
    assert res, res.error
    assert res.mirrored
    assert np.linalg.norm(res.position - pose.position) < MAX_ERROR_M
    # pixels are reported in the photo as given: the truth's u mirrored
    # (within the perspective offset of this tilted view, about half a pixel)
    for t in r.fixtures:
        shown = np.array([mirrored_camera.width - 1 - t.pixel[0], t.pixel[1]])
        assert any(np.hypot(*(f.pixel - shown)) < 1.5 and f.id == t.id for f in res.fixtures)


def test_mirrored_photo_without_mirroring_is_not_located(small_room):
    pose = Pose.from_euler([0.1, 0.0, -0.1], (94.0, 4.0, 137.0))
    r = render(make_small_camera(mirrored=True), small_room, pose, small_settings(seed=12))
    res = locate(r.image, make_small_camera(), small_room)
    assert not res
    assert res.position is None
    assert "mirror" in res.error


def test_perspective_correction_helps_a_tilted_camera(renders, small_camera, small_room):
    r = renders["floor-tilt-rows-short-exposure"]
    on = locate(r.image, small_camera, small_room)
    off = locate(r.image, small_camera, small_room, LocateSettings(correct_perspective=False))
    err_on = np.linalg.norm(on.position - r.pose.position)
    err_off = np.linalg.norm(off.position - r.pose.position)
    assert err_on < err_off


def test_three_fixtures_are_not_enough(small_camera):
    room3 = make_small_room(ids=(5, 6, 9), xz=((0.8, 0.6), (0.8, -0.6), (-0.8, -0.6)))
    r = render(small_camera, room3, Pose.from_euler([0, 0, 0], LOOK_UP), small_settings(seed=13))
    res = locate(r.image, small_camera, room3)
    assert not res
    assert res.position is None and res.rotation is None and res.euler_deg is None
    assert "4" in res.error
    assert len(res.fixtures) == 3
    assert sorted(f.id for f in res.fixtures) == [5, 6, 9]
    assert not any(f.used for f in res.fixtures)
    d = res.to_dict()
    assert d["position"] is None and d["error"]
    json.dumps(d)


def test_black_photo_is_not_located(small_camera, small_room):
    res = locate(np.zeros((960, 1280, 3), np.uint8), small_camera, small_room)
    assert not res
    assert res.position is None
    assert res.fixtures == ()
    assert res.error


def test_wrong_size_photo_raises_input_error(small_camera, small_room):
    with pytest.raises(InputError, match="1280 x 960"):
        locate(np.zeros((480, 640, 3), np.uint8), small_camera, small_room)
    # turned a quarter turn where the way it was turned matters (the principal point off
    # the centre): refused, with a hint
    k = small_camera.matrix.copy()
    k[0, 2] += 40.0
    off = Camera(1280, 960, k, row_time_s=small_camera.row_time_s)
    with pytest.raises(InputError, match="turned"):
        locate(np.zeros((1280, 960, 3), np.uint8), off, small_room)


def test_a_photo_turned_a_quarter_turn_is_read_with_the_camera_turned(
    small_render, small_camera, small_room
):
    """A phone may store a portrait photo turned, with no EXIF to say which way; with the
    principal point at the centre and radial distortion only, either way gives the same
    camera: the photo is located with the camera turned (a note says so), as it is upright.
    (The Lumia's portrait photos of ../shared/real; the camera file describes landscape.)"""
    upright = locate(small_render.image, small_camera, small_room)
    turned = np.ascontiguousarray(np.rot90(small_render.image))
    res = locate(turned, small_camera, small_room)
    assert res, res.reason
    assert any("turned a quarter turn" in n for n in res.notes)
    assert res.readout.axis == "columns"
    np.testing.assert_allclose(res.position, upright.position, atol=1e-3)
    assert small_camera.turned().size == (960, 1280)


@pytest.mark.parametrize("size", [(4, 4), (1, 1), (7, 640)])
def test_a_photo_too_small_to_locate_raises_input_error(small_room, size):
    """A camera and photo of a few pixels: bad input naming the size, not a bare ValueError
    from the detector (which the command line printed without the file)."""
    h, w = size
    camera = Camera.from_focal(w, h, 3.0)
    with pytest.raises(InputError, match=f"image is {w} x {h} pixels, too small"):
        locate(np.zeros((h, w), np.uint8), camera, small_room)


def test_gray_16_bit_photo_is_located(small_render, small_camera, small_room):
    gray16 = small_render.image.mean(axis=2).astype(np.uint16) * 257
    res = locate(gray16, small_camera, small_room)
    assert res, res.error
    assert np.linalg.norm(res.position - small_render.pose.position) < MAX_ERROR_M


def test_map_in_centimetres_gives_centimetres(small_render, small_camera, small_room):
    cm = FixtureMap(
        tuple(
            type(f)(f.id, 100 * f.position, 100 * f.diameter, f.normal) for f in small_room.fixtures
        ),
        units="cm",
    )
    res = locate(small_render.image, small_camera, cm)
    assert res, res.error
    assert np.linalg.norm(res.position - 100 * small_render.pose.position) < 100 * MAX_ERROR_M


def test_four_fixtures_one_misplaced_in_the_map_is_not_located(small_camera):
    """Four fixtures, one of them 0.8 m from where the map says: no pose rather than a bad one."""
    xz = ((0.8, 0.6), (0.8, -0.6), (-0.8, -0.6), (-0.8, 0.6))
    room4 = make_small_room(ids=(5, 6, 9, 10), xz=xz)
    pose = Pose.from_euler([0.1, 0.0, -0.1], (94.0, 4.0, 137.0))
    r = render(small_camera, room4, pose, small_settings(seed=14))
    assert locate(r.image, small_camera, room4)  # the photo itself is fine
    wrong = make_small_room(ids=(5, 6, 9, 10), xz=(*xz[:3], (0.0, 0.6)))
    res = locate(r.image, small_camera, wrong)
    assert not res
    assert res.position is None
    assert res.error
    assert not any(f.used for f in res.fixtures)


def test_a_map_without_normals_is_as_accurate_as_one_with_them(renders, small_camera, small_room):
    # Without normals the discs' plane is inferred from the fixtures (coplanar, not on a
    # line), facing the camera; assuming each disc faces the camera instead biased tilted
    # photos by millimetres along the optical axis.
    bare = FixtureMap(tuple(dataclasses.replace(f, normal=None) for f in small_room.fixtures))
    for name in ("floor-tilt-rows-short-exposure", "floor-tilt-columns"):
        r = renders[name]
        truth = r.pose.position
        with_n = locate(r.image, small_camera, small_room)
        without = locate(r.image, small_camera, bare)
        assert with_n and without, (with_n.reason, without.reason)
        e_with = np.linalg.norm(with_n.position - truth)
        e_without = np.linalg.norm(without.position - truth)
        assert abs(e_without - e_with) < 0.3e-3, (name, e_with, e_without)


def test_the_centres_covariances_are_worked_out_when_first_read(
    small_render, small_camera, small_room, monkeypatch
):
    """A plain photo's ``locate`` does not work out the centres' covariances (a tenth of a
    1080p photo's time); reading one works it out, once, the same value as the detector's
    blob gives, and the result pickles unread."""
    import pickle

    import camvlp.pipeline.detect.blob as blob_module
    from camvlp.pipeline.detect.candidates import detect_fixtures

    calls = []
    real = blob_module.ellipse_centre_covariance

    def counted(*args):
        calls.append(1)
        return real(*args)

    monkeypatch.setattr(blob_module, "ellipse_centre_covariance", counted)
    res = locate(small_render.image, small_camera, small_room)
    assert res and calls == []
    unread = pickle.loads(pickle.dumps(res))
    sigmas = [f.centre_sigma_px for f in res.fixtures]
    assert [f.centre_sigma_px for f in res.fixtures] == sigmas
    assert len(calls) == len(res.fixtures)  # one each, once
    assert [f.centre_sigma_px for f in unread.fixtures] == sigmas
    blobs = detect_fixtures(small_render.image).blobs
    by_pixel = {tuple(np.round(b.pixel, 6)): b.centre_sigma_px for b in blobs}
    assert sigmas == [by_pixel[tuple(np.round(f.pixel, 6))] for f in res.fixtures]
    assert all(0.0 < s < 0.5 for s in sigmas)


def test_a_position_less_sure_than_asked_is_not_reported(small_render, small_camera, small_room):
    """``max_position_sigma``: a position whose sigma exceeds it along an axis is not
    reported (the reason gives the sigma); one within it is reported as without a limit."""
    free = locate(small_render.image, small_camera, small_room)
    sigma = free.position_sigma
    axis = int(np.argmax(sigma))
    below = LocateSettings(max_position_sigma=0.9 * float(sigma[axis]))
    res = locate(small_render.image, small_camera, small_room, below)
    assert not res and res.position is None and res.position_sigma is None
    assert "too unsure" in res.reason and f"along {'xyz'[axis]}" in res.reason
    assert f"{sigma[axis]:.3g}" in res.reason
    assert len(res.fixtures) == 5 and not any(f.used for f in res.fixtures)
    assert all(f.id is not None for f in res.fixtures)  # still identified
    assert res.alternative_position is None and np.isnan(res.alternative_rms_px)
    above = LocateSettings(max_position_sigma=1.1 * float(sigma.max()))
    ok = locate(small_render.image, small_camera, small_room, above)
    np.testing.assert_array_equal(ok.position, free.position)
    np.testing.assert_array_equal(ok.position_sigma, sigma)


def test_a_position_sigma_checked_against_a_limit_is_worked_out_once(
    small_render, small_camera, small_room, monkeypatch
):
    import camvlp.geometry.pose_sigma as pose_sigma

    calls = []
    real = pose_sigma.position_sigma

    def counted(*args):
        calls.append(1)
        return real(*args)

    monkeypatch.setattr(pose_sigma, "position_sigma", counted)
    monkeypatch.setattr(solve_module, "position_sigma", counted)
    limited = LocateSettings(max_position_sigma=1.0)
    res = locate(small_render.image, small_camera, small_room, limited)
    assert res and calls == [1]
    assert res.to_dict()["position_sigma"] == np.round(res.position_sigma, 6).tolist()
    assert calls == [1]
    # a sigma that is not finite is refused, and said so
    monkeypatch.setattr(solve_module, "position_sigma", lambda *a: np.array([1e-6, np.nan, 0.0]))
    res = locate(small_render.image, small_camera, small_room, limited)
    assert not res and "along y is not finite, for the limit of 1" in res.reason


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf"), True, "1"])
def test_max_position_sigma_must_be_a_positive_number(bad):
    with pytest.raises(InputError, match="max_position_sigma"):
        LocateSettings(max_position_sigma=bad)
