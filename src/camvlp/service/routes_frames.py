"""``POST /api/v1/sites/{id}/frames``: the real-time path, one video frame of a device.

The frame is located in the service's locate pool with its device's track (see
:mod:`camvlp.service.frames`); its fix is recorded, like a photo's, and streamed to the
site's page.
"""

from __future__ import annotations

import asyncio
import math
import time
from typing import Annotated, Any

from fastapi import APIRouter, Query, Request
from fastapi.exceptions import HTTPException
from starlette.concurrency import run_in_threadpool

from camvlp.io import camera_from_dict, map_from_dict
from camvlp.service.deps import (
    GateDep,
    MetricsDep,
    PoolDep,
    SettingsDep,
    Site,
    StoreDep,
    TracksDep,
    choose_camera,
    parse_gravity,
)
from camvlp.service.frames import FrameDropped, FrameRefused, locate_frame

__all__ = ["router"]

router = APIRouter(prefix="/api/v1")

#: Content types of a frame's body: an encoded picture, or gray bytes of the camera's size.
_KINDS = {"image/jpeg": "encoded", "image/png": "encoded", "application/octet-stream": "gray"}
#: Largest frame time accepted, s (a client's clock in seconds, from any origin).
_MAX_T = 1e12

_FRAME_BODY = {
    "requestBody": {
        "required": True,
        "description": "The frame: a JPEG or PNG, or gray bytes (one per pixel, rows from the "
        "top, of the camera's width x height) as application/octet-stream.",
        "content": {kind: {"schema": {"type": "string", "format": "binary"}} for kind in _KINDS},
    }
}


def _kind(request: Request) -> str:
    media = request.headers.get("content-type", "").split(";")[0].strip().lower()
    kind = _KINDS.get(media)
    if kind is None:
        raise HTTPException(
            415,
            "a frame's Content-Type must be image/jpeg, image/png or application/octet-stream "
            f"(gray bytes), got {media or 'none'!r}",
        )
    return kind


@router.post("/sites/{site_id}/frames", tags=["frames"], openapi_extra=_FRAME_BODY)
async def post_frame(
    site_id: Site,
    request: Request,
    store: StoreDep,
    cfg: SettingsDep,
    pool: PoolDep,
    gate: GateDep,
    tracks: TracksDep,
    metrics: MetricsDep,
    device: Annotated[
        str, Query(min_length=1, max_length=200, description="The device's name: its track.")
    ],
    camera: Annotated[str | None, Query(description="Which of the site's cameras.")] = None,
    t: Annotated[
        float | None,
        Query(
            ge=-_MAX_T,
            le=_MAX_T,
            description="The frame's time, s, on the device's clock (any origin; increasing "
            "from frame to frame). Default: when the service received it.",
        ),
    ] = None,
    gravity: Annotated[
        str | None,
        Query(
            description="gx,gy,gz: the phone's gravity in the camera frame (OpenCV axes, any "
            "length); a frame the track cannot place is then located alone with it."
        ),
    ] = None,
    reset: Annotated[
        bool, Query(description="Start a new track for the device (a new capture).")
    ] = False,
) -> dict[str, Any]:
    """Locate a video frame with its device's track; the answer is the frame's fix.

    ``status`` is ``fix`` (four or more fixtures), ``tracked`` (two or three, with the
    track's prior), ``gravity`` (located alone with ``gravity``), ``predicted`` or ``lost``
    (not located: ``error`` says why).  ``position`` is the track's filtered position (map
    units), ``raw_position`` the frame's own solve, ``position_sigma`` a standard deviation
    per axis (a fix's or a ``gravity`` frame's: its own solve's, as ``locate`` gives it; a
    tracked pose's: the filter's); ``plan`` has them on the plan seen from above.  Each device
    has one frame located at a time and at most one waiting: a newer frame takes the waiting
    one's place, and that one is answered 409 (``frame dropped``), as is a frame whose ``t``
    is not after the last one's.  413, 415, 400, 422 as for photos; 503 when the process has
    too many photos and frames in hand.
    """
    request.state.device = device
    kind = _kind(request)
    grav = parse_gravity(gravity)
    t_frame = _frame_time(t)
    site_row, cameras = await run_in_threadpool(
        lambda: (store.site(site_id), store.cameras(site_id))
    )
    if site_row is None:
        raise HTTPException(404, f"no site {site_id}")
    name = choose_camera(cameras, camera, site_id)
    if gate.busy >= gate.limit:
        raise HTTPException(
            503, f"busy: {gate.busy} photos and frames in hand; retry", headers={"Retry-After": "1"}
        )
    gate.busy += 1
    started = time.perf_counter()
    try:
        body = await request.body()
        build = _builder(cameras[name], site_row.map)
        track = tracks.track((site_id, name, device), cameras[name], site_row.map, build, reset)
        run, dropped = _runner(pool, cfg.max_pixels, metrics)
        answer, waited = await tracks.submit(track, body, kind, t_frame, grav, run, dropped)
    except FrameDropped as exc:
        raise HTTPException(409, exc.detail) from None
    except FrameRefused as exc:
        raise HTTPException(exc.status, exc.detail) from None
    finally:
        gate.busy -= 1
    metrics.frame_wait_seconds.observe(waited)
    fix_id = await run_in_threadpool(
        lambda: store.add_fix(
            site_id, device, name, answer, None, grav, source="frame", status=answer["status"]
        )
    )
    metrics.fixes.labels("frame", str(answer["located"]).lower()).inc()
    timing = dict(answer["timing_ms"])
    timing["wait"] = round(1e3 * waited, 2)
    timing["total"] = round(1e3 * (time.perf_counter() - started), 2)
    return {
        **answer,
        "fix_id": fix_id,
        "device": device,
        "camera": name,
        "t": t_frame,
        "timing_ms": timing,
        "frames_waiting": tracks.waiting(),
    }


def _frame_time(t: float | None) -> float:
    """The frame's time, s: the client's ``t`` (a finite number), else now."""
    if t is not None and not math.isfinite(t):
        raise HTTPException(422, "t: must be a finite number of seconds")
    return time.time() if t is None else float(t)


def _builder(camera_spec: dict, map_spec: dict):
    """A function that makes the site's camera and map for a new track (422 should the stored
    data not load: they are checked when stored, so never expected)."""

    def build():
        try:
            return camera_from_dict(camera_spec, "camera"), map_from_dict(map_spec, "map")
        except Exception as exc:
            raise HTTPException(422, f"the site's camera or map: {exc}") from None

    return build


def _runner(pool, max_pixels: int, metrics):
    """What the device's track calls: ``run(track, pending)``, which locates a pending frame
    in the locate ``pool`` (timed in ``metrics``), and ``dropped(reason)``, which counts a
    frame a newer one replaced."""

    async def run(tr, pending) -> dict[str, Any]:
        args = (tr, pending.body, pending.kind, pending.t, pending.gravity, max_pixels)
        t0 = time.perf_counter()
        try:
            return await asyncio.get_running_loop().run_in_executor(pool, locate_frame, *args)
        finally:
            metrics.locate_seconds.labels("frame").observe(time.perf_counter() - t0)

    def dropped(reason: str) -> None:
        metrics.frames_dropped.labels(reason).inc()

    return run, dropped
