"""``camvlp assign-ids``: IDs for a site of more fixtures than its frame has IDs."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._app import app, fail, handle_errors, parse_floats


@app.command("assign-ids")
@handle_errors
def assign_ids_command(
    layout: Annotated[
        Path,
        typer.Argument(
            help="The site's map: fixtures' positions, diameters and normals (IDs, if any, "
            "are replaced), its frame format and up."
        ),
    ],
    camera_path: Annotated[
        Path, typer.Option("--camera", help="The camera the site will be used with.")
    ],
    out: Annotated[Path, typer.Option("--out", help="Write the map with its IDs here.")],
    floor: Annotated[
        float, typer.Option("--floor", help="The floor's height along the map's up (map units).")
    ] = 0.0,
    heights: Annotated[
        str, typer.Option("--heights", help="Camera heights above the floor, 'lo,hi' (m).")
    ] = "1.0,1.6",
    tilt: Annotated[
        float, typer.Option("--tilt", help="Largest tilt from looking straight up (degrees).")
    ] = 20.0,
    poses: Annotated[
        int, typer.Option("--poses", help="Poses drawn for the search of the IDs.")
    ] = 50_000,
    check_poses: Annotated[
        int,
        typer.Option("--check-poses", help="Poses drawn anew to measure the IDs on."),
    ] = 5_000,
    min_frames: Annotated[
        float,
        typer.Option("--min-frames", help="Frames of rows a disc must span to be decodable."),
    ] = 1.2,
    chip_rate: Annotated[
        float | None,
        typer.Option("--chip-rate", help="Chips per second (default: the map's, else 10 kHz)."),
    ] = None,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the poses and the search.")] = 1,
    plot: Annotated[
        Path | None, typer.Option("--plot", help="Write the map of told and ambiguous views.")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Give a site's fixtures IDs of its frame, reused, so that what a camera sees tells
    where it is: the IDs a photo decodes in the arrangement it shows them in, wherever it is
    held (any heading, tilts up to --tilt) and with any one light of four or more missing.

    Prints the share of views of three or more lights (and four or more) told apart, on
    poses drawn anew, against a random assignment; --plot draws where they are not.
    """
    import numpy as np

    from camvlp.analysis.assign_ids import assign_ids, assignment_report
    from camvlp.analysis.study.site_views import sample_views
    from camvlp.geometry.gravity.tilt import map_up
    from camvlp.io import load_camera, save_map
    from camvlp.io.layout import load_layout, with_ids

    lo, hi = parse_floats(heights, 2, "--heights")
    if not (0 <= lo <= hi):
        fail(f"--heights must be 'lo,hi' with 0 <= lo <= hi, got {heights}")
    if not (0 <= tilt < 90):
        fail(f"--tilt must be from 0 to 90 degrees, got {tilt}")
    if poses < 1 or check_poses < 1:
        fail("--poses and --check-poses must be at least 1")
    site = load_layout(layout)
    camera = load_camera(camera_path)
    normals = [f.normal if f.normal is not None else [np.nan] * 3 for f in site.fixtures]
    up = map_up(site.positions, up=site.up, normals=normals)
    pos = site.positions * site.unit_m
    diam = np.array([f.diameter or 0.0 for f in site.fixtures]) * site.unit_m
    if not np.all(diam > 0):
        fail(f"every fixture needs a diameter: a camera must see its disc whole ({layout})")
    rate = chip_rate or site.chip_rate_hz or 10_000.0
    rows = min_frames * site.frame.n_chips / (rate * (camera.row_time_s or 2e-5))
    draw = dict(floor_m=floor * site.unit_m, heights_m=(lo, hi), tilt_max_deg=tilt, min_rows=rows)
    rng = np.random.default_rng(seed)
    searched = sample_views(camera, pos, diam, up, n_poses=poses, rng=rng, **draw)
    ids = assign_ids(pos, up, site.frame.reversed_ids, searched, rng=rng)
    fresh = sample_views(camera, pos, diam, up, n_poses=check_poses, rng=rng, **draw)
    report = assignment_report(pos, up, ids, site.frame.n_ids, fresh, rng=rng)
    save_map(with_ids(site, ids), out)
    if plot is not None:
        from camvlp.viz.assign_plot import plot_assignment

        plot_assignment(report, pos, up, plot)
    _print_report(report, site, searched, out, plot, as_json)


def _print_report(report, site, searched, out: Path, plot: Path | None, as_json: bool) -> None:
    """The assignment's figures: as text, or one JSON object."""
    from camvlp.io.atomic import strict_json

    assigned_rev, random_rev = report.reversed_neighbours(site.frame.reversed_ids)
    summary = {
        "fixtures": len(site.fixtures),
        "ids": site.frame.n_ids,
        "poses_searched": len(searched.seen),
        "poses_checked": len(report.views.seen),
        "reversed_neighbours": {"assigned": assigned_rev, "random": random_rev},
        "map": str(out),
        "plot": None if plot is None else str(plot),
    }
    for least in (3, 4):
        n, share, share_random = report.shares(least)
        summary[f"views_{least}_or_more"] = {"views": n, "assigned": share, "random": share_random}
    if as_json:
        print(strict_json(summary))
        return
    print(f"site        {summary['fixtures']} fixtures, {summary['ids']} IDs of the frame")
    print(
        f"poses       {summary['poses_searched']} searched, {summary['poses_checked']} drawn "
        "anew to check"
    )
    for least in (3, 4):
        v = summary[f"views_{least}_or_more"]
        print(
            f"told apart  views of {least}+ lights ({v['views']}): assigned "
            f"{100 * v['assigned']:.1f} %, random {100 * v['random']:.1f} %"
        )
    r = summary["reversed_neighbours"]
    print(f"reversals   pairs seen together: assigned {r['assigned']}, random {r['random']}")
    print(f"wrote       {out}" + (f", {plot}" if plot else ""))
