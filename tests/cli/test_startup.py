"""Starting the command line: ``import camvlp.cli``, which every ``camvlp`` run and every
``--help`` pays for, loads typer and the commands' declarations, not the modules that do the
work; each command imports what it needs when it runs.

Each module kept out below is one that no help text needs and that not every command needs:

- ``camvlp.pipeline``: the locator's stages (locate, evaluate, track, the service);
- ``camvlp.sim``: the renderer (render, render-video, render-chessboard, the studies' grids);
- ``camvlp.analysis``: calibration, surveys, tracks and studies;
- ``camvlp.service``: the HTTP service (serve only), which brings FastAPI and SQLAlchemy;
- ``camvlp.viz``: annotated photos and plots;
- ``camvlp.io`` and ``camvlp.geometry``: the file readers (YAML, images, video) and the
  pose solvers, which bring OpenCV and NumPy;
- ``cv2`` and ``numpy``: together some 0.1 s to import, which ``--help`` and ``encode``'s
  usage errors need not wait for (a command that reads a photo imports them when it runs);
- ``scipy``, ``matplotlib``, ``PIL``, ``av``: the statistics, plots, EXIF and video
  decoding of a few commands, each tens of milliseconds or more to import;
- ``fastapi``, ``sqlalchemy``, ``uvicorn``: the service's (serve only).

``pydantic`` is not in the list: typer itself (0.29) imports it to convert the options'
values when it builds the commands, for ``--help`` too.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import typer

import camvlp
from camvlp.cli import app

#: Modules (and their submodules) that starting the command line must not load.
KEPT_OUT = (
    "camvlp.pipeline",
    "camvlp.sim",
    "camvlp.analysis",
    "camvlp.service",
    "camvlp.viz",
    "camvlp.io",
    "camvlp.geometry",
    "cv2",
    "numpy",
    "scipy",
    "matplotlib",
    "PIL",
    "av",
    "fastapi",
    "sqlalchemy",
    "uvicorn",
)

#: The package's ``src`` folder: the child processes import this copy, not an installed one.
SRC = Path(camvlp.__file__).resolve().parents[1]

#: A child's code: runs its first argument (Python statements), then prints the names of the
#: modules loaded as a JSON list, on the last line of stdout.
CHILD = "import json, sys; exec(sys.argv[1]); print(json.dumps(sorted(sys.modules)))"


def _loaded(code: str, *args: str) -> list[str]:
    """The modules loaded by ``code`` run in a fresh interpreter (``args``: its sys.argv)."""
    out = subprocess.run(
        [sys.executable, "-c", CHILD, code, *args],
        capture_output=True,
        text=True,
        check=True,
        env={**os.environ, "PYTHONPATH": str(SRC)},
    )
    return json.loads(out.stdout.splitlines()[-1])


def _kept_out(modules: list[str]) -> list[str]:
    """The modules of :data:`KEPT_OUT` (or under one) among ``modules``."""
    return [m for m in modules if any(m == k or m.startswith(k + ".") for k in KEPT_OUT)]


def test_importing_the_cli_loads_no_command_s_work():
    modules = _loaded("import camvlp.cli")
    assert "camvlp.cli.locate" in modules and "typer" in modules  # the commands are declared
    assert _kept_out(modules) == []


def _help_commands() -> list[list[str]]:
    """The words of every command and group, for ``WORDS --help``: the root's first."""
    found: list[list[str]] = []

    def walk(words: list[str], command) -> None:
        found.append(words)
        for name, sub in getattr(command, "commands", {}).items():
            walk([*words, name], sub)

    walk([], typer.main.get_command(app))
    return found


def test_every_help_text_is_shown_without_the_command_s_work():
    """``camvlp --help`` and each ``camvlp COMMAND --help``, one after another in one process:
    the help texts and the options' defaults need none of the heavy modules."""
    commands = _help_commands()
    assert len(commands) > 10
    code = (
        "import contextlib, io, json, sys\n"
        "from camvlp.cli import main\n"
        "for words in json.loads(sys.argv[2]):\n"
        "    with contextlib.redirect_stdout(io.StringIO()) as shown:\n"
        "        assert main([*words, '--help']) == 0, words\n"
        "    assert 'Usage: camvlp' in shown.getvalue(), words\n"
    )
    assert _kept_out(_loaded(code, json.dumps(commands))) == []


@pytest.mark.parametrize(
    ("command", "option", "field"),
    [
        ("render", "chip_rate", "chip_rate_hz"),
        ("render", "brightness", "brightness"),
        ("render", "ambient", "ambient"),
        ("render", "off_level", "off_level"),
        ("render", "core", "core"),
        ("render", "core_offset", "core_offset"),
        ("render", "halo", "halo"),
        ("render", "soft", "soft"),
        ("render", "blur", "blur_px"),
        ("render", "vignetting", "vignetting"),
        ("render", "bayer", "bayer"),
        ("render", "gamma", "gamma"),
        ("render", "sharpen", "sharpen"),
        ("render", "black_point", "black_point"),
        ("render", "seed", "seed"),
        ("render-video", "chip_rate", "chip_rate_hz"),
        ("render-video", "brightness", "brightness"),
        ("render-video", "off_level", "off_level"),
        ("render-video", "core", "core"),
        ("render-video", "halo", "halo"),
        ("render-video", "soft", "soft"),
        ("render-video", "blur", "blur_px"),
        ("render-video", "vignetting", "vignetting"),
        ("render-video", "bayer", "bayer"),
        ("render-video", "gamma", "gamma"),
        ("render-video", "sharpen", "sharpen"),
        ("render-video", "black_point", "black_point"),
        ("render-video", "seed", "seed"),
    ],
)
def test_render_defaults_are_the_renderer_s(command, option, field):
    """The renderers' defaults are written out in the options (the simulator is imported only
    when a render runs): each is :class:`~camvlp.sim.render.RenderSettings`' own."""
    from camvlp.sim.render import RenderSettings

    params = typer.main.get_command(app).commands[command].params
    default = next(p.default for p in params if p.name == option)
    expected = getattr(RenderSettings(), field)
    converted = default if isinstance(expected, bool) else type(expected)(default)
    assert converted == expected, (command, option, default, expected)


def test_reading_a_map_and_loading_the_locator_need_no_scipy():
    """``camvlp locate`` imports the locator and reads the files before any work: SciPy (half a
    second to import) waits for a path that uses it (a k-d tree of a large site's map, a
    glowing lamp's fit)."""
    room = SRC.parent / "examples" / "thesis_room.yaml"
    code = "import camvlp.io, camvlp.pipeline.locate; camvlp.io.load_map(sys.argv[2]).index"
    modules = _loaded(code.removesuffix(".index"), str(room))
    assert "camvlp.pipeline.locate" in modules and "camvlp.model.fixtures" in modules
    assert not [m for m in modules if m == "scipy" or m.startswith("scipy.")]
    # the map's k-d tree is SciPy's, imported when first asked for
    assert "scipy.spatial" in _loaded(code, str(room))
