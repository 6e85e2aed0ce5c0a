"""Load test of ``camvlp serve`` on 127.0.0.1: fixes per second, latency, lost fixes.

Photos (``--mode photos``): renders a 1920 x 1080 and a 5184 x 3880 (20 MP) photo of the
thesis' room (JPEG), then for each photo and each number of service processes
(``--workers``) starts ``camvlp serve`` with a fresh SQLite file on a free port of 127.0.0.1
and sends the photo from ``--clients`` concurrent clients for ``--duration`` seconds (at most
``--max-requests`` requests per run; every request has a timeout).  It prints, per run: fixes
per second, median and 95th percentile latency, the statuses, and the lost fixes: answers 200
whose ``fix_id`` is not in the database afterwards (read back through the API), which must be
0, as must the 5xx.

Frames (``--mode frames``): renders 30 frames of a 1080p rolling-shutter video of a camera
going round a closed path under the thesis' room (``examples/video_camera.yaml``, 10 frames
per second) as JPEG, then ``--devices`` devices (8) each stream them to
``POST /api/v1/sites/{id}/frames`` at ``--fps`` (10) frames per second on their own schedule,
with the frame's gravity, at most ``--in-flight`` (2) requests in flight each: a tick that
finds them all out is skipped, as a phone's page that waits for its answers (the capture page
keeps one in flight; with three or more the service drops the older waiting frame, 409).
The path is closed, so each device's motion stays smooth as the frames loop.  While it runs,
``/metrics`` is read twice a second: the frames waiting (``camvlp_frame_queue_depth``) and
in hand.  It prints the answers (200 fixes, 409 frames dropped by the service, 5xx), the
latency of the fixes (median, 95th percentile), the frames located and their position error
against the truth, the queue's largest depth in each half of the run (a queue that grew
without bound would be larger in the second), and the lost fixes.

Only 127.0.0.1 is ever contacted.

Run: ``python benchmarks/bench_serve.py [--mode photos,frames] [--duration 30] [--clients 8]
[--workers 1,2] [--devices 8] [--fps 10]``.
"""

from __future__ import annotations

import argparse
import asyncio
import csv
import os
import secrets
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import cv2
import httpx
import numpy as np
import yaml

import camvlp
from camvlp.model.camera import Camera
from camvlp.sim.render import RenderSettings, render

ROOT = Path(__file__).resolve().parents[1]
HOST = "127.0.0.1"
#: The admin key of the benchmark's servers (it creates their one site).
ADMIN_KEY = secrets.token_urlsafe(32)


@dataclass(frozen=True)
class Photo:
    """A benchmark photo: its name, JPEG bytes, camera (as JSON keys) and true position."""

    name: str
    jpeg: bytes
    camera: dict
    position: np.ndarray


def _camera_json(cam: Camera) -> dict:
    return {
        "image_width": cam.width,
        "image_height": cam.height,
        "camera_matrix": cam.matrix.tolist(),
        "distortion_coefficients": cam.distortion.tolist(),
        "row_time_s": cam.row_time_s,
    }


def make_photos() -> list[Photo]:
    """The 1080p and 20 MP photos (the poses of ``bench_locate.py``)."""
    fmap = camvlp.load_map(ROOT / "examples/thesis_room.yaml")
    thesis = camvlp.load_camera(ROOT / "examples/thesis_camera.yaml")
    hd = Camera.from_focal(1920, 1080, 1200.0, row_time_s=30e-6)
    setups = [
        ("1080p", hd, camvlp.Pose.from_euler([0.0, -1.0, 0.0], [90.0, 0.0, 0.0]), 2),
        ("20MP", thesis, camvlp.Pose.from_euler([0.05, 0.0, -0.08], [91.0, 2.0, 15.0]), 1),
    ]
    photos = []
    for name, cam, pose, seed in setups:
        image = render(cam, fmap, pose, RenderSettings(seed=seed)).image
        ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 92])
        assert ok
        photos.append(Photo(name, buf.tobytes(), _camera_json(cam), pose.position))
    return photos


def _free_port() -> int:
    with socket.socket() as s:
        s.bind((HOST, 0))
        return s.getsockname()[1]


