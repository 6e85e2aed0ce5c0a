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

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np

from camvlp.geometry.pnp import refine_pose
from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import FixtureMap
from camvlp.model.readout import Readout
from camvlp.pipeline.decode import decode_profile
from camvlp.pipeline.locate import (
    LocateSettings,
    _decode,
    _detect,
    _Identified,
    _identify,
    _prepare,
    _profiles,
    _solve,
)

__all__ = [
    "STATUSES",
    "ConstantVelocityFilter",
    "TrackFrame",
    "TrackSettings",
    "TrackedFixture",
    "Tracker",
]

#: Per-frame statuses, best first.
STATUSES = ("fix", "tracked", "predicted", "lost")


@dataclass(frozen=True, kw_only=True)
class TrackSettings:
    """Tuning of :class:`Tracker`.

    Attributes
    ----------
    locate : LocateSettings
        The locator's settings (solver, outlier tolerance, detector sizes, readout).
    gate_px : float or None
        Largest distance (pixels) between a blob and a fixture's predicted position for the
        blob to keep that fixture's ID; None: 3 % of the focal length.
    ambiguity : float
        A blob keeps an ID only when every other prediction is this many times farther.
    min_tracked : int
        Fewest identified fixtures for a ``tracked`` pose (with the track's prior).
    max_gap_s : float
        Longest prediction without a measurement before the track is ``lost``, s.
    accel_sigma : float
        Process noise of the filter: acceleration, map units per s^2.
    angular_accel_sigma_deg : float
        Process noise of the angles: degrees per s^2.
    fix_sigma : float
        Measurement noise of a fix's position, map units.
    fix_sigma_deg : float
        Measurement noise of a fix's angles, degrees.
    rolling_shutter : bool
        Correct each fixture's pixel for the camera's motion between its row and the frame's
        middle row (needs the camera's ``row_time_s``).
    carry_chip_length : bool
        Pass the chip length measured in earlier frames to the decoder.
    """

    locate: LocateSettings = field(default_factory=LocateSettings)
    gate_px: float | None = None
    ambiguity: float = 2.0
    min_tracked: int = 2
    max_gap_s: float = 0.5
    accel_sigma: float = 4.0
    angular_accel_sigma_deg: float = 400.0
    fix_sigma: float = 0.002
    fix_sigma_deg: float = 0.05
    rolling_shutter: bool = True
    carry_chip_length: bool = True

    def __post_init__(self) -> None:
        for name in (
            "ambiguity",
            "max_gap_s",
            "accel_sigma",
            "angular_accel_sigma_deg",
            "fix_sigma",
            "fix_sigma_deg",
        ):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive number, got {v!r}")
        if self.gate_px is not None and not self.gate_px > 0:
            raise ValueError(f"gate_px must be a positive number, got {self.gate_px!r}")
        if self.ambiguity < 1:
            raise ValueError(f"ambiguity must be at least 1, got {self.ambiguity!r}")
        if self.min_tracked < 1:
            raise ValueError(f"min_tracked must be at least 1, got {self.min_tracked!r}")


