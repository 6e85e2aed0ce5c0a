"""Plots of a survey evaluation: the thesis' figures 5.9 (error over the floor) and 5.11.

matplotlib is imported only when a figure is made (:func:`~camvlp.viz.figure.new_figure`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from camvlp.analysis.evaluation import Evaluation, floor_axes
from camvlp.errors import InputError
from camvlp.format import mm_per_unit
from camvlp.io.survey_csv import AXES
from camvlp.io.writers import write_json, write_results_csv
from camvlp.model.fixtures import FixtureMap
from camvlp.viz.figure import new_figure

__all__ = [
    "draw_error_map",
    "draw_positions",
    "plot_error_map",
    "plot_positions",
    "write_evaluation",
]

_BLUE, _ORANGE = "#1f77b4", "#ff7f0e"


def _line_collection(segments, **kwargs):
    from matplotlib.collections import LineCollection

    return LineCollection(segments, **kwargs)


def draw_error_map(ax, evaluation: Evaluation) -> None:
    """Draw :func:`plot_error_map`'s figure on a matplotlib ``Axes`` (colour bar beside it)."""
    ev = evaluation
    a, b, _ = floor_axes(ev.survey.positions)
    scale, unit = mm_per_unit(ev.units)
    true = ev.survey.positions
    ok = ev.located
    n = max(len(true), 1)
    size = float(np.clip((0.55 * 330.0 / math.sqrt(n)) ** 2, 30.0, 900.0))
    if ok.any():
        sc = ax.scatter(
            true[ok, a],
            true[ok, b],
            c=ev.errors[ok] * scale,
            s=size,
            marker="s",
            cmap="viridis",
            edgecolors="none",
        )
        cb = ax.figure.colorbar(sc, ax=ax, shrink=0.9)
        cb.set_label(f"position error ({unit})")
    if (~ok).any():
        ax.scatter(
            true[~ok, a],
            true[~ok, b],
            s=60,
            marker="x",
            color="0.45",
            label=f"not located ({int((~ok).sum())})",
        )
        ax.legend(loc="upper right", fontsize=8, framealpha=0.9)
    ax.set_xlabel(f"{AXES[a]} ({ev.units})")
    ax.set_ylabel(f"{AXES[b]} ({ev.units})")
    ax.set_aspect("equal", adjustable="datalim")
    ax.margins(0.08)
    errs = ev.errors[ok] * scale
    stats = (
        f"mean {errs.mean():.2f} {unit}, max {errs.max():.2f} {unit}, "
        f"{int(ok.sum())}/{len(ok)} located"
        if ok.any()
        else f"0/{len(ok)} located"
    )
    ax.set_title(f"Position error over the floor ({AXES[a]}-{AXES[b]} plane)\n{stats}", fontsize=10)
    ax.grid(True, alpha=0.3)


def plot_error_map(evaluation: Evaluation, path: str | Path, *, dpi: int = 110) -> Path:
    """The thesis' figure 5.9: position error over the floor.

    Each photo is a square at its true position on the floor (the two axes along which the
    true positions spread most), coloured by its position error (millimetres for maps in
    m, cm or mm); photos that were not located are grey crosses.

    Returns
    -------
    Path
        ``path``.
    """
    fig = new_figure(6.4, 5.4, dpi=100)
    draw_error_map(fig.add_subplot(), evaluation)
    p = Path(path)
    fig.savefig(p, dpi=dpi)
    return p


def _auto_magnify(max_error: float, span: float) -> float:
    """A 1-2-5 magnification drawing the largest error as about 5 % of the survey's span."""
    if not (max_error > 0 and span > 0):
        return 1.0
    m = 0.05 * span / max_error
    if m <= 1.0:
        return 1.0
    decade = 10.0 ** math.floor(math.log10(m))
    return max(s * decade for s in (1.0, 2.0, 5.0) if s * decade <= m)


def _draw_points(ax, true: np.ndarray, shown: np.ndarray, ok: np.ndarray) -> None:
    """True points (N, 2) blue, shown estimates (M, 2) orange joined to them, misses as crosses.

    ``ok`` (N,) marks the located photos, whose estimates are ``shown`` in order.
    """
    if ok.any():
        segs = np.stack([true[ok], shown], axis=1)
        ax.add_collection(_line_collection(segs, colors="0.55", linewidths=0.8, zorder=1))
    ax.scatter(true[:, 0], true[:, 1], s=18, color=_BLUE, label="true", zorder=2)
    if ok.any():
        ax.scatter(shown[:, 0], shown[:, 1], s=18, color=_ORANGE, label="estimated", zorder=3)
    if (~ok).any():
        miss = true[~ok]
        ax.scatter(
            miss[:, 0], miss[:, 1], s=50, marker="x", color="0.3", label="not located", zorder=4
        )


