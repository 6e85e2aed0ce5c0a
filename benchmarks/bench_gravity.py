"""Locating from two or three fixtures with gravity: rendered photos and a geometry sweep.

Part 1, renders: full-size photographs of the thesis' room with exactly two or exactly three
fixtures in view (the others out of the image or cut by its border), camera on the floor and
1 m up, tilts up to 20 degrees about x and y, any heading; gravity from the true pose turned by
a Gaussian angle of ``--gravity-noise-deg`` (0.5) per axis.  ``camvlp.locate(...,
gravity=...)`` locates them; prints how many were located, positions from wrong IDs and the
error, per case.

Part 2, geometry (``--sweep``): the position error against the accelerometer's error (0 to 3
degrees, exactly that angle in a random direction) for 2, 3 and 4 fixtures, fixture centres
with ``--noise-px`` (0.1) Gaussian noise; a table, and a CSV and PNG with ``--out``.

    python benchmarks/bench_gravity.py --n 20
    python benchmarks/bench_gravity.py --sweep --trials 300 --out out/gravity
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

import camvlp
from camvlp.geometry.gravity import map_up, solve_pose_gravity
from camvlp.geometry.pose import estimate_pose
from camvlp.sim.render import fixture_truths

ROOT = Path(__file__).resolve().parents[1]


def turn(g: np.ndarray, angle_deg: float, rng: np.random.Generator) -> np.ndarray:
    """``g`` turned by ``angle_deg`` about a random axis perpendicular to it."""
    axis = rng.normal(size=3)
    axis -= (axis @ g) * g / (g @ g)
    axis /= np.linalg.norm(axis)
    return Rotation.from_rotvec(np.radians(angle_deg) * axis).apply(g)


def noisy_gravity(pose: camvlp.Pose, up: np.ndarray, sigma_deg: float, rng) -> np.ndarray:
    """Gravity in the camera frame (9.81 long), off by a Gaussian sigma_deg per axis."""
    g = 9.81 * (pose.world_from_camera.T @ -up)
    angle = np.hypot(*rng.normal(0.0, sigma_deg, 2))
    return turn(g, angle, rng)


def _outside(camera, truth) -> bool:
    """The fixture's disc is wholly outside the image (or behind the camera)."""
    if not truth.in_front:
        return True
    u, v = truth.pixel
    du = max(0.0, -0.5 - u, u - (camera.width - 0.5))
    dv = max(0.0, -0.5 - v, v - (camera.height - 0.5))
    return float(np.hypot(du, dv)) > 0.6 * truth.rows_spanned + 2.0


def sample_pose(rng, camera, room, settings, k: int, height: float, tilt_max: float = 20.0):
    """A random pose from which exactly ``k`` fixtures are whole in the image and decodable,
    and the others wholly outside it."""
    for _ in range(100_000):
        pos = [rng.uniform(-1.0, 1.0), -height, rng.uniform(-1.0, 1.0)]
        euler = [
            90 + rng.uniform(-tilt_max, tilt_max),
            rng.uniform(-tilt_max, tilt_max),
            rng.uniform(-180, 180),
        ]
        pose = camvlp.Pose.from_euler(pos, euler)
        truths = fixture_truths(camera, room, pose, settings)
        inside = [t for t in truths if t.fully_inside]
        if len(inside) == k and all(t.frames_spanned >= 1.2 for t in inside):
            if all(_outside(camera, t) for t in truths if not t.fully_inside):
                return pose
    raise RuntimeError(f"no pose with exactly {k} fixtures in view")


