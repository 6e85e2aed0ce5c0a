"""Tests for ``camvlp assign-ids``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from camvlp.cli import app
from camvlp.io import load_map
from conftest import one_error_line

runner = CliRunner()

CAMERA = {"image_width": 1600, "image_height": 1200, "focal_length_px": 1000, "row_time_s": 1e-5}


def _layout(tmp_path: Path, **change) -> Path:
    """A 9 x 7 grid of lights 1.2 m apart, 3 m up, without IDs."""
    x, y = np.meshgrid(np.arange(9) * 1.2, np.arange(7) * 1.2)
    fixtures = [
        {"position": [float(a), float(b), 3.0], "diameter": 0.15, "normal": [0, 0, -1]}
        for a, b in zip(x.ravel(), y.ravel(), strict=True)
    ]
    data = {"units": "m", "frame": {"id_bits": 4, "chip_rate_hz": 40000.0}, "up": [0, 0, 1]}
    data["fixtures"] = fixtures
    data.update(change)
    path = tmp_path / "layout.yaml"
    path.write_text(yaml.safe_dump(data))
    (tmp_path / "camera.json").write_text(json.dumps(CAMERA))
    return path


def _run(tmp_path: Path, layout: Path, *extra: str):
    return runner.invoke(
        app,
        ["assign-ids", str(layout), "--camera", str(tmp_path / "camera.json"), "--out",
         str(tmp_path / "site.yaml"), "--poses", "1500", "--check-poses", "300", *extra],
    )  # fmt: skip


def test_the_site_gets_reused_ids_that_tell_its_views_apart(tmp_path: Path):
    layout = _layout(tmp_path)
    plot = tmp_path / "ids.png"
    result = _run(tmp_path, layout, "--json", "--plot", str(plot))
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    site = load_map(tmp_path / "site.yaml")
    assert site.reuse and len(site.fixtures) == 63
    ids = np.array(site.ids)
    assert ids.min() >= 0 and ids.max() < 16 and np.unique(ids).size == 16
    three = summary["views_3_or_more"]
    assert three["views"] >= 100
    assert 1.0 - three["assigned"] <= (1.0 - three["random"]) / 2, three
    assert summary["reversed_neighbours"]["assigned"] < summary["reversed_neighbours"]["random"]
    assert plot.stat().st_size > 10_000


def test_text_output_names_the_shares(tmp_path: Path):
    result = _run(tmp_path, _layout(tmp_path), "--seed", "2")
    assert result.exit_code == 0, result.output
    assert "views of 3+ lights" in result.stdout and "random" in result.stdout


@pytest.mark.parametrize(
    ("change", "words"),
    [
        ({"frame": {"mode": "frequency"}}, "Manchester"),
        ({"fixtures": [{"position": [0, 0, 3], "normal": [0, 0, -1]}] * 0}, "fixtures"),
    ],
)
def test_a_bad_layout_is_one_line(tmp_path: Path, change, words):
    result = _run(tmp_path, _layout(tmp_path, **change))
    assert result.exit_code == 2
    assert words in one_error_line(result)


def test_fixtures_without_a_diameter_are_refused(tmp_path: Path):
    layout = _layout(tmp_path)
    data = yaml.safe_load(layout.read_text())
    del data["fixtures"][3]["diameter"]
    layout.write_text(yaml.safe_dump(data))
    result = _run(tmp_path, layout)
    assert result.exit_code == 2
    assert "diameter" in one_error_line(result)


@pytest.mark.parametrize(("option", "value"), [("--heights", "2,1"), ("--tilt", "95")])
def test_bad_options_are_one_line(tmp_path: Path, option: str, value: str):
    result = _run(tmp_path, _layout(tmp_path), option, value)
    assert result.exit_code == 2
    assert option in one_error_line(result)


def test_a_map_with_check_bits_is_read_and_written(tmp_path: Path):
    layout = _layout(tmp_path, frame={"id_bits": 4, "check_bits": 4, "chip_rate_hz": 40000.0})
    result = _run(tmp_path, layout, "--poses", "300", "--check-poses", "50")
    assert result.exit_code == 0, result.output
    site = load_map(tmp_path / "site.yaml")
    assert site.frame.check_bits == 4 and site.frame.n_chips == 2 * (3 + 4 + 4 + 2)
