"""Tests for camvlp.analysis.study and ``camvlp study``: the thesis' chapter 4 findings.

Bounds come from the thesis text (figures 3.8, 3.10, 4.2 to 4.5) or from first-order
reasoning, not from this code's output.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from camvlp.analysis.study import (
    axis_values,
    coverage_study,
    floor_grid,
    forced_error_study,
    monte_carlo_study,
    rounding_study,
    set_height,
)
from camvlp.cli import app
from camvlp.io import load_camera, load_map
from camvlp.model.fixtures import Fixture, FixtureMap
from conftest import one_error_line

runner = CliRunner()
FIG_4_4_EULERS = [(80, 0, 0), (85, 0, 0), (90, 0, 0), (95, 0, 0)]


@pytest.fixture(scope="module")
def cam(thesis_camera_path):
    return load_camera(thesis_camera_path)


@pytest.fixture(scope="module")
def room(thesis_room_path):
    return load_map(thesis_room_path)


def _scaled_map(fmap: FixtureMap, units: str, factor: float) -> FixtureMap:
    return FixtureMap(
        tuple(Fixture(f.id, f.position * factor, f.diameter * factor, f.normal)
              for f in fmap.fixtures),
        units=units,
    )


def _z_up_map(fmap: FixtureMap) -> FixtureMap:
    """The thesis' room in a z-up frame: (x, y, z) -> (x, z, -y), a proper rotation."""
    m = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])
    return FixtureMap(
        tuple(Fixture(f.id, m @ f.position, f.diameter, m @ f.normal) for f in fmap.fixtures)
    )


# --------------------------------------------------------------------------- rounding


THESIS_FIG_4_2_MM = {(90, 0, 0): 1.1, (90, 20, 0): 1.4, (70, 0, 0): 1.5, (70, 20, 0): 1.6}


@pytest.mark.parametrize(("euler", "thesis_mm"), list(THESIS_FIG_4_2_MM.items()))
def test_rounding_reproduces_thesis_figure_4_2(cam, room, euler, thesis_mm):
    res = rounding_study(cam, room, euler_deg=euler)  # the thesis' floor, 21 x 21
    assert res.errors_m.shape == (21, 21, 1)
    assert res.summary()["failures"] == 0
    assert abs(res.mean_error_m * 1e3 - thesis_mm) <= 0.4 * thesis_mm
    assert res.max_error_m < 0.01  # "always in the order of millimetres"


def test_rounding_error_grows_with_tilt(cam, room):
    # thesis: tilting in both axes gives the largest mean error (fig. 4.2d vs 4.2a)
    level = rounding_study(cam, room, euler_deg=(90, 0, 0)).mean_error_m
    both = rounding_study(cam, room, euler_deg=(70, 20, 0)).mean_error_m
    assert both > level


def test_without_rounding_the_error_vanishes(cam, room):
    res = rounding_study(cam, room, euler_deg=(70, 20, 0), step_m=0.5, rounding=False)
    assert res.max_error_m < 1e-6


