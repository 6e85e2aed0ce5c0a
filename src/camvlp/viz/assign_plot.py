"""The plot of ``camvlp assign-ids``: where on the site the IDs tell a photo's view apart."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from camvlp.analysis.assign_ids import Assignment
from camvlp.analysis.study.site_views import up_basis
from camvlp.viz.figure import new_figure

__all__ = ["plot_assignment"]


def plot_assignment(
    report: Assignment, positions_m: np.ndarray, up: np.ndarray, path: str | Path, least: int = 3
) -> None:
    """Two maps of the site seen from above, the assigned IDs and a random assignment: the
    fixtures (grey), and each pose that sees ``least`` or more lights at its camera's place,
    green where its view is told apart, red where it is ambiguous.

    Parameters
    ----------
    report : Assignment
        The assignment and its views (:func:`~camvlp.analysis.assign_ids.assignment_report`).
    positions_m : ndarray, shape (N, 3)
        Fixture centres, metres.
    up : ndarray, shape (3,)
        The map's up (the maps are drawn on the plane across it).
    path : str or Path
        The PNG to write.
    least : int
        Poses seeing fewer lights are left out.
    """
    basis = up_basis(up)
    flat = np.asarray(positions_m, dtype=float) @ basis[:2].T
    cams = report.views.positions_m @ basis[:2].T
    counted = report.views.counts() >= least
    extent = np.ptp(flat, axis=0)
    width = 12.0
    height = max(3.0, min(10.0, 0.5 * width * extent[1] / max(extent[0], 1e-9) + 1.2))
    fig = new_figure(width, height)
    axes = fig.subplots(1, 2, sharex=True, sharey=True)
    n, share, share_random = report.shares(least)
    for ax, amb, what, s in (
        (axes[0], report.ambiguous, "assigned IDs", share),
        (axes[1], report.random_ambiguous, "random IDs", share_random),
    ):
        ax.scatter(flat[:, 0], flat[:, 1], s=4, c="0.6", marker="s", lw=0, label="fixtures")
        for mask, colour, label in (
            (counted & ~amb, "tab:green", "told apart"),
            (counted & amb, "tab:red", "ambiguous"),
        ):
            ax.scatter(cams[mask, 0], cams[mask, 1], s=6, c=colour, lw=0, label=label)
        ax.set_title(f"{what}: {100 * s:.1f} % of {n} views of {least}+ lights told apart")
        ax.set_aspect("equal")
        ax.set_xlabel("across the site, m")
    axes[0].set_ylabel("m")
    axes[0].legend(loc="upper right", fontsize=8, markerscale=2)
    fig.savefig(str(path))
