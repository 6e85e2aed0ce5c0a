"""The progress bar of the commands that take a while (track, render-video, evaluate, study,
calibrate, render-chessboard): one look, on stderr, on a terminal only."""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager

__all__ = ["Update", "progress_bar"]

#: ``update(done, total=None)``: the count done so far, and the total when it changed.
Update = Callable[..., None]


@contextmanager
def progress_bar(total: int | None, label: str, *, show: bool = True) -> Iterator[Update | None]:
    """A progress bar on stderr while the block runs: the label, the bar, done / total and
    the time left (rich's), removed at the end.

    Parameters
    ----------
    total : int or None
        How many items (frames, photos, poses) there are; None: not known (the bar pulses).
    label : str
        What is being done ("rendering", "tracking" ...).
    show : bool
        False: no bar (the caller's choice, e.g. for a run too short to need one).

    Yields
    ------
    callable or None
        ``update(done, total=None)`` to call with the count done so far (and a new total);
        None when no bar is drawn: ``show`` is False, or stderr is not a terminal (a log or a
        pipe gets nothing), so that the work skips the calls.
    """
    if not (show and sys.stderr.isatty()):
        yield None
        return
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeRemainingColumn,
    )

    with Progress(
        TextColumn(label),
        BarColumn(),
        MofNCompleteColumn(),
        TimeRemainingColumn(),
        console=Console(stderr=True),
        transient=True,
    ) as bar:
        task = bar.add_task(label, total=total)

        def update(done: int, total: int | None = None) -> None:
            if total is None:
                bar.update(task, completed=done)
            else:
                bar.update(task, completed=done, total=total)

        yield update
