"""Per-key rate limits: a token bucket per API key, in the service process.

Each key (a site's key, or the admin key) has a bucket of ``burst`` tokens, refilled at
``rate`` tokens per second; a request takes one token, and a request that finds the bucket
empty is answered 429 with ``Retry-After`` (the seconds until a token is back).  The buckets
live in one process: with ``--workers N`` a key may make up to N times the rate in all.
The table of buckets is bounded: past ``max_keys`` keys the bucket used longest ago goes (a
key it forgets starts again with a full bucket, which only ever lets a request through).
"""

from __future__ import annotations

import math
import threading
import time
from collections import OrderedDict
from collections.abc import Callable

__all__ = ["RateLimiter"]


class RateLimiter:
    """Token buckets keyed by a string (the key's hash).

    Parameters
    ----------
    rate : float
        Tokens per second added to each bucket (requests per second on average).
    burst : int
        Tokens a bucket holds at most (requests at once).
    max_keys : int
        Buckets kept at most.
    clock : callable
        Seconds, monotonic (``time.monotonic``; a test may pass its own).
    """

    def __init__(
        self,
        rate: float,
        burst: int,
        max_keys: int = 10_000,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if not (rate > 0 and burst >= 1 and max_keys >= 1):
            raise ValueError(f"rate, burst and max_keys must be positive: {rate}, {burst}")
        self.rate, self.burst, self.max_keys, self.clock = float(rate), int(burst), max_keys, clock
        self._buckets: OrderedDict[str, tuple[float, float]] = OrderedDict()  # tokens, time
        self._lock = threading.Lock()  # FastAPI runs plain dependencies in worker threads

    def take(self, key: str) -> float:
        """Take a token from ``key``'s bucket: 0.0 when there was one, else the seconds until
        there will be one (the request is then refused and takes nothing)."""
        now = self.clock()
        with self._lock:
            tokens, then = self._buckets.pop(key, (float(self.burst), now))
            tokens = min(float(self.burst), tokens + (now - then) * self.rate)
            wait = 0.0
            if tokens >= 1.0:
                tokens -= 1.0
            else:
                wait = (1.0 - tokens) / self.rate
            self._buckets[key] = (tokens, now)
            while len(self._buckets) > self.max_keys:
                self._buckets.popitem(last=False)
        return wait

    @staticmethod
    def retry_after(wait_s: float) -> str:
        """``Retry-After``'s value for a wait: whole seconds, at least 1."""
        return str(max(1, math.ceil(wait_s)))
