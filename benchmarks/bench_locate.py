"""Speed and memory of ``camvlp.locate`` against decoding the photo's JPEG.

Renders a 5184 x 3880 photo of the thesis' room and a 1920 x 1080 one, saves them as JPEG,
then prints, as medians of several runs in one process, the time of ``cv2.imdecode`` of
each JPEG, the time of ``camvlp.locate`` on the decoded image (per stage), their ratio, and
the peak memory of a fresh process that decodes and locates the 20-megapixel photo.

Then the slow cells, a few runs each (``--hard-runs``, 0 leaves them out): a robot's 1080p
frame at 2.2 rows per chip (the model decoder's photo) and two stress grid photos of glowing
lamps, each with the special paths its time went to (``LocateResult.paths``).

Run: ``python benchmarks/bench_locate.py [--runs 15] [--hard-runs 3] [--against OTHER/src]``.

``--against`` compares this code with another copy of the package (e.g. a worktree of the
main branch): both run in worker processes, one ``imdecode`` and ``locate`` at a time in
turn, on the same JPEGs, so that a machine whose speed drifts (a shared one) slows both
alike; each code's medians and ratios are printed (of wall time, and of CPU time, which a
busy machine's other processes do not add to), and each one's peak memory.  The slow cells
are taken in turn too (``--hard-runs`` each), each photo with its camera and map written to
files both codes read.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

import camvlp
from camvlp import locate
from camvlp.io import save_camera, save_map
from camvlp.model.camera import Camera
from camvlp.sim.render import RenderSettings, render

ROOT = Path(__file__).resolve().parents[1]


def _peak_child(jpeg: Path, src: Path | None = None) -> dict:
    """Peak resident memory of a fresh process: imports, then decode, then locate."""
    code = f"""
import json, re, cv2, numpy as np, camvlp
from camvlp import locate
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
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, env=_env(src)
    )
    return json.loads(out.stdout)


def _env(src: Path | None) -> dict | None:
    """The environment of a child that imports the package from ``src`` (None: as this one)."""
    return None if src is None else {**os.environ, "PYTHONPATH": str(src)}


def _worker_env(src: Path | None) -> dict:
    """A ``--against`` worker's environment: :func:`_env`, with OpenBLAS on one thread.

    Two workers take turns on a 2-core machine; an OpenBLAS thread that one of them woke
    keeps spinning on the other core while the other one runs, and slows it: two workers
    of the same code came out up to 20 % apart that way, and within 2 % of each other with
    one BLAS thread each.  (``locate``'s matrix products are of a few values: one thread
    is what they use anyway.)"""
    return {**(_env(src) or os.environ), "OPENBLAS_NUM_THREADS": "1"}


_WORKER = """
import json, sys, time, cv2, numpy as np, camvlp
from camvlp import locate
cv2.setNumThreads(1)
_x = np.ones(20_000_000, np.uint8); del _x  # glibc's heap as after the 20 MP photo's decode
cams, maps = {}, {}
print(camvlp.__file__, flush=True)
for line in sys.stdin:
    name, jpeg, truth, cam_file, map_file = json.loads(line)
    cam = cams.setdefault(cam_file, camvlp.load_camera(cam_file))
    fmap = maps.setdefault(map_file, camvlp.load_map(map_file))
    data = np.fromfile(jpeg, np.uint8)
    c, t = time.process_time(), time.perf_counter()
    img = cv2.imdecode(data, cv2.IMREAD_COLOR)
    c1, t1 = time.process_time(), time.perf_counter()
    res = locate(img, cam, fmap)
    c2, t2 = time.process_time(), time.perf_counter()
    err = 1e3 * float(np.linalg.norm(res.position - truth)) if res else float("nan")
    cpu = [1e3 * (c1 - c), 1e3 * (c2 - c1)]
    print(json.dumps([1e3 * (t1 - t), 1e3 * (t2 - t1), res.timing_ms, err, cpu]), flush=True)
"""


