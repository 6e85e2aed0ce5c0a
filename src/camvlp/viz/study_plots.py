"""Plots of the error study: heat maps over the floor, error curves, error distributions.

Each ``draw_*`` function draws on a matplotlib ``Axes`` the caller gives (to compose its own
figure); each ``plot_*`` function makes a figure with :func:`~camvlp.viz.figure.new_figure`,
draws and writes the PNG.  matplotlib is imported only when a figure is made.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from camvlp.analysis.study import CoverageStudy, ForcedErrorStudy, MonteCarloStudy, RoundingStudy
from camvlp.format import format_vector, length_unit
from camvlp.viz.figure import new_figure

__all__ = [
    "draw_coverage",
    "draw_forced_error",
    "draw_heat_map",
    "draw_monte_carlo",
    "draw_rounding",
    "plot_coverage",
    "plot_forced_error",
    "plot_monte_carlo",
    "plot_rounding",
]


def _errors_unit(errors_m: np.ndarray) -> tuple[float, str]:
    """Factor from metres and unit name for an axis of these errors (m, cm or mm)."""
    big = np.nanmax(errors_m) if np.isfinite(errors_m).any() else 0.0
    return length_unit(float(big))


def draw_heat_map(
    ax, u, v, values, label: str, plane: str, cmap: str = "viridis", vmin=None, vmax=None
):
    """Draw ``values`` (NV, NU) over the floor grid ``u`` (NU,), ``v`` (NV,) metres, with a
    colour bar labelled ``label``; NaN cells are grey."""
    du = (u[1] - u[0]) if u.size > 1 else 0.1
    dv = (v[1] - v[0]) if v.size > 1 else 0.1
    ue = np.append(u - du / 2, u[-1] + du / 2)
    ve = np.append(v - dv / 2, v[-1] + dv / 2)
    masked = np.ma.masked_invalid(values)
    mesh = ax.pcolormesh(ue, ve, masked, cmap=cmap, shading="flat", vmin=vmin, vmax=vmax)
    ax.set_xlabel(f"Camera {plane[0]} (m)")
    ax.set_ylabel(f"Camera {plane[1]} (m)")
    ax.set_aspect("equal")
    ax.set_facecolor("0.85")
    ax.figure.colorbar(mesh, ax=ax, label=label)
    return mesh


def draw_rounding(ax, study: RoundingStudy) -> None:
    """Heat map of the position error over the floor (mm), like the thesis' figure 4.2."""
    draw_heat_map(
        ax, study.u_m, study.v_m, study.error_map_m * 1e3, "Position error (mm)", study.plane
    )
    noise = ""
    if study.noise_px or study.survey_error_m:
        noise = f", noise {study.noise_px:g} px / {study.survey_error_m:g} m"
    ax.set_title(
        f"θ = {format_vector(study.euler_deg)}°, height {study.height_m:g} m, "
        f"{study.solver}{noise}\n"
        f"mean = {study.mean_error_m * 1e3:.2f} mm, max = {study.max_error_m * 1e3:.2f} mm"
    )


def plot_rounding(study: RoundingStudy, path: str | Path) -> None:
    """Write :func:`draw_rounding` as a PNG."""
    fig = new_figure()
    draw_rounding(fig.add_subplot(), study)
    fig.savefig(path)


def draw_forced_error(ax, study: ForcedErrorStudy, label: str = "") -> None:
    """Position error against the forced error, one line per camera pose.

    ``label`` prefixes the title (e.g. ``"(a) "``).  What all poses share (position or
    orientation) goes in the title, what differs in the legend.
    """
    scale, unit = _errors_unit(study.errors_m)
    vary_pos = len({tuple(p) for p in study.positions_m.round(9)}) > 1
    vary_ang = len({tuple(a) for a in study.euler_deg.round(9)}) > 1
    for p, a, e in zip(study.positions_m, study.euler_deg, study.errors_m, strict=True):
        parts = []
        if vary_pos or not vary_ang:
            parts.append(f"C = {format_vector(p)} m")
        if vary_ang or not vary_pos:
            parts.append(f"θ = {format_vector(a)}°")
        ax.plot(study.offsets, e * scale, marker=".", ms=4, label=", ".join(parts))
    what = "image" if study.kind == "image" else "world"
    ax.set_xlabel(
        f"Forced error on fixture {study.fixture_id}'s {what} {study.axis} coordinate "
        f"({study.offset_unit})"
    )
    ax.set_ylabel(f"Position error ({unit})")
    common = []
    if not vary_pos:
        common.append(f"C = {format_vector(study.positions_m[0])} m")
    if not vary_ang:
        common.append(f"θ = {format_vector(study.euler_deg[0])}°")
    ax.set_title(
        f"{label}{what.capitalize()} {study.axis} coordinate, {study.solver}"
        + (f"\n{', '.join(common)}" if common else "")
    )
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")


