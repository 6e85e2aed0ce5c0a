"""Tests for the file formats: camera files, map files and photographs."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from camvlp.io import InputError, load_camera, load_image, load_map, save_camera, save_map
from camvlp.model.camera import Camera
from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.model.linecode import FrameFormat

THESIS_K = [[3912.0, 0.0, 2592.0], [0.0, 3912.0, 1940.0], [0.0, 0.0, 1.0]]  # thesis eq. 3.9
THESIS_K_FLAT = [3912.0, 0.0, 2592.0, 0.0, 3912.0, 1940.0, 0.0, 0.0, 1.0]
#: A valid camera file's first lines.
SIZE = "image_width: 640\nimage_height: 480\n"
FOCAL = SIZE + "focal_length_px: 500\n"


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _raises_naming(func, path: Path, *words: str) -> InputError:
    """Call ``func(path)``, expect an InputError whose single line names the file and words."""
    with pytest.raises(InputError) as info:
        func(path)
    message = str(info.value)
    assert "\n" not in message
    assert str(path) in message, message
    for word in words:
        assert word in message, message
    return info.value


# --- camera files ---------------------------------------------------------------------------


def test_load_the_example_camera(thesis_camera_path: Path):
    cam = load_camera(thesis_camera_path)
    assert cam.size == (5184, 3880)
    np.testing.assert_array_equal(cam.matrix, THESIS_K)
    np.testing.assert_array_equal(cam.distortion, np.zeros(5))
    assert cam.row_time_s == 20e-6
    assert cam.mirrored is False and cam.readout is None


def test_json_camera_with_the_same_keys(tmp_path: Path, thesis_camera_path: Path):
    path = tmp_path / "cam.json"
    path.write_text(
        json.dumps(
            {
                "image_width": 5184,
                "image_height": 3880,
                "camera_matrix": {"rows": 3, "cols": 3, "dt": "d", "data": THESIS_K_FLAT},
                "distortion_coefficients": [[0, 0, 0, 0, 0]],
                "row_time_s": 2e-5,
            }
        )
    )
    assert _same_camera(load_camera(path), load_camera(thesis_camera_path))


def test_plain_yaml_with_nested_list_matrix(tmp_path: Path):
    path = _write(
        tmp_path / "cam.yml",
        "image_width: 640\nimage_height: 480\n"
        "camera_matrix: [[500, 0, 320], [0, 510, 240], [0, 0, 1]]\n"
        "distortion_coefficients: [-0.1, 0.02, 0, 0]\n"
        "readout: columns\nmirrored: true\n",
    )
    cam = load_camera(path)
    np.testing.assert_array_equal(cam.matrix, [[500, 0, 320], [0, 510, 240], [0, 0, 1]])
    np.testing.assert_array_equal(cam.distortion, [-0.1, 0.02, 0, 0])
    assert cam.row_time_s is None and cam.readout == "columns" and cam.mirrored is True


def _same_camera(a: Camera, b: Camera) -> bool:
    return (
        a.size == b.size
        and np.array_equal(a.matrix, b.matrix)
        and np.array_equal(a.distortion, b.distortion)
        and a.row_time_s == b.row_time_s
        and a.mirrored == b.mirrored
        and a.readout == b.readout
        and a.tone_gamma == b.tone_gamma
    )


@pytest.mark.parametrize("suffix", [".yaml", ".yml", ".json"])
@pytest.mark.parametrize(
    "extra",
    [
        {},
        {"row_time_s": 1.7e-5},
        {"row_time_s": 3.1e-5, "mirrored": True},
        {"mirrored": True, "readout": "columns"},
        {"tone_gamma": 2.2},
    ],
)
def test_save_camera_round_trips(tmp_path: Path, suffix: str, extra: dict):
    k = [[1234.5, 0, 640.25], [0, 1236.75, 359.5], [0, 0, 1]]
    cam = Camera(1280, 720, k, [0.1234567891, -0.05, 0.001, -0.002, 0.0123], **extra)
    path = tmp_path / f"cam{suffix}"
    save_camera(cam, path, extra={"rms_px": 0.42})
    if suffix != ".json":
        assert path.read_text().startswith("%YAML")  # written by cv2.FileStorage
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)  # and readable by it
        np.testing.assert_array_equal(fs.getNode("camera_matrix").mat(), k)
        fs.release()
    assert _same_camera(load_camera(path), cam)


@pytest.mark.parametrize("bad", ["0", "-2", "9", "true", "fast", ".nan"])
def test_a_bad_tone_gamma_is_refused_naming_the_key(tmp_path: Path, bad: str):
    base = "image_width: 64\nimage_height: 48\nfocal_length_px: 50\n"
    with pytest.raises(InputError, match="tone_gamma"):
        load_camera(_write(tmp_path / "cam.yaml", base + f"tone_gamma: {bad}\n"))
    cam = load_camera(_write(tmp_path / "ok.yaml", base + "tone_gamma: 2.2\n"))
    assert cam.tone_gamma == 2.2 and cam.with_size(32, 24).tone_gamma == 2.2


def test_save_camera_without_distortion_loads_as_zero_distortion(tmp_path: Path):
    cam = Camera(64, 48, [[50, 0, 31.5], [0, 50, 23.5], [0, 0, 1]])
    save_camera(cam, tmp_path / "cam.yaml")
    back = load_camera(tmp_path / "cam.yaml")
    assert not np.any(back.distortion) and back.dist_or_none is None


def test_principal_point_centre_and_list(tmp_path: Path):
    base = "image_width: 101\nimage_height: 51\n"
    base += "camera_matrix: [[80, 0, 10], [0, 80, 12], [0, 0, 1]]\n"
    cam = load_camera(_write(tmp_path / "a.yaml", base + "principal_point: centre\n"))
    np.testing.assert_array_equal(cam.matrix[:2, 2], [50.0, 25.0])  # (w - 1) / 2, (h - 1) / 2
    cam = load_camera(_write(tmp_path / "b.yaml", base + "principal_point: [49.5, 24]\n"))
    np.testing.assert_array_equal(cam.matrix[:2, 2], [49.5, 24.0])
    _raises_naming(load_camera, _write(tmp_path / "c.yaml", base + "principal_point: middle\n"),
                   "principal_point")  # fmt: skip


def test_focal_length_px(tmp_path: Path):
    text = "image_width: 5184\nimage_height: 3880\nfocal_length_px: 3912\n"
    path = _write(tmp_path / "f.yaml", text)
    cam = load_camera(path)
    np.testing.assert_array_equal(cam.matrix, [[3912, 0, 2591.5], [0, 3912, 1939.5], [0, 0, 1]])
    assert cam.distortion.size == 0


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("image_width: [1, 2\n", ("malformed",)),
        ("just some words\n", ("malformed",)),
        ("image_height: 480\ncamera_matrix: [[5, 0, 1], [0, 5, 1], [0, 0, 1]]\n", ("image_width",)),
        (SIZE + "camera_matrix: [[500, 0], [0, 500]]\n", ("camera_matrix", "9")),
        (SIZE + "camera_matrix: [[500, 0, a], [0, 500, 1], [0, 0, 1]]\n", ("camera_matrix",)),
        (SIZE + "camera_matrix: [[500, 0, 1], [0, 500, 1], [0, 0, 1]]\nimage_width: -640\n",
         ("image_width",)),
        (FOCAL + "row_time_s: -2.0e-5\n", ("row_time_s",)),
        (FOCAL + "row_time_s: fast\n", ("row_time_s",)),
        (FOCAL + "distortion_coefficients: [1, 2, 3]\n", ("distortion",)),
        (SIZE, ("camera_matrix", "focal_length_px")),
        (FOCAL + "mirrored: maybe\n", ("mirrored",)),
        (FOCAL + "readout: sideways\n", ("readout",)),
    ],
)  # fmt: skip
def test_malformed_camera_files_name_the_file_and_key(tmp_path: Path, text: str, words):
    _raises_naming(load_camera, _write(tmp_path / "bad.yaml", text), *words)


@pytest.mark.parametrize(
    ("name", "text", "words"),
    [
        ("a.yaml", FOCAL + "image_width: 64\n", ("'image_width' is given twice", "line 4")),
        ("b.yaml", "%YAML:1.0\n---\n" + FOCAL + "row_time_s: 2e-5\nrow_time_s: 3e-5\n",
         ("'row_time_s' is given twice", "line 7")),
        ("c.json", '{"image_width": 640, "image_height": 480, "focal_length_px": 500, '
                   '"focal_length_px": 900}', ("'focal_length_px' is given twice",)),
    ],
)  # fmt: skip
def test_a_key_given_twice_is_refused_not_the_last_taken(tmp_path: Path, name, text, words):
    """YAML and JSON parsers keep the last of two equal keys silently; camvlp refuses them."""
    _raises_naming(load_camera, _write(tmp_path / name, text), "malformed", *words)


@pytest.mark.parametrize(
    ("name", "text", "got"),
    [
        ("a.json", "[1, 2, 3]", "a list"),
        ("b.json", '"room"', "a string"),
        ("c.json", "3.5", "a number"),
        ("d.json", "true", "true or false"),
        ("e.json", "null", "nothing"),
        ("f.yaml", "- 1\n- 2\n", "a list"),
        ("g.yaml", "# only a comment\n", "nothing"),
    ],
)
def test_a_file_that_is_not_a_mapping_says_what_it_holds(tmp_path: Path, name, text, got):
    """Camera, map and sidecar files alike: one line, the file named, what was found."""
    path = _write(tmp_path / name, text)
    for load in (load_camera, load_map):
        _raises_naming(load, path, f"expected a mapping of keys, got {got}")


def test_missing_camera_file_and_directory(tmp_path: Path):
    _raises_naming(load_camera, tmp_path / "nope.yaml", "not found")
    _raises_naming(load_camera, tmp_path, "directory")


def test_input_error_is_a_value_error():
    err = InputError("bad thing", "x.yaml")
    assert isinstance(err, ValueError) and str(err) == "bad thing (x.yaml)"
    assert err.what == "bad thing" and err.source == "x.yaml"


# --- map files ------------------------------------------------------------------------------


def test_load_the_example_map(thesis_room_path: Path):
    fm = load_map(thesis_room_path)
    assert fm.ids == [5, 6, 9, 10]
    assert fm.units == "m" and fm.unit_m == 1.0 and fm.mode == "manchester"
    assert fm.frame == FrameFormat("111", 4, "00")
    corners = np.tile([0.7935, 0.5935], (4, 1))
    np.testing.assert_array_equal(np.abs(fm.positions[:, [0, 2]]), corners)
    assert np.all(fm.positions[:, 1] == -2.7)
    for f in fm.fixtures:
        assert f.diameter == 0.15
        np.testing.assert_array_equal(f.normal, [0, 1, 0])
    assert fm.get(9).position.tolist() == [-0.7935, -2.7, -0.5935] and fm.get(7) is None
    # IDs as NumPy gives them, and what is no ID, looked up as the fixtures' own
    assert fm.get(np.int64(6)) is fm.get(6) and fm.get(None) is None and fm.get([5]) is None
    smaller = dataclasses.replace(fm, fixtures=fm.fixtures[:2])  # (its own lookup)
    assert smaller.get(5) is fm.get(5) and smaller.get(9) is None
    assert fm.source == str(thesis_room_path)


MAP_HEAD = 'frame: {preamble: "111", id_bits: 4, postamble: "00"}\nfixtures:\n'


def _map(tmp_path: Path, body: str, head: str = MAP_HEAD, name: str = "map.yaml") -> Path:
    return _write(tmp_path / name, head + body)


@pytest.mark.parametrize(
    ("body", "words"),
    [
        ("  - {id: 5, position: [0, 0, 0]}\n  - {id: 5, position: [1, 0, 0]}\n",
         ("duplicate", "fixture 5")),
        ("  - {id: 16, position: [0, 0, 0]}\n", ("fixture 16", "4 bits")),
        ("  - {id: 3, position: [1, 2, 3]}\n  - {id: 4, position: [1, 2, 3.0]}\n",
         ("fixtures 3 and 4", "both at position [1, 2, 3]")),
        ("  - {id: 3}\n", ("fixture 3", "position")),
        ("  - {id: 3, position: [0, x, 0]}\n", ("fixture 3", "position")),
        ("  - {id: 3, position: [0, 1]}\n", ("fixture 3", "position")),
        ("  - {id: 3, position: [0, 0, 0], diameter: -1}\n", ("fixture 3", "diameter")),
        ("  - {id: 3, position: [0, 0, 0], normal: [0, 0, 0]}\n",
         ("fixture 3", "normal", "got [0.0, 0.0, 0.0]")),
        ("  - {position: [0, 0, 0]}\n", ("fixture #1", "id")),
        ("  - {id: 2.5, position: [0, 0, 0]}\n", ("fixture #1", "id")),
        ("  - {id: 3, position: [0, 0, 0]}\n  - 7\n",
         ("map fixture #2: expected a mapping of keys, got a number",)),
    ],
)  # fmt: skip
def test_malformed_fixtures_name_the_file_and_fixture(tmp_path: Path, body: str, words):
    _raises_naming(load_map, _map(tmp_path, body), *words)


@pytest.mark.parametrize(
    ("head", "words"),
    [
        ('frame: {preamble: "1", id_bits: 4, postamble: "0"}\nfixtures:\n', ("ambiguous",)),
        ('frame: {preamble: "121"}\nfixtures:\n', ("preamble",)),
        ("frame: {postamble: 00}\nfixtures:\n", ("postamble", "quoted")),  # YAML reads 0
        ("frame: {mode: morse}\nfixtures:\n", ("mode",)),
        ("frame: [1, 2]\nfixtures:\n", ("map frame: expected a mapping of keys, got a list",)),
        ("units: ft\nfixtures:\n", ("units", "ft")),
    ],
)
def test_malformed_frames_and_units(tmp_path: Path, head: str, words):
    _raises_naming(load_map, _map(tmp_path, "  - {id: 3, position: [0, 0, 0]}\n", head), *words)


def test_a_map_key_given_twice_is_refused(tmp_path: Path):
    """A fixture's second ``position`` (or a second ``fixtures`` list) is not silently taken."""
    body = (
        "  - {id: 3, position: [0, 0, 0]}\n  - {id: 4, position: [1, 0, 0], position: [5, 5, 5]}\n"
    )
    _raises_naming(load_map, _map(tmp_path, body), "'position' is given twice", "line 4")
    twice = "fixtures:\n  - {id: 4, position: [1, 0, 0]}\n"
    _raises_naming(load_map, _map(tmp_path, twice + twice, head=""), "'fixtures' is given twice")
    as_json = '{"fixtures": [{"id": 3, "id": 4, "position": [0, 0, 0]}]}'
    _raises_naming(load_map, _write(tmp_path / "m.json", as_json), "'id' is given twice")


