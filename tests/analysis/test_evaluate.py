"""Tests of survey rendering and ``camvlp evaluate``: results, summary, plots, failures, errors."""

from __future__ import annotations

import csv
import dataclasses
import importlib.util
import json
import math

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from camvlp.analysis.evaluate import (
    Evaluation,
    PhotoResult,
    Survey,
    evaluate_survey,
    floor_axes,
    read_survey,
)
from camvlp.cli import app
from camvlp.io import load_camera, load_map, save_camera, save_map
from camvlp.model.camera import Camera
from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.sim.render import RenderSettings
from camvlp.sim.survey import render_survey
from conftest import one_error_line

runner = CliRunner()

# Six floor positions, camera looking up; photo 2 becomes a non-image, photo 4 a black image.
POSITIONS = np.array(
    [
        [0.0, 0.0, 0.0],
        [0.2, 0.0, 0.1],
        [-0.2, 0.0, 0.1],
        [0.1, 0.0, -0.2],
        [-0.1, 0.0, -0.1],
        [0.2, 0.0, -0.2],
    ]
)
NOT_AN_IMAGE, BLACK = 2, 4


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """A small camera and a room of big fixtures (0.4 m discs at 2.7 m, 4 rows per chip)."""
    d = tmp_path_factory.mktemp("scene")
    camera = Camera.from_focal(1280, 960, 1000.0, row_time_s=25e-6)  # 10 kHz: 4 rows/chip
    room = FixtureMap(
        tuple(
            Fixture(i, np.array([x, -2.7, z]), 0.4, np.array([0.0, 1.0, 0.0]))
            for i, x, z in ((5, 0.8, 0.6), (6, 0.8, -0.6), (9, -0.8, -0.6), (10, -0.8, 0.6))
        )
    )
    save_camera(camera, d / "cam.yaml")
    save_map(room, d / "room.yaml")
    return d, load_camera(d / "cam.yaml"), load_map(d / "room.yaml")


@pytest.fixture(scope="module")
def survey_dir(scene):
    """Six rendered photos (tilted by up to 2 degrees), two of them spoiled."""
    d, camera, room = scene
    rng = np.random.default_rng(7)
    euler = np.array([90.0, 0.0, 0.0]) + rng.uniform(-2, 2, size=(len(POSITIONS), 3))
    out = d / "survey"
    csv_path = render_survey(camera, room, POSITIONS, euler, out, RenderSettings(seed=11), jobs=2)
    (out / f"photo_{NOT_AN_IMAGE:03d}.jpg").write_text("this is not a photograph\n")
    cv2.imwrite(str(out / f"photo_{BLACK:03d}.jpg"), np.zeros((960, 1280, 3), np.uint8))
    return csv_path, euler


def evaluate_cli(scene, survey_csv, out, *extra):
    d = scene[0]
    args = [
        "evaluate",
        str(survey_csv),
        "--camera",
        str(d / "cam.yaml"),
        "--map",
        str(d / "room.yaml"),
        "--out",
        str(out),
        *extra,
    ]
    return runner.invoke(app, args)


# --------------------------------------------------------------------------------------------
# Rendering a survey


