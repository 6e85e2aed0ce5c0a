"""Bad inputs, made small: files an attacker or a careless user could hand to camvlp.

Every bomb here is a few hundred bytes to a few kilobytes: a PNG or JPEG header announcing
100000 x 100000 pixels, JSON and YAML nested 100,000 deep, a YAML "billion laughs", integers of
400 and 5000 digits, named pipes, a sparse file over the size limit.  :func:`cases` lists every
command-line case with the exit code it must give; ``benchmarks/hostile_retry.py`` runs them all
and the tests in this folder run them (or a fast subset) under memory and time limits.
"""

from __future__ import annotations

import os
import resource
import struct
import subprocess
import sys
import threading
import time
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

#: Small camera (64 x 48 px) and four-fixture map used by the cases.
SMALL_CAMERA = """image_width: 64
image_height: 48
focal_length_px: 50
"""
SMALL_MAP = """units: m
fixtures:
  - {id: 5, position: [0.5, 0.5, 2.7], diameter: 0.15}
  - {id: 6, position: [0.5, -0.5, 2.7], diameter: 0.15}
  - {id: 9, position: [-0.5, -0.5, 2.7], diameter: 0.15}
  - {id: 10, position: [-0.5, 0.5, 2.7], diameter: 0.15}
"""


# -------------------------------------------------------------------------- single files


def png_header_only(width: int, height: int) -> bytes:
    """A PNG whose IHDR announces ``width`` x ``height`` gray pixels, with a few bytes of data."""
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    idat = zlib.compress(b"\x00" * 4096)

    def chunk(tag: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data))

    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", idat) + chunk(b"IEND", b"")


def small_jpeg(seed: int = 0, shape: tuple[int, int] = (48, 64)) -> bytes:
    """A small colour JPEG of seeded noise."""
    rng = np.random.default_rng(seed)
    img = (rng.random((*shape, 3)) * 255).astype(np.uint8)
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 90])
    assert ok
    return buf.tobytes()


def jpeg_header_only(width: int, height: int) -> bytes:
    """A small JPEG whose frame header (SOF0) is rewritten to announce ``width`` x ``height``."""
    b = bytearray(small_jpeg())
    i = 2
    while b[i + 1] != 0xC0:
        i += 2 + ((b[i + 2] << 8) | b[i + 3])
    b[i + 5 : i + 9] = struct.pack(">HH", height, width)
    return bytes(b)


def corrupt_jpeg() -> bytes:
    """A whole JPEG (it ends with FF D9) whose entropy-coded data is damaged in the middle."""
    b = bytearray(small_jpeg(shape=(240, 320)))
    mid = len(b) // 2
    b[mid : mid + 40] = bytes(x ^ 0x55 for x in b[mid : mid + 40])
    return bytes(b)


def png_bad_crc() -> bytes:
    """A small PNG whose image-data chunk has a wrong checksum."""
    ok, buf = cv2.imencode(".png", np.full((48, 64), 128, np.uint8))
    assert ok
    b = bytearray(buf.tobytes())
    i = b.index(b"IDAT")
    n = struct.unpack(">I", b[i - 4 : i])[0]
    b[i + 4 + n] ^= 0xFF  # first byte of the CRC
    return bytes(b)


def tiff_of(dtype: str, shape: tuple[int, int] = (48, 64)) -> bytes:
    """A TIFF of seeded noise in ``dtype`` (int8, int16, int32, float32, float64 ...)."""
    rng = np.random.default_rng(1)
    img = (rng.random(shape) * 100).astype(dtype)
    ok, buf = cv2.imencode(".tiff", img)
    assert ok
    return buf.tobytes()


def tiff_header_only(width: int, height: int, dtype: str = "float64") -> bytes:
    """A small gray TIFF of ``dtype`` whose first directory is rewritten to announce
    ``width`` x ``height`` pixels (LONG values)."""
    b = bytearray(tiff_of(dtype, (8, 8)))
    e = "<" if b[:2] == b"II" else ">"
    (offset,) = struct.unpack(e + "I", b[4:8])
    (count,) = struct.unpack(e + "H", b[offset : offset + 2])
    for k in range(count):
        at = offset + 2 + 12 * k
        tag = struct.unpack(e + "H", b[at : at + 2])[0]
        if tag in (256, 257):
            b[at + 2 : at + 12] = struct.pack(e + "HII", 4, 1, width if tag == 256 else height)
    return bytes(b)


