"""The real-time path: video frames of one device after another, each with a memory.

A phone that streams its camera sends one frame after another to
``POST /api/v1/sites/{id}/frames``.  Each device (site, camera and device name) keeps a
:class:`camvlp.pipeline.track.Tracker` in the service process, as ``camvlp track`` does along
a video: the readout and chip length found in the first frames, every fixture's ID and image
position, and the last pose with a constant-velocity filter, the prior of the next frame (two
or three fixtures are then enough).  A frame that the track cannot place, sent with the
phone's gravity, is located alone with it (:func:`camvlp.locate`, two fixtures and more).

Each device has at most one frame being located and one waiting: a frame that arrives while
another waits takes its place (the one it replaces is answered at once as dropped), so a
client that sends faster than its frames are located never builds a queue; its answers are
the newest frames'.  The devices kept are bounded (``frame_devices``, the one idle longest
goes) and forgotten after ``frame_idle_s`` without a frame.
"""

from __future__ import annotations

import asyncio
import math
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from camvlp.errors import InputError
from camvlp.geometry.pose_sigma import position_sigma
from camvlp.io import decode_image
from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.locate import LocateSettings, locate
from camvlp.pipeline.track.tracker import Tracker, TrackFrame
from camvlp.service.imagesize import read_image_header
from camvlp.service.plan import PlanView, plan_view

__all__ = [
    "FRAME_STATUSES",
    "DeviceTrack",
    "FrameDropped",
    "FrameRefused",
    "FrameTracks",
    "locate_frame",
]

#: A frame's statuses: ``fix`` (four or more fixtures), ``tracked`` (two or three with the
#: track's prior), ``gravity`` (located alone with the phone's gravity), ``predicted`` (the
#: track's prediction, nothing measured), ``lost``.  The first three are located.
FRAME_STATUSES = ("fix", "tracked", "gravity", "predicted", "lost")
_LOCATED = ("fix", "tracked", "gravity")


class FrameRefused(Exception):
    """A frame the locator cannot take: ``status`` (4xx) and a one-line ``detail``."""

    def __init__(self, status: int, detail: str):
        super().__init__(detail)
        self.status, self.detail = status, detail


class FrameDropped(Exception):
    """A frame not located: ``reason`` is ``superseded`` or ``stale``."""

    def __init__(self, reason: str, detail: str):
        super().__init__(detail)
        self.reason, self.detail = reason, detail


@dataclass
class _Pending:
    """A frame waiting for its device's turn."""

    body: bytes
    kind: str  # "encoded" (JPEG or PNG) or "gray" (width x height bytes)
    t: float
    gravity: list[float] | None
    future: asyncio.Future
    arrived: float = field(default_factory=time.perf_counter)
    waited: float = 0.0  # seconds from its arrival to its turn


@dataclass
class DeviceTrack:
    """One device's track: its tracker and the frame running and the one waiting.

    Attributes
    ----------
    camera, fixture_map : Camera, FixtureMap
        What the tracker was made with; ``sources`` their stored JSON (a site whose map or
        camera changes starts a new track).
    view : PlanView
        The map seen from above (the answers' ``plan``).
    tracker : Tracker
        Keeps the readout, the chip length, the fixtures and the pose between frames.
    t0 : float or None
        The first frame's time (the tracker counts from it), s.
    last_t : float or None
        The newest frame's time accepted, s (a frame not after it is stale).
    frames : int
        Frames located so far.
    """

    camera: Camera
    fixture_map: FixtureMap
    view: PlanView
    sources: tuple[Any, Any]
    tracker: Tracker
    t0: float | None = None
    last_t: float | None = None
    frames: int = 0
    used: float = field(default_factory=time.monotonic)
    waiting: _Pending | None = None
    runner: asyncio.Task | None = None

    @property
    def busy(self) -> bool:
        """A frame of it is being located or waits."""
        return self.runner is not None and not self.runner.done()


