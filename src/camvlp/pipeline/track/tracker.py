"""Positions along a video: the locator's stages frame after frame, with a memory.

A single video frame often shows fewer than four decodable fixtures (stripes a little longer
than one frame of chips, a light entering at the border).  :class:`Tracker` keeps what the
previous frames established and uses it in the next one:

* **the readout** found in the first striped frame, the chip length (rows per chip)
  measured by the decodes so far, and the photo-wide parameters of the stripes' model last
  fitted (chip length, exposure, response, blur), passed to the decoder: a frame pays the
  photo-wide fit only when those parameters leave a light unread;
* **whether each fixture glows**, told while it is seen whole (and whether the room's lamps
  all glow or none does): a light the border cuts is not taken for a glowing one (centred on
  its radial shape) on the strength of its own rim;
* **each fixture's ID and image position**: every map fixture is predicted in the image
  (from the track's pose, else from where it was last seen and how it moved); a fixture whose
  stripes do not decode keeps its ID when it is the only prediction within a gate of it and
  no other prediction is nearly as close; a decoded ID that lands far from where the track
  predicts that fixture is refused (IDs are never swapped between fixtures);
* **the lights as locate finds them**: every frame runs locate's stages in its order
  (:mod:`camvlp.pipeline.stages`), a glowing lamp centred on its radial shape as
  :func:`camvlp.locate` centres it;
* **the pose**: with a pose prior, two or three identified fixtures give a ``tracked`` pose
  (:func:`camvlp.geometry.pnp.refine_pose`); four or more give a ``fix`` as in
  :func:`camvlp.locate`;
* **a filter**: a constant-velocity Kalman filter on the camera centre and the thesis'
  angles smooths the track and predicts through gaps (``predicted``); after ``max_gap_s``
  without a measurement the track is ``lost`` until the next fix.
* **a site whose IDs repeat** (``reuse``): the IDs name the fixtures around the camera, each
  ID once: those in view of the track's pose, else of the place the frame's lights give
  (:mod:`camvlp.pipeline.track.site`);
* **the rolling shutter**: a fixture imaged on sensor row ``k`` was seen
  ``(k - (N - 1) / 2) * row_time`` after the frame's middle row; with the track's velocity its
  pixel is moved to where it would have been at the frame's time before solving.

Frame time convention: a frame's ``t`` is its middle sensor row's time (see
:mod:`camvlp.sim.video`); positions are the camera's at that time.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np

from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import FixtureMap
from camvlp.model.readout import Readout
from camvlp.pipeline.decode.model import SensorModel
from camvlp.pipeline.identified import Identified, identified_as, identify
from camvlp.pipeline.lamp.glow import glowing
from camvlp.pipeline.locate import StageClock
from camvlp.pipeline.paths import recording
from camvlp.pipeline.stages import (
    Decoded,
    Prepared,
    decode,
    find_lights,
    prepare,
    read_profiles,
    readout_direction,
)
from camvlp.pipeline.track.assoc import associate, known_blobs, predicted_near
from camvlp.pipeline.track.gather import LightTracks
from camvlp.pipeline.track.kalman import ConstantVelocityFilter
from camvlp.pipeline.track.motion import Motion, MotionState
from camvlp.pipeline.track.offsets import PerspectiveOffsets
from camvlp.pipeline.track.predict import (
    Sighting,
    predicted_pixels,
    remember,
    row_offset_s,
    rs_shift,
    sighted_pixels,
)
from camvlp.pipeline.track.records import (
    STATUSES,
    TrackedFixture,
    TrackFrame,
    TrackSettings,
    checked_time,
    reported_fixtures,
)
from camvlp.pipeline.track.site import SiteView, changed_ids
from camvlp.pipeline.track.solve import FrameSolve, FrameSolver, Measurements

__all__ = [
    "STATUSES",
    "ConstantVelocityFilter",
    "TrackFrame",
    "TrackSettings",
    "TrackedFixture",
    "Tracker",
]


@dataclass(frozen=True)
class _Located:
    """A frame through the locator's stages up to identification, with the track's
    prediction of every fixture's pixel (``from_pose``: predicted from the track's pose)."""

    index: int
    t: float
    prepared: Prepared
    blobs: list
    found: Identified
    predicted: dict[int, np.ndarray]
    from_pose: bool
    gathered: frozenset[int] = frozenset()
    unplaced: str = ""  # a site's frame its lights do not place: why


@dataclass(frozen=True)
class _Associated:
    """Per blob: its ID (decoded, carried or None), the ID's source, and why it is unusable."""

    ids: list[int | None]
    sources: list[str]
    reasons: list[str]


