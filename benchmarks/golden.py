"""Record what ``camvlp.locate`` answers on a fixed set of photos, and compare two records.

A speed change that means to leave the results alone is checked with this: record on the
code before, record on the code after, compare.  The set: the two photos of
``bench_locate.py``, and photos of the stress benchmark's grid (``stress_decode.py``'s
``draw_photo``: plain discs, lamps with hot cores and halos, and a phone's processing, over
exposures of 0.1 to 1 chip and 2 to 12 rows per chip), each stored as a JPEG and decoded
again, as the stress benchmark does.

Every field that ``locate`` reports is recorded: the position and rotation, the reason, the
readout, the photo-wide parameters, and per fixture its ID, pixel, margin, reason, Hamming
distance, extent, chip length, reprojection error, centre sigma and look-alikes.

Run::

    python benchmarks/golden.py record out/golden/before.json [--per-look 12 --seed 5]
    python benchmarks/golden.py compare out/golden/before.json out/golden/after.json [--tol 0]

``compare`` prints every value that differs by more than ``--tol`` (absolute, on numbers;
exact on everything else) and exits 1 when any does.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import cv2
import numpy as np

import camvlp
from camvlp import locate
from camvlp.model.camera import Camera

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_locate import HD
from stress_decode import EXPOSURES, ROWS_PER_CHIP, draw_photo

from camvlp.sim.render import RenderSettings, render

ROOT = Path(__file__).resolve().parents[1]
LOOKS = {
    "plain": dict(looks=False),
    "lamps": dict(looks=True),
    "phone": dict(looks=True, phone=True),
}


def _value(x):
    """A JSON value of a result's field: floats as they are (NaN and inf as strings)."""
    if isinstance(x, np.ndarray):
        return [_value(v) for v in x.tolist()]
    if isinstance(x, (list, tuple)):
        return [_value(v) for v in x]
    if isinstance(x, (float, np.floating)):
        x = float(x)
        return x if math.isfinite(x) else str(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (str, int, bool)) or x is None:
        return x
    return str(x)


def _record(res) -> dict:
    """Every field of a :class:`~camvlp.pipeline.results.LocateResult` worth comparing."""
    out = {
        k: _value(getattr(res, k))
        for k in (
            "position",
            "rotation",
            "reprojection_rms_px",
            "reason",
            "readout",
            "mirrored",
            "alternative_position",
            "alternative_rms_px",
            "notes",
            "rows_per_chip",
            "exposure_chips",
            "position_sigma",
        )
    }
    out["located"], out["fixtures"] = bool(res), []
    for f in res.fixtures:
        out["fixtures"].append(
            {
                k: _value(getattr(f, k))
                for k in (
                    "id",
                    "pixel",
                    "used",
                    "margin",
                    "reason",
                    "hamming",
                    "rows_spanned",
                    "rows_per_chip",
                    "residual_px",
                    "frequency_hz",
                    "centre_sigma_px",
                    "look_alikes",
                )
            }
        )
    return out


def _photos(per_look: int, seed: int):
    """``(name, image, camera, map)`` of every photo of the set, in a fixed order."""
    fmap = camvlp.load_map(ROOT / "examples/thesis_room.yaml")
    thesis = camvlp.load_camera(ROOT / "examples/thesis_camera.yaml")
    hd = Camera.from_focal(*HD[:3], row_time_s=HD[3])
    for name, cam, pose, s in (
        ("bench-20MP", thesis, camvlp.Pose.from_euler([0.05, 0.0, -0.08], [91.0, 2.0, 15.0]), 1),
        ("bench-1080p", hd, camvlp.Pose.from_euler([0.0, -1.0, 0.0], [90.0, 0.0, 0.0]), 2),
    ):
        photo = render(cam, fmap, pose, RenderSettings(seed=s))
        _, buf = cv2.imencode(".jpg", photo.image, [cv2.IMWRITE_JPEG_QUALITY, 92])
        yield name, cv2.imdecode(buf, cv2.IMREAD_COLOR), cam, fmap
    cells = [(e, r) for e in EXPOSURES for r in ROWS_PER_CHIP]
    for li, (look, kw) in enumerate(LOOKS.items()):
        rng = np.random.default_rng([seed, li])
        for i in range(per_look):
            e, r = cells[int(rng.integers(len(cells)))]
            d = draw_photo(rng, e, r, **kw)
            photo = render(d.camera, d.fmap, camvlp.Pose(np.eye(3), np.zeros(3)), d.settings)
            _, buf = cv2.imencode(".jpg", photo.image, [cv2.IMWRITE_JPEG_QUALITY, d.quality])
            yield f"{look}-{i}-e{e}-r{r}", cv2.imdecode(buf, cv2.IMREAD_COLOR), d.camera, d.fmap


def record(path: Path, per_look: int, seed: int) -> int:
    results, t0 = {}, time.perf_counter()
    for name, image, cam, fmap in _photos(per_look, seed):
        results[name] = _record(locate(image, cam, fmap))
        print(
            f"{name}: {len(results[name]['fixtures'])} fixtures, located "
            f"{results[name]['located']}",
            file=sys.stderr,
        )
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(results, indent=1))
    print(f"{len(results)} photos recorded in {time.perf_counter() - t0:.0f} s: {path}")
    return 0


def _diff(a, b, tol: float, where: str, out: list[str]) -> None:
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            _diff(a.get(k), b.get(k), tol, f"{where}.{k}", out)
    elif isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _diff(x, y, tol, f"{where}[{i}]", out)
    elif (
        isinstance(a, (int, float))
        and isinstance(b, (int, float))
        and not isinstance(a, bool)
        and not isinstance(b, bool)
    ):
        if abs(a - b) > tol:
            out.append(f"{where}: {a!r} -> {b!r}")
    elif a != b:
        out.append(f"{where}: {a!r} -> {b!r}")


def compare(a: Path, b: Path, tol: float) -> int:
    ra, rb = json.loads(a.read_text()), json.loads(b.read_text())
    out: list[str] = []
    _diff(ra, rb, tol, "", out)
    for line in out:
        print(line)
    n_fix = sum(len(r["fixtures"]) for r in ra.values())
    print(f"{len(ra)} photos, {n_fix} fixtures: {len(out)} values differ by more than {tol}")
    return 1 if out else 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("record")
    r.add_argument("out", type=Path)
    r.add_argument("--per-look", type=int, default=12, help="stress photos per look")
    r.add_argument("--seed", type=int, default=5)
    c = sub.add_parser("compare")
    c.add_argument("a", type=Path)
    c.add_argument("b", type=Path)
    c.add_argument("--tol", type=float, default=0.0)
    args = ap.parse_args()
    cv2.setNumThreads(1)
    if args.cmd == "record":
        return record(args.out, args.per_look, args.seed)
    return compare(args.a, args.b, args.tol)


if __name__ == "__main__":
    raise SystemExit(main())
