"""Render a survey: simulated photos over a floor grid, plus survey.csv for ``camvlp evaluate``.

The simulated counterpart of the thesis' experiment (section 5.7): photographs taken from a
grid on the floor, camera looking up at the ceiling.  Example (the thesis' room, 81 photos)::

    python examples/make_survey.py --camera examples/thesis_camera.yaml \\
        --map examples/thesis_room.yaml --grid=-0.4:0.4:0.1,-0.4:0.4:0.1 \\
        --euler 90,0,0 --jitter-deg 2 --seed 1 --quality 90 --out out/survey
    camvlp evaluate out/survey/survey.csv --camera examples/thesis_camera.yaml \\
        --map examples/thesis_room.yaml --out out/evaluate

The grid is over the map's ``x`` and ``z`` axes; ``y`` is ``-height`` (the thesis' room has
``y`` pointing down, with the floor at ``y = 0`` and the ceiling at ``y = -2.7 m``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from camvlp.io import InputError, load_camera, load_map
from camvlp.model.camera import Pose
from camvlp.sim.grid import grid_points
from camvlp.sim.render import RenderSettings, all_fully_inside
from camvlp.sim.survey import default_jobs, render_survey


def _range(text: str) -> tuple[float, float, float]:
    try:
        start, stop, step = (float(v) for v in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected start:stop:step, got {text!r}") from None
    return start, stop, step


def _grid(text: str) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    parts = text.split(",")
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"expected x0:x1:step,z0:z1:step, got {text!r}")
    return _range(parts[0]), _range(parts[1])


def _triple(text: str) -> tuple[float, float, float]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 3:
        raise argparse.ArgumentTypeError(f"expected three comma-separated numbers, got {text!r}")
    return values  # type: ignore[return-value]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--camera", required=True, type=Path, help="camera file")
    parser.add_argument("--map", required=True, type=Path, help="map file")
    parser.add_argument(
        "--grid",
        required=True,
        type=_grid,
        help="x0:x1:step,z0:z1:step over the floor, map units (stop included)",
    )
    parser.add_argument(
        "--height",
        type=float,
        default=0.0,
        help="camera height above the floor, map units (y = -height); default 0",
    )
    parser.add_argument(
        "--euler",
        type=_triple,
        default=(90.0, 0.0, 0.0),
        help="the thesis' angles theta_x,theta_y,theta_z, degrees; default 90,0,0",
    )
    parser.add_argument(
        "--jitter-deg",
        type=float,
        default=0.0,
        help="add a uniform random angle in [-J, J] to each of the three angles",
    )
    parser.add_argument("--out", required=True, type=Path, help="output folder")
    parser.add_argument("--seed", type=int, default=0, help="seed of the jitter and the renders")
    parser.add_argument("--jobs", type=int, default=None, help="worker processes (default: all)")
    parser.add_argument("--quality", type=int, default=90, help="JPEG quality; default 90")
    parser.add_argument(
        "--chip-rate",
        type=float,
        default=10_000.0,
        help="Manchester chips per second; default 10000",
    )
    args = parser.parse_args(argv)
    if args.jitter_deg < 0:
        parser.error("--jitter-deg must not be negative")
    if args.jobs is not None and args.jobs < 1:
        parser.error("--jobs must be at least 1")

    try:
        camera = load_camera(args.camera)
        fixture_map = load_map(args.map)
        positions = grid_points(*args.grid, -args.height)
    except (InputError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    rng = np.random.default_rng(args.seed)
    euler = np.asarray(args.euler) + rng.uniform(
        -args.jitter_deg, args.jitter_deg, size=(len(positions), 3)
    )
    outside = sum(
        not all_fully_inside(camera, fixture_map, Pose.from_euler(p, e))
        for p, e in zip(positions, euler, strict=True)
    )
    if outside:
        print(
            f"note: {outside} of {len(positions)} poses do not see every fixture whole",
            file=sys.stderr,
        )
    jobs = args.jobs or default_jobs()
    print(
        f"rendering {len(positions)} photos ({camera.width} x {camera.height}) with {jobs} "
        f"jobs into {args.out}",
        file=sys.stderr,
    )
    t0 = time.perf_counter()
    try:
        csv_path = render_survey(
            camera,
            fixture_map,
            positions,
            euler,
            args.out,
            RenderSettings(
                chip_rate_hz=args.chip_rate, seed=args.seed, readout=camera.readout or "rows"
            ),
            jobs=jobs,
            jpeg_quality=args.quality,
            progress=lambda done, total: print(f"\r{done}/{total}", end="", file=sys.stderr),
        )
    except ValueError as exc:
        print(f"\nerror: {exc}", file=sys.stderr)
        return 2
    print(f"\nwrote {csv_path} in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
