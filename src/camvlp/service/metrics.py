"""The service's Prometheus metrics, served at ``/metrics`` in Prometheus' text format.

One :class:`ServiceMetrics` per application, with its own registry (``prometheus_client``),
so that several applications in one process (the tests) keep their counts apart.  The
figures are those of one service process: with ``--workers N`` each scrape reaches one of
them (scrape each process on a port of its own, or run one worker per container).
"""

from __future__ import annotations

from collections.abc import Callable

from prometheus_client import (
    CONTENT_TYPE_LATEST,
    CollectorRegistry,
    Counter,
    Gauge,
    Histogram,
    disable_created_metrics,
    generate_latest,
)

__all__ = ["CONTENT_TYPE", "ServiceMetrics"]

#: The media type of :meth:`ServiceMetrics.render`'s text.
CONTENT_TYPE = CONTENT_TYPE_LATEST

disable_created_metrics()  # no *_created series: only the counts and times

#: Latency buckets, seconds: a 640 x 480 frame takes milliseconds, a 20 MP photo a second.
_BUCKETS = (0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 30.0)


class ServiceMetrics:
    """Counters, histograms and gauges of one service process.

    Attributes
    ----------
    requests : Counter
        ``camvlp_http_requests_total{method, route, status}``: requests answered (the route
        is its template, e.g. ``/api/v1/sites/{site_id}/frames``; ``unmatched`` for none).
    request_seconds : Histogram
        ``camvlp_http_request_duration_seconds{method, route}``: time to answer, s.
    fixes : Counter
        ``camvlp_fixes_total{source, located}``: fixes recorded, from photos or frames.
    locate_seconds : Histogram
        ``camvlp_locate_duration_seconds{source}``: time in a locate thread (decoding the
        picture and locating it), s.
    frame_wait_seconds : Histogram
        ``camvlp_frame_queue_wait_seconds``: time a frame waited for its device's turn, s.
    frames_dropped : Counter
        ``camvlp_frames_dropped_total{reason}``: frames not located (``superseded``: a newer
        frame of the device arrived while it waited; ``stale``: older than one located).
    rate_limited : Counter
        ``camvlp_rate_limited_total``: requests answered 429.
    """

    def __init__(self) -> None:
        self.registry = CollectorRegistry(auto_describe=True)
        reg = self.registry
        self.requests = Counter(
            "camvlp_http_requests",
            "HTTP requests answered.",
            ["method", "route", "status"],
            registry=reg,
        )
        self.request_seconds = Histogram(
            "camvlp_http_request_duration_seconds",
            "Time to answer an HTTP request, seconds.",
            ["method", "route"],
            buckets=_BUCKETS,
            registry=reg,
        )
        self.fixes = Counter("camvlp_fixes", "Fixes recorded.", ["source", "located"], registry=reg)
        self.locate_seconds = Histogram(
            "camvlp_locate_duration_seconds",
            "Time to decode and locate a photo or frame, seconds.",
            ["source"],
            buckets=_BUCKETS,
            registry=reg,
        )
        self.frame_wait_seconds = Histogram(
            "camvlp_frame_queue_wait_seconds",
            "Time a frame waited for its device's turn, seconds.",
            buckets=_BUCKETS,
            registry=reg,
        )
        self.frames_dropped = Counter(
            "camvlp_frames_dropped", "Frames dropped before locating.", ["reason"], registry=reg
        )
        self.rate_limited = Counter(
            "camvlp_rate_limited", "Requests refused by the per-key rate limit.", registry=reg
        )
        self._gauges: dict[str, Gauge] = {}

    def gauge(self, name: str, doc: str, read: Callable[[], float]) -> None:
        """A gauge ``name`` whose value ``read()`` gives at each scrape."""
        g = Gauge(name, doc, registry=self.registry)
        g.set_function(read)
        self._gauges[name] = g

    def render(self) -> bytes:
        """Every metric in Prometheus' text format."""
        return generate_latest(self.registry)
