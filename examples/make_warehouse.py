"""Write a large site's map: a grid of ceiling fixtures that reuse the thesis' 4-bit IDs.

The map says ``reuse: true`` in its frame; its IDs are drawn so that no two fixtures within
two grid steps share one (:func:`camvlp.sim.site.site_map`), so that a photo of a few
fixtures tells its place by their IDs and geometry.  The default is a warehouse of 10,000
fixtures (100 x 100, 2.5 m apart, ceiling at 6 m)::

    python examples/make_warehouse.py --out out/warehouse.yaml
    python examples/make_warehouse.py --columns 20 --rows 10 --spacing 1 --height 3 \\
        --out out/site.yaml
"""

from __future__ import annotations

import argparse
from pathlib import Path

from camvlp.io import save_map
from camvlp.sim.site import PATTERNS, site_map


def main(argv: list[str] | None = None) -> None:
    """Write the map (YAML, or JSON for a ``.json`` path) and say how many fixtures it has."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--columns", type=int, default=100, help="fixtures along x (100)")
    ap.add_argument("--rows", type=int, default=100, help="fixtures along y (100)")
    ap.add_argument("--spacing", type=float, default=2.5, help="metres between fixtures (2.5)")
    ap.add_argument("--height", type=float, default=6.0, help="the ceiling's z, metres (6)")
    ap.add_argument("--diameter", type=float, default=0.4, help="fixture discs, metres (0.4)")
    ap.add_argument("--pattern", choices=PATTERNS, default="varied", help="ID pattern")
    ap.add_argument("--seed", type=int, default=1, help="seed of the IDs' draws (1)")
    ap.add_argument("--out", type=Path, required=True, help="the map file to write")
    a = ap.parse_args(argv)
    fmap = site_map(
        a.columns,
        a.rows,
        spacing=a.spacing,
        height=a.height,
        diameter=a.diameter,
        pattern=a.pattern,
        seed=a.seed,
    )
    a.out.parent.mkdir(parents=True, exist_ok=True)
    save_map(fmap, a.out)
    print(f"{a.out}: {len(fmap.fixtures):,} fixtures, {len(fmap.distinct_ids)} IDs")


if __name__ == "__main__":
    main()