class ConstantVelocityFilter:
    """Kalman filter with a constant-velocity model, independently per coordinate.

    State per coordinate: value and rate; the process noise is white acceleration of spectral
    density ``q`` per coordinate (units^2 / s^3).  Shapes: ``x`` (D, 2), ``P`` (D, 2, 2).

    Parameters
    ----------
    value : array_like, shape (D,)
        First measurement.
    value_sigma : array_like, shape (D,)
        Its standard deviation.
    rate_sigma : array_like, shape (D,)
        Standard deviation of the unknown initial rate (units per s).
    q : array_like, shape (D,)
        Process-noise spectral density per coordinate.
    """

    def __init__(self, value, value_sigma, rate_sigma, q) -> None:
        v = np.asarray(value, dtype=float).reshape(-1)
        d = v.size
        self.x = np.stack([v, np.zeros(d)], axis=1)
        self.P = np.zeros((d, 2, 2))
        self.P[:, 0, 0] = np.broadcast_to(np.asarray(value_sigma, dtype=float) ** 2, (d,))
        self.P[:, 1, 1] = np.broadcast_to(np.asarray(rate_sigma, dtype=float) ** 2, (d,))
        self.q = np.broadcast_to(np.asarray(q, dtype=float), (d,)).copy()

    @property
    def value(self) -> np.ndarray:
        """Current values, shape (D,)."""
        return self.x[:, 0].copy()

    @property
    def rate(self) -> np.ndarray:
        """Current rates (units per s), shape (D,)."""
        return self.x[:, 1].copy()

    @property
    def sigma(self) -> np.ndarray:
        """Standard deviation of each value, shape (D,)."""
        return np.sqrt(self.P[:, 0, 0])

    def predict(self, dt: float) -> None:
        """Move the state ``dt`` seconds on (``dt`` >= 0)."""
        dt = max(float(dt), 0.0)
        f = np.array([[1.0, dt], [0.0, 1.0]])
        qm = np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
        self.x = self.x @ f.T
        self.P = f[None] @ self.P @ f.T[None] + self.q[:, None, None] * qm[None]

    def update(self, z, sigma) -> None:
        """Fuse a measurement of the values, ``z`` (D,), with standard deviations (D,)."""
        z = np.asarray(z, dtype=float).reshape(-1)
        r = np.broadcast_to(np.asarray(sigma, dtype=float) ** 2, z.shape)
        s = self.P[:, 0, 0] + r
        k = self.P[:, :, 0] / s[:, None]  # (D, 2)
        innovation = z - self.x[:, 0]
        self.x = self.x + k * innovation[:, None]
        self.P = self.P - k[:, :, None] * self.P[:, None, 0, :]


@dataclass(frozen=True)
class TrackedFixture:
    """One blob of a frame, as the tracker saw it.

    Attributes
    ----------
    id : int or None
        Its fixture's ID, or None.
    pixel : ndarray, shape (2,)
        Centre of its disc in the frame as given, pixels.
    source : str
        Where its ID came from: ``"decoded"`` (its stripes), ``"carried"`` (the track), or
        ``""`` (no ID).
    used : bool
        Whether the frame's pose uses it.
    reason : str
        Why it is not used ("" when used).
    """

    id: int | None
    pixel: np.ndarray
    source: str
    used: bool
    reason: str


@dataclass(frozen=True)
class TrackFrame:
    """The tracker's answer for one frame.

    Attributes
    ----------
    index : int
        Frame number, from 0.
    t : float
        The frame's time, s.
    status : str
        ``fix`` (four or more fixtures), ``tracked`` (fewer, with the track's prior),
        ``predicted`` (the filter's prediction, no usable fixture), ``lost`` (no track).
    position, euler_deg : ndarray, shape (3,), or None
        The filtered camera centre (map units) and thesis angles (degrees); None when lost.
    raw_position, raw_euler_deg : ndarray, shape (3,), or None
        This frame's own solve (fix or tracked), before filtering; None otherwise.
    fixtures_used : tuple of int
        IDs of the fixtures the solve used.
    reprojection_rms_px : float
        RMS reprojection error of the solve, pixels (NaN without one).
    fixtures : tuple of TrackedFixture
        Every blob detected.
    reason : str
        Why there is no solve ("" for fix and tracked).
    timing_ms : dict
        ``locate`` (detection and decoding), ``track`` (association, solve, filter), ``total``.
    """

    index: int
    t: float
    status: str
    position: np.ndarray | None
    euler_deg: np.ndarray | None
    raw_position: np.ndarray | None
    raw_euler_deg: np.ndarray | None
    fixtures_used: tuple[int, ...]
    reprojection_rms_px: float
    fixtures: tuple[TrackedFixture, ...]
    reason: str
    timing_ms: dict[str, float]

    @classmethod
    def lost(cls, index: int, t: float, reason: str) -> TrackFrame:
        """A frame with nothing known (unreadable, or before the first fix)."""
        return cls(index, t, "lost", None, None, None, None, (), math.nan, (), reason, {})


@dataclass
class _Sighting:
    pixel: np.ndarray  # where the fixture was last seen, pixels (processing image)
    t: float
    velocity: np.ndarray  # pixels per s