def test_render_survey_writes_photos_and_csv(scene, survey_dir):
    csv_path, euler = survey_dir
    with open(csv_path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["photo", "x", "y", "z", "theta_x", "theta_y", "theta_z", "seed"]
    assert len(rows) == len(POSITIONS)
    for i, row in enumerate(rows):
        assert row["photo"] == f"photo_{i:03d}.jpg"
        assert [float(row[c]) for c in "xyz"] == pytest.approx(POSITIONS[i], abs=1e-6)
        angles = [float(row[c]) for c in ("theta_x", "theta_y", "theta_z")]
        assert angles == pytest.approx(euler[i], abs=1e-4)
        assert int(row["seed"]) == 11 + i
        if i not in (NOT_AN_IMAGE, BLACK):
            assert cv2.imread(str(csv_path.parent / row["photo"])).shape == (960, 1280, 3)
            truth = json.loads((csv_path.parent / f"photo_{i:03d}.json").read_text())
            assert truth["camera_position"] == pytest.approx(POSITIONS[i])
            assert truth["euler_deg"] == pytest.approx(euler[i])


def test_render_survey_rejects_bad_shapes(scene, tmp_path):
    _, camera, room = scene
    with pytest.raises(ValueError, match="positions"):
        render_survey(camera, room, np.zeros((2, 2)), (90, 0, 0), tmp_path)
    with pytest.raises(ValueError, match="euler_deg"):
        render_survey(camera, room, np.zeros((2, 3)), np.zeros((3, 3)), tmp_path)


# --------------------------------------------------------------------------------------------
# camvlp evaluate, end to end


def test_evaluate_counts_failures_and_writes_everything(scene, survey_dir, tmp_path):
    csv_path, _ = survey_dir
    out = tmp_path / "out"
    result = evaluate_cli(scene, csv_path, out, "--jobs", "2")
    assert result.exit_code == 0, result.output
    assert "4 located, 2 failed" in result.stdout

    summary = json.loads((out / "summary.json").read_text())
    for key in (
        "photos",
        "located",
        "mean_error",
        "median_error",
        "p95_error",
        "max_error",
        "success_rate",
        "units",
        "failures",
        "abs_error_per_axis",
    ):
        assert key in summary
    assert summary["photos"] == 6 and summary["located"] == 4
    assert summary["success_rate"] == pytest.approx(4 / 6, abs=1e-5)
    assert summary["units"] == "m"
    failures = {f["photo"]: f["reason"] for f in summary["failures"]}
    assert set(failures) == {f"photo_{NOT_AN_IMAGE:03d}.jpg", f"photo_{BLACK:03d}.jpg"}
    assert failures[f"photo_{NOT_AN_IMAGE:03d}.jpg"].startswith("unreadable")
    assert failures[f"photo_{BLACK:03d}.jpg"].startswith("not located")
    assert summary["max_error"] < 0.005  # 5 mm on these clean renders
    assert summary["angle_error_deg"]["max"] < 0.2

    with open(out / "results.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["photo"] for r in rows] == [f"photo_{i:03d}.jpg" for i in range(6)]
    located = [r for r in rows if r["located"] == "1"]
    assert len(located) == 4
    # the summary's statistics, recomputed from the table's estimates and true positions
    est = np.array([[float(r[f"est_{c}"]) for c in "xyz"] for r in located])
    true = np.array([[float(r[f"true_{c}"]) for c in "xyz"] for r in located])
    assert true == pytest.approx(np.delete(POSITIONS, [NOT_AN_IMAGE, BLACK], axis=0))
    err = np.linalg.norm(est - true, axis=1)
    assert [float(r["error"]) for r in located] == pytest.approx(err, rel=1e-5, abs=1e-8)
    assert summary["mean_error"] == pytest.approx(err.mean(), rel=1e-4)
    assert summary["median_error"] == pytest.approx(np.median(err), rel=1e-4)
    assert summary["max_error"] == pytest.approx(err.max(), rel=1e-4)
    for r in rows:
        if r["located"] == "0":
            assert r["reason"] and r["est_x"] == "" and r["error"] == ""
            assert r["sigma_x"] == ""
    # each located photo's own sigma, and how often its errors lie within it
    sigma = np.array([[float(r[f"sigma_{c}"]) for c in "xyz"] for r in located])
    assert np.all(sigma > 0)
    z = np.abs(est - true) / sigma
    assert summary["within_sigma"]["count"] == 12
    for k in (1, 2, 3):
        assert summary["within_sigma"][str(k)] == pytest.approx(np.mean(z <= k), abs=1e-6)
    for name in ("error_map.png", "positions.png"):
        image = cv2.imread(str(out / name))
        assert image is not None and image.shape[0] > 300 and image.shape[1] > 400


def test_json_output_and_one_job_agree_with_parallel(scene, survey_dir, tmp_path):
    csv_path, _ = survey_dir
    result = evaluate_cli(scene, csv_path, tmp_path / "one", "--jobs", "1", "--json")
    assert result.exit_code == 0, result.output
    printed = json.loads(result.stdout)
    assert printed == json.loads((tmp_path / "one" / "summary.json").read_text())
    assert printed["jobs"] == 1
    _, camera, room = scene
    parallel = evaluate_survey(read_survey(csv_path), camera, room, jobs=2)
    assert parallel.jobs == 2
    assert parallel.summary()["mean_error"] == pytest.approx(printed["mean_error"], rel=1e-9)
    assert [r.located for r in parallel.results] == [True, True, False, True, False, True]


def test_max_sigma_refuses_the_photos_less_sure(scene, survey_dir, tmp_path):
    """``--max-sigma`` reaches every photo's locate: below every sigma, none is located and
    each failure gives the reason."""
    result = evaluate_cli(scene, survey_dir[0], tmp_path / "out", "--max-sigma", "1e-12")
    assert result.exit_code == 0, result.output
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["located"] == 0 and summary["failed"] == 6
    reasons = [f["reason"] for f in summary["failures"]]
    assert sum("too unsure" in r for r in reasons) == 4  # the four located without it


# --------------------------------------------------------------------------------------------
# Bad input: exit 2, one line


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (None, "not found"),
        ("", "empty"),
        ("photo,x,y,z\n", "no photos"),
        ("photo,x,y\na.jpg,0,0\n", "lacks the column z"),
        ("photo,x,y,z\na.jpg,zero,0,0\n", "line 2: x must be a finite number"),
        ("photo,x,y,z\na.jpg,0,0\n", "line 2 has 3 values"),
    ],
)
def test_bad_survey_exits_2(scene, tmp_path, content, message):
    path = tmp_path / "survey.csv"
    if content is not None:
        path.write_text(content)
    result = evaluate_cli(scene, path, tmp_path / "out")
    assert result.exit_code == 2
    line = one_error_line(result)
    assert message in line and "survey.csv" in line


