"""``camvlp render``: a simulated rolling-shutter photograph and its ground truth.

The options' defaults are the renderer's (:class:`camvlp.sim.render.RenderSettings`), written
out here so that the simulator is imported only when a render runs (tests/cli/test_startup.py
checks that they agree).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from camvlp.model.readout import DEFAULT_ROW_TIME_S, Readout

from ._app import app, fail, handle_errors, parse_floats, parse_readout

if TYPE_CHECKING:
    from camvlp.model.camera import Camera, Pose
    from camvlp.model.fixtures import FixtureMap
    from camvlp.sim.render import Render, RenderSettings


@app.command("render")
@handle_errors
def render_command(
    camera_path: Annotated[
        Path, typer.Option("--camera", help="Camera file (OpenCV calibration YAML or JSON).")
    ],
    map_path: Annotated[Path, typer.Option("--map", help="Map file of the fixtures (YAML/JSON).")],
    position: Annotated[str, typer.Option("--position", help="Camera centre X,Y,Z in map units.")],
    euler: Annotated[
        str,
        typer.Option(
            "--euler",
            help="The thesis' angles TX,TY,TZ in degrees (R = Rx Ry Rz); 90,0,0 "
            "looks along world -y.",
        ),
    ],
    out: Annotated[Path, typer.Option("--out", help="Output photo, .png or .jpg.")],
    chip_rate: Annotated[
        str, typer.Option("--chip-rate", metavar="HZ", help="Manchester chips per second.")
    ] = "10000",
    row_time: Annotated[
        str | None,
        typer.Option(
            "--row-time",
            metavar="S",
            help="Seconds between sensor rows (default: camera file, else "
            f"{DEFAULT_ROW_TIME_S * 1e6:g} us).",
        ),
    ] = None,
    exposure: Annotated[
        str | None,
        typer.Option(
            "--exposure", metavar="S", help="Row exposure time, s (default: half a chip)."
        ),
    ] = None,
    brightness: Annotated[
        str,
        typer.Option(
            "--brightness", metavar="X", help="LED irradiance / sensor full scale (>1 saturates)."
        ),
    ] = "4",
    ambient: Annotated[
        str, typer.Option("--ambient", metavar="X", help="Background, fraction of full scale.")
    ] = "0.03",
    off_level: Annotated[
        str,
        typer.Option(
            "--off-level", metavar="X", help="LED light when off, fraction of on (0 to 1)."
        ),
    ] = "0",
    core: Annotated[
        str,
        typer.Option(
            "--core", metavar="X", help="Hot core: centre 1 + X times as bright as the rim."
        ),
    ] = "0",
    core_offset: Annotated[
        str,
        typer.Option(
            "--core-offset",
            metavar="F",
            help="Hot core's centre F radii off the disc's centre (0 to 1), "
            "each lamp its own direction.",
        ),
    ] = "0",
    halo: Annotated[
        str,
        typer.Option("--halo", metavar="X", help="Glow around each lamp, fraction of its level."),
    ] = "0",
    soft: Annotated[
        str,
        typer.Option(
            "--soft", metavar="X", help="Soft stripes: waveform smoothed over X periods (chips)."
        ),
    ] = "0",
    blur: Annotated[
        str, typer.Option("--blur", metavar="PX", help="Optical blur sigma, pixels.")
    ] = "0.8",
    noise: Annotated[
        str, typer.Option("--noise", metavar="X", help="Scale of shot and read noise (0 = none).")
    ] = "1",
    vignetting: Annotated[
        str,
        typer.Option(
            "--vignetting", metavar="X", help="Fraction of light lost at the corners (0 to 1)."
        ),
    ] = "0",
    bayer: Annotated[
        bool, typer.Option("--bayer", help="One colour per pixel (RGGB mosaic), demosaiced.")
    ] = False,
    gamma: Annotated[
        str,
        typer.Option("--gamma", metavar="G", help="Tone curve x^(1/G) (1 linear, 2.2 ~ sRGB)."),
    ] = "1",
    sharpen: Annotated[
        str, typer.Option("--sharpen", metavar="X", help="Unsharp-mask sharpening amount.")
    ] = "0",
    black_point: Annotated[
        str,
        typer.Option(
            "--black-point", metavar="X", help="Light stored as black, fraction of full scale."
        ),
    ] = "0",
    readout: Annotated[
        str | None,
        typer.Option(
            "--readout",
            help="rows (stripes horizontal), columns (portrait, stripes vertical), "
            "rows-reversed or columns-reversed (default: camera file, else rows).",
        ),
    ] = None,
    colour: Annotated[
        bool, typer.Option("--colour", help="Give each fixture its own colour.")
    ] = False,
    data_lights: Annotated[
        str | None,
        typer.Option(
            "--data-lights",
            metavar="ID,ID",
            help="These map fixtures send random data (Manchester chips at --chip-rate), "
            "not their ID.",
        ),
    ] = None,
    stamp: Annotated[
        str | None,
        typer.Option(
            "--stamp",
            metavar="TEXT",
            help="Text burned into the photo's bottom-right corner (e.g. a date and time).",
        ),
    ] = None,
    seed: Annotated[
        str, typer.Option("--seed", metavar="N", help="Seed of phases and noise.")
    ] = "0",
    quality: Annotated[
        str, typer.Option("--quality", metavar="Q", help="JPEG quality, 1 to 100.")
    ] = "95",
) -> None:
    """Render a photograph of the map's fixtures from a camera pose, with its truth JSON."""
    from camvlp.io import load_camera, load_map
    from camvlp.io.atomic import check_output_file
    from camvlp.io.writers import IMAGE_SUFFIXES
    from camvlp.model.camera import Pose
    from camvlp.sim.render import RenderSettings, check_render_size, distinct_colours

    if out.suffix.lower() not in IMAGE_SUFFIXES:
        fail(f"--out must end in {', '.join(IMAGE_SUFFIXES)} ({out})")
    check_output_file(out, "--out")
    check_output_file(out.with_suffix(".json"), "--out's truth file")
    jpeg_quality = _integer(quality, "--quality")
    if not 1 <= jpeg_quality <= 100:
        fail(f"--quality must be from 1 to 100, got {quality}")
    noise_scale = _number(noise, "--noise")
    if noise_scale < 0:
        fail(f"--noise must be a non-negative number, got {noise}")
    given_readout = parse_readout(readout)
    xyz = parse_floats(position, 3, "--position")
    angles = parse_floats(euler, 3, "--euler")
    camera = load_camera(camera_path)
    check_render_size(camera, camera_path)
    fixture_map = load_map(map_path)
    try:
        settings = RenderSettings(
            chip_rate_hz=_number(chip_rate, "--chip-rate"),
            row_time_s=None if row_time is None else _number(row_time, "--row-time"),
            exposure_s=None if exposure is None else _number(exposure, "--exposure"),
            brightness=_number(brightness, "--brightness"),
            ambient=_number(ambient, "--ambient"),
            off_level=_number(off_level, "--off-level"),
            core=_number(core, "--core"),
            core_offset=_number(core_offset, "--core-offset"),
            halo=_number(halo, "--halo"),
            soft=_number(soft, "--soft"),
            blur_px=_number(blur, "--blur"),
            **_noise_settings(noise_scale),
            vignetting=_number(vignetting, "--vignetting"),
            bayer=bayer,
            gamma=_number(gamma, "--gamma"),
            sharpen=_number(sharpen, "--sharpen"),
            black_point=_number(black_point, "--black-point"),
            readout=given_readout or camera.readout or Readout.ROWS,
            colours=distinct_colours(len(fixture_map.fixtures)) if colour else None,
            data_lights=_ids(data_lights, "--data-lights"),
            stamp=stamp,
            seed=_integer(seed, "--seed"),
        )
        pose = Pose.from_euler(xyz, angles)
    except ValueError as exc:
        fail(option_names(str(exc)))
    result = _render_or_fail(camera, fixture_map, pose, settings, map_path)
    _save(result, out, jpeg_quality)
    _print_render(result, camera, out, out.with_suffix(".json"))


