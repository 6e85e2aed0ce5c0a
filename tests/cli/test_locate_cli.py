"""Tests of ``camvlp locate``: exit codes, one-line errors, JSON, pictures.

Exit codes: 0 located, 1 not located (a readable photo without four usable fixtures),
2 bad input (a file that is missing, not what it should be, or does not match another).
A position is printed only when four decoded fixtures back it.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from camvlp.cli import main
from camvlp.io import save_map
from camvlp.model.camera import Pose
from camvlp.sim.render import render
from conftest import LOOK_UP, SMALL_ROOM_XZ, make_small_room, one_error_line, small_settings

CAMVLP = Path(sys.executable).with_name("camvlp")


def run(capsys, photo, camera, fixture_map, *extra) -> tuple[int, str, str]:
    """``camvlp locate`` in this process: (exit code, stdout, stderr)."""
    code = main(
        ["locate", str(photo), "--camera", str(camera), "--map", str(fixture_map), *map(str, extra)]
    )
    out, err = capsys.readouterr()
    return code, out, err


def no_position(out: str) -> None:
    """Nothing in stdout claims a position."""
    assert "Traceback" not in out
    if out.strip().startswith("{"):
        assert json.loads(out)["position"] is None
    else:
        assert "position" not in out


@pytest.fixture(scope="module")
def three_fixture_files(tmp_path_factory, small_camera):
    """A photo of a room with three fixtures, and that room's map."""
    room3 = make_small_room(ids=(5, 6, 9), xz=SMALL_ROOM_XZ[:3])
    r = render(small_camera, room3, Pose.from_euler([0, 0, 0], LOOK_UP), small_settings(seed=21))
    d = tmp_path_factory.mktemp("three")
    cv2.imwrite(str(d / "photo.png"), r.image)
    save_map(room3, d / "room3.yaml")
    return d / "photo.png", d / "room3.yaml"


@pytest.fixture(scope="module")
def stranger_photo(tmp_path_factory, small_camera):
    """A photo of the small room's layout whose lights send IDs the small room's map lacks."""
    strangers = make_small_room(ids=(1, 2, 3, 4, 7))
    r = render(
        small_camera, strangers, Pose.from_euler([0, 0, 0], LOOK_UP), small_settings(seed=22)
    )
    path = tmp_path_factory.mktemp("strangers") / "photo.png"
    cv2.imwrite(str(path), r.image)
    return path


# --------------------------------------------------------------------------------------------
# Located


def test_located_prints_the_position(capsys, small_files, small_render):
    code, out, err = run(capsys, small_files["photo"], small_files["camera"], small_files["map"])
    assert code == 0, err
    assert err == ""
    line = next(ln for ln in out.splitlines() if ln.startswith("position"))
    numbers = [float(v) for v in line.split("(")[1].split(")")[0].split(",")]
    assert np.linalg.norm(np.array(numbers) - small_render.pose.position) < 3e-3
    assert "5 detected, 5 used" in out
    # at the origin looking straight up, x, y and two angles are about zero, some below it:
    # they show as 0.0000 and 0.00, never with a minus sign ("-0.0000")
    assert not re.search(r"-0(\.0+)?(?![\d.])", out), out


def test_a_chip_rate_the_stripes_disagree_with_is_noted(capsys, tmp_path, small_files):
    """The map's chip_rate_hz 10 % off the 10 kHz the lights send: nothing decodes, and the
    output says which chip length the files give and which the stripes show (it said only
    that the stripes fit no ID's model); the note is printed, not only in --json."""
    room = yaml.safe_load(small_files["map"].read_text())
    room["frame"]["chip_rate_hz"] = 9000
    wrong = tmp_path / "room.yaml"
    wrong.write_text(yaml.safe_dump(room))
    code, out, err = run(capsys, small_files["photo"], small_files["camera"], wrong)
    assert code == 1, err
    note = next(ln for ln in out.splitlines() if ln.startswith("note"))
    assert "chip_rate_hz and the camera's row_time_s give 4.44 rows per chip" in note
    assert "the stripes 4.00" in note
    code, out, _ = run(capsys, small_files["photo"], small_files["camera"], wrong, "--json")
    assert "the stripes 4.00" in json.loads(out)["notes"][0]


def test_located_json(capsys, small_files, small_render):
    code, out, err = run(
        capsys, small_files["photo"], small_files["camera"], small_files["map"], "--json"
    )
    assert code == 0, err
    d = json.loads(out)
    assert np.linalg.norm(np.array(d["position"]) - small_render.pose.position) < 3e-3
    assert sorted(f["id"] for f in d["fixtures"]) == [5, 6, 9, 10, 12]
    assert all(f["used"] and f["reason"] == "" for f in d["fixtures"])
    assert {"detect", "decode", "pose"} <= set(d["timing_ms"])
    assert "error" not in d


def test_jpeg_photo_is_located(capsys, tmp_path, small_files, small_render):
    photo = tmp_path / "photo.jpg"
    cv2.imwrite(str(photo), small_render.image, [cv2.IMWRITE_JPEG_QUALITY, 90])
    code, out, err = run(capsys, photo, small_files["camera"], small_files["map"], "--json")
    assert code == 0, err
    assert np.linalg.norm(np.array(json.loads(out)["position"]) - small_render.pose.position) < 5e-3


