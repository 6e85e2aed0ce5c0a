"""Tests for camvlp.format: one rule for showing lengths."""

from __future__ import annotations

import math

import pytest

from camvlp.format import format_length, length_unit, mm_per_unit


@pytest.mark.parametrize(
    ("value_m", "text"),
    [
        (1.2345, "1.234 m"),
        (0.5, "0.500 m"),
        (0.4999, "49.99 cm"),
        (0.01, "1.00 cm"),
        (0.00999, "9.99 mm"),
        (0.0, "0.00 mm"),
        (-0.02, "-2.00 cm"),
        (None, "n/a"),
        (math.nan, "n/a"),
    ],
)
def test_the_unit_follows_the_size(value_m, text):
    assert format_length(value_m) == text


def test_a_unit_can_be_forced_and_maps_show_millimetres():
    assert format_length(0.75, "mm") == "750.00 mm"
    assert length_unit(0.3) == (100.0, "cm")
    assert mm_per_unit("m") == (1000.0, "mm") and mm_per_unit("cm") == (10.0, "mm")
    assert mm_per_unit("mm") == (1.0, "mm") and mm_per_unit("ft") == (1.0, "ft")
