"""camvlp.io's loaders for already-parsed input: the same objects and errors as from files."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from camvlp.errors import InputError
from camvlp.io import (
    camera_from_dict,
    decode_image,
    load_camera,
    load_image,
    load_map,
    map_from_dict,
)


def test_example_files_and_their_parsed_mappings_give_the_same_objects(
    thesis_camera_path: Path, thesis_room_path: Path
):
    room = map_from_dict(yaml.safe_load(thesis_room_path.read_text()))
    from_file = load_map(thesis_room_path)
    assert [f.id for f in room.fixtures] == [f.id for f in from_file.fixtures]
    for a, b in zip(room.fixtures, from_file.fixtures, strict=True):
        np.testing.assert_array_equal(a.position, b.position)
        np.testing.assert_array_equal(a.normal, b.normal)
        assert a.diameter == b.diameter
    assert room.frame == from_file.frame and room.units == from_file.units
    cam_data = {
        "image_width": 5184,
        "image_height": 3880,
        "camera_matrix": {"rows": 3, "cols": 3, "data": [3912, 0, 2592, 0, 3912, 1940, 0, 0, 1]},
        "row_time_s": 2e-5,
    }
    cam, ref = camera_from_dict(cam_data), load_camera(thesis_camera_path)
    np.testing.assert_array_equal(cam.matrix, ref.matrix)
    assert cam.size == ref.size and cam.row_time_s == ref.row_time_s


@pytest.mark.parametrize(
    ("bad", "what"),
    [
        ({"fixtures": [{"id": 1, "position": [0, 0]}]}, "fixture 1: position must be three"),
        ({"fixtures": "none"}, "map needs a non-empty list 'fixtures'"),
        ([1, 2], "malformed map: expected a mapping of keys"),
    ],
)
def test_a_bad_map_mapping_fails_as_its_file_does(tmp_path: Path, bad, what):
    with pytest.raises(InputError) as parsed:
        map_from_dict(bad, "site 3 map")
    assert str(parsed.value) == f"{parsed.value.what} (site 3 map)"
    assert parsed.value.what.startswith(what)
    if isinstance(bad, dict):  # a file must hold a mapping: that one is the parser's message
        path = tmp_path / "map.json"
        path.write_text(json.dumps(bad))
        with pytest.raises(InputError) as from_file:
            load_map(path)
        assert from_file.value.what == parsed.value.what


def test_decode_image_is_load_image_on_bytes(tmp_path: Path):
    image = np.random.default_rng(2).integers(0, 255, (30, 40, 3), dtype=np.uint8)
    path = tmp_path / "p.png"
    cv2.imwrite(str(path), image)
    np.testing.assert_array_equal(decode_image(path.read_bytes()), load_image(path))
    for raw, what in ((b"", "photo is empty"), (b"nope", "not an image, or a corrupt one")):
        with pytest.raises(InputError) as info:
            decode_image(raw, "upload")
        assert str(info.value).startswith(what) and str(info.value).endswith(" (upload)")