def _jpeg_segments(b: bytes) -> list[tuple[int, int, int]]:
    """``(marker, start, end)`` of each segment of a well-formed JPEG (a scan with its data)."""
    out, i = [], 2
    while i < len(b):
        marker = b[i + 1]
        if marker == 0xD9:
            out.append((marker, i, i + 2))
            break
        j = i + 2 + ((b[i + 2] << 8) | b[i + 3])
        if marker == 0xDA:
            while b[j] != 0xFF or b[j + 1] == 0 or 0xD0 <= b[j + 1] <= 0xD7:
                j += 1
        out.append((marker, i, j))
        i = j
    return out


def scan_bomb(scans: int, side: int) -> bytes:
    """A progressive JPEG of a flat ``side`` x ``side`` picture whose smallest scan (a few
    bytes: one run of zeros over the whole picture) is repeated ``scans`` times: each one is a
    decoding pass over every block."""
    ok, buf = cv2.imencode(
        ".jpg", np.full((side, side, 3), 128, np.uint8), [cv2.IMWRITE_JPEG_PROGRESSIVE, 1]
    )
    assert ok
    b = buf.tobytes()
    found = [s for s in _jpeg_segments(b) if s[0] == 0xDA]
    small = min(found, key=lambda s: s[2] - s[1])
    return b[: found[-1][2]] + b[small[1] : small[2]] * scans + b"\xff\xd9"


def small_video(path: Path, size: tuple[int, int] = (64, 48), frames: int = 5) -> Path:
    """A short H.264 video of flat grey frames (``size`` = width, height, both even)."""
    import av

    with av.open(str(path), "w") as out:
        stream = out.add_stream("libx264", rate=10)
        stream.width, stream.height, stream.pix_fmt = size[0], size[1], "yuv420p"
        for i in range(frames):
            image = np.full((size[1], size[0], 3), 60 + 10 * i, np.uint8)
            for packet in stream.encode(av.VideoFrame.from_ndarray(image, format="bgr24")):
                out.mux(packet)
        for packet in stream.encode():
            out.mux(packet)
    return path