def run_case(
    camera,
    room,
    k: int,
    height: float,
    n: int,
    sigma: float,
    rng,
    sigma_given: float = 1.0,
    centre_sigma: float | None = None,
) -> dict:
    """Render and locate ``n`` photos with exactly ``k`` fixtures in view."""
    up = map_up(room.positions, up=room.up)
    errors, wrong_positions, wrong_ids, solvers = [], 0, 0, []
    reasons: list[str] = []
    settings = camvlp.LocateSettings(gravity_sigma_deg=sigma_given, centre_sigma_px=centre_sigma)
    for _ in range(n):
        render_settings = camvlp.RenderSettings(
            exposure_s=rng.uniform(0.1, 1.0) / 10_000.0, seed=int(rng.integers(1 << 30))
        )
        pose = sample_pose(rng, camera, room, render_settings, k, height)
        photo = camvlp.render(camera, room, pose, render_settings)
        g = noisy_gravity(pose, up, sigma, rng)
        res = camvlp.locate(photo.image, camera, room, settings, gravity=g)
        truth = {t.id: t.pixel for t in photo.fixtures if t.in_front}
        bad = 0
        for f in res.fixtures:
            nearest = min(truth, key=lambda i: np.hypot(*(truth[i] - f.pixel)))
            if f.id is not None and f.id != nearest:
                bad += 1
                wrong_ids += 1
        if res:
            errors.append(float(np.linalg.norm(res.position - pose.position)))
            wrong_positions += int(bad > 0 and any(f.used for f in res.fixtures))
            solvers.append(res.solver)
        else:
            errors.append(float("nan"))
            reasons.append(res.error)
    e = np.array(errors)
    ok = np.isfinite(e)
    return {
        "k": k,
        "height": height,
        "n": n,
        "located": int(ok.sum()),
        "wrong_ids": wrong_ids,
        "wrong_positions": wrong_positions,
        "mean_mm": 1e3 * float(np.mean(e[ok])) if ok.any() else float("nan"),
        "median_mm": 1e3 * float(np.median(e[ok])) if ok.any() else float("nan"),
        "max_mm": 1e3 * float(np.max(e[ok])) if ok.any() else float("nan"),
        "solvers": sorted(set(solvers)),
        "reasons": reasons,
    }


