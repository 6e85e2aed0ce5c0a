"""How well each disc's estimated centre uncertainty matches its true centre error.

Renders of the thesis' room (camera on the floor and 1 m up, tilts up to 20 degrees, any
heading, exposures as in ``bench_gravity.py``); every fixture whole in the image is detected
and its centre compared with the true centre of its image (the projected centre plus the
perspective offset of the disc's ellipse, :func:`camvlp.geometry.disc.perspective_offset`).
Prints the estimated sigma (:attr:`camvlp.pipeline.detect.Blob.centre_sigma_px`) against the
true error: if the estimate is right, each axis' error over its sigma has an RMS near 1, the
squared Mahalanobis distance a mean near 2, and ``|error| / sigma`` a median near 1.18 (the
median of a Rayleigh distribution).

    python benchmarks/bench_centre_sigma.py --n 40
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import camvlp
from camvlp.geometry.disc import perspective_offset
from camvlp.pipeline.detect.candidates import detect_fixtures

ROOT = Path(__file__).resolve().parents[1]


def sample(camera, room, rng, height: float, tilt_max: float = 20.0):
    """A random pose and render settings from which at least one disc is whole in view."""
    while True:
        pose = camvlp.Pose.from_euler(
            [rng.uniform(-1.0, 1.0), -height, rng.uniform(-1.0, 1.0)],
            [
                90 + rng.uniform(-tilt_max, tilt_max),
                rng.uniform(-tilt_max, tilt_max),
                rng.uniform(-180, 180),
            ],
        )
        settings = camvlp.RenderSettings(
            exposure_s=rng.uniform(0.1, 1.0) / 10_000.0, seed=int(rng.integers(1 << 30))
        )
        truths = camvlp.fixture_truths(camera, room, pose, settings)
        if any(t.fully_inside for t in truths):
            return pose, settings


def measure(camera, room, n: int, rng) -> dict[str, np.ndarray]:
    """Per disc: error vector (K, 2), covariance (K, 2, 2), sigma (K,), edge points (K,),
    disc diameter in pixels (K,), and the camera height (K,)."""
    out: dict[str, list] = {"err": [], "cov": [], "sigma": [], "points": [], "diam": [], "h": []}
    for i in range(n):
        height = (0.0, 1.0)[i % 2]
        pose, settings = sample(camera, room, rng, height)
        photo = camvlp.render(camera, room, pose, settings)
        blobs = detect_fixtures(photo.image).blobs
        for f, t in zip(room.fixtures, photo.fixtures, strict=True):
            if not t.fully_inside:
                continue
            true = t.pixel + perspective_offset(camera, pose, f.position, f.diameter, f.normal)
            if camera.mirrored:
                true = np.array([camera.width - 1 - true[0], true[1]])
            near = [b for b in blobs if np.hypot(*(b.pixel - true)) < 0.25 * b.axes_px[1]]
            if len(near) != 1 or near[0].touches_border:
                continue
            b = near[0]
            out["err"].append(b.pixel - true)
            out["cov"].append(b.centre_cov_px2)
            out["sigma"].append(b.centre_sigma_px)
            out["points"].append(b.edge_points)
            out["diam"].append(float(b.axes_px[0]))
            out["h"].append(height)
    return {k: np.array(v) for k, v in out.items()}


def report(m: dict[str, np.ndarray]) -> None:
    """Print the comparison, all discs and per camera height."""
    print(
        "discs | height | |error| px: median / 95 % | sigma px: median | "
        "median |error|/sigma (1.18) | RMS error/sigma per axis u, v (1) | "
        "mean Mahalanobis^2 (2)"
    )
    for label, sel in (
        ("all", np.ones(len(m["h"]), bool)),
        ("0 m", m["h"] == 0.0),
        ("1 m", m["h"] == 1.0),
    ):
        ok = sel & np.isfinite(m["sigma"])
        err, cov, sigma = m["err"][ok], m["cov"][ok], m["sigma"][ok]
        norm = np.linalg.norm(err, axis=1)
        axis_sigma = np.sqrt(np.maximum(np.diagonal(cov, axis1=1, axis2=2), 1e-300))
        rms_axis = np.sqrt(np.mean((err / axis_sigma) ** 2, axis=0))
        maha = np.einsum("ki,kij,kj->k", err, np.linalg.inv(cov), err)
        print(
            f"{ok.sum()} | {label} | {np.median(norm):.4f} / {np.percentile(norm, 95):.4f} | "
            f"{np.median(sigma):.4f} | {np.median(norm / sigma):.2f} | "
            f"{rms_axis[0]:.2f}, {rms_axis[1]:.2f} | {np.mean(maha):.2f}"
        )
    bad = ~np.isfinite(m["sigma"])
    if bad.any():
        print(f"{int(bad.sum())} discs without an estimate (centroid fallback)")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=40, help="photos (half on the floor, half 1 m up)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    camera = camvlp.load_camera(ROOT / "examples/thesis_camera.yaml")
    room = camvlp.load_map(ROOT / "examples/thesis_room.yaml")
    report(measure(camera, room, args.n, np.random.default_rng(args.seed)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
