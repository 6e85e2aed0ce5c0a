"""The options of ``camvlp study``'s commands, and turning them into a study's arguments:
the camera and map (the thesis' by default), the floor grid, the poses, the noise, gravity;
each refused as a usage error naming the option at fault (exit 2).  The files are read
when a command runs: declaring the options imports typer only."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from camvlp.errors import InputError

from ._app import check_solver, fail, parse_floats

if TYPE_CHECKING:
    from camvlp.model.camera import Camera
    from camvlp.model.fixtures import FixtureMap

#: Thesis figure presets for image-error / world-error: positions (m), angles (deg), height.
FIGURES = {
    "4.3": ("-1,0,0;-0.5,0,0;0,0,0;0.5,0,0;1,0,0", "90,0,0", 0.0),
    "4.4": ("0,0,0", "80,0,0;85,0,0;90,0,0;95,0,0", 0.0),
    "4.5": ("0,0,0", "80,0,0;85,0,0;90,0,0;95,0,0", 1.0),
}

CameraOpt = Annotated[
    Path | None,
    typer.Option("--camera", help="Camera file (default: examples/thesis_camera.yaml)."),
]
MapOpt = Annotated[
    Path | None, typer.Option("--map", help="Map file (default: examples/thesis_room.yaml).")
]
SolverOpt = Annotated[
    str,
    typer.Option(
        "--solver",
        help="PnP solver: iterative, sqpnp, ippe, epnp, or locate (the locator's own pose "
        "stage: several solvers' candidates, refined, the best in front of the camera).",
    ),
]
NoiseOpt = Annotated[
    float,
    typer.Option("--noise-px", help="Monte Carlo: Gaussian sigma on every image point (px)."),
]
SurveyOpt = Annotated[
    float,
    typer.Option(
        "--survey-error-m", help="Monte Carlo: Gaussian sigma on every fixture's map position (m)."
    ),
]
SeedOpt = Annotated[int, typer.Option("--seed", help="Seed of the Monte Carlo noise.")]
RoundOpt = Annotated[
    bool, typer.Option("--round/--no-round", help="Round image points to whole pixels (thesis).")
]
OutOpt = Annotated[
    Path | None, typer.Option("--out", help="Write CSV, PNG and summary.json into this directory.")
]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print the summary as JSON on stdout.")]
PlaneOpt = Annotated[
    str,
    typer.Option("--plane", help="The two world axes spanning the floor (xz: thesis, y down)."),
]
RangeX = Annotated[
    str | None, typer.Option("--x-range", help="Grid extent along x, 'lo,hi' (m; -1,1).")
]
RangeY = Annotated[str | None, typer.Option("--y-range", help="Grid extent along y (m).")]
RangeZ = Annotated[str | None, typer.Option("--z-range", help="Grid extent along z (m).")]
StepOpt = Annotated[float, typer.Option("--step", help="Grid spacing (m).")]
HeightOpt = Annotated[
    float, typer.Option("--height", help="Camera height above the floor (m), towards the lights.")
]

_POS_HELP = "Camera centres 'x,y,z;x,y,z' (m) (default: thesis fig. 4.3, five along x)."
_EUL_HELP = "Camera orientations 'tx,ty,tz;...' (deg) (default: 90,0,0); one or as many."
_FIG_HELP = "Thesis figure preset for poses and height: 4.3, 4.4 or 4.5."
_HGT_HELP = "Put every camera at this height above the floor (m), towards the lights."

FixtureOpt = Annotated[
    int | None, typer.Option("--fixture", help="ID of the fixture to move (default: first).")
]
PositionsOpt = Annotated[str | None, typer.Option("--positions", help=_POS_HELP)]
EulersOpt = Annotated[str | None, typer.Option("--eulers", help=_EUL_HELP)]
ForcedHeightOpt = Annotated[float | None, typer.Option("--height", help=_HGT_HELP)]
FigureOpt = Annotated[str | None, typer.Option("--figure", help=_FIG_HELP)]
TrialsOpt = Annotated[int, typer.Option("--trials", help="Monte Carlo draws per pose.")]


def _default_file(path: Path | None, name: str) -> Path:
    """The given path, or the thesis example (cwd's examples/, else the source tree's)."""
    if path is not None:
        return path
    for base in (Path.cwd(), Path(__file__).resolve().parents[3]):
        candidate = base / "examples" / name
        if candidate.exists():
            return candidate
    return Path("examples") / name  # the loader reports it missing


def check_study_options(
    solver: str, noise_px: float, survey_error_m: float, trials: int, **positive: float
) -> None:
    """Usage checks shared by the commands, naming the option at fault."""
    check_solver(solver, allow_locate=True)
    for name, value in (("--noise-px", noise_px), ("--survey-error-m", survey_error_m)):
        if not value >= 0:
            fail(f"{name} must be a non-negative number, got {value}")
    if trials < 1:
        fail(f"--trials must be a positive integer, got {trials}")
    for name, value in positive.items():
        if not value > 0:
            fail(f"--{name.replace('_', '-')} must be positive, got {value}")


def load_inputs(
    camera: Path | None, fmap: Path | None, plane: str | None = None
) -> tuple[Camera, FixtureMap]:
    """The camera and the map (the thesis' by default), refused naming the file when the
    studies cannot use them; with ``plane`` (``--plane``, for a floor or a height), the
    fixtures must lie off the floor's level, on the side that is up."""
    from camvlp.io import load_camera, load_map
    from camvlp.sim.grid import plane_axes, up_sign

    camera_path = _default_file(camera, "thesis_camera.yaml")
    cam = load_camera(camera_path)
    if cam.distortion.size > 12:  # the studies' batched projection has no tilted sensor
        raise InputError(
            "the studies do not model a tilted sensor (a camera file with 14 distortion "
            "coefficients)",
            camera_path,
        )
    map_path = _default_file(fmap, "thesis_room.yaml")
    fixture_map = load_map(map_path)
    if plane is not None:
        try:
            up_sign(fixture_map.positions, plane_axes(plane)[2])
        except ValueError as exc:
            what = str(exc).removeprefix("plane: ")  # the library names its argument
            raise InputError(f"--plane {plane}: {what}", map_path) from None
    return cam, fixture_map


def parse_triples(text: str, name: str) -> list[list[float]]:
    """``"x,y,z;x,y,z"`` -> list of triples, or a usage error naming ``name``."""
    parts = [p for p in text.split(";") if p.strip()]
    if not parts:
        fail(f"{name} needs at least one 'a,b,c' triple, got {text!r}")
    return [parse_floats(p, 3, name) for p in parts]


def grid_options(
    plane: str, x: str | None, y: str | None, z: str | None, step: float, height: float
) -> dict:
    """The floor grid's keyword arguments (see :func:`camvlp.sim.grid.floor_grid`) from the
    options --plane, --x-range/--y-range/--z-range (the plane's two), --step and --height."""
    given = {a: r if r is not None else "-1,1" for a, r in zip("xyz", (x, y, z), strict=True)}
    if len(plane) != 2 or any(a not in "xyz" for a in plane) or plane[0] == plane[1]:
        fail(f"--plane must be two different axes of x, y, z (e.g. xz), got {plane!r}")
    across = ({"x": x, "y": y, "z": z}[a] for a in "xyz" if a not in plane)
    if next(across) is not None:
        vertical = next(a for a in "xyz" if a not in plane)
        fail(
            f"--{vertical}-range is not an axis of the floor --plane {plane}: the camera's "
            "place off the floor is --height"
        )
    return {
        "plane": plane,
        "u_range_m": parse_floats(given[plane[0]], 2, f"--{plane[0]}-range"),
        "v_range_m": parse_floats(given[plane[1]], 2, f"--{plane[1]}-range"),
        "step_m": step,
        "height_m": height,
    }


def noise_options(noise_px: float, survey_error_m: float, trials: int, seed: int) -> dict:
    """The Monte Carlo noise's keyword arguments of the study functions."""
    return {"noise_px": noise_px, "survey_error_m": survey_error_m, "trials": trials, "seed": seed}


def gravity_options(gravity: bool, sigma_deg: float, min_fixtures: int | None) -> dict:
    """The coverage study's gravity keyword arguments from --gravity, --gravity-sigma-deg and
    --min-fixtures, or a usage error naming the option at fault."""
    if min_fixtures is not None and not gravity and min_fixtures != 4:
        fail(f"--min-fixtures {min_fixtures} needs --gravity (without it a fix needs 4)")
    if min_fixtures is not None and min_fixtures not in (2, 3, 4):
        fail(f"--min-fixtures must be 2, 3 or 4, got {min_fixtures}")
    if not sigma_deg > 0:
        fail(f"--gravity-sigma-deg must be a positive number, got {sigma_deg}")
    return {"gravity": gravity, "gravity_sigma_deg": sigma_deg, "min_fixtures": min_fixtures}


def grid_point_count(grid: dict) -> float:
    """Points of the floor grid that :func:`grid_options` describes."""
    (u0, u1), (v0, v1), step = grid["u_range_m"], grid["v_range_m"], grid["step_m"]
    return ((u1 - u0) / step + 1) * ((v1 - v0) / step + 1)
