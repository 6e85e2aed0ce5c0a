"""The positioning service: sites with a map and cameras, photos in, fixes out, a live page.

:func:`create_app` builds the FastAPI application; ``camvlp serve`` runs it with uvicorn.
Locating runs in a bounded thread pool (OpenCV releases the GIL), never on the event loop.
"""

import asyncio
import math
import time
from collections.abc import AsyncIterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import asynccontextmanager
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Annotated, Any

import cv2
import numpy as np
from fastapi import APIRouter, Body, Depends, FastAPI, File, Form, Query, Request, UploadFile
from fastapi import Path as PathParam
from fastapi.exceptions import HTTPException, RequestValidationError
from fastapi.responses import (
    FileResponse,
    JSONResponse,
    RedirectResponse,
    Response,
    StreamingResponse,
)
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from fastapi.staticfiles import StaticFiles
from starlette.concurrency import run_in_threadpool
from starlette.datastructures import Headers
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from camvlp import __version__
from camvlp.errors import InputError
from camvlp.io import camera_from_dict, decode_image, map_from_dict
from camvlp.model.camera import Camera
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.locate import LocateSettings, locate
from camvlp.service.auth import hash_key, keys_match, new_key
from camvlp.service.db import FixRow, Store, make_engine
from camvlp.service.imagesize import read_image_header
from camvlp.service.plan import PlanView, plan_view
from camvlp.service.schemas import (
    CameraPut,
    FixOut,
    FixPage,
    PlanFixture,
    SiteCreate,
    SiteCreated,
    SiteOut,
)
from camvlp.service.settings import ServiceSettings
from camvlp.viz.annotate import annotate as annotate_photo

__all__ = ["app_from_env", "create_app"]

STATIC_DIR = Path(__file__).resolve().parent / "static"
_bearer = HTTPBearer(auto_error=False, description="The site's API key.")


class _LocateRefused(Exception):
    """A photo the locator cannot take: ``status`` and a one-line ``detail``."""

    def __init__(self, status: int, detail: str):
        super().__init__(detail)
        self.status, self.detail = status, detail


@dataclass
class _Gate:
    """Admission to the locate pool: at most ``limit`` photos running or waiting.

    Only touched from the event loop's thread, so a plain counter is enough.
    """

    limit: int
    busy: int = 0


class _BodyLimit:
    """Refuse request bodies over ``max_bytes`` with 413 and a JSON ``detail``.

    A declared Content-Length over the limit is refused before anything is read; a body
    without one (chunked) is counted as it arrives and refused when it goes over.
    """

    def __init__(self, app: ASGIApp, max_bytes: int):
        self.app, self.max_bytes = app, max_bytes
        size = f"{max_bytes / 2**20:g} MB" if max_bytes >= 2**20 else f"{max_bytes} bytes"
        self.message = f"request body over the limit of {size}"

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        length = Headers(scope=scope).get("content-length")
        if length is not None and (not length.isdigit() or int(length) > self.max_bytes):
            await JSONResponse({"detail": self.message}, status_code=413)(scope, receive, send)
            return
        total, started = 0, False

        async def counted() -> Message:
            nonlocal total
            message = await receive()
            if message["type"] == "http.request":
                total += len(message.get("body", b""))
                if total > self.max_bytes:
                    raise HTTPException(413, self.message)
            return message

        async def watched(message: Message) -> None:
            nonlocal started
            started = started or message["type"] == "http.response.start"
            await send(message)

        try:
            await self.app(scope, counted, watched)
        except HTTPException as exc:
            if started or exc.status_code != 413:
                raise
            await JSONResponse({"detail": exc.detail}, status_code=413)(scope, receive, send)


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
        id=row.id,
        time=_iso(row.time),
        time_unix=row.time,
        device=row.device,
        camera=row.camera,
        located=row.located,
        position=row.position,
        rotation=row.rotation,
        euler_deg=row.euler_deg,
        reprojection_rms_px=row.rms_px,
        fixtures_used=row.fixtures_used,
        error=row.error,
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


def _parse_gravity(text: str | None) -> list[float] | None:
    if text is None or not text.strip():
        return None
    try:
        values = [float(v) for v in text.replace(" ", "").split(",")]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values) or not any(values):
        raise HTTPException(422, f"gravity must be three numbers gx,gy,gz, not all 0, got {text!r}")
    return values


