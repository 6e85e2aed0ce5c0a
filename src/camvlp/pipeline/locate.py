"""The whole pipeline: photograph -> fixtures -> IDs -> map -> pose (thesis chapter 5).

:func:`locate` runs the stages in order, each a function of its own here: prepare the image,
detect the fixtures, cut each one's row profile, decode (Manchester IDs or frequencies),
identify them in the map, solve the pose, and report every fixture.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from camvlp.errors import InputError
from camvlp.geometry.disc import disc_normals, perspective_offset
from camvlp.geometry.gravity import (
    GravityPose,
    check_gravity,
    check_gravity_view,
    map_up,
    solve_pose_gravity,
)
from camvlp.geometry.pnp import check_solver
from camvlp.io.images import as_image
from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import FixtureMap
from camvlp.model.readout import Readout
from camvlp.pipeline.decode import StripeDecode, decode_profile, row_profile
from camvlp.pipeline.detect import Blob, Detection, detect_fixtures, to_gray
from camvlp.pipeline.frequency import decode_frequencies
from camvlp.pipeline.model_decode import ModelDecode, PhotoDecode, decode_photo
from camvlp.pipeline.pose import PoseEstimate, estimate_pose

__all__ = ["FixtureResult", "LocateResult", "LocateSettings", "LocateStages", "locate"]


@dataclass(frozen=True)
class LocateSettings:
    """Tuning options of :func:`locate` (all keyword-only with defaults).

    Attributes
    ----------
    solver : str
        OpenCV PnP solver for the first estimate: iterative, sqpnp, ippe or epnp.
    outlier_px : float or None
        Reprojection error (pixels) beyond which a fixture does not fit the pose: dropped
        with five or more fixtures, a failure with four.  None: 1 % of the focal length and
        at least 4 px (39 px for the thesis' camera), which tolerates map errors of a few
        centimetres while a wrong ID or a moved light misses by far more.
    kernel_px : int
        Smallest closing length of the detector, full-resolution pixels.
    min_diameter_px : float
        Smallest fixture image considered, pixels.
    readout : Readout, str or None
        Readout ("rows", "columns", "rows-reversed", "columns-reversed"; see
        :class:`camvlp.model.readout.Readout`); None takes the camera's, else finds the axis
        from the stripes (forward).
    mirrored : bool or None
        Flip the image left-right first; None takes the camera file's ``mirrored``.
    correct_perspective : bool
        Correct each disc's centre for the offset between an ellipse's centre and the
        projected centre of the disc (needs the map's diameters), then solve again.
    keep_stages : bool
        Keep the intermediate results (:class:`LocateStages`) in the result's ``stages``, for
        debug pictures.
    gravity_sigma_deg : float
        Uncertainty of a gravity direction given to :func:`locate`, degrees: weighs the
        gravity residual against the reprojection residuals.
    centre_sigma_px : float
        With gravity: the uncertainty of a detected disc centre, pixels, which weighs the
        reprojection residuals against the gravity residual.  1 px suits real photos; the
        simulator's are good to a few hundredths of a pixel.
    """

    solver: str = "iterative"
    outlier_px: float | None = None
    kernel_px: int = 16
    min_diameter_px: float = 8.0
    readout: Readout | None = None
    mirrored: bool | None = None
    correct_perspective: bool = True
    keep_stages: bool = False
    gravity_sigma_deg: float = 1.0
    centre_sigma_px: float = 1.0

    def __post_init__(self) -> None:
        check_solver(self.solver)
        for name in ("gravity_sigma_deg", "centre_sigma_px"):
            sigma = getattr(self, name)
            if isinstance(sigma, bool) or not (
                isinstance(sigma, (int, float)) and np.isfinite(sigma) and sigma > 0
            ):
                raise InputError(f"{name} must be a positive number, got {sigma!r}")
        object.__setattr__(self, "readout", Readout.parse_optional(self.readout))


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
        Decoding confidence: for Manchester IDs the decimal log of the likelihood ratio of
        the ID over the best other ID of the map (see
        :class:`camvlp.pipeline.model_decode.ModelDecode`; IDs need 4 or more); for
        frequencies, in [0, 1], how close the measured frequency is to the map's.
    reason : str
        Why it is not used ("" when used).
    hamming : int
        Chips that disagreed with the decoded ID (-1 when none were read).
    rows_spanned : float
        Extent of the disc along the readout axis, pixels.
    rows_per_chip : float
        Measured chip length, sensor rows (NaN when not measured).
    residual_px : float
        Reprojection error with the final pose, pixels (NaN without a pose).
    frequency_hz : float
        Measured blinking frequency (frequency mode), Hz; NaN otherwise.
    """

    id: int | None
    pixel: np.ndarray
    used: bool
    margin: float
    reason: str
    hamming: int = -1
    rows_spanned: float = float("nan")
    rows_per_chip: float = float("nan")
    residual_px: float = float("nan")
    frequency_hz: float = float("nan")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (NaN becomes null); ``reason`` is always there ("" when used)."""
        d: dict[str, Any] = {
            "id": self.id,
            "pixel": [round(float(v), 3) for v in self.pixel],
            "used": self.used,
            "margin": round(self.margin, 3),
            "reason": self.reason,
        }
        for key in ("hamming", "rows_spanned", "rows_per_chip", "residual_px", "frequency_hz"):
            v = getattr(self, key)
            if isinstance(v, float):
                v = None if not np.isfinite(v) else round(v, 3)
            d[key] = v
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
        Milliseconds per stage: ``detect``, ``decode``, ``pose``, ``total``.
    reason : str
        Why it was not located ("" when it was).  (``error`` is the same, its old name.)
    readout : Readout
        The readout the stripes were read with.
    mirrored : bool
        The image was flipped left-right before locating.
    alternative_position : ndarray, shape (3,), or None
        The other pose of a planar target's two-fold ambiguity, when it exists.
    alternative_rms_px : float
        Its reprojection RMS, pixels.
    notes : tuple of str
        Remarks on how the photo was read (e.g. a row time fitted from frequency ratios).
    rows_per_chip : float
        The photo's chip length, sensor rows, fitted to all fixtures (NaN in frequency mode).
    exposure_chips : float
        The photo's exposure window, chips, fitted to all fixtures (NaN in frequency mode).
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
    """

    position: np.ndarray | None
    rotation: np.ndarray | None
    euler_deg: np.ndarray | None
    reprojection_rms_px: float
    fixtures: tuple[FixtureResult, ...]
    timing_ms: dict[str, float]
    reason: str = ""
    readout: Readout = Readout.ROWS
    mirrored: bool = False
    alternative_position: np.ndarray | None = None
    alternative_rms_px: float = float("nan")
    notes: tuple[str, ...] = field(default_factory=tuple)
    rows_per_chip: float = float("nan")
    exposure_chips: float = float("nan")
    stages: LocateStages | None = field(default=None, repr=False, compare=False)
    solver: str = "pnp"
    tilt_disagreement_deg: float = float("nan")
    gravity_residual_deg: float = float("nan")

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
            "fixtures": [f.to_dict() for f in self.fixtures],
            "timing_ms": {k: round(v, 2) for k, v in self.timing_ms.items()},
            "readout": str(self.readout),
            "mirrored": self.mirrored,
            "solver": self.solver,
            "fixtures_used": self.fixtures_used,
        }
        for key in ("tilt_disagreement_deg", "gravity_residual_deg"):
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
    decodes : tuple of ModelDecode or StripeDecode
        Each blob's decode (the model fit's in Manchester mode).
    """

    detection: Detection
    gray_rois: tuple[np.ndarray, ...]
    profiles: tuple[np.ndarray, ...]
    decodes: tuple[ModelDecode | StripeDecode, ...]


def _check_arguments(camera: object, fixture_map: object, settings: object) -> None:
    for name, value, kind in (
        ("camera", camera, Camera),
        ("fixture_map", fixture_map, FixtureMap),
        ("settings", settings, (LocateSettings, type(None))),
    ):
        if not isinstance(value, kind):
            wanted = "LocateSettings or None" if name == "settings" else kind.__name__
            raise InputError(f"{name} must be a {wanted}, got {type(value).__name__}")


def _check_image(image: np.ndarray, camera: Camera) -> np.ndarray:
    img = as_image(image)
    if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] not in (1, 3, 4)):
        raise InputError(f"image must be (H, W) gray or (H, W, 3) BGR, got shape {img.shape}")
    h, w = img.shape[:2]
    if (w, h) != (camera.width, camera.height):
        hint = (
            " (rotated? the camera file describes the other orientation)"
            if (h, w)
            == (
                camera.width,
                camera.height,
            )
            else ""
        )
        raise InputError(
            f"image is {w} x {h} but the camera file says {camera.width} x {camera.height}{hint}"
        )
    return img


def _extent(blob: Blob, axis: str) -> float:
    """Sensor rows a detected disc spans along the readout axis ("rows" or "columns")."""
    m = blob.mask if axis == "rows" else blob.mask.T
    r = np.flatnonzero(m.any(axis=1))
    return float(r[-1] - r[0] + 1) if r.size else 0.0


def _decode_frequencies(
    blobs, gray_rois, extents: np.ndarray, axis: str, camera: Camera, fixture_map: FixtureMap
) -> tuple[list[StripeDecode], np.ndarray, str]:
    """Identify frequency-coded fixtures from their stripe periods (see ``frequency.py``)."""
    return decode_frequencies(blobs, gray_rois, axis, camera, fixture_map)


@dataclass(frozen=True)
class _Identified:
    """The identify stage: each blob's ID (or None) and why it cannot be used ("" if it can)."""

    ids: tuple[int | None, ...]
    reasons: tuple[str, ...]
    usable: tuple[int, ...]  # indices of blobs with an ID and no reason


