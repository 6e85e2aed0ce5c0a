"""Tests for camera calibration (chessboard intrinsics) and the row-time measurement."""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from camvlp.analysis.calibrate import (
    bright_blob_mask,
    calibrate_camera,
    estimate_row_time,
    estimate_stripe_period,
    find_board_corners,
)
from camvlp.cli import app
from camvlp.io import load_camera, save_camera
from camvlp.model.camera import Camera, Pose, rotation_x, rotation_z
from camvlp.sim.chessboard import board_object_points, render_chessboard
from conftest import one_error_line

runner = CliRunner()

BOARD = (9, 6)  # inner corners: a board of 10 x 7 squares
SQUARE_M = 0.03
TRUE_CAMERA = Camera.from_focal(640, 480, 520.0, principal_point=(324.5, 236.0))


def _board_poses(camera: Camera, n: int, seed: int) -> list[Pose]:
    """Poses seeing the whole board, tilted 20-40 degrees about a random in-plane axis."""
    rng = np.random.default_rng(seed)
    cols, rows = BOARD
    centre = np.array([(cols - 1) / 2, (rows - 1) / 2, 0.0]) * SQUARE_M
    outline = (
        np.array([[-2, -2, 0], [cols + 1, -2, 0], [-2, rows + 1, 0], [cols + 1, rows + 1, 0]])
        * SQUARE_M
    )
    poses: list[Pose] = []
    while len(poses) < n:
        az, tilt, roll = rng.uniform(0, 360), rng.uniform(20, 40), rng.uniform(-30, 30)
        r = rotation_z(az) @ rotation_x(tilt) @ rotation_z(-az) @ rotation_z(roll)
        distance = rng.uniform(0.45, 0.6) * camera.focal_px / camera.width
        c = centre - distance * r[:, 2] + r @ rng.uniform(-0.05, 0.05, 3) * np.array([1, 1, 0])
        pose = Pose(r, c)
        uv = camera.project(pose, outline)
        if np.all(np.isfinite(uv)) and np.all(uv > 5) and np.all(uv < np.array(camera.size) - 5):
            poses.append(pose)
    return poses


