"""``camvlp serve``: the positioning service (HTTP API, site database, live page)."""

from __future__ import annotations

import dataclasses
import os
import socket
import sys
from pathlib import Path
from typing import Annotated

import typer

from ._app import app, check_positive, fail, handle_errors


@app.command("serve")
@handle_errors
def serve_command(
    db: Annotated[
        str | None,
        typer.Option(
            "--db",
            envvar="CAMVLP_DB",
            metavar="URL|FILE",
            help="The database: a SQLite file (a path, or sqlite:///FILE; its folder is "
            "created) or a URL such as postgresql+psycopg://USER@HOST/NAME. Default: camvlp.db "
            "in the user's data folder ($XDG_DATA_HOME/camvlp, else ~/.local/share/camvlp).",
        ),
    ] = None,
    host: Annotated[str, typer.Option("--host", help="Address to listen on.")] = "127.0.0.1",
    port: Annotated[int, typer.Option("--port", help="TCP port.")] = 8000,
    workers: Annotated[int, typer.Option("--workers", help="Service processes.")] = 1,
    threads: Annotated[
        int, typer.Option("--threads", help="Photos located at once by each process.")
    ] = 2,
    max_upload_mb: Annotated[
        float, typer.Option("--max-upload-mb", help="Largest request body (MB); larger: 413.")
    ] = 40.0,
    max_megapixels: Annotated[
        float, typer.Option("--max-megapixels", help="Largest photo (megapixels); larger: 413.")
    ] = 50.0,
    log_level: Annotated[
        str,
        typer.Option(
            "--log-level",
            help="Lowest level logged (JSON lines on stderr, one per request at info): "
            "critical, error, warning, info, debug.",
        ),
    ] = "info",
    tls_cert: Annotated[
        Path | None,
        typer.Option("--tls-cert", help="Serve HTTPS with this certificate (PEM; with --tls-key)."),
    ] = None,
    tls_key: Annotated[
        Path | None, typer.Option("--tls-key", help="The certificate's private key (PEM).")
    ] = None,
    migrate: Annotated[
        bool,
        typer.Option(
            "--migrate",
            help="Upgrade the database's schema to this version's (back it up first), then "
            "exit without serving.",
        ),
    ] = False,
) -> None:
    """Serve the HTTP API (/api/v1, docs at /docs) and each site's pages (/sites/ID).

    /sites/ID/capture is the page that locates a phone from its camera's frames.
    Sites, cameras, maps and fixes are kept in the database (--db; by default camvlp.db in
    the user's data folder; the start line says where it is); several processes share it
    (--workers, or several machines with one PostgreSQL database). Sites are created with
    the admin key set in the environment variable CAMVLP_ADMIN_KEY (at least 16 characters).
    A database made by an older version is upgraded by --migrate (the service refuses to
    start on it until then); phones give their camera only to HTTPS pages: --tls-cert and
    --tls-key, or a reverse proxy (docs/service.md).
    """
    import uvicorn

    from camvlp.service import ServiceSettings
    from camvlp.service.connections import TimedH11Protocol
    from camvlp.service.logs import log_config
    from camvlp.service.settings import LOG_LEVELS

    for value, option in ((workers, "--workers"), (threads, "--threads")):
        check_positive(value, option)
    check_positive(max_upload_mb, "--max-upload-mb")
    check_positive(max_megapixels, "--max-megapixels")
    if not 0 < port < 65536:
        fail(f"--port must be 1 to 65535, got {port}")
    if log_level not in LOG_LEVELS:
        fail(f"--log-level must be one of {', '.join(LOG_LEVELS)}, got {log_level!r}")
    db = _database(db)
    if migrate:
        _migrate(db)
        return
    ssl = _tls_files(tls_cert, tls_key)
    _check_listen(host, port)
    try:  # the options, and the rest (the admin key, the timeouts) from CAMVLP_* variables
        settings = dataclasses.replace(
            ServiceSettings.from_env(),
            db=db,
            max_upload_bytes=round(max_upload_mb * 1024 * 1024),
            max_pixels=round(max_megapixels * 1e6),
            locate_threads=threads,
            log_level=log_level,
        )
    except ValueError as exc:
        fail(f"{exc} (environment)")
    admin_key = settings.admin_key
    _open_database(db)
    os.environ.update(settings.to_env())  # the workers build their app from these
    if not admin_key:
        print(
            "note: CAMVLP_ADMIN_KEY is not set: the service creates no sites (see docs/service.md)",
            file=sys.stderr,
        )
    scheme = "https" if ssl else "http"
    print(f"camvlp serve: {scheme}://{host}:{port}/docs  ({workers} worker(s))")
    print(f"database      {_shown(db)}")
    uvicorn.run(
        "camvlp.service:app_from_env",
        factory=True,
        host=host,
        port=port,
        workers=workers,
        log_level=log_level,
        log_config=log_config(log_level),  # JSON lines; the service writes the request lines
        access_log=False,
        http=TimedH11Protocol,  # uvicorn's h11, with header and body timeouts
        timeout_keep_alive=KEEP_ALIVE_S,
        limit_concurrency=settings.max_connections,
        h11_max_incomplete_event_size=MAX_HEADER_BYTES,
        **ssl,
    )


