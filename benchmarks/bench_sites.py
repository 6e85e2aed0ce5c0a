"""A large site's map: how long a map of 10,000 fixtures that reuse the thesis' 4-bit IDs takes
to load, and its spatial index to build and to answer.

Writes the map with :func:`camvlp.sim.site.site_map` (100 x 100 fixtures 2.5 m apart, as
``examples/make_warehouse.py`` does) as YAML and as JSON into a temporary folder, then times
``load_map`` on each ``--runs`` times (5) and prints the median and the largest, with the
k-d tree's build (:attr:`camvlp.model.fixtures.FixtureMap.index`) and a query of every
fixture within 10 m of a point.

Run: ``python benchmarks/bench_sites.py [--runs 5] [--columns 100 --rows 100]``.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from camvlp.io import load_map, save_map
from camvlp.sim.site import site_map


def _times(fn, runs: int) -> list[float]:
    """``fn()``'s wall time, seconds, ``runs`` times."""
    out = []
    for _ in range(runs):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return out


def main(argv: list[str] | None = None) -> None:
    """Print each load's and the index's median and largest time."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5, help="times each step is timed (5)")
    ap.add_argument("--columns", type=int, default=100, help="fixtures along x (100)")
    ap.add_argument("--rows", type=int, default=100, help="fixtures along y (100)")
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


if __name__ == "__main__":
    main()