def _save(result: Render, out: Path, jpeg_quality: int) -> None:
    """Write the photo ``out`` and its truth JSON beside it: both or neither."""
    from camvlp.io.atomic import StagedOutputs
    from camvlp.io.writers import save_render

    with StagedOutputs() as outputs:
        staged = outputs.folder(out.parent)
        try:
            save_render(result, staged / out.name, jpeg_quality=jpeg_quality)
        except ValueError as exc:
            fail(str(exc).replace(str(staged / out.name), str(out)))


def _noise_settings(scale: float) -> dict[str, float]:
    """Full well and read noise for ``--noise`` (0 = no noise, 1 = the default sensor)."""
    from camvlp.sim.render import RenderSettings

    base = RenderSettings()
    return {
        "full_well_e": base.full_well_e / scale**2 if scale > 0 else 0.0,
        "read_noise": base.read_noise * scale,
    }


def _print_render(result: Render, camera: Camera, out: Path, json_path: Path) -> None:
    """What was written, the timing used and where each fixture landed."""
    from camvlp.format import format_number

    s = result.settings
    print(
        f"wrote {out} ({camera.width} x {camera.height}) and {json_path}; "
        f"row time {s.row_time_s * 1e6:g} us, exposure {s.exposure_s * 1e6:g} us, "
        f"readout {s.readout}"
    )
    shown = [t for t in result.fixtures if _near_the_picture(t, camera)]
    for t in shown:
        u, v = (format_number(c, ".1f") for c in t.pixel)
        where = f"pixel ({u}, {v})" if t.in_front else "behind the camera"
        print(
            f"fixture {t.id:>3}: {where}, fully inside {'yes' if t.fully_inside else 'no'}, "
            f"{t.rows_spanned:.0f} rows, {t.frames_spanned:.2f} frames"
            + (", sends data" if t.sends_data else "")
        )
    if len(shown) < len(result.fixtures):
        rest = len(result.fixtures) - len(shown)
        print(f"{rest} other fixture{'s' if rest != 1 else ''} of the map out of the picture")
    if result.stamp_box is not None:
        u0, v0, u1, v1 = result.stamp_box
        print(f"stamp {s.stamp!r}: pixels {u0} to {u1 - 1} across, {v0} to {v1 - 1} down")


