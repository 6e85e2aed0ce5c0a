"""Frames with a check of the ID (a CRC) and the formats ``camvlp encode --design`` finds."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from camvlp.analysis.frame_design import design_frames
from camvlp.cli import app
from camvlp.model.linecode import CRC_POLYNOMIALS, FrameFormat, crc_bits
from conftest import one_error_line


def _divides(bits: str, width: int) -> bool:
    """Whether the polynomial of ``width`` divides the message ``bits`` (ID then check)."""
    value, poly = int(bits, 2), CRC_POLYNOMIALS[width]
    for shift in range(len(bits) - width - 1, -1, -1):
        if value >> (shift + width) & 1:
            value ^= poly << shift
    return value == 0


@pytest.mark.parametrize("width", sorted(CRC_POLYNOMIALS))
def test_the_check_makes_the_id_and_check_a_multiple_of_the_polynomial(width: int):
    for value in range(64):
        check = crc_bits(value, 6, width)
        assert len(check) == width
        assert _divides(format(value, "06b") + check, width)
        # any one bit flipped in the ID or the check is no longer a multiple
        message = format(value, "06b") + check
        for k in range(len(message)):
            flipped = message[:k] + ("1" if message[k] == "0" else "0") + message[k + 1 :]
            assert not _divides(flipped, width)


def test_a_frame_with_check_bits_carries_them_between_id_and_postamble():
    frame = FrameFormat("1111", 4, "000", 4)
    assert frame.n_bits == 4 + 4 + 4 + 3 and frame.n_chips == 30
    bits = frame.bits(9)
    assert bits == "1111" + "1001" + crc_bits(9, 4, 4) + "000"
    assert frame.min_distance == 4 > FrameFormat().min_distance
    assert (frame.reversed_ids < 0).all()  # no ID read backwards is another's
    # every ID decodes from any rotation of its chips, and one chip in error is not taken
    # for another ID
    rng = np.random.default_rng(0)
    for i in range(frame.n_ids):
        chips = np.roll(frame.chips(i), int(rng.integers(frame.n_chips)))
        assert frame.decode(chips).id == i
        chips[int(rng.integers(frame.n_chips))] ^= 1
        assert frame.decode(chips).id in (i, None)


def test_check_bits_outside_the_polynomials_are_refused():
    with pytest.raises(ValueError, match="check_bits"):
        FrameFormat(check_bits=9)


def test_the_design_finds_safe_formats_best_first():
    found = design_frames(16, 300.0, 5.0)
    assert found and all(d.reversal_pairs == 0 for d in found)
    assert all(d.frame.n_ids >= 16 and (d.frame.reversed_ids < 0).all() for d in found)
    assert found[0].one_photo and found[0].min_distance == max(d.min_distance for d in found)
    assert found[0].frames_per_disc == pytest.approx(300.0 / (found[0].frame.n_chips * 5.0))
    for a, b in itertools.pairwise(d for d in found if d.one_photo):
        assert (a.min_distance, -a.frame.n_chips) >= (b.min_distance, -b.frame.n_chips)
    short = design_frames(16, 40.0, 5.0)  # no disc of 40 rows holds a safe 16-ID frame
    assert short and not any(d.one_photo for d in short)
    assert [d.frame.n_chips for d in short] == sorted(d.frame.n_chips for d in short)


def test_encode_design_on_the_command_line():
    runner = CliRunner()
    result = runner.invoke(app, ["encode", "--design", "--fixtures", "16", "--rows", "300"])
    assert result.exit_code == 0, result.output
    assert "recommended: preamble" in result.stdout
    result = runner.invoke(
        app, ["encode", "--design", "--fixtures", "16", "--rows", "40", "--json"]
    )
    assert result.exit_code == 0, result.output
    rows = json.loads(result.stdout)
    assert rows and not any(r["one_photo"] for r in rows)
    bad = runner.invoke(app, ["encode", "--design", "--fixtures", "16"])
    assert bad.exit_code == 2 and "--rows" in one_error_line(bad)
    none = runner.invoke(app, ["encode"])
    assert none.exit_code == 2 and "ID" in one_error_line(none)
