"""Settings of the positioning service: the database, the limits and the locate pool."""

from __future__ import annotations

import os
from dataclasses import dataclass, field, fields

__all__ = ["LOG_LEVELS", "MIN_ADMIN_KEY_CHARS", "ServiceSettings"]

_ENV_PREFIX = "CAMVLP_"
#: Shortest admin key accepted (``secrets.token_urlsafe(32)`` gives 43 characters).
MIN_ADMIN_KEY_CHARS = 16
#: The levels of the service's log lines (``CAMVLP_LOG_LEVEL``), as Python's logging names them.
LOG_LEVELS = ("critical", "error", "warning", "info", "debug")


@dataclass(frozen=True)
class ServiceSettings:
    """What ``camvlp serve`` and :func:`camvlp.service.create_app` can be told.

    Attributes
    ----------
    db : str
        SQLAlchemy database URL: ``sqlite:///camvlp.db`` (a file next to where the service
        runs) or e.g. ``postgresql+psycopg://user@host/camvlp`` for several machines.
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

    db: str = "sqlite:///camvlp.db"
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
