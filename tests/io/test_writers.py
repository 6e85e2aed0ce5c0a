"""Tests for camvlp.io.writers: result tables and summaries."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from camvlp.io import InputError
from camvlp.io.writers import jsonable, write_csv, write_json


def test_csv_and_json_write_numbers_and_blanks(tmp_path):
    p = write_csv(tmp_path / "t.csv", ("a", "b", "c"), [[1, 0.1 + 0.2, math.nan]])
    assert p.read_text().splitlines() == ["a,b,c", "1,0.3,"]
    data = {"x": np.array([1.5, np.nan]), "n": np.int64(3), "t": (np.float32(0.25),)}
    assert jsonable(data) == {"x": [1.5, None], "n": 3, "t": [0.25]}
    j = write_json(tmp_path / "s.json", data)
    assert json.loads(j.read_text()) == {"x": [1.5, None], "n": 3, "t": [0.25]}


def test_an_unwritable_path_is_one_input_error(tmp_path):
    with pytest.raises(InputError, match=r"cannot write the results: .*missing"):
        write_csv(tmp_path / "missing" / "t.csv", ("a",), [[1]])
    with pytest.raises(InputError, match="cannot write the results"):
        write_json(tmp_path / "missing" / "s.json", {})
