"""Long frames read along a video: discs that show 0.4 to 0.9 of a frame, their IDs gathered
from frame to frame by the tracker (:mod:`camvlp.pipeline.decode.partial`).

For each of a few formats ``camvlp encode --design`` gives (7 ID bits for 100 fixtures, 10
for 600; CRCs of 7 and 8 bits), it renders (once, into ``--cache``, with ``camvlp
render-video``'s function) a 720p video (1280 x 720, f = 966 px, 45 us rows: 10 kHz chips
span 2.2 rows) of a camera walking 1.5 m under a ceiling grid of 50 fixtures (IDs drawn at
random, two of those the walk passes under sending random data instead), each disc's
diameter drawn so that it spans 0.4 to 0.9 of a frame (``--span``), 30 frames per second,
H.264 at crf 10.  Then it
tracks it (``camvlp track``'s run, the frames read as their luma plane) and prints:

* the discs' spans (frames of the code, from the truth) and the code's phase step from one
  video frame to the next (a fraction of a frame: near 0 or 1 the discs show the same
  stretch frame after frame, unless they move along the readout);
* frames until each fixture is identified, from the first frame it is wholly in the picture
  (p50 / p95 / max), by any means and by its own chips (``gathered`` or ``decoded``), and
  the fixtures never identified while in the picture ten frames or more;
* wrong IDs (a blob given an ID whose nearest true fixture has another), and IDs the data
  lights' chips were given (they must be none);
* the located share once identified (frames with a pose from the first one on) and the
  position RMSE.

Run: ``python benchmarks/bench_long_codes.py [--formats 111/7/8/00 ...] [--span 0.4 0.9]
[--seconds 4] [--cache out/bench_long_codes] [--unknown-readout]``; ``--unknown-readout``
gives the camera no readout direction (the tracker finds it: the single-photo decoders try
every frame until the gathered chips of two lights say it, slowly with 1024 IDs).
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

import numpy as np  # noqa: E402

from camvlp.analysis.track import LOCATED, read_truths, run_track, summarize  # noqa: E402
from camvlp.io.video import open_frames  # noqa: E402
from camvlp.model.camera import Camera  # noqa: E402
from camvlp.model.fixtures import Fixture, FixtureMap  # noqa: E402
from camvlp.model.linecode import FrameFormat  # noqa: E402
from camvlp.pipeline.track.tracker import Tracker  # noqa: E402
from camvlp.sim.render import RenderSettings  # noqa: E402
from camvlp.sim.trajectory import Trajectory  # noqa: E402
from camvlp.sim.video import render_video  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
FPS = 30.0
DEPTH = 1.5  # m, camera to ceiling
CEILING = -2.7
#: ``camvlp encode --design --fixtures 100`` (7 ID bits) and ``--fixtures 600`` (10).
FORMATS = ("111/7/7/00", "111/7/8/00", "1111/10/8/000")


def camera(readout: str | None) -> Camera:
    """A 720p video mode: 1280 x 720, f = 966 px, rows of 45 us (720 rows in 32.4 ms)."""
    return Camera.from_focal(1280, 720, 966.0, row_time_s=45e-6, readout=readout)


def parse_format(text: str) -> FrameFormat:
    """``preamble/id_bits/check_bits/postamble``, e.g. ``1111/10/8/000``."""
    pre, bits, check, post = text.split("/")
    return FrameFormat(pre, int(bits), post, int(check))


def scene(frame: FrameFormat, cam: Camera, chip_rate: float, span, seed: int):
    """A ceiling grid of 50 fixtures (5 across, 0.45 m apart) with random IDs of ``frame``,
    each disc's diameter drawn so that it spans ``span`` frames of the code seen from 1.5 m;
    two of them near the walk (chosen at random) send data.  Returns the map and the data
    lights' IDs."""
    rng = np.random.default_rng([seed, frame.n_chips])
    ids = rng.choice(frame.n_ids, 50, replace=False)
    rows_per_chip = 1.0 / (cam.row_time_s * chip_rate)
    per_frame = frame.n_chips * rows_per_chip * DEPTH / cam.focal_px  # m of disc a frame
    diameters = rng.uniform(*span, 50) * per_frame
    fixtures = []
    for k, (fid, d) in enumerate(zip(ids.tolist(), diameters.tolist(), strict=True)):
        x, z = -0.9 + 0.45 * (k % 5), -2.25 + 0.45 * (k // 5)
        fixtures.append(Fixture(fid, np.array([x, CEILING, z]), d, np.array([0.0, 1.0, 0.0])))
    room = FixtureMap(tuple(fixtures), frame=frame, chip_rate_hz=chip_rate)
    on_path = [f.id for f in fixtures if abs(f.position[0]) < 0.5 and -0.5 < f.position[2] < 0.7]
    data = tuple(int(i) for i in rng.choice(on_path, 2, replace=False))
    return room, data


def walk(seconds: float) -> Trajectory:
    """1.5 m under the ceiling, along z at 0.3 m/s, the picture turned 60 degrees from the
    walk (the discs move along the rows and the columns), swaying a little."""
    t = np.linspace(0.0, seconds, 41)
    pos = np.stack([0.1 * np.sin(t), np.full_like(t, CEILING + DEPTH), -0.6 + 0.3 * t], axis=1)
    eul = np.stack([90.0 + 1.5 * np.sin(1.3 * t), 1.0 * np.sin(0.9 * t), 60.0 + 4.0 * t], axis=1)
    return Trajectory(t, pos, eul)


def render(fmt: str, args, room, data) -> Path:
    stem = f"{fmt.replace('/', '_')}_s{args.span[0]:g}-{args.span[1]:g}_seed{args.seed}"
    stem += f"_{args.seconds:g}s_rate{args.chip_rate:g}_crf{args.crf}"
    path = args.cache / f"{stem}.mp4"
    if not path.exists():
        t0 = time.perf_counter()
        look = RenderSettings(seed=args.seed, chip_rate_hz=args.chip_rate, data_lights=data)
        n = render_video(
            camera("rows"), room, walk(args.seconds), path, fps=FPS, settings=look, crf=args.crf
        )
        print(f"rendered {path}: {n} frames in {time.perf_counter() - t0:.0f} s")
    return path


def spans(path: Path) -> np.ndarray:
    """The frames of the code each disc wholly in the picture spans (the truth), every frame."""
    with path.with_name(path.stem + "_fixtures.csv").open() as fh:
        return np.array(
            [float(r["frames_spanned"]) for r in csv.DictReader(fh) if r["fully_inside"] == "1"]
        )


def nearest_ids(truths, blobs) -> list[int | None]:
    """Per blob, the ID of the true fixture whose centre is nearest its pixel (``truths``:
    a frame's ``(id, u, v, inside)`` rows); None for every blob of a frame without truths."""
    if not truths:
        return [None] * len(blobs)
    tid = [t[0] for t in truths]
    tpx = np.nan_to_num(np.array([[t[1], t[2]] for t in truths]), nan=1e9)
    return [tid[int(np.argmin(np.linalg.norm(tpx - b.pixel, axis=1)))] for b in blobs]


def identified_after(run, fixtures_truth, data) -> tuple[list[int], list[int], list[int]]:
    """Per fixture (not a data light) wholly in the picture: frames from its first such frame
    to its first ID (any source), and to its first from its own chips; and the fixtures in
    the picture ten frames or more never identified by their chips."""
    first_in: dict[int, int] = {}
    frames_in: dict[int, int] = {}
    first_any: dict[int, int] = {}
    first_own: dict[int, int] = {}
    for k, (name, f) in enumerate(zip(run.names, run.frames, strict=True)):
        truths = fixtures_truth.get(name, [])
        for fid, _, _, inside in truths:
            if inside and fid not in data:
                first_in.setdefault(fid, k)
                frames_in[fid] = frames_in.get(fid, 0) + 1
        for b, near in zip(f.fixtures, nearest_ids(truths, f.fixtures), strict=True):
            if b.id is None or near != b.id:
                continue  # (a wrong ID: counted apart)
            first_any.setdefault(b.id, k)
            if b.source in ("gathered", "decoded"):
                first_own.setdefault(b.id, k)
    any_, own, never = [], [], []
    for fid, k0 in first_in.items():
        if fid in first_any:
            any_.append(max(0, first_any[fid] - k0))
        if fid in first_own:
            own.append(max(0, first_own[fid] - k0))
        elif frames_in[fid] >= 10:
            never.append(fid)
    return any_, own, never


def wrong_by_source(run, fixtures_truth) -> dict[str, int]:
    """Blobs given an ID whose nearest true fixture has another, by the ID's source."""
    out: dict[str, int] = {}
    for name, f in zip(run.names, run.frames, strict=True):
        for b, near in zip(
            f.fixtures, nearest_ids(fixtures_truth.get(name, []), f.fixtures), strict=True
        ):
            if b.id is not None and near is not None:
                out[b.source] = out.get(b.source, 0) + int(near != b.id)
    return out


def data_ids(run, fixtures_truth, data) -> tuple[int, int]:
    """Blobs of a data light given an ID by their chips, and the data lights' blobs."""
    n = seen = 0
    for name, f in zip(run.names, run.frames, strict=True):
        for b, near in zip(
            f.fixtures, nearest_ids(fixtures_truth.get(name, []), f.fixtures), strict=True
        ):
            seen += near in data
            n += near in data and b.source in ("gathered", "decoded")
    return n, seen


def pct(values) -> str:
    if not values:
        return "none"
    p50, p95 = np.percentile(values, [50, 95])
    return f"p50 {p50:.0f}, p95 {p95:.1f}, max {max(values)} ({len(values)} fixtures)"


def one(fmt: str, args) -> dict:
    frame = parse_format(fmt)
    cam = camera(None if args.unknown_readout else "rows")
    room, data = scene(frame, cam, args.chip_rate, args.span, args.seed)
    path = render(fmt, args, room, data)
    src = open_frames(path, threads=1, gray=True)
    truths = read_truths(src)
    t0 = time.perf_counter()
    tracker = Tracker(cam, room)
    run = run_track(src, tracker, args.cache / (path.stem + "_track"))
    seconds = time.perf_counter() - t0
    s = summarize(run, truths)
    given, seen = data_ids(run, truths.fixtures, set(data))
    wrong = wrong_by_source(run, truths.fixtures)
    any_, own, never = identified_after(run, truths.fixtures, set(data))
    located = [f.status in LOCATED for f in run.frames]
    first = located.index(True) if any(located) else len(located)
    after = located[first:]
    sp = spans(path)
    step = (args.chip_rate / FPS) % frame.n_chips / frame.n_chips
    out = {
        "format": fmt,
        "n_chips": frame.n_chips,
        "min_distance": frame.min_distance,
        "frames": len(run.frames),
        "span_p5_p95": [float(v) for v in np.percentile(sp, [5, 95])],
        "phase_step": step,
        "identified_after": any_,
        "own_chips_after": own,
        "never_identified": never,
        "wrong_ids": s.get("wrong_ids"),
        "wrong_by_source": wrong,
        "ids_checked": s.get("ids_checked"),
        "data_light_ids": given,
        "data_light_blobs": seen,
        "first_located": first,
        "located_share": float(np.mean(after)) if after else 0.0,
        "position_rmse_mm": 1e3 * (s["errors"]["position_rmse"] or float("nan")),
        "track_s_per_frame": seconds / max(1, len(run.frames)),
        "readout": str(tracker.readout),
    }
    print(
        f"\n== {fmt}: {frame.n_chips} chips, IDs {frame.min_distance} apart, {out['frames']} frames"
    )
    print(
        f"discs span {out['span_p5_p95'][0]:.2f} to {out['span_p5_p95'][1]:.2f} frames (p5-p95); "
        f"the code moves {step:.2f} of a frame from one video frame to the next"
    )
    print(f"identified after  {pct(any_)} frames")
    print(f"by its own chips  {pct(own)} frames; never (10+ frames in view): {never or 'none'}")
    by = ", ".join(f"{v} {k}" for k, v in wrong.items() if v) or "none"
    print(
        f"IDs               {out['wrong_ids']} wrong of {out['ids_checked']} ({by}); "
        f"{given} given by their chips to the data lights' {seen} blobs"
    )
    print(
        f"located           {100 * out['located_share']:.1f} % of the frames from the first "
        f"located one (frame {first}); position RMSE {out['position_rmse_mm']:.1f} mm"
    )
    how = "found" if cam.readout is None else "given"
    print(f"readout           {out['readout']} ({how})")
    print(f"time              {out['track_s_per_frame']:.2f} s a frame (tracking, wall)")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--formats", nargs="+", default=list(FORMATS))
    ap.add_argument("--span", nargs=2, type=float, default=[0.4, 0.9], help="Frames a disc spans.")
    ap.add_argument("--seconds", type=float, default=4.0, help="The walk's length, s.")
    ap.add_argument("--chip-rate", type=float, default=10_000.0, help="Chips per second.")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--crf", type=int, default=10, help="x264 quality of the videos rendered.")
    ap.add_argument("--cache", type=Path, default=ROOT / "out" / "bench_long_codes")
    ap.add_argument("--unknown-readout", action="store_true")
    ap.add_argument("--json", type=Path, default=None, help="Also write the figures here.")
    args = ap.parse_args()
    args.cache.mkdir(parents=True, exist_ok=True)
    results = [one(fmt, args) for fmt in args.formats]
    if args.json:
        args.json.write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