def test_annotate_writes_a_picture(capsys, tmp_path, small_files, small_render):
    out_png = tmp_path / "annotated.png"
    code, _, err = run(
        capsys,
        small_files["photo"],
        small_files["camera"],
        small_files["map"],
        "--annotate",
        out_png,
    )
    assert code == 0, err
    assert out_png.stat().st_size > 0
    picture = cv2.imread(str(out_png))
    assert picture.shape == small_render.image.shape
    changed = np.any(picture != small_render.image, axis=2)
    assert 0.001 < changed.mean() < 0.5  # drawn on, not replaced
    # green circles (fixtures used) are drawn around the discs
    b, g, r = (picture[..., k].astype(int) for k in range(3))
    assert np.sum((g > 180) & (r < 120) & (b < 120)) > 500


def test_annotate_with_a_bad_suffix_is_a_usage_error(capsys, tmp_path, small_files):
    code, out, err = run(
        capsys,
        small_files["photo"],
        small_files["camera"],
        small_files["map"],
        "--annotate",
        tmp_path / "annotated.gif",
    )
    assert code == 2
    assert "annotate" in one_error_line(err)
    no_position(out)


def test_debug_dir_writes_the_stage_pictures(capsys, tmp_path, small_files):
    debug = tmp_path / "debug"
    code, _, err = run(
        capsys,
        small_files["photo"],
        small_files["camera"],
        small_files["map"],
        "--debug-dir",
        debug,
    )
    assert code == 0, err
    names = sorted(p.name for p in debug.iterdir())
    assert names == [
        "1_candidates.png",
        *(f"2_fixture_{k}.png" for k in range(5)),
        "3_profiles.png",
    ]
    for p in debug.iterdir():
        img = cv2.imread(str(p))
        assert img is not None and img.size > 0 and img.max() > img.min(), p.name
    candidates = cv2.imread(str(debug / "1_candidates.png"), cv2.IMREAD_GRAYSCALE)
    n, _ = cv2.connectedComponents((candidates > 0).astype(np.uint8))
    assert n - 1 == 5  # one candidate per fixture


# --------------------------------------------------------------------------------------------
# Not located: exit 1


def test_black_photo_is_not_located(capsys, tmp_path, small_files):
    photo = tmp_path / "black.png"
    cv2.imwrite(str(photo), np.zeros((960, 1280, 3), np.uint8))
    code, out, err = run(capsys, photo, small_files["camera"], small_files["map"])
    assert code == 1
    line = one_error_line(err)
    assert "not located" in line and "black.png" in line
    no_position(out)


def test_three_fixtures_are_not_located(capsys, small_files, three_fixture_files):
    photo, room3 = three_fixture_files
    code, out, err = run(capsys, photo, small_files["camera"], room3)
    assert code == 1
    assert "4" in one_error_line(err)
    no_position(out)
    assert "3 detected, 0 used" in out


def test_ids_not_in_the_map_are_not_located(capsys, small_files, stranger_photo):
    # the readout given: with no light of the map in view, its direction cannot be told
    code, out, err = run(
        capsys, stranger_photo, small_files["camera"], small_files["map"], "--readout", "rows"
    )
    assert code == 1
    one_error_line(err)
    no_position(out)
    assert "not in the map" in out


def test_not_located_json_lists_the_fixtures(capsys, small_files, stranger_photo):
    code, out, err = run(
        capsys,
        stranger_photo,
        small_files["camera"],
        small_files["map"],
        "--json",
        "--readout",
        "rows",
    )
    assert code == 1
    assert "Traceback" not in err
    assert len(out.strip().splitlines()) == 1
    d = json.loads(out)
    assert d["position"] is None
    assert d["error"]
    # an ID the map lacks is no fixture's identity: told in the reason only
    assert [f["id"] for f in d["fixtures"]] == [None] * 5
    sent = sorted(int(re.search(r"sends ID (\d+)", f["reason"]).group(1)) for f in d["fixtures"])
    assert sent == [1, 2, 3, 4, 7]
    for f in d["fixtures"]:
        assert not f["used"]
        assert "not in the map" in f["reason"]
    # not told which way the sensor read, no light of the map to tell it: nothing is guessed
    code, out, err = run(
        capsys, stranger_photo, small_files["camera"], small_files["map"], "--json"
    )
    assert code == 1
    for f in json.loads(out)["fixtures"]:
        assert not f["used"]
        assert "not in the map" in f["reason"] or "direction undecided" in f["reason"]


def test_three_fixtures_json(capsys, small_files, three_fixture_files):
    photo, room3 = three_fixture_files
    code, out, _ = run(capsys, photo, small_files["camera"], room3, "--json")
    assert code == 1
    d = json.loads(out)
    assert d["position"] is None and d["rotation"] is None
    assert "4" in d["error"]
    assert len(d["fixtures"]) == 3


# --------------------------------------------------------------------------------------------
# Bad input: exit 2


