"""``camvlp study coverage --gravity``: its options, its summary and its figure."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from camvlp.cli import app
from conftest import one_error_line

runner = CliRunner()


def test_cli_coverage_gravity(tmp_path):
    result = runner.invoke(
        app,
        [
            "study",
            "coverage",
            "--gravity",
            "--min-fixtures",
            "3",
            "--step",
            "1",
            "--tilt-max",
            "10",
            "--tilt-step",
            "10",
            "--out",
            str(tmp_path),
            "--json",
        ],
    )
    assert result.exit_code == 0, result.output
    s = json.loads(result.stdout)
    assert s["gravity"] and s["min_fixtures"] == 3
    assert s["mean_fix_fraction"] >= s["mean_fix_fraction_four_no_gravity"]
    assert (tmp_path / "coverage.png").exists()


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--min-fixtures", "2"], "--gravity"),
        (["--gravity", "--min-fixtures", "5"], "--min-fixtures"),
        (["--gravity", "--gravity-sigma-deg", "0"], "--gravity-sigma-deg"),
    ],
)
def test_cli_coverage_bad_gravity_options(args, needle):
    result = runner.invoke(app, ["study", "coverage", *args])
    assert result.exit_code == 2
    assert needle in one_error_line(result)
