"""Photos of a few lights in a site whose IDs repeat, located with gravity: with a prior and
without (``docs/sites.md``, "Two or three lights: gravity and a prior"); and, with
``--lights 4,99``, photos of four lights or more, also without gravity and in a room (the
figures of "Photos of four lights or more").

The supermarket of ``examples/make_supermarket.py`` (``examples/supermarket.yaml``: 600
downlights of 20 cm, 1.5 m x 2.67 m apart under a 3.5 m ceiling, the thesis' 4-bit frame at
10 kHz, IDs from ``camvlp assign-ids``), photographed by the thesis' phone camera scaled to
a quarter (1296 x 970, f = 978 px) whose rows take 40 us (2.5 rows a chip), held 1.0 to 1.6 m
above the floor, any heading, tilted up to 20 degrees about its x and y axes, at random
places (seeded).  Only the poses that put two or three fixtures (``--lights``) whole in the
photo are rendered (``camvlp.sim.render``, the fixtures within 12 m of the camera: the others
are out of view).  Each photo is located with the direction of gravity turned by a random angle
(two perpendicular components of 1 / sqrt(2) degrees each: 1 degree RMS), once with a prior
(``near`` a point drawn uniformly within ``--offset`` m of the camera's x and y, ``within``
``--within`` m) and once without; with ``--lights`` from 4, once more without gravity, and
once against a room of the fixtures in the photo and near it alone, each ID once
(``view_map`` at the true pose: an ordinary map, its IDs unique), whose median error is the
one the site's is compared with.

A located position more than 10 cm from the truth counts as a wrong place: "wrong
fixtures" when the fixtures it used are not those the camera saw (a wrong correspondence),
"off" when they are (the gravity's error, through two or three fixtures).

Run: ``python benchmarks/sites_few.py [--photos 200] [--seed 11] [--within 5] [--offset 3]
[--lights 2,3]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import time
from collections import Counter
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from camvlp import locate
from camvlp.io import load_map
from camvlp.model.camera import Camera, Pose
from camvlp.pipeline.identify.placement import view_map
from camvlp.pipeline.settings import LocateSettings
from camvlp.sim.render import RenderSettings, render

MAP = Path(__file__).resolve().parents[1] / "examples" / "supermarket.yaml"
CAMERA = Camera.from_focal(1296, 970, 3912.0 / 4, row_time_s=40e-6, readout="rows")
RENDER = dict(chip_rate_hz=10_000.0, row_time_s=40e-6)
UP = np.array([0.0, 0.0, 1.0])


def _pose(rng: np.random.Generator) -> Pose:
    """A camera 1.0 to 1.6 m up over the shop floor (60 m x 40 m), any heading, tilted up to
    20 degrees about its x and y."""
    angles = [rng.uniform(0, 360), *rng.uniform(-20, 20, 2)]
    r = Rotation.from_euler("zxy", angles, degrees=True).as_matrix()
    return Pose(r, np.array([rng.uniform(0, 60), rng.uniform(0, 40), rng.uniform(1.0, 1.6)]))


def _whole(fmap, pose: Pose) -> int:
    """How many fixtures the pose puts whole in the photo (their discs 10 px in)."""
    off = fmap.positions - pose.position
    ahead = off @ pose.world_from_camera[:, 2] > 0.1
    where = CAMERA.project(pose, fmap.positions[ahead])
    pad = 0.5 * CAMERA.focal_px * 0.2 / np.linalg.norm(off[ahead], axis=1)[:, None] + 10
    size = np.array([CAMERA.width - 1, CAMERA.height - 1])
    return int(np.count_nonzero(np.all((where >= pad) & (where <= size - pad), axis=1)))


def _noisy(gravity: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``gravity`` turned by two perpendicular angles of 1 / sqrt(2) degrees (sigma) each."""
    e1 = np.cross(gravity, [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(gravity, e1) / np.linalg.norm(gravity)
    a, b = rng.normal(0.0, np.radians(1.0) / np.sqrt(2), 2)
    return Rotation.from_rotvec(a * e1 + b * e2).apply(gravity)


def _fixtures_right(fmap, pose: Pose, result) -> bool:
    """Whether each light the result used is, by its pose, the fixture the camera saw there
    (the fixture with its ID that each pose projects nearest to the light)."""
    found = Pose(result.rotation, result.position)
    for f in result.fixtures:
        if f.used:
            same = fmap.with_id(f.id)
            near = []
            for p in (pose, found):
                off = np.hypot(*(CAMERA.project(p, fmap.positions[same]) - f.pixel).T)
                near.append(same[np.argmin(np.where(np.isfinite(off), off, np.inf))])
            if near[0] != near[1]:
                return False
    return True


def _why(reason: str) -> str:
    """A refusal's kind: its words before the first colon or semicolon, numbers as N."""
    return re.sub(r"\d+(\.\d+)?", "N", re.split(r"[:;(]", reason)[0].strip())


def _summary(name: str, rows: list) -> None:
    """Print one line for a set of photos and its refusals by reason."""
    errors = np.array([e for e, _, _, _ in rows if e is not None])
    right = [ok for e, ok, _, _ in rows if e is not None]
    z = np.array([z for e, _, _, z in rows if e is not None and z is not None])
    located = int(np.sum(errors <= 0.1))
    wrong_fixtures = sum(1 for e, ok in zip(errors, right, strict=True) if not ok)
    off = sum(1 for e, ok in zip(errors, right, strict=True) if ok and e > 0.1)
    refused = Counter(why for e, _, why, _ in rows if e is None)
    median = f"{1e3 * np.median(errors):.1f} mm" if errors.size else "-"
    print(
        f"  {name}: {len(rows)} photos, located {located} ({100 * located / max(len(rows), 1):.0f} "
        f"%), wrong place {wrong_fixtures + off} ({wrong_fixtures} wrong fixtures, {off} off "
        f"> 10 cm), refused {sum(refused.values())}; median error {median}"
    )
    if z.size:
        within = ", ".join(f"{100 * np.mean(z <= k):.0f} % within {k}" for k in (1, 2, 3))
        print(f"      errors over their sigmas (the largest of x, y, z): {within}")
    for why, n in refused.most_common():
        print(f"      refused {n}: {why}")


def main(argv: list[str] | None = None) -> None:
    """Render, locate with and without the prior, and print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--photos", type=int, default=200, help="photos (200)")
    ap.add_argument("--seed", type=int, default=11, help="seed of the poses and noise (11)")
    ap.add_argument("--within", type=float, default=5.0, help="the prior's radius, m (5)")
    ap.add_argument("--offset", type=float, default=3.0, help="prior's centre off, m (3)")
    ap.add_argument("--lights", default="2,3", help="fixtures whole in the photo, MIN,MAX (2,3)")
    a = ap.parse_args(argv)
    least, most = (int(v) for v in a.lights.split(","))
    fmap = load_map(MAP)
    rng = np.random.default_rng(a.seed)
    rows: dict[tuple[str, int], list] = {}
    start, spent, stage_ms = time.perf_counter(), Counter(), {}
    k = 0
    while k < a.photos:
        pose = _pose(rng)
        whole = _whole(fmap, pose)
        if not least <= whole <= most:
            continue
        close = np.linalg.norm(fmap.positions[:, :2] - pose.position[:2], axis=1) < 12.0
        sub = dataclasses.replace(fmap, fixtures=tuple(np.array(fmap.fixtures)[close]))
        image = render(CAMERA, sub, pose, RenderSettings(seed=k, **RENDER)).image
        gravity = _noisy(pose.world_from_camera.T @ -UP, rng)
        r, t = a.offset * np.sqrt(rng.uniform()), rng.uniform(0, 2 * np.pi)
        near = tuple(pose.position[:2] + r * np.array([np.cos(t), np.sin(t)]))
        variants = [
            ("prior", fmap, LocateSettings(near=near, within=a.within), gravity),
            ("none", fmap, None, gravity),
        ]
        if least >= 4:
            room = view_map(fmap, CAMERA, pose, np.flatnonzero(close))
            variants += [("no gravity", fmap, None, None), ("room", room, None, None)]
        for name, where, st, g in variants:
            t0 = time.perf_counter()
            result = locate(image, CAMERA, where, st, gravity=g)
            spent[name] += time.perf_counter() - t0
            stage_ms.setdefault(name, []).append(result.timing_ms["pose"])
            if result:
                e = float(np.linalg.norm(result.position - pose.position))
                sigma = result.position_sigma
                z = (
                    None
                    if sigma is None
                    else float(np.max(np.abs(result.position - pose.position) / sigma))
                )
                row = (e, _fixtures_right(fmap, pose, result), "", z)
            else:
                row = (None, True, _why(result.reason), None)
            rows.setdefault((name, whole), []).append(row)
        k += 1
    print(
        f"{MAP.name}: {len(fmap.fixtures)} fixtures, {a.photos} photos of {least} to {most} "
        f"fixtures whole, seed {a.seed}, gravity 1 degree RMS off; "
        f"{time.perf_counter() - start:.0f} s (locate: {spent['prior']:.0f} s with the prior, "
        f"{spent['none']:.0f} s without)"
    )
    names = [("prior", f"prior within {a.within:g} m"), ("none", "no prior")]
    if least >= 4:
        names += [("no gravity", "no prior, no gravity"), ("room", "the room in view alone")]
    for name, words in names:
        ms = np.percentile(stage_ms[name], [50, 95, 100])
        print(
            f"{words}: identify and solve {ms[0]:.0f} ms (median), {ms[1]:.0f} (95 %), "
            f"{ms[2]:.0f} (max)"
        )
        _summary("all", [r for (n, _), v in rows.items() if n == name for r in v])
        for lights in sorted({c for n, c in rows if n == name}):
            _summary(f"{lights} fixtures whole", rows[(name, lights)])


if __name__ == "__main__":
    main()