@pytest.mark.parametrize(
    ("where", "refused"),
    [("[-100000, 3]", True), ("[320, 5000]", True), ("[-320, 240]", False), ("[700, 10]", False)],
)
def test_a_principal_point_far_outside_the_image_is_refused(tmp_path: Path, where, refused):
    """A principal point in other units or swapped far off the photo made locate give a
    position tens of metres off with exit 0; a lens shift or a crop moves it by a share."""
    text = f"image_width: 640\nimage_height: 480\nfocal_length_px: 500\nprincipal_point: {where}\n"
    path = _write(tmp_path / "c.yaml", text)
    if refused:
        _raises_naming(load_camera, path, "principal point", "640 x 480")
    else:
        assert load_camera(path).width == 640


def test_a_key_that_reads_almost_as_a_known_one_is_refused_naming_both(tmp_path: Path):
    """A typo (``diametre``) would be ignored and its value lost; a note the file carries
    (``name``) is not a typo and is left alone."""
    body = "  - {id: 3, position: [0, 0, 0], diametre: 0.2}\n"
    _raises_naming(load_map, _map(tmp_path, body), "fixture 3", "'diametre'", "'diameter'")
    head = "frame: {chip_rate: 10000}\nfixtures:\n"
    clean = "  - {id: 3, position: [0, 0, 0]}\n"
    _raises_naming(load_map, _map(tmp_path, clean, head), "frame", "'chip_rate_hz'")
    fm = load_map(_map(tmp_path, "  - {id: 3, position: [0, 0, 0], name: hall}\n"))
    assert fm.fixtures[0].id == 3 and fm.fixtures[0].diameter is None
    cam = "image_width: 640\nimage_height: 480\nfocal_length_px: 500\nrow_time: 2.0e-5\n"
    _raises_naming(load_camera, _write(tmp_path / "c.yaml", cam), "'row_time'", "'row_time_s'")
    noted = cam.replace("row_time", "calibration_rms_px")
    assert load_camera(_write(tmp_path / "d.yaml", noted)).row_time_s is None