def start_server(db: Path, port: int, workers: int, threads: int) -> subprocess.Popen:
    """``camvlp serve`` on 127.0.0.1:port; returns once it answers (or raises)."""
    env = dict(os.environ)
    env["CAMVLP_ADMIN_KEY"] = ADMIN_KEY
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), env.get("PYTHONPATH", "")])
    cmd = [sys.executable, "-m", "camvlp", "serve", "--db", f"sqlite:///{db}", "--host", HOST]
    cmd += ["--port", str(port), "--workers", str(workers), "--threads", str(threads)]
    cmd += ["--log-level", "warning"]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(f"camvlp serve exited with {proc.returncode}")
        try:
            if httpx.get(f"http://{HOST}:{port}/api/v1/health", timeout=1).status_code == 200:
                return proc
        except httpx.HTTPError:
            pass
        time.sleep(0.2)
    proc.kill()
    raise RuntimeError("camvlp serve did not start within 60 s")


def stop_server(proc: subprocess.Popen) -> None:
    """SIGTERM, then SIGKILL after 20 s."""
    proc.terminate()
    try:
        proc.wait(20)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


async def _load(
    base: str, site: int, headers: dict, photo: Photo, clients: int, duration: float, cap: int
) -> tuple[list[float], Counter, list[int], float, list[float]]:
    """Send the photo from ``clients`` tasks until ``duration`` s or ``cap`` requests."""
    latencies: list[float] = []
    statuses: Counter = Counter()
    fix_ids: list[int] = []
    errors_m: list[float] = []
    sent = 0
    deadline = time.monotonic() + duration
    limits = httpx.Limits(max_connections=clients)

    async def client(http: httpx.AsyncClient, index: int) -> None:
        nonlocal sent
        while time.monotonic() < deadline and sent < cap:
            sent += 1
            t = time.perf_counter()
            try:
                r = await http.post(
                    f"{base}/api/v1/sites/{site}/locate",
                    headers=headers,
                    files={"photo": ("photo.jpg", photo.jpeg, "image/jpeg")},
                    data={"device": f"client-{index}"},
                )
            except httpx.HTTPError as exc:
                statuses[type(exc).__name__] += 1
                continue
            latencies.append(time.perf_counter() - t)
            statuses[r.status_code] += 1
            if r.status_code == 200:
                body = r.json()
                fix_ids.append(body["fix_id"])
                if body["position"] is not None:
                    errors_m.append(float(np.linalg.norm(body["position"] - photo.position)))

    t0 = time.monotonic()
    async with httpx.AsyncClient(timeout=120, limits=limits) as http:
        await asyncio.gather(*(client(http, i) for i in range(clients)))
    return latencies, statuses, fix_ids, time.monotonic() - t0, errors_m


def _stored_fix_ids(base: str, site: int, headers: dict) -> set[int]:
    ids: set[int] = set()
    params: dict = {"limit": 1000}
    while True:
        page = httpx.get(
            f"{base}/api/v1/sites/{site}/fixes", headers=headers, params=params, timeout=60
        ).json()
        ids.update(f["id"] for f in page["fixes"])
        if page["next_before"] is None:
            return ids
        params["before"] = page["next_before"]


def run(photo: Photo, workers: int, threads: int, args, tmp: Path) -> dict:
    """One load run against a fresh server; returns its figures."""
    db = tmp / f"{photo.name}-{workers}.db"
    port = _free_port()
    base = f"http://{HOST}:{port}"
    proc = start_server(db, port, workers, threads)
    try:
        room = yaml.safe_load((ROOT / "examples/thesis_room.yaml").read_text())
        r = httpx.post(
            f"{base}/api/v1/sites",
            json={"name": "bench", "map": room, "camera": photo.camera},
            headers={"Authorization": f"Bearer {ADMIN_KEY}"},
        )
        r.raise_for_status()
        site, headers = r.json()["id"], {"Authorization": f"Bearer {r.json()['api_key']}"}
        lat, statuses, fix_ids, elapsed, errors_m = asyncio.run(
            _load(base, site, headers, photo, args.clients, args.duration, args.max_requests)
        )
        stored = _stored_fix_ids(base, site, headers)
    finally:
        stop_server(proc)
    ok = statuses.get(200, 0)
    lat_ms = sorted(1e3 * x for x in lat)
    return {
        "photo": photo.name,
        "workers": workers,
        "threads": threads,
        "requests": sum(statuses.values()),
        "fixes_per_s": ok / elapsed,
        "p50_ms": statistics.median(lat_ms) if lat_ms else float("nan"),
        "p95_ms": lat_ms[min(len(lat_ms) - 1, int(0.95 * len(lat_ms)))] if lat_ms else float("nan"),
        "statuses": dict(statuses),
        "server_errors": sum(n for s, n in statuses.items() if isinstance(s, int) and s >= 500),
        "lost": len(set(fix_ids) - stored),
        "stored": len(stored),
        "max_error_mm": 1e3 * max(errors_m) if errors_m else float("nan"),
        "located": len(errors_m),
    }


