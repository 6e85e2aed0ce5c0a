"""Glowing lamps at the photo's border: centred on their radial shape when only the glow is cut,
set aside when the disc is.

Each case renders one lamp with a halo (0.2 to 0.4, brightness 1 to 8 full scales, a hot core
in half the cases, blur 0.5 to 2 px, stripes of 2 to 8 rows per chip) on a 1080p ceiling
photo read along rows or columns, twice: once in the middle of the photo, once with its disc's
edge at a distance from one border (drawn at random) of -0.5 to 1 disc radius (below 0: the
border cuts the disc).  The lamp is detected and centred as :func:`camvlp.locate` does
(:func:`camvlp.pipeline.detect.candidates.detect_fixtures` then
:func:`camvlp.pipeline.lamp.glow.centred_on_glow`); it is used when it does not count as touching
the border.  Prints, for lamps whose disc is inside, how many are used and their centre
errors (px, from the renderer's truth) next to the same lamps' in the middle; and how many
lamps whose disc the border cuts are used (should be none).  Run::

    python benchmarks/border_glow.py --n 60 --seed 1
"""

from __future__ import annotations

import argparse

import numpy as np

from camvlp import Camera, Fixture, FixtureMap, Pose, RenderSettings, render
from camvlp.pipeline.detect.candidates import detect_fixtures
from camvlp.pipeline.lamp.glow import centred_on_glow

W, H, F, ROW_TIME = 1920, 1080, 1400.0, 15e-6
CEILING_M = 2.0


def _photo(rng: np.random.Generator, u: float, v: float, r_px: float, settings, cam: Camera):
    ray = cam.undistort_pixels(np.array([[u, v]]))[0]
    centre = np.array([ray[0], ray[1], 1.0]) * CEILING_M
    fx = Fixture(0, centre, diameter=2 * r_px * CEILING_M / F, normal=np.array([0.0, 0, -1]))
    return render(cam, FixtureMap((fx,)), Pose(np.eye(3), np.zeros(3)), settings)


def _measure(photo, axis: str):
    """(used, centre error px) of the blob nearest the truth; (False, nan) when none."""
    truth = photo.fixtures[0].pixel
    blobs = detect_fixtures(photo.image, readout=axis).blobs
    if not blobs:
        return False, float("nan")
    blobs = centred_on_glow(photo.image, blobs, axis)
    b = min(blobs, key=lambda b: np.linalg.norm(b.pixel - truth))
    return (not b.touches_border), float(np.linalg.norm(b.pixel - truth))


def one_case(rng: np.random.Generator):
    readout = str(rng.choice(["rows", "rows-reversed", "columns", "columns-reversed"]))
    axis = "rows" if readout.startswith("rows") else "columns"
    cam = Camera(W, H, np.array([[F, 0, (W - 1) / 2], [0, F, (H - 1) / 2], [0, 0, 1.0]]),
                 np.zeros(0), row_time_s=ROW_TIME)  # fmt: skip
    rows_per_chip = float(rng.uniform(2.0, 8.0))
    chip_rate = 1.0 / (rows_per_chip * ROW_TIME)
    r_px = float(rng.uniform(40.0, 110.0))
    settings = RenderSettings(
        chip_rate_hz=chip_rate,
        exposure_s=float(rng.uniform(0.1, 0.7)) / chip_rate,
        brightness=float(np.exp(rng.uniform(0.0, np.log(8.0)))),
        halo=float(rng.uniform(0.2, 0.4)),
        core=float(rng.choice([0.0, rng.uniform(1.0, 3.0)])),
        off_level=float(rng.uniform(0.0, 0.1)),
        blur_px=float(rng.uniform(0.5, 2.0)),
        readout=readout,
        seed=int(rng.integers(1 << 30)),
    )
    gap = float(rng.uniform(-0.5, 1.0))  # the disc's edge from the border, radii
    side = int(rng.integers(4))  # left, right, top, bottom
    along = float(rng.uniform(0.3, 0.7))
    d = r_px * (1.0 + gap)  # the centre from the border
    u, v = [(d, along * H), (W - 1 - d, along * H), (along * W, d), (along * W, H - 1 - d)][side]
    near = _measure(_photo(rng, u, v, r_px, settings, cam), axis)
    middle = _measure(_photo(rng, W / 2, H / 2, r_px, settings, cam), axis)
    return dict(gap=gap, axis=axis, near=near, middle=middle, settings=settings, r=r_px)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=60, help="lamps to render (twice each)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    cases = [one_case(rng) for _ in range(args.n)]
    inside = [c for c in cases if c["gap"] >= 0]
    cut = [c for c in cases if c["gap"] < 0]
    used = [c for c in inside if c["near"][0]]
    print(f"disc inside the photo: {len(inside)} lamps, {len(used)} used at the border")
    for axis in ("rows", "columns"):
        e = np.array([c["near"][1] for c in used if c["axis"] == axis])
        m = np.array([c["middle"][1] for c in used if c["axis"] == axis])
        if e.size:
            print(
                f"  {axis:7s} n={e.size:3d}  at the border: median {np.median(e):.3f} "
                f"p90 {np.percentile(e, 90):.3f} max {e.max():.3f} px;  the same lamps in "
                f"the middle: median {np.median(m):.3f} p90 {np.percentile(m, 90):.3f} "
                f"max {m.max():.3f} px"
            )
    for lo, hi in ((0.0, 0.1), (0.1, 0.3), (0.3, 1.0)):
        part = [c for c in inside if lo <= c["gap"] < hi]
        n_used = sum(c["near"][0] for c in part)
        print(f"  edge {lo:.1f}-{hi:.1f} radius from the border: {n_used} of {len(part)} used")
    for c in inside:
        if not c["near"][0] or c["near"][1] > 1.0:
            s = c["settings"]
            print(
                f"    gap {c['gap']:.2f} r {c['r']:.0f} {c['axis']} used {c['near'][0]} "
                f"err {c['near'][1]:.2f} (middle {c['middle'][1]:.2f}) halo {s.halo:.2f} "
                f"brightness {s.brightness:.1f} core {s.core:.1f} blur {s.blur_px:.1f}"
            )
    n_cut_used = sum(c["near"][0] for c in cut)
    print(f"disc cut by the border: {len(cut)} lamps, {n_cut_used} used")
    for c in cut:
        if c["near"][0]:
            print(f"    USED gap {c['gap']:.2f} r {c['r']:.0f} err {c['near'][1]:.2f}")


if __name__ == "__main__":
    main()
