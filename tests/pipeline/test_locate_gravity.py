"""Locating photos with two or three fixtures and the direction of gravity.

Renders of the small room (fast) and of the thesis' room at full size, with exactly two or
three fixtures in view; the Python call, the command line, a photo's sidecar and the map's
``up``.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import camvlp
from camvlp.cli import main
from camvlp.io import load_map, load_sidecar, save_map
from camvlp.model.camera import Pose
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.locate import LocateSettings, locate
from camvlp.sim.render import fixture_truths, render
from conftest import SMALL_ROOM_XZ, make_small_room, one_error_line, small_settings

UP = np.array([0.0, -1.0, 0.0])  # the rooms' up: y points down


def true_gravity(pose: Pose) -> np.ndarray:
    """Gravity in the camera frame, m/s^2."""
    return 9.81 * (pose.world_from_camera.T @ -UP)


def turned(g: np.ndarray, angle_deg: float, rng: np.random.Generator) -> np.ndarray:
    axis = rng.normal(size=3)
    axis -= (axis @ g) * g / (g @ g)
    axis /= np.linalg.norm(axis)
    return Rotation.from_rotvec(np.radians(angle_deg) * axis).apply(g)


@pytest.fixture(scope="module")
def two_and_three(tmp_path_factory, small_camera):
    """Photos of small rooms with two and three fixtures, tilted, and their files."""
    d = tmp_path_factory.mktemp("gravity")
    out = {}
    for k, euler in ((2, (96.0, 4.0, 20.0)), (3, (93.0, -3.0, 50.0))):
        room = make_small_room(ids=(5, 6, 9)[:k], xz=SMALL_ROOM_XZ[:k])
        pose = Pose.from_euler([0.1, 0.0, -0.1], euler)
        r = render(small_camera, room, pose, small_settings(seed=30 + k))
        assert sum(t.fully_inside for t in r.fixtures) == k
        cv2.imwrite(str(d / f"photo{k}.png"), r.image)
        save_map(room, d / f"room{k}.yaml")
        out[k] = (r.image, room, pose, d / f"photo{k}.png", d / f"room{k}.yaml")
    return out


@pytest.mark.parametrize("k", [2, 3])
def test_locate_with_gravity(two_and_three, small_camera, k: int) -> None:
    image, room, pose, _, _ = two_and_three[k]
    plain = locate(image, small_camera, room)
    assert not plain and "at least 4" in plain.reason and "2 with gravity" in plain.reason
    res = locate(image, small_camera, room, gravity=true_gravity(pose))
    assert res, res.reason
    assert res.solver == f"gravity-{k}" and res.fixtures_used == k
    assert np.linalg.norm(res.position - pose.position) < 2e-3
    assert res.gravity_residual_deg < 0.05
    d = res.to_dict()
    assert d["solver"] == f"gravity-{k}" and d["fixtures_used"] == k
    # how sure: from two fixtures the tilt is the gravity's (1 degree sigma): some cm at
    # their distance; a third holds it too, and its centres are sharp (renders)
    sigma = res.position_sigma
    assert np.all((sigma > 0) & (sigma < 0.2)) and (sigma.max() > 0.01) == (k == 2)
    np.testing.assert_allclose(d["position_sigma"], sigma, atol=1e-6)  # (rounded in the dict)
    # a gravity 1 degree off moves two fixtures' answer by about their distance times it
    off = locate(
        image, small_camera, room, gravity=turned(true_gravity(pose), 1.0, np.random.default_rng(k))
    )
    assert off
    error = np.linalg.norm(off.position - pose.position)
    if k == 2:
        assert 0.2 * 2.7 * np.radians(1) < error < 1.5 * 2.9 * np.radians(1)


def test_four_fixtures_with_gravity_report_the_tilt(small_camera, small_room, small_render):
    pose = Pose.from_euler([0, 0, 0], (90.0, 0.0, 0.0))
    rng = np.random.default_rng(1)
    res = locate(
        small_render.image,
        small_camera,
        small_room,
        LocateSettings(gravity_sigma_deg=2.0),
        gravity=turned(true_gravity(pose), 3.0, rng),
    )
    assert res and res.solver == "pnp+gravity" and res.fixtures_used == 5
    assert abs(res.tilt_disagreement_deg - 3.0) < 0.1
    assert "tilt_disagreement_deg" in res.to_dict()
    plain = locate(small_render.image, small_camera, small_room)
    assert plain.solver == "pnp" and np.isnan(plain.tilt_disagreement_deg)
    # a limit on the position's sigma holds for a pose solved with gravity too
    gravity = turned(true_gravity(pose), 3.0, np.random.default_rng(1))
    settings = LocateSettings(gravity_sigma_deg=2.0)
    loose = locate(small_render.image, small_camera, small_room, settings, gravity=gravity)
    assert loose and loose.solver == "pnp+gravity" and np.all(np.isfinite(loose.position_sigma))
    limit = 0.5 * float(loose.position_sigma.max())
    tight = dataclasses.replace(settings, max_position_sigma=limit)
    limited = locate(small_render.image, small_camera, small_room, tight, gravity=gravity)
    assert not limited and limited.position is None
    assert (
        "the position is too unsure" in limited.reason and f"limit of {limit:g}" in limited.reason
    )


def test_mirrored_photo_with_gravity(two_and_three, small_camera) -> None:
    image, room, pose, _, _ = two_and_three[3]
    res = locate(
        image[:, ::-1].copy(),
        small_camera,
        room,
        LocateSettings(mirrored=True),
        gravity=true_gravity(pose),
    )
    assert res, res.reason
    assert np.linalg.norm(res.position - pose.position) < 2e-3


@pytest.mark.parametrize(
    "gravity, words",
    [([0, 0, 0], "zero length"), ([np.nan, 0, 1], "finite"), ([0, 0, 9.81], "optical axis")],
)
def test_bad_gravity_is_an_input_error(two_and_three, small_camera, gravity, words) -> None:
    image, room, *_ = two_and_three[2]
    with pytest.raises(camvlp.InputError, match=words) as err:
        locate(image, small_camera, room, gravity=gravity)
    assert "\n" not in str(err.value)


def run(capsys, *args) -> tuple[int, str, str]:
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def test_cli_gravity_and_sidecar(two_and_three, small_files, capsys) -> None:
    _, _, pose, photo, room = two_and_three[2]
    cam = small_files["camera"]
    code, out, err = run(capsys, "locate", photo, "--camera", cam, "--map", room)
    assert code == 1
    g = ",".join(f"{v:.9f}" for v in true_gravity(pose))
    code, out, err = run(
        capsys, "locate", photo, "--camera", cam, "--map", room, "--json", f"--gravity={g}"
    )
    assert code == 0, err
    d = json.loads(out)
    assert d["solver"] == "gravity-2" and d["fixtures_used"] == 2
    assert np.linalg.norm(np.array(d["position"]) - pose.position) < 2e-3
    # the same from a sidecar beside the photo
    sidecar = photo.with_suffix(".json")
    sidecar.write_text(json.dumps({"gravity": true_gravity(pose).tolist()}))
    try:
        code, out, err = run(capsys, "locate", photo, "--camera", cam, "--map", room)
        assert code == 0, err
        assert "gravity-2, 2 fixtures" in out
        for text, words in (
            ("{not json", "malformed sidecar file"),
            ('{"gravity": [0, 0, 0]}', "zero length"),
            ('{"gravity": [1, 2]}', "three numbers"),
            # JSON but not an object: gravity alone, as the sidecar is easily mistaken to be
            ("[0.12, -0.31, -9.8]", "sidecar file: expected a mapping of keys, got a list"),
            ('"up"', "got a string"),
        ):
            sidecar.write_text(text)
            code, out, err = run(capsys, "locate", photo, "--camera", cam, "--map", room)
            assert code == 2
            assert words in one_error_line(err, out) and str(sidecar) in err
    finally:
        sidecar.unlink()


@pytest.mark.parametrize(
    "extra, words",
    [
        (["--gravity=0,0,0"], "zero length"),
        (["--gravity=1,nan,0"], "finite"),
        (["--gravity=1,2"], "3 comma-separated"),
        (["--gravity=0,0,9.81"], "optical axis"),
        (["--gravity=0,0,-1", "--gravity-sigma-deg", "0"], "--gravity-sigma-deg"),
    ],
)
def test_cli_bad_gravity(two_and_three, small_files, capsys, extra, words) -> None:
    _, _, _, photo, room = two_and_three[2]
    code, out, err = run(
        capsys, "locate", photo, "--camera", small_files["camera"], "--map", room, *extra
    )
    assert code == 2
    assert words in one_error_line(err, out)


def test_map_up(tmp_path: Path, two_and_three) -> None:
    room: FixtureMap = two_and_three[3][1]
    assert room.up is None
    with_up = FixtureMap(room.fixtures, up=[0, -2, 0])
    np.testing.assert_allclose(with_up.up, UP)
    save_map(with_up, tmp_path / "up.yaml")
    np.testing.assert_allclose(load_map(tmp_path / "up.yaml").up, UP)
    text = (tmp_path / "up.yaml").read_text()
    for bad, words in (("[0, 0, 0]", "non-zero"), ("[0, 1]", "3 numbers"), ("up", "numbers")):
        (tmp_path / "bad.yaml").write_text(text.replace("up:", f"up: {bad}\nold_up:"))
        with pytest.raises(camvlp.InputError, match=words) as err:
            load_map(tmp_path / "bad.yaml")
        assert "bad.yaml" in str(err.value)


def test_sidecar_names(tmp_path: Path) -> None:
    photo = tmp_path / "p.jpg"
    photo.write_bytes(b"")
    assert load_sidecar(photo) is None
    (tmp_path / "p.jpg.json").write_text('{"gravity": [0, 0, -9.8], "gravity_sigma_deg": 0.5}')
    s = load_sidecar(photo)
    assert s.gravity.tolist() == [0, 0, -9.8] and s.gravity_sigma_deg == 0.5
    (tmp_path / "p.json").write_text('{"gravity": [0, 1, -9.8]}')
    assert load_sidecar(photo).gravity.tolist() == [0, 1, -9.8]  # PHOTO.json first
    # a JSON without gravity (the simulator's truth) is not a sidecar
    (tmp_path / "p.json").write_text('{"pose": {"position": [0, 0, 0]}}')
    (tmp_path / "p.jpg.json").unlink()
    assert load_sidecar(photo) is None


# ------------------------------------------------- the thesis' room, full size (benchmark's)


def _pose_with(k: int, rng, camera, room, settings, height: float) -> Pose:
    for _ in range(20_000):
        pose = Pose.from_euler(
            [rng.uniform(-1, 1), -height, rng.uniform(-1, 1)],
            [90 + rng.uniform(-20, 20), rng.uniform(-20, 20), rng.uniform(-180, 180)],
        )
        inside = [t for t in fixture_truths(camera, room, pose, settings) if t.fully_inside]
        if len(inside) == k and all(t.frames_spanned >= 1.2 for t in inside):
            return pose
    raise AssertionError("no pose found")


@pytest.mark.parametrize("k, height", [(2, 0.0), (3, 1.0)])
def test_thesis_room_two_and_three_fixtures(thesis_camera_path, thesis_room_path, k, height):
    """The benchmark's case in small: one full-size photo, gravity off by 0.5 degrees."""
    camera, room = camvlp.load_camera(thesis_camera_path), camvlp.load_map(thesis_room_path)
    rng = np.random.default_rng(40 + k)
    settings = camvlp.RenderSettings(exposure_s=50e-6, seed=k)
    pose = _pose_with(k, rng, camera, room, settings, height)
    photo = render(camera, room, pose, settings)
    g = turned(true_gravity(pose), 0.5, rng)
    res = locate(photo.image, camera, room, gravity=g)
    assert res, res.reason
    assert res.solver == f"gravity-{k}" and res.fixtures_used == k
    truth = {t.id: t.pixel for t in photo.fixtures if t.in_front}
    for f in res.fixtures:
        if f.used:
            assert np.hypot(*(truth[f.id] - f.pixel)) < 2.0  # the right ID
    far = max(
        np.linalg.norm(room.get(f.id).position - pose.position) for f in res.fixtures if f.used
    )
    error = np.linalg.norm(res.position - pose.position)
    assert error < far * np.radians(0.5) * 1.5  # no more than the tilt error explains
    if k == 3:
        assert error < 5e-3


