"""Positions along a video: the locator's stages frame after frame, with a memory.

A single video frame often shows fewer than four decodable fixtures (stripes a little longer
than one frame of chips, a light entering at the border).  :class:`Tracker` keeps what the
previous frames established and uses it in the next one:

* **the readout** found in the first striped frame, and the chip length (rows per chip)
  measured by the decodes so far, passed to the decoder;
* **each fixture's ID and image position**: every map fixture is predicted in the image
  (from the track's pose, else from where it was last seen and how it moved); a fixture whose
  stripes do not decode keeps its ID when it is the only prediction within a gate of it and
  no other prediction is nearly as close; a decoded ID that lands far from where the track
  predicts that fixture is refused (IDs are never swapped between fixtures);
* **each fixture's glow**: told once (:func:`camvlp.pipeline.lamp.glow.glowing`); a glowing lamp is
  centred on its radial shape in every frame that uses it, as :func:`camvlp.locate` centres
  it, and a plain one is left as detected;
* **the pose**: with a pose prior, two or three identified fixtures give a ``tracked`` pose
  (:func:`camvlp.geometry.pnp.refine_pose`); four or more give a ``fix`` as in
  :func:`camvlp.locate`;
* **a filter**: a constant-velocity Kalman filter on the camera centre and the thesis'
  angles smooths the track and predicts through gaps (``predicted``); after ``max_gap_s``
  without a measurement the track is ``lost`` until the next fix.
* **the rolling shutter**: a fixture imaged on sensor row ``k`` was seen
  ``(k - (N - 1) / 2) * row_time`` after the frame's middle row; with the track's velocity its
  pixel is moved to where it would have been at the frame's time before solving.

Frame time convention: a frame's ``t`` is its middle sensor row's time (see
:mod:`camvlp.sim.video`); positions are the camera's at that time.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from camvlp.errors import InputError
from camvlp.geometry.disc import perspective_offset
from camvlp.geometry.pnp import PriorSolve, project_moving, refine_pose
from camvlp.io.files import MAX_MAGNITUDE
from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import FixtureMap
from camvlp.model.readout import Readout
from camvlp.pipeline.identify.identified import Identified, identify
from camvlp.pipeline.locate import StageClock
from camvlp.pipeline.stages import (
    PoseProblem,
    decode,
    find_lights,
    prepare,
    read_profiles,
    readout_direction,
    solve_pose,
)
from camvlp.pipeline.track.assoc import associate, known_blobs
from camvlp.pipeline.track.kalman import ConstantVelocityFilter
from camvlp.pipeline.track.records import STATUSES, TrackedFixture, TrackFrame, TrackSettings

__all__ = [
    "STATUSES",
    "ConstantVelocityFilter",
    "TrackFrame",
    "TrackSettings",
    "TrackedFixture",
    "Tracker",
]


@dataclass
class _Sighting:
    pixel: np.ndarray  # where the fixture was last seen, pixels (processing image)
    t: float
    velocity: np.ndarray  # pixels per s


class Tracker:
    """Locate a camera frame after frame, using what the earlier frames established.

    Call :meth:`update` with each frame in order.

    Parameters
    ----------
    camera : Camera
        The video's camera (its ``row_time_s`` enables the rolling-shutter correction).
    fixture_map : FixtureMap
        The room.
    settings : TrackSettings, optional
        How to track (defaults when None).
    """

    def __init__(
        self, camera: Camera, fixture_map: FixtureMap, settings: TrackSettings | None = None
    ) -> None:
        self.camera = camera
        self.map = fixture_map
        self.settings = settings or TrackSettings()
        st = self.settings.locate
        self._outlier_px = (
            st.outlier_px if st.outlier_px is not None else max(4.0, 0.01 * camera.focal_px)
        )
        self._gate = self.settings.gate_px or 0.03 * camera.focal_px
        self.readout: Readout | None = st.readout or camera.readout
        self.filter: ConstantVelocityFilter | None = None
        self._t_last: float | None = None  # time of the filter's state
        self._t_measured: float | None = None  # time of the last fix or tracked pose
        self._t_given: float | None = None  # time of the last frame given to update
        self._seen: dict[int, _Sighting] = {}
        self._chip_rows: list[float] = []
        self._ids = np.array([f.id for f in fixture_map.fixtures])
        self._positions = fixture_map.positions
        self._index = 0
        self._dt_pred = 0.0
        self._tilts: list[np.ndarray] = []  # (theta_x, theta_y) of the recent fixes
        self._offset_cache: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._verified: dict[int, int] = {}  # frame of each fixture's last decode

    # ---------------------------------------------------------------------------------------
    # Prediction

    def _predicted_state(self, t: float):
        """Predicted (values (6,), rates (6,), sigmas (6,)) at ``t``, or None without a track."""
        if self.filter is None or self._t_last is None:
            return None
        self._dt_pred = t - self._t_last
        x, p = self.filter.predicted(self._dt_pred)
        return x[:6], x[6:], np.sqrt(np.diag(p)[:6])

    def _pose_at(self, state, dt: float) -> Pose:
        x, rate, _ = state
        y = x + dt * rate
        return Pose.from_euler(y[:3], y[3:])

    def _row_offset_s(self, pixels: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
        """Time of each pixel's sensor row after the frame's middle row, s."""
        rt = self.camera.row_time_s
        if rt is None or self.readout is None:
            return np.zeros(len(pixels))
        h, w = shape
        n = h if self.readout.by_rows else w
        k = pixels[:, self.readout.pixel_index]
        if self.readout.reversed:
            k = n - 1 - k
        return (k - 0.5 * (n - 1)) * rt

    def _predict_pixels(
        self, t: float, shape: tuple[int, int]
    ) -> tuple[dict[int, np.ndarray], bool]:
        """Each fixture's predicted pixel (processing image): from the pose when there is a
        fresh track, else from where it was last seen; and whether the pose was used."""
        state = self._predicted_state(t)
        fresh = (
            state is not None
            and self._t_measured is not None
            and t - self._t_measured <= self.settings.max_gap_s
        )
        out: dict[int, np.ndarray] = {}
        if fresh:
            values, rates = state[0], state[1]
            zero = np.zeros(len(self._positions))
            uv = project_moving(self.camera, values, rates, self._positions, zero)
            if self.settings.rolling_shutter:  # where the rows that see them are read
                dts = self._row_offset_s(np.nan_to_num(uv), shape)
                uv = project_moving(self.camera, values, rates, self._positions, dts)
            for fid, p in zip(self._ids, uv, strict=True):
                if np.all(np.isfinite(p)):
                    out[int(fid)] = p
            return out, True
        for fid, s in self._seen.items():
            if t - s.t <= self.settings.max_gap_s:
                out[fid] = s.pixel + (t - s.t) * s.velocity
        return out, False

    # ---------------------------------------------------------------------------------------
    # Association (see :mod:`camvlp.pipeline.track.assoc`)

    def _associate(
        self, blobs, found: Identified, predicted: dict[int, np.ndarray], from_pose: bool
    ) -> tuple[list[int | None], list[str], list[str]]:
        """IDs per blob (decoded, carried or None), their sources, and reasons."""
        gate = self._gate * (1.0 if from_pose else 2.0)
        return associate(
            blobs, found.ids, found.reasons, predicted, self.map, gate, self.settings.ambiguity
        )

    def _known(self, blobs, predicted: dict[int, np.ndarray], from_pose: bool) -> set[int]:
        """Blobs whose ID the track already knows (their stripes need not be decoded)."""
        n_verify = self.settings.verify_every
        if not from_pose or n_verify <= 1 or self.map.mode == "frequency":
            return set()
        return known_blobs(
            blobs,
            predicted,
            self._verified,
            self._index,
            n_verify,
            self._gate,
            self.settings.ambiguity,
        )

    def _rpc(self) -> float | None:
        """The chip length the recent frames' decodes agree on (their median, rows), when
        carried (:attr:`TrackSettings.carry_chip_length`) and three or more were read."""
        carry = self.settings.carry_chip_length and self.map.mode != "frequency"
        if carry and len(self._chip_rows) >= 3:
            return float(np.median(self._chip_rows[-50:]))
        return None

    def _carry(self, decodes) -> None:
        """Remember the chip lengths of the IDs read (the last 50)."""
        for d in decodes:
            if d.id is not None and np.isfinite(d.rows_per_chip):
                self._chip_rows.append(float(d.rows_per_chip))
        del self._chip_rows[:-50]

    def _checked_time(self, t: object) -> float:
        """``t`` as a float when it is a finite time within +-1e9 s and later than the last
        frame's; InputError otherwise (before anything of the tracker changes)."""
        if isinstance(t, bool) or not isinstance(t, (int, float, np.integer, np.floating)):
            raise InputError(f"t must be a number of seconds, got {type(t).__name__}")
        value = float(t)
        if not (math.isfinite(value) and abs(value) <= MAX_MAGNITUDE):
            raise InputError(f"t must be a finite time within +-{MAX_MAGNITUDE:g} s, got {t!r}")
        if self._t_given is not None and not value > self._t_given:
            raise InputError(
                f"t must increase from frame to frame: {value!r} s after {self._t_given!r} s"
            )
        return value

    def update(self, image: np.ndarray, t: float) -> TrackFrame:
        """Process the next frame.

        Parameters
        ----------
        image : ndarray, shape (H, W, 3) or (H, W)
            The frame, of the camera's size.
        t : float
            Its time, s: a finite number within +-1e9 s, later than the previous frame's.

        Returns
        -------
        TrackFrame

        Raises
        ------
        InputError
            ``t`` is not such a time, or the frame is not an image of the camera's size; the
            tracker is left as it was, ready for the next frame.
        """
        t = self._checked_time(t)
        st = self.settings.locate
        clock = StageClock()
        # the stages of camvlp.locate, in its order (a video's readout, once decided, and
        # its chip length carried from frame to frame; the IDs the track knows not decoded)
        prepared = prepare(image, self.camera, self.map, st)
        img = prepared.image
        index = self._index  # the frame is taken: its time and index count from here
        self._index += 1
        self._t_given = t
        lights = find_lights(prepared, self.map, st, readout=self.readout)
        if self.readout is None and lights.readout is not None:
            # the first frame that decides the direction, from now on
            self.readout = readout_direction(prepared, lights, self.map, st)
        readout = self.readout or lights.readout or Readout.ROWS
        predicted, from_pose = self._predict_pixels(t, img.shape[:2])
        # no ID read reversed, nor along an axis the stripes do not show
        undecided = lights.readout is None or (
            self.readout is None and self.map.mode != "frequency"
        )
        blobs = list(lights.blobs)
        skip = set(range(len(blobs))) if undecided else self._known(blobs, predicted, from_pose)
        known = dataclasses.replace(lights, readout=readout, direction_known=True)
        profiles = read_profiles(img, blobs, readout)
        decoded = decode(prepared, known, profiles, self.map, skip=skip, rows_per_chip=self._rpc())
        self._carry(decoded.decodes)
        blobs = list(decoded.blobs)
        found = identify(blobs, list(decoded.decodes), self.map)
        clock.lap("locate")

        ids, sources, reasons = self._associate(blobs, found, predicted, from_pose)
        for k, src in enumerate(sources):
            if src == "decoded":
                self._verified[ids[k]] = index
        usable = [k for k in range(len(blobs)) if ids[k] is not None and not reasons[k]]
        state = self._predicted_state(t)
        fresh = from_pose and state is not None

        measured = np.array([blobs[k].pixel for k in usable]).reshape(-1, 2)
        rs = self.settings.rolling_shutter and self.camera.row_time_s is not None
        dts = self._row_offset_s(measured, img.shape[:2]) if rs else np.zeros(len(usable))
        obj = np.array([self.map.get(ids[k]).position for k in usable]).reshape(-1, 3)
        pixels = measured
        if fresh and rs and len(usable):  # a first guess for PnP: moved to the frame's time
            pixels = measured - self._rs_shift(state, obj, measured, img.shape[:2])

        status, reason, solved, used_mask = self._solve_frame(
            blobs, ids, usable, state, fresh, obj, measured, pixels, dts
        )
        raw_pose, rms, used_ids = None, math.nan, ()
        if solved is not None:
            raw_pose, rms = solved.pose, solved.reprojection_rms_px
            used_ids = tuple(int(ids[usable[j]]) for j in np.flatnonzero(used_mask))
            self._measure(
                solved, t, obj[used_mask], measured[used_mask], dts[used_mask], fix=status == "fix"
            )
            reason = ""
        elif self.filter is not None and self._t_measured is not None:
            status, reason = self._coast(t, reason)
        self._remember(blobs, ids, reasons, t)
        clock.lap("track")

        no_pose = "" if raw_pose is not None else (reason or "no pose")
        mirror_w = img.shape[1] if prepared.mirrored else None
        fixtures = self._fixtures(
            blobs, ids, sources, reasons, usable, used_mask, mirror_w, no_pose
        )
        pos = euler = None
        if self.filter is not None and status != "lost":
            v = self.filter.value
            pos, euler = v[:3], v[3:]
        return TrackFrame(
            index=index,
            t=float(t),
            status=status,
            position=pos,
            euler_deg=euler,
            raw_position=None if raw_pose is None else raw_pose.position,
            raw_euler_deg=None if raw_pose is None else self._near(raw_pose.euler_deg),
            fixtures_used=used_ids,
            reprojection_rms_px=rms,
            fixtures=fixtures,
            reason=reason,
            timing_ms=clock.total(),
        )

    def _solve_frame(self, blobs, ids, usable, state, fresh: bool, obj, measured, pixels, dts):
        """The frame's pose: a fix from four or more fixtures (from the track's prediction,
        else by PnP), else a tracked pose from fewer with the track's help.

        Returns (status, reason, solved PriorSolve or None, used mask over ``usable``).
        """
        st = self.settings.locate
        status, reason = "lost", ""
        solved = None
        used_mask = np.zeros(len(usable), bool)
        if len(usable) >= 4 and fresh:  # from the track's prediction: no PnP search needed
            used_mask = np.ones(len(usable), bool)
            start = self._pose_at(state, 0.0)
            solved = self._refine(start, state, obj, measured, dts, used_mask, fix=True)
            if solved is not None and np.max(solved.residuals_px) <= self._outlier_px:
                status = "fix"
            else:
                solved, used_mask = None, np.zeros(len(usable), bool)
        if len(usable) >= 4 and solved is None:
            moved = [
                dataclasses.replace(blobs[k], pixel=p) for k, p in zip(usable, pixels, strict=True)
            ]
            sub = Identified(
                tuple(ids[k] for k in usable), ("",) * len(usable), tuple(range(len(usable)))
            )
            problem = PoseProblem(self.camera, self.map, tuple(moved), st, self._outlier_px)
            est, why = solve_pose(problem, sub)
            if est is not None and est.pose is not None:
                used_mask = np.asarray(est.used, bool)
                solved = self._refine(est.pose, state, obj, measured, dts, used_mask, fix=True)
                status = "fix"
            else:
                reason = why
        if (
            solved is None
            and status != "fix"
            and fresh
            and len(usable) >= self.settings.min_tracked
        ):
            used_mask = np.ones(len(usable), bool)
            solved = self._refine(None, state, obj, measured, dts, used_mask, fix=False)
            if solved is not None and np.max(solved.residuals_px) <= self._outlier_px:
                status = "tracked"
            else:
                solved, used_mask = None, np.zeros(len(usable), bool)
                reason = reason or "the fixtures do not fit the track"
        elif solved is None and not reason:
            help_ = ", no track to help" if not fresh else ""
            reason = f"{len(usable)} identified fixture{'s' if len(usable) != 1 else ''}" + (
                help_ if len(usable) >= self.settings.min_tracked else ""
            )
        if status == "fix" and solved is None:
            status, used_mask = "lost", np.zeros(len(usable), bool)
            reason = "the rolling-shutter refinement failed"
        return status, reason, solved, used_mask

    @staticmethod
    def _fixtures(blobs, ids, sources, reasons, usable, used_mask, mirror_width, no_pose: str):
        """The frame's fixtures as reported (pixels of the photo as given: flipped back when
        ``mirror_width`` is the mirrored image's width); ``no_pose``: why identified fixtures
        are unused when there is no pose ("" when there is one)."""
        used_set = {usable[j] for j in np.flatnonzero(used_mask)}
        out = []
        for k, b in enumerate(blobs):
            why = reasons[k]
            if k in usable and k not in used_set:
                why = no_pose or "not used by the pose"
            p = b.pixel
            if mirror_width is not None:
                p = np.array([mirror_width - 1 - p[0], p[1]])
            out.append(TrackedFixture(ids[k], p, sources[k], k in used_set, why))
        return tuple(out)

    def _coast(self, t: float, reason: str) -> tuple[str, str]:
        """No measurement this frame: the filter predicts on, or the track is lost."""
        if t - self._t_measured <= self.settings.max_gap_s:
            self.filter.predict(t - self._t_last)
            self._t_last = t
            return "predicted", reason
        self.filter, self._t_last, self._t_measured = None, None, None
        return "lost", f"no measurement for {self.settings.max_gap_s} s"

    # ---------------------------------------------------------------------------------------

    def _rs_shift(self, state, obj, pixels, shape) -> np.ndarray:
        """Pixel motion of each fixture between its row's time and the frame's time."""
        dts = self._row_offset_s(pixels, shape)
        values, rates = state[0], state[1]
        moved = project_moving(self.camera, values, rates, obj, dts)
        return np.nan_to_num(moved - project_moving(self.camera, values, rates, obj, 0 * dts))

    def _refine(self, start: Pose | None, state, obj, pixels, dts, used, *, fix: bool):
        """The frame's pose (and rates) from its fixtures' pixels at their rows' times.

        A fix starts from its PnP pose with a loose prior; a tracked pose from the track's
        prediction with its uncertainty.  The rates' prior is the track's (or still, loosely).
        """
        st = self.settings
        if state is not None:
            rate = state[1]
            rate_sig = np.maximum(self._rate_sigma(), 1e-6)
        else:
            rate = np.zeros(6)
            rate_sig = np.array([1.0] * 3 + [30.0] * 3)
        cov = None
        if fix:
            values = np.concatenate([start.position, self._near(start.euler_deg)])
            sigma = np.array([0.5] * 3 + [20.0] * 3)
        else:
            ahead = self._ahead()
            values, rate, cov = ahead.x[:6], ahead.x[6:], ahead.P
            sigma = np.maximum(np.sqrt(np.diag(cov)[:6]), np.array([1e-5] * 3 + [1e-4] * 3))
        obj, pixels, dts = obj[used], pixels[used], dts[used]
        pixels = pixels - self._perspective(values, obj)
        return refine_pose(
            obj,
            pixels,
            self.camera,
            values[:3],
            values[3:],
            sigma_position=sigma[:3],
            sigma_euler_deg=sigma[3:],
            sigma_px=st.pixel_sigma,
            dt_s=dts,
            prior_rates=rate,
            sigma_rates=rate_sig,
            prior_covariance=cov,
        )

    def _ahead(self) -> ConstantVelocityFilter:
        """A copy of the filter moved to the frame's time, with the usual tilt fused in."""
        ahead = copy.deepcopy(self.filter)
        ahead.predict(self._dt_pred)
        self._fuse_tilt(ahead)
        return ahead

    def _fuse_tilt(self, flt: ConstantVelocityFilter) -> None:
        """Fuse the tilt (theta_x, theta_y) the recent fixes showed, with their spread: with
        two or three fixtures, what they leave open (a shift along the line through two of
        them against a tilt) is then held by how steadily the camera is carried."""
        if len(self._tilts) < 5:
            return
        tilts = np.array(self._tilts)
        mean = tilts.mean(axis=0)
        spread = np.maximum(tilts.std(axis=0), self.settings.min_tilt_sigma_deg)
        flt.update_some([3, 4], mean, spread)

    def _rate_sigma(self) -> np.ndarray:
        """Standard deviation of the predicted rates (6,)."""
        _, p = self.filter.predicted(self._dt_pred)
        return np.sqrt(np.diag(p)[6:])

    def _perspective(self, values: np.ndarray, obj: np.ndarray) -> np.ndarray:
        """Offsets (N, 2) of each disc's ellipse centre from its projected centre, pixels.

        Kept per fixture while the camera moves less than 10 % of its distance and turns
        less than a degree (the offset changes slowly and is a fraction of a pixel).
        """
        out = np.zeros((obj.shape[0], 2))
        if not self.settings.locate.correct_perspective:
            return out
        pose = None
        for j, p in enumerate(obj):
            k = int(np.argmin(np.linalg.norm(self._positions - p, axis=1)))
            f = self.map.fixtures[k]
            if not (f.diameter and f.normal is not None):
                continue
            cached = self._offset_cache.get(k)
            if cached is not None:
                at, offset = cached
                near = np.linalg.norm(at[:3] - values[:3]) <= 0.1 * np.linalg.norm(p - at[:3])
                if near and np.max(np.abs(at[3:] - values[3:])) <= 1.0:
                    out[j] = offset
                    continue
            if pose is None:
                pose = Pose.from_euler(values[:3], values[3:])
            out[j] = perspective_offset(self.camera, pose, f.position, f.diameter, f.normal)
            self._offset_cache[k] = (values.copy(), out[j].copy())
        return out

    def _near(self, euler: np.ndarray) -> np.ndarray:
        """Angles unwrapped to within 180 degrees of the track's."""
        if self.filter is None:
            return euler
        ref = self.filter.value[3:]
        return ref + (euler - ref + 180.0) % 360.0 - 180.0

    def _measure(self, solved: PriorSolve, t: float, obj, pixels, dts, *, fix: bool) -> None:
        """Fuse a frame's solve: its fixtures' pixels, linearised at its pose and rates."""
        s = self.settings
        values = np.concatenate([solved.values[:3], self._near(solved.values[3:])])
        if fix:
            self._tilts.append(values[3:5].copy())
            del self._tilts[: -s.tilt_window]
        if self.filter is None:
            self.filter = ConstantVelocityFilter(
                values,
                np.array([s.fix_sigma] * 3 + [s.fix_sigma_deg] * 3),
                np.array([2.0] * 3 + [90.0] * 3),
                np.array([s.accel_sigma] * 3 + [s.angular_accel_sigma_deg] * 3),
            )
        else:
            self.filter.predict(t - self._t_last)
            if not fix:
                self._fuse_tilt(self.filter)
            ref = np.concatenate([values, solved.rates])
            pixels = pixels - self._perspective(values, obj)
            model = project_moving(self.camera, values, solved.rates, obj, dts)
            residual = (pixels - model).ravel()
            jac = solved.jacobian_px
            if jac.shape[1] == 6:
                jac = np.hstack([jac, np.zeros_like(jac)])
            if np.all(np.isfinite(residual)) and np.all(np.isfinite(jac)):
                self.filter.update_linearized(residual, jac, ref, s.pixel_sigma)
        self._t_last = t
        self._t_measured = t

    def _remember(self, blobs, ids, reasons, t: float) -> None:
        for k, b in enumerate(blobs):
            fid = ids[k]
            if fid is None:
                continue
            prev = self._seen.get(fid)
            vel = np.zeros(2)
            if prev is not None and 0 < t - prev.t <= self.settings.max_gap_s:
                vel = (b.pixel - prev.pixel) / (t - prev.t)
            self._seen[fid] = _Sighting(np.asarray(b.pixel, dtype=float), t, vel)
