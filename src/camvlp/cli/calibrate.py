"""``camvlp calibrate`` and ``camvlp calibrate-rows``: make a camera file;
``camvlp render-chessboard``: photos to try calibrate on."""

from __future__ import annotations

import dataclasses
import itertools
import re
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, NoReturn

import typer

from camvlp.errors import InputError

from ._app import EXIT_NOT_LOCATED, app, fail, handle_errors
from .progress import progress_bar

if TYPE_CHECKING:
    from camvlp.analysis.calibrate import CalibrationResult
    from camvlp.analysis.row_time import RowTimeEstimate
    from camvlp.model.camera import Camera

#: Image files taken from a directory given as an argument.
IMAGE_SUFFIXES = {".jpg", ".jpeg", ".png", ".tif", ".tiff", ".bmp", ".webp"}

#: Show a progress bar from this many photos on (when stderr is a terminal).
PROGRESS_FROM = 5


def _expand(paths: list[Path]) -> list[Path]:
    """Files as given; directories replaced by their image files, sorted."""
    out: list[Path] = []
    for p in paths:
        if p.is_dir():
            try:
                found = sorted(q for q in p.iterdir() if q.suffix.lower() in IMAGE_SUFFIXES)
            except OSError as exc:
                raise InputError(f"cannot list the directory: {exc.strerror or exc}", p) from None
            if not found:
                raise InputError("no image files in the directory", p)
            out.extend(found)
        elif not p.exists():
            raise InputError("photo not found", p)
        else:
            out.append(p)
    return out


#: Most inner corners a --board side may have.
MAX_BOARD = 100


def _parse_board(text: str) -> tuple[int, int]:
    """``--board COLSxROWS``: the board's inner corners, or a usage error (exit 2)."""
    from camvlp.sim.chessboard import MIN_BOARD_SIDE

    m = re.fullmatch(r"\s*(\d{1,4})\s*[xX*,]\s*(\d{1,4})\s*", text)
    if not m or not all(MIN_BOARD_SIDE <= int(m.group(k)) <= MAX_BOARD for k in (1, 2)):
        fail(
            f"--board must be COLSxROWS inner corners, from {MIN_BOARD_SIDE}x{MIN_BOARD_SIDE} "
            f"to {MAX_BOARD}x{MAX_BOARD}, "
            f"e.g. 9x6; got {text[:40]!r}"
        )
    return int(m.group(1)), int(m.group(2))


@app.command()
@handle_errors
def calibrate(
    images: Annotated[
        list[Path] | None,
        typer.Argument(
            metavar="IMAGES...",
            help="Chessboard photographs (files, or directories of image files).",
            show_default=False,
        ),
    ] = None,
    board: Annotated[
        str | None,
        typer.Option(
            "--board",
            metavar="COLSxROWS",
            help="Inner corners of the board, e.g. 9x6 for 10 x 7 squares.",
        ),
    ] = None,
    square: Annotated[
        float | None,
        typer.Option("--square", metavar="SIZE_M", help="Side of one square, metres."),
    ] = None,
    out: Annotated[
        Path,
        typer.Option("--out", "-o", help="Camera file to write (.yaml: OpenCV; .json)."),
    ] = Path("camera.yaml"),
    row_time: Annotated[
        float | None,
        typer.Option(
            "--row-time",
            metavar="S",
            help="Row time to store in the camera file, seconds (calibrate-rows).",
        ),
    ] = None,
    fix_aspect: Annotated[
        bool, typer.Option("--fix-aspect", help="Keep fx = fy (square pixels).")
    ] = False,
    zero_tangent: Annotated[
        bool, typer.Option("--zero-tangent", help="Fix tangential distortion p1 = p2 = 0.")
    ] = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON summary.")] = False,
) -> None:
    """Calibrate a camera from chessboard photographs and write its camera file.

    Prints the intrinsics, the RMS reprojection error (px), and each photo's error or reason.

    Exit 1 when fewer than 3 photos show the board.
    """
    from camvlp.io import save_camera
    from camvlp.io.atomic import check_output_file, strict_json

    if not images:
        fail("no chessboard photos given (IMAGES...)")
    if board is None:
        fail("--board COLSxROWS is required (inner corners, e.g. 9x6)")
    cols_rows = _parse_board(board)
    if square is None or not square > 0:
        fail(f"--square must be a positive size in metres, got {square}")
    if row_time is not None and not 0 < row_time < 1:
        fail(f"--row-time must be a positive number of seconds, got {row_time}")
    if out.suffix.lower() not in (".yaml", ".yml", ".json"):
        fail(f"--out must end in .yaml, .yml or .json ({out})")
    check_output_file(out, "--out")
    paths = _expand(list(images))
    result = _calibrate_with_progress(paths, cols_rows, square, row_time, fix_aspect, zero_tangent)
    if not result:
        _report_failure(result, as_json)
    save_camera(
        result.camera,
        out,
        extra={"calibration_rms_px": result.rms_px, "calibration_photos": len(result.used)},
    )
    if as_json:
        print(strict_json(_calibration_json(result, out)))
    else:
        _print_calibration(result, out)


