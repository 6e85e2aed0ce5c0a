"""Real photographs as the judge: ``camvlp locate`` on every photo under ``../shared/real/``.

Each photo is located as a user would locate it from the command line: the camera and map
files its folder's README describes (``examples/real/``), the photo's own EXIF, and nothing
else but what the README says a user knows (that a photo is mirrored).  No readout is given.
What each photo should give is in ``examples/real/photos.yaml``.

One row per photo: the readout found, lights detected against those in view, lights
identified right and wrong (against the per-light truth where the README or a truth file
gives one; "unchecked" where it does not), lights refused and why, the position against the
reference, and the time of ``locate`` (per stage) against the photo's JPEG decode.  Then the
totals, the time distribution per resolution (p50 / p95 / max) and the slowest photos.
Exit code 1 when a photo falls short of what its README says (a wrong ID always does).
Run::

    python benchmarks/real_photos.py            # every photo (about two minutes)
    python benchmarks/real_photos.py --quick    # five photos, under a minute
    python benchmarks/real_photos.py --json out/real/results.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))

from timing import PhotoTime, path_dict, slowest, time_table  # (the benchmarks beside this one)

from camvlp.io import decode_image, exif_readout, load_camera, load_map
from camvlp.io.images import read_photo
from camvlp.pipeline.locate import LocateSettings, locate

REPO = Path(__file__).resolve().parents[1]
MANIFEST = REPO / "examples" / "real" / "photos.yaml"
ROOT = REPO.parent / "shared" / "real"


@dataclass
class Row:
    """What ``locate`` made of one real photo, against what its README says."""

    folder: str
    photo: str
    size: str
    readout: str
    lights: int  # in view, as the README says (0 when not said)
    detected: int
    right: int  # identified with the truth's frequency
    wrong: int  # identified with another one, or a light the truth does not hold
    unchecked: int  # identified where no per-light truth is known
    refused: list[str] = field(default_factory=list)  # reasons of lights not identified
    located: bool = False
    position: list[float] | None = None
    error: float | None = None  # distance to the reference position, map units
    reason: str = ""
    timing_ms: dict[str, float] = field(default_factory=dict)
    jpeg_ms: float = float("nan")
    failures: list[str] = field(default_factory=list)  # how it falls short of its README
    paths: dict[str, dict] = field(default_factory=dict)  # the special paths that ran

    @property
    def time(self) -> PhotoTime:
        """Its times, for :mod:`timing`'s tables."""
        return PhotoTime(
            f"{self.folder}/{self.photo}", self.size, self.jpeg_ms, self.timing_ms, self.paths
        )

    @property
    def ratio(self) -> float:
        """``locate``'s time over the JPEG decode's."""
        return self.time.ratio


def load_manifest(path: Path = MANIFEST) -> list[dict]:
    """Every photo of the manifest as one flat entry: folder, photo, camera and map paths,
    match distance, and the photo's expectations (folder defaults merged in)."""
    spec = yaml.safe_load(path.read_text())
    entries = []
    for folder, f in spec["folders"].items():
        truth_file = ROOT / folder / f["truth"] if f.get("truth") else None
        truths = json.loads(truth_file.read_text()) if truth_file and truth_file.is_file() else {}
        for photo, own in f["photos"].items():
            e = {**f.get("default", {}), **(own or {})}
            if "truth" not in e and photo in truths:
                e["truth"] = [
                    {"pixel": t["centroid"], "frequency_hz": t["frequency_hz"]}
                    for t in truths[photo]
                ]
            entries.append(
                {
                    "folder": folder,
                    "photo": photo,
                    "path": ROOT / folder / photo,
                    "camera": path.parent / f["camera"],
                    "map": path.parent / f["map"],
                    "match_px": float(f.get("match_px", 50)),
                    **e,
                }
            )
    return entries


def locate_as_user(entry: dict):
    """``camvlp locate PHOTO --camera C --map M [--mirrored]`` in process: the photo read
    once, its EXIF readout passed as the command line passes it.  Returns the result and the
    JPEG decode's time (ms)."""
    camera, fixture_map = load_camera(entry["camera"]), load_map(entry["map"])
    raw = read_photo(entry["path"])
    t0 = time.perf_counter()
    cv2.imdecode(np.frombuffer(raw, np.uint8), cv2.IMREAD_COLOR)
    jpeg_ms = 1e3 * (time.perf_counter() - t0)
    image = decode_image(raw, entry["path"])
    settings = LocateSettings(
        mirrored=bool(entry.get("mirrored", False)), readout_hint=exif_readout(raw)
    )
    return locate(image, camera, fixture_map, settings), jpeg_ms, fixture_map


def judge(entry: dict, result, fixture_map) -> Row:
    """Compare one result with the photo's truth and expectations."""
    freq = {f.id: f.frequency_hz for f in fixture_map.fixtures}
    truth = entry.get("truth") or []
    row = Row(
        entry["folder"],
        entry["photo"],
        "",
        str(result.readout),
        int(entry.get("lights", 0)),
        len(result.fixtures),
        0,
        0,
        0,
        located=bool(result),
        position=None if result.position is None else [float(v) for v in result.position],
        reason=result.reason or "",
        timing_ms={k: float(v) for k, v in result.timing_ms.items()},
    )
    claimed: set[int] = set()
    for f in result.fixtures:
        if f.id is None:
            row.refused.append(f.reason)
            continue
        if not truth:
            row.unchecked += 1
            continue
        d = [np.hypot(*(np.asarray(t["pixel"], float) - f.pixel)) for t in truth]
        k = int(np.argmin(d))
        if (
            d[k] <= entry["match_px"]
            and k not in claimed
            and freq[f.id] == truth[k]["frequency_hz"]
        ):
            row.right += 1
            claimed.add(k)
        else:
            row.wrong += 1
    ref = entry.get("reference")
    if ref is not None and row.position is not None:
        row.error = float(np.linalg.norm(np.subtract(row.position, ref)))
    row.failures = shortfalls(entry, row)
    return row


