"""One BLAS thread for the fits whose matrix products are small and many.

The radial shape of a glowing light (:func:`camvlp.pipeline.lamp.radial.radial_fit`) and a light's
waveform (:func:`camvlp.pipeline.lamp.light_wave.separated_wave`) are fitted by alternating least
squares, thousands of products of matrices of a few hundred rows and columns a photo.
OpenBLAS splits each product over every core, and its threads wait between products by
spinning: on a 2-core machine a photo of glowing lights then costs about twice the CPU time
at the same wall time (14 glowing lamps at 1080p: 16.9 s of CPU for 9.2 s, against 8.6 s for
8.8 s on one thread), and a second job on the machine (the service's next request,
``evaluate``'s other worker) waits for the spinning thread.  These fits run their products
on one thread (:mod:`threadpoolctl`), the rest of the process as it was.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import TypeVar

__all__ = ["one_blas_thread"]

F = TypeVar("F", bound=Callable)

_CONTROLLER = None


def _controller():
    """The process's BLAS libraries (:class:`threadpoolctl.ThreadpoolController`), found once:
    finding them costs about a millisecond, limiting them then some 20 microseconds."""
    global _CONTROLLER
    if _CONTROLLER is None:
        from threadpoolctl import ThreadpoolController

        _CONTROLLER = ThreadpoolController()
    return _CONTROLLER


def one_blas_thread(fn: F) -> F:
    """``fn``, its BLAS calls (NumPy's matrix products) on one thread while it runs; the
    limit in place before is restored after (also when ``fn`` raises)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with _controller().limit(limits=1, user_api="blas"):
            return fn(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
