"""The tracked path over the room's plan, with the fixtures drawn."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from camvlp.model.fixtures import FixtureMap
from camvlp.viz.figure import new_figure

__all__ = ["plan_axes", "plot_trajectory"]

_STATUS_COLOURS = {"fix": "#1a9850", "tracked": "#f46d43", "predicted": "#4575b4"}


def plan_axes(fixture_map: FixtureMap) -> tuple[int, int, int]:
    """``(a, b, vertical)``: the two map axes of the room's plan and the vertical one.

    The vertical axis is the one the fixtures' normals point along (else the one along
    which their positions spread least: a ceiling is flat).
    """
    normals = [f.normal for f in fixture_map.fixtures if f.normal is not None]
    if normals:
        vertical = int(np.argmax(np.abs(np.mean(np.abs(np.array(normals)), axis=0))))
    else:
        vertical = int(np.argmin(np.ptp(fixture_map.positions, axis=0)))
    a, b = (i for i in range(3) if i != vertical)
    return a, b, vertical


def plot_trajectory(
    path: str | Path,
    fixture_map: FixtureMap,
    positions: np.ndarray,
    statuses: list[str],
    *,
    raw_positions: np.ndarray | None = None,
    truth: np.ndarray | None = None,
    times: np.ndarray | None = None,
    title: str = "",
) -> Path:
    """Draw the tracked path over the plan of the room and write it as a PNG.

    Parameters
    ----------
    path : str or Path
        The picture to write (.png).
    fixture_map : FixtureMap
        The room: each fixture drawn as a disc of its diameter with its ID.
    positions : ndarray, shape (N, 3)
        Filtered camera centres per frame, map units (NaN rows where lost).
    statuses : list of str
        Each frame's status (colours the path).
    raw_positions : ndarray, shape (N, 3), optional
        The frames' own solves (small dots).
    truth : ndarray, shape (N, 3), optional
        The true path (grey line); with ``times``, a second panel shows the position error
        over time.
    times : ndarray, shape (N,), optional
        Each frame's time, s.
    title : str
        The figure's title.

    Returns
    -------
    Path
        ``path``.
    """
    a, b, _ = plan_axes(fixture_map)
    pos = np.asarray(positions, dtype=float).reshape(-1, 3)
    st = np.asarray(statuses)
    with_error = truth is not None and times is not None
    fig = new_figure(8.5, 8.0 if with_error else 6.0, layout=None)
    if with_error:
        grid = fig.add_gridspec(2, 1, height_ratios=[3, 1.2])
        ax = fig.add_subplot(grid[0])
    else:
        ax = fig.add_subplot(1, 1, 1)
    _draw_fixtures(ax, fixture_map, a, b)
    _draw_paths(ax, pos, st, truth, raw_positions, a, b)
    _legend(ax, st, raw_positions is not None)
    _frame_plan(ax, fixture_map, pos, a, b)
    ax.set_title(title or "Tracked path over the room's plan", fontsize=10)
    if with_error:
        _draw_errors(fig.add_subplot(grid[1]), times, pos, truth, st, fixture_map.units)
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out)
    return out


def _draw_fixtures(ax, fixture_map: FixtureMap, a: int, b: int) -> None:
    """Each fixture as a disc of its diameter (0.1 map units without one), with its ID."""
    from matplotlib.patches import Circle

    for f in fixture_map.fixtures:
        r = 0.5 * (f.diameter or 0.1)
        ax.add_patch(Circle((f.position[a], f.position[b]), r, color="#fdbf11", ec="k", lw=0.6))
        ax.annotate(
            str(f.id),
            (f.position[a], f.position[b]),
            xytext=(0, 12),
            textcoords="offset points",
            ha="center",
            fontsize=8,
        )


def _draw_paths(ax, pos: np.ndarray, st: np.ndarray, truth, raw_positions, a: int, b: int) -> None:
    """The true path (grey), the frames' own solves (dots) and the tracked path, each frame
    coloured by its status."""
    if truth is not None:
        tr = np.asarray(truth, dtype=float).reshape(-1, 3)
        ax.plot(tr[:, a], tr[:, b], "-", color="0.55", lw=2.5, alpha=0.6, zorder=1)
    if raw_positions is not None:
        rp = np.asarray(raw_positions, dtype=float).reshape(-1, 3)
        ax.plot(rp[:, a], rp[:, b], ".", color="k", ms=1.5, zorder=3)
    ax.plot(pos[:, a], pos[:, b], "-", color="0.2", lw=0.6, zorder=2)
    for s, colour in _STATUS_COLOURS.items():
        m = st == s
        if np.any(m):
            ax.plot(pos[m, a], pos[m, b], "o", ms=2.5, color=colour, zorder=4)


def _legend(ax, st: np.ndarray, with_raw: bool) -> None:
    """The legend beside the plan: each status with its count of frames, the truth, the raw
    solves (``with_raw``) and the lost frames' count."""
    from matplotlib.lines import Line2D

    handles = [
        Line2D([], [], marker="o", ls="", color=c, label=f"{s} ({int((st == s).sum())})")
        for s, c in _STATUS_COLOURS.items()
    ]
    handles.append(Line2D([], [], color="0.55", lw=2.5, alpha=0.6, label="truth"))
    if with_raw:
        handles.append(Line2D([], [], marker=".", ls="", color="k", label="raw solve"))
    lost = int((st == "lost").sum())
    if lost:
        handles.append(Line2D([], [], ls="", label=f"lost ({lost})"))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8)


def _frame_plan(ax, fixture_map: FixtureMap, pos: np.ndarray, a: int, b: int) -> None:
    """The plan's axes: labels in map units, equal scales, a grid, and limits around the
    fixtures and the tracked positions."""
    names = "xyz"
    ax.set_xlabel(f"{names[a]} ({fixture_map.units})")
    ax.set_ylabel(f"{names[b]} ({fixture_map.units})")
    ax.set_aspect("equal")
    ax.grid(True, lw=0.3, alpha=0.5)
    pts = np.concatenate(
        [fixture_map.positions[:, [a, b]], pos[np.all(np.isfinite(pos), axis=1)][:, [a, b]]]
    )
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.1 * float(np.max(hi - lo)) + 0.2
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)


def _draw_errors(ex, times, pos: np.ndarray, truth, st: np.ndarray, units: str) -> None:
    """The position error over time (thousandths of the map's unit), each frame coloured by
    its status."""
    tt = np.asarray(times, dtype=float).reshape(-1)
    err = 1e3 * np.linalg.norm(pos - np.asarray(truth, dtype=float).reshape(-1, 3), axis=1)
    ex.plot(tt, err, "-", color="0.3", lw=0.8)
    for s, colour in _STATUS_COLOURS.items():
        m = st == s
        if np.any(m):
            ex.plot(tt[m], err[m], "o", ms=2.5, color=colour)
    ex.set_xlabel("t (s)")
    ex.set_ylabel(f"position error (m{units})")
    ex.set_ylim(bottom=0)
    ex.grid(True, lw=0.3, alpha=0.5)
