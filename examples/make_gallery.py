"""Render the thesis' chapter 3 poses (figures 3.8 to 3.10), with the gallery's page.

Each photo is rendered at the thesis camera's full 5184 x 3880, then saved about 1000 px
wide with its pose as a caption and, in the corner, a full-resolution crop of one fixture
so that the stripes can be seen.  Also writes the page that shows them, ``index.md``, and
prints the render time of each full-size photo.  The documentation's gallery is this
script's output with ``--out docs/gallery``.

Usage::

    python examples/make_gallery.py [--out out/gallery]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import cv2
import numpy as np

from camvlp import Pose, RenderSettings, load_camera, load_map, render, tilt_limit
from camvlp.sim.render import distinct_colours

ROOT = Path(__file__).resolve().parents[1]
WIDTH = 1000  # px of the saved pictures
INSET = 240  # px of the full-resolution crop shown in the corner

# (file stem, figure, camera centre C (m), thesis angles theta (deg), colour per fixture)
POSES = [
    ("fig3_8a", "3.8a", (0, 0, 0), (90, 0, 0), False),
    ("fig3_8b", "3.8b", (0, 0, 0), (102, 0, 0), False),
    ("fig3_8c", "3.8c", (0, 0, 0), (78, 0, 0), False),
    ("fig3_8d", "3.8d", (0, 0, 0), (90, 15, 0), False),
    ("fig3_9a", "3.9a", (0, 0, 0.6), (90, 0, 0), False),
    ("fig3_9b", "3.9b", (0, 0, 0), (81, 14, 0), True),
    ("fig3_9c", "3.9c", (0, 0, -3.2), (60, 0, 0), False),
    ("fig3_9d", "3.9d", (0, 0, -0.9), (60, 0, 0), False),
    ("fig3_10a", "3.10a", (0, -1, 0), (90, 0, 0), False),
    ("fig3_10b", "3.10b", (0, -1, 0), (94, 0, 0), False),
    ("fig3_10c", "3.10c", (0, -1, 0), (90, 6, 0), False),
]


def _fmt(values) -> str:
    return "(" + ", ".join(f"{v:g}" for v in values) + ")"


def _picture(result, caption: str) -> np.ndarray:
    """Downscaled photo with a caption band, and a full-resolution crop of one fixture beside it."""
    img = result.image
    h, w = img.shape[:2]
    small = cv2.resize(img, (WIDTH, round(h * WIDTH / w)), interpolation=cv2.INTER_AREA)
    panel = np.zeros((small.shape[0], INSET + 16, 3), np.uint8)
    inside = [t for t in result.fixtures if t.fully_inside]
    if inside:
        t = min(inside, key=lambda t: abs(t.pixel[0] - w / 2) + abs(t.pixel[1] - h / 2))
        u, v = np.round(t.pixel).astype(int)
        # the disc's extent: lit pixels in a generous window around its centre
        r = int(2 * max(t.rows_spanned, 20))
        win = img[max(v - r, 0) : v + r, max(u - r, 0) : u + r].max(axis=2) > 64
        ys, xs = np.nonzero(win)
        half = int(0.6 * max(np.ptp(xs), np.ptp(ys), 20)) if xs.size else r // 2
        crop = img[max(v - half, 0) : v + half, max(u - half, 0) : u + half]
        crop = cv2.resize(crop, (INSET, INSET), interpolation=cv2.INTER_AREA)
        y0 = 40
        panel[y0 : y0 + INSET, 8 : 8 + INSET] = crop
        cv2.rectangle(panel, (7, y0 - 1), (8 + INSET, y0 + INSET), (160, 160, 160), 1)
        for i, text in enumerate(
            (
                f"fixture {t.id} at full resolution",
                f"{t.rows_spanned:.0f} rows, {t.frames_spanned:.2f} frames",
            )
        ):
            cv2.putText(
                panel,
                text,
                (8, y0 + INSET + 22 + 20 * i),
                cv2.FONT_HERSHEY_SIMPLEX,
                0.45,
                (220, 220, 220),
                1,
                cv2.LINE_AA,
            )
    panel[:, :2] = 90  # separator
    body = np.hstack([small, panel])
    band = np.zeros((34, body.shape[1], 3), np.uint8)
    cv2.putText(
        band, caption, (8, 23), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 1, cv2.LINE_AA
    )
    return np.vstack([band, body])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "out" / "gallery")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    camera = load_camera(ROOT / "examples" / "thesis_camera.yaml")
    fixture_map = load_map(ROOT / "examples" / "thesis_room.yaml")
    rows = []
    for stem, figure, position, euler, colour in POSES:
        settings = RenderSettings(
            colours=distinct_colours(len(fixture_map.fixtures)) if colour else None,
            full_well_e=0.0,  # no sensor noise: invisible at 1000 px, and it bloats the PNGs
            read_noise=0.0,
        )
        t0 = time.perf_counter()
        result = render(camera, fixture_map, Pose.from_euler(position, euler), settings)
        seconds = time.perf_counter() - t0
        n_inside = sum(t.fully_inside for t in result.fixtures)
        frames = min(t.frames_spanned for t in result.fixtures if t.in_front)
        caption = (
            f"Fig. {figure}   C = {_fmt(position)} m   theta = {_fmt(euler)} deg   "
            f"{n_inside}/4 fully inside"
        )
        picture = _picture(result, caption)
        if not colour:
            picture = cv2.cvtColor(picture, cv2.COLOR_BGR2GRAY)
        path = args.out / f"{stem}.png"
        cv2.imwrite(str(path), picture, [cv2.IMWRITE_PNG_COMPRESSION, 9])
        print(
            f"{path.name}: rendered 5184 x 3880 in {seconds:.2f} s, {n_inside}/4 fully inside, "
            f"{path.stat().st_size / 1024:.0f} KB"
        )
        rows.append((stem, figure, position, euler, n_inside, frames, colour))
    limits = {
        (c, axis, d): tilt_limit(camera, fixture_map, c, (90, 0, 0), axis, d)
        for c in [(0, 0, 0), (0, -1, 0)]
        for axis in (0, 1)
        for d in (1, -1)
    }
    _write_page(args.out, rows, limits)


def _write_page(out: Path, rows, limits) -> None:
    lines = [
        "# Simulated photographs of the thesis' room (figures 3.8 to 3.10)",
        "",
        "Rendered by `examples/make_gallery.py` with `camvlp.render`: the thesis camera",
        "(`examples/thesis_camera.yaml`, 5184 x 3880, f = 3912 px, 20 us per row) and room",
        "(`examples/thesis_room.yaml`, four 15 cm fixtures, IDs 5, 6, 9, 10, at y = -2.7 m),",
        "default settings (10 kHz chips, exposure half a chip, brightness 4 x full scale, so",
        "bright stripes bleed) but no sensor noise (invisible at this scale).  Each picture is",
        "the full photo scaled to 1000 px wide; beside it, a full-resolution crop of the",
        "fixture nearest the image centre.  C is the camera centre in metres (y down, the floor",
        "at y = 0), theta the thesis' angles in degrees (R = Rx Ry Rz; (90, 0, 0) looks",
        "straight up at the ceiling).  Frames spanned: Manchester frames (18 chips) across a",
        "fixture's image along the readout axis; decoding needs at least one.",
        "",
    ]
    for stem, figure, position, euler, n_inside, frames, colour in rows:
        note = ", a colour per fixture" if colour else ""
        lines += [
            f"## Fig. {figure}: C = {_fmt(position)}, theta = {_fmt(euler)}",
            "",
            f"{n_inside}/4 fixtures fully inside; the fewest frames any fixture spans: "
            f"{frames:.2f}{note}.",
            "",
            f"![Fig. {figure}]({stem}.png)",
            "",
        ]
    lines += [
        "## Tilt limits",
        "",
        "Tilt limits keeping all four discs wholly in the picture (bisection with",
        "`camvlp.sim.render.tilt_limit`; tilt about x is theta_x = 90 + t, about y is",
        "theta_y = t; the thesis, section 3.4, reports about 12 and 15 degrees from the floor",
        "and 4 and 6 from 1 m up):",
        "",
        "| camera centre | about x (+ / -) | about y (+ / -) |",
        "|---|---|---|",
    ]
    for c in [(0, 0, 0), (0, -1, 0)]:
        lines.append(
            f"| {_fmt(c)} | {limits[(c, 0, 1)]:.2f} / {limits[(c, 0, -1)]:.2f} | "
            f"{limits[(c, 1, 1)]:.2f} / {limits[(c, 1, -1)]:.2f} |"
        )
    (out / "index.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
