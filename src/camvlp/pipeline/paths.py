"""Which of the pipeline's special paths ran on a photo, how often, and for how long.

A plain disc costs ``locate`` a millisecond or two; a photo's time goes long where a light
needs one of the special paths: a glowing lamp's radial fit, lamps whose glows joined fitted
together, a joined region taken apart, the photo-wide model fit, a light's profile read by
the model decoder, glows taken apart to read their codes.  Each such path's entry point is
marked with :func:`path`; while :func:`recording` is active (``locate`` records every
photo), each call adds one call and its time to the record, which
:attr:`camvlp.pipeline.results.LocateResult.paths` reports.  A path that runs inside another
(a radial fit within a joint fit) counts in both: the times are inclusive.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from typing import NamedTuple, TypeVar

__all__ = ["PathTime", "path", "recording"]

F = TypeVar("F", bound=Callable)


class PathTime(NamedTuple):
    """A special path's calls on one photo and their time, milliseconds (inclusive)."""

    calls: int
    ms: float


#: The record of the photo being located, name -> [calls, seconds]; None when none is kept.
_RECORD: ContextVar[dict[str, list] | None] = ContextVar("camvlp_paths", default=None)


@contextmanager
def recording() -> Iterator[dict[str, PathTime]]:
    """Record the marked paths' calls within the block; the dict it yields is filled (name ->
    :class:`PathTime`, in the order the paths first ran) when the block ends."""
    record: dict[str, list] = {}
    out: dict[str, PathTime] = {}
    token = _RECORD.set(record)
    try:
        yield out
    finally:
        _RECORD.reset(token)
        out.update((name, PathTime(n, 1e3 * s)) for name, (n, s) in record.items())


def path(name: str) -> Callable[[F], F]:
    """Mark a function as the entry point of the special path ``name``: each call is counted
    and timed while :func:`recording` is active (some 0.3 microseconds a call otherwise)."""

    def mark(fn: F) -> F:
        @functools.wraps(fn)
        def timed(*args, **kwargs):
            record = _RECORD.get()
            if record is None:
                return fn(*args, **kwargs)
            entry = record.setdefault(name, [0, 0.0])  # (in the order the paths first ran)
            start = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                entry[0] += 1
                entry[1] += time.perf_counter() - start

        return timed  # type: ignore[return-value]

    return mark