def _prepare(image: np.ndarray, camera: Camera, st: LocateSettings) -> tuple[np.ndarray, bool]:
    """Stage 0: the checked image, flipped left-right when the photo is mirrored."""
    img = _check_image(image, camera)
    mirrored = camera.mirrored if st.mirrored is None else bool(st.mirrored)
    return (img[:, ::-1] if mirrored else img), mirrored


def _detect(
    img: np.ndarray, given: Readout | None, st: LocateSettings
) -> tuple[Detection, Readout]:
    """Stage 1: the fixtures, and the readout (given, else the axis most striped blobs show)."""
    detection = detect_fixtures(
        img,
        readout=None if given is None else given.axis,
        kernel_px=st.kernel_px,
        min_diameter_px=st.min_diameter_px,
    )
    if given is not None:
        return detection, given
    blobs = detection.blobs
    striped = [b for b in blobs if b.stripe_contrast > 2.0] or list(blobs)
    votes = [b.axis for b in striped]
    axis = max(set(votes), key=votes.count) if votes else "rows"
    return detection, Readout.of(axis)


def _profiles(
    img: np.ndarray, blobs, readout: Readout
) -> tuple[list[np.ndarray], np.ndarray, list[np.ndarray]]:
    """Stage 2: each blob's gray region, its extent along the readout (rows) and row profile.

    Each profile is in the order the sensor read it (reversed for a reversed readout).
    """
    gray_rois = [to_gray(img[b.box[1] : b.box[3], b.box[0] : b.box[2]]) for b in blobs]
    extents = np.array([_extent(b, readout.axis) for b in blobs])
    step = -1 if readout.reversed else 1
    profiles = [
        row_profile(g, b.mask, readout.axis)[0][::step]
        for b, g in zip(blobs, gray_rois, strict=True)
    ]
    return gray_rois, extents, profiles


