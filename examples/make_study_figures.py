"""Regenerate the figures and tables of the error study (the documentation's "Error study").

Run from the repository root::

    python examples/make_study_figures.py [--out out/study]

Writes the PNGs into ``--out`` and prints the tables (Markdown) on stdout.  The
documentation's figures are this script's output with ``--out docs/study``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from camvlp.analysis.study import (
    axis_values,
    coverage_study,
    forced_error_study,
    monte_carlo_study,
    rounding_study,
)
from camvlp.geometry.pnp import SOLVERS
from camvlp.io import load_camera, load_map
from camvlp.viz.study_plots import plot_coverage, plot_forced_error, plot_rounding

ROOT = Path(__file__).resolve().parents[1]
THESIS_MM = {(90, 0, 0): 1.1, (90, 20, 0): 1.4, (70, 0, 0): 1.5, (70, 20, 0): 1.6}
FIG_4_3 = dict(positions_m=[(x, 0, 0) for x in (-1, -0.5, 0, 0.5, 1)], euler_deg=(90, 0, 0))
ANGLES = [(a, 0, 0) for a in (80, 85, 90, 95)]
FIG_4_4 = dict(positions_m=(0, 0, 0), euler_deg=ANGLES)
FIG_4_5 = dict(positions_m=(0, -1, 0), euler_deg=ANGLES)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "study", help="folder of the PNGs")
    out = ap.parse_args().out
    out.mkdir(parents=True, exist_ok=True)
    cam = load_camera(ROOT / "examples" / "thesis_camera.yaml")
    room = load_map(ROOT / "examples" / "thesis_room.yaml")

    print("| θ (deg) | thesis | " + " | ".join(SOLVERS) + " |")
    print("|---|---|" + "---|" * len(SOLVERS))
    for euler, thesis in THESIS_MM.items():
        cells = []
        for solver in SOLVERS:
            res = rounding_study(cam, room, euler_deg=euler, solver=solver)
            cells.append(f"{res.mean_error_m * 1e3:.2f} (max {res.max_error_m * 1e3:.1f})")
            if solver == "iterative":
                plot_rounding(res, out / f"rounding_{'_'.join(map(str, euler))}.png")
        print(f"| {euler} | {thesis} | " + " | ".join(cells) + " |")

    px = axis_values((-20, 20), 1.0)
    m = axis_values((-1, 1), 0.05)
    panels = {
        "fig4_3": (
            FIG_4_3,
            [("image", "x", px), ("image", "y", px), ("world", "x", m), ("world", "z", m)],
        ),
        "fig4_4": (
            FIG_4_4,
            [("image", "x", px), ("image", "y", px), ("world", "x", m), ("world", "z", m)],
        ),
        "fig4_5": (FIG_4_5, [("image", "y", px), ("world", "z", m)]),
    }
    print("\n| figure | forced error | at -max | at -half | at +half | at +max |")
    print("|---|---|---|---|---|---|")
    for name, (poses, specs) in panels.items():
        studies = []
        for kind, axis, offsets in specs:
            s = forced_error_study(
                cam, room, kind=kind, axis=axis, offsets=offsets, fixture_id=5, **poses
            )
            studies.append(s)
            k = offsets.size
            cols = [0, k // 4, k - 1 - k // 4, k - 1]
            mean = np.nanmean(s.errors_m[:, cols], axis=0)
            unit = s.offset_unit
            cells = " | ".join(
                f"{mean[i] * (100 if kind == 'image' else 1):.2f} "
                f"{'cm' if kind == 'image' else 'm'} ({offsets[c]:g} {unit})"
                for i, c in enumerate(cols)
            )
            print(f"| {name} | {kind} {axis} | {cells} |")
        plot_forced_error(studies, out / f"{name}.png")

    print(
        "\n| camera height | tilts | fix possible (mean over floor and tilts) "
        "| floor with some fix | mean / 95 % error (0.5 px noise) |"
    )
    print("|---|---|---|---|---|")
    for h, tilt in ((0.0, 15.0), (1.0, 6.0)):
        cov = coverage_study(
            cam, room, height_m=h, tilt_max_deg=tilt, tilt_step_deg=tilt / 6, seed=0
        )
        s = cov.summary()
        print(
            f"| {h:g} m | ±{tilt:g}° | {s['mean_fix_fraction']:.0%} | "
            f"{s['floor_fraction_any_fix']:.0%} | "
            f"{s['mean_error_m'] * 1e3:.1f} / {s['p95_error_m'] * 1e3:.1f} mm |"
        )
        plot_coverage(cov, out / f"coverage_{int(h)}m.png")

    print("\n| noise | camera | mean | median | 95 % |")
    print("|---|---|---|---|---|")
    for label, kw in (
        ("0.5 px on every image point", dict(noise_px=0.5)),
        ("1 cm on every map position", dict(survey_error_m=0.01)),
        ("5 cm on every map position", dict(survey_error_m=0.05)),
    ):
        for where, poses in (("floor", FIG_4_4), ("1 m up", FIG_4_5)):
            s = monte_carlo_study(cam, room, trials=2000, seed=0, **poses, **kw).summary()
            print(
                f"| {label} | {where} | {s['mean_error_m'] * 100:.2f} cm | "
                f"{s['median_error_m'] * 100:.2f} cm | {s['p95_error_m'] * 100:.2f} cm |"
            )


if __name__ == "__main__":
    main()
