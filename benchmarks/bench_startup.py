"""Start-up cost of the command line: ``camvlp locate --json`` against reading the photo.

Renders a 4000 x 3000 photo of the thesis' room (JPEG, ``camvlp render``) into a temporary
folder, then times fresh processes, each ``--runs`` times (5), in turn so that a machine
whose speed drifts (a shared one) slows each alike:

- bare read: ``python -c "import cv2; cv2.imread(PHOTO)"``, what any tool pays to start
  Python, load OpenCV and decode the JPEG;
- locate: ``python -m camvlp locate --camera CAM --map examples/thesis_room.yaml --json
  PHOTO``;
- help: ``python -m camvlp --help``;
- import: the time ``import camvlp.cli`` itself takes, measured inside the process.

It prints each one's median (p50) and largest (max) wall time, and locate's median minus
the bare read's: the command's own cost, imports and locating, beyond reading the photo.

``--against OTHER/src`` times another copy of the package (e.g. the base commit's ``src``
exported with ``git archive``) in turn with this one, on the same photo.

Run: ``python benchmarks/bench_startup.py [--runs 5] [--against OTHER/src]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MAP = ROOT / "examples" / "thesis_room.yaml"
#: A 4000 x 3000 camera, f = 3000 px, no distortion, 20 us a row.
CAMERA_YAML = """\
image_width: 4000
image_height: 3000
camera_matrix: [[3000, 0, 2000], [0, 3000, 1500], [0, 0, 1]]
distortion_coefficients: [0, 0, 0, 0, 0]
row_time_s: 2.0e-05
"""
#: What ``import camvlp.cli`` takes, printed (s) by a child process.
IMPORT_CODE = (
    "import time; t = time.perf_counter(); import camvlp.cli; print(time.perf_counter() - t)"
)


def _env(src: Path) -> dict[str, str]:
    """The environment of a child that imports the package from ``src``."""
    return {**os.environ, "PYTHONPATH": str(src)}


def _render(src: Path, folder: Path) -> tuple[Path, Path]:
    """The camera file and the rendered photo (4000 x 3000 JPEG) in ``folder``."""
    camera = folder / "cam12.yaml"
    camera.write_text(CAMERA_YAML)
    photo = folder / "p12.jpg"
    args = ["--camera", camera, "--map", MAP, "--out", photo]
    pose = ["--position", "0.05,0,-0.08", "--euler", "91,2,15"]
    command = [sys.executable, "-m", "camvlp", "render", *map(str, args), *pose]
    subprocess.run(command, env=_env(src), check=True, capture_output=True)
    return camera, photo


def _commands(camera: Path, photo: Path) -> dict[str, list[str]]:
    """The timed commands by name (each run in a fresh process)."""
    python = sys.executable
    return {
        "bare read": [python, "-c", f"import cv2; cv2.imread({str(photo)!r})"],
        "locate --json": [
            *(python, "-m", "camvlp", "locate", "--camera", str(camera)),
            *("--map", str(MAP), "--json", str(photo)),
        ],
        "--help": [python, "-m", "camvlp", "--help"],
        "import camvlp.cli": [python, "-c", IMPORT_CODE],
    }


def _time(name: str, command: list[str], src: Path) -> float:
    """Seconds the command took: its wall time, or for the import what it printed."""
    start = time.perf_counter()
    out = subprocess.run(command, env=_env(src), capture_output=True, text=True)
    wall = time.perf_counter() - start
    if out.returncode != 0:
        raise RuntimeError(f"{name} failed ({out.returncode}): {out.stderr.strip()[-500:]}")
    return float(out.stdout) if name == "import camvlp.cli" else wall


def measure(codes: dict[str, Path], commands: dict[str, list[str]], runs: int) -> dict:
    """Each code's times of each command, ``runs`` rounds of one run each in turn (after one
    round not counted, which fills the caches)."""
    times: dict[str, dict[str, list[float]]] = {c: {n: [] for n in commands} for c in codes}
    for k in range(runs + 1):
        for code, src in codes.items():
            for name, command in commands.items():
                seconds = _time(name, command, src)
                if k:
                    times[code][name].append(seconds)
    return times


def report(times: dict, runs: int) -> None:
    """The table: each command's p50 / max per code, and locate's p50 minus the bare read's."""
    codes = list(times)
    print(f"{runs} runs each, fresh processes; seconds as p50 / max")
    print(f"{'':<20}" + "".join(f"{c:>20}" for c in codes))
    for name in times[codes[0]]:
        cells = []
        for code in codes:
            values = times[code][name]
            cells.append(f"{statistics.median(values):.3f} / {max(values):.3f}")
        print(f"{name:<20}" + "".join(f"{c:>20}" for c in cells))
    gaps = [
        statistics.median(times[c]["locate --json"]) - statistics.median(times[c]["bare read"])
        for c in codes
    ]
    print(f"{'locate - bare read':<20}" + "".join(f"{g:>20.3f}" for g in gaps))


def main() -> int:
    """Render the photo, time the commands and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5, help="timed runs of each command (5)")
    ap.add_argument("--against", type=Path, help="another copy's src/ to time in turn")
    args = ap.parse_args()
    if args.runs < 1:
        ap.error("--runs must be at least 1")
    codes = {"this": ROOT / "src"}
    if args.against is not None:
        codes["against"] = args.against.resolve()
    with tempfile.TemporaryDirectory() as folder:
        camera, photo = _render(codes["this"], Path(folder))
        times = measure(codes, _commands(camera, photo), args.runs)
    print(f"Python {sys.version.split()[0]}, photo 4000 x 3000 JPEG ({sys.executable})")
    report(times, args.runs)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
