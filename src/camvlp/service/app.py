"""The positioning service: sites with a map and cameras, photos in, fixes out, a live page.

:func:`create_app` builds the FastAPI application from :class:`ServiceSettings`; its routes are
in :mod:`camvlp.service.routes_api` (``/api/v1``) and :mod:`camvlp.service.routes_page` (the
page), and reach the state kept here on ``app.state`` through :mod:`camvlp.service.deps`.
``camvlp serve`` runs it with uvicorn.
"""

import logging
from collections.abc import AsyncIterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import asynccontextmanager

from fastapi import FastAPI, Request
from fastapi.exceptions import HTTPException, RequestValidationError
from fastapi.responses import JSONResponse
from fastapi.staticfiles import StaticFiles
from starlette.datastructures import Headers
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from camvlp import __version__
from camvlp.service import routes_api, routes_frames, routes_page
from camvlp.service.db import Store, make_engine
from camvlp.service.deps import Gate, parse_count
from camvlp.service.frames import FrameTracks
from camvlp.service.logs import AccessLog
from camvlp.service.metrics import ServiceMetrics
from camvlp.service.migrate import prepare
from camvlp.service.ratelimit import RateLimiter
from camvlp.service.settings import ServiceSettings

__all__ = ["app_from_env", "create_app"]


#: Largest Content-Length read as a number (bytes); a longer one is not a length but an attack.
_MAX_LENGTH = 2**63 - 1


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
        if length is not None and parse_count(length, _MAX_LENGTH) is None:
            detail = "Content-Length must be a whole number of bytes"
            await JSONResponse({"detail": detail}, status_code=400)(scope, receive, send)
            return
        if length is not None and int(length) > self.max_bytes:
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


async def _one_line(_request: Request, exc: RequestValidationError) -> JSONResponse:
    """A request that fails validation: 422 with its first error on one line."""
    errors = exc.errors()
    first = errors[0] if errors else {"loc": (), "msg": "invalid request"}
    where = ".".join(
        str(p) for p in first.get("loc", ()) if p not in ("body", "query", "path", "header")
    )
    detail = f"{where}: {first['msg']}" if where else str(first["msg"])
    if len(errors) > 1:
        detail += f" (and {len(errors) - 1} more)"
    return JSONResponse({"detail": detail}, status_code=422)


@asynccontextmanager
async def _lifespan(app: FastAPI) -> AsyncIterator[None]:
    """Nothing to start; at shutdown, the locate pool is drained and the database let go."""
    yield
    app.state.pool.shutdown(wait=True, cancel_futures=True)
    app.state.store.engine.dispose()


def create_app(settings: ServiceSettings | None = None) -> FastAPI:
    """The service's FastAPI application.

    Parameters
    ----------
    settings : ServiceSettings, optional
        Database URL, limits and pool sizes; default: from ``CAMVLP_*`` environment variables.

    Returns
    -------
    FastAPI
        Serves the API under ``/api/v1``, its documentation at ``/docs`` and ``/redoc``, the
        live page of each site at ``/sites/{id}``, its camera page at ``/sites/{id}/capture``
        and the metrics at ``/metrics``.

    Raises
    ------
    camvlp.service.migrate.SchemaError
        The database is at an older revision (``camvlp serve --migrate`` upgrades it), or at
        one this code does not know.  An empty database is created at the last revision.
    """
    cfg = settings or ServiceSettings.from_env()
    store = Store(make_engine(cfg.db))
    try:
        prepare(store.engine)
    except Exception:
        store.engine.dispose()
        raise
    app = FastAPI(
        title="camvlp",
        version=__version__,
        summary="Camera positioning from photos of coded ceiling lights.",
        description="Create a site with its map and camera, send photos or video frames, get "
        "fixes. Every "
        "request about a site needs its key: `Authorization: Bearer KEY`.",
        lifespan=_lifespan,
        docs_url=None,  # served by routes_page from the package's files
        redoc_url=None,
    )
    logging.getLogger("camvlp").setLevel(cfg.log_level.upper())
    app.state.settings, app.state.store = cfg, store
    app.state.pool = ThreadPoolExecutor(cfg.locate_threads, thread_name_prefix="camvlp-locate")
    app.state.gate = gate = Gate(cfg.locate_threads + cfg.max_queued)
    app.state.tracks = tracks = FrameTracks(cfg.frame_devices, cfg.frame_idle_s)
    app.state.limiter = RateLimiter(cfg.rate_per_s, cfg.rate_burst)
    app.state.metrics = metrics = ServiceMetrics()
    metrics.gauge(
        "camvlp_locate_in_hand",
        "Photos and frames admitted to the locate pool (running or waiting).",
        lambda: gate.busy,
    )
    metrics.gauge(
        "camvlp_frame_queue_depth",
        "Frames waiting for their device's turn (at most one per device).",
        tracks.waiting,
    )
    metrics.gauge("camvlp_frame_devices", "Devices with a frame track.", lambda: len(tracks))
    app.add_middleware(_BodyLimit, max_bytes=cfg.max_upload_bytes)
    app.add_middleware(AccessLog, metrics=metrics)  # outermost: sees every answer, 413s too
    app.add_exception_handler(RequestValidationError, _one_line)
    app.include_router(routes_api.router)
    app.include_router(routes_frames.router)
    app.mount("/static", StaticFiles(directory=routes_page.STATIC_DIR), name="static")
    app.mount(
        routes_page.DOCS_ASSETS_URL,
        StaticFiles(directory=routes_page.DOCS_ASSETS_DIR),
        name="static-docs",
    )
    app.include_router(routes_page.router)
    return app


def app_from_env() -> FastAPI:
    """The application with settings from ``CAMVLP_*`` variables (uvicorn's ``--factory``)."""
    return create_app(ServiceSettings.from_env())