def test_evaluate_reads_the_sidecars(two_and_three, small_camera, tmp_path: Path) -> None:
    from camvlp.analysis.evaluate import evaluate_survey, read_survey, write_results_csv

    _, room, pose, photo, _ = two_and_three[2]
    for name, with_sidecar in (("a.png", True), ("b.png", False)):
        (tmp_path / name).write_bytes(photo.read_bytes())
        if with_sidecar:
            (tmp_path / "a.json").write_text(json.dumps({"gravity": true_gravity(pose).tolist()}))
    x, y, z = pose.position
    (tmp_path / "survey.csv").write_text(f"photo,x,y,z\na.png,{x},{y},{z}\nb.png,{x},{y},{z}\n")
    ev = evaluate_survey(read_survey(tmp_path / "survey.csv"), small_camera, room, jobs=1)
    a, b = ev.results
    assert a.located and a.solver == "gravity-2" and a.error < 2e-3
    assert not b.located and "at least 4" in b.reason
    write_results_csv(ev, tmp_path / "results.csv")
    assert "gravity-2" in (tmp_path / "results.csv").read_text()


def test_one_fixture_with_gravity_is_not_enough(small_camera) -> None:
    room = make_small_room(ids=(5,), xz=SMALL_ROOM_XZ[:1])
    pose = Pose.from_euler([0.5, 0.0, 0.4], (90.0, 0.0, 0.0))
    r = render(small_camera, room, pose, small_settings(seed=3))
    res = locate(r.image, small_camera, room, gravity=true_gravity(pose))
    assert not res and res.solver == "gravity"
    assert "at least 2 are needed with gravity" in res.reason


