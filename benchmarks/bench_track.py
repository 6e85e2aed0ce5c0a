"""Tracking along simulated videos: accuracy, IDs, the rolling shutter's cost, and speed.

Renders (once, into ``--cache``) the two example videos with ``camvlp render-video``'s
function: the robot crossing the thesis' room (``examples/trajectories/robot.csv``,
``examples/thesis_room.yaml``) and the walk along the corridor
(``examples/trajectories/walk.csv``, ``examples/corridor_room.yaml``), both with
``examples/video_camera.yaml`` (1920 x 1080, 30 us rows: 3.33 rows per 10 kHz chip), 30 frames
per second, H.264 at x264's crf 10 (``--crf``; 10 keeps the sensor noise: about 48 Mbit/s,
where a phone records 1080p at 10 to 20).  Then for each video it prints:

* the tracker's statuses, its position RMSE (filtered and raw) against the truth, wrong IDs,
  and how many frames an entering fixture took to be used;
* the same without the rolling-shutter model (what a moving camera's rows cost);
* ``camvlp.locate`` on every frame alone (no track): frames located, and the share of the
  fixtures fully in the picture whose stripes decode;
* speed on one core (OpenCV, FFmpeg and BLAS on one thread): frames per second of CPU time,
  reading (H.264 decoding; the frames' luma plane, as ``camvlp track`` reads them) included,
  and the share of reading; the best of ``--runs`` runs (the machine may be shared: CPU time,
  not wall time, is counted), and ``camvlp.locate``'s time on ``bench_locate.py``'s 1080p
  photo as a reference of the machine's load.

Run: ``python benchmarks/bench_track.py [--runs 3] [--crf 10] [--cache out/bench_track]``;
``--halo 0.4 --brightness 1`` renders (and tracks) the lamps glowing, as
``camvlp render-video --halo --brightness`` does; ``--seed`` the renderer's seed (1);
``--videos robot`` takes one of the two; ``--rows-per-chip 2.2 --exposure-chips 0.3``
renders the chips 2.2 of the camera's rows long (a chip rate of ``1 / (2.2 * row_time)``)
with rows exposed for 0.3 chip (the model decoder's videos: the run-length decoder refuses
most lights there).  Per frame it prints p50 / p95 / max of each stage's time and of each
special path's (``TrackFrame.timing_ms``, ``TrackFrame.paths``; wall time), and of the
tracker's CPU time; ``--baseline`` times the tracker without the photo-wide model and the
fixtures' glows carried from frame to frame too (``TrackSettings(carry_model=False,
carry_glows=False)``) and prints the ratios.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

import camvlp  # noqa: E402
from camvlp.analysis.track import read_truths, run_track, summarize  # noqa: E402
from camvlp.io.video import open_frames, read_truth  # noqa: E402
from camvlp.pipeline.track.tracker import Tracker, TrackSettings  # noqa: E402
from camvlp.sim.render import RenderSettings  # noqa: E402
from camvlp.sim.video import load_trajectory, render_video  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
EX = ROOT / "examples"
VIDEOS = {"robot": "thesis_room.yaml", "walk": "corridor_room.yaml"}


def _video(
    name: str,
    cache: Path,
    crf: int,
    halo: float = 0.0,
    brightness: float = 4.0,
    seed: int = 1,
    rows_per_chip: float | None = None,
    exposure_chips: float | None = None,
) -> Path:
    camera = camvlp.load_camera(EX / "video_camera.yaml")
    rate = RenderSettings.chip_rate_hz
    if rows_per_chip is not None:  # the chips' rate that spans that many of the camera's rows
        rate = 1.0 / (rows_per_chip * camera.row_time_s)
    exposure_s = None if exposure_chips is None else exposure_chips / rate
    look = RenderSettings(
        seed=seed, halo=halo, brightness=brightness, chip_rate_hz=rate, exposure_s=exposure_s
    )
    stem = name + (f"_halo{halo:g}" if halo else "")
    stem += f"_bright{brightness:g}" if brightness != RenderSettings.brightness else ""
    stem += f"_seed{seed}" if seed != 1 else ""
    stem += f"_rpc{rows_per_chip:g}" if rows_per_chip is not None else ""
    stem += f"_exp{exposure_chips:g}" if exposure_chips is not None else ""
    path = cache / f"{stem}.mp4"
    if not path.exists() or not (cache / f"{stem}_truth.csv").exists():
        cache.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        n = render_video(
            camera,
            camvlp.load_map(EX / VIDEOS[name]),
            load_trajectory(EX / "trajectories" / f"{name}.csv"),
            path,
            fps=30.0,
            settings=look,
            crf=crf,
        )
        print(f"rendered {path}: {n} frames in {time.perf_counter() - t0:.0f} s")
    return path


def _track(video: Path, room, camera, out: Path, rolling_shutter: bool) -> dict:
    src = open_frames(video, threads=1, gray=True)
    run = run_track(src, Tracker(camera, room, TrackSettings(rolling_shutter=rolling_shutter)), out)
    s = summarize(run, read_truths(src))
    sources = [b.source for f in run.frames for b in f.fixtures if b.id is not None]
    s["decoded_ids"] = sources.count("decoded")
    s["carried_ids"] = sources.count("carried")
    return s


def _locate_alone(video: Path, room, camera) -> dict:
    """Each frame located alone: frames located, and decodes of fully visible fixtures."""
    truth: dict[str, list[tuple[int, np.ndarray]]] = {}
    with (video.parent / f"{video.stem}_fixtures.csv").open() as fh:
        for r in csv.DictReader(fh):
            if r["fully_inside"] == "1":
                truth.setdefault(r["frame"], []).append(
                    (int(r["id"]), np.array([float(r["u"]), float(r["v"])]))
                )
    poses = read_truth(video.parent / f"{video.stem}_truth.csv")
    located = visible = decoded = wrong = 0
    errors = []
    settings = camvlp.LocateSettings(readout="rows")
    for frame in open_frames(video, threads=1, gray=True):
        res = camvlp.locate(frame.image, camera, room, settings)
        inside = truth.get(frame.name, [])
        visible += len(inside)
        for fid, px in inside:
            near = [f for f in res.fixtures if np.linalg.norm(f.pixel - px) < 20]
            if near and near[0].id is not None and not near[0].reason.startswith("ID "):
                decoded += near[0].id == fid
                wrong += near[0].id != fid
        if res:
            located += 1
            errors.append(np.linalg.norm(res.position - poses[frame.name][:3]))
    return {
        "located": located,
        "visible": visible,
        "decoded": decoded,
        "wrong": wrong,
        "rmse": float(np.sqrt(np.mean(np.square(errors)))) if errors else None,
    }


def _speed(video: Path, room, camera, runs: int, settings: TrackSettings | None = None) -> dict:
    """Best of ``runs``: CPU seconds reading all frames, and reading + tracking them; the
    best run's frames (their ``timing_ms`` and ``paths``) under ``"frames"``."""
    read_cpu, total_cpu, wall, records = [], [], [], []
    n = 0
    for _ in range(runs):
        c0 = time.process_time()
        frames = list(open_frames(video, threads=1, gray=True))
        read_cpu.append(time.process_time() - c0)
        n = len(frames)
        del frames
        tracker = Tracker(camera, room, settings)
        run, cpu = [], []
        c0, w0 = time.process_time(), time.perf_counter()
        for f in open_frames(video, threads=1, gray=True):
            c1 = time.process_time()
            run.append(tracker.update(f.image, f.t))
            cpu.append(1e3 * (time.process_time() - c1))
        total_cpu.append(time.process_time() - c0)
        wall.append(time.perf_counter() - w0)
        records.append((run, cpu))
    read, total = min(read_cpu), min(total_cpu)
    return {
        "frames": n,
        "fps_cpu": n / total,
        "read_ms": 1e3 * read / n,
        "track_ms": 1e3 * (total - read) / n,
        "reading_share": read / total,
        "fps_wall": n / min(wall),
        "per_frame": _per_frame(*records[int(np.argmin(total_cpu))]),
    }