def _rows_per_chip_seed(camera: Camera, fixture_map: FixtureMap, profiles) -> float | None:
    """Chip length in rows to start from: the camera's row time and the map's chip rate when
    both are known, else the run-length decoder's measurement when two fixtures agree."""
    if camera.row_time_s and fixture_map.chip_rate_hz:
        return 1.0 / (camera.row_time_s * fixture_map.chip_rate_hz)
    quick = [decode_profile(p, fixture_map.frame) for p in profiles]
    t = np.array([d.rows_per_chip for d in quick if d and np.isfinite(d.rows_per_chip)])
    if t.size >= 2:
        med = float(np.median(t))
        if np.sum(np.abs(t / med - 1) < 0.03) >= 2:
            return med
    return None


@dataclass(frozen=True)
class _Manchester:
    """The Manchester decode of a photo (internal): per direction when it had to be chosen."""

    photo: PhotoDecode
    readout: Readout
    other: PhotoDecode | None = None  # the decode under the other direction, when it was tried
    note: str = ""


def _decode_manchester(
    profiles, readout: Readout, direction_known: bool, camera: Camera, fixture_map: FixtureMap
) -> _Manchester:
    """Model-based decode of every profile with photo-wide parameters (see ``model_decode``).

    When the readout's direction is not known, the profiles are decoded both ways (first with
    one way's parameters, refitted if that does not decide).  A reversed frame is no frame for
    half the IDs: a direction is taken when it gives more clear IDs (of the map or not) and
    fits the map's IDs better; otherwise both are kept for the pose to decide.
    """
    ids = fixture_map.ids
    seed = _rows_per_chip_seed(camera, fixture_map, profiles)
    fwd = decode_photo(profiles, fixture_map.frame, ids, rows_per_chip=seed)
    if direction_known:
        return _Manchester(fwd, readout)
    backwards = [p[::-1] for p in profiles]
    flipped = Readout.of(readout.axis, not readout.reversed)

    def better(a: PhotoDecode, b: PhotoDecode) -> bool:
        # read the wrong way, a fixture whose backwards frame is no frame (half the IDs)
        # reads as no clear ID: the right way gives more clear IDs (of the map or not) and
        # fits the map's IDs better
        def clear(p: PhotoDecode) -> int:
            return sum(d.id is not None or d.outside_id is not None for d in p.decodes)

        return clear(a) > clear(b) and a.fit_cost < b.fit_cost

    # the parameters do not depend on the direction: first try the other way with them
    back = decode_photo(backwards, fixture_map.frame, ids, model=fwd.model)
    if better(fwd, back):
        return _Manchester(fwd, readout)
    # refitted, from this way's chip length (it does not depend on the direction either)
    t_fwd = fwd.model.rows_per_chip if np.isfinite(fwd.cost) else seed
    back = decode_photo(backwards, fixture_map.frame, ids, rows_per_chip=t_fwd)
    if better(fwd, back):
        return _Manchester(fwd, readout)
    if better(back, fwd):
        return _Manchester(back, flipped)
    # the counts tie (every fixture seen has an ID whose backwards frame is another's): the
    # pose decides
    return _Manchester(fwd, readout, other=back)


