"""Pictures of a locate run: the annotated photo and one debug picture per stage."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from camvlp.model.camera import Camera
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.decode.beacon import square_wave
from camvlp.pipeline.decode.runs import find_runs, stripe_threshold
from camvlp.viz.figure import new_figure

__all__ = ["annotate", "write_debug_pictures"]

_GREEN, _RED, _CYAN, _YELLOW, _WHITE = (
    (60, 220, 60),
    (60, 60, 255),
    (255, 220, 0),
    (0, 220, 255),
    (255, 255, 255),
)


def annotate(image: np.ndarray, result, camera: Camera, fixture_map: FixtureMap) -> np.ndarray:
    """Draw a locate result on a copy of the photo.

    Green discs are fixtures used for the pose, red ones are not (with their reason); cyan
    crosses are the map's fixtures reprojected with the found pose; the position is written
    in the top-left corner.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3) or (H, W)
        The photo as given to :func:`camvlp.locate`.
    result : LocateResult
    camera : Camera
    fixture_map : FixtureMap

    Returns
    -------
    ndarray of uint8, shape (H, W, 3)
        BGR picture.
    """
    out = image.copy()
    if out.ndim == 2:
        out = cv2.cvtColor(out, cv2.COLOR_GRAY2BGR)
    if out.dtype != np.uint8:
        out = (out >> 8).astype(np.uint8) if out.dtype == np.uint16 else out.astype(np.uint8)
    h, w = out.shape[:2]
    scale = max(1.0, max(h, w) / 1500.0)
    for f in result.fixtures:
        _draw_fixture(out, f, scale)
    if result.pose is not None:
        _draw_map_fixtures(out, result, camera, fixture_map, scale)
        x, y, z = result.position
        lines = [
            f"position ({x:.3f}, {y:.3f}, {z:.3f}) {fixture_map.units}",
            "angles ({:.1f}, {:.1f}, {:.1f}) deg".format(*result.euler_deg),
            f"reprojection {result.reprojection_rms_px:.2f} px RMS",
        ]
    else:
        lines = [f"not located: {result.reason}"]
    y0 = int(40 * scale)
    for i, text in enumerate(lines):
        org = (int(20 * scale), y0 + int(i * 34 * scale))
        _text(out, text, org, 0.72 * scale, (0, 0, 0), _thickness(scale) + 3)
        _text(out, text, org, 0.72 * scale, _YELLOW, _thickness(scale))
    return out


def _thickness(scale: float) -> int:
    return max(1, round(2 * scale))


def _text(out: np.ndarray, text: str, org, size: float, colour, thick: int) -> None:
    cv2.putText(out, text, org, cv2.FONT_HERSHEY_SIMPLEX, size, colour, thick, cv2.LINE_AA)


def _draw_fixture(out: np.ndarray, f, scale: float) -> None:
    """A fixture's disc, green when used and red when not, labelled with its ID (and reason)."""
    w = out.shape[1]
    thick, font = _thickness(scale), 0.6 * scale
    colour = _GREEN if f.used else _RED
    u, v = (round(c) for c in f.pixel)
    radius = round(0.5 * f.rows_spanned) if np.isfinite(f.rows_spanned) else 20
    cv2.circle(out, (u, v), max(radius, 6), colour, thick, cv2.LINE_AA)
    label = f"ID {f.id}" if f.id is not None else "?"
    if not f.used and f.reason:
        label += f": {f.reason[:48]}"
    (tw, _), _ = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, font, thick)
    x = u + max(radius, 6) + 4
    if x + tw > w:  # no room on the right: write it on the left of the disc
        x = max(0, u - max(radius, 6) - 4 - tw)
    _text(out, label, (x, v), font, colour, thick)


def _draw_map_fixtures(out: np.ndarray, result, camera: Camera, fixture_map, scale: float) -> None:
    """The map's fixtures reprojected with the found pose: cyan crosses with their IDs."""
    thick = _thickness(scale)
    uv = camera.project(result.pose, fixture_map.positions)
    if result.mirrored:
        uv[:, 0] = out.shape[1] - 1 - uv[:, 0]
    for (u, v), fid in zip(uv, fixture_map.ids, strict=True):
        if not (np.isfinite(u) and np.isfinite(v)):
            continue
        p = (round(u), round(v))
        cv2.drawMarker(out, p, _CYAN, cv2.MARKER_CROSS, int(24 * scale), thick, cv2.LINE_AA)
        _text(out, str(fid), (p[0] + 6, p[1] + int(28 * scale)), 0.48 * scale, _CYAN, thick)


