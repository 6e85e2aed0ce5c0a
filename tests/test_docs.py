"""The documentation's example of ``camvlp locate --json`` (docs/locating.md) has the keys the
command prints, and its fixture record's confidence is where the decoder that read it puts it:
``run_margin`` (0 to 1, ``margin`` null) for the run-length decoder (``hamming`` 0), ``margin``
(a decimal log likelihood ratio, 4 to 99) for the model fit (``hamming`` -1)."""

from __future__ import annotations

import re
from pathlib import Path

from camvlp import locate

PAGE = Path(__file__).resolve().parents[1] / "docs" / "locating.md"


def _json_example() -> str:
    """The first ```json block after the page's "`--json` prints one object"."""
    text = PAGE.read_text()
    start = text.index("```json", text.index("`--json` prints one object"))
    return text[start : text.index("```\n", start + 7)]


def test_the_docs_json_example_has_the_keys_locate_prints(small_render, small_camera, small_room):
    result = locate(small_render.image, small_camera, small_room)
    assert result, result.error
    printed = result.to_dict()
    shown = set(re.findall(r'"(\w+)":', _json_example()))
    assert set(printed) - {"notes"} <= shown, set(printed) - shown
    fixture = printed["fixtures"][0]
    assert fixture["hamming"] == 0 and fixture["margin"] is None  # the run-length decoder
    assert 0.3 <= fixture["run_margin"] <= 1
    example = re.search(
        r'"margin": (null|[-\d.]+), "reason": "",\s+"hamming": (-?\d+), '
        r'"run_margin": (null|[\d.]+)',
        _json_example(),
    )
    assert example, "the example's first fixture shows margin, reason, hamming and run_margin"
    margin, hamming, run = example.groups()
    if hamming == "0":
        assert margin == "null" and 0.3 <= float(run) <= 1
    else:
        assert hamming == "-1" and run == "null" and 4 <= float(margin) <= 99
