"""``camvlp locate``: photograph -> camera position."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from camvlp.errors import InputError

from ._app import (
    EXIT_NOT_LOCATED,
    GravitySigmaOption,
    MaxSigmaOption,
    NearOption,
    OutlierOption,
    SolverOption,
    WithinOption,
    app,
    check_positive,
    check_solver,
    fail,
    handle_errors,
    parse_gravity,
    parse_prior,
    parse_readout,
)
from .render import option_names

if TYPE_CHECKING:
    import numpy as np

    from camvlp.model.camera import Camera
    from camvlp.model.fixtures import FixtureMap
    from camvlp.pipeline.locate import LocateResult


@app.command("locate")
@handle_errors
def locate_command(
    photo: Annotated[Path, typer.Argument(help="The photograph (JPEG, PNG, TIFF ...).")],
    camera_path: Annotated[Path, typer.Option("--camera", "-c", help="Camera file (YAML/JSON).")],
    map_path: Annotated[
        Path, typer.Option("--map", "-m", help="Map file of the room (YAML/JSON).")
    ],
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    annotate_path: Annotated[
        Path | None, typer.Option("--annotate", help="Write the annotated photo here (.png/.jpg).")
    ] = None,
    debug_dir: Annotated[
        Path | None, typer.Option("--debug-dir", help="Write one picture per stage here.")
    ] = None,
    solver: SolverOption = "iterative",
    readout: Annotated[
        str | None,
        typer.Option(
            help="Sensor readout: rows (top down), columns (left to right), rows-reversed or "
            "columns-reversed (default: the camera file's, else the axis the stripes show, its "
            "direction the photo's EXIF orientation's where it agrees, else found from the "
            "IDs)."
        ),
    ] = None,
    mirrored: Annotated[
        bool | None,
        typer.Option(
            "--mirrored/--not-mirrored", help="The photo is a mirror image: flip it first."
        ),
    ] = None,
    outlier_px: OutlierOption = None,
    max_sigma: MaxSigmaOption = None,
    tone_gamma: Annotated[
        float | None,
        typer.Option(
            "--tone-gamma",
            metavar="G",
            help="The camera's tone curve, as the camera file's tone_gamma (about 2.2 for a "
            "phone's JPEG; default: the camera file's, else levels taken as light).",
        ),
    ] = None,
    gravity: Annotated[
        str | None,
        typer.Option(
            "--gravity",
            help="Gravity in the camera frame, GX,GY,GZ (x right, y down, z forward; any "
            "length): two or three fixtures are then enough. Default: PHOTO.json's, if any.",
        ),
    ] = None,
    gravity_sigma_deg: GravitySigmaOption = None,
    near: NearOption = None,
    within: WithinOption = None,
) -> None:
    """Locate the camera that took PHOTO: position, orientation, fixtures seen.

    Exit code 0 when located, 1 when the photo could not be located (the reason is printed,
    and with --json the object still lists the fixtures), 2 on bad input.
    """
    from camvlp.io import decode_image, exif_readout, load_camera, load_map, load_sidecar
    from camvlp.io.atomic import check_output_dir, check_output_file, strict_json
    from camvlp.io.images import read_photo
    from camvlp.pipeline.locate import LocateSettings, locate

    check_solver(solver)
    check_positive(outlier_px, "--outlier-px")
    check_positive(max_sigma, "--max-sigma")
    check_positive(gravity_sigma_deg, "--gravity-sigma-deg")
    g = parse_gravity(gravity)
    prior_near, prior_within = parse_prior(near, within)
    given_readout = parse_readout(readout)
    if annotate_path is not None:
        check_output_file(annotate_path, "--annotate", (".png", ".jpg", ".jpeg"))
    if debug_dir is not None:
        check_output_dir(debug_dir, "--debug-dir")
    camera = load_camera(camera_path)
    if tone_gamma is not None:
        try:
            camera = dataclasses.replace(camera, tone_gamma=tone_gamma)
        except ValueError as exc:
            fail(option_names(str(exc)))
    fixture_map = load_map(map_path)
    raw = read_photo(photo)  # read once: decoded here, its EXIF read below
    image = decode_image(raw, photo)
    sidecar = load_sidecar(photo) if g is None else None
    if sidecar is not None:
        g = sidecar.gravity
        if gravity_sigma_deg is None:
            gravity_sigma_deg = sidecar.gravity_sigma_deg
    settings = LocateSettings(
        solver=solver,
        readout=given_readout,
        # a phone's orientation tag: a hint the stripes must bear out
        readout_hint=exif_readout(raw),
        mirrored=mirrored,
        outlier_px=outlier_px,
        max_position_sigma=max_sigma,
        keep_stages=debug_dir is not None,
        gravity_sigma_deg=1.0 if gravity_sigma_deg is None else gravity_sigma_deg,
        near=prior_near,
        within=prior_within,
    )
    try:
        result = locate(image, camera, fixture_map, settings, gravity=g)
    except InputError as exc:
        raise InputError(exc.what, photo) from None
    _write_pictures(result, image, camera, fixture_map, annotate_path, debug_dir)
    if as_json:
        print(strict_json(result.to_dict()))
    else:
        _print_human(result, fixture_map.units, photo)
    if not result:  # stdout keeps its JSON; the one error line goes to stderr either way
        fail(f"not located: {result.reason} ({photo})", EXIT_NOT_LOCATED)


def _write_pictures(
    result: LocateResult,
    image: np.ndarray,
    camera: Camera,
    fixture_map: FixtureMap,
    annotate_path: Path | None,
    debug_dir: Path | None,
) -> None:
    """The annotated photo (``--annotate``) and one picture per stage (``--debug-dir``):
    all or none."""
    if annotate_path is None and debug_dir is None:
        return
    import cv2

    from camvlp.io.atomic import StagedOutputs
    from camvlp.viz.annotate import annotate, write_debug_pictures

    with StagedOutputs() as outputs:
        if annotate_path is not None:
            staged = outputs.file(annotate_path)
            if not cv2.imwrite(str(staged), annotate(image, result, camera, fixture_map)):
                raise InputError("cannot write the annotated photo", annotate_path)
        if debug_dir is not None:
            write_debug_pictures(
                outputs.folder(debug_dir),
                image[:, ::-1] if result.mirrored else image,
                result,
                result.stages,
            )


def _tilt(result: LocateResult) -> str:
    """How far the pose found lies from the gravity given, and from the photo's own tilt."""
    text = f"pose {result.gravity_residual_deg:.2f} deg from gravity"
    if result.tilt_disagreement_deg == result.tilt_disagreement_deg:  # not NaN
        text += f", the photo's own tilt {result.tilt_disagreement_deg:.2f} deg"
    return text


