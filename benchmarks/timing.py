"""``locate``'s time as a distribution over many photos: the tables the benchmarks print.

Each photo gives a :class:`PhotoTime`: its JPEG decode's time, ``locate``'s time per stage
(``LocateResult.timing_ms``) and the special paths that ran (``LocateResult.paths``).
:func:`time_table` prints p50 / p95 / max of each stage per photo size, and of ``locate``'s
time over the decode's; :func:`slowest` the slowest photos against their decode, with the
paths their time went to.  Used by ``stress_decode.py`` and ``real_photos.py``.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

#: ``locate``'s stages in order (``LocateResult.timing_ms``), then their total.
STAGES = ("prepare", "detect", "profile", "decode", "pose", "total")


@dataclass
class PhotoTime:
    """One photo's times: ``name`` says which photo, ``size`` its pixels ("1920x1080"), the
    JPEG decode's time and ``locate``'s per stage (ms), and the special paths that ran
    (name -> ``{"calls": n, "ms": t}``, as in ``LocateResult.to_dict()["paths"]``)."""

    name: str
    size: str
    jpeg_ms: float
    timing_ms: dict[str, float]
    paths: dict[str, dict] = field(default_factory=dict)

    @property
    def ratio(self) -> float:
        """``locate``'s time over the JPEG decode's."""
        return self.timing_ms.get("total", float("nan")) / self.jpeg_ms


def path_dict(paths) -> dict[str, dict]:
    """``LocateResult.paths`` (name -> PathTime) as plain dicts, rounded to 0.01 ms."""
    return {k: {"calls": int(p.calls), "ms": round(float(p.ms), 2)} for k, p in paths.items()}


def _row(label: str, n: int, what: str, v: np.ndarray, fmt: str) -> str:
    p50, p95 = np.percentile(v, [50, 95])
    return f"| {label} | {n} | {what} | {p50:{fmt}} | {p95:{fmt}} | {v.max():{fmt}} |"


def time_table(times: Iterable[PhotoTime]) -> str:
    """A Markdown table: per photo size, p50 / p95 / max of the JPEG decode, of each of
    ``locate``'s stages, and of ``locate``'s total over the decode's (ms; a ratio)."""
    times = list(times)
    out = ["| size | photos | what | p50 | p95 | max |", "|---|---|---|---|---|---|"]
    for size in sorted({t.size for t in times}, key=_pixels):
        part = [t for t in times if t.size == size]
        out.append(
            _row(size, len(part), "JPEG decode ms", np.array([t.jpeg_ms for t in part]), ".1f")
        )
        for stage in STAGES:
            v = np.array([t.timing_ms.get(stage, np.nan) for t in part])
            out.append(_row(size, len(part), f"{stage} ms", v, ".1f"))
        out.append(
            _row(size, len(part), "locate / decode", np.array([t.ratio for t in part]), ".2f")
        )
    return "\n".join(out)


def _pixels(size: str) -> int:
    w, _, h = size.partition("x")
    return int(w) * int(h) if w.isdigit() and h.isdigit() else 0


def slowest(times: Iterable[PhotoTime], n: int = 5) -> str:
    """The ``n`` photos slowest against their JPEG decode, each with its stages' times and
    the special paths it ran, the longest first (inclusive ms, calls)."""
    lines = [f"the {n} photos slowest against their JPEG decode:"]
    for t in sorted(times, key=lambda t: -t.ratio)[:n]:
        stages = " / ".join(f"{t.timing_ms.get(s, np.nan):.0f}" for s in STAGES[1:-1])
        ran = sorted(t.paths.items(), key=lambda kv: -kv[1]["ms"])
        went = ", ".join(f"{k} {p['ms']:.0f} ms ({p['calls']}x)" for k, p in ran) or "none"
        lines.append(
            f"  {t.ratio:6.2f}x  {t.name} ({t.size}): locate {t.timing_ms['total']:.0f} ms "
            f"(detect / profile / decode / pose {stages}), JPEG {t.jpeg_ms:.0f} ms; "
            f"paths: {went}"
        )
    return "\n".join(lines)
