"""Running one of ``camvlp study``'s studies: within a budget of pose solves, with a progress
bar on a terminal, a bad value as a usage error (exit 2); then its files and its summary."""

from __future__ import annotations

import sys
from pathlib import Path

from ._app import fail
from .progress import progress_bar

__all__ = ["MAX_SOLVES", "finish_study", "run_study", "usage_errors"]


#: Pose solves from which a study shows a progress bar (a run of about a second or more).
PROGRESS_FROM_POSES = 5000


def finish_study(study, name: str, plot, out: Path | None, as_json: bool, lines: list[str]) -> None:
    """Write the files (with --out), then print the summary as JSON or as ``lines``."""
    from camvlp.io.atomic import StagedOutputs, check_output_dir, strict_json
    from camvlp.io.writers import write_outputs

    summary = study.summary()
    if out is not None:
        check_output_dir(out, "--out")
        with StagedOutputs() as outputs:  # the CSV, the figure and the summary: all or none
            summary = write_outputs(outputs.folder(out), name, study, plot)  # InputError: exit 2
        print(f"wrote {out}/{name}.csv, {name}.png, summary.json", file=sys.stderr)
    if as_json:
        print(strict_json(summary))
    else:
        for line in lines:
            print(line)


def usage_errors(func, *args, **kwargs):
    """``func(*args, **kwargs)``; a ValueError (bad value) becomes a usage error, exit 2."""
    try:
        return func(*args, **kwargs)
    except ValueError as exc:
        fail(str(exc))


#: Most pose solves one study may ask for (each keeps about 0.5 KB until the end: ~1 GB).
MAX_SOLVES = 2_000_000


def run_study(func, label: str, total_hint: float, *args, **kwargs):
    """Run a study function with a progress bar (long runs on a terminal) and :func:`usage_errors`;
    fail (exit 2) first when it would solve more than MAX_SOLVES poses (``total_hint``)."""
    if total_hint > MAX_SOLVES:
        fail(
            f"this study would solve {total_hint:,.0f} poses, over the budget of {MAX_SOLVES:,} "
            "(about 1 GB of memory); lower --trials, raise --step or --tilt-step, narrow the "
            "ranges or give fewer poses"
        )
    total_hint = int(total_hint)
    with progress_bar(None, label, show=total_hint >= PROGRESS_FROM_POSES) as update:
        return usage_errors(func, *args, progress=update, **kwargs)
