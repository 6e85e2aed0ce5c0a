"""Tests for ``camvlp study``: the thesis' chapter 4 findings.

Bounds come from the thesis text (figures 3.8, 3.10, 4.2 to 4.5) or from first-order
reasoning, not from this code's output.
"""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from camvlp.cli import app
from conftest import one_error_line

runner = CliRunner()


# --------------------------------------------------------------------------------- CLI


def test_cli_rounding_json_and_outputs(tmp_path, thesis_camera_path, thesis_room_path):
    out = tmp_path / "r"
    result = runner.invoke(
        app,
        [
            "study",
            "rounding",
            "--camera",
            str(thesis_camera_path),
            "--map",
            str(thesis_room_path),
            "--step",
            "0.5",
            "--euler",
            "70,20,0",
            "--out",
            str(out),
            "--json",
        ],
    )
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert summary["poses"] == 25 and summary["euler_deg"] == [70, 20, 0]
    assert 0 < summary["mean_error_m"] <= summary["max_error_m"] < 0.01
    assert json.loads((out / "summary.json").read_text()) == summary
    rows = (out / "rounding.csv").read_text().splitlines()
    assert rows[0].startswith("x_m,y_m,z_m,error_m") and len(rows) == 26
    assert (out / "rounding.png").read_bytes()[:4] == b"\x89PNG"


def test_cli_forced_and_monte_carlo(tmp_path):
    result = runner.invoke(
        app,
        [
            "study",
            "world-error",
            "--figure",
            "4.5",
            "--axis",
            "z",
            "--range",
            "-1,1",
            "--step",
            "0.5",
            "--json",
            "--out",
            str(tmp_path / "w"),
        ],
    )
    assert result.exit_code == 0, result.output
    s = json.loads(result.stdout)
    assert len(s["series"]) == 4
    assert all(ser["position_m"] == [0, -1, 0] for ser in s["series"])  # 1 m up, y down
    assert (tmp_path / "w" / "world-error.csv").exists()
    result = runner.invoke(
        app,
        [
            "study",
            "image-error",
            "--positions",
            "0,0,0",
            "--noise-px",
            "0.5",
            "--trials",
            "20",
            "--json",
        ],
    )
    assert result.exit_code == 0, result.output
    s = json.loads(result.stdout)
    assert s["study"] == "monte-carlo" and s["trials"] == 20 and s["poses"] == 20


def test_cli_coverage_text(tmp_path):
    result = runner.invoke(
        app,
        [
            "study",
            "coverage",
            "--step",
            "1",
            "--tilt-max",
            "5",
            "--tilt-step",
            "5",
            "--out",
            str(tmp_path),
        ],
    )
    assert result.exit_code == 0, result.output
    assert "fix possible" in result.stdout
    assert (tmp_path / "coverage.png").exists() and (tmp_path / "coverage.csv").exists()


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["rounding", "--solver", "dls"], "--solver"),
        (["rounding", "--euler", "90,0"], "--euler"),
        (["rounding", "--step", "0"], "--step"),
        (["rounding", "--camera", "missing.yaml"], "missing.yaml"),
        (["image-error", "--fixture", "7"], "fixture 7"),
        (["image-error", "--axis", "z"], "--axis"),
        (["world-error", "--positions", "1,2"], "--positions"),
        (["coverage", "--tilt-step", "0"], "--tilt-step"),
        (["coverage", "--noise-px", "-1"], "--noise-px"),
    ],
)
def test_cli_bad_input(args, needle):
    result = runner.invoke(app, ["study", *args])
    assert result.exit_code == 2
    assert needle in one_error_line(result)


@pytest.mark.parametrize("study", ["rounding", "coverage"])
def test_a_tilted_sensor_camera_is_refused_naming_the_file(tmp_path, study):
    """14 distortion coefficients (OpenCV's tilted sensor) load, but the studies cannot project
    them: one line naming the camera file (it named an internal function, and no file)."""
    camera = tmp_path / "tilted.yaml"
    camera.write_text(
        "image_width: 640\nimage_height: 480\nfocal_length_px: 500\n"
        "distortion_coefficients: [0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0.01, 0.01]\n"
    )
    result = runner.invoke(app, ["study", study, "--camera", str(camera), "--step", "0.5"])
    assert result.exit_code == 2
    line = one_error_line(result)
    assert "tilted sensor" in line and str(camera) in line


@pytest.mark.parametrize(
    ("args", "flat"),
    [
        (["rounding"], True),
        (["coverage"], True),
        (["image-error", "--height", "1"], True),
        (["rounding", "--plane", "xy", "--y-range", "-1,1"], False),
    ],
    ids=["rounding", "coverage", "image-error --height", "rounding --plane xy"],
)
def test_fixtures_at_the_floors_level_are_refused_naming_the_map(
    tmp_path, thesis_room_path, args, flat
):
    """Fixtures whose mean vertical is 0 (the floor's level: in the camera's plane, or the map
    has another vertical axis than --plane's) cannot say which way is up: one line naming the
    map file and the option (it named neither)."""
    room = thesis_room_path  # with --plane xy its vertical is z, from -0.59 to 0.59
    if flat:
        room = tmp_path / "flat.yaml"
        room.write_text(thesis_room_path.read_text().replace("-2.7", "0"))
    result = runner.invoke(app, ["study", *args, "--map", str(room), "--step", "0.5"])
    assert result.exit_code == 2
    line = one_error_line(result)
    assert "not above the floor" in line and str(room) in line and "--plane" in line, line


def test_study_cli_accepts_the_locate_solver_and_refuses_others():
    res = runner.invoke(app, ["study", "rounding", "--step", "0.5", "--solver", "locate", "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["solver"] == "locate"
    bad = runner.invoke(app, ["study", "rounding", "--solver", "dlt"])
    assert bad.exit_code == 2
    assert "locate" in one_error_line(bad)


def test_a_range_across_the_floor_is_refused_naming_height(thesis_room_path):
    """--z-range with --plane xy is not an axis of the floor: one line, not a silent study of
    another place (it was ignored)."""
    result = runner.invoke(
        app,
        ["study", "coverage", "--map", str(thesis_room_path), "--plane", "xy", "--z-range", "1,2"],
    )
    assert result.exit_code == 2
    line = one_error_line(result)
    assert "--z-range" in line and "--height" in line


def test_a_site_coverage_writes_the_fixtures_in_view_and_the_ambiguous_views(tmp_path):
    """A map whose IDs repeat: the summary says how many poses saw how many fixtures and how
    many were left ambiguous, and the plot has the fixtures in view."""
    from camvlp.io import save_map
    from camvlp.sim.site import site_map

    site = tmp_path / "site.yaml"
    save_map(site_map(12, 12, spacing=1.0, height=3.0, diameter=0.3, pattern="periodic"), site)
    args = ["study", "coverage", "--map", str(site), "--plane", "xy", "--x-range", "2,9"]
    args += ["--y-range", "2,9", "--step", "1", "--height", "0", "--euler", "0,0,0"]
    args += ["--tilt-max", "0", "--chip-rate", "100000", "--out", str(tmp_path / "out")]
    result = runner.invoke(app, [*args, "--json"])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert summary["reuse"] and summary["fixes"] == 0  # periodic: every view repeats
    assert summary["ambiguous_views"] > 0 and summary["poses_seeing_at_least"]["5"] > 0.5
    assert (tmp_path / "out" / "coverage.png").stat().st_size > 10_000
