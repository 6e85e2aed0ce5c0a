"""The service's shared state, handed to the routes as FastAPI dependencies.

:func:`camvlp.service.create_app` keeps the settings, the store, the locate pool and its
:class:`Gate` on ``app.state``; a route asks for them with the ``Annotated`` aliases below
(``store: StoreDep``), and for an authorised site with ``site_id: Site``.
"""

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import PurePath
from typing import Annotated, Any

from fastapi import Depends, Path, Request
from fastapi.exceptions import HTTPException
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from camvlp.errors import InputError
from camvlp.io.limits import limit
from camvlp.io.textfiles import parse_mapping
from camvlp.service.auth import hash_key, keys_match
from camvlp.service.db import Store
from camvlp.service.frames import FrameTracks
from camvlp.service.metrics import ServiceMetrics
from camvlp.service.ratelimit import RateLimiter
from camvlp.service.settings import ServiceSettings

__all__ = [
    "MAX_ROW_ID",
    "Admin",
    "Gate",
    "GateDep",
    "MetricsDep",
    "PoolDep",
    "RowId",
    "SettingsDep",
    "Site",
    "StoreDep",
    "TracksDep",
    "admin_access",
    "choose_camera",
    "get_gate",
    "get_pool",
    "get_settings",
    "get_store",
    "json_body_gate",
    "parse_count",
    "parse_gravity",
    "rate_limit",
    "site_access",
]

_bearer = HTTPBearer(auto_error=False, description="The site's API key.")


@dataclass
class Gate:
    """Admission to the locate pool: at most ``limit`` photos running or waiting.

    Only touched from the event loop's thread, so a plain counter is enough.
    """

    limit: int
    busy: int = 0


# The getters are ``async`` so that FastAPI calls them on the event loop instead of handing
# each one to a worker thread: they only read ``app.state``.


def _json_content(request: Request) -> bool:
    """Whether FastAPI reads the request's body as JSON: no content type, or a JSON one."""
    kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
    return not kind or kind == "application/json" or kind.endswith("+json")


async def json_body_gate(request: Request) -> None:
    """A JSON body is checked before any route reads it, as the camera and map files are
    (:func:`camvlp.io.textfiles.parse_mapping`): at most ``CAMVLP_MAX_FILE_BYTES`` (413), UTF-8,
    an object nested at most ``CAMVLP_MAX_DEPTH`` deep, no number of more than 30 digits, no
    key given twice in one object (JSON keeps the last one without a word, so a map with a
    fixture's ``position`` given twice would be stored as one of them), and (what a JSON
    answer could not give back) no NaN or infinity and no string that is not valid Unicode
    (a lone surrogate).  Each refusal is one line: 422 (413 for the size)."""
    if not _json_content(request):
        return
    body = await request.body()
    if not body:
        return  # the route says what is missing
    most = limit("CAMVLP_MAX_FILE_BYTES")
    if len(body) > most:
        raise HTTPException(413, f"JSON body is {len(body):,} bytes, over the limit of {most:,}")
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise HTTPException(422, f"JSON body is not UTF-8 (byte {exc.start})") from None
    try:
        data = parse_mapping(text, _JSON_BODY, "JSON body")
        _plain_values(data)
    except InputError as exc:
        raise HTTPException(422, exc.what) from None


#: How a request's JSON body is named to the file parser (its suffix says: JSON).
_JSON_BODY = PurePath("body.json")


def _plain_values(value: Any, where: str = "") -> None:
    """Refuse NaN and infinite numbers and strings that are not valid Unicode, anywhere in
    ``value`` (nested at most ``CAMVLP_MAX_DEPTH`` deep: checked before)."""
    if isinstance(value, dict):
        for key, item in value.items():
            _plain_values(key, where)
            _plain_values(item, f"{where}.{key}" if where else str(key))
    elif isinstance(value, list):
        for k, item in enumerate(value):
            _plain_values(item, f"{where}[{k}]")
    elif isinstance(value, float) and not math.isfinite(value):
        raise InputError(f"malformed JSON body: {value} at {where or 'the top'} is not a number")
    elif isinstance(value, str):
        try:
            value.encode("utf-8")
        except UnicodeEncodeError:
            raise InputError(
                f"malformed JSON body: a string that is not valid Unicode (a lone surrogate) "
                f"at {where or 'a key'}"
            ) from None


def parse_gravity(text: str | None) -> list[float] | None:
    """A ``gx,gy,gz`` field as three finite numbers, not all 0 (None when empty); 422
    otherwise."""
    if text is None or not text.strip():
        return None
    try:
        values = [float(v) for v in text.replace(" ", "").split(",")]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values) or not any(values):
        raise HTTPException(422, f"gravity must be three numbers gx,gy,gz, not all 0, got {text!r}")
    return values