def _decode(
    blobs, gray_rois, extents, profiles, readout: Readout, camera: Camera, fixture_map: FixtureMap
) -> tuple[list, np.ndarray, list[str]]:
    """Stage 3 with the readout taken as known: each blob's decode, measured frequencies (Hz,
    NaN in Manchester mode), notes.  (:func:`locate` itself decides an unknown direction.)"""
    if fixture_map.mode != "frequency":
        man = _decode_manchester(profiles, readout, True, camera, fixture_map)
        return list(man.photo.decodes), np.full(len(blobs), np.nan), []
    decodes, frequencies, note = _decode_frequencies(
        blobs, gray_rois, extents, readout.axis, camera, fixture_map
    )
    return decodes, frequencies, [note] if note else []


def _identify(blobs, decodes, fixture_map: FixtureMap) -> _Identified:
    """Stage 4: IDs looked up in the map; cut discs, unknown and repeated IDs set aside."""
    reasons: list[str] = []
    ids: list[int | None] = []
    for b, dec in zip(blobs, decodes, strict=True):
        fid, reason = dec.id, dec.reason
        outside = getattr(dec, "outside_id", None)
        if fid is None and outside is not None:  # a light that sends an ID the map lacks
            ids.append(outside)
            reasons.append(f"ID {outside} is not in the map")
            continue
        if fid is not None and fixture_map.get(fid) is None:
            reason, fid = f"ID {dec.id} is not in the map", None
        elif fid is not None and b.touches_border:
            reason = "cut by the image border (its centre would be biased)"
        ids.append(dec.id if fid is None and dec.id is not None else fid)
        reasons.append(reason)
    # the same ID twice: neither can be trusted
    decoded = [i for i, r in zip(ids, reasons, strict=True) if i is not None and not r]
    for k, (i, r) in enumerate(zip(ids, reasons, strict=True)):
        if i is not None and not r and decoded.count(i) > 1:
            reasons[k] = f"ID {i} was decoded for two fixtures"
    usable = tuple(k for k, r in enumerate(reasons) if ids[k] is not None and not r)
    return _Identified(tuple(ids), tuple(reasons), usable)


