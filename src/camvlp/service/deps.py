"""The service's shared state, handed to the routes as FastAPI dependencies.

:func:`camvlp.service.create_app` keeps the settings, the store, the locate pool and its
:class:`Gate` on ``app.state``; a route asks for them with the ``Annotated`` aliases below
(``store: StoreDep``), and for an authorised site with ``site_id: Site``.
"""

import json
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Annotated

from fastapi import Depends, Path, Request
from fastapi.exceptions import HTTPException
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from camvlp.io.files import unique_keys
from camvlp.service.auth import hash_key, keys_match
from camvlp.service.db import Store
from camvlp.service.settings import ServiceSettings

__all__ = [
    "MAX_ROW_ID",
    "Gate",
    "GateDep",
    "PoolDep",
    "RowId",
    "SettingsDep",
    "Site",
    "StoreDep",
    "get_gate",
    "get_pool",
    "get_settings",
    "get_store",
    "keys_once",
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


async def keys_once(request: Request) -> None:
    """A JSON body whose objects give a key twice is refused (422, naming the key), as the
    camera and map files are: JSON keeps the last one without a word, so a map with a
    fixture's ``position`` given twice would be stored as one of them.  A body that is not
    JSON is left to the route's own parsing."""
    if "json" not in request.headers.get("content-type", ""):
        return
    try:
        json.loads(await request.body(), object_pairs_hook=unique_keys)
    except json.JSONDecodeError:
        return  # malformed: the route's parsing says so
    except (ValueError, RecursionError) as err:
        raise HTTPException(422, f"malformed JSON body: {err}") from None


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


SettingsDep = Annotated[ServiceSettings, Depends(get_settings)]
StoreDep = Annotated[Store, Depends(get_store)]
PoolDep = Annotated[ThreadPoolExecutor, Depends(get_pool)]
GateDep = Annotated[Gate, Depends(get_gate)]


#: Largest id of a database row (SQL's BIGINT, SQLite's INTEGER: signed 64 bits).
MAX_ROW_ID = 2**63 - 1
#: A row id in a path: beyond 64 bits it is a 422, not an overflow in the database driver.
RowId = Annotated[int, Path(ge=-MAX_ROW_ID - 1, le=MAX_ROW_ID)]


def site_access(
    site_id: RowId,
    credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)],
    store: StoreDep,
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


#: A path's ``site_id`` once the request's key has been checked against it.
Site = Annotated[int, Depends(site_access)]
