"""Real photographs, read from ../shared/real/ (skipped when absent): each photo held to what
its folder's README says it gives, located as a user would locate it (the camera and map
files of ``examples/real/``, the photo's EXIF, no readout given), and the iPhone photos'
particulars.

The photos are not part of this repository.  What each README says is written once, in
``examples/real/photos.yaml``, for these tests and ``benchmarks/real_photos.py``.
"""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from camvlp import LocateSettings, locate
from camvlp.io import load_camera, load_image, load_map

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared" / "real"
REAL = SHARED / "iphone7-demo-floor"
PHOTOS = ("2017-02-15-17-47-52-84.jpg", "test.jpg", "test2.jpg")
DEMO = "2017-02-15-17-47-52-84.jpg"
EXAMPLES = REPO / "examples" / "real"

pytestmark = [
    pytest.mark.real,
    pytest.mark.long,  # seconds a test: run first (tests/conftest.py)
    pytest.mark.skipif(not SHARED.is_dir(), reason=f"real photographs not found at {SHARED}"),
]


def _harness():
    """``benchmarks/real_photos.py``, the one home of locating a photo as a user would."""
    spec = importlib.util.spec_from_file_location(
        "real_photos", REPO / "benchmarks" / "real_photos.py"
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # (its dataclasses look their module up)
    spec.loader.exec_module(module)
    return module


HARNESS = _harness()
ENTRIES = {f"{e['folder']}/{e['photo']}": e for e in HARNESS.load_manifest()}


@pytest.mark.parametrize("name", sorted(ENTRIES))
def test_each_photo_gives_what_its_readme_says(name):
    """Every light in view detected, identified right where the README or truth file says
    which it is, none wrong; located where it should be, refused where it cannot be."""
    entry = ENTRIES[name]
    if not entry["path"].is_file():
        pytest.skip(f"{entry['path']} not found")
    result, _, fixture_map = HARNESS.locate_as_user(entry)
    row = HARNESS.judge(entry, result, fixture_map)
    assert row.wrong == 0
    assert not row.failures, (row.failures, [f.reason for f in result.fixtures])


def test_a_portrait_photo_stored_upright_is_read_along_its_columns_on_the_command_line(tmp_path):
    """The Lumia stores its portrait photos upright with EXIF orientation 1: the command line
    took that to mean a readout along rows, and identified none of the five lights (786 Hz,
    0.87 stripe periods...).  The stripes say columns."""
    photo = SHARED / "jasonqsong-lumia1020" / "01.jpg"
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "camvlp",
            "locate",
            str(photo),
            "--camera",
            str(EXAMPLES / "lumia1020_small_camera.yaml"),
            "--map",
            str(EXAMPLES / "five_frequencies_room.yaml"),
            "--json",
        ],
        capture_output=True,
        text=True,
    )
    assert "Traceback" not in out.stderr
    res = json.loads(out.stdout)
    assert res["readout"].startswith("columns")
    assert sorted(f["id"] for f in res["fixtures"] if f["id"] is not None) == [1, 2, 3, 4, 5]


def test_the_luxapose_photo_with_all_five_lights_is_located_near_luxapose_own_estimate():
    """The 2000 Hz light (2 to 3 periods, a bright core) was read as 564 Hz, and the four
    lights left (three on a diagonal) fitted a pose a metre off; every light is identified
    now and the camera comes within 5 cm of Luxapose's (-1.61, 4.38, 1.24) cm."""
    entry = ENTRIES["luxapose-lumia1020/x_0_y_1.27.jpg"]
    result, _, _ = HARNESS.locate_as_user(entry)
    assert sorted(f.id for f in result.fixtures) == [1, 2, 3, 4, 5]
    assert result, result.reason
    assert np.linalg.norm(result.position - [-1.61, 4.38, 1.24]) < 5.0
    assert result.pose_margin > 0.5


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict:
    """The iPhone folder's camera and map (``examples/real``), and the camera without its row
    time."""
    d = tmp_path_factory.mktemp("real")
    text = (EXAMPLES / "iphone7_camera.yaml").read_text()
    (d / "camera_no_row_time.yaml").write_text(
        "\n".join(line for line in text.splitlines() if "row_time" not in line)
    )
    return {
        "dir": d,
        "camera": EXAMPLES / "iphone7_camera.yaml",
        "map": EXAMPLES / "demo_floor_room.yaml",
    }


@pytest.mark.parametrize("name", PHOTOS)
def test_five_fixtures_found_in_each_photo(files, name):
    camera, room = load_camera(files["camera"]), load_map(files["map"])
    image = load_image(REAL / name)
    assert image.shape[:2] == (1920, 1080)  # portrait once the EXIF orientation is applied
    res = locate(image, camera, room)
    assert len(res.fixtures) == 5
    assert res.readout == "columns"
    # five distinct lights, none cut by the border
    px = np.array([f.pixel for f in res.fixtures])
    assert np.min([np.hypot(*(a - b)) for i, a in enumerate(px) for b in px[i + 1 :]]) > 100