def many_fixtures_map(n: int) -> str:
    """A frequency-coded map (JSON) of ``n`` fixtures on a 0.5 m grid at 2.7 m."""
    import json

    side = int(np.ceil(np.sqrt(n)))
    fixtures = [
        {
            "id": k + 1,
            "position": [0.5 * (k % side - side // 2), 0.5 * (k // side - side // 2), 2.7],
            "diameter": 0.15,
            "frequency_hz": 1000 + k,
        }
        for k in range(n)
    ]
    return json.dumps({"units": "m", "frame": {"mode": "frequency"}, "fixtures": fixtures})


def deep_json(depth: int = 100_000) -> str:
    """A camera file's JSON with a list nested ``depth`` deep."""
    return '{"image_width": 64, "image_height": 48, "x": ' + "[" * depth + "]" * depth + "}"


def deep_yaml(depth: int = 100_000) -> str:
    """A camera file's YAML with a flow list nested ``depth`` deep."""
    return "image_width: 64\nimage_height: 48\nx: " + "[" * depth + "]" * depth + "\n"


def billion_laughs() -> str:
    """A YAML map whose aliases expand to 10^9 items."""
    lines = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for k in range(1, 9):
        prev, cur = chr(ord("a") + k - 1), chr(ord("a") + k)
        lines.append(f"{cur}: &{cur} [{','.join(['*' + prev] * 10)}]")
    lines.append("fixtures: *i")
    return "\n".join(lines) + "\n"


# -------------------------------------------------------------------------- the cases


@dataclass
class Case:
    """One command line and what it must give.

    ``argv`` are camvlp's arguments; ``code`` the exit code it must give (2: bad input, 1: not
    located, 0: done); ``left_behind`` the paths that must not exist afterwards; ``stdout``
    the file the command's stdout is sent to (None: a pipe); ``env`` environment variables set
    for it (a limit lowered).
    """

    name: str
    kind: str
    argv: list[str]
    code: int = 2
    left_behind: list[Path] = field(default_factory=list)
    stdout: str | None = None
    json_stdout: bool = False
    env: dict[str, str] = field(default_factory=dict)


def make_files(root: Path) -> dict[str, Path]:
    """Write every bad (and a few good) input file into ``root``; their paths by name."""
    root.mkdir(parents=True, exist_ok=True)
    f: dict[str, Path] = {}

    def put(name: str, data: bytes | str) -> Path:
        p = root / name
        p.write_bytes(data.encode() if isinstance(data, str) else data)
        f[name] = p
        return p

    put("camera.yaml", SMALL_CAMERA)
    put("map.yaml", SMALL_MAP)
    put("photo.jpg", small_jpeg())
    put("new\nline.jpg", small_jpeg())
    put("bomb_100000.png", png_header_only(100_000, 100_000))
    put("bomb_32000.png", png_header_only(32_000, 32_000))
    put("bomb_30000.jpg", jpeg_header_only(30_000, 30_000))
    put("corrupt.jpg", corrupt_jpeg())
    put("float64_180mp.tiff", tiff_header_only(15_000, 12_000))
    put("truncated.jpg", small_jpeg()[:-300])
    put("bad_crc.png", png_bad_crc())
    put("not_an_image.jpg", "this is text, not a photo\n")
    for dtype in ("float64", "float32", "int32", "int16", "int8"):
        put(f"photo_{dtype}.tiff", tiff_of(dtype))
    put("deep.json", deep_json())
    put("deep.yaml", deep_yaml())
    put("laughs_map.yaml", billion_laughs())
    put("digits400.yaml", SMALL_CAMERA.replace("64", "9" * 400, 1))
    put("digits5000.json", '{"image_width": ' + "9" * 5000 + ', "image_height": 48}')
    put("width_fraction.yaml", SMALL_CAMERA.replace("64", "64.5", 1))
    put("huge_camera.yaml", "image_width: 1000000\nimage_height: 1000000\nfocal_length_px: 50\n")
    put("camera_196mp.yaml", "image_width: 14000\nimage_height: 14000\nfocal_length_px: 1e4\n")
    put("nan_map.yaml", SMALL_MAP.replace("[0.5, 0.5, 2.7]", "[.nan, 0.5, 2.7]"))
    put("idbits12_map.yaml", SMALL_MAP.replace("units: m", "units: m\nframe: {id_bits: 12}"))
    put("tiny_4x4.png", cv2.imencode(".png", np.zeros((4, 4), np.uint8))[1].tobytes())
    put(  # three years at 30 frames/s: 3e9 frames, of which --frames asks for 2
        "years.csv", "t,x,y,z,theta_x,theta_y,theta_z\n0,0,0,0,0,0,0\n1e8,0.1,0,0,0,0,0\n"
    )
    put("survey.csv", "photo,x,y,z\nphoto.jpg,0,0,0\nphoto.jpg,1,0,0\n")
    put("survey1.csv", "photo,x,y,z\nphoto.jpg,0,0,0\n")
    for folder in ("study_blocked", "evaluate_blocked"):  # summary.json cannot be written
        (root / folder / "summary.json").mkdir(parents=True, exist_ok=True)
    big = root / "big_map.yaml"
    with open(big, "wb") as fh:  # sparse: 20 MB on paper, nothing on disk
        fh.truncate(20 * 1024 * 1024)
    f["big_map.yaml"] = big
    fifo = root / "pipe"
    if not fifo.exists():
        os.mkfifo(fifo)
    f["pipe"] = fifo
    existing = root / "existing_file"
    existing.write_text("x")
    f["existing_file"] = existing
    (root / "truth_dir_out.json").mkdir(exist_ok=True)  # blocks render's truth file
    # the second round: costly structures, videos, track's and render-video's outputs
    put("scans_500.jpg", scan_bomb(500, 64))
    f["video.mp4"] = small_video(root / "video.mp4")
    f["video_128.mp4"] = small_video(root / "video_128.mp4", (128, 96), 2)
    fifo_video = root / "pipe.mp4"
    if not fifo_video.exists():
        os.mkfifo(fifo_video)
    f["pipe.mp4"] = fifo_video
    put("camera_641.yaml", "image_width: 641\nimage_height: 361\nfocal_length_px: 500\n")
    put("camera_1.yaml", "image_width: 1\nimage_height: 1\nfocal_length_px: 1\n")
    put("map_2500.json", many_fixtures_map(2500))
    put("second.csv", "t,x,y,z,theta_x,theta_y,theta_z\n0,0,0,0,0,0,0\n1,0.1,0,0,0,0,0\n")
    frames = root / "frames"
    frames.mkdir(exist_ok=True)
    for k in range(2):
        (frames / f"f{k}.png").write_bytes(
            cv2.imencode(".png", np.full((48, 64), 40, np.uint8))[1].tobytes()
        )
    f["frames"] = frames
    bad_truth = root / "frames_bad_truth"
    bad_truth.mkdir(exist_ok=True)
    for k in range(2):
        (bad_truth / f"f{k}.png").write_bytes((frames / f"f{k}.png").read_bytes())
    (bad_truth / "truth.csv").write_text("frame,t,x,y,z,theta_x,theta_y,theta_z\nf0.png,0,a\n")
    f["frames_bad_truth"] = bad_truth
    noted = root / "frames_noted"  # a file that is not a frame (a warning) and no lamp
    noted.mkdir(exist_ok=True)
    (noted / "f0.png").write_bytes((frames / "f0.png").read_bytes())
    (noted / "readme.txt").write_text("not a frame")
    f["frames_noted"] = noted
    for blocked in ("summary.json", "trajectory.png"):  # an output place that is a folder
        (root / f"track_blocked_{Path(blocked).stem}" / blocked).mkdir(parents=True, exist_ok=True)
    return f


def cases(root: Path) -> list[Case]:
    """Every command-line case, with its files written into ``root``."""
    f = make_files(root)
    cam, fmap, photo = str(f["camera.yaml"]), str(f["map.yaml"]), str(f["photo.jpg"])
    thesis_cam = str(Path(__file__).resolve().parents[2] / "examples" / "thesis_camera.yaml")
    loc = ["-c", cam, "-m", fmap]
    out = root / "out"
    out.mkdir(exist_ok=True)
    c: list[Case] = []

    def add(name: str, kind: str, argv: list[str], code: int = 2, **kw) -> None:
        c.append(Case(name, kind, [str(a) for a in argv], code, **kw))

    def render_argv(camera, png, *extra, position="0,0,0") -> list:
        """``camvlp render`` of ``camera`` and the small map into ``png``, with ``extra``."""
        return [
            "render",
            "--camera",
            camera,
            "--map",
            fmap,
            f"--position={position}",
            "--euler",
            "0,0,0",
            "--out",
            png,
            *extra,
        ]

    # images: bombs, depths, damage, special files
    for name in ("bomb_100000.png", "bomb_32000.png", "bomb_30000.jpg"):
        add(f"locate {name}", "memory: image bomb", ["locate", f[name], *loc])
    add(
        "locate float64_180mp.tiff",
        "memory: image bomb",
        ["locate", f["float64_180mp.tiff"], *loc],
    )
    for dtype in ("float64", "float32", "int32", "int16", "int8"):
        add(
            f"locate photo_{dtype}.tiff",
            "traceback: pixel type",
            ["locate", f[f"photo_{dtype}.tiff"], *loc],
            code=1,
        )
    add("locate corrupt.jpg", "stderr: corrupt JPEG", ["locate", f["corrupt.jpg"], *loc])
    add("locate truncated.jpg", "stderr: truncated JPEG", ["locate", f["truncated.jpg"], *loc])
    add("locate bad_crc.png", "stderr: libpng error", ["locate", f["bad_crc.png"], *loc])
    add("locate not_an_image.jpg", "bad input", ["locate", f["not_an_image.jpg"], *loc])
    add("locate FIFO photo", "hang: named pipe", ["locate", f["pipe"], *loc])
    add("locate FIFO camera", "hang: named pipe", ["locate", photo, "-c", f["pipe"], "-m", fmap])
    add("locate FIFO map", "hang: named pipe", ["locate", photo, "-c", cam, "-m", f["pipe"]])
    add("locate /dev/zero", "hang: device", ["locate", "/dev/zero", *loc])
    add("locate a folder", "bad input", ["locate", root, *loc])
    add(
        "locate newline name",
        "stderr: newline in a name",
        ["locate", root / "no\nsuch.jpg", *loc],
    )
    add(
        "locate a photo named with a newline",
        "stderr: newline in a name",
        ["locate", f["new\nline.jpg"], *loc],
        code=1,
    )
    # camera and map files
    for name in ("deep.json", "deep.yaml", "digits400.yaml", "digits5000.json"):
        add(
            f"locate -c {name}",
            "traceback: camera file",
            ["locate", photo, "-c", f[name], "-m", fmap],
        )
    add(
        "locate -c width_fraction.yaml",
        "wrong answer: fractional width",
        ["locate", photo, "-c", f["width_fraction.yaml"], "-m", fmap],
    )
    add(
        "locate -m laughs_map.yaml",
        "memory: billion laughs",
        ["locate", photo, "-c", cam, "-m", f["laughs_map.yaml"]],
    )
    add(
        "locate -m nan_map.yaml", "bad input", ["locate", photo, "-c", cam, "-m", f["nan_map.yaml"]]
    )
    add(
        "locate -m idbits12_map.yaml",
        "memory: ambiguity check",
        ["locate", photo, "-c", cam, "-m", f["idbits12_map.yaml"]],
    )
    add(
        "locate -m big_map.yaml (20 MB)",
        "memory: file size",
        ["locate", photo, "-c", cam, "-m", f["big_map.yaml"]],
    )
    add(
        "render huge camera",
        "memory: render size",
        render_argv(f["huge_camera.yaml"], out / "huge.png"),
        left_behind=[out / "huge.png", out / "huge.json"],
    )
    add(
        "render 196 MP camera",
        "memory: render size",
        render_argv(f["camera_196mp.yaml"], out / "big.png"),
        left_behind=[out / "big.png", out / "big.json"],
    )
    # option values
    add("encode --chip-rate nan", "traceback: NaN option", ["encode", "5", "--chip-rate", "nan"])
    add("encode --chip-rate inf", "wrong answer: inf option", ["encode", "5", "--chip-rate", "inf"])
    add(
        "calibrate-rows --frequency inf",
        "traceback: inf option",
        ["calibrate-rows", photo, "--frequency", "inf"],
    )
    add(
        "calibrate-rows --frequency 1e308",
        "traceback: huge option",
        ["calibrate-rows", photo, "--frequency", "1e308"],
    )
    add(
        "study world-error --range=-1e308,1e308",
        "traceback: huge option",
        ["study", "world-error", "--range=-1e308,1e308"],
    )
    add(
        "study image-error --trials 1e9",
        "memory: Monte Carlo trials",
        ["study", "image-error", "--noise-px", "1", "--trials", "1000000000"],
    )
    add(
        "calibrate --board 100000x100000",
        "memory: board size",
        [
            "calibrate",
            photo,
            "--board",
            "100000x100000",
            "--square",
            "0.02",
            "--out",
            out / "cal.yaml",
        ],
        left_behind=[out / "cal.yaml"],
    )
    add(
        "calibrate 4 x 4 photo",
        "traceback: tiny photo",
        [
            *("calibrate", f["tiny_4x4.png"], "--board", "9x6"),
            *("--square", "0.02", "--out", out / "c3.yaml"),
        ],
        code=1,  # the photo is rejected: fewer than 3 photos show the board
        left_behind=[out / "c3.yaml"],
    )
    add(
        "calibrate --board 3x2",
        "traceback: board size",
        ["calibrate", photo, "--board", "3x2", "--square", "0.02", "--out", out / "c4.yaml"],
        left_behind=[out / "c4.yaml"],
    )
    add(
        "render-video --frames 2 of a years-long trajectory",
        "memory: frame times",
        [
            *("render-video", "--camera", cam, "--map", fmap),
            *("--trajectory", f["years.csv"], "--frames", "2", "--out", out / "years"),
        ],
        code=0,
    )
    add(
        "evaluate --jobs 1000",
        "memory: worker processes",
        ["evaluate", f["survey.csv"], *loc, "--jobs", "1000", "--out", out / "ev"],
        code=0,
    )
    add(
        "render --blur 1e6",
        "crash: blur",
        render_argv(thesis_cam, out / "b1.png", "--blur", "1e6"),
        left_behind=[out / "b1.png", out / "b1.json"],
    )
    add(
        "render --blur 1000",
        "hang: blur",
        render_argv(thesis_cam, out / "b2.png", "--blur", "1000"),
        left_behind=[out / "b2.png", out / "b2.json"],
    )
    add(
        "render --position=1e308,0,0",
        "wrong answer: NaN truth",
        render_argv(cam, out / "p.png", position="1e308,0,0"),
        left_behind=[out / "p.png", out / "p.json"],
    )
    add(
        "evaluate FIFO survey",
        "hang: named pipe",
        ["evaluate", f["pipe"], *loc, "--out", out / "ev2"],
    )
    add(
        "calibrate FIFO board folder",
        "hang: named pipe",
        ["calibrate", f["pipe"], "--board", "9x6", "--square", "0.02", "--out", out / "c2.yaml"],
        code=1,  # calibrate reports unreadable photos as photos without the board
        left_behind=[out / "c2.yaml"],
    )
    # outputs
    add(
        "locate --debug-dir existing file",
        "traceback: output",
        ["locate", photo, *loc, "--debug-dir", f["existing_file"]],
    )
    add(
        "locate --annotate A --debug-dir BAD",
        "half-written output",
        ["locate", photo, *loc, "--annotate", out / "a.png", "--debug-dir", f["existing_file"]],
        left_behind=[out / "a.png"],
    )
    add(
        "calibrate --out missing folder",
        "traceback: output",
        [
            "calibrate",
            photo,
            "--board",
            "9x6",
            "--square",
            "0.02",
            "--out",
            root / "missing" / "cal.yaml",
        ],
    )
    add(
        "render truth file blocked",
        "half-written output",
        render_argv(cam, root / "truth_dir_out.png"),
        left_behind=[root / "truth_dir_out.png"],
    )
    add(
        "study --out: summary.json blocked",
        "half-written output",
        ["study", "rounding", "--step", "0.5", "--out", root / "study_blocked"],
        left_behind=[root / "study_blocked" / n for n in ("rounding.csv", "rounding.png")],
    )
    add(
        "evaluate --out: summary.json blocked",
        "half-written output",
        ["evaluate", f["survey1.csv"], *loc, "--out", root / "evaluate_blocked"],
        left_behind=[root / "evaluate_blocked" / n for n in ("results.csv", "error_map.png")],
    )
    add("encode > /dev/full", "traceback: full device", ["encode", "5"], stdout="/dev/full")
    # the second round
    add(
        "locate scans_500.jpg",
        "cpu: JPEG scans",
        ["locate", f["scans_500.jpg"], *loc],
    )

    def video_argv(camera, out_path, *extra) -> list:
        """``camvlp render-video`` of ``camera`` and the small map along a 1 s trajectory."""
        return [
            *("render-video", "--camera", camera, "--map", fmap),
            *("--trajectory", f["second.csv"], "--out", out_path, *extra),
        ]

    rv = root / "rv"
    rv.mkdir(exist_ok=True)
    for blur, kind in (("1e6", "crash: blur"), ("1000", "hang: blur")):
        add(
            f"render-video --blur {blur}",
            f"render-video: {kind}",
            video_argv(cam, rv / f"blur{blur}", "--frames", "1", "--blur", blur),
            left_behind=[rv / f"blur{blur}"],
        )
    add(
        "render-video --fps 1e9 without --frames",
        "render-video: frame budget",
        video_argv(cam, rv / "fps", "--fps", "1e9"),
        left_behind=[rv / "fps"],
    )
    for name in ("camera_641.yaml", "camera_1.yaml"):
        add(
            f"render-video {name} to mp4",
            "render-video: odd picture for H.264",
            video_argv(f[name], rv / f"{name}.mp4", "--frames", "1"),
            left_behind=[rv / f"{name}.mp4", rv / f"{name}.partial.mp4"],
        )
    add(
        "render-video map_2500.json",
        "render-video: many fixtures",
        video_argv(cam, rv / "many", "--map", f["map_2500.json"], "--frames", "1"),
        code=0,
    )
    tr = root / "tr"
    tr.mkdir(exist_ok=True)
    written = ("trajectory.csv", "fixtures.csv", "summary.json", "trajectory.png")

    def track_case(name: str, kind: str, source, out_dir: Path, *extra, code=2, **kw) -> None:
        left = [out_dir / n for n in written if code == 2 and not (out_dir / n).is_dir()]
        add(
            name,
            kind,
            ["track", source, *loc, "--out", out_dir, *extra],
            code,
            left_behind=left,
            **kw,
        )

    track_case("track FIFO pipe.mp4", "track: hang on a pipe", f["pipe.mp4"], tr / "fifo")
    track_case(
        "track a video over the pixel limit",
        "track: video pixels",
        f["video_128.mp4"],
        tr / "pixels",
        env={"CAMVLP_MAX_PIXELS": "5000"},
    )
    track_case(
        "track a video over the frame limit",
        "track: video frames",
        f["video.mp4"],
        tr / "count",
        env={"CAMVLP_MAX_FRAMES": "3"},
    )
    track_case(
        "track --fps 1e-300",
        "track: half-written outputs",
        f["frames"],
        tr / "fps",
        "--fps",
        "1e-300",
    )
    for blocked in ("summary", "trajectory"):
        track_case(
            f"track --out: {blocked} blocked",
            "track: half-written outputs",
            f["frames"],
            root / f"track_blocked_{blocked}",
            "--fps",
            "10",
        )
    track_case(
        "track a malformed truth.csv",
        "track: half-written outputs",
        f["frames_bad_truth"],
        tr / "truth",
        "--fps",
        "10",
    )
    track_case(
        "track: the error line alone (no warning before it)",
        "track: warning before the error",
        f["frames_noted"],
        tr / "noted",
        "--fps",
        "10",
        code=1,
    )
    add(
        "locate --json (not located)",
        "wrong answer: JSON with NaN",
        ["locate", photo, *loc, "--json"],
        code=1,
        json_stdout=True,
    )
    return c


# -------------------------------------------------------------------------- running a case


@dataclass
class Outcome:
    """What a case did: exit code, stderr lines, peak resident memory (MB), wall time (s)."""

    code: int
    stderr: list[str]
    stdout: str
    peak_mb: float
    seconds: float
    timed_out: bool


def run_case(
    case: Case,
    *,
    timeout_s: float = 10.0,
    memory_bytes: int = 1 << 30,
    env: dict[str, str] | None = None,
) -> Outcome:
    """Run ``camvlp`` with the case's arguments in a child process limited to ``memory_bytes``
    of address space, killed after ``timeout_s`` seconds."""
    src = str(Path(__file__).resolve().parents[2] / "src")
    child_env = dict(os.environ if env is None else env)
    child_env.update(case.env)
    child_env["PYTHONPATH"] = src + os.pathsep + child_env.get("PYTHONPATH", "")
    child_env.setdefault("OPENBLAS_NUM_THREADS", "1")

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (memory_bytes, memory_bytes))

    stdout = open(case.stdout, "w") if case.stdout else subprocess.PIPE
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, "-m", "camvlp", *case.argv],
        stdin=subprocess.DEVNULL,
        stdout=stdout,
        stderr=subprocess.PIPE,
        env=child_env,
        preexec_fn=limit,
    )
    killed = threading.Event()

    def kill() -> None:
        killed.set()
        proc.kill()

    timer = threading.Timer(timeout_s, kill)
    timer.start()
    out_chunks: list[bytes] = []
    reader = None
    if proc.stdout is not None:
        reader = threading.Thread(target=lambda: out_chunks.append(proc.stdout.read()))
        reader.start()
    err = proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    seconds = time.perf_counter() - t0
    timer.cancel()
    if reader is not None:
        reader.join()
    proc.returncode = os.waitstatus_to_exitcode(status)
    if case.stdout:
        stdout.close()
    return Outcome(
        code=proc.returncode,
        stderr=err.decode("utf-8", "replace").splitlines(),
        stdout=b"".join(out_chunks).decode("utf-8", "replace"),
        peak_mb=usage.ru_maxrss / 1024.0,
        seconds=seconds,
        timed_out=killed.is_set(),
    )