#: Seconds an idle connection is kept open between two requests (uvicorn's default).
KEEP_ALIVE_S = 5
#: Largest request line and headers, bytes (h11's default): larger gets 431.
MAX_HEADER_BYTES = 16 * 1024


def _open_database(db: str) -> None:
    """Create the tables of an empty database (once, before the workers start) and check that
    any other one is at this version's schema, or fail in one line: a URL that is not one, a
    driver that is missing, a file that is not a database (or not a file), a schema of
    another version."""
    from camvlp.service.migrate import prepare

    _with_database(db, prepare)


def _migrate(db: str) -> None:
    """``--migrate``: upgrade the database's schema and say from which revision to which."""
    from camvlp.service.migrate import upgrade

    before, after = _with_database(db, upgrade)
    if before == after:
        print(f"camvlp serve --migrate: the database is at revision {after} already")
    else:
        print(
            f"camvlp serve --migrate: upgraded the database from revision "
            f"{before or '(empty)'} to {after}"
        )
    print(f"database      {_shown(db)}")


def _database(db: str | None) -> str:
    """The database URL of ``--db`` (or CAMVLP_DB): a URL, or a path to a SQLite file;
    None, the default (:func:`camvlp.service.settings.default_db_url`). Empty: a usage
    error."""
    from camvlp.service.settings import database_url, default_db_url

    try:
        return database_url(db) if db is not None else default_db_url()
    except ValueError as exc:
        fail(str(exc))


def _shown(db: str) -> str:
    """Where the database is, as the start line says it: a SQLite database's file (absolute),
    another's URL without its password."""
    import sqlalchemy as sa

    from camvlp.service.settings import sqlite_file

    path = sqlite_file(db)
    if path is not None:
        return str(path.absolute())
    return sa.engine.make_url(db).render_as_string(hide_password=True)


def _with_database(db: str, work):
    """``work(engine)`` on the database of ``--db``; any failure is one error line."""
    import sqlalchemy as sa

    from camvlp.service.db import make_engine
    from camvlp.service.migrate import SchemaError
    from camvlp.service.settings import sqlite_file

    try:
        path = sqlite_file(db)
        if path is not None and path.exists() and not path.is_file():
            fail(f"cannot open the database: {path} is not a file (--db {db})")
        try:
            engine = make_engine(db)
        except OSError as exc:
            where = path.parent if path is not None else db
            reason = "a file is there" if isinstance(exc, FileExistsError) else exc.strerror
            fail(f"cannot create the database's folder {where}: {reason or exc} (--db {db})")
        try:
            return work(engine)
        finally:
            engine.dispose()
    except SchemaError as exc:
        fail(f"{exc} (--db {db})")
    except (sa.exc.SQLAlchemyError, ModuleNotFoundError, OSError, ValueError) as exc:
        text = str(getattr(exc, "orig", None) or exc).strip()
        first = text.splitlines()[0] if text else type(exc).__name__
        fail(f"cannot open the database: {first} (--db {db})")


def _tls_files(cert: Path | None, key: Path | None) -> dict[str, str]:
    """uvicorn's ``ssl_certfile`` and ``ssl_keyfile``, once Python's ssl module has loaded
    them; empty without --tls-cert; a usage error (one line) for one without the other, a
    file that cannot be read, or a key that does not match its certificate."""
    import ssl

    if cert is None and key is None:
        return {}
    if cert is None or key is None:
        fail("--tls-cert and --tls-key go together (a certificate and its private key)")
    for path, option in ((cert, "--tls-cert"), (key, "--tls-key")):
        if not path.is_file():
            fail(f"{option}: {path} is not a file")
    try:
        ssl.create_default_context(ssl.Purpose.CLIENT_AUTH).load_cert_chain(cert, key)
    except (ssl.SSLError, OSError, ValueError) as exc:
        reason = getattr(exc, "reason", None) or getattr(exc, "strerror", None) or exc
        fail(f"cannot use --tls-cert {cert} with --tls-key {key}: {reason}")
    return {"ssl_certfile": str(cert), "ssl_keyfile": str(key)}


def _check_listen(host: str, port: int) -> None:
    """A usage error (exit 2, one line) unless ``host:port`` can be listened on: an address
    that does not resolve, a port in use or not allowed (uvicorn would log several lines
    after starting the application and exit 3)."""
    try:
        family, kind, proto, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0]
        with socket.socket(family, kind, proto) as probe:
            probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as uvicorn does
            probe.bind(address)
    except OSError as exc:
        fail(f"cannot listen on {host}:{port}: {exc.strerror or exc} (--host, --port)")
