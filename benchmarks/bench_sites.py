"""A large site's map: how long a map of 10,000 fixtures that reuse the thesis' 4-bit IDs takes
to load, and its spatial index to build and to answer.

Writes the map with :func:`camvlp.sim.site.site_map` (100 x 100 fixtures 2.5 m apart, as
``examples/make_warehouse.py`` does) as YAML and as JSON into a temporary folder, then times
``load_map`` on each ``--runs`` times (5) and prints the median and the largest, with the
k-d tree's build (:attr:`camvlp.model.fixtures.FixtureMap.index`) and a query of every
fixture within 10 m of a point.

Then ``--photos`` (12) renders of the warehouse at 1920 x 1440 (f = 800 px, 25 us rows,
16 kHz chips) from random places 1.0 to 1.6 m above the floor, looking up (any heading,
tilts up to 10 degrees), each where the fixtures in view send different IDs, are located
against the whole warehouse and against a map of those fixtures alone (their IDs unique, an
ordinary map), ``--runs`` times each: the median times, the identify and solve stages'
share, and the position errors; then the ratio of the two times and the time the whole map
adds to identify and solve, p50, p95 and max over the photos.

Run: ``python benchmarks/bench_sites.py [--runs 5] [--columns 100 --rows 100] [--photos 12]``.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from camvlp import locate
from camvlp.io import load_map, save_map
from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import FixtureMap
from camvlp.sim.render import RenderSettings, render
from camvlp.sim.site import site_map

CAMERA = Camera.from_focal(1920, 1440, 800.0, row_time_s=25e-6, readout="rows")


def _times(fn, runs: int) -> list[float]:
    """``fn()``'s wall time, seconds, ``runs`` times."""
    out = []
    for _ in range(runs):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return out


def _in_view(fmap: FixtureMap, pose: Pose) -> tuple[FixtureMap, FixtureMap] | None:
    """The fixtures within 25 m of the camera (what a render needs: the others are out of
    view) and those of them in the photo as an ordinary map, or None when two of those in
    the photo send one ID."""
    near = np.asarray(fmap.index.query_ball_point(pose.position, 25.0), dtype=np.int64)
    uv = CAMERA.project(pose, fmap.positions[near])
    inside = np.all((uv >= 0) & (uv < [CAMERA.width, CAMERA.height]), axis=1)
    seen = [fmap.fixtures[i] for i in near[inside]]
    if len({f.id for f in seen}) < len(seen):
        return None
    return (
        FixtureMap(tuple(fmap.fixtures[i] for i in near), frame=fmap.frame, reuse=True),
        FixtureMap(tuple(seen), frame=fmap.frame),
    )


def bench_locate(fmap: FixtureMap, photos: int, runs: int) -> None:
    """Locate ``photos`` renders against the whole map and the fixtures in view alone; print
    each photo's times and the ratios' p50, p95 and max."""
    rng = np.random.default_rng(7)
    lo, hi = fmap.positions[:, :2].min(axis=0) + 5.0, fmap.positions[:, :2].max(axis=0) - 5.0
    ratios, added = [], []
    while len(ratios) < photos:
        xy = rng.uniform(lo, hi)
        angles = [rng.uniform(0, 360), *rng.uniform(-10, 10, 2)]
        r = Rotation.from_euler("zxy", angles, degrees=True).as_matrix()
        pose = Pose(r, np.array([*xy, rng.uniform(1.0, 1.6)]))
        maps = _in_view(fmap, pose)
        if maps is None:
            continue
        settings = RenderSettings(chip_rate_hz=16_000.0, row_time_s=25e-6, seed=len(ratios))
        image = render(CAMERA, maps[0], pose, settings).image
        line, totals, stages = [], [], []
        for name, m in (("warehouse", fmap), (f"{len(maps[1].fixtures)} in view", maps[1])):
            results = [locate(image, CAMERA, m) for _ in range(runs)]
            totals.append(statistics.median(x.timing_ms["total"] for x in results))
            stages.append(statistics.median(x.timing_ms["pose"] for x in results))
            res = results[0]
            err = np.linalg.norm(res.position - pose.position) if res else float("nan")
            line.append(
                f"{name}: {totals[-1]:.0f} ms (identify and solve {stages[-1]:.0f}), "
                f"error {1e3 * err:.1f} mm"
                if res
                else f"{name}: not located ({res.reason})"
            )
        print(f"photo {len(ratios)}: " + "; ".join(line))
        ratios.append(totals[0] / totals[1])
        added.append(stages[0] - stages[1])
    for name, values, unit in (
        ("warehouse over in view alone", ratios, "x"),
        ("identify and solve added", added, " ms"),
    ):
        p50, p95 = np.percentile(values, [50, 95])
        print(f"{name}: p50 {p50:.2f}{unit}, p95 {p95:.2f}{unit}, max {max(values):.2f}{unit}")


def main(argv: list[str] | None = None) -> None:
    """Print each load's and the index's median and largest time."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5, help="times each step is timed (5)")
    ap.add_argument("--columns", type=int, default=100, help="fixtures along x (100)")
    ap.add_argument("--rows", type=int, default=100, help="fixtures along y (100)")
    ap.add_argument("--photos", type=int, default=12, help="warehouse photos located (12)")
    a = ap.parse_args(argv)
    fmap = site_map(a.columns, a.rows, spacing=2.5, height=6.0, seed=1)
    n = len(fmap.fixtures)
    with tempfile.TemporaryDirectory() as tmp:
        for suffix in ("yaml", "json"):
            path = Path(tmp) / f"warehouse.{suffix}"
            save_map(fmap, path)
            t = _times(lambda p=path: load_map(p), a.runs)
            size = path.stat().st_size / 1e6
            print(
                f"load_map, {n:,} fixtures, {suffix} ({size:.1f} MB): median "
                f"{statistics.median(t):.3f} s, max {max(t):.3f} s"
            )
    maps = [site_map(a.columns, a.rows, spacing=2.5, height=6.0, seed=1) for _ in range(a.runs)]
    t = [_times(lambda m=m: m.index, 1)[0] for m in maps]  # (built once a map: fresh ones)
    print(f"k-d tree build: median {1e3 * statistics.median(t):.1f} ms")
    t = _times(lambda: maps[0].index.query_ball_point([120.0, 120.0, 6.0], 10.0), a.runs)
    print(f"fixtures within 10 m of a point: median {1e3 * statistics.median(t):.3f} ms")
    bench_locate(maps[0], a.photos, a.runs)


if __name__ == "__main__":
    main()
