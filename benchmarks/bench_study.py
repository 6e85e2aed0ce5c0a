"""Poses per second of the error study, per PnP solver, on one core.

Usage::

    python benchmarks/bench_study.py [--poses 20000] [--repeats 5]

Two figures per solver, each the median of ``--repeats`` runs:

* ``solve``: :func:`camvlp.geometry.pnp.solve_pnp_batch` alone (one ``cv2.solvePnP`` per pose);
* ``study``: the whole pipeline of :func:`camvlp.analysis.study.rounding_study` (vectorised
  projection, rounding, solve, error), on the thesis' camera and room.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import cv2
import numpy as np

from camvlp.analysis.study import round_pixels, rounding_study
from camvlp.geometry.pnp import SOLVERS, solve_pnp_batch
from camvlp.geometry.projection import project_batch
from camvlp.io import load_camera, load_map
from camvlp.model.camera import euler_to_matrix

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=20_000, help="poses per run")
    parser.add_argument("--repeats", type=int, default=5, help="runs per figure (median)")
    args = parser.parse_args()
    cv2.setNumThreads(1)

    cam = load_camera(EXAMPLES / "thesis_camera.yaml")
    room = load_map(EXAMPLES / "thesis_room.yaml")
    pts = room.positions * room.unit_m
    rng = np.random.default_rng(0)
    n = args.poses
    c = np.column_stack([rng.uniform(-1, 1, n), np.zeros(n), rng.uniform(-1, 1, n)])
    eul = np.column_stack(
        [90 + rng.uniform(-20, 20, n), rng.uniform(-20, 20, n), rng.uniform(-180, 180, n)]
    )
    r = np.stack([euler_to_matrix(e) for e in eul])
    uv = round_pixels(project_batch(cam, r, c, pts))
    # the study pipeline: a floor grid with as many points as --poses (square grid)
    side = max(2, round(np.sqrt(n)))
    step = 2.0 / (side - 1)
    grid_poses = side * side

    print(
        f"OpenCV {cv2.__version__}, {n} poses per solve run, {grid_poses} per study run, "
        f"median of {args.repeats}"
    )
    print(f"{'solver':<10} {'solve (poses/s)':>16} {'study (poses/s)':>16}")
    for solver in SOLVERS:
        solve_t, study_t = [], []
        for _ in range(args.repeats):
            t = time.perf_counter()
            solve_pnp_batch(pts, uv, cam, solver)
            solve_t.append(time.perf_counter() - t)
            t = time.perf_counter()
            rounding_study(cam, room, euler_deg=(70, 20, 0), step_m=step, solver=solver)
            study_t.append(time.perf_counter() - t)
        print(
            f"{solver:<10} {n / statistics.median(solve_t):>16,.0f} "
            f"{grid_poses / statistics.median(study_t):>16,.0f}"
        )


if __name__ == "__main__":
    main()
