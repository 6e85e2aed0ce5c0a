"""Structured logs: one JSON object per line, and one line per request.

:class:`JsonFormatter` writes a log record as a JSON object (``time``, ``level``, ``logger``,
``message`` and the record's own fields); :func:`log_config` gives uvicorn a logging
configuration that uses it for its own lines too, and :class:`AccessLog` is the middleware
that writes the request lines (logger ``camvlp.access``):

``{"time": "...", "level": "info", "logger": "camvlp.access", "message": "request",
"method": "POST", "path": "/api/v1/sites/3/frames", "route": "/api/v1/sites/{site_id}/frames",
"status": 200, "latency_ms": 21.4, "site": 3, "device": "phone-1"}``

The path is the request's path alone: the query string is left out, and keys never appear
in either (they travel in the Authorization header).  The same middleware counts each request
in the service's metrics (:class:`camvlp.service.metrics.ServiceMetrics`).
"""

from __future__ import annotations

import json
import logging
import time
from datetime import UTC, datetime
from typing import Any
from urllib.parse import parse_qsl

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from camvlp.service.metrics import ServiceMetrics

__all__ = ["ACCESS_LOGGER", "AccessLog", "JsonFormatter", "log_config"]

#: The logger of the request lines.
ACCESS_LOGGER = "camvlp.access"

#: A LogRecord's own attributes: everything else on a record is a field of the line.
_RECORD_KEYS = set(vars(logging.makeLogRecord({}))) | {"message", "asctime", "color_message"}


class JsonFormatter(logging.Formatter):
    """A log record as one line of JSON: time (UTC, ISO 8601), level, logger, message, the
    fields given in ``extra``, and the exception's text when there is one."""

    def format(self, record: logging.LogRecord) -> str:
        line: dict[str, Any] = {
            "time": datetime.fromtimestamp(record.created, UTC)
            .isoformat(timespec="milliseconds")
            .replace("+00:00", "Z"),
            "level": record.levelname.lower(),
            "logger": record.name,
            "message": record.getMessage(),
        }
        for key, value in vars(record).items():
            if key not in _RECORD_KEYS and not key.startswith("_"):
                line[key] = value
        if record.exc_info:
            line["exception"] = self.formatException(record.exc_info)
        return json.dumps(line, default=str, ensure_ascii=False)


def log_config(level: str) -> dict[str, Any]:
    """A ``logging.config.dictConfig`` configuration (uvicorn's ``log_config``): every line
    of uvicorn and of the service as JSON on standard error, at ``level`` and above."""
    handler = {"class": "logging.StreamHandler", "formatter": "json", "stream": "ext://sys.stderr"}
    ours = {"handlers": ["json"], "level": level.upper(), "propagate": False}
    return {
        "version": 1,
        "disable_existing_loggers": False,
        "formatters": {"json": {"()": JsonFormatter}},
        "handlers": {"json": handler},
        "loggers": {
            **{name: dict(ours) for name in ("uvicorn", "uvicorn.error", "camvlp")},
            "uvicorn.access": {"handlers": [], "level": "CRITICAL", "propagate": False},
        },
    }


class AccessLog:
    """ASGI middleware: after each HTTP request, one ``camvlp.access`` line and the request's
    count and time in ``metrics``.

    The route's site is its ``site_id`` path parameter; its device, the ``device`` a route
    put in the request's state, else the ``device`` query parameter.
    """

    def __init__(self, app: ASGIApp, metrics: ServiceMetrics) -> None:
        self.app, self.metrics = app, metrics
        self.log = logging.getLogger(ACCESS_LOGGER)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        start = time.perf_counter()
        status = 500  # unless an answer starts

        async def watched(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = message["status"]
            await send(message)

        try:
            await self.app(scope, receive, watched)
        finally:
            self._record(scope, status, time.perf_counter() - start)

    def _record(self, scope: Scope, status: int, seconds: float) -> None:
        # the route's template; a mount's path (the static files); else unmatched (a 404)
        route = getattr(scope.get("route"), "path", None) or scope.get("root_path") or "unmatched"
        method = scope["method"]
        self.metrics.requests.labels(method, route, str(status)).inc()
        self.metrics.request_seconds.labels(method, route).observe(seconds)
        if not self.log.isEnabledFor(logging.INFO):
            return
        site = (scope.get("path_params") or {}).get("site_id")
        if not (isinstance(site, str) and site.isdigit() and len(site) < 19):
            site = None
        device = (scope.get("state") or {}).get("device")
        if device is None:
            device = _query_value(scope, "device")
        fields = {
            "method": method,
            "path": scope["path"],
            "route": route,
            "status": status,
            "latency_ms": round(1e3 * seconds, 2),
            "site": None if site is None else int(site),
            "device": device,
        }
        self.log.info("request", extra=fields)


def _query_value(scope: Scope, name: str) -> str | None:
    """The first value of a query parameter (at most 200 characters), or None."""
    raw = scope.get("query_string", b"").decode("latin-1")
    for key, value in parse_qsl(raw, keep_blank_values=True):
        if key == name:
            return value[:200]
    return None
