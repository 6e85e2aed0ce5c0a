"""Tests for camvlp.format: one rule for showing lengths."""

from __future__ import annotations

import math

import numpy as np
import pytest

from camvlp.format import format_length, format_number, format_vector, length_unit, mm_per_unit


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


@pytest.mark.parametrize(
    ("value", "spec", "text"),
    [
        (-0.0001, ".2f", "0.00"),
        (-0.0, "7.1f", "    0.0"),
        (-0.0, "g", "0"),
        (-0.004, "+.2f", "+0.00"),
        (-0.006, ".2f", "-0.01"),  # a figure that is not zero keeps its sign
        (-1e-9, ".5g", "-1e-09"),
        (np.float64(-0.00003), ".4f", "0.0000"),
        (-3, "d", "-3"),
        (math.nan, ".2f", "nan"),
    ],
)
def test_a_figure_that_rounds_to_zero_has_no_minus_sign(value, spec, text):
    assert format_number(value, spec) == text


def test_lengths_show_no_negative_zero():
    assert format_length(-1e-7) == "0.00 mm"
    assert format_length(-0.0, "m") == "0.000 m"


def test_a_vector_is_shown_flat_in_g_format():
    assert format_vector([0.59, -2.88, -9.36]) == "(0.59, -2.88, -9.36)"
    assert format_vector(np.array([[1e-7], [2.0]])) == "(1e-07, 2)"
