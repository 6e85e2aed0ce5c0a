"""Tests of ``camvlp track`` and ``camvlp render-video``: files, summary, one-line errors."""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import re
import sys

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from camvlp.cli import app, main
from camvlp.cli.progress import progress_bar
from camvlp.io import load_map, save_camera, save_map
from camvlp.model.camera import Camera
from camvlp.model.fixtures import Fixture, FixtureMap
from conftest import one_error_line

runner = CliRunner()


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """A 640 x 360 camera 1.2 m under four 0.25 m discs, a trajectory file and a rendered
    folder of five frames (with its truth)."""
    d = tmp_path_factory.mktemp("track")
    save_camera(Camera.from_focal(640, 360, 483.0, row_time_s=40e-6), d / "cam.yaml")
    xz = ((0.35, 0.25), (0.35, -0.25), (-0.35, -0.25), (-0.35, 0.25))
    room = FixtureMap(
        tuple(
            Fixture(i, np.array([x, -2.7, z]), 0.25, np.array([0.0, 1.0, 0.0]))
            for i, (x, z) in zip((5, 6, 9, 10), xz, strict=True)
        )
    )
    save_map(room, d / "room.yaml")
    (d / "traj.csv").write_text(
        "t,x,y,z,theta_x,theta_y,theta_z\n0,0.0,-1.5,0,90,0,0\n0.27,0.1,-1.5,0,90,0,0\n"
    )
    result = runner.invoke(
        app,
        [
            "render-video",
            "--camera",
            str(d / "cam.yaml"),
            "--map",
            str(d / "room.yaml"),
            "--trajectory",
            str(d / "traj.csv"),
            "--out",
            str(d / "frames"),
            "--fps",
            "15",
        ],
    )
    assert result.exit_code == 0, result.output
    return d


def track(scene, source, out, *extra):
    return runner.invoke(
        app,
        [
            "track",
            str(source),
            "--camera",
            str(scene / "cam.yaml"),
            "--map",
            str(scene / "room.yaml"),
            "--out",
            str(out),
            *extra,
        ],
    )


def test_track_writes_trajectory_summary_and_picture(scene, tmp_path):
    result = track(scene, scene / "frames", tmp_path / "out", "--json")
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout.strip().splitlines()[-1])
    assert summary["frames"] == 5 and summary["fix"] == 5
    assert summary["errors"]["position_rmse"] < 0.003
    assert summary["wrong_ids"] == 0
    rows = list(csv.DictReader((tmp_path / "out" / "trajectory.csv").open()))
    assert [r["status"] for r in rows] == ["fix"] * 5
    assert {"x_raw", "fixtures_used", "reprojection_rms_px"} <= set(rows[0])
    assert cv2.imread(str(tmp_path / "out" / "trajectory.png")) is not None


def test_bad_frames_become_lost_rows(scene, tmp_path):
    folder = tmp_path / "mixed"
    folder.mkdir()
    names = sorted(p.name for p in (scene / "frames").glob("*.png"))
    for n in names[:3]:
        (folder / n).write_bytes((scene / "frames" / n).read_bytes())
    cv2.imwrite(str(folder / "frame_000003.png"), np.zeros((100, 100, 3), np.uint8))
    (folder / "readme.txt").write_text("hello")
    result = track(scene, folder, tmp_path / "out", "--fps", "15")
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader((tmp_path / "out" / "trajectory.csv").open()))
    assert [r["status"] for r in rows] == ["fix", "fix", "fix", "lost"]
    assert "camera file says" in rows[3]["reason"]
    assert "warning: skipped 1 file(s) that are not images: readme.txt" in result.stderr
    # the frame not located is counted by its reason on stderr
    assert "note: 1 of 4 frames not located:" in result.stderr.splitlines()
    assert "  1  image is 100 x 100 but the camera file says 640 x 360" in result.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["not_located"] == [
        {"reason": "image is 100 x 100 but the camera file says 640 x 360", "frames": 1}
    ]


def test_a_wrong_camera_file_is_named_in_the_error(scene, tmp_path):
    """Nothing located for one reason: the error line gives it, with its count of frames."""
    save_camera(Camera.from_focal(1280, 720, 966.0, row_time_s=40e-6), tmp_path / "big.yaml")
    result = runner.invoke(
        app,
        [
            "track",
            str(scene / "frames"),
            *("--camera", str(tmp_path / "big.yaml"), "--map", str(scene / "room.yaml")),
            *("--out", str(tmp_path / "out")),
        ],
    )
    assert result.exit_code == 1
    line = one_error_line(result)
    assert line.startswith(
        "error: no frame could be located: image is 640 x 360 but the camera file says "
        "1280 x 720 (5 of 5 frames; "
    ), line