@dataclass(frozen=True)
class Frames:
    """The frame benchmark's video: JPEG frames, their truth and gravity, and the camera."""

    jpegs: list[bytes]
    positions: np.ndarray  # (N, 3), metres
    gravity: np.ndarray  # (N, 3), the camera frame's gravity (unit)
    camera: dict


def make_frames(n: int = 30, fps: float = 10.0) -> Frames:
    """``n`` frames of a 1080p rolling-shutter video (JPEG, quality 90) of a camera going
    round a closed path under the thesis' room in ``n / fps`` seconds: 2.6 m under the
    ceiling, an ellipse of 0.2 x 0.15 m (0.4 m/s), the heading turning +-5 degrees; played
    in a loop, its motion stays smooth."""
    from camvlp.sim.video import Trajectory, render_video

    cam = camvlp.load_camera(ROOT / "examples/video_camera.yaml")
    room = camvlp.load_map(ROOT / "examples/thesis_room.yaml")
    t = np.linspace(0.0, n / fps, 4 * n + 1)
    w = 2 * np.pi * t / (n / fps)
    ones = np.ones_like(t)
    path = Trajectory(
        t,
        np.stack([0.2 * np.cos(w), -0.1 * ones, 0.15 * np.sin(w)], axis=1),
        np.stack([90.0 * ones, 0.0 * ones, 10 + 5 * np.sin(w)], axis=1),
    )
    down = -np.asarray(room.up, dtype=float)
    with tempfile.TemporaryDirectory() as d:
        render_video(cam, room, path, Path(d), fps=fps, settings=RenderSettings(seed=1),
                     max_frames=n)  # fmt: skip
        jpegs, positions, gravity = [], [], []
        with (Path(d) / "truth.csv").open() as fh:
            rows = list(csv.DictReader(fh))
        for row in rows:
            image = cv2.imread(str(Path(d) / row["frame"]))
            ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 90])
            assert ok
            jpegs.append(buf.tobytes())
            pose = camvlp.Pose.from_euler(
                [float(row[c]) for c in "xyz"], [float(row[f"theta_{c}"]) for c in "xyz"]
            )
            positions.append(pose.position)
            gravity.append(pose.world_from_camera.T @ down)
    return Frames(jpegs, np.array(positions), np.array(gravity), _camera_json(cam))


async def _watch_metrics(
    http: httpx.AsyncClient,
    base: str,
    t_start: float,
    deadline: float,
    depth: list[tuple[float, float, float]],
) -> None:
    """Read ``/metrics`` twice a second until ``deadline``: ``(s since the start, frames
    waiting, photos and frames in hand)`` appended to ``depth``."""
    names = ("camvlp_frame_queue_depth ", "camvlp_locate_in_hand ")
    while time.monotonic() < deadline:
        try:
            text = (await http.get(f"{base}/metrics")).text
        except httpx.HTTPError:
            text = ""
        values = dict(line.split(" ", 1) for line in text.splitlines() if line.startswith(names))
        depth.append(
            (
                time.monotonic() - t_start,
                float(values.get("camvlp_frame_queue_depth", "nan")),
                float(values.get("camvlp_locate_in_hand", "nan")),
            )
        )
        await asyncio.sleep(0.5)