def test_demo_floor_photo_frequencies_corners_and_pose(files):
    camera, room = load_camera(files["camera"]), load_map(files["map"])
    res = locate(load_image(REAL / DEMO), camera, room)
    assert res, res.error
    # every light identified, its frequency within 3 % of the one the map gives it
    ids = sorted(f.id for f in res.fixtures)
    assert ids == [1, 2, 3, 4, 5]
    for f in res.fixtures:
        assert f.frequency_hz == pytest.approx(room.get(f.id).frequency_hz, rel=0.03)
        assert f.used
    # the README's stripe periods (px), as a set, match ours within 3 %
    periods = sorted(1.0 / (f.frequency_hz * camera.row_time_s) for f in res.fixtures)
    np.testing.assert_allclose(periods, sorted([15.1, 12.6, 8.4, 9.5, 10.8]), rtol=0.03)
    # corners, independently of the pose: the 4500 Hz light is the middle one, and going
    # 2500 -> 3000 -> 3500 -> 4000 Hz turns the same way in the photo as in the map (a camera
    # below the ceiling looking up, photo not mirrored: image u, v follow map x, y)
    by_id = {f.id: f.pixel for f in res.fixtures}
    centroid = np.mean([by_id[i] for i in (1, 2, 3, 4)], axis=0)
    assert min(by_id, key=lambda i: np.hypot(*(by_id[i] - centroid))) == 5

    def turn(points) -> float:
        p = np.asarray(points, dtype=float)
        return float(np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]))

    corners = [1, 2, 3, 4]
    map_turn = turn([room.get(i).position[:2] for i in corners])
    assert np.sign(turn([by_id[i] for i in corners])) == np.sign(map_turn)
    # the camera is below the ceiling (z = 0, lights facing -z), about 2 m down
    assert res.position[2] < -150
    assert res.reprojection_rms_px <= 3.0
    # how sure: about a centimetre from five lights 1 px RMS off at 2 m; the photos' own
    # independent solve (x about -2, y about 3 cm) lies within three of its sigmas
    sigma = res.position_sigma
    assert 0.1 < sigma.max() < 5.0
    assert np.all(np.abs(res.position[:2] - [-2.0, 3.0]) < 3 * sigma[:2])


def test_demo_floor_photo_without_row_time_matches_by_ratios(files):
    camera = load_camera(files["dir"] / "camera_no_row_time.yaml")
    room = load_map(files["map"])
    res = locate(load_image(REAL / DEMO), camera, room)
    assert res, res.error
    assert any("ratios" in n for n in res.notes)
    assert res.reprojection_rms_px <= 3.0
    for f in res.fixtures:
        assert f.frequency_hz == pytest.approx(room.get(f.id).frequency_hz, rel=0.03)


def test_mirrored_photo_is_flagged_then_located_with_mirrored(files):
    image = load_image(REAL / DEMO)[:, ::-1].copy()
    camera, room = load_camera(files["camera"]), load_map(files["map"])
    res = locate(image, camera, room)
    assert not res and res.position is None
    assert "mirrored" in res.error
    res = locate(image, camera, room, LocateSettings(mirrored=True))
    assert res, res.error
    assert res.reprojection_rms_px <= 3.0
    assert res.position[2] < -150


def test_mirrored_photo_on_the_command_line(files, tmp_path):
    flipped = tmp_path / "flipped.png"
    cv2.imwrite(str(flipped), load_image(REAL / DEMO)[:, ::-1])
    base = [
        sys.executable,
        "-m",
        "camvlp",
        "locate",
        str(flipped),
        "--camera",
        str(files["camera"]),
        "--map",
        str(files["map"]),
        "--json",
    ]
    out = subprocess.run(base, capture_output=True, text=True)
    assert out.returncode == 1
    assert "mirrored" in json.loads(out.stdout)["error"]
    assert "Traceback" not in out.stderr
    out = subprocess.run([*base, "--mirrored"], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout)["position"][2] < -150


def test_row_time_is_refused_on_a_photo_of_five_lights():
    """calibrate-rows measured the largest light (the 4500 Hz one) whatever frequency it was
    given: 47.7 us per row at 2500 Hz against the 26.5 us the source recorded."""
    from camvlp.analysis.calibrate import estimate_row_time

    est = estimate_row_time(load_image(REAL / DEMO), frequency_hz=2500)
    assert not est and "different stripe periods" in est.reason
