"""A video frame's pose from its identified fixtures, with the track's help
(:mod:`camvlp.pipeline.track.tracker`).

Four or more fixtures give a ``fix``: refined from the track's prediction when it is fresh and
every fixture fits, else by the locator's pose stage (:func:`camvlp.pipeline.stages.solve_pose`)
and refined with the rows' times.  Fewer, down to ``min_tracked``, give a ``tracked`` pose from
a fresh track's prediction and its uncertainty (:func:`camvlp.geometry.pnp.refine_pose`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from camvlp.geometry.pnp import PriorSolve, refine_pose
from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.identified import Identified
from camvlp.pipeline.stages import PoseProblem, solve_pose
from camvlp.pipeline.track.motion import Motion, MotionState, pose_at
from camvlp.pipeline.track.offsets import PerspectiveOffsets
from camvlp.pipeline.track.records import TrackSettings

__all__ = ["FrameSolve", "FrameSolver", "Measurements"]


@dataclass(frozen=True)
class Measurements:
    """A frame's identified, usable fixtures.

    Attributes
    ----------
    usable : list of int
        Their blobs' indices (N,).
    obj : ndarray, shape (N, 3)
        Their map positions, map units.
    measured : ndarray, shape (N, 2)
        Their detected pixels (processing image).
    pixels : ndarray, shape (N, 2)
        The same moved to the frame's time with the track's velocity (a first guess for PnP).
    dts : ndarray, shape (N,)
        Time of each one's sensor row after the frame's middle row, s (zeros without the
        rolling-shutter model).
    """

    usable: list[int]
    obj: np.ndarray
    measured: np.ndarray
    pixels: np.ndarray
    dts: np.ndarray


@dataclass(frozen=True)
class FrameSolve:
    """A frame's pose, or why there is none.

    Attributes
    ----------
    status : str
        ``fix``, ``tracked`` or ``lost`` (before the track coasts).
    reason : str
        Why there is no pose ("" with one).
    solved : PriorSolve or None
        The pose and rates.
    used_mask : ndarray of bool, shape (N,)
        Which of the usable fixtures it uses.
    """

    status: str
    reason: str
    solved: PriorSolve | None
    used_mask: np.ndarray


class FrameSolver:
    """Solves each frame's pose with the track's prior.

    Parameters
    ----------
    camera : Camera
    fixture_map : FixtureMap
    settings : TrackSettings
    motion : Motion
        The track's motion (prior, rates' uncertainty, angles' unwrapping).
    offsets : PerspectiveOffsets
        The discs' perspective offsets.
    outlier_px : float
        Largest reprojection error of a fixture in a pose, pixels.
    """

    def __init__(
        self,
        camera: Camera,
        fixture_map: FixtureMap,
        settings: TrackSettings,
        motion: Motion,
        offsets: PerspectiveOffsets,
        outlier_px: float,
    ) -> None:
        self.camera = camera
        self.map = fixture_map
        self.settings = settings
        self.motion = motion
        self.offsets = offsets
        self.outlier_px = outlier_px

    def solve(self, blobs, ids, m: Measurements, state: MotionState | None, fresh: bool):
        """The frame's pose: a fix from four or more fixtures (from the track's prediction,
        else by PnP), else a tracked pose from fewer with the track's help.

        ``blobs`` and ``ids``: the frame's blobs and their IDs; ``state``: the track's
        prediction at the frame's time; ``fresh``: whether the track may help.  Returns a
        :class:`FrameSolve`.
        """
        n = len(m.usable)
        status, reason, solved, used_mask = "lost", "", None, np.zeros(n, bool)
        if n >= 4 and fresh:  # from the track's prediction: no PnP search needed
            solved, used_mask = self._checked(pose_at(state, 0.0), state, m, fix=True)
            status = "fix" if solved is not None else status
        if n >= 4 and solved is None:
            status, solved, used_mask, reason = self._by_pnp(blobs, ids, m, state)
        if solved is None and status != "fix" and fresh and n >= self.settings.min_tracked:
            solved, used_mask = self._checked(None, state, m, fix=False)
            if solved is not None:
                status = "tracked"
            else:
                reason = reason or "the fixtures do not fit the track"
        elif solved is None and not reason:
            help_ = ", no track to help" if not fresh else ""
            reason = f"{n} identified fixture{'s' if n != 1 else ''}" + (
                help_ if n >= self.settings.min_tracked else ""
            )
        if status == "fix" and solved is None:
            status, used_mask = "lost", np.zeros(n, bool)
            reason = "the rolling-shutter refinement failed"
        return FrameSolve(status, reason, solved, used_mask)

    def _checked(self, start: Pose | None, state, m: Measurements, *, fix: bool):
        """A refinement on every usable fixture, kept when each fits within the outlier
        tolerance: (solve, used mask), or (None, none used)."""
        used_mask = np.ones(len(m.usable), bool)
        solved = self.refine(start, state, m, used_mask, fix=fix)
        if solved is not None and np.max(solved.residuals_px) <= self.outlier_px:
            return solved, used_mask
        return None, np.zeros(len(m.usable), bool)

    def _by_pnp(self, blobs, ids, m: Measurements, state):
        """The locator's pose stage on the fixtures moved to the frame's time, refined with
        their rows' times: (status ``fix`` or ``lost``, solve or None, used mask, reason "" when
        the stage gave a pose; its refinement may still fail)."""
        moved = [
            dataclasses.replace(blobs[k], pixel=p) for k, p in zip(m.usable, m.pixels, strict=True)
        ]
        n = len(m.usable)
        sub = Identified(tuple(ids[k] for k in m.usable), ("",) * n, tuple(range(n)))
        problem = PoseProblem(
            self.camera, self.map, tuple(moved), self.settings.locate, self.outlier_px
        )
        est, why = solve_pose(problem, sub)
        if est is None or est.pose is None:
            return "lost", None, np.zeros(n, bool), why
        used_mask = np.asarray(est.used, bool)
        return "fix", self.refine(est.pose, state, m, used_mask, fix=True), used_mask, ""

    def refine(self, start: Pose | None, state, m: Measurements, used, *, fix: bool):
        """The frame's pose (and rates) from its fixtures' pixels at their rows' times.

        A fix starts from its PnP pose with a loose prior; a tracked pose from the track's
        prediction with its uncertainty.  The rates' prior is the track's (or still, loosely).
        """
        if state is not None:
            rate = state[1]
            rate_sig = np.maximum(self.motion.rate_sigma(), 1e-6)
        else:
            rate = np.zeros(6)
            rate_sig = np.array([1.0] * 3 + [30.0] * 3)
        cov = None
        if fix:
            values = np.concatenate([start.position, self.motion.near(start.euler_deg)])
            sigma = np.array([0.5] * 3 + [20.0] * 3)
        else:
            ahead = self.motion.ahead()
            values, rate, cov = ahead.x[:6], ahead.x[6:], ahead.P
            sigma = np.maximum(np.sqrt(np.diag(cov)[:6]), np.array([1e-5] * 3 + [1e-4] * 3))
        obj, pixels, dts = m.obj[used], m.measured[used], m.dts[used]
        pixels = pixels - self.offsets(values, obj)
        return refine_pose(
            obj,
            pixels,
            self.camera,
            values[:3],
            values[3:],
            sigma_position=sigma[:3],
            sigma_euler_deg=sigma[3:],
            sigma_px=self.settings.pixel_sigma,
            dt_s=dts,
            prior_rates=rate,
            sigma_rates=rate_sig,
            prior_covariance=cov,
        )