def write_debug_pictures(out_dir: str | Path, image: np.ndarray, result, stages) -> list[Path]:
    """Write one picture per stage into ``out_dir``.

    * ``1_candidates.png``: the reduced image's closed candidate mask;
    * ``2_fixture_<k>.png``: each fixture's region of interest beside its disc mask;
    * ``3_profiles.png``: each fixture's row profile, threshold and chips read;
    * ``4_beacons.png`` (frequency-coded maps): each light's waveform per line, the square
      wave of the map frequency that fits it best and of the next one, with how much of the
      stripes each explains, and why a light was refused.

    Returns the paths written.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    p = out / "1_candidates.png"
    cv2.imwrite(str(p), stages.detection.candidate_mask)
    written.append(p)
    blobs = stages.detection.blobs
    for k, (b, g) in enumerate(zip(blobs, stages.gray_rois, strict=True)):
        m = b.mask.astype(np.uint8) * 255
        pair = np.hstack([g, np.full((g.shape[0], 4), 128, np.uint8), m])
        p = out / f"2_fixture_{k}.png"
        cv2.imwrite(str(p), pair)
        written.append(p)
    if blobs:
        fig = new_figure(10, 2.2 * len(blobs), dpi=100, layout=None)
        axes = fig.subplots(len(blobs), 1, squeeze=False)
        for k, (prof, dec, fr) in enumerate(
            zip(stages.profiles, stages.decodes, result.fixtures, strict=True)
        ):
            ax = axes[k, 0]
            ax.plot(prof, ".-", lw=0.8, ms=2, color="0.2")
            fitted = getattr(dec, "fitted", None)
            if fitted is not None:  # the model fit of the best ID
                ax.plot(fitted, lw=1.0, color="tab:orange", label="model of the best ID")
            elif prof.size >= 8:
                runs = find_runs(prof, stripe_threshold(prof))
                ax.axhline(runs.threshold, color="tab:orange", lw=0.8, label="threshold")
                for e in runs.edges:
                    ax.axvline(e, color="tab:blue", lw=0.4, alpha=0.5)
            title = f"fixture {k} at ({fr.pixel[0]:.0f}, {fr.pixel[1]:.0f}): "
            title += f"ID {dec.id}" if dec.id is not None else f"no ID ({dec.reason})"
            if np.isfinite(dec.rows_per_chip):
                title += f", {dec.rows_per_chip:.2f} rows/chip"
            if np.isfinite(dec.bleed_rows):
                title += f", bleed {dec.bleed_rows:.2f} rows"
            if fitted is not None:
                title += f", margin {dec.margin:.1f}"
            ax.set_title(title, fontsize=9, loc="left")
            ax.text(
                0.0,
                -0.42,
                f"chips {dec.chips}",
                transform=ax.transAxes,
                fontsize=7,
                family="monospace",
            )
            ax.set_ylabel("mean gray")
        axes[-1, 0].set_xlabel(f"sensor row across the disc ({result.readout} readout)")
        fig.tight_layout()
        p = out / "3_profiles.png"
        fig.savefig(p, dpi=110)
        written.append(p)
    if getattr(stages, "beacons", ()):
        p = out / "4_beacons.png"
        draw_beacons(stages.beacons, result, p)
        written.append(p)
    return written


def draw_beacons(beacons, result, path: str | Path) -> Path:
    """The frequency-coded lights' fits (:attr:`LocateStages.beacons`), one panel a light:
    its waveform per line (black; clipped lines as red ticks, where it reached at least that
    level), the square wave of the map frequency that explains it best (orange) and of the
    next one (blue, dashed), each over the envelopes fitted with it, and in the title what
    was decided: the ID, or why none."""
    n = len(beacons)
    fig = new_figure(10, 2.3 * n, dpi=100, layout=None)
    axes = fig.subplots(n, 1, squeeze=False)
    for k, ((profile, test, periods), fr) in enumerate(zip(beacons, result.fixtures, strict=True)):
        ax = axes[k, 0]
        title = f"light {k} at ({fr.pixel[0]:.0f}, {fr.pixel[1]:.0f}): "
        title += f"ID {fr.id}" if fr.id is not None else f"no ID ({fr.reason})"
        if not profile.usable:
            ax.set_title(title, fontsize=8, loc="left")
            continue
        ax.plot(profile.lines, profile.level, ".", ms=2.5, color="0.15", label="waveform")
        if profile.bound_lines.size:
            ax.plot(
                profile.bound_lines, profile.bounds, "|", color="tab:red", ms=6, label="clipped"
            )
        if test is not None:
            ranked = [j for j in np.argsort(test.costs) if test.waves[j] is not None][:2]
            for j, style in zip(ranked, (("tab:orange", "-"), ("tab:blue", "--")), strict=False):
                a, b = profile.envelopes(test.waves[j])
                fitted = a + b * square_wave(profile.lines, *test.waves[j])
                hz = fr.frequency_hz * test.period_px / periods[j]  # the map's frequency
                steady = profile.steady_cost
                share = 1.0 - test.costs[j] / steady if steady > 0 else 0.0
                ax.plot(
                    profile.lines,
                    fitted,
                    style[1],
                    color=style[0],
                    lw=1.0,
                    label=f"{hz:.0f} Hz (the map's): explains {100 * share:.0f} %",
                )
            title += (
                f"; margin {test.log_ratio:.1f}, {test.periods_seen:.1f} periods, "
                f"{100 * test.agreement:.0f} % of lines agree"
            )
        ax.set_title(title, fontsize=8, loc="left")
        ax.legend(fontsize=6, loc="upper right")
        ax.set_ylabel("level (scaled)")
    axes[-1, 0].set_xlabel(f"sensor line across the light ({result.readout} readout)")
    fig.tight_layout()
    p = Path(path)
    fig.savefig(p, dpi=110)
    return p