#: The tracker's stages per frame (``TrackFrame.timing_ms``), then their total.
STAGES = ("prepare", "detect", "profile", "decode", "track", "total")


def _per_frame(frames, cpu_ms) -> dict:
    """p50 / p95 / max over the frames of the tracker's CPU time (``cpu_ms``, one a frame),
    of each stage's time and of each special path's (``TrackFrame.paths``; 0 where it did not
    run), wall ms; and in how many frames each path ran."""
    names = list(dict.fromkeys(k for f in frames for k in f.paths))
    out = {}
    for what, v in [
        ("tracking, CPU", cpu_ms),
        *((st, [f.timing_ms.get(st, 0.0) for f in frames]) for st in STAGES),
        *((f"path: {p}", [f.paths[p].ms if p in f.paths else 0.0 for f in frames]) for p in names),
    ]:
        a = np.asarray(v, dtype=float)
        p50, p95 = np.percentile(a, [50, 95])
        out[what] = {"p50": p50, "p95": p95, "max": a.max(), "frames": int(np.sum(a > 0))}
    return out


def _print_per_frame(label: str, table: dict) -> None:
    print(f"per frame ({label}; ms; wall time but the first row, the machine's load included):")
    print("| stage or path | frames | p50 | p95 | max |")
    print("|---|---|---|---|---|")
    for what, r in table.items():
        print(f"| {what} | {r['frames']} | {r['p50']:.1f} | {r['p95']:.1f} | {r['max']:.1f} |")


