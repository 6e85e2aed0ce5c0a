"""Load test of ``camvlp serve`` on 127.0.0.1: fixes per second, latency, lost fixes.

Renders a 1920 x 1080 and a 5184 x 3880 (20 MP) photo of the thesis' room (JPEG), then for
each photo and each number of service processes (``--workers``) starts ``camvlp serve`` with
a fresh SQLite file on a free port of 127.0.0.1 and sends the photo from ``--clients``
concurrent clients for ``--duration`` seconds (at most ``--max-requests`` requests per run;
every request has a timeout).  It prints, per run: fixes per second, median and 95th
percentile latency, the statuses, and the lost fixes: answers 200 whose ``fix_id`` is not in
the database afterwards (read back through the API), which must be 0, as must the 5xx.

Only 127.0.0.1 is ever contacted.

Run: ``python benchmarks/bench_serve.py [--duration 30] [--clients 8] [--workers 1,2]``.
"""

from __future__ import annotations

import argparse
import asyncio
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


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--duration", type=float, default=30.0, help="seconds of load per run")
    ap.add_argument("--clients", type=int, default=8, help="concurrent clients")
    ap.add_argument("--workers", default="1,2", help="service processes to try, e.g. 1,2")
    ap.add_argument("--threads", type=int, default=2, help="locate threads per process")
    ap.add_argument("--max-requests", type=int, default=5000, help="cap per run")
    ap.add_argument("--photos", default="1080p,20MP", help="which photos: 1080p, 20MP")
    args = ap.parse_args()
    if not (0 < args.duration <= 600 and 0 < args.clients <= 64 and 0 < args.max_requests):
        ap.error("--duration must be in (0, 600] s, --clients in 1..64, --max-requests > 0")
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
    failed = False
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


if __name__ == "__main__":
    raise SystemExit(main())