def test_missing_photo(capsys, tmp_path, small_files):
    code, out, err = run(capsys, tmp_path / "absent.jpg", small_files["camera"], small_files["map"])
    assert code == 2
    assert "absent.jpg" in one_error_line(err)
    no_position(out)


def test_not_an_image(capsys, tmp_path, small_files):
    photo = tmp_path / "notes.jpg"
    photo.write_text("these are not the pixels you are looking for\n")
    code, out, err = run(capsys, photo, small_files["camera"], small_files["map"])
    assert code == 2
    assert "notes.jpg" in one_error_line(err)
    no_position(out)


def test_truncated_jpeg(capsys, tmp_path, small_files, small_render):
    ok, buf = cv2.imencode(".jpg", small_render.image, [cv2.IMWRITE_JPEG_QUALITY, 90])
    assert ok
    photo = tmp_path / "cut.jpg"
    photo.write_bytes(buf.tobytes()[: buf.size // 2])
    code, out, err = run(capsys, photo, small_files["camera"], small_files["map"])
    assert code == 2
    line = one_error_line(err)
    assert "cut.jpg" in line and "truncated" in line
    no_position(out)


def test_photo_size_does_not_match_the_camera(capsys, tmp_path, small_files, small_render):
    photo = tmp_path / "half.png"
    cv2.imwrite(str(photo), cv2.resize(small_render.image, (640, 480)))
    code, out, err = run(capsys, photo, small_files["camera"], small_files["map"])
    assert code == 2
    line = one_error_line(err)
    assert "640 x 480" in line and "half.png" in line
    no_position(out)


@pytest.mark.parametrize(
    "text",
    [
        "image_width: [1280\n",  # not YAML
        "image_width: 1280\nimage_height: 960\n",  # no intrinsics
        "image_width: 1280\nimage_height: 960\ncamera_matrix: [1, 2, 3]\n",  # not 3 x 3
        "just a line of text\n",  # not a mapping
    ],
)
def test_malformed_camera_file(capsys, tmp_path, small_files, text):
    camera = tmp_path / "camera.yaml"
    camera.write_text(text)
    code, out, err = run(capsys, small_files["photo"], camera, small_files["map"])
    assert code == 2
    assert "camera.yaml" in one_error_line(err)
    no_position(out)


@pytest.mark.parametrize(
    "text",
    [
        "fixtures: [\n",  # not YAML
        "units: m\n",  # no fixtures
        "fixtures:\n  - {id: 5}\n",  # no position
        "fixtures:\n  - {id: 5, position: [0, 1]}\n",  # two coordinates
        "fixtures:\n  - {id: 99, position: [0, -2.7, 0]}\n",  # ID beyond 4 bits
    ],
)
def test_malformed_map_file(capsys, tmp_path, small_files, text):
    room = tmp_path / "room.yaml"
    room.write_text(text)
    code, out, err = run(capsys, small_files["photo"], small_files["camera"], room)
    assert code == 2
    assert "room.yaml" in one_error_line(err)
    no_position(out)


def test_missing_camera_file(capsys, tmp_path, small_files):
    code, out, err = run(capsys, small_files["photo"], tmp_path / "nocam.yaml", small_files["map"])
    assert code == 2
    assert "nocam.yaml" in one_error_line(err)
    no_position(out)


def test_a_position_less_sure_than_max_sigma_is_not_located(capsys, small_files):
    """``--max-sigma``: exit 1 and the reason when the position is less sure than asked,
    located as without it when it is surer."""
    files = small_files["photo"], small_files["camera"], small_files["map"]
    code, out, err = run(capsys, *files, "--max-sigma", "1e-9")
    assert code == 1
    assert "too unsure" in one_error_line(err) and "over the limit of 1e-09" in err
    no_position(out)
    code, out, err = run(capsys, *files, "--max-sigma", "0.01", "--json")
    assert code == 0, err
    assert max(json.loads(out)["position_sigma"]) <= 0.01


@pytest.mark.parametrize(
    "option",
    [["--solver", "magic"], ["--readout", "diagonal"], ["--max-sigma", "0"], ["--max-sigma", "-1"]],
)
def test_bad_option_values(capsys, small_files, option):
    code, out, err = run(
        capsys, small_files["photo"], small_files["camera"], small_files["map"], *option
    )
    assert code == 2
    assert option[0].lstrip("-") in one_error_line(err)
    no_position(out)


# --------------------------------------------------------------------------------------------
# The console script itself


@pytest.mark.skipif(not CAMVLP.exists(), reason="console script not installed")
def test_console_script_exit_codes(tmp_path, small_files, stranger_photo):
    base = ["--camera", str(small_files["camera"]), "--map", str(small_files["map"])]
    done = subprocess.run(
        [str(CAMVLP), "locate", str(tmp_path / "absent.png"), *base],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 2
    one_error_line(done.stderr)
    assert done.stdout == ""
    done = subprocess.run(
        [str(CAMVLP), "locate", str(stranger_photo), *base, "--json"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 1
    assert "Traceback" not in done.stderr
    assert json.loads(done.stdout)["position"] is None