def test_thesis_room_three_fixtures_weighed_by_their_own_centre_sigmas(
    thesis_camera_path, thesis_room_path
):
    """Three fixtures on the floor, gravity 0.5 degrees off: each disc weighed by its own
    centre sigma (hundredths of a pixel) trusts the pixels as much as they deserve; one
    sigma of 1 px for all lets the accelerometer's error through."""
    camera, room = camvlp.load_camera(thesis_camera_path), camvlp.load_map(thesis_room_path)
    rng = np.random.default_rng(61)
    settings = camvlp.RenderSettings(exposure_s=50e-6, seed=1)
    pose = _pose_with(3, rng, camera, room, settings, 0.0)
    photo = render(camera, room, pose, settings)
    g = turned(true_gravity(pose), 0.5, rng)
    res = locate(photo.image, camera, room, gravity=g)
    assert res and res.solver == "gravity-3", res.reason
    sigmas = np.array([f.centre_sigma_px for f in res.fixtures if f.used])
    assert np.all((sigmas >= 0.01) & (sigmas < 0.2))
    assert all(f.to_dict()["centre_sigma_px"] == round(f.centre_sigma_px, 4) for f in res.fixtures)
    assert np.linalg.norm(res.position - pose.position) < 3e-3
    one = locate(photo.image, camera, room, LocateSettings(centre_sigma_px=1.0), gravity=g)
    assert one and np.linalg.norm(one.position - pose.position) > 3e-3