async def _stream(base: str, site: int, headers: dict, frames: Frames, args) -> dict:
    """``args.devices`` devices streaming for ``args.duration`` s (at most
    ``args.max_requests`` requests in all), ``/metrics`` read meanwhile."""
    period, n = 1.0 / args.fps, len(frames.jpegs)
    latencies: list[float] = []
    statuses: Counter = Counter()
    located, errors_mm, fix_ids, skipped = [0], [], [], [0]
    server_ms: list[float] = []
    depth: list[tuple[float, float, float]] = []  # (time, frames waiting, in hand)
    sent = [0]
    t_start = time.monotonic()
    deadline = t_start + args.duration

    async def one(http, device: str, k: int, t: float) -> None:
        i = k % n  # the path is closed: the loop goes on smoothly
        g = ",".join(f"{v:.6f}" for v in frames.gravity[i])
        params = {"device": device, "t": f"{t:.4f}", "gravity": g}
        if k == 0:
            params["reset"] = "true"
        t0 = time.perf_counter()
        try:
            r = await http.post(
                f"{base}/api/v1/sites/{site}/frames",
                params=params,
                content=frames.jpegs[i],
                headers={**headers, "Content-Type": "image/jpeg"},
            )
        except httpx.HTTPError as exc:
            statuses[type(exc).__name__] += 1
            return
        statuses[r.status_code] += 1
        if r.status_code == 200:
            latencies.append(time.perf_counter() - t0)
            body = r.json()
            fix_ids.append(body["fix_id"])
            server_ms.append(body["timing_ms"]["locate"])
            if body["located"]:
                located[0] += 1
                errors_mm.append(
                    1e3 * np.linalg.norm(np.array(body["position"]) - frames.positions[i])
                )

    async def device(http, index: int) -> None:
        name, in_flight, tasks, k = f"device-{index}", [], [], 0
        next_tick = time.monotonic() + index * period / args.devices  # spread the devices
        while time.monotonic() < deadline and sent[0] < args.max_requests:
            await asyncio.sleep(max(0.0, next_tick - time.monotonic()))
            next_tick += period
            in_flight = [task for task in in_flight if not task.done()]
            if len(in_flight) >= args.in_flight:
                skipped[0] += 1
                continue
            sent[0] += 1
            task = asyncio.create_task(one(http, name, k, k * period))
            in_flight.append(task)
            tasks.append(task)
            k += 1
        await asyncio.gather(*tasks)

    limits = httpx.Limits(max_connections=3 * args.devices)
    async with httpx.AsyncClient(timeout=60, limits=limits) as http:
        await asyncio.gather(
            _watch_metrics(http, base, t_start, deadline, depth),
            *(device(http, i) for i in range(args.devices)),
        )
    elapsed = time.monotonic() - t_start
    half = args.duration / 2
    first = [d for t, d, _ in depth if t < half]
    second = [d for t, d, _ in depth if t >= half]
    lat_ms = sorted(1e3 * x for x in latencies)
    return {
        "sent": sent[0],
        "skipped": skipped[0],
        "statuses": dict(statuses),
        "fixes_per_s": statuses.get(200, 0) / elapsed,
        "p50_ms": statistics.median(lat_ms) if lat_ms else float("nan"),
        "p95_ms": lat_ms[min(len(lat_ms) - 1, int(0.95 * len(lat_ms)))] if lat_ms else float("nan"),
        "server_locate_ms": statistics.median(server_ms) if server_ms else float("nan"),
        "located": located[0],
        "median_error_mm": statistics.median(errors_mm) if errors_mm else float("nan"),
        "max_depth_first_half": max(first, default=float("nan")),
        "max_depth_second_half": max(second, default=float("nan")),
        "max_in_hand": max((h for _, _, h in depth), default=float("nan")),
        "fix_ids": fix_ids,
    }


