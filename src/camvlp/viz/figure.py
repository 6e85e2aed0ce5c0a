"""A matplotlib figure that belongs to no window: no pyplot, no process-wide backend."""

from __future__ import annotations

__all__ = ["new_figure"]


def new_figure(
    width: float = 6.4, height: float = 4.8, *, dpi: int = 120, layout: str | None = "constrained"
):
    """A ``matplotlib.figure.Figure`` of ``width`` x ``height`` inches (constrained layout).

    It is drawn with the Agg canvas when saved (``fig.savefig``); nothing is shown, no
    pyplot state is kept (nothing to close) and the backend of the process is left alone.
    matplotlib is imported here, on first use.
    """
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), dpi=dpi, layout=layout)
