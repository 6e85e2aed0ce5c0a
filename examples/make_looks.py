"""Draw one lamp as a linear sensor stores it and as a phone does (docs/stress/looks.png).

Rows: a plain lamp, one with a hot core, one whose core lies 0.4 of the radius off its
centre, one with a halo; columns: the plain sensor, and the
same light through a phone's processing (``camvlp.sim.sensor.PHONE``: a colour mosaic
demosaiced, a black point of 0.04, gamma 2.2, sharpening 1, vignetting 0.3).  A 1280 x 960
camera under the thesis' lamps at 2.5 rows per chip, exposure half a chip, LEDs 5 % on when
off; each crop is shown at twice its size.

Usage::

    python examples/make_looks.py [--out out/looks.png]
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import cv2
import numpy as np

from camvlp import Pose, RenderSettings, load_map, render
from camvlp.model.camera import Camera
from camvlp.sim.sensor import PHONE

ROOT = Path(__file__).resolve().parents[1]
HALF = 64  # px: half the side of a crop
LOOKS = [
    ("plain", {}),
    ("hot core", {"core": 1.5}),
    ("core off centre", {"core": 1.5, "core_offset": 0.4}),
    ("halo", {"halo": 0.3}),
]
SENSORS = [("linear sensor", {}), ("phone", PHONE)]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "looks.png")
    args = ap.parse_args()
    fmap = load_map(ROOT / "examples/thesis_room.yaml")
    camera = Camera.from_focal(1280, 960, 1250.0, row_time_s=20e-6)
    pose = Pose.from_euler([0, 0, 0], [90, 0, 0])
    base = RenderSettings(
        chip_rate_hz=20000, exposure_s=0.5 / 20000, off_level=0.05, brightness=2.0, seed=1
    )
    rows = []
    for look, lk in LOOKS:
        tiles = []
        for sensor, sk in SENSORS:
            photo = render(camera, fmap, pose, dataclasses.replace(base, **lk, **sk))
            u, v = np.rint(photo.fixtures[0].pixel).astype(int)
            crop = photo.image[v - HALF : v + HALF, u - HALF : u + HALF]
            tile = cv2.resize(crop, None, fx=2, fy=2, interpolation=cv2.INTER_NEAREST)
            cv2.putText(
                tile, f"{look}, {sensor}", (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 255, 255)
            )
            tiles.append(tile)
        rows.append(np.hstack(tiles))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(args.out), np.vstack(rows)):
        raise SystemExit(f"cannot write {args.out}")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