def _print_speed(label: str, speed: dict) -> None:
    print(
        f"{label} {speed['fps_cpu']:.1f} frames/s of CPU time on one core "
        f"(reading {speed['read_ms']:.1f} ms, tracking {speed['track_ms']:.1f} ms a frame: "
        f"{100 * speed['reading_share']:.0f} % reading); wall {speed['fps_wall']:.1f} frames/s"
    )


def _reference_cpu_ms(runs: int = 15) -> float:
    """CPU time of ``camvlp.locate`` on ``bench_locate.py``'s 1080p photo (median, ms): the
    same call docs/speed.md times on an idle machine, to tell how loaded this one is."""
    from camvlp.model.camera import Camera
    from camvlp.sim.render import render

    room = camvlp.load_map(EX / "thesis_room.yaml")
    hd = Camera.from_focal(1920, 1080, 1200.0, row_time_s=30e-6)
    pose = camvlp.Pose.from_euler([0.0, -1.0, 0.0], [90.0, 0.0, 0.0])
    image = render(hd, room, pose, RenderSettings(seed=2)).image
    times = []
    for _ in range(runs):
        c0 = time.process_time()
        camvlp.locate(image, hd, room)
        times.append(time.process_time() - c0)
    return 1e3 * float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--cache", type=Path, default=ROOT / "out" / "bench_track")
    ap.add_argument("--crf", type=int, default=10, help="x264 quality of the videos rendered.")
    ap.add_argument("--json", type=Path, default=None, help="Also write the figures here.")
    ap.add_argument(
        "--halo",
        type=float,
        default=0.0,
        help="Lamps that glow: the halo of `camvlp render-video --halo` (0: plain discs).",
    )
    ap.add_argument(
        "--brightness",
        type=float,
        default=RenderSettings.brightness,
        help="The lamps' brightness, in full scales (`camvlp render-video --brightness`).",
    )
    ap.add_argument(
        "--seed", type=int, default=1, help="The renderer's seed (noise, phases, lamps' looks)."
    )
    ap.add_argument(
        "--rows-per-chip",
        type=float,
        default=None,
        help="Render the chips this many of the camera's rows long (default: 10 kHz chips, "
        "3.33 rows), as `camvlp render-video --chip-rate` does.",
    )
    ap.add_argument(
        "--exposure-chips",
        type=float,
        default=None,
        help="Exposure of each row, chips (half a chip by default; `camvlp render-video "
        "--exposure`).",
    )
    ap.add_argument(
        "--baseline",
        action="store_true",
        help="Also time the tracker without the photo-wide model and the fixtures' glows "
        "carried from frame to frame (TrackSettings(carry_model=False, carry_glows=False): "
        "every frame the model decoder reads fits its own, a cut disc's ring tells its glow).",
    )
    ap.add_argument("--videos", nargs="+", choices=sorted(VIDEOS), default=list(VIDEOS))
    args = ap.parse_args()
    cv2.setNumThreads(1)
    camera = camvlp.load_camera(EX / "video_camera.yaml")
    results = {}
    for name in args.videos:
        room_file = VIDEOS[name]
        video = _video(
            name,
            args.cache,
            args.crf,
            args.halo,
            args.brightness,
            args.seed,
            args.rows_per_chip,
            args.exposure_chips,
        )
        room = camvlp.load_map(EX / room_file)
        rs = _track(video, room, camera, args.cache / f"track_{video.stem}", True)
        plain = _track(video, room, camera, args.cache / f"track_{video.stem}_no_rs", False)
        alone = _locate_alone(video, room, camera)
        speed = _speed(video, room, camera, args.runs)
        if args.baseline:  # the same run without the model carried, for ratios
            old = TrackSettings(carry_model=False, carry_glows=False)
            base = _speed(video, room, camera, args.runs, old)
            speed["without_carrying"] = base
        results[name] = {"track": rs, "no_rolling_shutter": plain, "locate": alone, "speed": speed}
        e, p = rs["errors"], plain["errors"]
        n = rs["frames"]
        print(f"\n== {name}: {n} frames")
        print(
            f"tracker       {rs['fix']} fix, {rs['tracked']} tracked, {rs['predicted']} "
            f"predicted, {rs['lost']} lost: {100 * rs['fix_or_tracked_rate']:.1f} % fix or tracked"
        )
        print(
            f"position RMSE {1e3 * e['position_rmse']:.2f} mm filtered, "
            f"{1e3 * e['raw_position_rmse']:.2f} mm raw, max {1e3 * e['position_max']:.2f} mm; "
            f"angles {e['angle_rmse_deg']:.3f} deg RMS"
        )
        print(
            f"IDs           {rs['wrong_ids']} wrong of {rs['ids_checked']}, "
            f"{rs['used_not_fully_inside']} used while not wholly in the picture; "
            f"{rs['decoded_ids']} decoded, {rs['carried_ids']} carried by the track; "
            f"entering fixtures used after {rs['pickup_frames']} frames"
        )
        print(
            f"no rolling-shutter model: position RMSE {1e3 * p['position_rmse']:.2f} mm "
            f"filtered, {1e3 * p['raw_position_rmse']:.2f} mm raw"
        )
        rmse = "-" if alone["rmse"] is None else f"{1e3 * alone['rmse']:.2f} mm"
        print(
            f"locate alone  {alone['located']} / {n} frames located (RMSE {rmse}); "
            f"{alone['decoded']} / {alone['visible']} visible fixtures decoded "
            f"({100 * alone['decoded'] / max(alone['visible'], 1):.0f} %), "
            f"{alone['wrong']} wrong"
        )
        _print_speed("speed        ", speed)
        _print_per_frame("the best speed run", speed["per_frame"])
        if args.baseline:
            base = speed["without_carrying"]
            _print_speed("without the model and glows carried:", base)
            _print_per_frame("the best run without the model and glows carried", base["per_frame"])
            print(
                f"carried: {speed['fps_cpu'] / base['fps_cpu']:.2f}x the frames/s, "
                f"{speed['track_ms'] / base['track_ms']:.2f}x the tracking time a frame"
            )
    ref = _reference_cpu_ms()
    results["reference_locate_1080p_cpu_ms"] = ref
    print(
        f"\nreference: camvlp.locate on bench_locate.py's 1080p photo takes {ref:.1f} ms of CPU "
        "time here (bench_locate.py, idle machine: 10.4 ms)"
    )
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(results, indent=2, default=float) + "\n")


if __name__ == "__main__":
    main()