class FrameTracks:
    """The devices' tracks of one service process (used from the event loop's thread only).

    Parameters
    ----------
    max_devices : int
        Tracks kept at most.
    idle_s : float
        A track without a frame for this long is forgotten, s.
    """

    def __init__(self, max_devices: int, idle_s: float) -> None:
        self.max_devices, self.idle_s = max_devices, idle_s
        self._tracks: OrderedDict[tuple[int, str, str], DeviceTrack] = OrderedDict()

    def __len__(self) -> int:
        return len(self._tracks)

    def waiting(self) -> int:
        """Frames waiting for their device's turn, all devices."""
        return sum(1 for tr in self._tracks.values() if tr.waiting is not None)

    def track(
        self,
        key: tuple[int, str, str],
        camera_json: dict[str, Any],
        map_json: dict[str, Any],
        build: Callable[[], tuple[Camera, FixtureMap]],
        reset: bool = False,
    ) -> DeviceTrack:
        """The device's track, new when it has none, when its site's camera or map changed,
        or when ``reset``; ``build()`` parses the camera and map for a new one.
        :class:`FrameRefused` (422) for a map the tracker does not take (IDs that repeat)."""
        now = time.monotonic()
        for k in [k for k, tr in self._tracks.items() if now - tr.used > self.idle_s]:
            if not self._tracks[k].busy:
                del self._tracks[k]
        tr = self._tracks.get(key)
        if tr is not None and (reset or tr.sources != (camera_json, map_json)) and not tr.busy:
            tr = None
        if tr is None:
            camera, fmap = build()
            sources = (camera_json, map_json)
            try:
                tracker = Tracker(camera, fmap)
            except InputError as exc:  # a map whose IDs repeat: not tracked
                raise FrameRefused(422, f"the site's map: {exc.what}") from None
            tr = DeviceTrack(camera, fmap, plan_view(fmap), sources, tracker)
            self._tracks[key] = tr
            idle = [k for k, t in self._tracks.items() if not t.busy and k != key]
            while len(self._tracks) > self.max_devices and idle:
                del self._tracks[idle.pop(0)]
        tr.used = now
        self._tracks.move_to_end(key)
        return tr

    async def submit(
        self,
        track: DeviceTrack,
        body: bytes,
        kind: str,
        t: float,
        gravity: list[float] | None,
        run: Callable[[DeviceTrack, _Pending], Any],
        on_drop: Callable[[str], None],
    ) -> tuple[dict[str, Any], float]:
        """Locate a frame in its device's turn: ``(answer, seconds it waited)``.

        ``run(track, pending)`` locates one frame (awaitable: it hands the work to the
        locate pool).  Raises :class:`FrameDropped` for a frame that is stale or that a newer
        one replaced while it waited (``on_drop(reason)`` is called for it), and
        :class:`FrameRefused` for one the locator refused.
        """
        if track.last_t is not None and not t > track.last_t:
            on_drop("stale")
            raise FrameDropped(
                "stale",
                f"frame dropped: its time {t!r} s is not after the device's last frame "
                f"({track.last_t!r} s); start a new track with reset=true",
            )
        track.last_t = t
        pending = _Pending(body, kind, t, gravity, asyncio.get_running_loop().create_future())
        if track.waiting is not None:  # the older frame waiting is out of date: answer it now
            old, track.waiting = track.waiting, None
            on_drop("superseded")
            old.future.set_exception(
                FrameDropped("superseded", "frame dropped: a newer frame of this device came")
            )
        track.waiting = pending
        if not track.busy:
            track.runner = asyncio.create_task(self._run(track, run))
        answer = await pending.future
        return answer, pending.waited

    @staticmethod
    async def _run(track: DeviceTrack, run: Callable[[DeviceTrack, _Pending], Any]) -> None:
        """Locate the device's waiting frames, one at a time, until none waits."""
        while track.waiting is not None:
            pending, track.waiting = track.waiting, None
            pending.waited = time.perf_counter() - pending.arrived
            try:
                answer = await run(track, pending)
            except Exception as exc:  # the frame's own answer: a refusal (or a fault)
                if not pending.future.done():
                    pending.future.set_exception(exc)
            else:
                if not pending.future.done():
                    pending.future.set_result(answer)


def _round(values: Any, digits: int = 6) -> list | None:
    if values is None:
        return None
    arr = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(arr)):
        return None
    return np.round(arr, digits).tolist()


def _image(body: bytes, kind: str, camera: Camera, max_pixels: int) -> np.ndarray:
    """The frame's pixels: a JPEG or PNG decoded, or gray bytes of the camera's size."""
    if not body:
        raise FrameRefused(400, "frame is empty")
    if kind == "gray":
        if len(body) != camera.width * camera.height:
            raise FrameRefused(
                422,
                f"a gray frame must be {camera.width} x {camera.height} = "
                f"{camera.width * camera.height} bytes (the camera's size), got {len(body)}",
            )
        return np.frombuffer(body, np.uint8).reshape(camera.height, camera.width)
    header = read_image_header(body)
    if header is None:
        raise FrameRefused(415, "frame must be a JPEG or PNG (or gray bytes)")
    if header.pixels > max_pixels:
        raise FrameRefused(
            413, f"frame is {header.width} x {header.height} pixels, over the limit of {max_pixels}"
        )
    try:
        return decode_image(body, "frame")
    except InputError as exc:
        raise FrameRefused(400, str(exc)) from None


