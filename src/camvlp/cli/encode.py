"""``camvlp encode``: a fixture's frame, chips and driver schedule."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._app import app, fail, handle_errors


@app.command()
@handle_errors
def encode(
    fixture_id: Annotated[
        int | None, typer.Argument(metavar="ID", help="The fixture's ID.", show_default=False)
    ] = None,
    chip_rate: Annotated[
        float, typer.Option("--chip-rate", help="Chips per second (Hz), for the schedule.")
    ] = 10_000.0,
    map_path: Annotated[
        Path | None, typer.Option("--map", help="Take the frame format from this map file.")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    design: Annotated[
        bool,
        typer.Option(
            "--design", help="Recommend frame formats for --fixtures fixtures of --rows rows."
        ),
    ] = False,
    fixtures: Annotated[
        int | None, typer.Option("--fixtures", help="With --design: fixtures that need IDs.")
    ] = None,
    rows: Annotated[
        float | None,
        typer.Option("--rows", help="With --design: rows a fixture's disc spans in a photo."),
    ] = None,
    rows_per_chip: Annotated[
        float, typer.Option("--rows-per-chip", help="With --design: rows one chip lasts.")
    ] = 5.0,
) -> None:
    """Print a fixture's frame bits, its Manchester chips, and the LED's on/off schedule;
    with --design, the frame formats that give --fixtures fixtures IDs of their own."""
    if design:
        if fixtures is None or rows is None:
            fail("--design needs --fixtures and --rows")
        _design(fixtures, rows, rows_per_chip, as_json)
        return
    if fixture_id is None:
        fail("give a fixture ID (or --design)")
    from camvlp.io import load_map
    from camvlp.io.atomic import strict_json
    from camvlp.model.linecode import FrameFormat, chip_schedule

    fixture_map = load_map(map_path) if map_path else None
    if fixture_map is not None and fixture_map.mode != "manchester":
        fail(
            f"the map's fixtures are {fixture_map.mode}-coded: each blinks its frequency_hz, "
            f"they send no Manchester frame ({map_path})"
        )
    frame = fixture_map.frame if fixture_map is not None else FrameFormat()
    if chip_rate <= 0:
        fail(f"--chip-rate must be positive, got {chip_rate}")
    try:
        bits = frame.bits(fixture_id)
    except ValueError as exc:
        fail(str(exc))
    chips = frame.chips(fixture_id)
    schedule = chip_schedule(chips, chip_rate)
    chip_str = "".join(map(str, chips))
    if as_json:
        print(
            strict_json(
                {
                    "id": fixture_id,
                    "bits": bits,
                    "chips": chip_str,
                    "chip_rate_hz": chip_rate,
                    "frame_duration_s": len(chips) / chip_rate,
                    "schedule": [{"on": bool(s), "duration_s": d} for s, d in schedule],
                }
            )
        )
        return
    print(f"id        {fixture_id}")
    print(f"bits      {bits}  (preamble {frame.preamble}, id, postamble {frame.postamble})")
    print(f"chips     {chip_str}  (0 -> 10, 1 -> 01; 1 = light on)")
    duration_us = len(chips) / chip_rate * 1e6
    print(f"frame     {len(chips)} chips, {duration_us:.1f} us at {chip_rate:g} Hz")
    print("schedule  " + ", ".join(f"{'on' if s else 'off'} {d * 1e6:.1f} us" for s, d in schedule))


def _design(fixtures: int, rows: float, rows_per_chip: float, as_json: bool) -> None:
    """Print the frame formats :func:`~camvlp.analysis.frame_design.design_frames` finds."""
    from camvlp.analysis.frame_design import ONE_PHOTO_FRAMES, design_frames
    from camvlp.io.atomic import strict_json

    try:
        found = design_frames(fixtures, rows, rows_per_chip)[:5]
    except ValueError as exc:
        fail(str(exc))
    if as_json:
        print(strict_json([
            {"preamble": d.frame.preamble, "id_bits": d.frame.id_bits,
             "check_bits": d.frame.check_bits, "postamble": d.frame.postamble,
             "chips": d.frame.n_chips, "min_distance": d.min_distance,
             "frames_per_disc": d.frames_per_disc, "one_photo": d.one_photo}
            for d in found
        ]))  # fmt: skip
        return
    print(f"{fixtures} fixtures, discs of {rows:g} rows, {rows_per_chip:g} rows a chip")
    print("preamble  id bits  check bits  postamble  chips  min distance  frames a disc")
    for d in found:
        f = d.frame
        print(
            f"{f.preamble:>8}  {f.id_bits:7d}  {f.check_bits:10d}  {f.postamble:>9}  "
            f"{f.n_chips:5d}  {d.min_distance:12d}  {d.frames_per_disc:13.2f}"
        )
    if found and found[0].one_photo:
        f = found[0].frame
        print(
            f"recommended: preamble {f.preamble}, {f.id_bits} ID bits, {f.check_bits} check "
            f"bits, postamble {f.postamble} (a map's frame: id_bits: {f.id_bits}, "
            f"check_bits: {f.check_bits})"
        )
    else:
        print(
            f"no format gives {fixtures} IDs in {ONE_PHOTO_FRAMES:g} frames of a "
            f"{rows:g}-row disc: reuse a shorter frame's IDs (camvlp assign-ids), or read "
            "the longer frame along a video"
        )