def test_rounding_same_in_cm_map_and_z_up_frame(cam, room):
    ref = rounding_study(cam, room, euler_deg=(90, 0, 0), step_m=0.25, height_m=0.5)
    in_cm = rounding_study(cam, _scaled_map(room, "cm", 100.0), euler_deg=(90, 0, 0),
                           step_m=0.25, height_m=0.5)
    np.testing.assert_allclose(in_cm.errors_m, ref.errors_m, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(in_cm.positions_m, ref.positions_m)
    # same room, z up: the camera looking up (+z) is theta = (0, 0, 0); floor plane xy
    z_up = rounding_study(cam, _z_up_map(room), euler_deg=(0, 0, 0), plane="xy",
                          step_m=0.25, height_m=0.5)
    # same pixels; the solver's convergence depends slightly on the frame (microns)
    np.testing.assert_allclose(z_up.errors_m, ref.errors_m, rtol=0, atol=2e-5)
    assert np.allclose(z_up.positions_m[..., 2], 0.5)  # up is +z here
    assert np.allclose(ref.positions_m[..., 1], -0.5)  # and -y in the thesis' frame


def test_rounding_monte_carlo_is_seeded(cam, room):
    kw = dict(euler_deg=(90, 0, 0), step_m=1.0, noise_px=0.5, trials=5)
    a = rounding_study(cam, room, seed=1, **kw)
    b = rounding_study(cam, room, seed=1, **kw)
    c = rounding_study(cam, room, seed=2, **kw)
    assert a.errors_m.shape == (3, 3, 5)
    np.testing.assert_array_equal(a.errors_m, b.errors_m)
    assert not np.array_equal(a.errors_m, c.errors_m)
    assert a.summary()["trials"] == 5


def test_solvers_agree_where_they_should(cam, room):
    # iterative and SQPnP both minimise the reprojection error: same answer to a few %
    it = rounding_study(cam, room, euler_deg=(70, 20, 0), step_m=0.25).mean_error_m
    sq = rounding_study(cam, room, euler_deg=(70, 20, 0), step_m=0.25, solver="sqpnp")
    assert sq.mean_error_m == pytest.approx(it, rel=0.1)


# ------------------------------------------------------------------------ forced errors


def test_image_error_grows_linearly(cam, room):
    positions = [(-1, 0, 0), (-0.5, 0, 0), (0, 0, 0), (0.5, 0, 0), (1, 0, 0)]  # fig. 4.3
    offsets = np.arange(-20, 21, 2)
    for axis in "xy":
        res = forced_error_study(cam, room, kind="image", axis=axis, offsets=offsets,
                                 positions_m=positions, euler_deg=(90, 0, 0), fixture_id=5)
        x = np.abs(offsets)
        for e in res.errors_m:
            slope, icpt = np.polyfit(x, e, 1)
            r2 = 1 - np.sum((e - (slope * x + icpt)) ** 2) / np.sum((e - e.mean()) ** 2)
            assert r2 > 0.95
            at20 = e[[0, -1]].mean()
            at10 = e[[5, -6]].mean()
            assert 1.7 < at20 / at10 < 2.3  # linear: twice the offset, twice the error
            assert 0.005 < at20 < 0.2  # thesis: "in the order of centimetres" at 20 px


def _world_errors(cam, room, height_m):
    """Errors for +-0.5 m and +-1 m on fixture 5's world x and z, fig. 4.4 / 4.5 poses."""
    out = {}
    for axis in "xz":
        res = forced_error_study(cam, room, kind="world", axis=axis,
                                 offsets=[-1.0, -0.5, 0.5, 1.0], positions_m=(0, -height_m, 0),
                                 euler_deg=FIG_4_4_EULERS, fixture_id=5)
        out[axis] = res.errors_m
    return out


def test_world_error_grows_non_linearly(cam, room):
    for errs in _world_errors(cam, room, 0.0).values():
        half = errs[:, [1, 2]]
        full = errs[:, [0, 3]]
        # a linear response would give half the error at half the offset; the thesis'
        # curves saturate (0.5 m already costs about as much as 1 m)
        assert np.all(half > 0.6 * full)
        assert np.all(full > half)


def test_world_error_magnitudes_on_floor_and_one_metre_up(cam, room):
    floor = np.concatenate([e[:, [0, 3]].ravel() for e in _world_errors(cam, room, 0.0).values()])
    up = np.concatenate([e[:, [0, 3]].ravel() for e in _world_errors(cam, room, 1.0).values()])
    # thesis: a 1 m error costs about 2 m on the floor and about 1 m from 1 m up
    assert 1.4 < floor.mean() < 3.0
    assert 0.6 < up.mean() < 1.5
    assert up.mean() < 0.8 * floor.mean()


def test_forced_error_study_bad_input(cam, room):
    kw = dict(offsets=[1.0], positions_m=(0, 0, 0), euler_deg=(90, 0, 0))
    with pytest.raises(ValueError, match="kind"):
        forced_error_study(cam, room, kind="map", axis="x", **kw)
    with pytest.raises(ValueError, match="axis"):
        forced_error_study(cam, room, kind="image", axis="z", **kw)
    with pytest.raises(ValueError, match="fixture 7"):
        forced_error_study(cam, room, kind="image", axis="x", fixture_id=7, **kw)
    with pytest.raises(ValueError, match="solver"):
        forced_error_study(cam, room, kind="image", axis="x", solver="dls", **kw)
    with pytest.raises(ValueError, match="euler_deg 3"):
        forced_error_study(cam, room, kind="image", axis="x", offsets=[1.0],
                           positions_m=[(0, 0, 0), (1, 0, 0)], euler_deg=[(90, 0, 0)] * 3)


# ------------------------------------------------------------------------- Monte Carlo


def test_monte_carlo_error_scales_with_noise(cam, room):
    # small noise propagates linearly: twice the pixel noise, twice the position error
    kw = dict(positions_m=(0.3, 0, -0.2), euler_deg=(85, 5, 0), trials=400, seed=3,
              rounding=False)
    a = monte_carlo_study(cam, room, noise_px=0.5, **kw).summary()
    b = monte_carlo_study(cam, room, noise_px=1.0, **kw).summary()
    assert a["failures"] == b["failures"] == 0
    assert 1.7 < b["mean_error_m"] / a["mean_error_m"] < 2.3
    assert a["median_error_m"] <= a["p95_error_m"] <= a["max_error_m"]
    s = monte_carlo_study(cam, room, survey_error_m=0.01, **kw).summary()
    assert 0.001 < s["mean_error_m"] < 0.2  # 1 cm map errors: centimetres, not metres


def test_monte_carlo_per_pose_summary(cam, room):
    res = monte_carlo_study(cam, room, positions_m=[(0, 0, 0), (0.5, 0, 0)],
                            euler_deg=(90, 0, 0), noise_px=0.5, trials=10)
    s = res.summary()
    assert res.errors_m.shape == (2, 10)
    assert [p["position_m"] for p in s["per_pose"]] == [[0, 0, 0], [0.5, 0, 0]]


# ---------------------------------------------------------------------------- coverage


def _max_tilts(res):
    e, fix = res.euler_deg, res.fix[0, 0]
    about_x = np.abs(e[(e[:, 1] == 0) & fix, 0] - 90).max()
    about_y = np.abs(e[(e[:, 0] == 90) & fix, 1]).max()
    return about_x, about_y


def test_coverage_tilt_limits_match_thesis_chapter_3(cam, room):
    kw = dict(u_range_m=(0, 0), v_range_m=(0, 0), tilt_max_deg=18, tilt_step_deg=1,
              min_frames=0)
    # thesis fig. 3.8: from the floor about 12 deg about x and 15 about y
    tx, ty = _max_tilts(coverage_study(cam, room, height_m=0.0, **kw))
    assert 10 <= tx <= 14 and 13 <= ty <= 17
    assert ty > tx  # the sensor is wider than tall and the layout too
    # fig. 3.10: from 1 m up about 4 and 6 deg
    tx, ty = _max_tilts(coverage_study(cam, room, height_m=1.0, **kw))
    assert 3 <= tx <= 5 and 5 <= ty <= 7


def test_coverage_needs_enough_rows_to_decode(cam, room):
    # a 15 cm disc 2.7 m away spans 3912 * 0.15 / 2.7 = 217 rows; 18 chips at 4 kHz and
    # 20 us per row last 225 rows per frame -> undecodable; at 10 kHz 90 rows -> fine
    kw = dict(u_range_m=(0, 0), v_range_m=(0, 0), tilt_max_deg=0, tilt_step_deg=1)
    ok = coverage_study(cam, room, chip_rate_hz=10_000, **kw)
    slow = coverage_study(cam, room, chip_rate_hz=4_000, **kw)
    assert ok.frame_rows == pytest.approx(90.0)
    assert ok.fix.all() and not slow.fix.any()
    assert slow.usable.max() == 0
    assert ok.summary()["mean_error_m"] < 0.02


def test_coverage_rejects_collinear_fixtures(cam):
    line = FixtureMap(tuple(Fixture(i, [x, -2.7, 0.0], 0.15) for i, x in
                            zip((1, 2, 3, 4), (-0.3, -0.1, 0.1, 0.3), strict=True)))
    res = coverage_study(cam, line, u_range_m=(0, 0), v_range_m=(0, 0), tilt_max_deg=0,
                         tilt_step_deg=1)
    assert res.usable[0, 0, 0] == 4 and not res.fix.any()


def test_coverage_map_shape_and_summary(cam, room):
    res = coverage_study(cam, room, step_m=1.0, tilt_max_deg=10, tilt_step_deg=10, seed=1)
    assert res.fix.shape == (3, 3, 9) and res.errors_m.shape == (3, 3, 9, 1)
    s = res.summary()
    assert 0 < s["mean_fix_fraction"] <= 1 and s["orientations"] == 9
    assert np.all(np.isnan(res.errors_m[~res.fix]))
    assert np.all(np.isfinite(res.errors_m[res.fix]))


def test_coverage_needs_diameters(cam):
    bare = FixtureMap(tuple(Fixture(i, p) for i, p in
                            zip((1, 2, 3, 4), [(1, -2.7, 1), (1, -2.7, -1), (-1, -2.7, -1),
                                               (-1, -2.7, 1)], strict=True)))
    kw = dict(u_range_m=(0, 0), v_range_m=(0, 0), tilt_max_deg=0, tilt_step_deg=1)
    with pytest.raises(ValueError, match="fixture 1 has no diameter"):
        coverage_study(cam, bare, **kw)
    assert coverage_study(cam, bare, default_diameter_m=0.15, **kw).fix.all()


# ----------------------------------------------------------------------------- helpers


def test_grid_helpers(room):
    np.testing.assert_allclose(axis_values((-1, 1), 0.1, "x"), np.linspace(-1, 1, 21))
    assert axis_values((0, 1), 0.3).tolist() == [0.0, 0.3, 0.6, 0.9]
    with pytest.raises(ValueError, match="x range"):
        floor_grid(room.positions, u_range_m=(1, -1))
    with pytest.raises(ValueError, match="plane"):
        floor_grid(room.positions, plane="xx")
    pos = set_height([(0.5, 0, 0)], room.positions, height_m=1.0)
    np.testing.assert_allclose(pos, [[0.5, -1.0, 0.0]])


# --------------------------------------------------------------------------------- CLI




def test_cli_rounding_json_and_outputs(tmp_path, thesis_camera_path, thesis_room_path):
    out = tmp_path / "r"
    result = runner.invoke(app, [
        "study", "rounding", "--camera", str(thesis_camera_path), "--map", str(thesis_room_path),
        "--step", "0.5", "--euler", "70,20,0", "--out", str(out), "--json",
    ])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert summary["poses"] == 25 and summary["euler_deg"] == [70, 20, 0]
    assert 0 < summary["mean_error_m"] <= summary["max_error_m"] < 0.01
    assert json.loads((out / "summary.json").read_text()) == summary
    rows = (out / "rounding.csv").read_text().splitlines()
    assert rows[0].startswith("x_m,y_m,z_m,error_m") and len(rows) == 26
    assert (out / "rounding.png").read_bytes()[:4] == b"\x89PNG"


def test_cli_forced_and_monte_carlo(tmp_path):
    result = runner.invoke(app, [
        "study", "world-error", "--figure", "4.5", "--axis", "z", "--range", "-1,1",
        "--step", "0.5", "--json", "--out", str(tmp_path / "w"),
    ])
    assert result.exit_code == 0, result.output
    s = json.loads(result.stdout)
    assert len(s["series"]) == 4
    assert all(ser["position_m"] == [0, -1, 0] for ser in s["series"])  # 1 m up, y down
    assert (tmp_path / "w" / "world-error.csv").exists()
    result = runner.invoke(app, [
        "study", "image-error", "--positions", "0,0,0", "--noise-px", "0.5", "--trials", "20",
        "--json",
    ])
    assert result.exit_code == 0, result.output
    s = json.loads(result.stdout)
    assert s["study"] == "monte-carlo" and s["trials"] == 20 and s["poses"] == 20


def test_cli_coverage_text(tmp_path):
    result = runner.invoke(app, [
        "study", "coverage", "--step", "1", "--tilt-max", "5", "--tilt-step", "5",
        "--out", str(tmp_path),
    ])
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


@pytest.mark.parametrize("axis", ["rows", "columns"])
def test_coverage_reads_a_reversed_readout_along_the_same_axis(cam, room, axis):
    # fy half of fx: a 15 cm disc 2.7 m away spans about 217 columns but only 109 rows; 1.5
    # frames are 135 rows (18 chips at 10 kHz, 20 us rows), so the readout's axis decides
    k = cam.matrix.copy()
    k[1, 1] = 0.5 * k[0, 0]
    kw = dict(u_range_m=(0, 0), v_range_m=(0, 0), tilt_max_deg=0, tilt_step_deg=1,
              min_frames=1.5)
    usable = {}
    for readout in (axis, f"{axis}-reversed"):
        wide = dataclasses.replace(cam, matrix=k, readout=readout)
        usable[readout] = int(coverage_study(wide, room, **kw).usable.max())
    assert usable[axis] == usable[f"{axis}-reversed"]
    assert usable[axis] == (4 if axis == "columns" else 0)


def test_rounding_study_runs_the_locators_own_pose_path(cam, room):
    kw = dict(euler_deg=(90, 0, 0), u_range_m=(-0.2, 0.2), v_range_m=(-0.2, 0.2), step_m=0.2)
    ours = rounding_study(cam, room, solver="locate", **kw)
    opencv = rounding_study(cam, room, solver="iterative", **kw)
    assert np.all(np.isfinite(ours.errors_m))
    # both reach the rounding floor (about a millimetre), not the same numbers
    assert np.nanmean(ours.errors_m) < 0.005 and np.nanmean(opencv.errors_m) < 0.005
    assert ours.summary()["solver"] == "locate"


def test_study_cli_accepts_the_locate_solver_and_refuses_others():
    res = runner.invoke(app, ["study", "rounding", "--step", "0.5", "--solver", "locate",
                              "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["solver"] == "locate"
    bad = runner.invoke(app, ["study", "rounding", "--solver", "dlt"])
    assert bad.exit_code == 2
    assert "locate" in one_error_line(bad)