def _calibrate_with_progress(
    paths: list[Path],
    board: tuple[int, int],
    square_m: float,
    row_time_s: float | None,
    fix_aspect: bool,
    zero_tangent: bool,
) -> CalibrationResult:
    """:func:`~camvlp.analysis.calibrate.calibrate_camera` with a progress bar on stderr (a
    terminal, 5 photos or more)."""
    from camvlp.analysis.calibrate import calibrate_camera

    with progress_bar(len(paths), "finding the board", show=len(paths) >= PROGRESS_FROM) as update:
        done = itertools.count(1)
        return calibrate_camera(
            paths,
            board,
            square_m,
            row_time_s=row_time_s,
            fix_aspect=fix_aspect,
            zero_tangent=zero_tangent,
            on_image=None if update is None else lambda _name: update(next(done)),
        )


def _report_failure(result: CalibrationResult, as_json: bool) -> NoReturn:
    """Print the rejected photos (or the JSON failure) and exit 1 with the reason."""
    from camvlp.io.atomic import strict_json

    if not as_json:
        for name, reason in result.rejected:
            print(f"rejected  {name}: {reason}")
    else:
        print(
            strict_json(
                {
                    "ok": False,
                    "message": result.reason,
                    "rejected": [{"photo": n, "reason": r} for n, r in result.rejected],
                }
            )
        )
    fail(result.reason, EXIT_NOT_LOCATED)


def _calibration_json(result: CalibrationResult, out: Path) -> dict:
    """The ``--json`` summary of a successful calibration."""
    camera = result.camera
    return {
        "ok": True,
        "camera_file": str(out),
        "image_width": camera.width,
        "image_height": camera.height,
        "camera_matrix": camera.matrix.tolist(),
        "distortion_coefficients": camera.distortion.tolist(),
        "row_time_s": camera.row_time_s,
        "rms_px": result.rms_px,
        "used": [
            {"photo": n, "rms_px": e}
            for n, e in zip(result.used, result.per_image_rms_px, strict=True)
        ],
        "rejected": [{"photo": n, "reason": r} for n, r in result.rejected],
    }


def _print_calibration(result: CalibrationResult, out: Path) -> None:
    """The human summary: intrinsics, distortion, RMS, each photo's error or reason."""
    from camvlp.format import format_number

    camera = result.camera
    k = camera.matrix
    width = max(len(n) for n in (*result.used, *(n for n, _ in result.rejected)))
    print(f"camera     {camera.width} x {camera.height} px, written to {out}")
    print(f"focal      fx {k[0, 0]:.2f}  fy {k[1, 1]:.2f} px")
    print(f"centre     cx {k[0, 2]:.2f}  cy {k[1, 2]:.2f} px")
    coefficients = " ".join(format_number(v, ".5g") for v in camera.distortion)
    print(f"distortion {coefficients}  (k1 k2 p1 p2 k3)")
    if camera.row_time_s is not None:
        print(f"row time   {camera.row_time_s * 1e6:.3f} us")
    print(f"rms        {result.rms_px:.3f} px over {len(result.used)} photos")
    for name, err in zip(result.used, result.per_image_rms_px, strict=True):
        print(f"  used      {name:<{width}}  rms {err:.3f} px")
    for name, reason in result.rejected:
        print(f"  rejected  {name:<{width}}  {reason}")