def _photo(camera: Camera, pose: Pose, seed: int) -> np.ndarray:
    """A rendered board, blurred (sigma 0.7 px) with noise (sigma 2 grey levels)."""
    rng = np.random.default_rng(seed)
    img = render_chessboard(camera, pose, BOARD, SQUARE_M).astype(np.float64)
    img = cv2.GaussianBlur(img, (0, 0), 0.7) + rng.normal(0.0, 2.0, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


@cache
def _photos(n: int = 10, seed: int = 7) -> tuple[np.ndarray, ...]:
    return tuple(
        _photo(TRUE_CAMERA, p, seed + k) for k, p in enumerate(_board_poses(TRUE_CAMERA, n, seed))
    )


# ----------------------------------------------------------------------------------------
# Chessboard rendering and calibration


def test_rendered_board_corners_match_projection():
    """The renderer and the corner finder agree with the camera model to a small fraction
    of a pixel (the detected order may start from either end of the board)."""
    pose = _board_poses(TRUE_CAMERA, 1, seed=3)[0]
    corners = find_board_corners(render_chessboard(TRUE_CAMERA, pose, BOARD, SQUARE_M), BOARD)
    truth = TRUE_CAMERA.project(pose, board_object_points(BOARD, SQUARE_M))
    assert corners is not None and corners.shape == truth.shape
    err = min(np.abs(corners - truth).max(), np.abs(corners[::-1] - truth).max())
    assert err < 0.2


def test_large_photo_is_searched_downscaled_and_refined_at_full_size():
    """A photo above 1600 px is searched at reduced size; the corners stay sub-pixel."""
    cam = Camera.from_focal(2400, 1800, 1950.0)
    pose = _board_poses(cam, 1, seed=5)[0]
    img = render_chessboard(cam, pose, BOARD, SQUARE_M, supersample=1)
    img = cv2.GaussianBlur(img, (0, 0), 1.2)
    corners = find_board_corners(img, BOARD)
    truth = cam.project(pose, board_object_points(BOARD, SQUARE_M))
    assert corners is not None
    err = min(np.abs(corners - truth).max(), np.abs(corners[::-1] - truth).max())
    assert err < 0.1


def test_render_with_distortion_bends_the_board():
    """With barrel distortion the board's corners land where the distorted model puts them."""
    base = Camera.from_focal(320, 240, 260.0)
    cam = Camera(320, 240, base.matrix, [-0.25, 0.06, 0.0, 0.0, 0.0])
    pose = _board_poses(base, 1, seed=11)[0]
    img = render_chessboard(cam, pose, BOARD, SQUARE_M, supersample=2)
    corners = find_board_corners(img, BOARD)
    truth = cam.project(pose, board_object_points(BOARD, SQUARE_M))
    undistorted = base.project(pose, board_object_points(BOARD, SQUARE_M))
    assert corners is not None
    err = min(np.abs(corners - truth).max(), np.abs(corners[::-1] - truth).max())
    assert err < 0.3
    assert np.abs(truth - undistorted).max() > 3  # the distortion is visible


def test_calibration_recovers_focal_length_and_principal_point():
    result = calibrate_camera(list(_photos()), BOARD, SQUARE_M)
    assert result, result.message
    k, k_true = result.camera.matrix, TRUE_CAMERA.matrix
    assert k[0, 0] == pytest.approx(k_true[0, 0], rel=0.005)
    assert k[1, 1] == pytest.approx(k_true[1, 1], rel=0.005)
    assert np.abs(k[:2, 2] - k_true[:2, 2]).max() < 3.0
    assert np.abs(result.camera.distortion[:2]).max() < 0.1  # the lens had none
    assert result.camera.size == TRUE_CAMERA.size
    assert result.rms_px < 0.2  # noise 2/255 and blur: well under a pixel
    assert len(result.per_image_rms_px) == len(result.used) == 10
    assert result.rejected == ()


def test_fix_aspect_and_zero_tangent_and_row_time():
    result = calibrate_camera(
        list(_photos()[:6]),
        BOARD,
        SQUARE_M,
        fix_aspect=True,
        zero_tangent=True,
        row_time_s=21e-6,
    )
    assert result
    k = result.camera.matrix
    assert k[0, 0] == pytest.approx(k[1, 1], rel=1e-9)
    assert k[0, 0] == pytest.approx(520.0, rel=0.005)
    assert np.all(result.camera.distortion[2:4] == 0)
    assert result.camera.row_time_s == 21e-6


def test_rejected_photos_are_listed_with_reasons(tmp_path: Path):
    photos = list(_photos()[:4])
    blank = np.full((480, 640), 128, np.uint8)
    small = cv2.resize(photos[0], (320, 240), interpolation=cv2.INTER_AREA)
    corrupt = tmp_path / "corrupt.png"
    corrupt.write_bytes(b"\x89PNG not really an image")
    result = calibrate_camera(
        [*photos, blank, small, corrupt],
        BOARD,
        SQUARE_M,
    )
    assert result
    assert len(result.used) == 4
    reasons = dict(result.rejected)
    assert set(reasons) == {"image 5", "image 6", "corrupt.png"}
    assert "no 9x6 board" in reasons["image 5"]
    assert "320x240" in reasons["image 6"] and "640x480" in reasons["image 6"]
    assert "image" in reasons["corrupt.png"]


def test_a_photo_too_small_for_the_board_shows_none():
    """A photo too small to hold the board's squares is rejected, not an OpenCV error."""
    for shape in [(4, 4), (1, 1), (14, 640), (480, 14), (16, 16)]:
        assert find_board_corners(np.zeros(shape, np.uint8), BOARD) is None, shape
    result = calibrate_camera([*_photos()[:3], np.zeros((4, 4), np.uint8)], BOARD, SQUARE_M)
    assert result and dict(result.rejected) == {"image 4": "no 9x6 board found"}


def test_fewer_than_three_usable_photos_is_a_failure_value():
    blank = np.zeros((480, 640), np.uint8)
    result = calibrate_camera([*_photos()[:2], blank], BOARD, SQUARE_M)
    assert not result
    assert result.camera is None
    assert "only 2 of 3" in result.message and "need 3" in result.message
    assert [name for name, _ in result.rejected] == ["image 3"]


@pytest.mark.parametrize(
    ("kwargs", "word"),
    [
        ({"board": (1, 6)}, "board"),
        ({"board": (2, 6)}, "board"),
        ({"board": "9x6"}, "board"),
        ({"square_m": -0.03}, "square_m"),
        ({"images": []}, "images"),
        ({"names": ["a"]}, "names"),
    ],
)
def test_bad_arguments_raise_naming_them(kwargs, word):
    args = {"images": list(_photos()[:3]), "board": BOARD, "square_m": SQUARE_M} | kwargs
    with pytest.raises(ValueError, match=word):
        calibrate_camera(**args)


# ----------------------------------------------------------------------------------------
# Stripe period and row time


def _striped_light(
    size: int,
    diameter: float,
    row_time_s: float,
    frequency_hz: float,
    *,
    seed: int,
    exposure_s: float | None = None,
) -> np.ndarray:
    """A disc lit while sin(2 pi f t + phi) > 0, sensor row r starting at t = r * row_time.

    Each row averages the light over its exposure (16 samples); blur sigma 1 px; noise
    sigma 2 grey levels.  Stripes are horizontal (readout along the rows).
    """
    rng = np.random.default_rng(seed)
    phase = rng.uniform(0, 2 * np.pi)
    exposure = 0.2 / frequency_hz if exposure_s is None else exposure_s
    t = np.arange(size)[:, None] * row_time_s + (np.arange(16) + 0.5) / 16 * exposure
    on = (np.sin(2 * np.pi * frequency_hz * t + phase) > 0).mean(axis=1)
    centre = size / 2 + rng.uniform(-3, 3, 2)
    yy, xx = np.mgrid[0:size, 0:size]
    disc = np.clip(diameter / 2 + 0.5 - np.hypot(xx - centre[0], yy - centre[1]), 0, 1)
    img = 10.0 + 220.0 * disc * on[:, None]
    img = cv2.GaussianBlur(img, (0, 0), 1.0) + rng.normal(0, 2.0, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("axis", ["rows", "columns"])
@pytest.mark.parametrize(
    ("period_rows", "periods"),
    [(4.0, 12), (7.3, 8), (15.0, 5), (30.0, 4), (12.0, 3), (25.0, 3)],
)
def test_row_time_recovered_within_two_percent(period_rows, periods, axis):
    row_time = 18.5e-6
    freq = 1.0 / (period_rows * row_time)
    diameter = period_rows * periods
    img = _striped_light(int(diameter + 40), diameter, row_time, freq, seed=int(period_rows))
    if axis == "columns":
        img = np.ascontiguousarray(np.rot90(img))
    est = estimate_row_time(img, freq)
    assert est, est.message
    assert est.axis == axis
    assert est.row_time_s == pytest.approx(row_time, rel=0.02)
    assert est.period_px == pytest.approx(period_rows, rel=0.02)
    assert est.rows_per_s == pytest.approx(1 / row_time, rel=0.02)


def test_stripe_period_with_a_mask_over_three_periods_is_within_one_percent():
    """The decoder's use: a region of interest, its mask, about three periods."""
    row_time, period = 20e-6, 9.0
    errors = []
    for seed in range(6):
        img = _striped_light(60, 3 * period, row_time, 1 / (period * row_time), seed=seed)
        mask = bright_blob_mask(img)
        sp = estimate_stripe_period(img, mask, axis="rows")
        assert sp and sp.axis == "rows"
        assert 1.8 < sp.periods_seen < 3.0  # the rows used, inside the eroded disc
        errors.append(sp.period_px / period - 1)
    assert np.abs(errors).max() < 0.01


def test_stripe_period_picks_the_readout_axis_without_a_mask():
    row_time, period = 20e-6, 6.0
    img = _striped_light(80, 70, row_time, 1 / (period * row_time), seed=1)
    rows = estimate_stripe_period(img)
    cols = estimate_stripe_period(np.rot90(img))
    assert (rows.axis, cols.axis) == ("rows", "columns")
    assert rows.period_px == pytest.approx(period, rel=0.01)
    assert cols.period_px == pytest.approx(period, rel=0.01)
    across = estimate_stripe_period(img, axis="columns")
    assert across.strength < 0.3 < rows.strength


def test_stripe_period_rejects_bad_arguments():
    img = np.zeros((20, 30))
    with pytest.raises(ValueError, match="mask"):
        estimate_stripe_period(img, np.ones((30, 20), bool))
    with pytest.raises(ValueError, match="axis"):
        estimate_stripe_period(img, axis="diagonal")
    assert not estimate_stripe_period(img, np.zeros((20, 30), bool))
    assert not estimate_stripe_period(img)  # flat: no stripes


def test_no_light_and_steady_light_are_failure_values():
    blank = np.full((100, 100), 12, np.uint8)
    est = estimate_row_time(blank, 1000.0)
    assert not est and "no bright light" in est.message
    steady = _striped_light(100, 60, 20e-6, 1.0, seed=2, exposure_s=1.0)  # on the whole time
    est = estimate_row_time(steady, 1000.0)
    assert not est and "stripes" in est.message
    with pytest.raises(ValueError, match="frequency"):
        estimate_row_time(blank, 0.0)


def test_lights_of_different_frequencies_are_refused_not_the_largest_taken():
    """Two lights side by side: the row time of the given frequency cannot be told when their
    stripe periods differ (the largest light was measured, whatever it blinked at); lights
    that agree give it."""
    row_time = 20e-6
    big = _striped_light(120, 100, row_time, 1 / (12.0 * row_time), seed=5)  # 12 px period
    other = _striped_light(120, 80, row_time, 1 / (8.0 * row_time), seed=6)  # 8 px period
    est = estimate_row_time(np.hstack([big, other]), 1 / (8.0 * row_time))
    assert not est and np.isnan(est.row_time_s)
    assert "different stripe periods" in est.reason and "alone" in est.reason
    same = _striped_light(120, 80, row_time, 1 / (12.0 * row_time), seed=7)
    est = estimate_row_time(np.hstack([big, same]), 1 / (12.0 * row_time))
    assert est and abs(est.row_time_s / row_time - 1) < 0.02


def test_row_time_from_a_simulated_frequency_fixture():
    simulate = pytest.importorskip("camvlp.sim.render")
    from camvlp.model.fixtures import Fixture, FixtureMap

    row_time = 23.7e-6
    camera = Camera.from_focal(320, 240, 300.0, row_time_s=row_time)
    pose = Pose.from_euler([0.05, 0.0, 0.02], [90, 0, 0])  # looking up at the ceiling
    for period, readout in [(6.0, "rows"), (12.0, "columns"), (25.0, "rows")]:
        freq = 1.0 / (period * row_time)
        room = FixtureMap(
            (Fixture(0, [0.0, -2.0, 0.0], diameter=0.6, frequency_hz=freq),), mode="frequency"
        )
        settings = simulate.RenderSettings(exposure_s=0.2 / freq, readout=readout, seed=3)
        photo = simulate.render(camera, room, pose, settings).image
        est = estimate_row_time(photo, freq)
        assert est, est.message
        assert est.axis == readout
        assert est.row_time_s == pytest.approx(row_time, rel=0.02)


# ----------------------------------------------------------------------------------------
# Command line


@pytest.fixture(scope="module")
def photo_dir(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("boards")
    for k, img in enumerate(_photos()[:6]):
        cv2.imwrite(str(d / f"board_{k:02d}.png"), img)
    cv2.imwrite(str(d / "blank.png"), np.full((480, 640), 90, np.uint8))
    return d


def test_cli_calibrate_writes_a_loadable_camera_file(photo_dir: Path, tmp_path: Path):
    out = tmp_path / "camera.yaml"
    result = runner.invoke(
        app,
        [
            "calibrate",
            str(photo_dir),
            "--board",
            "9x6",
            "--square",
            "0.03",
            "--out",
            str(out),
            "--row-time",
            "2e-5",
        ],
    )
    assert result.exit_code == 0, result.output
    cam = load_camera(out)
    assert cam.size == (640, 480)
    assert cam.focal_px == pytest.approx(520.0, rel=0.005)
    assert cam.row_time_s == pytest.approx(2e-5)
    assert "rms" in result.stdout
    assert "board_05.png" in result.stdout
    assert "blank.png" in result.stdout and "no 9x6 board" in result.stdout


def test_cli_calibrate_json(photo_dir: Path, tmp_path: Path):
    out = tmp_path / "camera.json"
    images = sorted(str(p) for p in photo_dir.glob("board_0[0-3].png"))
    result = runner.invoke(
        app,
        [
            "calibrate",
            *images,
            "--board",
            "9x6",
            "--square",
            "0.03",
            "--out",
            str(out),
            "--json",
            "--fix-aspect",
            "--zero-tangent",
        ],
    )
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert summary["ok"] is True
    assert [u["photo"] for u in summary["used"]] == [Path(p).name for p in images]
    assert all(u["rms_px"] < 0.5 for u in summary["used"])
    assert summary["camera_matrix"][0][0] == pytest.approx(summary["camera_matrix"][1][1])
    assert load_camera(out).focal_px == pytest.approx(520.0, rel=0.01)


@pytest.mark.parametrize(
    ("args", "word"),
    [
        ([], "no chessboard photos"),
        (["{dir}/board_00.png", "--board", "9by6", "--square", "0.03"], "9by6"),
        (["{dir}/board_00.png", "--board", "9x6"], "--square"),
        (
            ["{dir}/board_00.png", "{dir}/missing.png", "--board", "9x6", "--square", "0.03"],
            "missing.png",
        ),
    ],
)
def test_cli_calibrate_bad_input(photo_dir: Path, tmp_path: Path, args, word):
    args = [a.replace("{dir}", str(photo_dir)) for a in args]
    result = runner.invoke(app, ["calibrate", *args, "--out", str(tmp_path / "c.yaml")])
    assert result.exit_code == 2
    assert word in one_error_line(result)
    assert not (tmp_path / "c.yaml").exists()


def test_cli_calibrate_too_few_photos_exits_1(photo_dir: Path, tmp_path: Path):
    result = runner.invoke(
        app,
        [
            "calibrate",
            str(photo_dir / "board_00.png"),
            str(photo_dir / "blank.png"),
            "--board",
            "9x6",
            "--square",
            "0.03",
            "--out",
            str(tmp_path / "c.yaml"),
        ],
    )
    assert result.exit_code == 1
    assert "need 3" in one_error_line(result)
    assert "blank.png" in result.stdout
    assert not (tmp_path / "c.yaml").exists()


def test_cli_calibrate_rows_writes_row_time(tmp_path: Path):
    row_time, period = 31e-6, 10.0
    freq = 1.0 / (period * row_time)
    img = np.ascontiguousarray(np.rot90(_striped_light(120, 90, row_time, freq, seed=4)))
    photo = tmp_path / "light.png"
    cv2.imwrite(str(photo), img)
    cam_in = tmp_path / "cam.yaml"
    save_camera(Camera.from_focal(120, 120, 100.0), cam_in)
    cam_out = tmp_path / "cam2.yaml"
    result = runner.invoke(
        app,
        [
            "calibrate-rows",
            str(photo),
            "--frequency",
            f"{freq:.6f}",
            "--camera",
            str(cam_in),
            "--out",
            str(cam_out),
        ],
    )
    assert result.exit_code == 0, result.output
    assert "columns" in result.stdout and "row time" in result.stdout
    cam = load_camera(cam_out)
    assert cam.row_time_s == pytest.approx(row_time, rel=0.02)
    assert cam.focal_px == 100.0
    result = runner.invoke(app, ["calibrate-rows", str(photo), "--frequency", str(freq), "--json"])
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    assert out["axis"] == "columns"
    assert out["row_time_s"] == pytest.approx(row_time, rel=0.02)


def test_cli_calibrate_rows_errors(tmp_path: Path):
    photo = tmp_path / "dark.png"
    cv2.imwrite(str(photo), np.full((60, 80), 5, np.uint8))
    result = runner.invoke(app, ["calibrate-rows", str(photo), "--frequency", "1000"])
    assert result.exit_code == 1
    assert "no bright light" in one_error_line(result)
    result = runner.invoke(app, ["calibrate-rows", str(photo)])
    assert result.exit_code == 2 and "--frequency" in one_error_line(result)
    result = runner.invoke(
        app,
        ["calibrate-rows", str(photo), "--frequency", "1000", "--out", str(tmp_path / "x.yaml")],
    )
    assert result.exit_code == 2 and "--camera" in one_error_line(result)
    result = runner.invoke(
        app, ["calibrate-rows", str(tmp_path / "nope.png"), "--frequency", "1000"]
    )
    assert result.exit_code == 2 and "nope.png" in one_error_line(result)
    cam = tmp_path / "cam.yaml"
    save_camera(Camera.from_focal(640, 480, 500.0), cam)
    result = runner.invoke(
        app, ["calibrate-rows", str(photo), "--frequency", "1000", "--camera", str(cam)]
    )
    assert result.exit_code == 2 and "640 x 480" in one_error_line(result)


def test_failure_values_carry_their_reason_under_both_names():
    result = calibrate_camera(_photos()[:2], BOARD, SQUARE_M)
    assert not result and result.reason.startswith("only 2 of 2")
    assert result.message == result.reason
    est = estimate_row_time(np.zeros((40, 40), np.uint8), 1000.0)
    assert not est and est.reason == est.message == "no bright light found"