def test_the_reasons_frames_failed_are_counted_most_frequent_first(scene, tmp_path):
    """Nothing located for two reasons (a map without the lights' IDs, two frames of another
    size): both counted on stderr, the most frequent first, and named in the error line."""
    folder = tmp_path / "mixed"
    folder.mkdir()
    names = sorted(p.name for p in (scene / "frames").glob("*.png"))
    for n in names[:3]:
        (folder / n).write_bytes((scene / "frames" / n).read_bytes())
    for n in names[3:]:
        cv2.imwrite(str(folder / n), np.zeros((100, 100), np.uint8))
    room = load_map(scene / "room.yaml")
    others = [dataclasses.replace(f, id=f.id - 4) for f in room.fixtures]  # 1, 2, 5, 6
    save_map(dataclasses.replace(room, fixtures=tuple(others)), tmp_path / "other.yaml")
    result = runner.invoke(
        app,
        [
            "track",
            str(folder),
            *("--camera", str(scene / "cam.yaml"), "--map", str(tmp_path / "other.yaml")),
            *("--out", str(tmp_path / "out"), "--fps", "15"),
        ],
    )
    assert result.exit_code == 1
    lines = result.stderr.splitlines()
    assert lines[0] == "note: 5 of 5 frames not located:"
    first, second = lines[1].split(maxsplit=1), lines[2].split(maxsplit=1)
    assert first[0] == "3" and "identified" in first[1]
    assert second == ["2", "image is 100 x 100 but the camera file says 640 x 360"]
    assert lines[3] == f"error: no frame could be located: {first[1]} (3 of 5 frames; {folder})"
    assert len(lines) == 4


def test_a_start_after_the_last_frame_says_so(scene, tmp_path):
    """--start past the input's end: no frame is read, and the error says that rather than
    "no frame could be located"."""
    result = track(scene, scene / "frames", tmp_path / "out", "--start", "100")
    assert result.exit_code == 1
    assert "no frame at or after --start 100 s" in one_error_line(result)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--fps", "0"], "--fps must be a positive number"),
        (["--gather-frames", "-1"], "--gather-frames must be 0 or more"),
        ([], "no such video or folder"),
    ],
)
def test_bad_input_is_one_line(scene, tmp_path, args, message):
    result = track(scene, tmp_path / "nothing.mp4", tmp_path / "out", *args)
    assert result.exit_code == 2
    assert message in one_error_line(result)


def test_render_video_refuses_a_bad_suffix(scene, tmp_path):
    result = _render_video(scene, tmp_path / "v.avi")
    assert result.exit_code == 2
    assert "--out must be" in one_error_line(result)


def _render_video(scene, out, *extra):
    return runner.invoke(
        app,
        [
            "render-video",
            "--camera",
            str(scene / "cam.yaml"),
            "--map",
            str(scene / "room.yaml"),
            "--trajectory",
            str(scene / "traj.csv"),
            "--out",
            str(out),
            "--frames",
            "1",
            *extra,
        ],
    )


def test_render_video_draws_the_lights_look(scene, tmp_path):
    # an LED never fully off, a glow, portrait readout: as in `camvlp render`
    plain = _render_video(scene, tmp_path / "plain")
    looks = _render_video(
        scene, tmp_path / "looks", "--off-level", "0.5", "--halo", "0.4", "--readout", "columns"
    )
    assert plain.exit_code == 0 and looks.exit_code == 0, looks.output
    a = cv2.imread(str(next((tmp_path / "plain").glob("*.png"))), cv2.IMREAD_GRAYSCALE)
    b = cv2.imread(str(next((tmp_path / "looks").glob("*.png"))), cv2.IMREAD_GRAYSCALE)
    lit = a > 128
    # the glow lights the ceiling around each lamp
    near = cv2.dilate(lit.astype(np.uint8), np.ones((9, 9), np.uint8)).astype(bool) & ~lit
    assert b[near].mean() > a[near].mean() + 10
    # stripes along the columns: the rows of a lamp vary less than its columns
    ys, xs = np.nonzero(b > 128)
    box = b[ys.min() : ys.min() + 40, xs.min() : xs.min() + 40].astype(float)
    assert box.std(axis=0).mean() < box.std(axis=1).mean()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--off-level", "2"), "--off-level must be a number from 0 to 1"),
        (("--halo", "-1"), "--halo must be a non-negative number"),
        (("--readout", "diagonal"), "--readout"),
    ],
)
def test_render_video_refuses_bad_looks(scene, tmp_path, args, message):
    result = _render_video(scene, tmp_path / "v", *args)
    assert result.exit_code == 2
    assert message in one_error_line(result)