def test_empty_or_missing_fixtures(tmp_path: Path):
    _raises_naming(load_map, _write(tmp_path / "a.yaml", "fixtures: []\n"), "fixtures")
    _raises_naming(load_map, _write(tmp_path / "b.yaml", "units: m\n"), "fixtures")
    _raises_naming(load_map, tmp_path / "none.yaml", "not found")
    _raises_naming(load_map, _write(tmp_path / "c.yaml", "fixtures: [\n"), "malformed")


def test_units_cm_accepted(tmp_path: Path):
    fm = load_map(_map(tmp_path, "  - {id: 3, position: [79.35, -270, 59.35], diameter: 15}\n",
                       "units: cm\nfixtures:\n"))  # fmt: skip
    assert fm.units == "cm" and fm.unit_m == 0.01
    np.testing.assert_array_equal(fm.positions, [[79.35, -270, 59.35]])  # kept in map units
    assert fm.fixtures[0].diameter == 15


def test_frequency_mode(tmp_path: Path):
    head = "frame: {mode: frequency}\nfixtures:\n"
    body = "  - {position: [0, 0, 0], frequency_hz: 1000}\n"
    body += "  - {id: 40, position: [1, 0, 0], frequency_hz: 1500}\n"
    fm = load_map(_map(tmp_path, body, head))
    assert fm.mode == "frequency" and fm.ids == [0, 40]  # no 4-bit limit; id defaults to index
    assert [f.frequency_hz for f in fm.fixtures] == [1000.0, 1500.0]
    _raises_naming(load_map, _map(tmp_path, "  - {id: 1, position: [0, 0, 0]}\n", head),
                   "frequency_hz")  # fmt: skip


