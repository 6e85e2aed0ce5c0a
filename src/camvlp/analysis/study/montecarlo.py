"""The Monte Carlo study: Gaussian noise on every fixture's image and world point."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camvlp.analysis.stats import error_stats
from camvlp.analysis.study.common import (
    POSE_COLUMNS,
    Progress,
    pose_rows,
    poses,
    position_errors,
    rotations,
    study_inputs,
)
from camvlp.io.writers import jsonable
from camvlp.model.camera import Camera
from camvlp.model.fixtures import FixtureMap

__all__ = ["MonteCarloStudy", "monte_carlo_study"]


@dataclass(frozen=True)
class MonteCarloStudy:
    """Position error under Gaussian noise on every fixture, many trials per pose.

    Attributes
    ----------
    positions_m : ndarray, shape (P, 3)
        True camera centres, metres.
    euler_deg : ndarray, shape (P, 3)
        Orientations, degrees.
    errors_m : ndarray, shape (P, T)
        Position error per trial, metres; NaN where PnP failed.
    noise_px : float
        Sigma of the noise on each image coordinate, pixels.
    survey_error_m : float
        Sigma of the noise on each world coordinate given to the solver, metres.
    seed : int
    solver : str
    rounding : bool
    """

    positions_m: np.ndarray
    euler_deg: np.ndarray
    errors_m: np.ndarray
    noise_px: float
    survey_error_m: float
    seed: int
    solver: str
    rounding: bool

    def summary(self) -> dict:
        """JSON-ready summary: overall and per-pose mean, median, 95th percentile, max."""
        per_pose = [
            {"position_m": p, "euler_deg": a, **error_stats(e)}
            for p, a, e in zip(self.positions_m, self.euler_deg, self.errors_m, strict=True)
        ]
        return jsonable(
            {
                "study": "monte-carlo",
                "solver": self.solver,
                "noise_px": self.noise_px,
                "survey_error_m": self.survey_error_m,
                "trials": int(self.errors_m.shape[1]),
                "seed": self.seed,
                "rounding": self.rounding,
                **error_stats(self.errors_m),
                "per_pose": per_pose,
            }
        )

    csv_header = (*POSE_COLUMNS, "trial", "error_m")

    def rows(self) -> list[list]:
        """CSV rows: pose index, position (m), angles (deg), trial, error (m)."""
        trials = range(self.errors_m.shape[1])
        return pose_rows(self.positions_m, self.euler_deg, self.errors_m, trials)


def monte_carlo_study(
    camera: Camera,
    fixture_map: FixtureMap,
    *,
    positions_m,
    euler_deg,
    noise_px: float = 0.0,
    survey_error_m: float = 0.0,
    trials: int = 1000,
    seed: int = 0,
    solver: str = "iterative",
    rounding: bool = True,
    progress: Progress | None = None,
) -> MonteCarloStudy:
    """Position error statistics with Gaussian noise on all fixtures' image and world points.

    Parameters
    ----------
    camera : Camera
    fixture_map : FixtureMap
    positions_m, euler_deg : array_like, shape (P, 3) or (3,)
        Camera poses (metres, degrees); one of the two may be given once.
    noise_px : float
        Sigma on each image coordinate (pixels), added after rounding.
    survey_error_m : float
        Sigma on each world coordinate given to the solver (metres).
    trials : int
        Draws per pose.
    seed : int
    solver : str
    rounding : bool
    progress : callable, optional

    Returns
    -------
    MonteCarloStudy
    """
    inp = study_inputs(
        fixture_map,
        solver=solver,
        rounding=rounding,
        noise_px=noise_px,
        survey_error_m=survey_error_m,
        trials=trials,
        seed=seed,
    )
    c, e = poses(positions_m, euler_deg)
    _, r = rotations(e)
    rr, cc = np.repeat(r, inp.trials, axis=0), np.repeat(c, inp.trials, axis=0)
    err = position_errors(camera, inp, rr, cc, progress=progress)
    return MonteCarloStudy(
        c,
        e,
        err.reshape(c.shape[0], inp.trials),
        inp.noise_px,
        inp.survey_error_m,
        int(seed),
        solver,
        inp.rounding,
    )
