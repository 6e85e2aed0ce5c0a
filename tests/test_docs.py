"""The documentation's example of ``camvlp locate --json`` (docs/locating.md) has the keys the
command prints, and its fixture record's ``margin`` is on the scale its ``hamming`` says (run
margin, 0 to 1)."""

from __future__ import annotations

import re
from pathlib import Path

from camvlp.pipeline.locate import locate

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
    assert fixture["hamming"] == 0 and 0 <= fixture["margin"] <= 1  # the run-length decoder
    example = re.search(r'"margin": ([-\d.]+), "reason": "",\s+"hamming": (-?\d+)', _json_example())
    assert example, "the example's first fixture shows margin, reason and hamming"
    margin, hamming = float(example.group(1)), int(example.group(2))
    assert (hamming == 0 and 0 <= margin <= 1) or (hamming == -1 and 4 <= margin <= 99)