def test_json_map_equals_yaml_map(tmp_path: Path, thesis_room_path: Path):
    path = tmp_path / "room.json"
    path.write_text(
        json.dumps(
            {
                "units": "m",
                "frame": {"line_code": "manchester", "preamble": "111", "id_bits": 4,
                          "postamble": "00"},
                "fixtures": [
                    {"id": 5, "position": [0.7935, -2.7, 0.5935], "diameter": 0.15,
                     "normal": [0, 1, 0]},
                    {"id": 6, "position": [0.7935, -2.7, -0.5935], "diameter": 0.15,
                     "normal": [0, 1, 0]},
                    {"id": 9, "position": [-0.7935, -2.7, -0.5935], "diameter": 0.15,
                     "normal": [0, 1, 0]},
                    {"id": 10, "position": [-0.7935, -2.7, 0.5935], "diameter": 0.15,
                     "normal": [0, 1, 0]},
                ],
            }
        )
    )  # fmt: skip
    a, b = load_map(path), load_map(thesis_room_path)
    assert a.ids == b.ids and a.frame == b.frame and a.units == b.units
    np.testing.assert_array_equal(a.positions, b.positions)


@pytest.mark.parametrize("name", ["out.yaml", "out.json"])
def test_save_map_round_trips(tmp_path: Path, name: str):
    fm = FixtureMap(
        (
            Fixture(3, [1.5, 2.0, -0.25], diameter=12.0, normal=[0, 0, -1]),
            Fixture(60, [0.0, 1.0, 2.0]),
        ),
        units="cm",
        frame=FrameFormat("111", 6, "000"),
    )
    save_map(fm, tmp_path / name)
    back = load_map(tmp_path / name)
    assert back.ids == [3, 60] and back.units == "cm" and back.frame == fm.frame
    np.testing.assert_array_equal(back.positions, fm.positions)
    assert back.fixtures[0].diameter == 12.0 and back.fixtures[1].diameter is None
    np.testing.assert_array_equal(back.fixtures[0].normal, [0, 0, -1])