def test_an_interrupted_render_says_where_its_frames_are(scene, tmp_path, monkeypatch):
    # Ctrl-C during render-video: exit 130, and the partial video named (its frames so far).
    # The command imports render_video when it runs: the simulator's own is replaced.
    import camvlp.sim.video as sim_video
    from camvlp.sim.video import partial_path

    def interrupted(camera, fixture_map, trajectory, out, **kwargs):
        partial_path(out).write_bytes(b"frames so far")
        raise KeyboardInterrupt

    monkeypatch.setattr(sim_video, "render_video", interrupted)
    out = tmp_path / "v.mp4"
    result = _render_video(scene, out)
    assert result.exit_code == 130
    assert f"interrupted: the frames so far are in {tmp_path / 'v.partial.mp4'}" in one_error_line(
        result
    )


# --------------------------------------------------------------------------------------------
# The progress bar: drawn on stderr when it is a terminal, else nothing

_CONTROL = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")


class Terminal(io.StringIO):
    """A stderr that says it is a terminal, and keeps what is drawn on it."""

    def isatty(self) -> bool:
        return True


def as_terminal(monkeypatch) -> Terminal:
    """stderr replaced by a :class:`Terminal` (an ordinary one: not TERM=dumb), from within
    the test itself (pytest sets its own stderr again after the fixtures)."""
    for name in ("TTY_COMPATIBLE", "TTY_INTERACTIVE", "NO_COLOR"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("TERM", "xterm")
    stderr = Terminal()
    monkeypatch.setattr(sys, "stderr", stderr)
    return stderr


def _drawn(stderr: Terminal) -> str:
    return _CONTROL.sub("", stderr.getvalue())


def _render_frames(scene, out) -> int:
    return main(
        [
            "render-video",
            *("--camera", str(scene / "cam.yaml"), "--map", str(scene / "room.yaml")),
            *("--trajectory", str(scene / "traj.csv"), "--frames", "3", "--out", str(out)),
        ]
    )


def test_render_video_and_track_draw_their_progress_on_a_terminal(scene, tmp_path, monkeypatch):
    terminal = as_terminal(monkeypatch)
    assert _render_frames(scene, tmp_path / "frames") == 0
    drawn = _drawn(terminal)
    assert "rendering" in drawn and "3/3" in drawn, drawn
    terminal.seek(0)
    terminal.truncate()
    code = main(
        [
            "track",
            str(tmp_path / "frames"),
            *("--camera", str(scene / "cam.yaml"), "--map", str(scene / "room.yaml")),
            *("--out", str(tmp_path / "track")),
        ]
    )
    assert code == 0
    drawn = _drawn(terminal)
    assert "tracking" in drawn and "3/3" in drawn, drawn


def test_no_bar_is_drawn_when_stderr_is_not_a_terminal(scene, tmp_path, capsys):
    assert _render_frames(scene, tmp_path / "frames") == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    assert captured.out.startswith("wrote 3 frames to")


def test_the_bar_counts_what_it_is_told(monkeypatch):
    terminal = as_terminal(monkeypatch)
    with progress_bar(None, "working") as update:
        assert update is not None
        update(2, total=5)
    assert "working" in _drawn(terminal) and "2/5" in _drawn(terminal)
    terminal.seek(0)
    terminal.truncate()
    with progress_bar(5, "quiet", show=False) as update:
        assert update is None  # the caller's choice: no bar, nothing to call
    assert terminal.getvalue() == ""


def test_gather_frames_reach_the_tracker(scene, tmp_path, monkeypatch):
    """--gather-frames N is the tracker's TrackSettings.gather_frames (0: no gathering)."""
    from camvlp.pipeline.track import tracker as tracker_module

    seen = []
    original = tracker_module.Tracker.__init__

    def spy(self, camera, fixture_map, settings=None):
        seen.append(settings.gather_frames)
        original(self, camera, fixture_map, settings)

    monkeypatch.setattr(tracker_module.Tracker, "__init__", spy)
    for n in ("0", "30"):
        result = track(scene, scene / "frames", tmp_path / f"out{n}", "--gather-frames", n)
        assert result.exit_code == 0, result.output
    assert seen == [0, 30]
