"""Tests for ``camvlp encode``."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from camvlp.cli import app, main
from conftest import one_error_line

runner = CliRunner()


def _run(*args: str):
    return runner.invoke(app, ["encode", *args])


def test_prints_bits_and_chips_of_id_5():
    result = _run("5")
    assert result.exit_code == 0, result.output
    # preamble 111, ID 0101, postamble 00; Manchester 0 -> 10, 1 -> 01
    assert "111010100" in result.stdout
    assert "010101100110011010" in result.stdout
    assert "1800.0 us" in result.stdout  # 18 chips at 10 kHz


def test_json_output():
    result = _run("9", "--json", "--chip-rate", "20000")
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    assert {"bits", "chips", "schedule"} <= out.keys()
    assert out["id"] == 9
    assert out["bits"] == "111" + "1001" + "00"
    assert out["chips"] == "010101" + "01101001" + "1010"
    assert out["frame_duration_s"] == pytest.approx(18 / 20000)
    durations = [s["duration_s"] for s in out["schedule"]]
    assert sum(durations) == pytest.approx(18 / 20000)
    states = [s["on"] for s in out["schedule"]]
    assert states[0] is False and all(a != b for a, b in itertools.pairwise(states))


def test_id_that_does_not_fit_is_bad_input():
    result = _run("16")
    assert result.exit_code == 2
    assert "16" in one_error_line(result)
    assert result.stdout == ""


@pytest.mark.parametrize("rate", ["0", "-100"])
def test_non_positive_chip_rate_is_bad_input(rate):
    result = _run("5", "--chip-rate", rate)
    assert result.exit_code == 2
    assert "--chip-rate" in one_error_line(result)


def test_frame_from_a_map(tmp_path: Path):
    path = tmp_path / "room.yaml"
    path.write_text(
        'frame: {preamble: "1111", id_bits: 6, postamble: "00"}\n'
        "fixtures:\n  - {id: 40, position: [0, 0, 0]}\n"
    )
    result = _run("40", "--map", str(path), "--json")
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    assert out["bits"] == "1111" + "101000" + "00"
    assert out["chips"] == "01010101" + "011001101010" + "1010"
    # the map's frame bounds the IDs: 6 bits allow 63, the default 4 would not
    assert _run("63", "--map", str(path)).exit_code == 0
    assert _run("64", "--map", str(path)).exit_code == 2


def test_a_frequency_map_has_no_frame_to_encode(tmp_path: Path):
    """A frequency-coded map is refused, not encoded with the default Manchester frame."""
    path = tmp_path / "lights.yaml"
    path.write_text(
        "frame: {mode: frequency}\n"
        "fixtures:\n  - {id: 1, frequency_hz: 2500, position: [0, 0, 0]}\n"
    )
    result = _run("1", "--map", str(path))
    assert result.exit_code == 2
    line = one_error_line(result)
    assert "frequency-coded" in line and str(path) in line
    assert result.stdout == ""


def test_bad_map_is_one_line_naming_the_file(tmp_path: Path):
    path = tmp_path / "broken.yaml"
    path.write_text("fixtures: [\n")
    result = _run("5", "--map", str(path))
    assert result.exit_code == 2
    assert str(path) in one_error_line(result)
    result = _run("5", "--map", str(tmp_path / "absent.yaml"))
    assert result.exit_code == 2
    assert "absent.yaml" in one_error_line(result)


#: The console script installed beside this Python (the virtual environment's bin/).
CAMVLP = Path(sys.executable).with_name("camvlp")


@pytest.mark.skipif(not CAMVLP.exists(), reason="console script not installed")
def test_console_script():
    done = subprocess.run(
        [str(CAMVLP), "encode", "16"], capture_output=True, text=True, timeout=60, check=False
    )
    assert done.returncode == 2
    assert done.stderr.startswith("error: ") and done.stderr.count("\n") == 1
    done = subprocess.run(
        [str(CAMVLP), "encode", "10", "--json"],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 0
    assert json.loads(done.stdout)["bits"] == "111101000"


@pytest.mark.parametrize(
    "argv",
    [
        ["encode", "-1"],
        ["encode", "-1", "--json"],
        ["encode", "--json", "-3"],
        ["encode", "--chip-rate", "20000", "-7"],
        ["encode", "--", "-1"],
    ],
)
def test_a_negative_id_is_refused_as_an_id(argv, capsys):
    """``camvlp encode -1``: the parser would take -1 for an unknown option; it is the ID, and
    out of range."""
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    line = one_error_line(err)
    assert "fixture ID -" in line and "(0 to 15)" in line, line


def test_an_unknown_option_is_still_named(capsys):
    for argv, named in (
        (["encode", "5", "-x"], "-x"),
        (["encode", "--chip-rate", "-100", "5"], "--chip-rate"),  # an option's value
        (["encode", "-1", "-2"], "extra argument(s) (-2)"),  # two IDs
    ):
        assert main(argv) == 2
        out, err = capsys.readouterr()
        assert named in one_error_line(err) and out == ""
