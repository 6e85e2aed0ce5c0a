"""``camvlp encode``: a fixture's frame, chips and driver schedule."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._app import app, fail, handle_errors


@app.command()
@handle_errors
def encode(
    fixture_id: Annotated[int, typer.Argument(metavar="ID", help="The fixture's ID.")],
    chip_rate: Annotated[
        float, typer.Option("--chip-rate", help="Chips per second (Hz), for the schedule.")
    ] = 10_000.0,
    map_path: Annotated[
        Path | None, typer.Option("--map", help="Take the frame format from this map file.")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Print a fixture's frame bits, its Manchester chips, and the LED's on/off schedule."""
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