@app.command("calibrate-rows")
@handle_errors
def calibrate_rows(
    photo: Annotated[
        Path,
        typer.Argument(help="Photo of one light blinking a 50 % square wave.", show_default=False),
    ],
    frequency: Annotated[
        float | None,
        typer.Option("--frequency", metavar="HZ", help="The light's blink frequency, Hz."),
    ] = None,
    camera_path: Annotated[
        Path | None,
        typer.Option("--camera", metavar="CAM", help="Camera file to check the photo against."),
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out", "-o", metavar="CAM2", help="Write --camera's file here with row_time_s added."
        ),
    ] = None,
    axis: Annotated[
        str | None,
        typer.Option("--axis", help="rows (stripes horizontal) or columns; default: found."),
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Measure the rolling shutter's row time from the stripes of a blinking light.

    Stripe period P (rows) of a light blinking at F Hz: row time = 1 / (F * P).

    Take the photo at full resolution, with a short exposure.

    Exit 1 when no light or no clear stripes are found.
    """
    from camvlp.analysis.calibrate import estimate_row_time
    from camvlp.io import load_camera, load_image, save_camera
    from camvlp.io.atomic import check_output_file

    if frequency is None or not frequency > 0:
        fail(f"--frequency must be a positive number of Hz, got {frequency}")
    if axis is not None and axis not in ("rows", "columns"):
        fail(f"--axis must be rows or columns, got {axis!r}")
    if out is not None and camera_path is None:
        fail("--out needs --camera (the camera file to copy)")
    if out is not None and out.suffix.lower() not in (".yaml", ".yml", ".json"):
        fail(f"--out must end in .yaml, .yml or .json ({out})")
    if out is not None:
        check_output_file(out, "--out")
    camera = load_camera(camera_path) if camera_path is not None else None
    image = load_image(photo)
    h, w = image.shape[:2]
    if camera is not None:
        if (w, h) not in ((camera.width, camera.height), (camera.height, camera.width)):
            fail(
                f"photo is {w} x {h} px but the camera is {camera.width} x {camera.height}; "
                f"use the full-resolution photo ({photo})"
            )
        if axis is None and camera.readout is not None and (w, h) == camera.size:
            axis = camera.readout.axis
    est = estimate_row_time(image, frequency, axis=axis)
    if not est:
        fail(f"{est.reason} ({photo})", EXIT_NOT_LOCATED)
    if out is not None and camera is not None:
        save_camera(dataclasses.replace(camera, row_time_s=est.row_time_s), out)
    _print_row_time(est, photo, frequency, out, as_json)


def _print_row_time(
    est: RowTimeEstimate, photo: Path, frequency: float, out: Path | None, as_json: bool
) -> None:
    """calibrate-rows' result: the stripes' axis and period, the row time; JSON or text."""
    from camvlp.io.atomic import strict_json

    if as_json:
        print(
            strict_json(
                {
                    "photo": str(photo),
                    "frequency_hz": frequency,
                    "period_px": est.period_px,
                    "axis": est.axis,
                    "row_time_s": est.row_time_s,
                    "rows_per_s": est.rows_per_s,
                    "strength": est.strength,
                    "periods_seen": est.periods_seen,
                    "camera_file": str(out) if out is not None else None,
                }
            )
        )
        return
    stripes = "horizontal" if est.axis == "rows" else "vertical"
    print(f"axis       {est.axis} (stripes {stripes})")
    print(
        f"period     {est.period_px:.4f} px over {est.periods_seen:.1f} periods "
        f"(strength {est.strength:.2f})"
    )
    print(f"row time   {est.row_time_s * 1e6:.4f} us")
    print(f"rows/s     {est.rows_per_s:.1f}")
    if est.periods_seen < 3:
        print(
            f"warning: only {est.periods_seen:.1f} periods in the light; a lower frequency "
            "or a larger light gives a better estimate",
            file=sys.stderr,
        )
    if out is not None:
        print(f"written    {out}")


#: Most views ``camvlp render-chessboard`` renders in one run.
MAX_VIEWS = 500


@app.command("render-chessboard")
@handle_errors
def render_chessboard_command(
    camera_path: Annotated[
        Path, typer.Option("--camera", "-c", help="Camera file (YAML/JSON) to take the photos.")
    ],
    out: Annotated[
        Path, typer.Option("--out", "-o", metavar="DIR", help="Folder for the photos and truth.")
    ],
    views: Annotated[
        int, typer.Option("--views", "-n", metavar="N", help="Photos to render.")
    ] = 12,
    board: Annotated[
        str,
        typer.Option(
            "--board",
            metavar="COLSxROWS",
            help="Inner corners of the board, e.g. 9x6 for 10 x 7 squares.",
        ),
    ] = "9x6",
    square: Annotated[
        float, typer.Option("--square", metavar="SIZE_M", help="Side of one square, metres.")
    ] = 0.025,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the poses and the noise.")] = 0,
    blur: Annotated[
        float, typer.Option("--blur", metavar="PX", help="Optical blur sigma, pixels.")
    ] = 0.7,
    noise: Annotated[
        float,
        typer.Option("--noise", metavar="GREY", help="Sensor noise sigma, grey levels (of 255)."),
    ] = 2.0,
) -> None:
    """Render chessboard photos as a camera file's camera would take them, to try calibrate on.

    Each view sees the whole board from a random pose (tilted 20 to 40 degrees, filling 55 to
    80 % of the picture), through the camera's lens distortion, blurred and with noise.
    Writes DIR/board_01.png ... and DIR/truth.json (the camera, the board, each view's pose
    in the board's frame and its inner corners' true pixels), all or none; `camvlp calibrate
    DIR --board COLSxROWS --square SIZE_M` should then find the camera file's intrinsics.
    """
    import cv2

    from camvlp.io import load_camera
    from camvlp.io.atomic import StagedOutputs, check_output_dir, check_output_file, strict_json
    from camvlp.sim.chessboard import chessboard_views
    from camvlp.sim.render import check_render_size

    cols_rows = _parse_board(board)
    if not square > 0 or square > 100:
        fail(f"--square must be a positive size in metres, at most 100, got {square}")
    if not 1 <= views <= MAX_VIEWS:
        fail(f"--views must be from 1 to {MAX_VIEWS}, got {views}")
    if seed < 0:
        fail(f"--seed must be a non-negative integer, got {seed}")
    if not 0 <= blur <= 100:
        fail(f"--blur must be from 0 to 100 pixels, got {blur}")
    if not 0 <= noise <= 255:
        fail(f"--noise must be from 0 to 255 grey levels, got {noise}")
    check_output_dir(out, "--out")
    names = [f"board_{k:0{max(2, len(str(views)))}d}.png" for k in range(1, views + 1)]
    for name in (*names, "truth.json") if out.is_dir() else ():
        check_output_file(out / name, "--out")
    camera = load_camera(camera_path)
    check_render_size(camera, camera_path)
    rendered = chessboard_views(
        camera, cols_rows, square, views, seed=seed, blur_px=blur, noise=noise
    )
    truth = _chessboard_truth(camera, cols_rows, square, seed, blur, noise)
    with StagedOutputs() as outputs, progress_bar(views, "rendering") as update:
        staged = outputs.folder(out)
        for k, (name, view) in enumerate(zip(names, rendered, strict=True), 1):
            if not cv2.imwrite(str(staged / name), view.image):
                fail(f"cannot write {out / name}")
            truth["views"].append(
                {
                    "photo": name,
                    "position_m": view.pose.position.tolist(),
                    "world_from_camera": view.pose.world_from_camera.tolist(),
                    "corners_px": view.corners_px.round(4).tolist(),
                }
            )
            if update is not None:
                update(k)
        (staged / "truth.json").write_text(strict_json(truth, indent=1) + "\n")
    print(f"wrote {views} photos of a {board} board and truth.json to {out}")
    print(f"calibrate with: camvlp calibrate {out} --board {board} --square {square:g}")


def _chessboard_truth(
    camera: Camera, board: tuple[int, int], square: float, seed: int, blur: float, noise: float
) -> dict:
    """The head of render-chessboard's truth.json: the camera and how the photos were made."""
    return {
        "camera": {
            "image_width": camera.width,
            "image_height": camera.height,
            "camera_matrix": camera.matrix.tolist(),
            "distortion_coefficients": camera.distortion.tolist(),
        },
        "board": list(board),
        "square_m": square,
        "seed": seed,
        "blur_px": blur,
        "noise_grey": noise,
        "views": [],
    }
