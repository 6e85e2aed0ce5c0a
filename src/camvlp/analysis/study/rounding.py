"""The rounding study: position error over a floor grid at one orientation (thesis fig. 4.2)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from camvlp.analysis.stats import error_stats
from camvlp.analysis.study.common import (
    Progress,
    mean_over_last_axis,
    position_errors,
    rotations,
    study_inputs,
)
from camvlp.io.writers import jsonable
from camvlp.model.camera import Camera
from camvlp.model.fixtures import FixtureMap
from camvlp.sim.grid import floor_grid

__all__ = ["RoundingStudy", "rounding_study"]


@dataclass(frozen=True)
class RoundingStudy:
    """Position error over a floor grid at one orientation (thesis figure 4.2).

    Attributes
    ----------
    solver : str
        PnP method.
    euler_deg : ndarray, shape (3,)
        Camera orientation, the thesis' angles in degrees.
    plane : str
        Floor axes, e.g. ``"xz"``.
    u_m, v_m : ndarray, shapes (NU,), (NV,)
        Grid values along the first and second floor axis, metres.
    height_m : float
        Camera height above the floor, metres.
    positions_m : ndarray, shape (NV, NU, 3)
        True camera centres, world frame, metres.
    errors_m : ndarray, shape (NV, NU, T)
        Distance from true to estimated centre per trial, metres; NaN where PnP failed.
    rounding : bool
        Image points rounded to whole pixels.
    noise_px, survey_error_m : float
        Gaussian noise (sigma) on image points (pixels) and world points (metres).
    seed : int
        Seed of the noise.
    """

    solver: str
    euler_deg: np.ndarray
    plane: str
    u_m: np.ndarray
    v_m: np.ndarray
    height_m: float
    positions_m: np.ndarray
    errors_m: np.ndarray
    rounding: bool
    noise_px: float
    survey_error_m: float
    seed: int

    @property
    def error_map_m(self) -> np.ndarray:
        """Mean error over trials at each grid point, shape (NV, NU), metres."""
        return mean_over_last_axis(self.errors_m)

    @property
    def mean_error_m(self) -> float:
        """Mean position error over all poses solved, metres."""
        return float(np.nanmean(self.errors_m))

    @property
    def max_error_m(self) -> float:
        """Largest position error, metres."""
        return float(np.nanmax(self.errors_m))

    def summary(self) -> dict:
        """JSON-ready summary (``mean_error_m``, ``max_error_m``, ``poses``, ...)."""
        return jsonable(
            {
                "study": "rounding",
                "solver": self.solver,
                "euler_deg": self.euler_deg,
                "plane": self.plane,
                "height_m": self.height_m,
                "grid": {
                    f"{self.plane[0]}_range_m": [self.u_m[0], self.u_m[-1]],
                    f"{self.plane[1]}_range_m": [self.v_m[0], self.v_m[-1]],
                    "points": int(self.u_m.size * self.v_m.size),
                    "step_m": round(float(self.u_m[1] - self.u_m[0]), 9)
                    if self.u_m.size > 1
                    else None,
                },
                "rounding": self.rounding,
                "noise_px": self.noise_px,
                "survey_error_m": self.survey_error_m,
                "trials": int(self.errors_m.shape[-1]),
                "seed": self.seed,
                **error_stats(self.errors_m),
            }
        )

    def rows(self) -> list[list]:
        """CSV rows: position (m), mean error (m), trials solved."""
        pos = self.positions_m.reshape(-1, 3)
        em = self.error_map_m.reshape(-1)
        solved = np.isfinite(self.errors_m).sum(-1).reshape(-1)
        return [[*p, e, int(s)] for p, e, s in zip(pos, em, solved, strict=True)]

    csv_header = ("x_m", "y_m", "z_m", "error_m", "trials_solved")


def rounding_study(
    camera: Camera,
    fixture_map: FixtureMap,
    *,
    euler_deg: Sequence[float] = (90.0, 0.0, 0.0),
    plane: str = "xz",
    u_range_m: Sequence[float] = (-1.0, 1.0),
    v_range_m: Sequence[float] = (-1.0, 1.0),
    step_m: float = 0.1,
    height_m: float = 0.0,
    solver: str = "iterative",
    rounding: bool = True,
    noise_px: float = 0.0,
    survey_error_m: float = 0.0,
    trials: int = 1,
    seed: int = 0,
    progress: Progress | None = None,
) -> RoundingStudy:
    """Camera position error over a grid on the floor at a fixed orientation.

    The thesis' figure 4.2: fixtures' centres projected (infinite image plane), rounded to
    whole pixels, PnP; the error is the distance between true and estimated camera centres.

    Parameters
    ----------
    camera : Camera
        Intrinsics (the image size does not limit the view here).
    fixture_map : FixtureMap
        At least four fixtures; any length unit.
    euler_deg : (3,)
        Camera orientation, the thesis' angles (degrees); (90, 0, 0) faces the ceiling.
    plane, u_range_m, v_range_m, step_m, height_m
        The floor grid, see :func:`floor_grid`.
    solver : str
        PnP method, a key of :data:`camvlp.geometry.pnp.SOLVERS`.
    rounding : bool
        Round image points to whole pixels.
    noise_px, survey_error_m : float
        Gaussian noise sigma on every image point (pixels, after rounding) and on every
        world point given to the solver (metres).  With either, ``trials`` draws per point.
    trials : int
        Monte Carlo trials per grid point (1 without noise).
    seed : int
        Seed of the noise.
    progress : callable, optional
        ``progress(done, total)``, in poses.

    Returns
    -------
    RoundingStudy
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
    e, r = rotations(euler_deg)
    u, v, pos = floor_grid(
        inp.fixtures_m,
        plane=plane,
        u_range_m=u_range_m,
        v_range_m=v_range_m,
        step_m=step_m,
        height_m=height_m,
    )
    c = np.repeat(pos.reshape(-1, 3), inp.trials, axis=0)
    err = position_errors(
        camera, inp, np.broadcast_to(r[0], (c.shape[0], 3, 3)), c, progress=progress
    )
    return RoundingStudy(
        solver,
        e[0],
        plane,
        u,
        v,
        float(height_m),
        pos,
        err.reshape(v.size, u.size, inp.trials),
        inp.rounding,
        inp.noise_px,
        inp.survey_error_m,
        int(seed),
    )
