"""Time limits on a client's connection: its request's headers, and the pauses in its body.

uvicorn closes a connection that stays idle between requests (``timeout_keep_alive``) and
answers 503 past a number of connections (``limit_concurrency``); h11 refuses headers over
``h11_max_incomplete_event_size``.  It has no limit on how long a client may take to send a
request: a client that sends one byte every few seconds holds its connection for good.
:class:`TimedH11Protocol` is uvicorn's h11 protocol with two more limits:

* a request's line and headers must arrive within ``header_timeout_s`` of its first byte (or of
  the connection's opening);
* its body may pause at most ``body_timeout_s`` between two pieces (a body that stops, or a
  chunk that announces more bytes than ever come, ends there).

Past either, the client gets ``408 Request Timeout`` (unless an answer has started) and the
connection is closed; the application sees the client disconnect.  The limits come from
:class:`camvlp.service.ServiceSettings` (``CAMVLP_HEADER_TIMEOUT_S``,
``CAMVLP_BODY_TIMEOUT_S``); ``camvlp serve`` passes the class to uvicorn as its ``http``.
"""

from __future__ import annotations

import asyncio
import functools

import h11
from uvicorn.protocols.http.h11_impl import H11Protocol

from camvlp.service.settings import ServiceSettings

__all__ = ["TimedH11Protocol", "timeouts"]

_TIMED_OUT = b"request timed out"
_RESPONSE_408 = (
    b"HTTP/1.1 408 Request Timeout\r\ncontent-type: text/plain; charset=utf-8\r\n"
    b"connection: close\r\ncontent-length: " + str(len(_TIMED_OUT)).encode() + b"\r\n\r\n"
) + _TIMED_OUT


@functools.cache
def timeouts() -> tuple[float, float]:
    """``(header_timeout_s, body_timeout_s)`` of this process's settings (its environment)."""
    settings = ServiceSettings.from_env()
    return settings.header_timeout_s, settings.body_timeout_s


class TimedH11Protocol(H11Protocol):
    """uvicorn's h11 protocol, closing a connection whose request headers take longer than
    ``header_timeout_s`` or whose body pauses longer than ``body_timeout_s``."""

    _guard: asyncio.TimerHandle | None = None

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        self._arm(timeouts()[0])

    def data_received(self, data: bytes) -> None:
        super().data_received(data)
        state = self.conn.their_state
        if state is h11.SEND_BODY:  # a body arriving: each piece gives it another pause
            self._arm(timeouts()[1])
        elif state is h11.IDLE and self._guard is None:  # the first bytes of a new request
            self._arm(timeouts()[0])
        elif state is not h11.IDLE:  # the request is in: the application has it
            self._disarm()

    def connection_lost(self, exc: Exception | None) -> None:
        self._disarm()
        super().connection_lost(exc)

    def on_response_complete(self) -> None:
        self._disarm()  # uvicorn's keep-alive timeout takes over until the next request
        super().on_response_complete()

    def _arm(self, seconds: float) -> None:
        self._disarm()
        self._guard = self.loop.call_later(seconds, self._timed_out)

    def _disarm(self) -> None:
        if self._guard is not None:
            self._guard.cancel()
            self._guard = None

    def _timed_out(self) -> None:
        self._guard = None
        if self.transport.is_closing():
            return
        if self.conn.their_state is h11.SEND_BODY and self.flow.read_paused:
            self._arm(timeouts()[1])  # we stopped reading (the application is behind): wait
            return
        if self.cycle is None or not self.cycle.response_started:
            self.transport.write(_RESPONSE_408)
        self.transport.close()