def _near_the_picture(t, camera: Camera) -> bool:
    """Whether a fixture's truth is worth a line: in front of the camera, its centre within
    the picture or within its disc's extent (its rows) of it; a large site's others are
    only counted."""
    if not t.in_front:
        return False
    u, v = t.pixel
    pad = t.rows_spanned if math.isfinite(t.rows_spanned) else 0.0
    return -pad <= u <= camera.width + pad and -pad <= v <= camera.height + pad


def _number(text: str, option: str) -> float:
    """A finite float from an option's text, or fail naming the option."""
    try:
        value = float(text)
    except ValueError:
        fail(f"{option} must be a number, got {text!r}")
    if not math.isfinite(value):
        fail(f"{option} must be a finite number, got {text!r}")
    return value


def _integer(text: str, option: str) -> int:
    """An integer from an option's text, or fail naming the option."""
    try:
        return int(text)
    except ValueError:
        fail(f"{option} must be an integer, got {text!r}")


def _ids(text: str | None, option: str) -> tuple[int, ...]:
    """Fixture IDs from an option's comma-separated text (none for None), or fail naming the
    option."""
    if text is None:
        return ()
    try:
        return tuple(int(part) for part in text.split(","))
    except ValueError:
        fail(f"{option} must be fixture IDs separated by commas, got {text!r}")


def _render_or_fail(
    camera: Camera,
    fixture_map: FixtureMap,
    pose: Pose,
    settings: RenderSettings,
    map_path: Path,
) -> Render:
    """Render, or fail with one line when the pose or the map cannot be rendered."""
    from camvlp.sim.render import render

    try:
        result = render(camera, fixture_map, pose, settings)
    except ValueError as exc:
        fail(f"{option_names(str(exc))} ({map_path})")
    if not any(t.in_front for t in result.fixtures):
        fail(f"every fixture is behind the camera; check --position and --euler ({map_path})")
    return result


_OPTIONS = {
    "chip_rate_hz": "--chip-rate",
    "row_time_s": "--row-time",
    "exposure_s": "--exposure",
    "brightness": "--brightness",
    "ambient": "--ambient",
    "off_level": "--off-level",
    "core": "--core",
    "core_offset": "--core-offset",
    "halo": "--halo",
    "soft": "--soft",
    "blur_px": "--blur",
    "full_well_e": "--noise",
    "read_noise": "--noise",
    "vignetting": "--vignetting",
    "gamma": "--gamma",
    "sharpen": "--sharpen",
    "black_point": "--black-point",
    "data_lights": "--data-lights",
    "stamp": "--stamp",
    "tone_gamma": "--tone-gamma",
    "seed": "--seed",
    "position": "--position",
}


def option_names(message: str) -> str:
    """Name the command-line option instead of the library's argument in a message."""
    for name, option in _OPTIONS.items():
        if message.startswith(name + " "):
            return option + message[len(name) :]
    return message
