"""``camvlp study``: the thesis' error study (chapter 4) and a coverage planner."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from camvlp.analysis import study as st
from camvlp.format import format_length
from camvlp.io import InputError, load_camera, load_map
from camvlp.io.atomic import StagedOutputs, check_output_dir, strict_json
from camvlp.io.writers import write_outputs
from camvlp.model.camera import DEFAULT_ROW_TIME_S, Camera
from camvlp.model.fixtures import FixtureMap
from camvlp.sim.grid import plane_axes, up_sign
from camvlp.viz import study_plots

from ._app import app, check_solver, fail, handle_errors, parse_floats
from .progress import progress_bar

study_app = typer.Typer(
    name="study",
    help="Error study (thesis chapter 4) and deployment planning, geometry only.",
    no_args_is_help=True,
)
app.add_typer(study_app, name="study")


#: Thesis figure presets for image-error / world-error: positions (m), angles (deg), height.
FIGURES = {
    "4.3": ("-1,0,0;-0.5,0,0;0,0,0;0.5,0,0;1,0,0", "90,0,0", 0.0),
    "4.4": ("0,0,0", "80,0,0;85,0,0;90,0,0;95,0,0", 0.0),
    "4.5": ("0,0,0", "80,0,0;85,0,0;90,0,0;95,0,0", 1.0),
}

# ------------------------------------------------------------------ shared option types

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
RangeX = Annotated[str, typer.Option("--x-range", help="Grid extent along x, 'lo,hi' (m).")]
RangeY = Annotated[str | None, typer.Option("--y-range", help="Grid extent along y (m).")]
RangeZ = Annotated[str | None, typer.Option("--z-range", help="Grid extent along z (m).")]
StepOpt = Annotated[float, typer.Option("--step", help="Grid spacing (m).")]
HeightOpt = Annotated[
    float, typer.Option("--height", help="Camera height above the floor (m), towards the lights.")
]


# --------------------------------------------------------------------------- helpers


def _default_file(path: Path | None, name: str) -> Path:
    """The given path, or the thesis example (cwd's examples/, else the source tree's)."""
    if path is not None:
        return path
    for base in (Path.cwd(), Path(__file__).resolve().parents[3]):
        candidate = base / "examples" / name
        if candidate.exists():
            return candidate
    return Path("examples") / name  # the loader reports it missing


def _check(
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


def _inputs(
    camera: Path | None, fmap: Path | None, plane: str | None = None
) -> tuple[Camera, FixtureMap]:
    """The camera and the map (the thesis' by default), refused naming the file when the
    studies cannot use them; with ``plane`` (``--plane``, for a floor or a height), the
    fixtures must lie off the floor's level, on the side that is up."""
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


def _triples(text: str, name: str) -> list[list[float]]:
    """``"x,y,z;x,y,z"`` -> list of triples, or a usage error naming ``name``."""
    parts = [p for p in text.split(";") if p.strip()]
    if not parts:
        fail(f"{name} needs at least one 'a,b,c' triple, got {text!r}")
    return [parse_floats(p, 3, name) for p in parts]


def _grid_options(
    plane: str, x: str, y: str | None, z: str | None, step: float, height: float
) -> dict:
    """The floor grid's keyword arguments (see :func:`camvlp.sim.grid.floor_grid`) from the
    options --plane, --x-range/--y-range/--z-range (the plane's two), --step and --height."""
    given = {"x": x, "y": y if y is not None else "-1,1", "z": z if z is not None else "-1,1"}
    if len(plane) != 2 or any(a not in "xyz" for a in plane) or plane[0] == plane[1]:
        fail(f"--plane must be two different axes of x, y, z (e.g. xz), got {plane!r}")
    return {
        "plane": plane,
        "u_range_m": parse_floats(given[plane[0]], 2, f"--{plane[0]}-range"),
        "v_range_m": parse_floats(given[plane[1]], 2, f"--{plane[1]}-range"),
        "step_m": step,
        "height_m": height,
    }


def _finish(study, name: str, plot, out: Path | None, as_json: bool, lines: list[str]) -> None:
    """Write the files (with --out), then print the summary as JSON or as ``lines``."""
    summary = study.summary()
    if out is not None:
        check_output_dir(out, "--out")
        with StagedOutputs() as outputs:  # the CSV, the figure and the summary: all or none
            summary = write_outputs(outputs.folder(out), name, study, plot)  # InputError: exit 2
        print(f"wrote {out}/{name}.csv, {name}.png, summary.json", file=sys.stderr)
    if as_json:
        print(strict_json(summary))
    else:
        for line in lines:
            print(line)


def _noise_options(noise_px: float, survey_error_m: float, trials: int, seed: int) -> dict:
    """The Monte Carlo noise's keyword arguments of the study functions."""
    return {"noise_px": noise_px, "survey_error_m": survey_error_m, "trials": trials, "seed": seed}


def _gravity_options(gravity: bool, sigma_deg: float, min_fixtures: int | None) -> dict:
    """The coverage study's gravity keyword arguments from --gravity, --gravity-sigma-deg and
    --min-fixtures, or a usage error naming the option at fault."""
    if min_fixtures is not None and not gravity and min_fixtures != 4:
        fail(f"--min-fixtures {min_fixtures} needs --gravity (without it a fix needs 4)")
    if min_fixtures is not None and min_fixtures not in (2, 3, 4):
        fail(f"--min-fixtures must be 2, 3 or 4, got {min_fixtures}")
    if not sigma_deg > 0:
        fail(f"--gravity-sigma-deg must be a positive number, got {sigma_deg}")
    return {"gravity": gravity, "gravity_sigma_deg": sigma_deg, "min_fixtures": min_fixtures}


def _coverage_lines(s: dict, tilt_max: float, height: float, noise_px: float) -> list[str]:
    """The coverage command's summary ``s`` as text lines."""
    how = s["solver"]
    four = ""
    if s["gravity"]:
        how = (
            f"gravity (sigma {s['gravity_sigma_deg']:g} deg), at least {s['min_fixtures']} fixtures"
        )
        four = f" (four fixtures without gravity: {s['mean_fix_fraction_four_no_gravity']:.1%})"
    return [
        f"coverage: {s['floor_points']} floor points x {s['orientations']} orientations "
        f"(tilt up to {tilt_max:g} deg), height {height:g} m, {how}",
        f"a frame lasts {s['frame_rows']:.1f} rows; fixtures must span {s['min_rows']:.1f}",
        f"fix possible: {s['mean_fix_fraction']:.1%} of poses; "
        f"{s['floor_fraction_any_fix']:.1%} of the floor for some tilt, "
        f"{s['floor_fraction_all_fix']:.1%} for every tilt{four}",
        f"error where fixed (noise {noise_px:g} px): mean {_mm(s['mean_error_m'])}, "
        f"median {_mm(s['median_error_m'])}, 95% {_mm(s['p95_error_m'])}",
    ]


def _mm(v: float | None) -> str:
    return format_length(v, "mm")


_len = format_length


def _run(func, *args, **kwargs):
    """``func(*args, **kwargs)``; a ValueError (bad value) becomes a usage error, exit 2."""
    try:
        return func(*args, **kwargs)
    except ValueError as exc:
        fail(str(exc))


#: Most pose solves one study may ask for (each keeps about 0.5 KB until the end: ~1 GB).
MAX_SOLVES = 2_000_000
#: Pose solves from which a study shows a progress bar (a run of about a second or more).
PROGRESS_FROM_POSES = 5000


def _grid_points(grid: dict) -> float:
    """Points of the floor grid that :func:`_grid_options` describes."""
    (u0, u1), (v0, v1), step = grid["u_range_m"], grid["v_range_m"], grid["step_m"]
    return ((u1 - u0) / step + 1) * ((v1 - v0) / step + 1)


def _study(func, label: str, total_hint: float, *args, **kwargs):
    """Run a study function with a progress bar (long runs on a terminal) and :func:`_run`;
    fail (exit 2) first when it would solve more than MAX_SOLVES poses (``total_hint``)."""
    if total_hint > MAX_SOLVES:
        fail(
            f"this study would solve {total_hint:,.0f} poses, over the budget of {MAX_SOLVES:,} "
            "(about 1 GB of memory); lower --trials, raise --step or --tilt-step, narrow the "
            "ranges or give fewer poses"
        )
    total_hint = int(total_hint)
    with progress_bar(None, label, show=total_hint >= PROGRESS_FROM_POSES) as update:
        return _run(func, *args, progress=update, **kwargs)


def _monte_carlo(cam, fmap, positions, eulers, solver, rounding, noise: dict, out, as_json) -> None:
    """The Monte Carlo study of the image-error and world-error commands given noise."""
    n = max(len(positions), len(eulers)) * noise["trials"]
    res = _study(
        st.monte_carlo_study,
        "Monte Carlo",
        n,
        cam,
        fmap,
        positions_m=positions,
        euler_deg=eulers,
        solver=solver,
        rounding=rounding,
        **noise,
    )
    s = res.summary()
    lines = [
        f"monte carlo: sigma {noise['noise_px']:g} px (image), {noise['survey_error_m']:g} m "
        f"(map), {s['trials']} trials per pose, {solver}",
        f"all poses: mean {_len(s['mean_error_m'])}, median {_len(s['median_error_m'])}, "
        f"95% {_len(s['p95_error_m'])}, failures {s['failures']}",
    ]
    for p in s["per_pose"]:
        lines.append(
            f"  C={tuple(p['position_m'])} theta={tuple(p['euler_deg'])}: mean "
            f"{_len(p['mean_error_m'])}, median {_len(p['median_error_m'])}, "
            f"95% {_len(p['p95_error_m'])}"
        )
    _finish(res, "monte-carlo", study_plots.plot_monte_carlo, out, as_json, lines)


# -------------------------------------------------------------------------- commands


@study_app.command("rounding")
@handle_errors
def rounding(
    camera: CameraOpt = None,
    map_path: MapOpt = None,
    euler: Annotated[
        str, typer.Option("--euler", help="Camera orientation, thesis angles 'tx,ty,tz' (deg).")
    ] = "90,0,0",
    plane: PlaneOpt = "xz",
    x_range: RangeX = "-1,1",
    y_range: RangeY = None,
    z_range: RangeZ = None,
    step: StepOpt = 0.1,
    height: HeightOpt = 0.0,
    solver: SolverOpt = "iterative",
    noise_px: NoiseOpt = 0.0,
    survey_error_m: SurveyOpt = 0.0,
    trials: Annotated[
        int, typer.Option("--trials", help="Draws per grid point (with noise).")
    ] = 20,
    seed: SeedOpt = 0,
    rounding: RoundOpt = True,
    out: OutOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Position error from pixel rounding over a grid on the floor (thesis fig. 4.2)."""
    _check(solver, noise_px, survey_error_m, trials, step=step)
    angles = parse_floats(euler, 3, "--euler")
    grid = _grid_options(plane, x_range, y_range, z_range, step, height)
    cam, fmap = _inputs(camera, map_path, plane)
    noise = _noise_options(noise_px, survey_error_m, trials, seed)
    est = _grid_points(grid) * (trials if noise_px > 0 or survey_error_m > 0 else 1)
    res = _study(
        st.rounding_study,
        "rounding study",
        est,
        cam,
        fmap,
        euler_deg=angles,
        solver=solver,
        rounding=rounding,
        **grid,
        **noise,
    )
    s = res.summary()
    lines = [
        f"rounding study: theta=({euler}) deg, height {height:g} m, {s['grid']['points']} "
        f"floor points, {solver}",
        f"mean {_mm(s['mean_error_m'])}, median {_mm(s['median_error_m'])}, "
        f"95% {_mm(s['p95_error_m'])}, max {_mm(s['max_error_m'])}, "
        f"{s['poses']} poses, {s['failures']} failures",
    ]
    _finish(res, "rounding", study_plots.plot_rounding, out, as_json, lines)


def _forced(
    kind: str,
    *,
    camera,
    map_path,
    fixture,
    axis,
    value_range,
    step,
    positions,
    eulers,
    height,
    plane,
    figure,
    solver,
    noise_px,
    survey_error_m,
    trials,
    seed,
    rounding,
    out,
    as_json,
) -> None:
    """The image-error or world-error study (``kind``) from the command's options, by name.

    With noise (--noise-px or --survey-error-m) the Monte Carlo study runs instead.
    """
    _check(solver, noise_px, survey_error_m, trials, step=step)
    axes = "xy" if kind == "image" else "xyz"
    if axis not in axes:
        fail(f"--axis must be one of {', '.join(axes)} for {kind} errors, got {axis!r}")
    if figure is not None and figure not in FIGURES:
        fail(f"--figure must be one of {', '.join(FIGURES)}, got {figure!r}")
    fig_pos, fig_eul, fig_h = FIGURES[figure or "4.3"]
    pos = _triples(positions if positions is not None else fig_pos, "--positions")
    eul = _triples(eulers if eulers is not None else fig_eul, "--eulers")
    if len(pos) > 1 and len(eul) > 1 and len(pos) != len(eul):
        fail(
            f"--positions has {len(pos)} poses and --eulers {len(eul)}: give one of them once "
            "or both the same number of times"
        )
    if height is None and figure is not None:
        height = fig_h
    cam, fmap = _inputs(camera, map_path, plane if height is not None else None)
    if height is not None:
        pos = _run(
            st.set_height, pos, fmap.positions * fmap.unit_m, plane=plane, height_m=height
        ).tolist()
    if noise_px > 0 or survey_error_m > 0:
        noise = _noise_options(noise_px, survey_error_m, trials, seed)
        _monte_carlo(cam, fmap, pos, eul, solver, rounding, noise, out, as_json)
        return
    lo, hi = parse_floats(value_range, 2, "--range")
    offsets = _run(st.axis_values, (lo, hi), step, "--range")
    res = _study(
        st.forced_error_study,
        f"{kind}-error study",
        len(offsets) * max(len(pos), len(eul)),
        cam,
        fmap,
        kind=kind,
        axis=axis,
        offsets=offsets,
        positions_m=pos,
        euler_deg=eul,
        fixture_id=fixture,
        solver=solver,
        rounding=rounding,
    )
    s = res.summary()
    unit = res.offset_unit
    lines = [
        f"{kind}-error study: fixture {res.fixture_id}, {kind} {axis} from {lo:g} to {hi:g} "
        f"{unit}, {solver}"
    ]
    for ser in s["series"]:
        r2 = ser["r2_linear"]
        lines.append(
            f"  C={tuple(ser['position_m'])} theta={tuple(ser['euler_deg'])}: error at {lo:g} "
            f"{unit} {_len(ser['error_at_min_offset_m'])}, at {hi:g} {unit} "
            f"{_len(ser['error_at_max_offset_m'])}, linear R^2 "
            + ("n/a" if r2 is None else f"{r2:.3f}")
        )
    _finish(res, f"{kind}-error", study_plots.plot_forced_error, out, as_json, lines)


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


def _forced_command(
    kind: str, axes_help: str, unit: str, default_range: str, default_step: float, doc: str
):
    """The image-error or the world-error command: the same options in other units.

    The three options that differ (``--axis``, ``--range``, ``--step``) take their help and
    defaults from the arguments; the command passes every option on to :func:`_forced`.
    """

    def command(
        camera: CameraOpt = None,
        map_path: MapOpt = None,
        fixture: FixtureOpt = None,
        axis: str = typer.Option("x", "--axis", help=axes_help),
        value_range: str = typer.Option(
            default_range, "--range", help=f"Forced error 'lo,hi' ({unit})."
        ),
        step: float = typer.Option(default_step, "--step", help=f"Forced error step ({unit})."),
        positions: PositionsOpt = None,
        eulers: EulersOpt = None,
        height: ForcedHeightOpt = None,
        plane: PlaneOpt = "xz",
        figure: FigureOpt = None,
        solver: SolverOpt = "iterative",
        noise_px: NoiseOpt = 0.0,
        survey_error_m: SurveyOpt = 0.0,
        trials: TrialsOpt = 1000,
        seed: SeedOpt = 0,
        rounding: RoundOpt = True,
        out: OutOpt = None,
        as_json: JsonOpt = False,
    ) -> None:
        options = {k: v for k, v in locals().items() if k != "kind"}
        _forced(kind, **options)

    command.__doc__ = doc
    command.__name__ = f"{kind}_error"
    return command


image_error = study_app.command("image-error")(
    handle_errors(
        _forced_command(
            "image",
            "Image axis: x or y.",
            "px",
            "-20,20",
            1.0,
            """Position error against a forced error on one fixture's image point (fig. 4.3-4.5).

    With --noise-px or --survey-error-m: Monte Carlo over every fixture instead.
    """,
        )
    )
)

world_error = study_app.command("world-error")(
    handle_errors(
        _forced_command(
            "world",
            "World axis: x, y or z.",
            "m",
            "-1,1",
            0.05,
            """Position error against a forced error on one fixture's map position (fig. 4.3-4.5).

    With --noise-px or --survey-error-m: Monte Carlo over every fixture instead.
    """,
        )
    )
)


@study_app.command("coverage")
@handle_errors
def coverage(
    camera: CameraOpt = None,
    map_path: MapOpt = None,
    plane: PlaneOpt = "xz",
    x_range: RangeX = "-1,1",
    y_range: RangeY = None,
    z_range: RangeZ = None,
    step: StepOpt = 0.1,
    height: HeightOpt = 0.0,
    euler: Annotated[
        str, typer.Option("--euler", help="Orientation with no tilt, 'tx,ty,tz' (deg).")
    ] = "90,0,0",
    tilt_max: Annotated[
        float, typer.Option("--tilt-max", help="Largest tilt about x and about y (deg).")
    ] = 15.0,
    tilt_step: Annotated[float, typer.Option("--tilt-step", help="Tilt step (deg).")] = 2.5,
    chip_rate: Annotated[
        float, typer.Option("--chip-rate", help="Line-code chips per second (Hz).")
    ] = 10_000.0,
    row_time: Annotated[
        float | None,
        typer.Option(
            "--row-time",
            help=f"Seconds per sensor row (default: camera's, or {DEFAULT_ROW_TIME_S * 1e6:g} us).",
        ),
    ] = None,
    min_frames: Annotated[
        float, typer.Option("--min-frames", help="Frames of rows a fixture must span.")
    ] = 1.2,
    diameter: Annotated[
        float | None,
        typer.Option("--diameter", help="Fixture diameter (m) where the map gives none."),
    ] = None,
    solver: SolverOpt = "iterative",
    noise_px: Annotated[
        float, typer.Option("--noise-px", help="Detection noise sigma on image points (px).")
    ] = 0.5,
    trials: Annotated[
        int, typer.Option("--trials", help="Noise draws per position and orientation.")
    ] = 1,
    seed: SeedOpt = 0,
    rounding: RoundOpt = True,
    out: OutOpt = None,
    as_json: JsonOpt = False,
    gravity: Annotated[
        bool,
        typer.Option(
            "--gravity",
            help="The camera knows which way is down (accelerometer): two or three fixtures "
            "can be enough (see --min-fixtures).",
        ),
    ] = False,
    gravity_sigma_deg: Annotated[
        float,
        typer.Option(
            "--gravity-sigma-deg", help="With --gravity: the accelerometer's error, deg per axis."
        ),
    ] = 1.0,
    min_fixtures: Annotated[
        int | None,
        typer.Option(
            "--min-fixtures", help="Fixtures a fix needs: 2, 3 or 4 with --gravity (default 2)."
        ),
    ] = None,
) -> None:
    """Where on the floor a fix is possible over a range of tilts, and its expected error."""
    grav = _gravity_options(gravity, gravity_sigma_deg, min_fixtures)
    _check(
        solver,
        noise_px,
        0.0,
        trials,
        step=step,
        tilt_step=tilt_step,
        chip_rate=chip_rate,
        **({"row_time": row_time} if row_time is not None else {}),
    )
    base = parse_floats(euler, 3, "--euler")
    grid = _grid_options(plane, x_range, y_range, z_range, step, height)
    cam, fmap = _inputs(camera, map_path, plane)
    n_tilts = (2 * int(tilt_max / tilt_step) + 1) ** 2 if tilt_step > 0 else 1
    res = _study(
        st.coverage_study,
        "coverage study",
        _grid_points(grid) * n_tilts * (trials if noise_px > 0 else 1),
        cam,
        fmap,
        base_euler_deg=base,
        tilt_max_deg=tilt_max,
        tilt_step_deg=tilt_step,
        chip_rate_hz=chip_rate,
        row_time_s=row_time,
        min_frames=min_frames,
        default_diameter_m=diameter,
        noise_px=noise_px,
        trials=trials,
        seed=seed,
        solver=solver,
        rounding=rounding,
        **grid,
        **grav,
    )
    lines = _coverage_lines(res.summary(), tilt_max, height, noise_px)
    _finish(res, "coverage", study_plots.plot_coverage, out, as_json, lines)