def problems(case: Case, outcome: Outcome) -> list[str]:
    """Every way ``outcome`` breaks the promise for ``case`` (empty when it keeps it)."""
    found = []
    if outcome.timed_out:
        found.append("timed out")
    if outcome.code != case.code:
        found.append(f"exit {outcome.code}, expected {case.code}")
    errors = [ln for ln in outcome.stderr if ln.startswith("error: ")]
    others = [ln for ln in outcome.stderr if not ln.startswith(("error: ", "note: "))]
    if case.code != 0 and len(errors) != 1:
        found.append(f"{len(errors)} error lines")
    if others:
        found.append(f"extra stderr: {others[0][:80]!r}")
    if outcome.peak_mb > 1024:
        found.append(f"peak {outcome.peak_mb:.0f} MB")
    for p in case.left_behind:
        if Path(p).exists():
            found.append(f"left behind {Path(p).name}")
    if case.json_stdout:
        try:
            import json

            json.loads(outcome.stdout, parse_constant=_refuse_constant)
        except ValueError as exc:
            found.append(f"stdout not strict JSON: {exc}")
    return found


def _refuse_constant(name: str) -> float:
    raise ValueError(f"{name} in JSON")


#: Arguments of the cases' command lines, for callers that want them as a function.
CaseFactory = Callable[[Path], list[Case]]


