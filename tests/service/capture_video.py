"""A camera for the capture page's browser test: a video that ``camvlp render-video`` makes,
turned into the .y4m file that Chromium's fake camera plays, with its truth per frame.

The camera (640 x 480, f = 420 px, 40 us rows: 2.5 rows per 10 kHz chip) is held 2 m under
the small room's ceiling, tilted 3 degrees and 2 degrees off looking straight up, and goes
round an ellipse of 0.15 x 0.10 m in 4 s while it turns its heading by +-6 degrees: 60 frames
at 15 frames per second.  The path is closed, so Chromium, which plays the file in a loop,
shows one smooth motion.  Its gravity in the camera's frame is the same in every frame to
within 0.3 degrees (the heading turns about the vertical).
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from pathlib import Path

import av
import numpy as np
from service_helpers import MAP_JSON

from camvlp.cli import main
from camvlp.model.camera import Pose

#: The fake camera: its camera file's keys.
CAMERA_JSON = {
    "image_width": 640,
    "image_height": 480,
    "focal_length_px": 420.0,
    "row_time_s": 40e-6,
}
FPS, PERIOD_S = 15, 4.0
#: The map's down (the small room is y-down: up is -y).
DOWN = np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class CaptureVideo:
    """The fake camera's file and what it shows.

    Attributes
    ----------
    y4m : Path
        The video Chromium plays as its camera.
    frames : ndarray, shape (N, H, W), float32
        Each frame's gray levels, as the file holds them (to tell which frame a page sent).
    positions : ndarray, shape (N, 3)
        The true camera centre of each frame (its middle row's time), metres.
    fixtures : list of dict
        Per frame: fixture ID -> its true pixel (u, v), for the fixtures whose disc is in it.
    gravity : ndarray, shape (3,)
        Gravity in the camera's frame (unit vector), the mean over the frames.
    """

    y4m: Path
    frames: np.ndarray
    positions: np.ndarray
    fixtures: list[dict[int, np.ndarray]]
    gravity: np.ndarray

    def which_frame(self, gray: np.ndarray) -> tuple[int, float]:
        """The frame nearest to a gray picture (mean squared difference) and how sure: the
        ratio of the best difference to the second best (small: sure)."""
        d = np.mean(np.square(self.frames - gray.astype(np.float32)[None]), axis=(1, 2))
        order = np.argsort(d)
        return int(order[0]), float(d[order[0]] / max(d[order[1]], 1e-9))


def _trajectory(path: Path) -> None:
    t = np.linspace(0.0, PERIOD_S, 121)
    w = 2 * np.pi * t / PERIOD_S
    with path.open("w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(["t", "x", "y", "z", "theta_x", "theta_y", "theta_z"])
        for ti, wi in zip(t, w, strict=True):
            row = [ti, 0.15 * np.cos(wi), -0.7, 0.10 * np.sin(wi), 93.0, 2.0, 10 + 6 * np.sin(wi)]
            out.writerow([f"{v:.6f}" for v in row])


def make_capture_video(folder: Path) -> CaptureVideo:
    """Render the video with ``camvlp render-video`` (H.264, as a phone records) and write
    it as ``capture.y4m`` (PyAV: the same 4:2:0 frames, uncompressed)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "camera.json").write_text(json.dumps(CAMERA_JSON))
    (folder / "map.json").write_text(json.dumps(MAP_JSON))
    _trajectory(folder / "trajectory.csv")
    mp4 = folder / "capture.mp4"
    code = main(
        ["render-video", "--camera", str(folder / "camera.json"), "--map",
         str(folder / "map.json"), "--trajectory", str(folder / "trajectory.csv"), "--out",
         str(mp4), "--fps", str(FPS), "--frames", str(int(FPS * PERIOD_S)), "--seed", "5"]
    )  # fmt: skip
    assert code == 0, f"camvlp render-video exited {code}"
    y4m = folder / "capture.y4m"
    frames = []
    with av.open(str(mp4)) as src, av.open(str(y4m), "w", format="yuv4mpegpipe") as dst:
        stream = dst.add_stream("rawvideo", rate=FPS)
        stream.width, stream.height = CAMERA_JSON["image_width"], CAMERA_JSON["image_height"]
        stream.pix_fmt = "yuv420p"
        for frame in src.decode(video=0):
            frames.append(frame.to_ndarray(format="gray").astype(np.float32))
            for packet in stream.encode(frame.reformat(format="yuv420p")):
                dst.mux(packet)
        for packet in stream.encode():
            dst.mux(packet)
    with (folder / "capture_truth.csv").open() as fh:
        truth = list(csv.DictReader(fh))
    positions = np.array([[float(r[c]) for c in "xyz"] for r in truth])
    angles = np.array([[float(r[f"theta_{c}"]) for c in "xyz"] for r in truth])
    seen: list[dict[int, np.ndarray]] = [{} for _ in truth]
    with (folder / "capture_fixtures.csv").open() as fh:
        for r in csv.DictReader(fh):
            seen[int(r["frame"])][int(r["id"])] = np.array([float(r["u"]), float(r["v"])])
    down = [
        Pose.from_euler(p, a).world_from_camera.T @ DOWN
        for p, a in zip(positions, angles, strict=True)
    ]
    gravity = np.mean(down, axis=0)
    assert len(frames) == len(truth) == FPS * PERIOD_S
    return CaptureVideo(y4m, np.stack(frames), positions, seen, gravity / np.linalg.norm(gravity))