class Tracker:
    """Locate a camera frame after frame, using what the earlier frames established.

    Parameters
    ----------
    camera : Camera
        The video's camera (its ``row_time_s`` enables the rolling-shutter correction).
    fixture_map : FixtureMap
        The room.
    settings : TrackSettings, optional

    Call :meth:`update` with each frame in order.
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
        self._seen: dict[int, _Sighting] = {}
        self._chip_rows: list[float] = []
        self._ids = np.array([f.id for f in fixture_map.fixtures])
        self._positions = fixture_map.positions
        self._index = 0

    # ---------------------------------------------------------------------------------------
    # Prediction

    def _predicted_state(self, t: float):
        """Predicted (position, euler, velocity, euler rate, sigmas) at ``t``, or None."""
        if self.filter is None or self._t_last is None:
            return None
        dt = t - self._t_last
        x = self.filter.x[:, 0] + dt * self.filter.x[:, 1]
        return x, self.filter.x[:, 1].copy()

    def _pose_at(self, state, dt: float) -> Pose:
        x, rate = state
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
            pose = self._pose_at(state, 0.0)
            uv = self.camera.project(pose, self._positions)
            if self.settings.rolling_shutter:  # where the rows that see them are read
                dts = self._row_offset_s(np.nan_to_num(uv), shape)
                uv = np.array(
                    [
                        self.camera.project(self._pose_at(state, dt), p[None])[0]
                        for dt, p in zip(dts, self._positions, strict=True)
                    ]
                )
            for fid, p in zip(self._ids, uv, strict=True):
                if np.all(np.isfinite(p)):
                    out[int(fid)] = p
            return out, True
        for fid, s in self._seen.items():
            if t - s.t <= self.settings.max_gap_s:
                out[fid] = s.pixel + (t - s.t) * s.velocity
        return out, False

    # ---------------------------------------------------------------------------------------
    # Association

    def _associate(
        self, blobs, found: _Identified, predicted: dict[int, np.ndarray], from_pose: bool
    ) -> tuple[list[int | None], list[str], list[str]]:
        """IDs per blob (decoded, carried or None), their sources, and reasons."""
        n = len(blobs)
        ids: list[int | None] = [None] * n
        sources = [""] * n
        reasons = list(found.reasons)
        gate = self._gate * (1.0 if from_pose else 2.0)
        pred_ids = list(predicted)
        pred_px = np.array([predicted[i] for i in pred_ids]).reshape(-1, 2)
        pixels = np.array([b.pixel for b in blobs]).reshape(-1, 2)
        dist = np.linalg.norm(pixels[:, None, :] - pred_px[None, :, :], axis=2)  # (n, m)
        # decoded IDs, checked against the prediction
        for k in range(n):
            fid = found.ids[k]
            decoded = fid is not None and (not found.reasons[k] or blobs[k].touches_border)
            if not decoded or self.map.get(fid) is None:
                continue
            if fid in predicted:
                d = dist[k, pred_ids.index(fid)]
                if d > gate:
                    reasons[k] = (
                        f"decoded ID {fid}, but the track puts that fixture {d:.0f} px away"
                    )
                    continue
            ids[k], sources[k] = fid, "decoded"
            if reasons[k].startswith("ID ") and "decoded for two" in reasons[k]:
                reasons[k] = ""
        # the same ID decoded twice: keep neither
        for k in range(n):
            if ids[k] is not None and sum(i == ids[k] for i in ids) > 1:
                reasons[k] = f"ID {ids[k]} was decoded for two fixtures"
        for k in range(n):
            if reasons[k].startswith(f"ID {ids[k]} was decoded for two"):
                ids[k], sources[k] = None, ""
        # carried IDs: the one prediction within the gate, no rival nearly as close
        claimed = {i for i in ids if i is not None}
        for k in range(n):
            if ids[k] is not None or pred_px.shape[0] == 0:
                continue
            order = np.argsort(dist[k])
            j = int(order[0])
            d = dist[k, j]
            fid = pred_ids[j]
            if d > gate:
                continue
            if order.size > 1 and dist[k, order[1]] < self.settings.ambiguity * max(d, 1.0):
                reasons[k] = reasons[k] or "ambiguous: two fixtures are predicted near it"
                continue
            others = [q for q in range(n) if q != k and ids[q] is None]
            if any(dist[q, j] < self.settings.ambiguity * max(d, 1.0) for q in others):
                reasons[k] = reasons[k] or "ambiguous: two blobs near one predicted fixture"
                continue
            if fid in claimed:
                continue
            ids[k], sources[k] = fid, "carried"
            claimed.add(fid)
        for k in range(n):
            if ids[k] is not None:
                border = blobs[k].touches_border
                reasons[k] = (
                    "cut by the image border (its centre would be biased)" if border else ""
                )
        return ids, sources, reasons

    # ---------------------------------------------------------------------------------------

    def _decode(self, img, blobs, readout):
        gray_rois, extents, profiles = _profiles(img, blobs, readout)
        if (
            self.settings.carry_chip_length
            and self.map.mode != "frequency"
            and len(self._chip_rows) >= 3
        ):
            rpc = float(np.median(self._chip_rows[-50:]))
            decodes = [decode_profile(p, self.map.frame, rows_per_chip=rpc) for p in profiles]
        else:
            decodes, _, _ = _decode(
                blobs, gray_rois, extents, profiles, readout, self.camera, self.map
            )
        for d in decodes:
            if d.id is not None and np.isfinite(d.rows_per_chip):
                self._chip_rows.append(float(d.rows_per_chip))
        return decodes

    def update(self, image: np.ndarray, t: float) -> TrackFrame:
        """Process the next frame.

        Parameters
        ----------
        image : ndarray, shape (H, W, 3) or (H, W)
            The frame, of the camera's size.
        t : float
            Its time, s (increasing from frame to frame).

        Returns
        -------
        TrackFrame

        Raises
        ------
        InputError
            The frame is not an image of the camera's size.
        """
        index = self._index
        self._index += 1
        st = self.settings.locate
        t0 = time.perf_counter()
        img, mirrored = _prepare(image, self.camera, st)
        detection, readout = _detect(img, self.readout, st)
        blobs = list(detection.blobs)
        if self.readout is None and any(b.stripe_contrast > 2.0 for b in blobs):
            self.readout = readout  # the readout of the first striped frame, from now on
        decodes = self._decode(img, blobs, readout)
        found = _identify(blobs, decodes, self.map)
        t1 = time.perf_counter()

        predicted, from_pose = self._predict_pixels(t, img.shape[:2])
        ids, sources, reasons = self._associate(blobs, found, predicted, from_pose)
        usable = [k for k in range(len(blobs)) if ids[k] is not None and not reasons[k]]
        state = self._predicted_state(t)
        fresh = from_pose and state is not None

        pixels = np.array([blobs[k].pixel for k in usable]).reshape(-1, 2)
        if fresh and self.settings.rolling_shutter and len(usable):
            pixels = pixels - self._rs_shift(state, usable, ids, pixels, img.shape[:2])

        status, reason = "lost", ""
        raw_pose, rms, used_ids = None, math.nan, ()
        used_mask = np.zeros(len(usable), bool)
        if len(usable) >= 4:
            moved = [
                dataclasses.replace(blobs[k], pixel=p) for k, p in zip(usable, pixels, strict=True)
            ]
            sub = _Identified(
                tuple(ids[k] for k in usable), ("",) * len(usable), tuple(range(len(usable)))
            )
            est, why = _solve(self.camera, self.map, moved, sub, st, self._outlier_px)
            if est is not None and est.pose is not None:
                raw_pose, rms, used_mask = est.pose, float(est.reprojection_rms_px), est.used
                status = "fix"
            else:
                reason = why
        if raw_pose is None and fresh and len(usable) >= self.settings.min_tracked:
            solved = self._tracked_solve(state, usable, ids, pixels)
            if solved is not None:
                raw_pose, rms, used_mask = solved
                status = "tracked"
            else:
                reason = reason or "the fixtures do not fit the track"
        elif raw_pose is None and not reason:
            reason = f"{len(usable)} identified fixture{'s' if len(usable) != 1 else ''}" + (
                ", no track to help" if not fresh else ""
            )
        if raw_pose is not None:
            used_ids = tuple(int(ids[usable[j]]) for j in np.flatnonzero(used_mask))
            self._measure(raw_pose, t, status)
            reason = ""
        elif self.filter is not None and self._t_measured is not None:
            if t - self._t_measured <= self.settings.max_gap_s:
                self.filter.predict(t - self._t_last)
                self._t_last = t
                status = "predicted"
            else:
                self.filter, self._t_last, self._t_measured = None, None, None
                status, reason = "lost", f"no measurement for {self.settings.max_gap_s} s"
        self._remember(blobs, ids, reasons, t)
        t2 = time.perf_counter()

        width = img.shape[1]

        def shown(p: np.ndarray) -> np.ndarray:
            return np.array([width - 1 - p[0], p[1]]) if mirrored else p

        used_set = {usable[j] for j in np.flatnonzero(used_mask)}
        fixtures = []
        for k, b in enumerate(blobs):
            why = reasons[k]
            if k in usable and k not in used_set:
                why = "not used by the pose" if raw_pose is not None else (reason or "no pose")
            fixtures.append(TrackedFixture(ids[k], shown(b.pixel), sources[k], k in used_set, why))
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
            fixtures=tuple(fixtures),
            reason=reason,
            timing_ms={
                "locate": 1e3 * (t1 - t0),
                "track": 1e3 * (t2 - t1),
                "total": 1e3 * (t2 - t0),
            },
        )

    # ---------------------------------------------------------------------------------------

    def _rs_shift(self, state, usable, ids, pixels, shape) -> np.ndarray:
        """Pixel motion of each fixture between its row's time and the frame's time."""
        dts = self._row_offset_s(pixels, shape)
        base = self._pose_at(state, 0.0)
        shift = np.zeros_like(pixels)
        for j, k in enumerate(usable):
            x = self.map.get(ids[k]).position[None]
            shift[j] = (
                self.camera.project(self._pose_at(state, dts[j]), x)[0]
                - (self.camera.project(base, x)[0])
            )
        return np.nan_to_num(shift)

    def _tracked_solve(self, state, usable, ids, pixels):
        x, _ = state
        sig = self.filter.sigma if self.filter is not None else np.full(6, 1.0)
        obj = np.array([self.map.get(ids[k]).position for k in usable])
        solved = refine_pose(
            obj,
            pixels,
            self.camera,
            x[:3],
            x[3:],
            sigma_position=np.maximum(sig[:3], 1e-4),
            sigma_euler_deg=np.maximum(sig[3:], 1e-3),
            sigma_px=0.5,
        )
        if solved is None or np.max(solved.residuals_px) > self._outlier_px:
            return None
        return solved.pose, solved.reprojection_rms_px, np.ones(len(usable), bool)

    def _near(self, euler: np.ndarray) -> np.ndarray:
        """Angles unwrapped to within 180 degrees of the track's."""
        if self.filter is None:
            return euler
        ref = self.filter.value[3:]
        return ref + (euler - ref + 180.0) % 360.0 - 180.0

    def _measure(self, pose: Pose, t: float, status: str) -> None:
        s = self.settings
        z = np.concatenate([pose.position, self._near(pose.euler_deg)])
        if status == "fix":
            sigma = np.array([s.fix_sigma] * 3 + [s.fix_sigma_deg] * 3)
        else:
            sigma = np.array([2 * s.fix_sigma] * 3 + [2 * s.fix_sigma_deg] * 3)
        if self.filter is None:
            if status != "fix":
                return
            self.filter = ConstantVelocityFilter(
                z,
                sigma,
                np.array([2.0] * 3 + [90.0] * 3),
                np.array([s.accel_sigma**2] * 3 + [s.angular_accel_sigma_deg**2] * 3),
            )
        else:
            self.filter.predict(t - self._t_last)
            self.filter.update(z, sigma)
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
