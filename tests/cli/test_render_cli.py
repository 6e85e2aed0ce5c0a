"""Tests of ``camvlp render``: files written, the truth JSON, and one-line errors."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from camvlp.cli import app
from camvlp.io import save_camera
from camvlp.model.camera import Camera
from conftest import one_error_line

runner = CliRunner()


@pytest.fixture
def small_camera_path(tmp_path):
    """A 640 x 480 camera (f = 500 px) that sees the thesis' four fixtures from the floor."""
    path = tmp_path / "cam.yaml"
    save_camera(Camera.from_focal(640, 480, 500.0, row_time_s=20e-6), path)
    return path


def run(camera, room, out, *extra):
    args = [
        "render",
        "--camera",
        str(camera),
        "--map",
        str(room),
        "--position",
        "0,0,0",
        "--euler",
        "90,0,0",
        "--out",
        str(out),
        *extra,
    ]
    return runner.invoke(app, args)


@pytest.mark.parametrize("suffix", [".png", ".jpg"])
def test_render_writes_image_and_truth(tmp_path, small_camera_path, thesis_room_path, suffix):
    out = tmp_path / f"photo{suffix}"
    result = run(small_camera_path, thesis_room_path, out, "--seed", "3", "--quality", "90")
    assert result.exit_code == 0, result.output
    image = cv2.imread(str(out))
    assert image.shape == (480, 640, 3)
    truth = json.loads((tmp_path / "photo.json").read_text())
    for key in ("camera_position", "rotation", "euler_deg", "image_size", "settings", "fixtures"):
        assert key in truth
    assert truth["image_size"] == [640, 480]
    assert truth["camera_position"] == [0, 0, 0]
    assert truth["euler_deg"] == pytest.approx([90, 0, 0])
    assert truth["settings"]["seed"] == 3
    assert [f["id"] for f in truth["fixtures"]] == [5, 6, 9, 10]
    for f in truth["fixtures"]:
        assert set(f) >= {
            "id",
            "pixel",
            "in_front",
            "fully_inside",
            "rows_spanned",
            "frames_spanned",
            "phase_s",
        }
        assert f["fully_inside"] is True
        u, v = np.round(f["pixel"]).astype(int)
        assert image[v - 2 : v + 3, u - 2 : u + 3].max() > 128  # a lit fixture there
    assert "photo.json" in result.stdout
    assert result.stdout.count("fixture") == 4


def test_render_options_reach_the_settings(tmp_path, small_camera_path, thesis_room_path):
    out = tmp_path / "p.png"
    result = run(
        small_camera_path,
        thesis_room_path,
        out,
        "--chip-rate",
        "5000",
        "--row-time",
        "1e-5",
        "--exposure",
        "3e-5",
        "--brightness",
        "2",
        "--ambient",
        "0",
        "--blur",
        "0",
        "--noise",
        "0",
        "--readout",
        "columns",
        "--colour",
    )
    assert result.exit_code == 0, result.output
    s = json.loads((tmp_path / "p.json").read_text())["settings"]
    assert (s["chip_rate_hz"], s["row_time_s"], s["exposure_s"]) == (5000, 1e-5, 3e-5)
    assert (s["brightness"], s["ambient"], s["blur_px"]) == (2, 0, 0)
    assert (s["full_well_e"], s["read_noise"], s["readout"]) == (0, 0, "columns")
    assert len(s["colours"]) == 4 and len({tuple(c) for c in s["colours"]}) == 4
    image = cv2.imread(str(out))
    assert image[:40].max() == 0  # no ambient, no noise: black away from the fixtures


