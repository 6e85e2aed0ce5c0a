"""The readout value type: parsed once, read through its properties."""

import json

import numpy as np
import pytest

from camvlp.model.camera import Camera
from camvlp.model.readout import READOUT_NAMES, Readout


@pytest.mark.parametrize(
    ("name", "axis", "reversed_", "pixel_index", "array_axis"),
    [
        ("rows", "rows", False, 1, 0),
        ("columns", "columns", False, 0, 1),
        ("rows-reversed", "rows", True, 1, 0),
        ("columns-reversed", "columns", True, 0, 1),
    ],
)
def test_properties(name, axis, reversed_, pixel_index, array_axis):
    r = Readout.parse(name)
    assert r == name and str(r) == name and json.dumps(r) == f'"{name}"'
    assert (r.axis, r.reversed, r.pixel_index, r.array_axis) == (
        axis,
        reversed_,
        pixel_index,
        array_axis,
    )
    assert Readout.of(axis, reversed_) is r


def test_names_and_errors():
    assert READOUT_NAMES == ("rows", "columns", "rows-reversed", "columns-reversed")
    assert Readout.parse_optional(None) is None
    with pytest.raises(ValueError, match=r"^--readout must be rows, columns, .* got .diagonal.$"):
        Readout.parse("diagonal", "--readout")


def test_camera_parses_its_readout():
    k = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    cam = Camera(640, 480, k, readout="columns-reversed")
    assert cam.readout is Readout.COLUMNS_REVERSED and cam.readout.axis == "columns"
    with pytest.raises(ValueError, match="readout must be"):
        Camera(640, 480, k, readout="sideways")