def locate_frame(
    track: DeviceTrack,
    body: bytes,
    kind: str,
    t: float,
    gravity: list[float] | None,
    max_pixels: int,
) -> dict[str, Any]:
    """Locate one frame with the device's track (runs in the locate pool, one frame of a
    device at a time); the answer of ``POST .../frames`` without ``fix_id``.

    Raises
    ------
    FrameRefused
        Not a picture, corrupt, over the pixel limit, or not of the camera's size.
    """
    t0 = time.perf_counter()
    camera = track.camera
    image = _image(body, kind, camera, max_pixels)
    if image.shape[1] != camera.width or image.shape[0] != camera.height:
        raise FrameRefused(
            422,
            f"frame is {image.shape[1]} x {image.shape[0]} pixels, the camera's are "
            f"{camera.width} x {camera.height}",
        )
    if track.t0 is None:
        track.t0 = t
    try:
        frame = track.tracker.update(image, t - track.t0)
    except InputError as exc:
        raise FrameRefused(422, f"{exc.what} (frame)") from None
    track.frames += 1
    answer = _from_track(frame, track)
    if answer["status"] not in _LOCATED and gravity is not None:
        alone = _with_gravity(image, track, gravity)
        if alone is not None:
            answer = alone
    answer["plan"] = _plan(track.view, answer)
    answer["timing_ms"] = {"locate": round(1e3 * (time.perf_counter() - t0), 2)}
    answer["frame"] = track.frames - 1
    answer["readout"] = None if track.tracker.readout is None else str(track.tracker.readout)
    return answer


def _from_track(frame: TrackFrame, track: DeviceTrack) -> dict[str, Any]:
    """A tracker's frame as the answer's fields.

    ``position`` is the track's filtered position, as ``camvlp track`` reports it; the
    frame's own solve is ``raw_position``.  ``position_sigma`` is, for a ``fix`` (four
    fixtures or more), the sigma of the frame's own solve as :func:`camvlp.locate` works it
    out (the fixtures' reprojection error and what their layout makes of a pixel): the
    filtered position adds the track's earlier frames to it.  For a ``tracked`` pose (two or
    three fixtures, which do not fix a pose alone) it is the filter's own sigma.
    """
    sigma = pos = euler = None
    if frame.status == "fix" and frame.raw_position is not None:
        pos, euler = frame.position, frame.euler_deg
        fixtures = track.tracker.map  # (in a site, the fixtures the frame's IDs name)
        points = np.array([fixtures.get(i).position for i in frame.fixtures_used])
        rms = np.full(len(points), frame.reprojection_rms_px)  # the sigma needs r @ r alone
        raw = Pose.from_euler(frame.raw_position, frame.raw_euler_deg)
        sigma = position_sigma(track.camera, raw, points, rms)
    elif frame.status == "tracked" and track.tracker.filter is not None:
        pos, euler = frame.position, frame.euler_deg
        sigma = track.tracker.filter.sigma[:3]
    pose = None if pos is None else Pose.from_euler(pos, euler)
    return {
        "status": frame.status,
        "located": pose is not None,
        "position": _round(pos),
        "position_sigma": _round(sigma, 7),
        "rotation": None if pose is None else _round(pose.world_from_camera, 8),
        "euler_deg": None if pose is None else _round(euler, 4),
        "raw_position": _round(frame.raw_position),
        "reprojection_rms_px": None
        if not math.isfinite(frame.reprojection_rms_px)
        else round(frame.reprojection_rms_px, 4),
        "fixtures": [
            {
                "id": f.id,
                "pixel": _round(f.pixel, 2),
                "used": f.used,
                "source": f.source,
                "reason": f.reason,
            }
            for f in frame.fixtures
        ],
        "fixtures_used": list(frame.fixtures_used),
        "error": frame.reason,
    }


def _with_gravity(
    image: np.ndarray, track: DeviceTrack, gravity: list[float]
) -> dict[str, Any] | None:
    """The frame located alone with the phone's gravity (two fixtures and more), or None."""
    readout = track.tracker.readout
    try:
        res = locate(
            image, track.camera, track.fixture_map, LocateSettings(readout=readout), gravity=gravity
        )
    except (InputError, ValueError):  # gravity facing the floor: the track's answer stands
        return None
    if res.position is None:
        return None
    fixtures = [
        {
            "id": f.id,
            "pixel": _round(f.pixel, 2),
            "used": f.used,
            "source": "decoded" if f.id is not None else "",
            "reason": f.reason,
        }
        for f in res.fixtures
    ]
    return {
        "status": "gravity",
        "located": True,
        "position": _round(res.position),
        "position_sigma": _round(res.position_sigma, 7),
        "rotation": _round(res.rotation, 8),
        "euler_deg": _round(res.euler_deg, 4),
        "raw_position": _round(res.position),
        "reprojection_rms_px": round(res.reprojection_rms_px, 4),
        "fixtures": fixtures,
        "fixtures_used": [f["id"] for f in fixtures if f["used"]],
        "error": "",
    }


def _plan(view: PlanView, answer: dict[str, Any]) -> dict[str, Any]:
    """The position, its sigma and the heading on the plan seen from above."""
    plan: dict[str, Any] = {"position": None, "sigma": None, "heading_deg": None}
    if answer["position"] is not None:
        plan["position"] = _round(view.project(np.array(answer["position"])))
        if answer["position_sigma"] is not None:
            plan["sigma"] = _round(view.project(np.array(answer["position_sigma"])), 7)
        heading = view.heading_deg(np.array(answer["rotation"]))
        plan["heading_deg"] = None if heading is None else round(heading, 3)
    return plan
