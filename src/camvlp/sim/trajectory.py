"""A camera's path: poses at increasing times, and the CSV files that hold one.

A trajectory CSV has the columns ``t,x,y,z,theta_x,theta_y,theta_z``: times (s), camera
centres (map units) and the thesis' angles (degrees).  ``camvlp render-video`` renders a video
along one (:mod:`camvlp.sim.video`), and writes the true one beside it.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camvlp.errors import InputError
from camvlp.io.files import MAX_MAGNITUDE
from camvlp.io.textfiles import read_text_file
from camvlp.model.camera import Pose

__all__ = ["TRAJECTORY_COLUMNS", "Trajectory", "load_trajectory", "save_trajectory"]

#: Columns of a trajectory CSV.
TRAJECTORY_COLUMNS = ("t", "x", "y", "z", "theta_x", "theta_y", "theta_z")


@dataclass(frozen=True)
class Trajectory:
    """A camera's path: poses at increasing times, interpolated linearly in between.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Times, s, strictly increasing.
    position : ndarray, shape (N, 3)
        Camera centres, map units.
    euler_deg : ndarray, shape (N, 3)
        The thesis' angles ``(theta_x, theta_y, theta_z)``, degrees (unwrapped, so that
        interpolation never goes the long way round).
    """

    t: np.ndarray
    position: np.ndarray
    euler_deg: np.ndarray

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=float).reshape(-1)
        p = np.asarray(self.position, dtype=float).reshape(-1, 3)
        e = np.asarray(self.euler_deg, dtype=float).reshape(-1, 3)
        if t.size < 2 or p.shape[0] != t.size or e.shape[0] != t.size:
            raise ValueError("a trajectory needs at least two poses, one per time")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(p)) and np.all(np.isfinite(e))):
            raise ValueError("a trajectory's times and poses must be finite numbers")
        if np.any(np.diff(t) <= 0):
            raise ValueError("a trajectory's times must be strictly increasing")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "position", p)
        object.__setattr__(self, "euler_deg", np.rad2deg(np.unwrap(np.deg2rad(e), axis=0)))

    @property
    def duration_s(self) -> float:
        """Time from the first pose to the last, s."""
        return float(self.t[-1] - self.t[0])

    def sample(self, times) -> tuple[np.ndarray, np.ndarray]:
        """Positions (M, 3) and angles (M, 3, degrees) at ``times`` (M,), s (clamped at ends)."""
        tt = np.asarray(times, dtype=float).reshape(-1)
        pos = np.stack([np.interp(tt, self.t, self.position[:, i]) for i in range(3)], axis=1)
        eul = np.stack([np.interp(tt, self.t, self.euler_deg[:, i]) for i in range(3)], axis=1)
        return pos, eul

    def pose(self, time: float) -> Pose:
        """The pose at one time, s."""
        pos, eul = self.sample([time])
        return Pose.from_euler(pos[0], eul[0])


def load_trajectory(path: str | Path) -> Trajectory:
    """Read a trajectory CSV with the columns ``t,x,y,z,theta_x,theta_y,theta_z``.

    Raises
    ------
    InputError
        Unreadable file, missing columns, non-numbers, fewer than two rows or times that do
        not increase (one line naming the file).
    """
    p = Path(path)
    rows = list(csv.DictReader(io.StringIO(read_text_file(p, "trajectory"), newline="")))
    if not rows:
        raise InputError("the trajectory has no rows", p)
    missing = [c for c in TRAJECTORY_COLUMNS if c not in rows[0]]
    if missing:
        raise InputError(f"the trajectory lacks the column(s) {', '.join(missing)}", p)
    try:
        data = np.array([[float(r[c]) for c in TRAJECTORY_COLUMNS] for r in rows])
    except (TypeError, ValueError):
        raise InputError("the trajectory has a value that is not a number", p) from None
    if np.any(np.abs(data) > MAX_MAGNITUDE):  # as every number of camera and map files
        raise InputError(f"the trajectory has a value beyond +-{MAX_MAGNITUDE:g}", p)
    try:
        return Trajectory(data[:, 0], data[:, 1:4], data[:, 4:7])
    except ValueError as exc:
        raise InputError(str(exc), p) from None


def save_trajectory(trajectory: Trajectory, path: str | Path) -> None:
    """Write a trajectory CSV (``t,x,y,z,theta_x,theta_y,theta_z``)."""
    data = np.column_stack([trajectory.t, trajectory.position, trajectory.euler_deg])
    with Path(path).open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(TRAJECTORY_COLUMNS)
        w.writerows([[f"{v:.6f}" for v in row] for row in data])