def plot_forced_error(
    study: ForcedErrorStudy | Sequence[ForcedErrorStudy], path: str | Path, *, ncols: int = 2
) -> None:
    """Position error against the forced error, one line per camera pose.

    Parameters
    ----------
    study : ForcedErrorStudy or sequence of them
        One panel per study (panels labelled (a), (b), ... when there are several).
    path : str or Path
        PNG file to write.
    ncols : int
        Panels per row.
    """
    studies = [study] if isinstance(study, ForcedErrorStudy) else list(study)
    cols = min(ncols, len(studies))
    rows = -(-len(studies) // cols)
    fig = new_figure(6.4 * cols, 4.8 * rows)
    axes = np.atleast_1d(fig.subplots(rows, cols)).reshape(-1)
    for i, (ax, s) in enumerate(zip(axes, studies, strict=False)):
        draw_forced_error(ax, s, f"({chr(97 + i)}) " if len(studies) > 1 else "")
    for ax in axes[len(studies) :]:
        ax.set_visible(False)
    fig.savefig(path)


def draw_monte_carlo(ax, study: MonteCarloStudy) -> None:
    """Cumulative distribution of the position error, one line per pose."""
    scale, unit = _errors_unit(study.errors_m)
    for p, a, e in zip(study.positions_m, study.euler_deg, study.errors_m, strict=True):
        s = np.sort(e[np.isfinite(e)]) * scale
        frac = np.arange(1, s.size + 1) / e.size
        ax.step(s, frac, where="post", label=f"C = {format_vector(p)} m, θ = {format_vector(a)}°")
    ax.axhline(0.95, color="0.5", lw=0.8, ls="--", label="95 %")
    ax.set_xlabel(f"Position error ({unit})")
    ax.set_ylabel("Fraction of trials")
    ax.set_ylim(0, 1.02)
    ax.set_title(
        f"Monte Carlo: σ = {study.noise_px:g} px on image points, "
        f"{study.survey_error_m:g} m on world points\n"
        f"{study.errors_m.shape[1]} trials per pose, {study.solver}"
    )
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")


def plot_monte_carlo(study: MonteCarloStudy, path: str | Path) -> None:
    """Write :func:`draw_monte_carlo` as a PNG."""
    fig = new_figure()
    draw_monte_carlo(fig.add_subplot(), study)
    fig.savefig(path)


def _draw_fix_fraction(ax, study: CoverageStudy, fraction: np.ndarray, what: str, vmax) -> None:
    """One map of the fraction of orientations with a fix; ``what`` heads its title."""
    draw_heat_map(
        ax,
        study.u_m,
        study.v_m,
        fraction,
        "Fraction of orientations with a fix",
        study.plane,
        cmap="magma",
        vmin=0.0,
        vmax=vmax,
    )
    t = np.ptp(study.euler_deg[:, 0]) / 2
    ax.set_title(
        f"Fix possible: {what}\ntilts up to ±{t:g}° about x and y, camera height "
        f"{study.height_m:g} m\nmean {fraction.mean():.0%}"
    )


def draw_coverage(ax_fix, ax_error, study: CoverageStudy, ax_four=None) -> None:
    """Two maps: fraction of orientations with a fix, and the mean error where there is one.

    With gravity, ``ax_four`` (when given) gets a third: where four fixtures without gravity
    give a fix, on the same colour scale as ``ax_fix``.
    """
    four = study.gravity and ax_four is not None
    fractions = [study.fraction, study.fraction_four] if four else [study.fraction]
    vmax = max(float(f.max()) for f in fractions) if study.fix.any() else 1.0
    what = f"≥ {study.min_fixtures} fixtures in view and decodable"
    if study.ambiguous is not None:
        what = "the fixtures place it (IDs reused)"
    _draw_fix_fraction(ax_fix, study, study.fraction, what + (" + gravity" * study.gravity), vmax)
    if four:
        _draw_fix_fraction(ax_four, study, study.fraction_four, "≥ 4 fixtures, no gravity", vmax)
    draw_heat_map(
        ax_error,
        study.u_m,
        study.v_m,
        study.error_map_m * 1e3,
        "Mean position error (mm)",
        study.plane,
    )
    noise = f"σ = {study.noise_px:g} px detection noise"
    if study.gravity:
        noise += f", gravity σ = {study.gravity_sigma_deg:g}° per axis"
    ax_error.set_title(f"Mean position error where a fix is possible\n{noise}, {study.solver}")


def draw_fixtures_in_view(ax, study: CoverageStudy) -> None:
    """A map of the fixtures in view and decodable, the mean over the orientations."""
    draw_heat_map(
        ax,
        study.u_m,
        study.v_m,
        study.usable.mean(axis=-1),
        "Fixtures in view and decodable (mean)",
        study.plane,
        cmap="viridis",
        vmin=0.0,
    )
    t = np.ptp(study.euler_deg[:, 0]) / 2
    ax.set_title(
        f"Fixtures in view and decodable\ntilts up to ±{t:g}° about x and y, camera height "
        f"{study.height_m:g} m\nat most {int(study.usable.max())}"
    )


def plot_coverage(study: CoverageStudy, path: str | Path) -> None:
    """Write :func:`draw_coverage` as a PNG, the maps side by side (with gravity: the
    four-fixture map without gravity first, then the one with gravity, then the error); for
    a map whose IDs repeat, the fixtures in view first (:func:`draw_fixtures_in_view`)."""
    site = study.ambiguous is not None
    panels = 2 + int(study.gravity) + int(site)
    axes = list(new_figure(6.0 * panels, 5.0).subplots(1, panels))
    fig = axes[0].figure
    if site:
        draw_fixtures_in_view(axes.pop(0), study)
    if study.gravity:
        ax_four, ax_fix, ax_error = axes
        draw_coverage(ax_fix, ax_error, study, ax_four=ax_four)
    else:
        draw_coverage(*axes, study)
    fig.savefig(path)
