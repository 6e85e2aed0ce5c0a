"""The routes under ``/api/v1``: sites, their map and cameras, photos in, fixes out.

Locating runs in the service's bounded thread pool (OpenCV releases the GIL), never on the
event loop; the pool, the store and the settings come from :mod:`camvlp.service.deps`.
"""

import asyncio
import dataclasses
import time
from collections.abc import AsyncIterator
from datetime import UTC, datetime
from typing import Annotated, Any, BinaryIO

import cv2
import numpy as np
from fastapi import APIRouter, Body, Depends, Query, Request
from fastapi import Path as PathParam
from fastapi.exceptions import HTTPException, RequestValidationError
from fastapi.responses import Response, StreamingResponse
from pydantic import ValidationError
from starlette.concurrency import run_in_threadpool
from starlette.datastructures import FormData, UploadFile
from starlette.formparsers import MultiPartException

from camvlp import __version__
from camvlp.errors import InputError
from camvlp.io import camera_from_dict, decode_image, exif_readout, map_from_dict
from camvlp.model.camera import Camera
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.locate import LocateSettings, locate
from camvlp.service.auth import new_key
from camvlp.service.db import FixRow, Store
from camvlp.service.deps import (
    MAX_ROW_ID,
    Admin,
    GateDep,
    MetricsDep,
    PoolDep,
    RowId,
    SettingsDep,
    Site,
    StoreDep,
    choose_camera,
    json_body_gate,
    parse_count,
    parse_gravity,
)
from camvlp.service.imagesize import read_image_header
from camvlp.service.plan import PlanView, plan_view
from camvlp.service.schemas import (
    CameraPut,
    FixFields,
    FixOut,
    FixPage,
    LocateForm,
    PlanFixture,
    SiteCreate,
    SiteCreated,
    SiteOut,
)
from camvlp.service.settings import ServiceSettings
from camvlp.viz.annotate import annotate as annotate_photo

__all__ = ["router"]

router = APIRouter(prefix="/api/v1", dependencies=[Depends(json_body_gate)])


class _LocateRefused(Exception):
    """A photo the locator cannot take: ``status`` and a one-line ``detail``."""

    def __init__(self, status: int, detail: str):
        super().__init__(detail)
        self.status, self.detail = status, detail