@pytest.mark.parametrize("which", ["--camera", "--map"])
def test_bad_camera_or_map_exits_2(scene, survey_dir, tmp_path, which):
    d = scene[0]
    bad = tmp_path / "bad.yaml"
    bad.write_text("just: [unclosed\n")
    files = {"--camera": d / "cam.yaml", "--map": d / "room.yaml"} | {which: bad}
    result = runner.invoke(
        app,
        [
            "evaluate",
            str(survey_dir[0]),
            "--camera",
            str(files["--camera"]),
            "--map",
            str(files["--map"]),
            "--out",
            str(tmp_path / "out"),
        ],
    )
    assert result.exit_code == 2
    assert "bad.yaml" in one_error_line(result)


@pytest.mark.parametrize("option", ["--jobs", "--outlier-px", "--magnify", "--max-sigma"])
def test_bad_option_value_exits_2(scene, survey_dir, tmp_path, option):
    result = evaluate_cli(scene, survey_dir[0], tmp_path / "out", option, "0")
    assert result.exit_code == 2
    assert option in one_error_line(result)
    assert not (tmp_path / "out").exists()


def test_out_that_is_a_file_exits_2(scene, survey_dir, tmp_path):
    (tmp_path / "out").write_text("")
    result = evaluate_cli(scene, survey_dir[0], tmp_path / "out")
    assert result.exit_code == 2
    assert "--out" in one_error_line(result)


# --------------------------------------------------------------------------------------------
# The pieces


def test_floor_axes_picks_the_two_widest():
    p = np.array([[0, 0, 5], [1, 0.1, 5], [0, 2, 5.01]])
    assert floor_axes(p) == (0, 1, 2)
    p = np.array([[0, 0, 0], [1, 0, 1], [2, 0, -1]])
    assert floor_axes(p) == (0, 2, 1)


def test_summary_statistics_of_known_errors(tmp_path):
    true = np.zeros((4, 3))
    est = [np.array([3.0, 0, 0]), np.array([0, -4.0, 0]), np.array([0, 0, 5.0]), None]
    results = tuple(
        PhotoResult(
            photo=f"p{i}",
            true_position=true[i],
            position=e,
            euler_deg=None if e is None else np.array([90.0, 0, 3.0 * i]),
            true_euler_deg=np.array([90.0, 0, 0]),
            reason="" if e is not None else "not located: none",
        )
        for i, e in enumerate(est)
    )
    survey = Survey(
        tmp_path / "s.csv",
        tuple(r.photo for r in results),
        true,
        np.tile([90.0, 0, 0], (4, 1)),
        (),
        ((),) * 4,
    )
    assert [bool(r) for r in results] == [r.located for r in results] == [True] * 3 + [False]
    s = Evaluation(results, "m", survey, 1, 0.0).summary()
    assert (s["photos"], s["located"], s["failed"], s["success_rate"]) == (4, 3, 1, 0.75)
    # errors 3, 4, 5: linear-interpolated 95th percentile 4 + 0.9 * (5 - 4)
    assert (s["mean_error"], s["median_error"], s["max_error"]) == (4.0, 4.0, 5.0)
    assert s["p95_error"] == pytest.approx(4.9)
    assert s["rms_error"] == pytest.approx(math.sqrt(50 / 3), rel=1e-5)
    assert s["abs_error_per_axis"]["y"]["max"] == 4.0
    assert s["bias_per_axis"]["y"] == pytest.approx(-4 / 3, rel=1e-5)
    # orientation errors 0, 3 and 6 degrees about the optical axis
    assert s["angle_error_deg"]["max"] == pytest.approx(6.0, abs=1e-6)
    assert s["angle_error_deg"]["mean"] == pytest.approx(3.0, abs=1e-6)
    assert s["failures"] == [{"photo": "p3", "reason": "not located: none"}]
    # no photo says its sigma: nothing to count
    assert s["within_sigma"] == {"1": None, "2": None, "3": None, "count": 0}
    # with sigmas: errors 3, 4, 5 along one axis each (1.5, 2 and 2.5 sigmas), 0 along
    # the others, sigma 2 everywhere
    with_sigma = tuple(dataclasses.replace(r, position_sigma=np.full(3, 2.0)) for r in results)
    w = Evaluation(with_sigma, "m", survey, 1, 0.0).summary()["within_sigma"]
    assert w == {"1": pytest.approx(6 / 9), "2": pytest.approx(8 / 9), "3": 1.0, "count": 9}


def test_make_survey_script(scene, examples_dir, tmp_path):
    d = scene[0]
    spec = importlib.util.spec_from_file_location("make_survey", examples_dir / "make_survey.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    code = module.main(
        [
            "--camera",
            str(d / "cam.yaml"),
            "--map",
            str(d / "room.yaml"),
            "--grid=-0.1:0.1:0.1,0:0.1:0.1",
            "--jitter-deg",
            "1",
            "--jobs",
            "1",
            "--seed",
            "3",
            "--out",
            str(tmp_path / "s"),
        ]
    )
    assert code == 0
    survey = read_survey(tmp_path / "s" / "survey.csv")
    assert len(survey) == 6
    assert np.all(np.abs(survey.euler_deg - [90, 0, 0]) <= 1.0)
    assert len(np.unique(survey.euler_deg[:, 0])) == 6  # jittered, not constant
    assert all(survey.photo_path(i).exists() for i in range(6))
