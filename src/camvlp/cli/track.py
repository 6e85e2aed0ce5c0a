"""``camvlp track``: positions along a video; ``camvlp render-video``: simulated videos.

render-video's defaults of the lights' looks are the renderer's
(:class:`camvlp.sim.render.RenderSettings`), written out here so that the simulator is
imported only when a render runs (tests/cli/test_startup.py checks that they agree).
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from ._app import (
    EXIT_NOT_LOCATED,
    NearOption,
    OutlierOption,
    SolverOption,
    WithinOption,
    app,
    check_positive,
    check_solver,
    fail,
    handle_errors,
    parse_prior,
    parse_readout,
)
from .progress import progress_bar
from .render import option_names

if TYPE_CHECKING:
    from camvlp.analysis.track import TrackRun, Truths
    from camvlp.model.camera import Camera
    from camvlp.model.fixtures import FixtureMap
    from camvlp.pipeline.track.records import TrackSettings
    from camvlp.sim.render import RenderSettings
    from camvlp.sim.trajectory import Trajectory

#: The files ``camvlp track`` writes into its --out folder.
TRACK_FILES = ("trajectory.csv", "fixtures.csv", "summary.json", "trajectory.png")


@app.command("track")
@handle_errors
def track_command(
    source: Annotated[
        Path, typer.Argument(help="A video file (mp4, mov, mkv ...) or a folder of images.")
    ],
    camera_path: Annotated[Path, typer.Option("--camera", "-c", help="Camera file (YAML/JSON).")],
    map_path: Annotated[
        Path, typer.Option("--map", "-m", help="Map file of the room (YAML/JSON).")
    ],
    out: Annotated[Path, typer.Option("--out", metavar="DIR", help="Output folder.")],
    as_json: Annotated[bool, typer.Option("--json", help="Print the summary as JSON.")] = False,
    fps: Annotated[
        float | None,
        typer.Option(
            "--fps",
            help="Frames per second: the times of a folder without timestamps.csv (and of a "
            "video, instead of its own timestamps).",
        ),
    ] = None,
    start: Annotated[float, typer.Option("--start", help="Skip the frames before S s.")] = 0.0,
    frames: Annotated[
        int | None, typer.Option("--frames", help="Process at most N frames.")
    ] = None,
    solver: SolverOption = "iterative",
    readout: Annotated[
        str | None,
        typer.Option(
            help="Sensor readout: rows, columns, rows-reversed or columns-reversed (default: "
            "the camera file's, else the axis found in the first striped frame, forward)."
        ),
    ] = None,
    outlier_px: OutlierOption = None,
    rolling_shutter: Annotated[
        bool,
        typer.Option(
            "--rolling-shutter/--no-rolling-shutter",
            help="Correct each fixture for the camera's motion while the rows are read.",
        ),
    ] = True,
    gather_frames: Annotated[
        int,
        typer.Option(
            "--gather-frames",
            metavar="N",
            help="A light whose disc shows less than a frame of its code gathers the pieces "
            "it shows over its last N frames until they hold its ID (a long frame); 0 turns "
            "it off.",
        ),
    ] = 12,
    near: NearOption = None,
    within: WithinOption = None,
) -> None:
    """Track the camera along a video: its trajectory, fixtures and a plot, written to DIR.

    Writes DIR/trajectory.csv, fixtures.csv, summary.json and trajectory.png, all four or
    none. The frames that could not be located are counted by reason on stderr (every
    frame's reason is in trajectory.csv). Exit code 0 when at least one frame was located, 1
    when none was (the most frequent reason in the error line), 2 on bad input.
    """
    from camvlp.analysis.track import read_truths, run_track, summarize
    from camvlp.io import load_camera, load_map
    from camvlp.io.atomic import StagedOutputs, check_output_dir, check_output_file, strict_json
    from camvlp.io.video import open_frames
    from camvlp.pipeline.track.tracker import Tracker

    check_positive(fps, "--fps")
    settings = _settings(solver, readout, outlier_px, near, within, rolling_shutter, gather_frames)
    check_output_dir(out, "--out")
    for name in TRACK_FILES if out.is_dir() else ():
        check_output_file(out / name, "--out")
    camera = load_camera(camera_path)
    fixture_map = load_map(map_path)
    frames_src = open_frames(
        source, fps=fps, start_s=start, max_frames=frames, threads=0, gray=True
    )
    truths = read_truths(frames_src)  # before any frame: a bad truth file stops nothing midway
    tracker = Tracker(camera, fixture_map, settings)
    total = frames_src.total if frames is None else min(frames, frames_src.total or frames)
    with StagedOutputs() as outputs:  # the four files: all or none
        staged = outputs.folder(out)
        with progress_bar(total, "tracking") as update:
            run = run_track(frames_src, tracker, staged, progress=update)
        summary = summarize(run, truths)
        summary["input"] = str(source)
        (staged / "summary.json").write_text(strict_json(summary, indent=2) + "\n")
        _plot(staged / "trajectory.png", fixture_map, run, truths)
    located = summary["fix"] + summary["tracked"]
    reasons = summary["not_located"]
    if not located:  # the warnings are in summary.json; the reasons, unless one says all
        why, where = "no frame could be located", str(source)
        if not summary["frames"]:  # nothing was read: say why rather than "not located"
            why = f"no frame at or after --start {start:g} s" if start else "no frame was read"
            if run.warnings:
                why += f": {run.warnings[0]}"
        elif reasons:
            if len(reasons) > 1:
                _print_reasons(reasons, summary["frames"], out)
            why += f": {reasons[0]['reason']}"
            where = f"{reasons[0]['frames']} of {summary['frames']} frames; {source}"
        print(f"error: {why} ({where})", file=sys.stderr)
        raise typer.Exit(EXIT_NOT_LOCATED)
    for w in run.warnings:
        print(f"warning: {w} ({source})", file=sys.stderr)
    if reasons:
        _print_reasons(reasons, summary["frames"], out)
    if as_json:
        print(strict_json(summary))
    else:
        _print_human(summary, fixture_map.units, out)


#: Reasons that track's note on the frames not located lists one by one (the rest counted).
SHOWN_REASONS = 5


def _print_reasons(reasons: list[dict], frames: int, out: Path) -> None:
    """The frames not located and why, on stderr: a line per reason with its count of frames,
    the most frequent first (``reasons`` as :func:`camvlp.analysis.track.summarize` gives
    them), at most :data:`SHOWN_REASONS`, the others counted in a last line."""
    missed = sum(r["frames"] for r in reasons)
    width = len(str(reasons[0]["frames"]))
    lines = [f"note: {missed} of {frames} frames not located:"]
    lines += [f"  {r['frames']:>{width}}  {r['reason']}" for r in reasons[:SHOWN_REASONS]]
    rest = reasons[SHOWN_REASONS:]
    if rest:
        lines.append(
            f"  {sum(r['frames'] for r in rest):>{width}}  for {len(rest)} other reasons "
            f"(the column reason of {out / 'trajectory.csv'})"
        )
    print("\n".join(lines), file=sys.stderr)


def _settings(
    solver: str,
    readout: str | None,
    outlier_px: float | None,
    near: str | None,
    within: float | None,
    rolling_shutter: bool,
    gather_frames: int,
) -> TrackSettings:
    """The tracker's settings from ``camvlp track``'s options (a usage error for a bad one)."""
    from camvlp.pipeline.locate import LocateSettings
    from camvlp.pipeline.track.tracker import TrackSettings

    check_solver(solver)
    check_positive(outlier_px, "--outlier-px")
    if gather_frames < 0:
        fail(f"--gather-frames must be 0 or more, got {gather_frames}")
    prior_near, prior_within = parse_prior(near, within)
    locate = LocateSettings(
        solver=solver,
        readout=parse_readout(readout),
        outlier_px=outlier_px,
        near=prior_near,
        within=prior_within,
    )
    return TrackSettings(
        locate=locate, rolling_shutter=rolling_shutter, gather_frames=gather_frames
    )


def _plot(path: Path, fixture_map: FixtureMap, run: TrackRun, truths: Truths) -> None:
    """The trajectory's plot: each frame's position by its status, the raw solves, the truth."""
    import numpy as np

    from camvlp.viz.trajectory import plot_trajectory

    nan3 = np.full(3, np.nan)
    pos = np.array([f.position if f.position is not None else nan3 for f in run.frames])
    raw = np.array([f.raw_position if f.raw_position is not None else nan3 for f in run.frames])
    truth = None
    if truths.poses is not None:
        t = truths.poses
        truth = np.array([t[n][:3] if n in t else nan3 for n in run.names])
    plot_trajectory(
        path,
        fixture_map,
        pos.reshape(-1, 3),
        [f.status for f in run.frames],
        raw_positions=raw.reshape(-1, 3),
        truth=truth,
        times=np.array([f.t for f in run.frames]),
    )


def _print_human(summary: dict, units: str, out: Path) -> None:
    n = summary["frames"]
    print(
        f"frames        {n}: {summary['fix']} fix, {summary['tracked']} tracked, "
        f"{summary['predicted']} predicted, {summary['lost']} lost "
        f"({100 * summary['fix_or_tracked_rate']:.1f} % fix or tracked)"
    )
    if summary.get("frames_per_second"):
        print(
            f"speed         {summary['frames_per_second']:.1f} frames/s "
            f"({100 * summary['reading_share']:.0f} % reading the frames)"
        )
    err = summary.get("errors")
    if err and err.get("position_rmse") is not None:
        raw = err.get("raw_position_rmse")
        print(
            f"error         position RMSE {1e3 * err['position_rmse']:.1f} m{units} filtered, "
            + (f"{1e3 * raw:.1f} m{units} raw" if raw is not None else "no raw solve")
        )
    if "wrong_ids" in summary:
        print(f"IDs           {summary['wrong_ids']} wrong of {summary['ids_checked']} given")
    print(f"written       {out}/trajectory.csv, fixtures.csv, summary.json, trajectory.png")


@app.command("render-video")
@handle_errors
def render_video_command(
    camera_path: Annotated[Path, typer.Option("--camera", help="Camera file (YAML/JSON).")],
    map_path: Annotated[Path, typer.Option("--map", help="Map file of the fixtures.")],
    trajectory_path: Annotated[
        Path,
        typer.Option(
            "--trajectory", help="CSV with t,x,y,z,theta_x,theta_y,theta_z (s, map units, degrees)."
        ),
    ],
    out: Annotated[
        Path,
        typer.Option("--out", help="A video (.mp4, .mov, .mkv: H.264) or a folder of PNG frames."),
    ],
    fps: Annotated[float, typer.Option("--fps", help="Frames per second.")] = 30.0,
    chip_rate: Annotated[float, typer.Option("--chip-rate", help="Chips per second.")] = 10000.0,
    row_time: Annotated[
        float | None,
        typer.Option("--row-time", help="Seconds between sensor rows (default: camera file)."),
    ] = None,
    exposure: Annotated[
        float | None, typer.Option("--exposure", help="Row exposure, s (default: half a chip).")
    ] = None,
    crf: Annotated[
        int, typer.Option("--crf", help="H.264 quality: 0 lossless ... 51 (default 10).")
    ] = 10,
    frames: Annotated[int | None, typer.Option("--frames", help="At most N frames.")] = None,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the LED phases and noise.")] = 0,
    brightness: Annotated[
        float, typer.Option("--brightness", help="LED level, in sensor full scales (>1 clips).")
    ] = 4.0,
    off_level: Annotated[
        float, typer.Option("--off-level", help="LED light when off, fraction of on (0 to 1).")
    ] = 0.0,
    core: Annotated[
        float, typer.Option("--core", help="Hot core: centre 1 + X times as bright as the rim.")
    ] = 0.0,
    halo: Annotated[
        float, typer.Option("--halo", help="Glow around each lamp, fraction of its level.")
    ] = 0.0,
    soft: Annotated[
        float, typer.Option("--soft", help="Soft stripes: waveform smoothed over X chips.")
    ] = 0.0,
    blur: Annotated[float, typer.Option("--blur", help="Optical blur sigma, pixels.")] = 0.8,
    vignetting: Annotated[
        float, typer.Option("--vignetting", help="Fraction of light lost at the corners (0 to 1).")
    ] = 0.0,
    bayer: Annotated[
        bool, typer.Option("--bayer", help="One colour per pixel (RGGB mosaic), demosaiced.")
    ] = False,
    gamma: Annotated[
        float, typer.Option("--gamma", help="Tone curve x^(1/G) (1 linear, 2.2 ~ sRGB).")
    ] = 1.0,
    sharpen: Annotated[
        float, typer.Option("--sharpen", help="Unsharp-mask sharpening amount.")
    ] = 0.0,
    black_point: Annotated[
        float,
        typer.Option("--black-point", help="Light stored as black, fraction of full scale."),
    ] = 0.0,
    readout: Annotated[
        str | None,
        typer.Option("--readout", help="rows, columns, rows-reversed or columns-reversed."),
    ] = None,
) -> None:
    """Render a rolling-shutter video of a camera moving along a trajectory, with its truth.

    Each sensor row is seen from the pose at its own time, and the true trajectory is
    written beside the video; the lights look as in `camvlp render` (off level, hot core,
    halo, soft stripes, blur, a phone's processing, readout)."""
    from camvlp.io import load_camera, load_map
    from camvlp.sim.render import RenderSettings, check_render_size
    from camvlp.sim.video import check_frame_budget, check_video_size, frame_count, load_trajectory

    _check_render_options(fps, chip_rate, row_time, exposure, crf, frames, seed)
    _check_video_out(out)
    camera = load_camera(camera_path)
    check_render_size(camera, camera_path)
    fixture_map = load_map(map_path)
    trajectory = load_trajectory(trajectory_path)
    look = dict(
        brightness=brightness,
        off_level=off_level,
        core=core,
        halo=halo,
        soft=soft,
        blur_px=blur,
        vignetting=vignetting,
        bayer=bayer,
        gamma=gamma,
        sharpen=sharpen,
        black_point=black_point,
    )
    try:
        settings = RenderSettings(
            chip_rate_hz=chip_rate,
            row_time_s=row_time,
            exposure_s=exposure,
            seed=seed,
            readout=parse_readout(readout) or camera.readout or "rows",
            **look,
        )
    except ValueError as exc:
        fail(option_names(str(exc)))
    if any(f.diameter is None for f in fixture_map.fixtures):
        fail(f"every fixture needs a diameter to be rendered ({map_path})")
    total = frame_count(trajectory, fps, frames)
    check_frame_budget(total, trajectory_path)
    if out.suffix:
        check_video_size(camera, camera_path)
    n = _render(camera, fixture_map, trajectory, out, fps, settings, crf, frames, total)
    print(f"wrote {n} frames to {out} ({n / fps:.2f} s at {fps:g} frames/s)")


def _check_render_options(
    fps: float,
    chip_rate: float,
    row_time: float | None,
    exposure: float | None,
    crf: int,
    frames: int | None,
    seed: int,
) -> None:
    """render-video's numbers in range, else one line of error (exit 2)."""
    check_positive(fps, "--fps")
    check_positive(chip_rate, "--chip-rate")
    check_positive(row_time, "--row-time")
    check_positive(exposure, "--exposure")
    if not 0 <= crf <= 51:
        fail(f"--crf must be from 0 to 51, got {crf}")
    if frames is not None and frames < 1:
        fail(f"--frames must be at least 1, got {frames}")
    if seed < 0:
        fail(f"--seed must be a non-negative integer, got {seed}")


def _check_video_out(out: Path) -> None:
    """render-video's --out: a video (its truth files beside it) or a folder, where each of
    those files can be written; else one line of error (exit 2)."""
    from camvlp.io.atomic import check_output_dir, check_output_file
    from camvlp.sim.video import VIDEO_SUFFIXES, truth_paths

    if out.suffix and out.suffix.lower() not in VIDEO_SUFFIXES:
        fail(f"--out must be a .mp4, .mov or .mkv video or a folder ({out})")
    if out.suffix:  # the video and its truth beside it
        for path in (out, *truth_paths(out)):
            check_output_file(path, "--out")
    else:
        check_output_dir(out, "--out")
        for path in (out / "timestamps.csv", *truth_paths(out)) if out.is_dir() else ():
            check_output_file(path, "--out")


def _render(
    camera: Camera,
    fixture_map: FixtureMap,
    trajectory: Trajectory,
    out: Path,
    fps: float,
    settings: RenderSettings,
    crf: int,
    frames: int | None,
    total: int,
) -> int:
    """Render the video (or frames) with a progress bar; the number of frames written.  On
    Ctrl-C, where the frames so far were kept."""
    from camvlp.sim.video import partial_path, render_video

    try:
        with progress_bar(total, "rendering") as update:
            return render_video(
                camera,
                fixture_map,
                trajectory,
                out,
                fps=fps,
                settings=settings,
                crf=crf,
                max_frames=frames,
                progress=update,
            )
    except KeyboardInterrupt:
        kept = partial_path(out)  # (a video's: a folder of frames has none)
        if kept.is_file():
            fail(f"interrupted: the frames so far are in {kept}", 130)
        raise