def _iso(t: float) -> str:
    return datetime.fromtimestamp(t, UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def _fix_out(row: FixRow, view: PlanView | None, *, with_result: bool = False) -> FixOut:
    plan: dict[str, Any] = {"position": None, "heading_deg": None}
    if view is not None and row.position is not None:
        plan["position"] = [round(float(v), 6) for v in view.project(np.array(row.position))]
        if row.rotation is not None:
            heading = view.heading_deg(np.array(row.rotation))
            plan["heading_deg"] = None if heading is None else round(heading, 3)
    return FixOut(
        **row.model_dump(include=set(FixFields.model_fields)),
        time=_iso(row.time),
        time_unix=row.time,
        reprojection_rms_px=row.rms_px,
        plan=plan,
        has_picture=row.has_picture,
        result=row.result if with_result else None,
    )


def _parse_map(data: dict[str, Any]) -> FixtureMap:
    try:
        return map_from_dict(data, "map")
    except InputError as exc:
        raise HTTPException(422, str(exc)) from None


def _parse_camera(data: dict[str, Any]) -> Camera:
    try:
        return camera_from_dict(data, "camera")
    except InputError as exc:
        raise HTTPException(422, str(exc)) from None


def _locate_job(
    upload: BinaryIO,
    camera: Camera,
    fixture_map: FixtureMap,
    settings: LocateSettings,
    want_picture: bool,
    cfg: ServiceSettings,
    gravity: list[float] | None = None,
) -> tuple[dict[str, Any], bytes | None]:
    """Read the uploaded photo (its temporary file), check its header, decode, locate (with
    ``gravity``, camera frame, when given) and (optionally) annotate it; runs in the locate
    pool, so that at most its threads hold a photo's bytes in memory."""
    upload.seek(0)
    raw = upload.read()
    if not raw:
        raise _LocateRefused(400, "photo is empty (photo)")
    header = read_image_header(raw)
    if header is None:
        raise _LocateRefused(415, "photo must be a JPEG or PNG (photo)")
    if header.pixels > cfg.max_pixels:
        raise _LocateRefused(
            413,
            f"photo is {header.width} x {header.height} pixels, over the limit of "
            f"{cfg.max_pixels} (photo)",
        )
    picture_max_px = cfg.picture_max_px
    try:
        image = decode_image(raw, "photo")
    except InputError as exc:
        raise _LocateRefused(400, str(exc)) from None
    if settings.readout_hint is None:  # the photo's orientation tag: a hint, as on the command line
        settings = dataclasses.replace(settings, readout_hint=exif_readout(raw))
    try:
        result = locate(image, camera, fixture_map, settings, gravity=gravity)
    except (InputError, ValueError) as exc:  # wrong size, bad readout, gravity facing the floor
        raise _LocateRefused(422, f"{exc} (photo)") from None
    picture = None
    if want_picture:
        drawn = annotate_photo(image, result, camera, fixture_map)
        scale = picture_max_px / max(drawn.shape[:2])
        if scale < 1:
            drawn = cv2.resize(drawn, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
        ok, buf = cv2.imencode(".jpg", drawn, [cv2.IMWRITE_JPEG_QUALITY, 85])
        picture = buf.tobytes() if ok else None
    return result.to_dict(), picture


def _site_view(store: Store, site_id: int) -> PlanView | None:
    row = store.site(site_id)
    return None if row is None else plan_view(map_from_dict(row.map, "map"))


@router.get("/health", tags=["service"])
def health() -> dict[str, Any]:
    """Whether the service is up, and its version."""
    return {"ok": True, "version": __version__}


@router.post("/sites", status_code=201, response_model=SiteCreated, tags=["sites"])
def create_site(body: SiteCreate, store: StoreDep, _admin: Admin) -> SiteCreated:
    """Create a site (with the service's admin key: ``Authorization: Bearer ADMIN_KEY``); its
    API key is in the answer, once (only its hash is kept)."""
    _parse_map(body.map)
    _parse_camera(body.camera)
    key, key_hash = new_key()
    site_id = store.create_site(body.name, key_hash, body.map, body.camera_name, body.camera)
    return SiteCreated(id=site_id, api_key=key, camera=body.camera_name)


@router.get("/sites/{site_id}", response_model=SiteOut, tags=["sites"])
def get_site(site_id: Site, store: StoreDep) -> SiteOut:
    """The site: its map and cameras as stored, and its fixtures on the plan."""
    row = store.site(site_id)
    if row is None:  # deleted between the key check and now
        raise HTTPException(404, f"no site {site_id}")
    fmap = map_from_dict(row.map, "map")
    view = plan_view(fmap)
    fixtures = [
        PlanFixture(
            id=f.id,
            plan=[round(float(v), 6) for v in view.project(f.position)],
            diameter=f.diameter,
        )
        for f in fmap.fixtures
    ]
    return SiteOut(
        id=row.id,
        name=row.name,
        created=_iso(row.created),
        map=row.map,
        cameras=store.cameras(site_id),
        units=fmap.units,
        plan=view.to_dict(),
        fixtures=fixtures,
    )


@router.put("/sites/{site_id}/map", tags=["sites"])
def put_map(
    site_id: Site,
    body: Annotated[dict[str, Any], Body(description="The map file's keys.")],
    store: StoreDep,
) -> dict[str, Any]:
    """Replace the site's map (checked as a map file is)."""
    fmap = _parse_map(body)
    store.set_map(site_id, body)
    return {"site_id": site_id, "fixtures": len(fmap.fixtures)}


@router.put("/sites/{site_id}/cameras/{name}", response_model=CameraPut, tags=["sites"])
def put_camera(
    site_id: Site,
    name: Annotated[str, PathParam(min_length=1, max_length=100, pattern=r"^[A-Za-z0-9._-]+$")],
    body: Annotated[dict[str, Any], Body(description="The camera file's keys.")],
    response: Response,
    store: StoreDep,
) -> CameraPut:
    """Add or replace one of the site's cameras (checked as a camera file is)."""
    _parse_camera(body)
    created = store.put_camera(site_id, name, body)
    response.status_code = 201 if created else 200
    return CameraPut(site_id=site_id, name=name, created=created)


#: The multipart form of ``POST .../locate``, for the API's documentation (the route reads it
#: itself, once the photo is admitted: see :func:`locate_photo`).
_LOCATE_FORM = {
    "requestBody": {
        "required": True,
        "content": {
            "multipart/form-data": {
                "schema": {
                    "type": "object",
                    "required": ["photo"],
                    "properties": {
                        "photo": {
                            "type": "string",
                            "format": "binary",
                            "description": "The photo, JPEG or PNG.",
                        },
                        **{
                            name: {"description": field.description}
                            | ({"type": "string"} if name in ("readout", "gravity") else {})
                            | ({"type": "boolean"} if name in ("mirrored", "annotate") else {})
                            | ({"type": "number"} if name == "max_sigma" else {})
                            | ({"type": "string", "maxLength": 200} if name == "device" else {})
                            for name, field in LocateForm.model_fields.items()
                        },
                    },
                }
            }
        },
    }
}


@router.post("/sites/{site_id}/locate", tags=["fixes"], openapi_extra=_LOCATE_FORM)
async def locate_photo(
    site_id: Site,
    request: Request,
    store: StoreDep,
    cfg: SettingsDep,
    pool: PoolDep,
    gate: GateDep,
    metrics: MetricsDep,
    camera: Annotated[str | None, Query(description="Which of the site's cameras took it.")] = None,
) -> dict[str, Any]:
    """Locate a photo: the JSON of ``camvlp locate --json`` plus ``fix_id``.

    The fix is recorded whether or not the photo could be located (then ``position`` is
    null and ``error`` says why).  413: over the size or pixel limit (not decoded);
    415: not a JPEG or PNG; 400: corrupt; 422: not of the camera's size, or bad options;
    503: too many photos waiting.  The body is read only once the photo is admitted (not
    503), into a temporary file (in memory up to 1 MB), and into memory only by the thread
    that decodes it.
    """
    site_row, cameras = await run_in_threadpool(
        lambda: (store.site(site_id), store.cameras(site_id))
    )
    if site_row is None:
        raise HTTPException(404, f"no site {site_id}")
    camera = choose_camera(cameras, camera, site_id)
    if gate.busy >= gate.limit:
        raise HTTPException(
            503, f"busy: {gate.busy} photos being located; retry", headers={"Retry-After": "1"}
        )
    gate.busy += 1
    try:
        async with request.form(max_files=1, max_fields=len(LocateForm.model_fields)) as form:
            fields, grav = _locate_form(form)
            photo = form.get("photo")
            if not isinstance(photo, UploadFile):
                raise HTTPException(422, "photo: must be a file (multipart/form-data)")
            cam = camera_from_dict(cameras[camera], "camera")
            fmap = map_from_dict(site_row.map, "map")
            try:
                settings = LocateSettings(
                    readout=fields.readout,
                    mirrored=fields.mirrored,
                    max_position_sigma=fields.max_sigma,
                )
            except ValueError as exc:
                raise HTTPException(422, str(exc)) from None
            request.state.device = fields.device
            job = (photo.file, cam, fmap, settings, fields.annotate, cfg, grav)
            started = time.perf_counter()
            try:
                result, picture = await asyncio.get_running_loop().run_in_executor(
                    pool, _locate_job, *job
                )
            finally:
                metrics.locate_seconds.labels("photo").observe(time.perf_counter() - started)
    except _LocateRefused as exc:
        raise HTTPException(exc.status, exc.detail) from None
    except MultiPartException as exc:
        raise HTTPException(400, f"malformed form: {exc.message}") from None
    finally:
        gate.busy -= 1
    fix_id = await run_in_threadpool(
        store.add_fix, site_id, fields.device, camera, result, picture, grav
    )
    metrics.fixes.labels("photo", str(result["position"] is not None).lower()).inc()
    return {**result, "fix_id": fix_id}


def _locate_form(form: FormData) -> tuple[LocateForm, list[float] | None]:
    """The form's fields, checked (422 in one line, as FastAPI's own forms), and the gravity
    parsed; the photo is required but not read here."""
    values: dict[str, Any] = {k: v for k, v in form.items() if k in LocateForm.model_fields}
    errors = [] if "photo" in form else [{"loc": ("body", "photo"), "msg": "Field required"}]
    try:
        fields = LocateForm.model_validate(values)
    except ValidationError as exc:
        errors += [{**e, "loc": ("body", *e["loc"])} for e in exc.errors()]
        raise RequestValidationError(errors) from None
    if errors:
        raise RequestValidationError(errors)
    return fields, parse_gravity(fields.gravity)


@router.get("/sites/{site_id}/fixes", response_model=FixPage, tags=["fixes"])
def list_fixes(
    site_id: Site,
    store: StoreDep,
    device: Annotated[str | None, Query(max_length=200)] = None,
    since: Annotated[
        datetime | None, Query(description="Only fixes at or after this time (ISO 8601).")
    ] = None,
    before: Annotated[
        int | None,
        Query(
            ge=-MAX_ROW_ID - 1,
            le=MAX_ROW_ID,
            description="Only fixes older than this fix id (paging).",
        ),
    ] = None,
    limit: Annotated[int, Query(ge=1, le=1000)] = 50,
) -> FixPage:
    """The site's fixes, newest first, ``limit`` per page."""
    since_s = None
    if since is not None:
        since_s = (since if since.tzinfo else since.replace(tzinfo=UTC)).timestamp()
    rows = store.fixes(site_id, device=device, since=since_s, before=before, limit=limit + 1)
    view = _site_view(store, site_id)
    page = rows[:limit]
    return FixPage(
        fixes=[_fix_out(r, view) for r in page],
        next_before=page[-1].id if len(rows) > limit else None,
    )


@router.get("/sites/{site_id}/fixes/stream", tags=["fixes"])
async def stream_fixes(
    site_id: Site,
    request: Request,
    store: StoreDep,
    cfg: SettingsDep,
    after: Annotated[
        int | None,
        Query(ge=0, le=MAX_ROW_ID, description="Send fixes after this id (default: new ones)."),
    ] = None,
) -> StreamingResponse:
    """Server-sent events: one ``fix`` event per new fix of the site (``id:`` its id).

    The stream polls the database, so fixes recorded by any service process appear; it
    closes after a while (``retry`` tells the client to reconnect) and resumes from the
    ``Last-Event-ID`` header.
    """
    last_event = request.headers.get("last-event-id", "").strip()
    if after is None and last_event:
        if not (last_event.isascii() and last_event.isdigit()):
            raise HTTPException(400, "Last-Event-ID must be a fix id (digits 0 to 9)")
        after = parse_count(last_event, MAX_ROW_ID)
        if after is None:
            raise HTTPException(422, f"Last-Event-ID must be at most {MAX_ROW_ID}")
    if after is None:
        after = await run_in_threadpool(store.last_fix_id, site_id)
    view = await run_in_threadpool(_site_view, store, site_id)

    async def events() -> AsyncIterator[str]:
        last, end = after, time.monotonic() + cfg.stream_max_s
        next_ping = time.monotonic() + 15.0
        yield "retry: 2000\n\n"
        while time.monotonic() < end:
            rows = await run_in_threadpool(
                store.fixes, site_id, after=last, limit=100, newest_first=False
            )
            for row in rows:
                data = _fix_out(row, view).model_dump_json()
                yield f"id: {row.id}\nevent: fix\ndata: {data}\n\n"
                last = row.id
            if time.monotonic() >= next_ping:
                yield ": ping\n\n"
                next_ping = time.monotonic() + 15.0
            if await request.is_disconnected():
                return
            await asyncio.sleep(cfg.stream_poll_s)

    return StreamingResponse(
        events(),
        media_type="text/event-stream",
        headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"},
    )


@router.get("/sites/{site_id}/fixes/{fix_id}", response_model=FixOut, tags=["fixes"])
def get_fix(site_id: Site, fix_id: RowId, store: StoreDep) -> FixOut:
    """One fix, with the whole locate JSON in ``result``."""
    row = store.fix(site_id, fix_id)
    if row is None:
        raise HTTPException(404, f"no fix {fix_id} in site {site_id}")
    return _fix_out(row, _site_view(store, site_id), with_result=True)


@router.get(
    "/sites/{site_id}/fixes/{fix_id}/picture",
    response_class=Response,
    responses={200: {"content": {"image/jpeg": {}}}},
    tags=["fixes"],
)
def get_picture(site_id: Site, fix_id: RowId, store: StoreDep) -> Response:
    """The annotated picture of a fix located with ``annotate``, JPEG."""
    jpeg = store.picture(site_id, fix_id)
    if jpeg is None:
        raise HTTPException(404, f"no picture of fix {fix_id} in site {site_id}")
    return Response(jpeg, media_type="image/jpeg", headers={"Cache-Control": "private"})
