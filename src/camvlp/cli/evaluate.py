"""``camvlp evaluate``: locate a survey of photos with known positions and report the errors."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from ._app import (
    GravitySigmaOption,
    MaxSigmaOption,
    OutlierOption,
    SolverOption,
    app,
    cap_jobs,
    check_positive,
    check_solver,
    fail,
    handle_errors,
)
from .progress import progress_bar

if TYPE_CHECKING:
    from camvlp.analysis.evaluate import Evaluation
    from camvlp.io.survey_csv import Survey
    from camvlp.model.camera import Camera
    from camvlp.model.fixtures import FixtureMap
    from camvlp.pipeline.locate import LocateSettings


@app.command("evaluate")
@handle_errors
def evaluate_command(
    survey_path: Annotated[
        Path,
        typer.Argument(
            metavar="SURVEY", help="Survey CSV: photo,x,y,z (photo paths relative to it)."
        ),
    ],
    camera_path: Annotated[Path, typer.Option("--camera", "-c", help="Camera file (YAML/JSON).")],
    map_path: Annotated[
        Path, typer.Option("--map", "-m", help="Map file of the room (YAML/JSON).")
    ],
    out: Annotated[
        Path,
        typer.Option(
            "--out", "-o", metavar="OUT", help="Folder for results.csv, summary.json, plots."
        ),
    ],
    jobs: Annotated[
        int | None, typer.Option("--jobs", "-j", help="Worker processes (default: all cores).")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print the summary as JSON.")] = False,
    solver: SolverOption = "iterative",
    outlier_px: OutlierOption = None,
    max_sigma: MaxSigmaOption = None,
    magnify: Annotated[
        float | None,
        typer.Option(
            help="Draw estimates in positions.png at true + X * (estimate - true) "
            "(default: automatic, 1 for large errors)."
        ),
    ] = None,
    gravity_sigma_deg: GravitySigmaOption = None,
) -> None:
    """Locate every photo of SURVEY and compare with the true positions.

    Writes into the folder OUT:

    - results.csv, one row per photo;
    - summary.json, the figures;
    - error_map.png, the error over the floor;
    - positions.png, the true and estimated positions.

    Photos that cannot be read or located are counted and listed; the run goes on. A photo
    with a sidecar PHOTO.json giving gravity is located with it (two fixtures are enough).

    Exit code 0 when the run completed (even with failures), 2 on bad input.
    """
    from camvlp.analysis.evaluate import read_survey
    from camvlp.io import load_camera, load_map
    from camvlp.io.atomic import StagedOutputs, check_output_dir, strict_json
    from camvlp.pipeline.locate import LocateSettings
    from camvlp.sim.survey import default_jobs
    from camvlp.viz.evaluate_plots import write_evaluation

    check_solver(solver)
    check_positive(outlier_px, "--outlier-px")
    check_positive(max_sigma, "--max-sigma")
    check_positive(gravity_sigma_deg, "--gravity-sigma-deg")
    jobs = cap_jobs(jobs)
    if magnify is not None and not magnify > 0:
        fail(f"--magnify must be a positive number, got {magnify}")
    check_output_dir(out, "--out")
    survey = read_survey(survey_path)
    camera = load_camera(camera_path)
    fixture_map = load_map(map_path)
    n_jobs = min(jobs or default_jobs(), len(survey))
    settings = LocateSettings(
        solver=solver,
        outlier_px=outlier_px,
        max_position_sigma=max_sigma,
        gravity_sigma_deg=1.0 if gravity_sigma_deg is None else gravity_sigma_deg,
    )
    evaluation = _run(survey, camera, fixture_map, settings, n_jobs)
    with StagedOutputs() as outputs:  # every result file or none
        staged = outputs.folder(out)
        try:
            written = write_evaluation(evaluation, staged, fixture_map=fixture_map, magnify=magnify)
        except ValueError as exc:
            fail(str(exc).replace(str(staged), str(out)))
    paths = {k: None if p is None else out / Path(p).name for k, p in written.items()}
    summary = evaluation.summary()
    if as_json:
        print(strict_json(summary))
    else:
        _print_human(evaluation, summary, paths)


def _run(
    survey: Survey, camera: Camera, fixture_map: FixtureMap, settings: LocateSettings, jobs: int
) -> Evaluation:
    """Evaluate with a progress bar on stderr (shown only on a terminal)."""
    from camvlp.analysis.evaluate import evaluate_survey

    with progress_bar(len(survey), "locating") as update:
        return evaluate_survey(survey, camera, fixture_map, settings, jobs=jobs, progress=update)


def _print_human(evaluation: Evaluation, s: dict, paths: dict) -> None:
    """The summary ``s`` as text: the photos located, the errors, the failures, the files."""
    from camvlp.analysis.evaluate import AXES
    from camvlp.format import mm_per_unit

    scale, unit = mm_per_unit(s["units"])

    def v(x) -> str:
        return "-" if x is None else f"{x * scale:.2f}"

    rate = "-" if s["success_rate"] is None else f"{100 * s['success_rate']:.1f} %"
    print(
        f"photos     {s['photos']}: {s['located']} located, {s['failed']} failed ({rate} located)"
    )
    print(
        f"time       {s['wall_time_s']:.1f} s with {s['jobs']} job{'s' if s['jobs'] != 1 else ''}"
    )
    print()
    print(f"error ({unit})    mean   median      p95      max")
    print(
        f"  position  {v(s['mean_error']):>7}  {v(s['median_error']):>7}  "
        f"{v(s['p95_error']):>7}  {v(s['max_error']):>7}"
    )
    for ax in AXES:
        st = s["abs_error_per_axis"][ax]
        print(
            f"  |{ax}|       {v(st['mean']):>7}  {v(st['median']):>7}  {v(st['p95']):>7}  "
            f"{v(st['max']):>7}"
        )
    if "angle_error_deg" in s:
        st = s["angle_error_deg"]

        def d(x) -> str:
            return "-" if x is None else f"{x:.3f}"

        print(
            f"  angle deg {d(st['mean']):>7}  {d(st['median']):>7}  {d(st['p95']):>7}  "
            f"{d(st['max']):>7}"
        )
    within = s["within_sigma"]
    if within["count"]:  # how well each photo's own position_sigma told its error
        shares = ", ".join(f"{k} sigma {100 * within[k]:.1f} %" for k in "123")
        print(f"  within    {shares} of {within['count']} coordinates (normal: 68, 95, 99.7)")
    if s["failures"]:
        print()
        print("failures")
        for f in s["failures"]:
            print(f"  {f['photo']}: {f['reason']}")
    print()
    print("wrote      " + ", ".join(str(p) for p in paths.values()))
