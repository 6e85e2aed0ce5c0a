"""The tracker's settings and its answers: :class:`TrackSettings`, :class:`TrackFrame` per
frame, :class:`TrackedFixture` per blob (re-exported by :mod:`camvlp.pipeline.track.tracker`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from camvlp.errors import InputError
from camvlp.io.files import MAX_MAGNITUDE
from camvlp.pipeline.locate import LocateSettings
from camvlp.pipeline.paths import PathTime

__all__ = [
    "STATUSES",
    "TrackFrame",
    "TrackSettings",
    "TrackedFixture",
    "checked_time",
    "reported_fixtures",
]

#: Per-frame statuses, best first.
STATUSES = ("fix", "tracked", "predicted", "lost")


@dataclass(frozen=True, kw_only=True)
class TrackSettings:
    """Tuning of :class:`camvlp.pipeline.track.tracker.Tracker`.

    Attributes
    ----------
    locate : LocateSettings
        The locator's settings (solver, outlier tolerance, detector sizes, readout); its
        ``max_position_sigma`` is not applied (the tracker works out no position sigma).
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
        Uncertainty of the first fix's position (the filter's start), map units.
    fix_sigma_deg : float
        Uncertainty of the first fix's angles, degrees.
    pixel_sigma : float
        Uncertainty of a fixture's centre in the image, pixels: every later fix or tracked
        pose enters the filter as its fixtures' pixels (an iterated extended Kalman update,
        so that what two or three fixtures leave open keeps the track's prediction).
    tilt_window : int
        Fixes whose tilts (theta_x, theta_y) give a tracked pose its tilt prior: their mean,
        with their spread (at least ``min_tilt_sigma_deg``) as its uncertainty.
    min_tilt_sigma_deg : float
        Smallest uncertainty of that tilt prior, degrees.
    rolling_shutter : bool
        Correct each fixture's pixel for the camera's motion between its row and the frame's
        middle row (needs the camera's ``row_time_s``).
    carry_chip_length : bool
        Pass the chip length measured in earlier frames to the decoder.
    carry_model : bool
        Pass the photo-wide parameters of the stripes' model (chip length, exposure, sensor
        response, blur) last fitted to a frame to the next frames' decoder, which fits them
        anew only when they leave a light that spans a frame of the code without an ID.
    carry_glows : bool
        Tell whether a light the border cuts glows (and is centred on its radial shape) by
        its fixture's glow as told in an earlier frame that showed it whole, when the track
        predicts that fixture alone near it, else by the video's lights told so far when two
        or more were and all alike (its own ring may read as a glow: the round outline of a
        cut disc can be smaller than the disc).
    verify_every : int
        A blob that the track's pose identifies without doubt (the only prediction within the
        gate) is not decoded again while its fixture's stripes were decoded in the last
        ``verify_every`` frames (1: decode every blob in every frame).
    gather_frames : int
        Each light that shows less than a frame of its code gathers the pieces it shows from
        frame to frame (:mod:`camvlp.pipeline.track.gather`), and those of its last
        ``gather_frames`` frames give it an ID once they hold a whole frame that fits one ID
        as surely as a whole frame would (:mod:`camvlp.pipeline.decode.partial`); 0 turns
        the gathering off.
    relocate_speed_m_s : float
        In a map whose IDs repeat (``reuse``), a frame placed anew (the track lost) is looked
        for near the last place the track knew first, as far as the camera can have gone
        since at this speed (metres per second; a person walks at 1.5), then over the whole
        map (:mod:`camvlp.pipeline.track.site`).
    """

    locate: LocateSettings = field(default_factory=LocateSettings)
    gate_px: float | None = None
    ambiguity: float = 2.0
    min_tracked: int = 2
    max_gap_s: float = 0.5
    accel_sigma: float = 3.0
    angular_accel_sigma_deg: float = 250.0
    fix_sigma: float = 0.002
    fix_sigma_deg: float = 0.05
    pixel_sigma: float = 0.5
    tilt_window: int = 90
    min_tilt_sigma_deg: float = 0.02
    rolling_shutter: bool = True
    carry_chip_length: bool = True
    carry_model: bool = True
    carry_glows: bool = True
    verify_every: int = 10
    gather_frames: int = 12
    relocate_speed_m_s: float = 2.0

    def __post_init__(self) -> None:
        for name in (
            "ambiguity",
            "max_gap_s",
            "accel_sigma",
            "angular_accel_sigma_deg",
            "fix_sigma",
            "fix_sigma_deg",
            "pixel_sigma",
            "relocate_speed_m_s",
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
        if isinstance(self.gather_frames, bool) or not (
            isinstance(self.gather_frames, int) and self.gather_frames >= 0
        ):
            raise ValueError(f"gather_frames must be 0 or more, got {self.gather_frames!r}")


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
        Where its ID came from: ``"decoded"`` (its stripes), ``"gathered"`` (the pieces of
        code its stripes showed over several frames), ``"carried"`` (the track), or ``""``
        (no ID).
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
        Milliseconds (wall time) per stage: ``prepare``, ``detect``, ``profile``, ``decode``
        (locate's stages, :mod:`camvlp.pipeline.stages`), ``track`` (association, glowing
        lights centred, solve, filter), and their ``total``.
    paths : dict
        The special paths that ran on the frame (the photo-wide model fit, the model
        decoder, ...: :mod:`camvlp.pipeline.paths`), name -> ``PathTime(calls, ms)``.
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
    paths: dict[str, PathTime] = field(default_factory=dict)

    @classmethod
    def lost(cls, index: int, t: float, reason: str) -> TrackFrame:
        """A frame with nothing known (unreadable, or before the first fix)."""
        return cls(index, t, "lost", None, None, None, None, (), math.nan, (), reason, {})


def reported_fixtures(
    blobs, ids, sources, reasons, usable, used, mirror_width: int | None, no_pose: str
) -> tuple[TrackedFixture, ...]:
    """A frame's blobs as reported, one :class:`TrackedFixture` each.

    ``ids``, ``sources`` and ``reasons`` are per blob (its ID or None, where the ID came
    from, why it is unusable); ``usable`` the indices of the usable blobs and ``used``
    indices into ``usable`` of those the pose uses; pixels are given in the photo as given
    (flipped back when ``mirror_width``, the mirrored image's width in pixels, is given);
    ``no_pose`` says why identified fixtures are unused when there is no pose ("" when
    there is one)."""
    used_set = {usable[j] for j in used}
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


def checked_time(t: object, previous: float | None) -> float:
    """A frame's time ``t`` as a float when it is a finite time within +-1e9 s and later than
    the ``previous`` frame's (s; None for the first frame); InputError otherwise."""
    if isinstance(t, bool) or not isinstance(t, (int, float, np.integer, np.floating)):
        raise InputError(f"t must be a number of seconds, got {type(t).__name__}")
    value = float(t)
    if not (math.isfinite(value) and abs(value) <= MAX_MAGNITUDE):
        raise InputError(f"t must be a finite time within +-{MAX_MAGNITUDE:g} s, got {t!r}")
    if previous is not None and not value > previous:
        raise InputError(f"t must increase from frame to frame: {value!r} s after {previous!r} s")
    return value