def test_a_phone_photo_is_rendered_and_located(tmp_path, thesis_room_path):
    """A phone's processing (mosaic, tone curve, sharpening, vignetting) reaches the settings
    and the photo, and the photo is still located."""
    camera = tmp_path / "cam.yaml"  # lamps of 69 rows, 1.5 frames at 2.5 rows per chip
    save_camera(Camera.from_focal(1280, 960, 1250.0, row_time_s=20e-6), camera)
    out, plain = tmp_path / "phone.jpg", tmp_path / "plain.jpg"
    phone = ["--bayer", "--gamma", "2.2", "--sharpen", "1", "--vignetting", "0.3"]
    assert run(camera, thesis_room_path, out, "--chip-rate", "20000", *phone).exit_code == 0
    s = json.loads((tmp_path / "phone.json").read_text())["settings"]
    assert (s["bayer"], s["gamma"], s["sharpen"], s["vignetting"]) == (True, 2.2, 1, 0.3)
    assert run(camera, thesis_room_path, plain, "--chip-rate", "20000").exit_code == 0
    dark = [float(np.median(cv2.imread(str(p))[:40])) for p in (out, plain)]
    assert dark[0] > 2 * dark[1]  # the tone curve lifts the dark background
    args = ["locate", str(out), "--camera", str(camera), "--map", str(thesis_room_path)]
    located = runner.invoke(app, [*args, "--json"])
    assert located.exit_code == 0, located.output
    result = json.loads(located.output)
    assert [f["id"] for f in result["fixtures"] if f["used"]] == [9, 6, 10, 5]
    assert np.linalg.norm(result["position"]) < 0.005  # the truth is the origin, metres
    # a black point over the ambient light stores the background black, as phones do
    black = tmp_path / "black.jpg"
    assert (
        run(
            camera, thesis_room_path, black, "--chip-rate", "20000", *phone, "--black-point", "0.04"
        ).exit_code
        == 0
    )
    assert json.loads((tmp_path / "black.json").read_text())["settings"]["black_point"] == 0.04
    assert float(np.median(cv2.imread(str(black))[:40])) <= 2
    located = runner.invoke(app, ["locate", str(black), *args[2:], "--json"])
    assert located.exit_code == 0, located.output
    result = json.loads(located.output)
    assert [f["id"] for f in result["fixtures"] if f["used"]] == [9, 6, 10, 5]
    assert np.linalg.norm(result["position"]) < 0.005
    # the tone curve given on the command line: the photo read as light, located as well
    toned = runner.invoke(app, [*args, "--json", "--tone-gamma", "2.2"])
    assert toned.exit_code == 0, toned.output
    assert np.linalg.norm(json.loads(toned.output)["position"]) < 0.005
    for bad in ("0", "9", "nan"):
        refused = runner.invoke(app, [*args, "--tone-gamma", bad])
        assert refused.exit_code == 2 and "--tone-gamma" in one_error_line(refused)


def test_bad_input_givesone_error_line(tmp_path, small_camera_path, thesis_room_path):
    bad_map = tmp_path / "bad.yaml"
    bad_map.write_text("fixtures: [ {id: 5, position: [0, 1]\n")
    cases = [
        (tmp_path / "missing.yaml", thesis_room_path, "p.png", [], "missing.yaml"),
        (small_camera_path, bad_map, "p.png", [], "bad.yaml"),
        (small_camera_path, thesis_room_path, "p.gif", [], ".gif"),
        (small_camera_path, thesis_room_path, "p.png", ["--exposure", "abc"], "--exposure"),
        (small_camera_path, thesis_room_path, "p.png", ["--chip-rate", "-5"], "--chip-rate"),
        (small_camera_path, thesis_room_path, "p.png", ["--seed", "1.5"], "--seed"),
        (small_camera_path, thesis_room_path, "p.png", ["--position", "0,0"], "--position"),
        (small_camera_path, thesis_room_path, "p.png", ["--euler", "-90,0,0"], "behind"),
        (small_camera_path, thesis_room_path, "nodir/p.png", [], "nodir"),
        (small_camera_path, thesis_room_path, "p.png", ["--gamma", "0"], "--gamma"),
        (small_camera_path, thesis_room_path, "p.png", ["--vignetting", "1"], "--vignetting"),
        (small_camera_path, thesis_room_path, "p.png", ["--sharpen", "-1"], "--sharpen"),
        (small_camera_path, thesis_room_path, "p.png", ["--black-point", "1"], "--black-point"),
    ]
    for camera, room, out, extra, needle in cases:
        result = run(camera, room, tmp_path / out, *extra)
        assert result.exit_code == 2, (needle, result.output)
        assert needle in one_error_line(result)
    assert not list(tmp_path.glob("p.*"))


