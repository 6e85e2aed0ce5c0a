"""``camvlp render-chessboard``: photos a camera file's camera would take of a chessboard, from
which ``camvlp calibrate`` finds that camera again."""

from __future__ import annotations

import json

import numpy as np
import pytest

from camvlp.analysis.calibrate import find_board_corners
from camvlp.cli import main
from camvlp.io import load_camera, load_image, save_camera
from camvlp.model.camera import Camera
from conftest import one_error_line

#: A VGA camera with its principal point off the centre (so that finding it is a test).
CAMERA = Camera.from_focal(640, 480, 520.0, principal_point=(324.5, 236.0))
#: How far calibrate's focal lengths and principal point may be from the camera file's, px.
#: The renders' corners are found within 0.08 px of their truth (0.025 px RMS reprojection
#: over 12 views); calibrating 12 views of seeds 0 to 3 gave focal lengths within 0.14 px
#: and principal points within 0.13 px (0.03 % and 0.1 px): 1 px is seven times that, and
#: 0.2 % of f, the error of a careful calibration from real photos.
TOLERANCE_PX = 1.0


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """The camera file, and 10 views rendered from it (seed 3) in ``views/``."""
    d = tmp_path_factory.mktemp("chessboard")
    save_camera(CAMERA, d / "camera.yaml")
    args = ["render-chessboard", "--camera", str(d / "camera.yaml"), "--out", str(d / "views")]
    assert main([*args, "--views", "10", "--seed", "3"]) == 0
    return d


def test_calibrate_recovers_the_camera_of_the_renders(rendered, capsys):
    out = rendered / "calibrated.yaml"
    args = ["calibrate", str(rendered / "views"), "--board", "9x6", "--square", "0.025"]
    code = main([*args, "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    k, k_true = load_camera(out).matrix, CAMERA.matrix
    assert abs(k[0, 0] - k_true[0, 0]) < TOLERANCE_PX
    assert abs(k[1, 1] - k_true[1, 1]) < TOLERANCE_PX
    assert np.abs(k[:2, 2] - k_true[:2, 2]).max() < TOLERANCE_PX


def test_the_truth_gives_each_photo_its_pose_and_corners(rendered):
    truth = json.loads((rendered / "views" / "truth.json").read_text())
    assert truth["board"] == [9, 6] and truth["square_m"] == 0.025 and truth["seed"] == 3
    np.testing.assert_allclose(truth["camera"]["camera_matrix"], CAMERA.matrix)
    photos = sorted(p.name for p in (rendered / "views").glob("*.png"))
    assert photos == [f"board_{k:02d}.png" for k in range(1, 11)]
    assert [v["photo"] for v in truth["views"]] == photos
    positions = np.array([v["position_m"] for v in truth["views"]])
    assert len(np.unique(positions.round(6), axis=0)) == 10  # ten poses, not one
    for view in truth["views"][:3]:
        image = load_image(rendered / "views" / view["photo"])
        assert image.shape[:2] == (480, 640)
        found = find_board_corners(image, (9, 6))
        corners = np.array(view["corners_px"])
        assert found is not None and corners.shape == (54, 2)
        err = min(np.abs(found - corners).max(), np.abs(found[::-1] - corners).max())
        assert err < 0.2


def test_the_same_seed_renders_the_same_photos(rendered, tmp_path):
    args = ["render-chessboard", "--camera", str(rendered / "camera.yaml"), "--out"]
    assert main([*args, str(tmp_path / "again"), "--views", "10", "--seed", "3"]) == 0
    first = (rendered / "views" / "board_04.png").read_bytes()
    assert (tmp_path / "again" / "board_04.png").read_bytes() == first
    assert main([*args, str(tmp_path / "other"), "--views", "2", "--seed", "4"]) == 0
    assert (tmp_path / "other" / "board_01.png").read_bytes() != (
        rendered / "views" / "board_01.png"
    ).read_bytes()


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        (["--views", "0"], "--views must be from 1 to"),
        (["--board", "2x9"], "--board must be COLSxROWS"),
        (["--square", "-1"], "--square must be a positive size"),
        (["--seed", "-1"], "--seed must be a non-negative integer"),
        (["--blur", "1000"], "--blur must be from 0 to 100 pixels"),
        (["--noise", "-2"], "--noise must be from 0 to 255"),
    ],
)
def test_bad_options_are_one_error_line(rendered, tmp_path, capsys, extra, words):
    args = ["render-chessboard", "--camera", str(rendered / "camera.yaml")]
    assert main([*args, "--out", str(tmp_path / "out"), *extra]) == 2
    assert words in one_error_line(capsys.readouterr().err)
    assert not (tmp_path / "out").exists()  # nothing written
