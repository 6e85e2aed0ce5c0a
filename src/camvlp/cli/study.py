"""``camvlp study``: the thesis' error study (chapter 4) and a coverage planner.

The commands' options and their checks are in :mod:`camvlp.cli._study_options`; running a
study (its budget, progress bar, files and summary) in :mod:`camvlp.cli._study_run`.  The
studies (:mod:`camvlp.analysis.study`) and their plots (:mod:`camvlp.viz.study_plots`) are
imported when a command runs.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from camvlp.model.readout import DEFAULT_ROW_TIME_S

from ._app import app, fail, handle_errors, parse_floats
from ._study_options import (
    FIGURES,
    CameraOpt,
    EulersOpt,
    FigureOpt,
    FixtureOpt,
    ForcedHeightOpt,
    HeightOpt,
    JsonOpt,
    MapOpt,
    NoiseOpt,
    OutOpt,
    PlaneOpt,
    PositionsOpt,
    RangeX,
    RangeY,
    RangeZ,
    RoundOpt,
    SeedOpt,
    SolverOpt,
    StepOpt,
    SurveyOpt,
    TrialsOpt,
    check_study_options,
    gravity_options,
    grid_options,
    grid_point_count,
    load_inputs,
    noise_options,
    parse_triples,
)
from ._study_run import finish_study, run_study, usage_errors

if TYPE_CHECKING:
    from camvlp.analysis.study import ForcedErrorStudy
    from camvlp.model.camera import Camera
    from camvlp.model.fixtures import FixtureMap

study_app = typer.Typer(
    name="study",
    help="Error study (thesis chapter 4) and deployment planning, geometry only.",
    no_args_is_help=True,
)
app.add_typer(study_app, name="study")


# --------------------------------------------------------------------------- helpers


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
        *_site_lines(s),
    ]


def _site_lines(s: dict) -> list[str]:
    """For a map whose IDs repeat: the fixtures poses see, and the views left ambiguous."""
    if not s["reuse"]:
        return []
    seeing = ", ".join(f"{k}+ {v:.1%}" for k, v in s["poses_seeing_at_least"].items())
    return [
        f"IDs reused: a pose is placed by its fixtures' IDs and arrangement; poses seeing {seeing}",
        f"{s['ambiguous_views']} poses with fixtures enough for a pose were too few or ambiguous "
        "to place",
    ]


def _mm(v: float | None) -> str:
    """A length (m) in millimetres ("n/a" for None or NaN)."""
    from camvlp.format import format_length

    return format_length(v, "mm")


def _len(v: float | None) -> str:
    """A length (m) in the unit that suits it ("n/a" for None or NaN)."""
    from camvlp.format import format_length

    return format_length(v)


def _monte_carlo(
    cam: Camera,
    fmap: FixtureMap,
    positions: list[list[float]],
    eulers: list[list[float]],
    solver: str,
    rounding: bool,
    noise: dict,
    out: Path | None,
    as_json: bool,
) -> None:
    """The Monte Carlo study of the image-error and world-error commands given noise."""
    from camvlp.analysis import study as st
    from camvlp.viz import study_plots

    n = max(len(positions), len(eulers)) * noise["trials"]
    res = run_study(
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
    finish_study(res, "monte-carlo", study_plots.plot_monte_carlo, out, as_json, lines)


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
    x_range: RangeX = None,
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
    from camvlp.analysis import study as st
    from camvlp.viz import study_plots

    check_study_options(solver, noise_px, survey_error_m, trials, step=step)
    angles = parse_floats(euler, 3, "--euler")
    grid = grid_options(plane, x_range, y_range, z_range, step, height)
    cam, fmap = load_inputs(camera, map_path, plane)
    noise = noise_options(noise_px, survey_error_m, trials, seed)
    est = grid_point_count(grid) * (trials if noise_px > 0 or survey_error_m > 0 else 1)
    res = run_study(
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
    finish_study(res, "rounding", study_plots.plot_rounding, out, as_json, lines)


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
    from camvlp.analysis import study as st
    from camvlp.viz import study_plots

    check_study_options(solver, noise_px, survey_error_m, trials, step=step)
    axes = "xy" if kind == "image" else "xyz"
    if axis not in axes:
        fail(f"--axis must be one of {', '.join(axes)} for {kind} errors, got {axis!r}")
    if figure is not None and figure not in FIGURES:
        fail(f"--figure must be one of {', '.join(FIGURES)}, got {figure!r}")
    fig_pos, fig_eul, fig_h = FIGURES[figure or "4.3"]
    pos = parse_triples(positions if positions is not None else fig_pos, "--positions")
    eul = parse_triples(eulers if eulers is not None else fig_eul, "--eulers")
    if len(pos) > 1 and len(eul) > 1 and len(pos) != len(eul):
        fail(
            f"--positions has {len(pos)} poses and --eulers {len(eul)}: give one of them once "
            "or both the same number of times"
        )
    if height is None and figure is not None:
        height = fig_h
    cam, fmap = load_inputs(camera, map_path, plane if height is not None else None)
    if height is not None:
        pos = usage_errors(
            st.set_height, pos, fmap.positions * fmap.unit_m, plane=plane, height_m=height
        ).tolist()
    if noise_px > 0 or survey_error_m > 0:
        noise = noise_options(noise_px, survey_error_m, trials, seed)
        _monte_carlo(cam, fmap, pos, eul, solver, rounding, noise, out, as_json)
        return
    lo, hi = parse_floats(value_range, 2, "--range")
    offsets = usage_errors(st.axis_values, (lo, hi), step, "--range")
    res = run_study(
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
    lines = _forced_lines(res, kind, axis, lo, hi, solver)
    finish_study(res, f"{kind}-error", study_plots.plot_forced_error, out, as_json, lines)


def _forced_lines(
    res: ForcedErrorStudy, kind: str, axis: str, lo: float, hi: float, solver: str
) -> list[str]:
    """The image-error or world-error study ``res``'s summary as text lines."""
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
    return lines


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
    x_range: RangeX = None,
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
    from camvlp.analysis import study as st
    from camvlp.viz import study_plots

    grav = gravity_options(gravity, gravity_sigma_deg, min_fixtures)
    check_study_options(
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
    grid = grid_options(plane, x_range, y_range, z_range, step, height)
    cam, fmap = load_inputs(camera, map_path, plane)
    n_tilts = (2 * int(tilt_max / tilt_step) + 1) ** 2 if tilt_step > 0 else 1
    res = run_study(
        st.coverage_study,
        "coverage study",
        grid_point_count(grid) * n_tilts * (trials if noise_px > 0 else 1),
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
    finish_study(res, "coverage", study_plots.plot_coverage, out, as_json, lines)