def choose_camera(cameras: dict[str, Any], name: str | None, site_id: int) -> str:
    """The camera a request names, or the site's only (or ``default``) one; 422 when the
    request must say which, 404 when the site has no such camera."""
    if name is None:
        if len(cameras) != 1 and "default" not in cameras:
            raise HTTPException(422, f"say which camera: ?camera=NAME, one of {', '.join(cameras)}")
        name = next(iter(cameras)) if len(cameras) == 1 else "default"
    if name not in cameras:
        raise HTTPException(404, f"no camera {name!r} in site {site_id}")
    return name


def parse_count(text: str, most: int) -> int | None:
    """``text`` as a whole number from 0 to ``most`` (ASCII digits only), else None."""
    text = text.strip()
    if not (text.isascii() and text.isdigit()) or len(text) > len(str(most)):
        return None
    value = int(text)
    return value if value <= most else None


async def get_settings(request: Request) -> ServiceSettings:
    """The service's settings (``app.state.settings``)."""
    return request.app.state.settings


async def get_store(request: Request) -> Store:
    """The site database (``app.state.store``)."""
    return request.app.state.store


async def get_pool(request: Request) -> ThreadPoolExecutor:
    """The pool that locates photos (``app.state.pool``)."""
    return request.app.state.pool


async def get_gate(request: Request) -> Gate:
    """The admission count of the locate pool (``app.state.gate``)."""
    return request.app.state.gate


async def get_tracks(request: Request) -> FrameTracks:
    """The devices' frame tracks (``app.state.tracks``)."""
    return request.app.state.tracks


async def get_metrics(request: Request) -> ServiceMetrics:
    """The service's metrics (``app.state.metrics``)."""
    return request.app.state.metrics


SettingsDep = Annotated[ServiceSettings, Depends(get_settings)]
StoreDep = Annotated[Store, Depends(get_store)]
PoolDep = Annotated[ThreadPoolExecutor, Depends(get_pool)]
GateDep = Annotated[Gate, Depends(get_gate)]
TracksDep = Annotated[FrameTracks, Depends(get_tracks)]
MetricsDep = Annotated[ServiceMetrics, Depends(get_metrics)]


#: Largest id of a database row (SQL's BIGINT, SQLite's INTEGER: signed 64 bits).
MAX_ROW_ID = 2**63 - 1
#: A row id in a path: beyond 64 bits it is a 422, not an overflow in the database driver.
RowId = Annotated[int, Path(ge=-MAX_ROW_ID - 1, le=MAX_ROW_ID)]


def rate_limit(request: Request, key: str) -> None:
    """Take one of the key's tokens (``app.state.limiter``); 429 with ``Retry-After`` when it
    has none left."""
    limiter: RateLimiter = request.app.state.limiter
    wait = limiter.take(key)
    if wait > 0:
        request.app.state.metrics.rate_limited.inc()
        retry = limiter.retry_after(wait)
        raise HTTPException(
            429,
            f"rate limit: {limiter.rate:g} requests per second per key (bursts of "
            f"{limiter.burst}); retry in {retry} s",
            headers={"Retry-After": retry},
        )


def site_access(
    site_id: RowId,
    credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)],
    store: StoreDep,
    request: Request,
) -> int:
    """The site's id when the request carries its key and the key is within its rate limit;
    401, 403, 404 or 429 otherwise."""
    if credentials is None or not credentials.credentials:
        raise HTTPException(
            401,
            "missing API key: send Authorization: Bearer KEY",
            headers={"WWW-Authenticate": "Bearer"},
        )
    key = credentials.credentials
    stored = store.site_key_hash(site_id)
    if stored is not None and keys_match(key, stored):
        rate_limit(request, f"site:{site_id}")
        return site_id
    if store.key_hash_exists(hash_key(key)):
        if stored is None:
            raise HTTPException(404, f"no site {site_id}")
        raise HTTPException(403, f"this key is not the key of site {site_id}")
    raise HTTPException(401, "wrong API key", headers={"WWW-Authenticate": "Bearer"})


#: A path's ``site_id`` once the request's key has been checked against it.
Site = Annotated[int, Depends(site_access)]


def admin_access(
    credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)],
    settings: SettingsDep,
    request: Request,
) -> None:
    """Nothing when the request carries the service's admin key (``CAMVLP_ADMIN_KEY``) within
    its rate limit; 401 otherwise, and always when the service has none (429 over the
    limit)."""
    if not settings.admin_key:
        raise HTTPException(
            401,
            "this service creates no sites: it was started without an admin key (set "
            "CAMVLP_ADMIN_KEY where it runs)",
        )
    if credentials is None or not credentials.credentials:
        raise HTTPException(
            401,
            "creating a site needs the admin key: send Authorization: Bearer ADMIN_KEY",
            headers={"WWW-Authenticate": "Bearer"},
        )
    if not keys_match(credentials.credentials, hash_key(settings.admin_key)):
        raise HTTPException(401, "wrong admin key", headers={"WWW-Authenticate": "Bearer"})
    rate_limit(request, "admin")


#: A request made with the service's admin key.
Admin = Annotated[None, Depends(admin_access)]