def run_frames(frames: Frames, args, tmp: Path) -> dict:
    """The frame path against a fresh one-process server; returns its figures."""
    port = _free_port()
    base = f"http://{HOST}:{port}"
    proc = start_server(tmp / "frames.db", port, 1, args.threads)
    try:
        room = yaml.safe_load((ROOT / "examples/thesis_room.yaml").read_text())
        r = httpx.post(
            f"{base}/api/v1/sites",
            json={"name": "bench frames", "map": room, "camera": frames.camera},
            headers={"Authorization": f"Bearer {ADMIN_KEY}"},
        )
        r.raise_for_status()
        site, headers = r.json()["id"], {"Authorization": f"Bearer {r.json()['api_key']}"}
        res = asyncio.run(_stream(base, site, headers, frames, args))
        stored = _stored_fix_ids(base, site, headers)
    finally:
        stop_server(proc)
    res["lost"] = len(set(res.pop("fix_ids")) - stored)
    res["server_errors"] = sum(
        n for s, n in res["statuses"].items() if not isinstance(s, int) or s >= 500
    )
    return res


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--duration", type=float, default=30.0, help="seconds of load per run")
    ap.add_argument("--clients", type=int, default=8, help="concurrent clients")
    ap.add_argument("--workers", default="1,2", help="service processes to try, e.g. 1,2")
    ap.add_argument("--threads", type=int, default=2, help="locate threads per process")
    ap.add_argument("--max-requests", type=int, default=5000, help="cap per run")
    ap.add_argument("--photos", default="1080p,20MP", help="which photos: 1080p, 20MP")
    ap.add_argument("--mode", default="photos,frames", help="photos, frames, or both")
    ap.add_argument("--devices", type=int, default=8, help="devices streaming frames")
    ap.add_argument("--fps", type=float, default=10.0, help="frames per second per device")
    ap.add_argument(
        "--in-flight", type=int, default=2, help="most frame requests a device has in flight"
    )
    args = ap.parse_args()
    if not (0 < args.duration <= 600 and 0 < args.clients <= 64 and 0 < args.max_requests):
        ap.error("--duration must be in (0, 600] s, --clients in 1..64, --max-requests > 0")
    if not (0 < args.devices <= 64 and 0 < args.fps <= 60 and 0 < args.in_flight <= 8):
        ap.error("--devices must be in 1..64, --fps in (0, 60], --in-flight in 1..8")
    modes = set(args.mode.split(","))
    failed = False
    if "frames" in modes:
        failed |= frame_benchmark(args)
    if "photos" not in modes:
        return 1 if failed else 0
    workers = [int(w) for w in args.workers.split(",")]
    wanted = set(args.photos.split(","))
    photos = [p for p in make_photos() if p.name in wanted]
    print(
        f"camvlp serve on {HOST}, {os.cpu_count()} cores, {args.clients} clients, "
        f"{args.duration:g} s per run, {args.threads} locate threads per process, SQLite"
    )
    for p in photos:
        print(f"  {p.name}: {p.camera['image_width']} x {p.camera['image_height']}, "
              f"JPEG {len(p.jpeg) / 1e6:.2f} MB")  # fmt: skip
    print()
    header = (
        f"{'photo':<6} {'workers':>7} {'requests':>8} {'fixes/s':>8} {'p50 ms':>8} "
        f"{'p95 ms':>8} {'5xx':>4} {'lost':>4} {'load':>5}  statuses / max position error"
    )
    print(header)
    with tempfile.TemporaryDirectory() as d:
        for photo in photos:
            for w in workers:
                res = run(photo, w, args.threads, args, Path(d))
                load = os.getloadavg()[0]  # 1-minute load average: others' jobs show here
                failed |= res["lost"] > 0 or res["server_errors"] > 0
                print(
                    f"{res['photo']:<6} {res['workers']:>7} {res['requests']:>8} "
                    f"{res['fixes_per_s']:>8.2f} {res['p50_ms']:>8.0f} {res['p95_ms']:>8.0f} "
                    f"{res['server_errors']:>4} {res['lost']:>4} {load:>5.1f}  {res['statuses']}, "
                    f"{res['located']} located, max error {res['max_error_mm']:.2f} mm",
                    flush=True,
                )
    return 1 if failed else 0


def frame_benchmark(args) -> bool:
    """The frame path's run, printed; True when it lost a fix or answered 5xx."""
    frames = make_frames()
    size = f"{frames.camera['image_width']} x {frames.camera['image_height']}"
    kb = statistics.mean(len(j) for j in frames.jpegs) / 1e3
    print(
        f"camvlp serve on {HOST}, {os.cpu_count()} cores, 1 process, {args.threads} locate "
        f"threads, SQLite; {args.devices} devices x {args.fps:g} frames/s of {size} JPEG "
        f"(mean {kb:.0f} kB) for {args.duration:g} s, at most {args.in_flight} requests in "
        "flight each"
    )
    with tempfile.TemporaryDirectory() as d:
        res = run_frames(frames, args, Path(d))
    load = os.getloadavg()[0]
    print(
        f"frames: {res['sent']} sent ({res['skipped']} ticks skipped, {args.in_flight} in "
        "flight), "
        f"statuses {res['statuses']}, {res['fixes_per_s']:.1f} fixes/s; latency of the fixes "
        f"p50 {res['p50_ms']:.0f} ms, p95 {res['p95_ms']:.0f} ms (server's locate "
        f"{res['server_locate_ms']:.0f} ms median); {res['located']} located, median error "
        f"{res['median_error_mm']:.2f} mm; frames waiting at most "
        f"{res['max_depth_first_half']:g} (first half) and {res['max_depth_second_half']:g} "
        f"(second half), at most {res['max_in_hand']:g} in hand; {res['server_errors']} 5xx, "
        f"{res['lost']} lost fixes; load {load:.1f}",
        flush=True,
    )
    print()
    return res["lost"] > 0 or res["server_errors"] > 0


if __name__ == "__main__":
    raise SystemExit(main())