def _compare(photos: list[tuple], against: Path) -> None:
    """This code and the one at ``against`` in turn on each photo ``(name, JPEG, true
    position, camera file, map file, runs)``; their medians and ratios."""
    codes = {"this": None, "against": against}
    workers = {
        k: subprocess.Popen(
            [sys.executable, "-c", _WORKER],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            env=_worker_env(src),
        )
        for k, src in codes.items()
    }
    for k, w in workers.items():
        print(f"{k}: {w.stdout.readline().strip()}")
    for name, jpeg, truth, cam_file, map_file, runs in photos:
        rows: dict[str, list] = {k: [] for k in workers}
        line = json.dumps([name, str(jpeg), truth.tolist(), str(cam_file), str(map_file)])
        for i in range(runs + 2):  # the first two of each warm up
            for k in list(workers)[:: 1 if i % 2 else -1]:
                workers[k].stdin.write(line + "\n")
                workers[k].stdin.flush()
                rows[k].append(json.loads(workers[k].stdout.readline()))
        print(f"{name}, {runs} runs each, in turn (stages: {' / '.join(STAGES)}):")
        for k, r in rows.items():
            r = r[2:]
            dec, loc = statistics.median(x[0] for x in r), statistics.median(x[1] for x in r)
            st = " / ".join(
                f"{statistics.median(x[2].get(s, math.nan) for x in r):.1f}" for s in STAGES
            )
            print(
                f"  {k:<8} imdecode {dec:6.1f} ms  locate {loc:6.1f} ms ({st})  ratio "
                f"{loc / dec:.2f}  error {r[-1][3]:.3f} mm"
            )
            # CPU time: what a busy machine's other work does not add (it still slows both);
            # medians, and minima (the least disturbed runs)
            cpu = [[x[4][i] for x in r] for i in (0, 1)]
            cdec, cloc = (statistics.median(v) for v in cpu)
            mdec, mloc = (min(v) for v in cpu)
            print(
                f"  {'':<8} CPU time: imdecode {cdec:6.1f} ms  locate {cloc:6.1f} ms  ratio "
                f"{cloc / cdec:.2f}; minima {mdec:.2f} and {mloc:.2f} ms, ratio {mloc / mdec:.2f}"
            )
    for w in workers.values():
        w.stdin.close()
        w.wait()
    for k, src in codes.items():
        print(f"peak memory, {k}: {_peak_child(photos[0][1], src)['peak_mb']:.0f} MB")


def _compared(photos, fmap, runs: int, hard_runs: int, tmp: Path) -> list[tuple]:
    """The photos ``--against`` times in turn, as :func:`_compare` takes them: the two
    photos (``runs`` each), then the slow cells (``hard_runs`` each; none for 0), each
    rendered into ``tmp`` with its camera and map files."""
    room = tmp / "room.yaml"
    save_map(fmap, room)
    out = []
    for n, cam, pose, seed in photos:
        cam_file = tmp / f"{n}.camera.yaml"
        save_camera(cam, cam_file)
        jpeg = _jpeg(n, cam, fmap, pose, RenderSettings(seed=seed), tmp)
        out.append((n, jpeg, pose.position, cam_file, room, runs))
    hard = _hard_photos(fmap) if hard_runs > 0 else []
    for k, (n, cam, hard_map, pose, settings, quality) in enumerate(hard):
        cam_file, map_file = tmp / f"hard{k}.camera.yaml", tmp / f"hard{k}.map.yaml"
        save_camera(cam, cam_file)
        save_map(hard_map, map_file)
        jpeg = _jpeg(f"hard{k}", cam, hard_map, pose, settings, tmp, quality)
        out.append((n, jpeg, pose.position, cam_file, map_file, hard_runs))
    return out


#: The stages timed (``LocateResult.timing_ms``); a code without one shows nan there.
STAGES = ("prepare", "detect", "profile", "decode", "pose")
#: The 1080p camera: width, height, focal length (px), row time (s).
HD = (1920, 1080, 1200.0, 30e-6)


def _jpeg(
    name: str, camera: Camera, fmap, pose, settings: RenderSettings, tmp: Path, quality: int = 92
) -> Path:
    """The photo rendered and saved as ``tmp/name.jpg`` (of JPEG ``quality``)."""
    path = tmp / f"{name}.jpg"
    cv2.imwrite(
        str(path), render(camera, fmap, pose, settings).image, [cv2.IMWRITE_JPEG_QUALITY, quality]
    )
    return path