def test_real_photo_looks_reach_the_photo_and_the_truth(
    tmp_path, small_camera_path, thesis_room_path
):
    """An off-centre core, two lights sending data, a stamp, a portrait photo turned the
    other way: the settings, the truth and the printed lines say so."""
    out = tmp_path / "looks.png"
    stamp = "2017-02-15 17:47:52"
    result = run(
        small_camera_path,
        thesis_room_path,
        out,
        *("--core", "2", "--core-offset", "0.4", "--data-lights", "6,9", "--stamp", stamp),
        *("--readout", "columns-reversed", "--seed", "2"),
    )
    assert result.exit_code == 0, result.output
    truth = json.loads((tmp_path / "looks.json").read_text())
    s = truth["settings"]
    assert (s["core"], s["core_offset"], s["data_lights"]) == (2, 0.4, [6, 9])
    assert (s["stamp"], s["readout"]) == (stamp, "columns-reversed")
    assert [f["sends_data"] for f in truth["fixtures"]] == [False, True, True, False]
    for f in truth["fixtures"]:  # each core 0.4 radius off its centre
        off = np.hypot(*np.subtract(f["core_pixel"], f["pixel"]))
        assert off == pytest.approx(0.4 * f["rows_spanned"] / 2, rel=0.02)
    u0, v0, u1, v1 = truth["stamp_box"]
    assert u1 <= 640 and v1 <= 480 and u0 > 320 and v0 > 400  # bottom right
    image = cv2.imread(str(out))
    assert np.mean(image[v0:v1, u0:u1].min(axis=2) > 200) > 0.15  # white text there
    assert result.stdout.count("sends data") == 2
    assert "readout columns-reversed" in result.stdout and f"stamp '{stamp}'" in result.stdout
    plain = tmp_path / "plain.png"
    assert run(small_camera_path, thesis_room_path, plain).exit_code == 0
    plain_truth = json.loads((tmp_path / "plain.json").read_text())
    assert plain_truth["stamp_box"] is None
    assert all(f["core_pixel"] is None and not f["sends_data"] for f in plain_truth["fixtures"])


def test_bad_looks_give_one_error_line(tmp_path, small_camera_path, thesis_room_path):
    cases = [
        (["--core-offset", "1.5"], "--core-offset must be a number from 0 to 1"),
        (["--core-offset", "abc"], "--core-offset must be a number"),
        (["--data-lights", "6,x"], "--data-lights must be fixture IDs separated by commas"),
        (["--data-lights", ""], "--data-lights must be fixture IDs"),
        (["--data-lights", "-1"], "--data-lights must be distinct fixture IDs"),
        (["--data-lights", "6,6"], "--data-lights must be distinct"),
        (["--data-lights", "6,7"], "--data-lights names ID 7, not a fixture of the map"),
        (["--stamp", ""], "--stamp must be 1 to 100 characters"),
        (["--stamp", "17:47 \u00b0C"], "--stamp must be printable ASCII"),
    ]
    for extra, needle in cases:
        result = run(small_camera_path, thesis_room_path, tmp_path / "p.png", *extra)
        assert result.exit_code == 2, (extra, result.output)
        assert needle in one_error_line(result), (extra, result.output)
    assert not list(tmp_path.glob("p.*"))


def test_a_large_site_lists_the_fixtures_near_the_picture_and_counts_the_others(
    tmp_path, small_camera_path
):
    from camvlp.io import save_map
    from camvlp.sim.site import site_map

    site = tmp_path / "site.yaml"
    save_map(site_map(20, 10, spacing=1.0, height=4.0, diameter=0.5, seed=0), site)
    out = tmp_path / "photo.png"
    result = runner.invoke(
        app,
        ["render", "--camera", str(small_camera_path), "--map", str(site), "--position",
         "4.5,3,1.5", "--euler", "0,0,0", "--out", str(out), "--noise", "0"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    listed = [ln for ln in result.stdout.splitlines() if ln.startswith("fixture ")]
    truth = json.loads(out.with_suffix(".json").read_text())["fixtures"]
    inside = [f for f in truth if f["fully_inside"]]
    assert inside and len(inside) <= len(listed) < 200
    assert f"{200 - len(listed)} other fixtures of the map out of the picture" in result.stdout
    assert len(truth) == 200  # the truth file keeps every fixture
