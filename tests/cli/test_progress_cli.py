"""The progress bar of the long commands: drawn on stderr when it is a terminal, else nothing."""

from __future__ import annotations

import io
import re
import sys

import numpy as np
import pytest

from camvlp.cli import main
from camvlp.cli.progress import progress_bar
from camvlp.io import save_camera, save_map
from camvlp.model.camera import Camera
from camvlp.model.fixtures import Fixture, FixtureMap

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


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """A 320 x 180 camera 1.2 m under four discs and a trajectory: files for render-video."""
    d = tmp_path_factory.mktemp("progress")
    save_camera(Camera.from_focal(320, 180, 240.0, row_time_s=80e-6), d / "cam.yaml")
    xz = ((0.35, 0.25), (0.35, -0.25), (-0.35, -0.25), (-0.35, 0.25))
    room = FixtureMap(
        tuple(
            Fixture(i, np.array([x, -2.7, z]), 0.25, np.array([0.0, 1.0, 0.0]))
            for i, (x, z) in zip((5, 6, 9, 10), xz, strict=True)
        )
    )
    save_map(room, d / "room.yaml")
    (d / "traj.csv").write_text(
        "t,x,y,z,theta_x,theta_y,theta_z\n0,0.0,-1.5,0,90,0,0\n1,0.1,-1.5,0,90,0,0\n"
    )
    return d


def _render_video(scene, out) -> int:
    return main(
        [
            "render-video",
            *("--camera", str(scene / "cam.yaml"), "--map", str(scene / "room.yaml")),
            *("--trajectory", str(scene / "traj.csv"), "--frames", "3", "--out", str(out)),
        ]
    )


def test_render_video_and_track_draw_their_progress_on_a_terminal(scene, tmp_path, monkeypatch):
    terminal = as_terminal(monkeypatch)
    assert _render_video(scene, tmp_path / "frames") == 0
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
    assert code in (0, 1)  # located or not: the bar is drawn either way
    drawn = _drawn(terminal)
    assert "tracking" in drawn and "3/3" in drawn, drawn


def test_nothing_is_drawn_when_stderr_is_not_a_terminal(scene, tmp_path, capsys):
    assert _render_video(scene, tmp_path / "frames") == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    assert captured.out.startswith("wrote 3 frames to")


def test_the_bar_counts_what_it_is_told(monkeypatch):
    terminal = as_terminal(monkeypatch)
    with progress_bar(None, "working") as update:
        assert update is not None
        update(2, total=5)
    assert "working" in _drawn(terminal) and "2/5" in _drawn(terminal)
    with progress_bar(5, "working", show=False) as update:
        assert update is None  # the caller's choice: no bar, nothing to call
    terminal.seek(0)
    terminal.truncate()
    with progress_bar(5, "quiet", show=False):
        pass
    assert terminal.getvalue() == ""