def _bench(
    name: str,
    camera: Camera,
    fmap,
    pose,
    settings: RenderSettings,
    runs: int,
    tmp: Path,
    quality: int = 92,
):
    """``imdecode`` and ``locate`` of the photo's JPEG ``runs`` times: their medians, each
    stage's, and the special paths the last run went through (printed)."""
    path = _jpeg(name, camera, fmap, pose, settings, tmp, quality)
    data = np.fromfile(str(path), np.uint8)
    decode_ms, locate_ms = [], []
    stages: dict[str, list[float]] = {k: [] for k in STAGES}
    result = None
    for _ in range(runs):
        t = time.perf_counter()
        img = cv2.imdecode(data, cv2.IMREAD_COLOR)
        decode_ms.append(1e3 * (time.perf_counter() - t))
        t = time.perf_counter()
        result = locate(img, camera, fmap)
        locate_ms.append(1e3 * (time.perf_counter() - t))
        for k in stages:
            stages[k].append(result.timing_ms.get(k, math.nan))
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
    if result.paths:
        ran = ", ".join(f"{k} {p.ms:.0f} ms ({p.calls}x)" for k, p in result.paths.items())
        print(f"  paths of the last run: {ran}")
    return path, med_dec, med_loc


def _hard_photos(fmap) -> list[tuple[str, Camera, object, object, RenderSettings, int]]:
    """The slow cells beside the two photos: ``(name, camera, map, pose, settings, JPEG
    quality)`` of a robot's 1080p frame of the room looking up (four plain discs of 65 rows,
    2.2 rows per chip, an exposure of 0.2 chip, JPEG 80: the model decoder's photo) and of
    stress grid photos of glowing lamps (seed 3, two photos a cell: among its slowest)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import stress_decode  # (the benchmark beside this one)

    rate = 1.0 / (2.2 * HD[3])
    robot = Camera.from_focal(*HD[:2], 740.0, row_time_s=HD[3])
    up = camvlp.Pose.from_euler([0.0, -1.0, 0.0], [90.0, 0.0, 0.0])
    out = [
        (
            "1080p robot frame",
            robot,
            fmap,
            up,
            RenderSettings(chip_rate_hz=rate, exposure_s=0.2 / rate, seed=1),
            80,
        )
    ]
    for cell in HARD_CELLS:
        d = stress_decode.drawn_photo(3, 2, cell, looks=True)
        name = f"stress {cell[0]:g} chip, {cell[1]:g} rows per chip, photo {cell[2]}"
        pose = camvlp.Pose(np.eye(3), np.zeros(3))
        out.append((name, d.camera, d.fmap, pose, d.settings, d.quality))
    return out


#: Stress grid photos (exposure in chips, rows per chip, photo) of seed 3, two a cell, among
#: its slowest: 1080p photos of glowing lamps whose glows join.
HARD_CELLS = ((0.5, 8.0, 1), (0.85, 12.0, 1))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--runs", type=int, default=15)
    ap.add_argument("--against", type=Path, help="another copy's src/ to run in turn with")
    ap.add_argument(
        "--hard-runs",
        type=int,
        default=3,
        help="runs of each slow cell (a robot's frame at 2.2 rows per chip, stress photos of "
        "glowing lamps); 0 leaves them out",
    )
    args = ap.parse_args()
    cv2.setNumThreads(1)
    fmap = camvlp.load_map(ROOT / "examples/thesis_room.yaml")
    thesis = camvlp.load_camera(ROOT / "examples/thesis_camera.yaml")
    hd = Camera.from_focal(*HD[:3], row_time_s=HD[3])
    photos = [
        ("20MP", thesis, camvlp.Pose.from_euler([0.05, 0.0, -0.08], [91.0, 2.0, 15.0]), 1),
        ("1080p", hd, camvlp.Pose.from_euler([0.0, -1.0, 0.0], [90.0, 0.0, 0.0]), 2),
    ]
    print(f"OpenCV {cv2.__version__}, NumPy {np.__version__}, OpenCV threads 1")
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        if args.against is not None:
            _compare(_compared(photos, fmap, args.runs, args.hard_runs, tmp), args.against)
            return 0
        for n, cam, pose, seed in photos:
            _bench(n, cam, fmap, pose, RenderSettings(seed=seed), args.runs, tmp)
        mem = _peak_child(tmp / "20MP.jpg")
        if args.hard_runs > 0:
            print(f"the slow cells, {args.hard_runs} runs each:")
            for name, cam, hard_map, pose, settings, quality in _hard_photos(fmap):
                _bench(name, cam, hard_map, pose, settings, args.hard_runs, tmp, quality)
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
