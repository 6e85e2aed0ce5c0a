"""Shared test fixtures: paths to the example files and to the shared data directory."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def pytest_configure(config: pytest.Config) -> None:
    """Under pytest-xdist each worker has a core of its own: OpenCV's thread pool would put
    a second thread on the other worker's core (scripts/test.sh sets OpenBLAS's and OpenMP's
    threads the same way, for the subprocesses too)."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        import cv2

        cv2.setNumThreads(1)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The tests marked ``long`` (seconds each) run first, in their order, then the rest.

    pytest-xdist hands each worker the next tests as it finishes others: with the long
    tests last, one worker could still be running them when the other had nothing left.
    """
    items.sort(key=lambda item: item.get_closest_marker("long") is None)


@pytest.fixture(scope="session")
def examples_dir() -> Path:
    """The repository's ``examples/`` directory."""
    return REPO / "examples"


@pytest.fixture(scope="session")
def thesis_camera_path(examples_dir: Path) -> Path:
    """``examples/thesis_camera.yaml``: the thesis' phone camera."""
    return examples_dir / "thesis_camera.yaml"


@pytest.fixture(scope="session")
def thesis_room_path(examples_dir: Path) -> Path:
    """``examples/thesis_room.yaml``: the thesis' four-fixture room."""
    return examples_dir / "thesis_room.yaml"


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """The shared data directory next to the repository (real photographs, thesis text)."""
    return REPO.parent / "shared"


# --------------------------------------------------------------------------------------------
# A small camera and room for the locator's tests: renders of 1280 x 960 pixels that take a
# fraction of a second, with fixtures big enough to span two frames of stripes.

#: Small test camera: 1280 x 960 pixels, f = 1000 px, principal point at the centre.
SMALL_SIZE, SMALL_FOCAL_PX = (1280, 960), 1000.0
#: Sensor timing of the small room's renders: 25 us per row and 10 kHz chips give 4 rows per
#: chip, so a 0.4 m disc 2.7 m away (about 148 px) spans about two 18-chip frames.
SMALL_ROW_TIME_S, SMALL_CHIP_RATE_HZ = 25e-6, 10_000.0
#: The small room: 0.4 m discs on the ceiling (y = -2.7 m, facing down, +y), the thesis'
#: rectangle plus one in the middle.
SMALL_ROOM_IDS = (5, 6, 9, 10, 12)
SMALL_ROOM_XZ = ((0.8, 0.6), (0.8, -0.6), (-0.8, -0.6), (-0.8, 0.6), (0.0, 0.0))
CEILING_Y, SMALL_DIAMETER = -2.7, 0.4
#: The thesis' angles of a camera on the floor looking straight up at the ceiling.
LOOK_UP = (90.0, 0.0, 0.0)


def make_small_camera(**kwargs):
    """The small test camera (see ``SMALL_SIZE``); keyword arguments go to ``Camera``."""
    from camvlp.model.camera import Camera

    kwargs.setdefault("row_time_s", SMALL_ROW_TIME_S)
    return Camera.from_focal(*SMALL_SIZE, SMALL_FOCAL_PX, **kwargs)


def make_small_room(ids=SMALL_ROOM_IDS, xz=SMALL_ROOM_XZ, diameter=SMALL_DIAMETER):
    """A map of ceiling discs at ``(x, CEILING_Y, z)``, facing down (+y), metres."""
    import numpy as np

    from camvlp.model.fixtures import Fixture, FixtureMap

    return FixtureMap(
        tuple(
            Fixture(int(i), np.array([x, CEILING_Y, z]), diameter, np.array([0.0, 1.0, 0.0]))
            for i, (x, z) in zip(ids, xz, strict=True)
        )
    )


def small_settings(**kwargs):
    """Render settings of the small room (10 kHz chips, 25 us rows); overrides as keywords."""
    from camvlp.sim.render import RenderSettings

    kwargs.setdefault("chip_rate_hz", SMALL_CHIP_RATE_HZ)
    kwargs.setdefault("row_time_s", SMALL_ROW_TIME_S)
    return RenderSettings(**kwargs)