# -------------------------------------------------------------------------- the Python API


def api_cases(root: Path) -> list[tuple[str, Callable[[], object]]]:
    """Calls of the Python API with bad input (files from :func:`make_files` in ``root``)."""
    import camvlp

    f = make_files(root)
    camera = camvlp.load_camera(f["camera.yaml"])
    fmap = camvlp.load_map(f["map.yaml"])
    rng = np.random.default_rng(2)
    base = rng.random((48, 64))
    arrays = {
        dtype: (base * 100).astype(dtype)
        for dtype in ("float64", "float16", "int8", "int64", "uint32", "bool", "complex128")
    }
    arrays["object"] = base.astype(object)
    arrays["float64 NaN"] = np.where(base > 0.5, np.nan, base)
    calls: list[tuple[str, Callable[[], object]]] = [
        (f"locate({name} array)", lambda a=a: camvlp.locate(a, camera, fmap))
        for name, a in arrays.items()
    ]
    calls += [
        (
            "locate(nested list)",
            lambda: camvlp.locate((base * 255).astype(int).tolist(), camera, fmap),
        ),
        ("locate(ragged list)", lambda: camvlp.locate([[1, 2], [3]], camera, fmap)),
        ("locate(None)", lambda: camvlp.locate(None, camera, fmap)),
        ("locate(camera=None)", lambda: camvlp.locate(arrays["int8"], None, fmap)),
        ("locate(fixture_map=None)", lambda: camvlp.locate(arrays["int8"], camera, None)),
        ("locate((48, 64, 5) array)", lambda: camvlp.locate(np.zeros((48, 64, 5)), camera, fmap)),
    ]
    for name in ("bomb_100000.png", "bomb_30000.jpg", "corrupt.jpg", "pipe"):
        calls.append((f"load_image({name})", lambda p=f[name]: camvlp.load_image(p)))
    for name in ("deep.json", "deep.yaml", "digits400.yaml", "digits5000.json", "pipe"):
        calls.append((f"load_camera({name})", lambda p=f[name]: camvlp.load_camera(p)))
    for name in ("laughs_map.yaml", "nan_map.yaml", "big_map.yaml", "idbits12_map.yaml"):
        calls.append((f"load_map({name})", lambda p=f[name]: camvlp.load_map(p)))
    from camvlp.io import camera_from_dict, decode_image, map_from_dict

    for name in ("bomb_100000.png", "float64_180mp.tiff", "corrupt.jpg", "not_an_image.jpg"):
        calls.append(
            (f"decode_image({name} bytes)", lambda p=f[name]: decode_image(p.read_bytes(), "up"))
        )
    calls += [
        ("decode_image(a str)", lambda: decode_image("not bytes", "up")),
        (
            "camera_from_dict(400-digit width)",
            lambda: camera_from_dict({"image_width": 10**400, "image_height": 48}),
        ),
        (
            "camera_from_dict(width 5184.5)",
            lambda: camera_from_dict(
                {"image_width": 5184.5, "image_height": 3880, "focal_length_px": 3912}
            ),
        ),
        (
            "map_from_dict(NaN position)",
            lambda: map_from_dict({"fixtures": [{"id": 1, "position": [float("nan"), 0, 0]}]}),
        ),
    ]
    # the second round: a JPEG's scans, the tracker's times, a render's size
    from camvlp.pipeline.track.tracker import Tracker

    calls.append(("decode_image(20,000 scans)", lambda: decode_image(scan_bomb(20_000, 512))))
    for t in (1e300, float("nan"), -1.0):

        def backwards(t=t):
            tracker = Tracker(camera, fmap)
            tracker.update(np.zeros((48, 64), np.uint8), 0.0)
            try:
                return tracker.update(np.zeros((48, 64), np.uint8), t)
            finally:  # the tracker must still take the next frame
                tracker.update(np.zeros((48, 64), np.uint8), 0.1)

        calls.append((f"Tracker.update(t={t})", backwards))
    huge = camvlp.Camera.from_focal(100_000, 100_000, 5e4)
    pose = camvlp.Pose.from_euler([0, 0, 0], [0, 0, 0])
    calls.append(("render(100000 x 100000 camera)", lambda: camvlp.render(huge, fmap, pose)))
    return calls