def _solve(
    camera: Camera,
    fixture_map: FixtureMap,
    blobs,
    found: _Identified,
    st: LocateSettings,
    outlier_px: float,
    gravity: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[PoseEstimate | GravityPose | None, str]:
    """Stage 5: the pose from the usable fixtures, then again with perspective-corrected
    centres; (estimate or None when too few fixtures, why it failed or "").  With
    ``gravity`` (its unit direction in the camera frame, the map's up), two fixtures are
    enough (:mod:`camvlp.geometry.gravity`)."""
    usable = found.usable
    needed = 4 if gravity is None else 2
    if len(usable) < needed:
        return None, (
            f"{len(usable)} usable fixture{'s' if len(usable) != 1 else ''} "
            f"({len(blobs)} detected), at least {needed} are needed"
            + (" (or 2 with gravity)" if gravity is None else " with gravity")
        )
    pixels = np.array([blobs[k].pixel for k in usable]).reshape(-1, 2)
    fixtures = [fixture_map.get(found.ids[k]) for k in usable]
    obj = np.array([f.position for f in fixtures]).reshape(-1, 3)
    normals = None
    if any(f.normal is not None for f in fixtures):
        normals = np.array([f.normal if f.normal is not None else [np.nan] * 3 for f in fixtures])

    def solve(points: np.ndarray) -> PoseEstimate | GravityPose:
        if gravity is not None:
            return solve_pose_gravity(
                points,
                obj,
                camera,
                gravity[0],
                up=gravity[1],
                normals=normals,
                sigma_deg=st.gravity_sigma_deg,
                pixel_sigma_px=st.centre_sigma_px,
                outlier_px=outlier_px,
            )
        return estimate_pose(
            points, obj, camera, normals=normals, solver=st.solver, outlier_px=outlier_px
        )

    est = solve(pixels)
    if est and st.correct_perspective and all(f.diameter for f in fixtures):
        # discs without a map normal lie on the plane of the others, facing the camera
        facing = disc_normals(obj, normals, est.pose.position)
        offsets = np.array(
            [
                perspective_offset(camera, est.pose, f.position, f.diameter, n)
                for f, n in zip(fixtures, facing, strict=True)
            ]
        )
        if np.max(np.abs(offsets)) >= 0.02:  # below: facing the lights, nothing to correct
            corrected = solve(pixels - offsets)
            est = corrected if corrected else est
    return est, "" if est else est.reason


def _fixture_results(
    blobs,
    decodes,
    found: _Identified,
    est: PoseEstimate | GravityPose | None,
    extents: np.ndarray,
    frequencies: np.ndarray,
    shown,
    needed: int = 4,
) -> tuple[FixtureResult, ...]:
    """Stage 6: every fixture seen, identified or not, with why it was not used."""
    results = []
    for k, (b, dec) in enumerate(zip(blobs, decodes, strict=True)):
        reason = found.reasons[k]
        used = False
        residual = float("nan")
        if k in found.usable:
            j = found.usable.index(k)
            if est is not None and est.pose is not None:
                used = bool(est.used[j])
                residual = float(est.residuals_px[j])
                if not used:
                    reason = f"does not fit the pose of the others ({residual:.1f} px off)"
            elif est is not None:
                reason = "no pose"
            else:
                reason = f"fewer than {needed} usable fixtures"
        results.append(
            FixtureResult(
                id=found.ids[k],
                pixel=shown(b.pixel),
                used=used,
                margin=dec.margin,
                reason=reason,
                hamming=dec.hamming,
                rows_spanned=float(extents[k]),
                rows_per_chip=dec.rows_per_chip,
                residual_px=residual,
                frequency_hz=float(frequencies[k]),
            )
        )
    return tuple(results)


def _same_answer(a: _Identified, b: _Identified) -> bool:
    return [a.ids[k] for k in a.usable] == [b.ids[k] for k in b.usable] and a.usable == b.usable


def _pick_direction(est1, est2, found1: _Identified, found2: _Identified) -> int:
    """Which direction's pose to keep (1 or 2); 0 when both fit and cannot be told apart,
    -1 when neither gives a pose."""
    ok1, ok2 = bool(est1), bool(est2)
    if _same_answer(found1, found2):
        return 1
    if ok1 != ok2:
        return 1 if ok1 else 2
    if not ok1:
        return -1  # neither locates
    n1, n2 = int(np.sum(est1.used)), int(np.sum(est2.used))
    r1, r2 = est1.reprojection_rms_px, est2.reprojection_rms_px
    if n1 > n2 and r1 <= r2:
        return 1
    if n2 > n1 and r2 <= r1:
        return 2
    if r1 * 5 < r2:
        return 1
    if r2 * 5 < r1:
        return 2
    return 0


def locate(
    image: np.ndarray,
    camera: Camera,
    fixture_map: FixtureMap,
    settings: LocateSettings | None = None,
    *,
    gravity=None,
) -> LocateResult:
    """Locate the camera that took a photograph of a room's coded lights.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3) or (H, W)
        The photograph, BGR or gray, 8- or 16-bit, of the camera's size.
    camera : Camera
        The camera's intrinsics, distortion and (optionally) row time and readout.
    fixture_map : FixtureMap
        The room's fixtures.
    settings : LocateSettings, optional
        Tuning options (``keep_stages=True`` keeps the intermediate results).
    gravity : array_like, shape (3,), optional
        The direction of gravity in the camera's frame when the photo was taken (OpenCV axes:
        x right, y down, z forward, of the camera itself, so of a mirrored photo once flipped
        back; any length), e.g. from the phone's accelerometer.  With
        it, two or three identified fixtures are enough (``result.solver`` says how the pose
        was solved); the map's ``up`` says which way is up in its frame.

    Returns
    -------
    LocateResult
        Falsy (``position`` None, ``reason`` set) when the photo could not be located; it
        still lists every fixture found and why each one was or was not used.

    Raises
    ------
    InputError
        The image is not an image of the camera's size; gravity is not three finite numbers,
        is of zero length, or leaves the map's lights out of the camera's view (a camera
        looking along gravity, at the floor, cannot see lights that face down).
    """
    _check_arguments(camera, fixture_map, settings)
    st = settings or LocateSettings()
    outlier_px = st.outlier_px if st.outlier_px is not None else max(4.0, 0.01 * camera.focal_px)
    t0 = time.perf_counter()
    img, mirrored = _prepare(image, camera, st)
    down = None
    if gravity is not None:
        g = check_gravity(gravity)  # the camera's own frame: that of the photo unmirrored
        normals = np.array(
            [f.normal if f.normal is not None else [np.nan] * 3 for f in fixture_map.fixtures]
        )
        up = map_up(fixture_map.positions, up=fixture_map.up, normals=normals)
        check_gravity_view(g, camera, up, normals)
        down = (g, up)
    given = st.readout or camera.readout
    detection, readout = _detect(img, given, st)
    blobs = detection.blobs
    t1 = time.perf_counter()
    gray_rois, extents, profiles = _profiles(img, blobs, readout)
    photo: PhotoDecode | None = None
    if fixture_map.mode == "frequency":
        decodes, frequencies, notes = _decode(
            blobs, gray_rois, extents, profiles, readout, camera, fixture_map
        )
    else:
        man = _decode_manchester(profiles, readout, given is not None, camera, fixture_map)
        photo, decodes, frequencies, notes = man.photo, list(man.photo.decodes), None, []
        if man.readout != readout:  # read the other way: keep the profiles in sensor order
            profiles = [p[::-1] for p in profiles]
        readout = man.readout
    t2 = time.perf_counter()
    found = _identify(blobs, decodes, fixture_map)
    est, reason = _solve(camera, fixture_map, blobs, found, st, outlier_px, down)
    if photo is not None and man.other is not None:
        # the stripes fit both directions about equally (IDs whose reversed frames are
        # other IDs'): the direction whose IDs give a pose decides, else the photo is refused
        decodes2 = list(man.other.decodes)
        found2 = _identify(blobs, decodes2, fixture_map)
        est2, reason2 = _solve(camera, fixture_map, blobs, found2, st, outlier_px, down)
        flipped = Readout.of(readout.axis, not readout.reversed)
        pick = _pick_direction(est, est2, found, found2)
        if pick == 2:
            photo, decodes, found, est, reason, readout = (
                man.other,
                decodes2,
                found2,
                est2,
                reason2,
                flipped,
            )
            profiles = [p[::-1] for p in profiles]
        elif pick in (0, -1):
            # undecided: no ID that depends on the direction is reported, and no pose
            def shown(d):
                return d.id if d.id is not None else getattr(d, "outside_id", None)

            withheld = [
                dataclasses.replace(
                    d1,
                    id=None,
                    outside_id=None,
                    reason=f"readout direction undecided: ID {shown(d1)} read one way, "
                    f"{shown(d2)} the other",
                )
                if shown(d1) != shown(d2)
                else d1
                for d1, d2 in zip(decodes, decodes2, strict=True)
            ]
            decodes = withheld
            found = _identify(blobs, decodes, fixture_map)
            est = None
            reason = (
                "readout direction ambiguous: read either way, the stripes give IDs of the map "
                "that fit a pose; give the camera's readout (e.g. rows or rows-reversed)"
                if pick == 0
                else f"{reason} (and the readout direction is undecided)"
            )
    if frequencies is None:
        frequencies = np.full(len(blobs), np.nan)
    t3 = time.perf_counter()

    width = img.shape[1]

    def shown(pixel: np.ndarray) -> np.ndarray:  # pixel in the photo as given
        return np.array([width - 1 - pixel[0], pixel[1]]) if mirrored else pixel

    pose = est.pose if est is not None else None
    return LocateResult(
        position=None if pose is None else pose.position,
        rotation=None if pose is None else pose.world_from_camera,
        euler_deg=None if pose is None else pose.euler_deg,
        reprojection_rms_px=float(est.reprojection_rms_px) if pose is not None else float("nan"),
        fixtures=_fixture_results(
            blobs, decodes, found, est, extents, frequencies, shown, 4 if down is None else 2
        ),
        timing_ms={
            "detect": 1e3 * (t1 - t0),
            "decode": 1e3 * (t2 - t1),
            "pose": 1e3 * (t3 - t2),
            "total": 1e3 * (t3 - t0),
        },
        reason=reason,
        readout=readout,
        mirrored=mirrored,
        rows_per_chip=float("nan") if photo is None else photo.model.rows_per_chip,
        exposure_chips=float("nan") if photo is None else photo.model.exposure_chips,
        alternative_position=None
        if est is None or est.alternative is None
        else est.alternative.position,
        alternative_rms_px=float("nan") if est is None else est.alternative_rms_px,
        notes=tuple(notes),
        stages=LocateStages(detection, tuple(gray_rois), tuple(profiles), tuple(decodes))
        if st.keep_stages
        else None,
        solver=est.solver
        if isinstance(est, GravityPose)
        else ("pnp" if down is None else "gravity"),
        tilt_disagreement_deg=est.tilt_disagreement_deg
        if isinstance(est, GravityPose) and pose is not None
        else float("nan"),
        gravity_residual_deg=est.gravity_residual_deg
        if isinstance(est, GravityPose) and pose is not None
        else float("nan"),
    )
