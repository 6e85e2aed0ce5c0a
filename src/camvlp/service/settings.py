"""Settings of the positioning service: the database, the limits and the locate pool."""

from __future__ import annotations

import os
from dataclasses import dataclass, field, fields
from pathlib import Path

__all__ = [
    "LOG_LEVELS",
    "MIN_ADMIN_KEY_CHARS",
    "ServiceSettings",
    "database_url",
    "default_db_url",
    "sqlite_file",
]

_ENV_PREFIX = "CAMVLP_"
#: Shortest admin key accepted (``secrets.token_urlsafe(32)`` gives 43 characters).
MIN_ADMIN_KEY_CHARS = 16
#: The levels of the service's log lines (``CAMVLP_LOG_LEVEL``), as Python's logging names them.
LOG_LEVELS = ("critical", "error", "warning", "info", "debug")


def default_db_url() -> str:
    """The service's database when none is given: ``camvlp.db`` in the user's data folder.

    That is ``$XDG_DATA_HOME/camvlp/camvlp.db``, else ``~/.local/share/camvlp/camvlp.db`` on
    Linux; ``~/Library/Application Support/camvlp`` on macOS, ``%LOCALAPPDATA%\\camvlp`` on
    Windows (platformdirs' user data folder).  Never the folder the service runs in.
    """
    import platformdirs

    folder = Path(platformdirs.user_data_dir("camvlp", appauthor=False))
    return f"sqlite:///{folder / 'camvlp.db'}"


def database_url(text: str) -> str:
    """A database as ``--db`` or ``CAMVLP_DB`` give it, as an SQLAlchemy URL: a URL
    (``sqlite:///FILE``, ``postgresql+psycopg://USER@HOST/NAME`` ...) as it is; a path
    without ``://`` (``~/vlp/sites.db``) the SQLite file there, made absolute."""
    text = text.strip()
    if not text:
        raise ValueError("the database is empty: give a URL or a file (--db, CAMVLP_DB)")
    if "://" in text:
        return text
    return f"sqlite:///{Path(text).expanduser().resolve()}"


def sqlite_file(url: str) -> Path | None:
    """The file of a SQLite database URL (``sqlite:///FILE``, ``sqlite+pysqlite:///FILE``);
    None for another database, an in-memory one or a URL that is not one."""
    import sqlalchemy as sa

    try:
        parsed = sa.engine.make_url(url)
    except (sa.exc.ArgumentError, ValueError):
        return None
    if parsed.get_backend_name() != "sqlite" or parsed.database in (None, "", ":memory:"):
        return None
    if parsed.database.startswith("file:"):  # a URI filename (?uri=true): SQLite's to read
        return None
    return Path(parsed.database)


@dataclass(frozen=True)
class ServiceSettings:
    """What ``camvlp serve`` and :func:`camvlp.service.create_app` can be told.

    Attributes
    ----------
    db : str
        SQLAlchemy database URL, e.g. ``postgresql+psycopg://user@host/camvlp`` for several
        machines, or a SQLite file (a path without ``://`` is one, :func:`database_url`).
        Default: :func:`default_db_url`, ``camvlp.db`` in the user's data folder.
    max_upload_bytes : int
        Largest request body accepted (bytes); larger ones get 413 before being read.
    max_pixels : int
        Largest photo accepted (width x height, pixels), read from the file's header; larger
        ones get 413 without being decoded.
    locate_threads : int
        Photos located at once by one service process (OpenCV releases the GIL).
    max_queued : int
        Photos waiting for a locate thread, per process, before new ones get 503.
    stream_poll_s : float
        How often (seconds) a fix stream looks for new fixes in the database.
    stream_max_s : float
        How long (seconds) one fix stream stays open; clients reconnect with Last-Event-ID.
    picture_max_px : int
        Longest side (pixels) of the annotated pictures kept for the page.
    admin_key : str
        The key that creates sites (``Authorization: Bearer KEY`` on ``POST /sites``), at
        least 16 characters; empty: no site can be created.  From ``CAMVLP_ADMIN_KEY``.
    header_timeout_s : float
        Most seconds a client may take to send a request's line and headers.
    body_timeout_s : float
        Most seconds a request's body may pause between two pieces.
    max_connections : int
        Connections (and requests in progress) per process before new requests get 503.
    rate_per_s : float
        Requests per second allowed to one API key (a site's, or the admin key), on average,
        per process: a token bucket refilled at this rate; beyond it, 429 with Retry-After.
    rate_burst : int
        The bucket's size: requests one key may make at once before the rate applies.
    frame_devices : int
        Devices whose frames one process tracks at once (each keeps a tracker); a new device
        beyond them takes the place of the one idle longest.
    frame_idle_s : float
        Seconds after a device's last frame before its track is forgotten (its next frame
        starts a new one).
    log_level : str
        Level of the service's JSON log lines (one per request): debug, info, warning, error
        or critical.
    """

    db: str = field(default_factory=default_db_url)
    max_upload_bytes: int = 40 * 1024 * 1024
    max_pixels: int = 50_000_000
    locate_threads: int = 2
    max_queued: int = 32
    stream_poll_s: float = 0.5
    stream_max_s: float = 600.0
    picture_max_px: int = 1280
    admin_key: str = field(default="", repr=False)
    header_timeout_s: float = 10.0
    body_timeout_s: float = 10.0
    max_connections: int = 500
    rate_per_s: float = 100.0
    rate_burst: int = 200
    frame_devices: int = 256
    frame_idle_s: float = 300.0
    log_level: str = "info"

    def __post_init__(self) -> None:
        object.__setattr__(self, "db", database_url(self.db))
        for f in fields(self):
            value = getattr(self, f.name)
            if f.type in ("int", "float") and not value > 0:
                raise ValueError(f"{f.name} must be positive, got {value!r}")
        if self.log_level not in LOG_LEVELS:
            raise ValueError(
                f"log_level must be one of {', '.join(LOG_LEVELS)}, got {self.log_level!r}"
            )
        if self.admin_key and len(self.admin_key) < MIN_ADMIN_KEY_CHARS:
            raise ValueError(
                f"CAMVLP_ADMIN_KEY must be at least {MIN_ADMIN_KEY_CHARS} characters, got "
                f"{len(self.admin_key)}"
            )

    def to_env(self) -> dict[str, str]:
        """The settings as ``CAMVLP_*`` environment variables (for worker processes)."""
        return {_ENV_PREFIX + f.name.upper(): str(getattr(self, f.name)) for f in fields(self)}

    @classmethod
    def from_env(cls, env: dict[str, str] | None = None) -> ServiceSettings:
        """Settings from ``CAMVLP_*`` environment variables; defaults for the others."""
        env = dict(os.environ if env is None else env)
        kwargs: dict[str, object] = {}
        for f in fields(cls):
            text = env.get(_ENV_PREFIX + f.name.upper())
            if text is not None:
                kind = {"int": int, "float": float}.get(str(f.type), str)
                kwargs[f.name] = kind(text)
        return cls(**kwargs)  # type: ignore[arg-type]