class Tracker:
    """Locate a camera frame after frame, using what the earlier frames established.

    Call :meth:`update` with each frame in order.

    Parameters
    ----------
    camera : Camera
        The video's camera (its ``row_time_s`` enables the rolling-shutter correction).
    fixture_map : FixtureMap
        The room, or a site whose IDs repeat (``reuse``: see
        :mod:`camvlp.pipeline.track.site`).
    settings : TrackSettings, optional
        How to track (defaults when None).

    Attributes
    ----------
    map : FixtureMap
        The fixtures its IDs name: the room, or a site's around the camera, each ID once.
    """

    def __init__(
        self, camera: Camera, fixture_map: FixtureMap, settings: TrackSettings | None = None
    ) -> None:
        self.camera = camera
        self.settings = settings or TrackSettings()
        st = self.settings.locate
        self._outlier_px = (
            st.outlier_px if st.outlier_px is not None else max(4.0, 0.01 * camera.focal_px)
        )
        self._gate = self.settings.gate_px or 0.03 * camera.focal_px
        self.readout: Readout | None = st.readout or camera.readout
        self._motion = Motion(camera, self.settings)
        self._site = SiteView(camera, fixture_map, self.settings) if fixture_map.reuse else None
        self._bind(fixture_map)
        self._t_given: float | None = None  # time of the last frame given to update
        self._seen: dict[int, Sighting] = {}
        self._chip_rows: list[float] = []
        self._model: SensorModel | None = None  # the photo-wide parameters last used
        self._glows: dict[int, bool] = {}  # whether each fixture glows, told when seen whole
        self._told = np.zeros(2, dtype=np.int64)  # lights told surely: plain, glowing
        self._index = 0
        self._verified: dict[int, int] = {}  # frame of each fixture's last decode
        window = self.settings.gather_frames
        gather = window > 0 and fixture_map.mode != "frequency"
        amb = self.settings.ambiguity
        self._lights = (
            LightTracks(fixture_map.frame, window, 2 * self._gate, amb) if gather else None
        )

    @property
    def filter(self) -> ConstantVelocityFilter | None:
        """The track's Kalman filter on the pose (None before the first fix, and while lost)."""
        return self._motion.filter

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
        t = checked_time(t, self._t_given)
        clock = StageClock()
        with recording() as paths:  # the special paths that run, and their time
            frame = self._locate(image, t, clock)
            assoc = self._associate(frame)
            state = self._motion.state_at(t)
            fresh = frame.from_pose and state is not None
            m = self._measurements(frame, assoc, state, fresh)
            outcome = self._solver.solve(frame.blobs, assoc.ids, m, state, fresh)
            status, reason = self._follow(outcome, t, m)
            reason = frame.unplaced if frame.unplaced and outcome.solved is None else reason
            remember(self._seen, frame.blobs, assoc.ids, t, self.settings.max_gap_s)
            clock.lap("track")
        return self._report(frame, assoc, m, outcome, status, reason, clock, paths)

    # ---------------------------------------------------------------------------------------
    # The frame's steps, in order

    def _locate(self, image: np.ndarray, t: float, clock: StageClock) -> _Located:
        """The stages of :func:`camvlp.locate`, in its order, up to identification (each
        timed on ``clock``): a video's readout, once decided, and its chip length carried from
        frame to frame; the IDs the track knows not decoded.  The frame counts (its index, its
        time) once prepared."""
        st = self.settings.locate
        prepared = prepare(image, self.camera, self.map, st)
        img = prepared.image
        index = self._index  # the frame is taken: its time and index count from here
        self._index += 1
        self._t_given = t
        clock.lap("prepare")
        predicted, from_pose = self._predict_pixels(t, img.shape[:2])
        # a site's frame that the track does not place is read in the whole site's IDs
        by_track = self._site is None or from_pose
        fmap = self.map if by_track else self._site.site
        glows = functools.partial(self._glowing, img, predicted, from_pose)
        glows = glows if self.settings.carry_glows else None
        lights = find_lights(prepared, fmap, st, readout=self.readout, glows=glows)
        if self.readout is None and lights.readout is not None:
            # the first frame that decides the direction, from now on
            self.readout = readout_direction(prepared, lights, fmap, st)
        readout = self.readout or lights.readout or Readout.ROWS
        clock.lap("detect")
        # no ID read reversed, nor along an axis the stripes do not show
        undecided = lights.readout is None or (self.readout is None and fmap.mode != "frequency")
        blobs = list(lights.blobs)
        known_ids = set() if undecided else self._known(blobs, predicted, from_pose)
        skip = set(range(len(blobs))) if undecided else known_ids
        known = dataclasses.replace(lights, readout=readout, direction_known=True)
        profiles = read_profiles(img, blobs, readout)
        clock.lap("profile")
        decoded = decode(
            prepared,
            known,
            profiles,
            fmap,
            skip=skip,
            rows_per_chip=self._rpc(),
            model=self._model,
        )
        blobs = list(decoded.blobs)
        decodes, gathered = self._gather(index, t, lights, blobs, profiles, decoded, known_ids)
        self._carry(decoded, decodes)
        found = identify(blobs, decodes, self.map) if by_track else None
        unplaced = ""
        if found is None:  # a site's frame: placed by its lights first
            place = self._site.placed(prepared, blobs, decodes, t, lights.glowing)
            unplaced = place.reason
            if place.local is None:  # no ID names a fixture: none carried either
                predicted = {}
                why = [unplaced if d.id is not None else d.reason for d in decodes]
                found = identified_as([d.id for d in decodes], why)
            else:
                self._rebind(place.local)
                predicted, _ = self._predict_pixels(t, img.shape[:2])
                found = identify(blobs, decodes, self.map)
        clock.lap("decode")
        return _Located(index, t, prepared, blobs, found, predicted, from_pose, gathered, unplaced)

    def _associate(self, frame: _Located) -> _Associated:
        """IDs per blob (see :mod:`camvlp.pipeline.track.assoc`); the decoded ones verified."""
        gate = self._gate * (1.0 if frame.from_pose else 2.0)
        ids, sources, reasons = associate(
            frame.blobs,
            frame.found.ids,
            frame.found.reasons,
            frame.predicted,
            self.map,
            gate,
            self.settings.ambiguity,
        )
        for k, src in enumerate(sources):
            if src == "decoded":
                self._verified[ids[k]] = frame.index
                sources[k] = "gathered" if k in frame.gathered else src
        return _Associated(ids, sources, reasons)

    def _measurements(
        self, frame: _Located, assoc: _Associated, state: MotionState | None, fresh: bool
    ) -> Measurements:
        """The identified, usable fixtures with their rows' times; with a fresh track and
        the rolling-shutter model, their pixels moved to the frame's time (a first guess)."""
        ids, blobs = assoc.ids, frame.blobs
        usable = [k for k in range(len(blobs)) if ids[k] is not None and not assoc.reasons[k]]
        shape = frame.prepared.image.shape[:2]
        measured = np.array([blobs[k].pixel for k in usable]).reshape(-1, 2)
        rs = self.settings.rolling_shutter and self.camera.row_time_s is not None
        dts = (
            row_offset_s(self.camera, self.readout, measured, shape)
            if rs
            else np.zeros(len(usable))
        )
        obj = np.array([self.map.get(ids[k]).position for k in usable]).reshape(-1, 3)
        pixels = measured
        if fresh and rs and len(usable):
            pixels = measured - rs_shift(self.camera, self.readout, state, obj, measured, shape)
        return Measurements(usable, obj, measured, pixels, dts)

    def _follow(self, outcome: FrameSolve, t: float, m: Measurements) -> tuple[str, str]:
        """The track after the frame: its solve fused into the filter, else the filter
        coasting on (or lost); the frame's status and reason."""
        if outcome.solved is not None:
            if self._site is not None:
                self._site.last, self._site.last_t = outcome.solved.pose.position, t
            used = outcome.used_mask
            obj, pixels, dts = m.obj[used], m.measured[used], m.dts[used]
            fix = outcome.status == "fix"
            self._motion.measure(outcome.solved, t, obj, pixels, dts, self._offsets, fix=fix)
            return outcome.status, ""
        if self._motion.filter is not None and self._motion.t_measured is not None:
            return self._motion.coast(t, outcome.reason)
        return outcome.status, outcome.reason

    def _report(
        self,
        frame: _Located,
        assoc: _Associated,
        m: Measurements,
        outcome: FrameSolve,
        status: str,
        reason: str,
        clock: StageClock,
        paths: dict,
    ) -> TrackFrame:
        """The frame as reported: the track's pose, the frame's own solve, its fixtures."""
        solved, ids = outcome.solved, assoc.ids
        used = np.flatnonzero(outcome.used_mask)
        raw_pose = None if solved is None else solved.pose
        no_pose = "" if raw_pose is not None else (reason or "no pose")
        img = frame.prepared.image
        mirror_w = img.shape[1] if frame.prepared.mirrored else None
        fixtures = reported_fixtures(
            frame.blobs, assoc.ids, assoc.sources, assoc.reasons, m.usable, used, mirror_w, no_pose
        )
        pos, euler = self._motion.current(status)
        return TrackFrame(
            index=frame.index,
            t=float(frame.t),
            status=status,
            position=pos,
            euler_deg=euler,
            raw_position=None if raw_pose is None else raw_pose.position,
            raw_euler_deg=None if raw_pose is None else self._motion.near(raw_pose.euler_deg),
            fixtures_used=tuple(int(ids[m.usable[j]]) for j in used) if solved is not None else (),
            reprojection_rms_px=math.nan if solved is None else solved.reprojection_rms_px,
            fixtures=fixtures,
            reason=reason,
            timing_ms=clock.total(),
            paths=dict(paths),
        )

    # ---------------------------------------------------------------------------------------
    # Helpers of the steps

    def _bind(self, fixture_map: FixtureMap) -> None:
        """Work on ``fixture_map`` (the room, or a site's fixtures around the camera)."""
        self.map = fixture_map
        self._fixtures = (fixture_map.id_array, fixture_map.positions)
        st = self.settings.locate
        self._offsets = PerspectiveOffsets(self.camera, fixture_map, enabled=st.correct_perspective)
        self._solver = FrameSolver(
            self.camera, fixture_map, self.settings, self._motion, self._offsets, self._outlier_px
        )

    def _rebind(self, local: FixtureMap) -> None:
        """Work on a site's fixtures ``local`` from now on; what was remembered of an ID
        that names another fixture there (or none) is forgotten."""
        gone = changed_ids(self.map, local)
        if not gone and len(local.fixtures) == len(self.map.fixtures):
            return  # the same fixtures
        for memo in (self._seen, self._glows, self._verified):
            for fid in gone & memo.keys():
                del memo[fid]
        self._bind(local)

    def _predict_pixels(
        self, t: float, shape: tuple[int, int]
    ) -> tuple[dict[int, np.ndarray], bool]:
        """Each fixture's predicted pixel (processing image): from the pose when there is a
        fresh track (in a site, of the fixtures in view of that pose, now the track's map),
        else from where it was last seen; and whether the pose was used."""
        state = self._motion.state_at(t)
        if state is not None and self._motion.fresh(t):
            if self._site is not None:
                values = state[0]
                self._rebind(self._site.around_pose(Pose.from_euler(values[:3], values[3:])))
            rolling = self.settings.rolling_shutter
            out = predicted_pixels(
                self.camera, self.readout, state, self._fixtures, shape, rolling_shutter=rolling
            )
            return out, True
        return sighted_pixels(self._seen, t, self.settings.max_gap_s), False

    def _glowing(self, img: np.ndarray, predicted, from_pose: bool, blobs) -> np.ndarray:
        """Which lights glow (``blobs``: the readable ones as detected): as each one's ring
        tells (:func:`~camvlp.pipeline.lamp.glow.glowing`), but a light whose ring does not
        tell surely (the border cuts it) as its fixture's was told in an earlier frame, when
        the track predicts that fixture alone near it; else, when two or more of the video's
        lights were told surely so far and all alike (all plain, or all glowing), as they
        were (a room's lamps are alike; one entering the picture is not yet known).  The
        fixtures' glows told surely here are remembered."""
        which, told = glowing(img, blobs)
        self._told += np.bincount(which[told].astype(np.int64), minlength=2)
        plain, glows = self._told
        alike = bool(glows) if min(plain, glows) == 0 and plain + glows >= 2 else None
        gate = self._gate * (1.0 if from_pose else 2.0)
        for k, b in enumerate(blobs):
            fid = predicted_near(b, predicted, gate, self.settings.ambiguity)
            if told[k]:
                if fid is not None:
                    self._glows[fid] = bool(which[k])
            elif fid is not None and fid in self._glows:
                which[k] = self._glows[fid]
            elif alike is not None:
                which[k] = alike
        return which

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

    def _gather(self, index, t, lights, blobs, profiles, decoded: Decoded, known):
        """The frame's decodes with the IDs its lights' gathered chips say (their profiles as
        read, ``profiles``)
        (:mod:`camvlp.pipeline.track.gather`), and the lights given one; the readout's
        direction taken when the gathered chips say it."""
        decodes = list(decoded.decodes)
        if self._lights is None or lights.readout is None:
            return decodes, frozenset()
        rpc = self._rpc()
        if rpc is None and self.camera.row_time_s and self.map.chip_rate_hz:
            rpc = 1.0 / (self.camera.row_time_s * self.map.chip_rate_hz)
        readout = self.readout or lights.readout
        got = self._lights.gather(
            index,
            t,
            blobs,
            lights.readable,
            profiles.profiles,
            readout,
            decodes,
            known=known,
            reversed_readout=None if self.readout is None else self.readout.reversed,
            rows_per_chip=rpc,
        )
        if self.readout is None and got.reversed is not None:
            self.readout = Readout.of(readout.axis, got.reversed)
        return got.decodes, frozenset(got.gathered)

    def _carry(self, decoded: Decoded, decodes) -> None:
        """Remember the chip lengths of the IDs read (``decodes``, the last 50), and the
        photo-wide parameters the decoder used, when it used any
        (:attr:`TrackSettings.carry_model`)."""
        for d in decodes:
            if d.id is not None and np.isfinite(d.rows_per_chip):
                self._chip_rows.append(float(d.rows_per_chip))
        del self._chip_rows[:-50]
        man = decoded.manchester
        if self.settings.carry_model and man is not None and man.model is not None:
            self._model = man.model
