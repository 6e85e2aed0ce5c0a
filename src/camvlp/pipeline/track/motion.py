"""The video tracker's memory of the camera's motion (:mod:`camvlp.pipeline.track.tracker`).

A constant-velocity Kalman filter on the camera centre and the thesis' angles, the times of
its state and of the last measurement, and the tilts the recent fixes showed: it predicts the
pose at a frame's time, fuses a frame's solve (its fixtures' pixels, linearised at the solved
pose and rates), predicts on through a gap, and forgets the track after ``max_gap_s``.
"""

from __future__ import annotations

import copy
from collections.abc import Callable

import numpy as np

from camvlp.geometry.pnp import PriorSolve, project_moving
from camvlp.model.camera import Camera, Pose
from camvlp.pipeline.track.kalman import ConstantVelocityFilter
from camvlp.pipeline.track.records import TrackSettings

__all__ = ["Motion", "MotionState"]

#: A predicted state: values (6,) (position, map units; angles, degrees), their rates (6,)
#: (per s) and the values' standard deviations (6,).
MotionState = tuple[np.ndarray, np.ndarray, np.ndarray]


class Motion:
    """The camera's motion along a video, as the track knows it.

    Parameters
    ----------
    camera : Camera
        The video's camera.
    settings : TrackSettings
        The tracker's settings (gap, noise, tilt window).

    Attributes
    ----------
    filter : ConstantVelocityFilter or None
        The filter (None before the first fix and after the track is lost).
    t_last : float or None
        Time of the filter's state, s.
    t_measured : float or None
        Time of the last fix or tracked pose, s.
    dt_pred : float
        Time from the filter's state to the frame being solved, s (set by :meth:`state_at`).
    """

    def __init__(self, camera: Camera, settings: TrackSettings) -> None:
        self.camera = camera
        self.settings = settings
        self.filter: ConstantVelocityFilter | None = None
        self.t_last: float | None = None
        self.t_measured: float | None = None
        self.dt_pred = 0.0
        self.tilts: list[np.ndarray] = []  # (theta_x, theta_y) of the recent fixes

    def state_at(self, t: float) -> MotionState | None:
        """Predicted (values (6,), rates (6,), sigmas (6,)) at ``t`` (s), or None without a
        track; ``t`` becomes the time of the frame being solved (:attr:`dt_pred`)."""
        if self.filter is None or self.t_last is None:
            return None
        self.dt_pred = t - self.t_last
        x, p = self.filter.predicted(self.dt_pred)
        return x[:6], x[6:], np.sqrt(np.diag(p)[:6])

    def fresh(self, t: float) -> bool:
        """Whether the track was measured within ``max_gap_s`` of ``t`` (s)."""
        return (
            self.filter is not None
            and self.t_last is not None
            and self.t_measured is not None
            and t - self.t_measured <= self.settings.max_gap_s
        )

    def ahead(self) -> ConstantVelocityFilter:
        """A copy of the filter moved to the frame's time, with the usual tilt fused in."""
        ahead = copy.deepcopy(self.filter)
        ahead.predict(self.dt_pred)
        self.fuse_tilt(ahead)
        return ahead

    def fuse_tilt(self, flt: ConstantVelocityFilter) -> None:
        """Fuse the tilt (theta_x, theta_y) the recent fixes showed, with their spread: with
        two or three fixtures, what they leave open (a shift along the line through two of
        them against a tilt) is then held by how steadily the camera is carried."""
        if len(self.tilts) < 5:
            return
        tilts = np.array(self.tilts)
        mean = tilts.mean(axis=0)
        spread = np.maximum(tilts.std(axis=0), self.settings.min_tilt_sigma_deg)
        flt.update_some([3, 4], mean, spread)

    def rate_sigma(self) -> np.ndarray:
        """Standard deviation of the predicted rates (6,) at the frame's time."""
        _, p = self.filter.predicted(self.dt_pred)
        return np.sqrt(np.diag(p)[6:])

    def near(self, euler: np.ndarray) -> np.ndarray:
        """Angles (degrees) unwrapped to within 180 degrees of the track's."""
        if self.filter is None:
            return euler
        ref = self.filter.value[3:]
        return ref + (euler - ref + 180.0) % 360.0 - 180.0

    def measure(
        self,
        solved: PriorSolve,
        t: float,
        obj: np.ndarray,
        pixels: np.ndarray,
        dts: np.ndarray,
        offsets: Callable[[np.ndarray, np.ndarray], np.ndarray],
        *,
        fix: bool,
    ) -> None:
        """Fuse a frame's solve at ``t`` (s): its fixtures (``obj`` (N, 3), map units) seen at
        ``pixels`` (N, 2) on rows read ``dts`` (N,) s after the frame's time, linearised at its
        pose and rates; ``offsets(values, obj)`` gives each disc's perspective offset (N, 2)."""
        s = self.settings
        values = np.concatenate([solved.values[:3], self.near(solved.values[3:])])
        if fix:
            self.tilts.append(values[3:5].copy())
            del self.tilts[: -s.tilt_window]
        if self.filter is None:
            self.filter = ConstantVelocityFilter(
                values,
                np.array([s.fix_sigma] * 3 + [s.fix_sigma_deg] * 3),
                np.array([2.0] * 3 + [90.0] * 3),
                np.array([s.accel_sigma] * 3 + [s.angular_accel_sigma_deg] * 3),
            )
        else:
            self.filter.predict(t - self.t_last)
            if not fix:
                self.fuse_tilt(self.filter)
            ref = np.concatenate([values, solved.rates])
            pixels = pixels - offsets(values, obj)
            model = project_moving(self.camera, values, solved.rates, obj, dts)
            residual = (pixels - model).ravel()
            jac = solved.jacobian_px
            if jac.shape[1] == 6:
                jac = np.hstack([jac, np.zeros_like(jac)])
            if np.all(np.isfinite(residual)) and np.all(np.isfinite(jac)):
                self.filter.update_linearized(residual, jac, ref, s.pixel_sigma)
        self.t_last = t
        self.t_measured = t

    def coast(self, t: float, reason: str) -> tuple[str, str]:
        """No measurement at ``t`` (s): the filter predicts on (``predicted``), or the track
        is ``lost`` after ``max_gap_s``; the status and its reason."""
        if t - self.t_measured <= self.settings.max_gap_s:
            self.filter.predict(t - self.t_last)
            self.t_last = t
            return "predicted", reason
        self.filter, self.t_last, self.t_measured = None, None, None
        return "lost", f"no measurement for {self.settings.max_gap_s} s"

    def current(self, status: str) -> tuple[np.ndarray | None, np.ndarray | None]:
        """The track's position (3,) and angles (3,) to report, (None, None) when ``lost``."""
        if self.filter is None or status == "lost":
            return None, None
        v = self.filter.value
        return v[:3], v[3:]


def pose_at(state: MotionState, dt: float) -> Pose:
    """The pose of a predicted state moved on by ``dt`` s."""
    x, rate, _ = state
    y = x + dt * rate
    return Pose.from_euler(y[:3], y[3:])