def shortfalls(entry: dict, row: Row) -> list[str]:
    """How a row falls short of what the photo's README says (empty: it does not)."""
    out = []
    if row.wrong:
        out.append(f"{row.wrong} wrong ID(s)")
    if entry.get("lights") and row.detected < entry["lights"]:
        out.append(f"{row.detected} of {entry['lights']} lights detected")
    if entry.get("identify"):
        ids = row.right + row.unchecked
        if ids < entry["lights"]:
            out.append(f"{ids} of {entry['lights']} lights identified")
    if entry.get("located") is True and not row.located:
        out.append(f"not located: {row.reason}")
    if entry.get("located") is False and row.located:
        out.append("located, but the README says it cannot be")
    if entry.get("reference") is not None and row.located:
        if row.error is None or row.error > float(entry.get("within", np.inf)):
            out.append(f"{row.error:.1f} from the reference (at most {entry['within']})")
    box = entry.get("inside")
    if box is not None and row.located:
        lo, hi = np.asarray(box, float)
        if not np.all((lo <= row.position) & (row.position <= hi)):
            out.append(f"position {np.round(row.position, 1).tolist()} outside {box}")
    return out


def run(entries: list[dict], progress: bool = True) -> list[Row]:
    """Locate every entry's photo; photos that are absent are left out.  The first present
    photo is located once before, untimed: a process's first call imports what its paths
    need (SciPy's optimiser, the BLAS controller: about 0.25 s, ``bench_startup.py``'s
    start-up), which is no photo's time."""
    present = [e for e in entries if e["path"].is_file()]
    if present:
        locate_as_user(present[0])
    rows = []
    for i, e in enumerate(entries, 1):
        if not e["path"].is_file():
            continue
        if progress:
            print(f"  [{i}/{len(entries)}] {e['folder']}/{e['photo']}", file=sys.stderr)
        result, jpeg_ms, fixture_map = locate_as_user(e)
        row = judge(e, result, fixture_map)
        row.jpeg_ms = jpeg_ms
        row.paths = path_dict(result.paths)
        row.size = _size(e["path"])
        rows.append(row)
    return rows


def _size(path: Path) -> str:
    from PIL import Image

    with Image.open(path) as im:
        w, h = im.size
    return f"{w}x{h}"


def table(rows: list[Row]) -> str:
    """The per-photo table (Markdown) and its totals."""
    lines = [
        "| photo | readout | lights | right | wrong | unchecked | refused | located | "
        "position error | locate ms (detect / decode / pose) | x JPEG decode |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        t = r.timing_ms
        refused = f"{len(r.refused)}" + (f": {r.refused[0]}" if r.refused else "")
        err = "" if r.error is None else f"{r.error:.1f}"
        lines.append(
            f"| {r.folder}/{r.photo} | {r.readout} | {r.detected}/{r.lights or '?'} | "
            f"{r.right} | {r.wrong} | {r.unchecked} | {refused} | "
            f"{'yes' if r.located else 'no'} | {err} | "
            f"{t['total']:.0f} ({t['detect']:.0f} / {t['decode']:.0f} / {t['pose']:.0f}) | "
            f"{r.ratio:.2f} |"
        )
    lights = sum(r.lights for r in rows)
    lines.append(
        f"\ntotal: {len(rows)} photos, {sum(r.detected for r in rows)} lights detected of "
        f"{lights} in view; {sum(r.right for r in rows)} identified right, "
        f"{sum(r.wrong for r in rows)} wrong, {sum(r.unchecked for r in rows)} identified "
        f"without a per-light truth, {sum(len(r.refused) for r in rows)} refused; "
        f"{sum(r.located for r in rows)} located"
    )
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="only the photos marked quick")
    ap.add_argument("--only", help="only photos whose folder/name contains this text")
    ap.add_argument("--json", type=Path, help="write every row here")
    args = ap.parse_args()
    if not ROOT.is_dir():
        print(f"error: the real photographs are not at {ROOT}", file=sys.stderr)
        return 2
    entries = load_manifest()
    if args.quick:
        entries = [e for e in entries if e.get("quick")]
    if args.only:
        entries = [e for e in entries if args.only in f"{e['folder']}/{e['photo']}"]
    rows = run(entries)
    print(table(rows))
    print()
    print(time_table(r.time for r in rows))
    print(slowest((r.time for r in rows), 3))
    short = [r for r in rows if r.failures]
    for r in short:
        print(f"short of its README: {r.folder}/{r.photo}: {'; '.join(r.failures)}")
    if not short:
        print("every photo gives what its README says")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps([asdict(r) for r in rows], indent=1))
    return 1 if short else 0


if __name__ == "__main__":
    sys.exit(main())