# --- images ---------------------------------------------------------------------------------


def _photo() -> np.ndarray:
    """Gray stripes, 8 rows each, on a horizontal ramp, with a little noise; (48, 64, 3)."""
    rng = np.random.default_rng(21)
    rows = np.where((np.arange(48) // 8) % 2 == 0, 200, 40)
    img = rows[:, None] + np.linspace(0, 40, 64)[None, :] + rng.integers(0, 3, (48, 64))
    return np.repeat(img[:, :, None], 3, axis=2).astype(np.uint8)


def test_png_loads_exactly(tmp_path: Path):
    img = _photo()
    cv2.imwrite(str(tmp_path / "p.png"), img)
    np.testing.assert_array_equal(load_image(tmp_path / "p.png"), img)
    gray16 = (np.arange(48 * 64, dtype=np.uint16).reshape(48, 64) * 20).astype(np.uint16)
    cv2.imwrite(str(tmp_path / "g.png"), gray16)
    out = load_image(tmp_path / "g.png")
    assert out.dtype == np.uint16 and out.shape == (48, 64)
    np.testing.assert_array_equal(out, gray16)
    bgra = np.dstack([img, np.full((48, 64), 255, np.uint8)])
    cv2.imwrite(str(tmp_path / "a.png"), bgra)
    np.testing.assert_array_equal(load_image(tmp_path / "a.png"), img)


def test_jpeg_loads_and_truncated_jpeg_is_refused(tmp_path: Path):
    ok, buf = cv2.imencode(".jpg", _photo(), [cv2.IMWRITE_JPEG_QUALITY, 95])
    assert ok
    data = buf.tobytes()
    (tmp_path / "whole.jpg").write_bytes(data)
    img = load_image(tmp_path / "whole.jpg")
    assert img.shape == (48, 64, 3)
    assert np.abs(img.astype(int) - _photo()).mean() < 5
    # phones may append data after the image (motion-photo video, vendor trailers)
    rng = np.random.default_rng(22)
    trailer = b"MotionPhoto" + rng.integers(0, 256, 4000, dtype=np.uint8).tobytes()
    (tmp_path / "trailer.jpg").write_bytes(data + trailer)
    np.testing.assert_array_equal(load_image(tmp_path / "trailer.jpg"), img)
    for frac in (0.3, 0.6, 0.95):
        cut = tmp_path / f"cut{frac}.jpg"
        cut.write_bytes(data[: int(len(data) * frac)])
        _raises_naming(load_image, cut, "truncated")


def test_bad_photo_files(tmp_path: Path):
    _raises_naming(load_image, tmp_path / "missing.jpg", "not found")
    _raises_naming(load_image, tmp_path, "directory")
    text = _write(tmp_path / "notes.jpg", "not a photo at all\n")
    _raises_naming(load_image, text, "not an image")
    (tmp_path / "empty.png").write_bytes(b"")
    _raises_naming(load_image, tmp_path / "empty.png", "empty")
