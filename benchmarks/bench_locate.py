"""Speed and memory of ``camvlp.locate`` against decoding the photo's JPEG.

Renders a 5184 x 3880 photo of the thesis' room and a 1920 x 1080 one, saves them as JPEG,
then prints, as medians of several runs in one process, the time of ``cv2.imdecode`` of
each JPEG, the time of ``camvlp.locate`` on the decoded image (per stage), their ratio, and
the peak memory of a fresh process that decodes and locates the 20-megapixel photo.

Run: ``python benchmarks/bench_locate.py [--runs 15]``.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
from camvlp.locate import locate

import camvlp
from camvlp.model.camera import Camera
from camvlp.sim.render import RenderSettings, render

ROOT = Path(__file__).resolve().parents[1]


def _peak_child(jpeg: Path) -> dict:
    """Peak resident memory of a fresh process: imports, then decode, then locate."""
    code = f"""
import json, re, cv2, numpy as np, camvlp
from camvlp.locate import locate
def rss():  # high-water mark of resident memory, MB (VmHWM is reset by exec, ru_maxrss is not)
    status = open("/proc/self/status").read()
    return int(re.search(r"VmHWM:\\s+(\\d+) kB", status).group(1)) / 1024
base = rss()
cam = camvlp.load_camera({str(ROOT / "examples/thesis_camera.yaml")!r})
fmap = camvlp.load_map({str(ROOT / "examples/thesis_room.yaml")!r})
img = cv2.imdecode(np.fromfile({str(jpeg)!r}, np.uint8), cv2.IMREAD_COLOR)
decoded = rss()
res = locate(img, cam, fmap)
print(json.dumps(dict(after_imports_mb=base, after_decode_mb=decoded, peak_mb=rss(),
                      located=bool(res))))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def _bench(name: str, camera: Camera, fmap, pose, settings: RenderSettings, runs: int, tmp: Path):
    photo = render(camera, fmap, pose, settings)
    path = tmp / f"{name}.jpg"
    cv2.imwrite(str(path), photo.image, [cv2.IMWRITE_JPEG_QUALITY, 92])
    data = np.fromfile(str(path), np.uint8)
    decode_ms, locate_ms = [], []
    stages: dict[str, list[float]] = {"detect": [], "decode": [], "pose": []}
    result = None
    for _ in range(runs):
        t = time.perf_counter()
        img = cv2.imdecode(data, cv2.IMREAD_COLOR)
        decode_ms.append(1e3 * (time.perf_counter() - t))
        t = time.perf_counter()
        result = locate(img, camera, fmap)
        locate_ms.append(1e3 * (time.perf_counter() - t))
        for k in stages:
            stages[k].append(result.timing_ms[k])
    err_mm = (
        1e3 * float(np.linalg.norm(result.position - pose.position)) if result else float("nan")
    )
    med_dec, med_loc = statistics.median(decode_ms), statistics.median(locate_ms)
    print(f"{name}: {camera.width} x {camera.height}, JPEG {data.size / 1e6:.1f} MB, {runs} runs")
    print(f"  cv2.imdecode          median {med_dec:7.1f} ms")
    print(
        f"  camvlp.locate         median {med_loc:7.1f} ms   (locate / imdecode = "
        f"{med_loc / med_dec:.2f})"
    )
    for k, v in stages.items():
        print(f"    {k:<8}            median {statistics.median(v):7.1f} ms")
    print(
        f"  located: {bool(result)}, position error {err_mm:.3f} mm, "
        f"{sum(f.used for f in result.fixtures)} fixtures used"
    )
    return path, med_dec, med_loc


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--runs", type=int, default=15)
    args = ap.parse_args()
    cv2.setNumThreads(1)
    fmap = camvlp.load_map(ROOT / "examples/thesis_room.yaml")
    thesis = camvlp.load_camera(ROOT / "examples/thesis_camera.yaml")
    hd = Camera.from_focal(1920, 1080, 1200.0, row_time_s=30e-6)
    pose = camvlp.Pose.from_euler([0.05, 0.0, -0.08], [91.0, 2.0, 15.0])
    print(f"OpenCV {cv2.__version__}, NumPy {np.__version__}, OpenCV threads 1")
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        big, _, _ = _bench("20MP", thesis, fmap, pose, RenderSettings(seed=1), args.runs, tmp)
        _bench(
            "1080p",
            hd,
            fmap,
            camvlp.Pose.from_euler([0.0, -1.0, 0.0], [90.0, 0.0, 0.0]),
            RenderSettings(seed=2),
            args.runs,
            tmp,
        )
        mem = _peak_child(big)
    print(
        f"peak memory, fresh process decoding and locating the 20MP JPEG: {mem['peak_mb']:.0f} MB "
        f"(after imports {mem['after_imports_mb']:.0f} MB, after decoding "
        f"{mem['after_decode_mb']:.0f} MB; located: {mem['located']})"
    )
    print(
        f"(this process's own peak, renders included: "
        f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