def _print_human(result: LocateResult, units: str, photo: Path) -> None:
    """The located position, its uncertainty and orientation, and each fixture, as text."""
    from camvlp.format import format_number

    if result:
        position = ", ".join(format_number(v, ".4f") for v in result.position)
        angles = ", ".join(format_number(v, ".2f") for v in result.euler_deg)
        print(f"position      ({position}) {units}")
        sigma = result.position_sigma
        if sigma is not None:  # (how far the fixtures' fit and layout let it be off)
            spread = ", ".join(format_number(v, ".2g") for v in sigma)  # (sub-mm ones too)
            source = "fit" if result.solver == "pnp" else "fit and the gravity's sigma"
            print(f"uncertainty   ({spread}) {units}, 1 sigma from the fixtures' {source}")
        print(f"orientation   theta = ({angles}) deg")
        print(f"reprojection  {result.reprojection_rms_px:.3f} px RMS")
        if result.solver != "pnp":
            print(
                f"solver        {result.solver}, {result.fixtures_used} fixtures, {_tilt(result)}"
            )
    print(
        f"fixtures      {len(result.fixtures)} detected, "
        f"{sum(f.used for f in result.fixtures)} used ({result.readout} readout"
        f"{', mirrored' if result.mirrored else ''})"
    )
    for f in result.fixtures:
        ident = f"ID {f.id:>3}" if f.id is not None else "ID   ?"
        state = "used" if f.used else f"not used: {f.reason}"
        u, v = (format_number(c, "7.1f") for c in f.pixel)
        sure = (
            f"run margin {format_number(f.run_margin, '.2f')}"
            if math.isfinite(f.run_margin)
            else f"margin {format_number(f.margin, '.1f')}"
        )
        print(f"  {ident}  at ({u}, {v})  {sure}  {state}")
    t = result.timing_ms
    stages = ", ".join(f"{k} {v:.0f}" for k, v in t.items() if k != "total")
    print(f"time          {t['total']:.0f} ms ({stages})")
    if result.paths:  # where a long photo's time went
        ran = ", ".join(f"{k} {p.ms:.0f} ms ({p.calls}x)" for k, p in result.paths.items())
        print(f"paths         {ran}")
    for note in result.notes:
        print(f"note          {note}")