def draw_positions(
    axes,
    evaluation: Evaluation,
    *,
    fixture_map: FixtureMap | None = None,
    magnify: float | None = None,
) -> float:
    """Draw :func:`plot_positions`' three views on three matplotlib ``Axes``.

    Returns
    -------
    float
        The magnification used (``magnify``, or the automatic one).
    """
    ev = evaluation
    a, b, v = floor_axes(ev.survey.positions)
    true = ev.survey.positions
    ok = ev.located
    vec = ev.error_vectors
    if magnify is None:
        span = float(np.ptp(true[:, [a, b]], axis=0).max()) if len(true) else 0.0
        magnify = _auto_magnify(float(np.nanmax(ev.errors)) if ok.any() else 0.0, span)
    if not (math.isfinite(magnify) and magnify > 0):
        raise ValueError(f"magnify must be a positive number, got {magnify!r}")
    shown = true[ok] + magnify * vec[ok]
    up_is_decreasing = False
    if fixture_map is not None and len(fixture_map.fixtures) and len(true):
        up_is_decreasing = fixture_map.positions[:, v].mean() < true[:, v].mean()
    views = ((a, b, "top view"), (a, v, "side view"), (b, v, "side view"))
    for ax, (i, j, name) in zip(axes, views, strict=True):
        _draw_points(ax, true[:, [i, j]], shown[:, [i, j]], ok)
        ax.set_xlabel(f"{AXES[i]} ({ev.units})")
        offsets = f"; orange offsets x{magnify:g}" if magnify != 1 and j == v else ""
        ax.set_ylabel(f"{AXES[j]} ({ev.units}{offsets})")
        ax.set_title(f"{name} ({AXES[i]}-{AXES[j]})", fontsize=10)
        ax.grid(True, alpha=0.3)
        ax.margins(0.08)
        if j == v and up_is_decreasing:
            ax.invert_yaxis()
        if name == "top view":
            ax.set_aspect("equal", adjustable="datalim")
    return magnify


def plot_positions(
    evaluation: Evaluation,
    path: str | Path,
    *,
    fixture_map: FixtureMap | None = None,
    magnify: float | None = None,
    dpi: int = 110,
) -> Path:
    """The thesis' figure 5.11: true (blue) and estimated (orange) positions, three views.

    Top view (the two floor axes) and both side views (each floor axis against the third,
    vertical axis); a grey line joins each true position to its estimate.

    Parameters
    ----------
    evaluation : Evaluation
    path : str or Path
        The PNG to write.
    fixture_map : FixtureMap, optional
        When given, the vertical axis is drawn with the fixtures' side up (for the thesis'
        room, whose ``y`` points down, the axis is inverted).
    magnify : float, optional
        Draw each estimate at ``true + magnify * (estimate - true)``, so that millimetre
        errors show on a metre-wide survey; the factor is in the title.  Default: a 1-2-5
        factor that draws the largest error as about 5 % of the survey's span (1 when the
        errors are already that large).
    dpi : int

    Returns
    -------
    Path
        ``path``.
    """
    fig = new_figure(13.5, 4.6, dpi=100)
    axes = fig.subplots(1, 3)
    magnify = draw_positions(axes, evaluation, fixture_map=fixture_map, magnify=magnify)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=9)
    title = "True (blue) and estimated (orange) camera positions"
    if magnify != 1:
        title += (
            f"; differences magnified {magnify:g}x: estimates drawn at "
            f"true + {magnify:g} x (estimate - true)"
        )
    fig.suptitle(title, fontsize=11)
    p = Path(path)
    fig.savefig(p, dpi=dpi)
    return p


def write_evaluation(
    evaluation: Evaluation,
    out_dir: str | Path,
    *,
    fixture_map: FixtureMap | None = None,
    magnify: float | None = None,
) -> dict[str, Path]:
    """Write ``results.csv``, ``summary.json``, ``error_map.png`` and ``positions.png``.

    The table by :func:`camvlp.io.writers.write_results_csv`, the figures by
    :func:`plot_error_map` and :func:`plot_positions`.

    Returns
    -------
    dict
        The written paths under the keys ``results``, ``summary``, ``error_map``,
        ``positions``.

    Raises
    ------
    InputError
        The folder cannot be created or written (naming it).
    """
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
        paths = {
            "results": write_results_csv(evaluation, out / "results.csv"),
            "summary": write_json(out / "summary.json", evaluation.summary()),
        }
        paths["error_map"] = plot_error_map(evaluation, out / "error_map.png")
        paths["positions"] = plot_positions(
            evaluation, out / "positions.png", fixture_map=fixture_map, magnify=magnify
        )
    except OSError as exc:
        raise InputError(f"cannot write the results: {exc.strerror or exc}", out) from None
    return paths
