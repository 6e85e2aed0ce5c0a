"""What :func:`camvlp.pipeline.locate.locate` returns: the result, each fixture's, the stages."""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from camvlp.geometry.disc import centre_sigma
from camvlp.model.camera import Pose
from camvlp.model.readout import Readout
from camvlp.pipeline.decode.result import StripeDecode
from camvlp.pipeline.detect.blob import EllipseFit
from camvlp.pipeline.detect.candidates import Detection
from camvlp.pipeline.paths import PathTime

__all__ = ["FixtureResult", "LocateResult", "LocateStages"]


@dataclass(frozen=True)
class FixtureResult:
    """One fixture seen in the photo.

    Attributes
    ----------
    id : int or None
        Its ID (Manchester mode) or map index (frequency mode); None when not identified.
    pixel : ndarray, shape (2,)
        Centre of its disc in the photo as given (before any mirroring), pixels.
    used : bool
        Whether the pose uses it.
    margin : float
        How sure the ID is: the decimal log of the likelihood ratio of the ID over the best
        other ID (or frequency) of the map (4: ten thousand times likelier; the model fit needs
        4, a frequency 5.4; see :class:`~camvlp.pipeline.decode.result.StripeDecode`).  NaN
        when the run-length decoder read the ID: see ``run_margin``.
    run_margin : float
        The run-length decoder's confidence, 0 to 1 (it takes an ID from 0.3 on, with no chip
        in error); NaN when another decoder read the stripes.
    reason : str
        Why it is not used ("" when used).
    hamming : int
        Chips that disagreed with the decoded ID (-1 when none were read, i.e. the model fit
        decoded it).
    rows_spanned : float
        Extent of the disc along the readout axis, pixels.
    rows_per_chip : float
        Measured chip length, sensor rows (NaN when not measured).
    residual_px : float
        Reprojection error with the final pose, pixels (NaN without a pose).
    frequency_hz : float
        Measured blinking frequency (frequency mode), Hz; NaN otherwise.
    centre_sigma_px : float
        Uncertainty of ``pixel`` estimated from the disc's ellipse fit, pixels (1-sigma per
        axis; NaN when the disc was too small to fit).  Worked out when first read, from
        ``edge_fit`` (:class:`~camvlp.pipeline.detect.blob.EllipseFit`).
    look_alikes : tuple of int
        When the stripes fit two or more IDs of the map almost equally and the pose told
        them apart (:mod:`camvlp.pipeline.identify.by_pose`): those IDs, ``id`` among them (the one
        whose map position projects onto the fixture).  Empty when the stripes alone said
        the ID (``margin`` is then the stripes' own).
    """

    id: int | None
    pixel: np.ndarray
    used: bool
    margin: float
    reason: str
    hamming: int = -1
    run_margin: float = float("nan")
    rows_spanned: float = float("nan")
    rows_per_chip: float = float("nan")
    residual_px: float = float("nan")
    frequency_hz: float = float("nan")
    look_alikes: tuple[int, ...] = ()
    edge_fit: EllipseFit | None = field(default=None, repr=False, compare=False)

    @functools.cached_property
    def centre_sigma_px(self) -> float:
        """See the class' attributes."""
        if self.edge_fit is None:
            return float("nan")
        return centre_sigma(self.edge_fit.covariance)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (NaN becomes null); ``reason`` is always there ("" when used)."""
        d: dict[str, Any] = {
            "id": self.id,
            "pixel": [round(float(v), 3) for v in self.pixel],
            "used": self.used,
            "margin": None if not np.isfinite(self.margin) else round(self.margin, 3),
            "reason": self.reason,
        }
        keys = ("hamming", "run_margin", "rows_spanned", "rows_per_chip", "residual_px")
        for key in (*keys, "frequency_hz"):
            v = getattr(self, key)
            if isinstance(v, float):
                v = None if not np.isfinite(v) else round(v, 3)
            d[key] = v
        sigma = self.centre_sigma_px
        d["centre_sigma_px"] = None if not np.isfinite(sigma) else round(float(sigma), 4)
        d["look_alikes"] = [int(i) for i in self.look_alikes]
        return d


@dataclass(frozen=True)
class LocateResult:
    """Where the camera is, or why it could not be located.

    Attributes
    ----------
    position : ndarray, shape (3,), or None
        Camera centre in the map's units and frame; None when not located.
    rotation : ndarray, shape (3, 3), or None
        Camera-to-world rotation (the camera's axes, in world coordinates, as columns).
    euler_deg : ndarray, shape (3,), or None
        The thesis' angles ``(theta_x, theta_y, theta_z)``, degrees.
    reprojection_rms_px : float
        RMS reprojection error over the fixtures used, pixels (NaN when not located).
    fixtures : tuple of FixtureResult
        Every fixture detected, identified or not.
    timing_ms : dict
        Milliseconds per stage: ``prepare``, ``detect``, ``profile``, ``decode``, ``pose``,
        and their ``total``.
    paths : dict
        The special paths that ran (a glowing lamp's radial fit, the photo-wide model fit,
        ...: :mod:`camvlp.pipeline.paths`), each with its calls and time, milliseconds
        (inclusive: a path run within another counts in both); empty for a photo of plain
        discs read by the run-length decoder.
    reason : str
        Why it was not located ("" when it was).  (``error`` is the same, its old name.)
    readout : Readout
        The readout the stripes were read with.
    mirrored : bool
        The image was flipped left-right before locating.
    alternative_position : ndarray, shape (3,), or None
        The next best pose (another local minimum of the reprojection error: the planar
        ambiguity's other pose, or another), when there is one; of a photo refused because
        two poses fit about equally, the second of the two.
    alternative_rms_px : float
        Its reprojection RMS, pixels.
    pose_margin : float
        How much better the pose fits than the alternative, ``1 - SSR / SSR_alternative``
        (sums of squared reprojection errors): near 0 when both fit alike; 1 without an
        alternative; NaN when no pose was solved.
    notes : tuple of str
        Remarks on how the photo was read (e.g. a row time fitted from frequency ratios).
    rows_per_chip : float
        The photo's chip length, sensor rows, fitted to all fixtures (NaN in frequency mode).
    exposure_chips : float
        The photo's exposure window, chips, fitted to all fixtures (NaN in frequency mode,
        and when the run-length decoder read every fixture so that no model was fitted).
    stages : LocateStages or None
        Intermediate results, with ``LocateSettings(keep_stages=True)``.
    solver : str
        How the pose was solved: ``"pnp"`` (four or more fixtures, no gravity), or with a
        gravity direction ``"gravity-2"``, ``"gravity-3"`` or ``"pnp+gravity"`` (see
        :data:`camvlp.geometry.gravity.SOLVER_NAMES`); ``"gravity"`` when gravity was given
        but too few fixtures were identified to try.
    tilt_disagreement_deg : float
        With gravity and four or more fixtures: the angle between the down of the pose the
        pixels alone give and the measured gravity, degrees (NaN otherwise).
    gravity_residual_deg : float
        With gravity: the angle between the located pose's down and the measured gravity,
        degrees (NaN otherwise).
    position_sigma : ndarray, shape (3,), or None
        How sure the position is: its standard deviation along the map's x, y and z, map
        units, from the fixtures' reprojection errors and what their layout makes of a pixel
        (:func:`camvlp.geometry.pose_sigma.position_sigma`); for a pose solved with gravity,
        from the centres' and the gravity's sigmas
        (:func:`camvlp.geometry.pose_sigma.gravity_position_sigma`).  Worked out when first
        read (``sigma_of``, a function of no arguments that gives it).  None when not
        located, or when it is not finite.
    """

    position: np.ndarray | None
    rotation: np.ndarray | None
    euler_deg: np.ndarray | None
    reprojection_rms_px: float
    fixtures: tuple[FixtureResult, ...]
    timing_ms: dict[str, float]
    paths: dict[str, PathTime] = field(default_factory=dict)
    reason: str = ""
    readout: Readout = Readout.ROWS
    mirrored: bool = False
    alternative_position: np.ndarray | None = None
    alternative_rms_px: float = float("nan")
    pose_margin: float = float("nan")
    notes: tuple[str, ...] = field(default_factory=tuple)
    rows_per_chip: float = float("nan")
    exposure_chips: float = float("nan")
    stages: LocateStages | None = field(default=None, repr=False, compare=False)
    solver: str = "pnp"
    tilt_disagreement_deg: float = float("nan")
    gravity_residual_deg: float = float("nan")
    sigma_of: Callable[[], np.ndarray | None] | None = field(
        default=None, repr=False, compare=False
    )

    @functools.cached_property
    def position_sigma(self) -> np.ndarray | None:
        """See the class' attributes."""
        return None if self.sigma_of is None else self.sigma_of()

    @property
    def fixtures_used(self) -> int:
        """How many fixtures the pose uses."""
        return sum(f.used for f in self.fixtures)

    def __bool__(self) -> bool:
        return self.position is not None

    @property
    def error(self) -> str:
        """Why it was not located: the same as ``reason`` (its former name)."""
        return self.reason

    @property
    def pose(self) -> Pose | None:
        """The pose as a :class:`Pose`, or None."""
        if self.position is None or self.rotation is None:
            return None
        return Pose(self.rotation, self.position)

    def to_dict(self) -> dict[str, Any]:
        """The JSON object of ``camvlp locate --json``."""

        def arr(a, nd=6):
            return None if a is None else np.round(np.asarray(a, dtype=float), nd).tolist()

        d: dict[str, Any] = {
            "position": arr(self.position),
            "rotation": arr(self.rotation, 8),
            "euler_deg": arr(self.euler_deg, 4),
            "reprojection_rms_px": None
            if not np.isfinite(self.reprojection_rms_px)
            else round(self.reprojection_rms_px, 4),
            "position_sigma": arr(self.position_sigma),
            "fixtures": [f.to_dict() for f in self.fixtures],
            "timing_ms": {k: round(v, 2) for k, v in self.timing_ms.items()},
            "paths": {k: {"calls": p.calls, "ms": round(p.ms, 2)} for k, p in self.paths.items()},
            "readout": str(self.readout),
            "mirrored": self.mirrored,
            "solver": self.solver,
            "fixtures_used": self.fixtures_used,
        }
        for key in ("tilt_disagreement_deg", "gravity_residual_deg", "pose_margin"):
            v = getattr(self, key)
            if np.isfinite(v):
                d[key] = round(float(v), 4)
        for key in ("rows_per_chip", "exposure_chips"):
            v = getattr(self, key)
            d[key] = None if not np.isfinite(v) else round(float(v), 4)
        if self.alternative_position is not None:
            d["alternative"] = {
                "position": arr(self.alternative_position),
                "reprojection_rms_px": round(self.alternative_rms_px, 4),
            }
        if self.notes:
            d["notes"] = list(self.notes)
        if self.reason:
            d["error"] = self.reason
        return d


@dataclass(frozen=True)
class LocateStages:
    """Intermediate results of :func:`locate`, kept for the debug pictures.

    Attributes
    ----------
    detection : Detection
        The detector's output (blobs in the possibly mirrored image).
    gray_rois : tuple of ndarray, each (h, w) uint8
        Each blob's region of interest, gray.
    profiles : tuple of ndarray, each (n,)
        Each blob's row profile, in the order the sensor read it.
    decodes : tuple of StripeDecode
        Each blob's decode (the model fit's in Manchester mode).
    profile_weights : tuple of ndarray, each (n,)
        Each profile's row weights, in the same order: the inverse of each row's variance
        under pixels of equal noise, up to a constant
        (:func:`~camvlp.pipeline.decode.profile.shape_profiles`).
    beacons : tuple of tuple
        Frequency mode: each light's beacon profile, its test against the map's frequencies
        and the map's periods (:func:`~camvlp.pipeline.decode.frequency.decode_frequencies`).
    """

    detection: Detection
    gray_rois: tuple[np.ndarray, ...]
    profiles: tuple[np.ndarray, ...]
    decodes: tuple[StripeDecode, ...]
    profile_weights: tuple[np.ndarray, ...] = ()
    beacons: tuple = ()