def _locate_job(
    raw: bytes,
    camera: Camera,
    fixture_map: FixtureMap,
    settings: LocateSettings,
    want_picture: bool,
    picture_max_px: int,
    gravity: list[float] | None = None,
) -> tuple[dict[str, Any], bytes | None]:
    """Decode, locate (with ``gravity``, camera frame, when given) and (optionally) annotate
    one photo; runs in the locate pool."""
    try:
        image = decode_image(raw, "photo")
    except InputError as exc:
        raise _LocateRefused(400, str(exc)) from None
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


def create_app(settings: ServiceSettings | None = None) -> FastAPI:
    """The service's FastAPI application.

    Parameters
    ----------
    settings : ServiceSettings, optional
        Database URL, limits and pool sizes; default: from ``CAMVLP_*`` environment variables.

    Returns
    -------
    FastAPI
        Serves the API under ``/api/v1``, its documentation at ``/docs`` and the live page of
        each site at ``/sites/{id}``.
    """
    cfg = settings or ServiceSettings.from_env()
    store = Store(make_engine(cfg.db))
    store.create_tables()
    pool = ThreadPoolExecutor(cfg.locate_threads, thread_name_prefix="camvlp-locate")
    gate = _Gate(cfg.locate_threads + cfg.max_queued)

    @asynccontextmanager
    async def lifespan(_app: FastAPI) -> AsyncIterator[None]:
        yield
        pool.shutdown(wait=True, cancel_futures=True)
        store.engine.dispose()

    app = FastAPI(
        title="camvlp",
        version=__version__,
        summary="Camera positioning from photos of coded ceiling lights.",
        description="Create a site with its map and camera, send photos, get fixes. Every "
        "request about a site needs its key: `Authorization: Bearer KEY`.",
        lifespan=lifespan,
    )
    app.add_middleware(_BodyLimit, max_bytes=cfg.max_upload_bytes)
    app.state.settings, app.state.store = cfg, store

    @app.exception_handler(RequestValidationError)
    async def _one_line(_request: Request, exc: RequestValidationError) -> JSONResponse:
        errors = exc.errors()
        first = errors[0] if errors else {"loc": (), "msg": "invalid request"}
        where = ".".join(
            str(p) for p in first.get("loc", ()) if p not in ("body", "query", "path", "header")
        )
        detail = f"{where}: {first['msg']}" if where else str(first["msg"])
        if len(errors) > 1:
            detail += f" (and {len(errors) - 1} more)"
        return JSONResponse({"detail": detail}, status_code=422)

    def site_access(
        site_id: int,
        credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)],
    ) -> int:
        """The site's id when the request carries its key; 401, 403 or 404 otherwise."""
        if credentials is None or not credentials.credentials:
            raise HTTPException(
                401,
                "missing API key: send Authorization: Bearer KEY",
                headers={"WWW-Authenticate": "Bearer"},
            )
        key = credentials.credentials
        stored = store.site_key_hash(site_id)
        if stored is not None and keys_match(key, stored):
            return site_id
        if store.key_hash_exists(hash_key(key)):
            if stored is None:
                raise HTTPException(404, f"no site {site_id}")
            raise HTTPException(403, f"this key is not the key of site {site_id}")
        raise HTTPException(401, "wrong API key", headers={"WWW-Authenticate": "Bearer"})

    Site = Annotated[int, Depends(site_access)]

    def site_view(site_id: int) -> PlanView | None:
        row = store.site(site_id)
        return None if row is None else plan_view(map_from_dict(row.map, "map"))

    api = APIRouter(prefix="/api/v1")

    @api.get("/health", tags=["service"])
    def health() -> dict[str, Any]:
        """Whether the service is up, and its version."""
        return {"ok": True, "version": __version__}

    @api.post("/sites", status_code=201, response_model=SiteCreated, tags=["sites"])
    def create_site(body: SiteCreate) -> SiteCreated:
        """Create a site; its API key is in the answer, once (only its hash is kept)."""
        _parse_map(body.map)
        _parse_camera(body.camera)
        key, key_hash = new_key()
        site_id = store.create_site(body.name, key_hash, body.map, body.camera_name, body.camera)
        return SiteCreated(id=site_id, api_key=key, camera=body.camera_name)

    @api.get("/sites/{site_id}", response_model=SiteOut, tags=["sites"])
    def get_site(site_id: Site) -> SiteOut:
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

    @api.put("/sites/{site_id}/map", tags=["sites"])
    def put_map(
        site_id: Site, body: Annotated[dict[str, Any], Body(description="The map file's keys.")]
    ) -> dict[str, Any]:
        """Replace the site's map (checked as a map file is)."""
        fmap = _parse_map(body)
        store.set_map(site_id, body)
        return {"site_id": site_id, "fixtures": len(fmap.fixtures)}

    @api.put("/sites/{site_id}/cameras/{name}", response_model=CameraPut, tags=["sites"])
    def put_camera(
        site_id: Site,
        name: Annotated[str, PathParam(min_length=1, max_length=100, pattern=r"^[A-Za-z0-9._-]+$")],
        body: Annotated[dict[str, Any], Body(description="The camera file's keys.")],
        response: Response,
    ) -> CameraPut:
        """Add or replace one of the site's cameras (checked as a camera file is)."""
        _parse_camera(body)
        created = store.put_camera(site_id, name, body)
        response.status_code = 201 if created else 200
        return CameraPut(site_id=site_id, name=name, created=created)

    @api.post("/sites/{site_id}/locate", tags=["fixes"])
    async def locate_photo(
        site_id: Site,
        photo: Annotated[UploadFile, File(description="The photo, JPEG or PNG.")],
        camera: Annotated[
            str | None, Query(description="Which of the site's cameras took it.")
        ] = None,
        device: Annotated[str, Form(max_length=200, description="The client's name.")] = "",
        readout: Annotated[
            str | None,
            Form(description="rows, columns, rows-reversed or columns-reversed."),
        ] = None,
        mirrored: Annotated[bool | None, Form(description="The photo is a mirror image.")] = None,
        gravity: Annotated[
            str | None,
            Form(
                description="gx,gy,gz: the phone's gravity in the camera frame (OpenCV axes, "
                "any length); the locator uses it (two or three fixtures are then enough) and "
                "it is kept with the fix."
            ),
        ] = None,
        annotate: Annotated[
            bool, Form(description="Keep an annotated picture of the fix (for the page).")
        ] = False,
    ) -> dict[str, Any]:
        """Locate a photo: the JSON of ``camvlp locate --json`` plus ``fix_id``.

        The fix is recorded whether or not the photo could be located (then ``position`` is
        null and ``error`` says why).  413: over the size or pixel limit (not decoded);
        415: not a JPEG or PNG; 400: corrupt; 422: not of the camera's size, or bad options;
        503: too many photos waiting.
        """
        grav = _parse_gravity(gravity)
        raw = await photo.read()
        header = read_image_header(raw)
        if not raw:
            raise HTTPException(400, "photo is empty (photo)")
        if header is None:
            raise HTTPException(415, "photo must be a JPEG or PNG (photo)")
        if header.pixels > cfg.max_pixels:
            raise HTTPException(
                413,
                f"photo is {header.width} x {header.height} pixels, over the limit of "
                f"{cfg.max_pixels} (photo)",
            )
        site_row, cameras = await run_in_threadpool(
            lambda: (store.site(site_id), store.cameras(site_id))
        )
        if site_row is None:
            raise HTTPException(404, f"no site {site_id}")
        if camera is None:
            if len(cameras) != 1 and "default" not in cameras:
                raise HTTPException(
                    422, f"say which camera: ?camera=NAME, one of {', '.join(cameras)}"
                )
            camera = next(iter(cameras)) if len(cameras) == 1 else "default"
        if camera not in cameras:
            raise HTTPException(404, f"no camera {camera!r} in site {site_id}")
        cam = camera_from_dict(cameras[camera], "camera")
        fmap = map_from_dict(site_row.map, "map")
        try:
            settings = LocateSettings(readout=readout, mirrored=mirrored)
        except ValueError as exc:
            raise HTTPException(422, str(exc)) from None
        if gate.busy >= gate.limit:
            raise HTTPException(
                503, f"busy: {gate.busy} photos being located; retry", headers={"Retry-After": "1"}
            )
        gate.busy += 1
        try:
            result, picture = await asyncio.get_running_loop().run_in_executor(
                pool, _locate_job, raw, cam, fmap, settings, annotate, cfg.picture_max_px, grav
            )
        except _LocateRefused as exc:
            raise HTTPException(exc.status, exc.detail) from None
        finally:
            gate.busy -= 1
        fix_id = await run_in_threadpool(
            store.add_fix, site_id, device, camera, result, picture, grav
        )
        return {**result, "fix_id": fix_id}

    @api.get("/sites/{site_id}/fixes", response_model=FixPage, tags=["fixes"])
    def list_fixes(
        site_id: Site,
        device: Annotated[str | None, Query(max_length=200)] = None,
        since: Annotated[
            datetime | None, Query(description="Only fixes at or after this time (ISO 8601).")
        ] = None,
        before: Annotated[
            int | None, Query(description="Only fixes older than this fix id (paging).")
        ] = None,
        limit: Annotated[int, Query(ge=1, le=1000)] = 50,
    ) -> FixPage:
        """The site's fixes, newest first, ``limit`` per page."""
        since_s = None
        if since is not None:
            since_s = (since if since.tzinfo else since.replace(tzinfo=UTC)).timestamp()
        rows = store.fixes(site_id, device=device, since=since_s, before=before, limit=limit + 1)
        view = site_view(site_id)
        page = rows[:limit]
        return FixPage(
            fixes=[_fix_out(r, view) for r in page],
            next_before=page[-1].id if len(rows) > limit else None,
        )

    @api.get("/sites/{site_id}/fixes/stream", tags=["fixes"])
    async def stream_fixes(
        site_id: Site,
        request: Request,
        after: Annotated[
            int | None, Query(ge=0, description="Send fixes after this id (default: new ones).")
        ] = None,
    ) -> StreamingResponse:
        """Server-sent events: one ``fix`` event per new fix of the site (``id:`` its id).

        The stream polls the database, so fixes recorded by any service process appear; it
        closes after a while (``retry`` tells the client to reconnect) and resumes from the
        ``Last-Event-ID`` header.
        """
        last_event = request.headers.get("last-event-id", "")
        if after is None and last_event.isdigit():
            after = int(last_event)
        if after is None:
            after = await run_in_threadpool(store.last_fix_id, site_id)
        view = await run_in_threadpool(site_view, site_id)

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

    @api.get("/sites/{site_id}/fixes/{fix_id}", response_model=FixOut, tags=["fixes"])
    def get_fix(site_id: Site, fix_id: int) -> FixOut:
        """One fix, with the whole locate JSON in ``result``."""
        row = store.fix(site_id, fix_id)
        if row is None:
            raise HTTPException(404, f"no fix {fix_id} in site {site_id}")
        return _fix_out(row, site_view(site_id), with_result=True)

    @api.get(
        "/sites/{site_id}/fixes/{fix_id}/picture",
        response_class=Response,
        responses={200: {"content": {"image/jpeg": {}}}},
        tags=["fixes"],
    )
    def get_picture(site_id: Site, fix_id: int) -> Response:
        """The annotated picture of a fix located with ``annotate``, JPEG."""
        jpeg = store.picture(site_id, fix_id)
        if jpeg is None:
            raise HTTPException(404, f"no picture of fix {fix_id} in site {site_id}")
        return Response(jpeg, media_type="image/jpeg", headers={"Cache-Control": "private"})

    app.include_router(api)
    app.mount("/static", StaticFiles(directory=STATIC_DIR), name="static")

    @app.get("/sites/{site_id}", include_in_schema=False)
    def site_page(site_id: int) -> FileResponse:
        """The live page of a site (its data come from the API with the site's key)."""
        return FileResponse(STATIC_DIR / "site.html", headers={"Cache-Control": "no-cache"})

    @app.get("/", include_in_schema=False)
    def root() -> RedirectResponse:
        return RedirectResponse("/docs")

    return app


def app_from_env() -> FastAPI:
    """The application with settings from ``CAMVLP_*`` variables (uvicorn's ``--factory``)."""
    return create_app(ServiceSettings.from_env())