def renders(args) -> int:
    camera = camvlp.load_camera(ROOT / "examples/thesis_camera.yaml")
    room = camvlp.load_map(ROOT / "examples/thesis_room.yaml")
    rng = np.random.default_rng(args.seed)
    print(
        f"gravity noise {args.gravity_noise_deg} deg per axis; given sigmas: gravity "
        f"{args.sigma_deg} deg, centres "
        + ("each disc's own" if args.centre_sigma_px is None else f"{args.centre_sigma_px} px")
    )
    print(
        "fixtures | height | located | wrong IDs | positions from wrong IDs | "
        "mean / median / max error (mm)"
    )
    t0 = time.perf_counter()
    for k in map(int, args.fixtures.split(",")):
        for height in (0.0, 1.0):
            r = run_case(
                camera,
                room,
                k,
                height,
                args.n,
                args.gravity_noise_deg,
                rng,
                args.sigma_deg,
                args.centre_sigma_px,
            )
            print(
                f"{k} | {height:g} m | {r['located']} / {r['n']} | {r['wrong_ids']} | "
                f"{r['wrong_positions']} | {r['mean_mm']:.2f} / {r['median_mm']:.2f} / "
                f"{r['max_mm']:.2f} | {','.join(r['solvers'])}"
            )
            for reason in r["reasons"]:
                print("   not located:", reason)
    print(f"({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
    return 0


def sweep(args) -> int:
    camera = camvlp.load_camera(ROOT / "examples/thesis_camera.yaml")
    room = camvlp.load_map(ROOT / "examples/thesis_room.yaml")
    pts = room.positions
    normals = np.array([f.normal for f in room.fixtures])
    up = map_up(pts, up=room.up, normals=normals)
    angles = [0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0]
    rows = []
    print(
        f"pixel noise {args.noise_px} px, {args.trials} poses per cell (floor and 1 m up, "
        "tilts up to 10 deg), sigma given 1 deg; error in mm: mean / median / 95 %"
    )
    print("gravity error (deg) | 2 fixtures | 3 fixtures | 4 fixtures | 4 fixtures, no gravity")
    for angle in angles:
        rng = np.random.default_rng(args.seed)
        errs: dict[object, list[float]] = {2: [], 3: [], 4: [], "pnp": []}
        for _ in range(args.trials):
            height = float(rng.choice([0.0, 1.0]))
            pose = camvlp.Pose.from_euler(
                [rng.uniform(-1, 1), -height, rng.uniform(-1, 1)],
                [90 + rng.uniform(-10, 10), rng.uniform(-10, 10), rng.uniform(-180, 180)],
            )
            order = rng.permutation(4)
            uv = camera.project(pose, pts[order]) + rng.normal(0, args.noise_px, (4, 2))
            g = turn(9.81 * (pose.world_from_camera.T @ -up), angle, rng)
            for n in (2, 3, 4):
                res = solve_pose_gravity(
                    uv[:n], pts[order][:n], camera, g, up=up, normals=normals[order][:n]
                )
                errs[n].append(np.linalg.norm(res.pose.position - pose.position) if res else np.nan)
            est = estimate_pose(uv, pts[order], camera)
            errs["pnp"].append(np.linalg.norm(est.pose.position - pose.position) if est else np.nan)
        cells = []
        row = [angle]
        for key in (2, 3, 4, "pnp"):
            e = 1e3 * np.array(errs[key])
            ok = np.isfinite(e)
            mean, med, p95 = np.mean(e[ok]), np.median(e[ok]), np.percentile(e[ok], 95)
            fails = int((~ok).sum())
            cells.append(
                f"{mean:.2f} / {med:.2f} / {p95:.2f}" + (f" ({fails} failed)" if fails else "")
            )
            row += [mean, med, p95, fails]
        rows.append(row)
        print(f"{angle:g} | " + " | ".join(cells))
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        header = ["gravity_error_deg"] + [
            f"{key}_{stat}"
            for key in ("two", "three", "four", "four_no_gravity")
            for stat in ("mean_mm", "median_mm", "p95_mm", "failures")
        ]
        with open(out / "gravity_error.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(header)
            w.writerows([[f"{v:.6g}" for v in r] for r in rows])
        plot(np.array(rows), out / "gravity_error.png", args)
        print(f"wrote {out / 'gravity_error.csv'} and {out / 'gravity_error.png'}")
    return 0


def plot(rows: np.ndarray, path: Path, args) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.4, 4.4), layout="constrained")
    ax = fig.subplots()
    labels = [
        "2 fixtures + gravity",
        "3 fixtures + gravity",
        "4 fixtures + gravity",
        "4 fixtures, no gravity",
    ]
    for j, label in enumerate(labels):
        ax.plot(rows[:, 0], rows[:, 1 + 4 * j], "o-", label=f"{label} (mean)")
    ax.set_yscale("log")
    ax.set_xlabel("accelerometer error (degrees)")
    ax.set_ylabel("camera position error (mm)")
    ax.set_title(
        f"Thesis' room, floor and 1 m up, tilts to 10°, {args.noise_px:g} px centre noise\n"
        f"{args.trials} poses per point, gravity sigma given 1°"
    )
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    fig.savefig(path, dpi=110)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=20, help="photos per case (renders)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--gravity-noise-deg", type=float, default=0.5)
    ap.add_argument("--fixtures", default="2,3", help="fixtures in view, e.g. 2,3 (renders)")
    ap.add_argument("--sigma-deg", type=float, default=1.0, help="gravity sigma given")
    ap.add_argument(
        "--centre-sigma-px",
        type=float,
        default=None,
        help="centre sigma given, px (default: each disc's own estimate)",
    )
    ap.add_argument("--sweep", action="store_true", help="the geometry sweep instead")
    ap.add_argument("--trials", type=int, default=300, help="poses per cell (sweep)")
    ap.add_argument("--noise-px", type=float, default=0.1, help="centre noise, px (sweep)")
    ap.add_argument("--out", help="directory for the sweep's CSV and PNG")
    args = ap.parse_args()
    return sweep(args) if args.sweep else renders(args)


if __name__ == "__main__":
    raise SystemExit(main())