@pytest.fixture(scope="session")
def small_camera():
    """The small test camera (1280 x 960, f = 1000 px, 25 us rows)."""
    return make_small_camera()


@pytest.fixture(scope="session")
def small_room():
    """The small test room: five 0.4 m ceiling discs, IDs 5, 6, 9, 10, 12."""
    return make_small_room()


@pytest.fixture(scope="session")
def small_render(small_camera, small_room):
    """One render of the small room from the floor's origin, looking straight up (seed 1)."""
    from camvlp.model.camera import Pose
    from camvlp.sim.render import render

    return render(
        small_camera, small_room, Pose.from_euler([0, 0, 0], LOOK_UP), small_settings(seed=1)
    )


@pytest.fixture(scope="session")
def small_files(tmp_path_factory, small_camera, small_room, small_render):
    """The small camera, room and render written to files: dict of Paths.

    Keys: ``camera`` (YAML), ``map`` (YAML), ``photo`` (PNG of ``small_render``), ``dir``.
    """
    import cv2

    from camvlp.io import save_camera, save_map

    d = tmp_path_factory.mktemp("small_room")
    paths = {
        "dir": d,
        "camera": d / "camera.yaml",
        "map": d / "room.yaml",
        "photo": d / "photo.png",
    }
    save_camera(small_camera, paths["camera"])
    save_map(small_room, paths["map"])
    cv2.imwrite(str(paths["photo"]), small_render.image)
    return paths


def one_error_line(result_or_stderr, stdout: str = "") -> str:
    """Check that a command failed with exactly one ``error: ...`` line and no traceback.

    ``result_or_stderr`` is a CliRunner or subprocess result (its ``stderr`` and ``stdout``
    are read), or the stderr text itself.  Returns the error line.
    """
    if isinstance(result_or_stderr, str):
        err, out = result_or_stderr, stdout
    else:
        err, out = result_or_stderr.stderr, result_or_stderr.stdout or ""
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("error: "), err
    assert "Traceback" not in err + out
    return lines[0]


def stress_settings(rows_per_chip: float, exposure_chips: float, **look):
    """The render settings of a stress photo (rows of 15 us): ``rows_per_chip`` rows per
    chip, an exposure of ``exposure_chips`` chips, and the ``look`` (brightness, off level,
    halo, core, blur, readout, noise seed)."""
    from camvlp.sim.render import RenderSettings

    rate = 1e5 / (1.5 * rows_per_chip)  # Hz
    return RenderSettings(chip_rate_hz=rate, exposure_s=exposure_chips / rate, **look)


def stress_scene(size, lamps, settings, quality: int, chip_rate_hz=None, k1: float = 0.0):
    """A drawn scene of ``benchmarks/stress_decode.py``: a camera of ``size`` (w, h; f = 1400
    px, 15 us rows, radial distortion ``k1``) at the origin looking up at ``lamps``
    ``(id, x, y, diameter)`` 2 m above it (metres, facing down), rendered with ``settings``
    and saved as a JPEG of ``quality``; returns the camera, the map, the render and the
    decoded JPEG."""
    import cv2
    import numpy as np

    from camvlp.model.camera import Camera, Pose
    from camvlp.model.fixtures import Fixture, FixtureMap
    from camvlp.sim.render import render

    distortion = np.array([k1, 0.0, 0.0, 0.0, 0.0]) if k1 else np.zeros(0)
    cam = Camera.from_focal(*size, 1400.0, row_time_s=1.5e-5, distortion=distortion)
    room = FixtureMap(
        tuple(
            Fixture(i, np.array([x, y, 2.0]), d, np.array([0.0, 0.0, -1.0])) for i, x, y, d in lamps
        ),
        chip_rate_hz=chip_rate_hz,
    )
    photo = render(cam, room, Pose(np.eye(3), np.zeros(3)), settings)
    _, buf = cv2.imencode(".jpg", photo.image, [cv2.IMWRITE_JPEG_QUALITY, quality])
    return cam, room, photo, cv2.imdecode(buf, cv2.IMREAD_COLOR)
