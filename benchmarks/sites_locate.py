"""Photos of large sites whose IDs repeat, located: how many are placed, how many at a wrong
place, how many refused and why (``docs/sites.md``'s table).

Renders at 640 x 480 (f = 400 px, 25 us rows, 16 kHz chips: 2.5 rows a chip) of sites of
0.5 m discs 1 m apart on a 4 m ceiling with the thesis' 4-bit frame
(:func:`camvlp.sim.site.site_map`), the camera 1.0 to 1.6 m above the floor, any heading,
tilts up to 20 degrees, at random places (seeded):

- ``varied``: 30 x 20 fixtures, no two within two grid steps alike (seed 5);
- ``periodic``: 20 x 10 fixtures, the same 4 x 4 block of IDs over and over (every photo
  should be refused as ambiguous);
- ``room``: one 4 x 4 block alone, its 16 IDs unique (an ordinary map), the camera over it:
  the error to compare the sites' with;
- ``lamps``: the varied site's lamps with the stress benchmark's looks (hot cores, some off
  centre, halos: ``stress_decode.lamp_look``), brightness 0.5 to 8, blur 0.5 to 2 px, each
  photo stored as a JPEG (quality 85) and read back.

A place more than 10 cm from the truth counts as wrong.

Run: ``python benchmarks/sites_locate.py [--photos 60] [--seed 11] [--sites varied,lamps]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections import Counter
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).resolve().parent))
from stress_decode import lamp_look

from camvlp import locate
from camvlp.model.camera import Camera, Pose
from camvlp.sim.render import RenderSettings, render
from camvlp.sim.site import site_map

CAMERA = Camera.from_focal(640, 480, 400.0, row_time_s=25e-6, readout="rows")
RENDER = dict(chip_rate_hz=16_000.0, row_time_s=25e-6)
SITE = dict(spacing=1.0, height=4.0, diameter=0.5)
#: name -> (columns, rows, pattern, photos' share of ``--photos``)
SITES = {
    "varied": (30, 20, "varied", 1.0),
    "periodic": (20, 10, "periodic", 1 / 3),
    "room": (4, 4, "periodic", 1 / 3),
    "lamps": (30, 20, "varied", 2 / 3),
}


def _pose(rng: np.random.Generator, columns: int, rows: int, margin: float) -> Pose:
    """A camera 1.0 to 1.6 m up, over the site (``margin`` m in from its edge fixtures),
    any heading, tilted up to 20 degrees about its x and y."""
    xy = [rng.uniform(margin, columns - 1 - margin), rng.uniform(margin, rows - 1 - margin)]
    angles = [rng.uniform(0, 360), *rng.uniform(-20, 20, 2)]
    r = Rotation.from_euler("zxy", angles, degrees=True).as_matrix()
    return Pose(r, np.array([*xy, rng.uniform(1.0, 1.6)]))


def _photo(fmap, pose: Pose, seed: int, looks: np.random.Generator | None) -> np.ndarray:
    """A render of ``fmap`` from ``pose``; with ``looks``, its lamps' looks, brightness and
    blur drawn from it, stored as a JPEG and read back."""
    if looks is None:
        return render(CAMERA, fmap, pose, RenderSettings(seed=seed, **RENDER)).image
    brightness = float(np.exp(looks.uniform(np.log(0.5), np.log(8.0))))
    settings = RenderSettings(
        seed=seed,
        brightness=brightness,
        blur_px=float(looks.uniform(0.5, 2.0)),
        **lamp_look(np.random.default_rng(seed)),
        **RENDER,
    )
    image = render(CAMERA, fmap, pose, settings).image
    _, jpeg = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 85])
    return cv2.imdecode(jpeg, cv2.IMREAD_COLOR)


def run(name: str, photos: int, seed: int) -> None:
    """Locate ``photos`` renders of site ``name``; print one line and the refusals' reasons."""
    columns, rows, pattern, _ = SITES[name]
    fmap = site_map(columns, rows, pattern=pattern, seed=5, **SITE)
    if name == "room":
        fmap = dataclasses.replace(fmap, reuse=False)
    rng = np.random.default_rng(seed)
    errors, refused = [], Counter()
    start = time.perf_counter()
    for k in range(photos):
        pose = _pose(rng, columns, rows, 0.5 if name == "room" else 1.0)
        image = _photo(fmap, pose, k, rng if name == "lamps" else None)
        result = locate(image, CAMERA, fmap)
        if result:
            errors.append(float(np.linalg.norm(result.position - pose.position)))
        else:
            refused[result.reason.split(":")[0]] += 1
    e = np.array(errors)
    median = f"{1e3 * np.median(e):.2f} mm" if e.size else "-"
    print(
        f"{name}: {len(fmap.fixtures)} fixtures, {photos} photos: located {int(np.sum(e <= 0.1))}, "
        f"wrong place {int(np.sum(e > 0.1))}, refused {sum(refused.values())}; median error "
        f"{median}; {time.perf_counter() - start:.0f} s"
    )
    for why, n in refused.most_common():
        print(f"    refused {n}: {why}")


def main(argv: list[str] | None = None) -> None:
    """Run every site."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--photos", type=int, default=60, help="photos of the varied site (60)")
    ap.add_argument("--seed", type=int, default=11, help="seed of the poses (11)")
    ap.add_argument("--sites", default=",".join(SITES), help="which, comma-separated (all)")
    a = ap.parse_args(argv)
    for name in a.sites.split(","):
        if name not in SITES:
            ap.error(f"--sites: no site {name!r} (one of {', '.join(SITES)})")
        run(name, max(1, round(a.photos * SITES[name][3])), a.seed)


if __name__ == "__main__":
    main()
