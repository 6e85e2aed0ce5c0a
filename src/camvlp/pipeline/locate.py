"""The whole pipeline: photograph -> fixtures -> IDs -> map -> pose (thesis chapter 5)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from camvlp.io import InputError
from camvlp.model.camera import READOUTS, Camera, Pose
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.decode import StripeDecode, decode_profile, row_profile
from camvlp.pipeline.detect import Blob, Detection, detect_fixtures, to_gray
from camvlp.pipeline.frequency import assign_frequencies
from camvlp.pipeline.pose import PoseEstimate, estimate_pose
from camvlp.pipeline.stripes import estimate_stripe_period

__all__ = ["FixtureResult", "LocateResult", "LocateSettings", "locate"]


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
    readout : str or None
        Readout ("rows", "columns", "rows-reversed", "columns-reversed"; see
        :class:`camvlp.Camera`); None takes the camera's, else finds the axis (forward).
    mirrored : bool or None
        Flip the image left-right first; None takes the camera file's ``mirrored``.
    correct_perspective : bool
        Correct each disc's centre for the offset between an ellipse's centre and the
        projected centre of the disc (needs the map's diameters), then solve again.
    """

    solver: str = "iterative"
    outlier_px: float | None = None
    kernel_px: int = 16
    min_diameter_px: float = 8.0
    readout: str | None = None
    mirrored: bool | None = None
    correct_perspective: bool = True


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
        Decoding confidence in [0, 1] (see :class:`camvlp.decode.StripeDecode`).
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
    error : str
        Why it was not located ("" when it was).
    readout : str
        Readout axis used ("rows" or "columns").
    mirrored : bool
        The image was flipped left-right before locating.
    alternative_position : ndarray, shape (3,), or None
        The other pose of a planar target's two-fold ambiguity, when it exists.
    alternative_rms_px : float
        Its reprojection RMS, pixels.
    """

    position: np.ndarray | None
    rotation: np.ndarray | None
    euler_deg: np.ndarray | None
    reprojection_rms_px: float
    fixtures: tuple[FixtureResult, ...]
    timing_ms: dict[str, float]
    error: str = ""
    readout: str = "rows"
    mirrored: bool = False
    alternative_position: np.ndarray | None = None
    alternative_rms_px: float = float("nan")
    notes: tuple[str, ...] = field(default_factory=tuple)

    def __bool__(self) -> bool:
        return self.position is not None

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
            "readout": self.readout,
            "mirrored": self.mirrored,
        }
        if self.alternative_position is not None:
            d["alternative"] = {
                "position": arr(self.alternative_position),
                "reprojection_rms_px": round(self.alternative_rms_px, 4),
            }
        if self.notes:
            d["notes"] = list(self.notes)
        if self.error:
            d["error"] = self.error
        return d


@dataclass(frozen=True)
class _Stages:
    """Intermediate results kept for the debug pictures."""

    detection: Detection
    gray_rois: tuple[np.ndarray, ...]
    profiles: tuple[np.ndarray, ...]
    decodes: tuple[StripeDecode, ...]


def _check_image(image: np.ndarray, camera: Camera) -> np.ndarray:
    img = np.asarray(image)
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


def _perspective_offset(camera: Camera, pose: Pose, centre, diameter, normal) -> np.ndarray:
    """Image offset of a disc's ellipse centre from its centre's projection, pixels (2,)."""
    n = np.asarray(normal, float) if normal is not None else pose.position - centre
    n = n / np.linalg.norm(n)
    a = np.cross(n, [1.0, 0.0, 0.0])
    if np.linalg.norm(a) < 1e-6:
        a = np.cross(n, [0.0, 1.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    t = np.linspace(0, 2 * np.pi, 72, endpoint=False)
    rim = centre + 0.5 * diameter * (np.cos(t)[:, None] * a + np.sin(t)[:, None] * b)
    uv = camera.project(pose, np.vstack([centre, rim]))
    if not np.all(np.isfinite(uv)):
        return np.zeros(2)
    (cx, cy), _, _ = cv2.fitEllipse(uv[1:].astype(np.float32))
    return np.array([cx, cy]) - uv[0]


def _extent(blob: Blob, readout: str) -> float:
    """Sensor rows a detected disc spans along the readout axis."""
    m = blob.mask if readout == "rows" else blob.mask.T
    r = np.flatnonzero(m.any(axis=1))
    return float(r[-1] - r[0] + 1) if r.size else 0.0


def _decode_frequencies(
    blobs, gray_rois, extents: np.ndarray, readout: str, camera: Camera, fixture_map: FixtureMap
) -> tuple[list[StripeDecode], np.ndarray, str]:
    """Identify frequency-coded fixtures from their stripe periods (see ``frequency.py``)."""
    periods = np.full(len(blobs), np.nan)
    failures = [""] * len(blobs)
    for k, (b, g) in enumerate(zip(blobs, gray_rois, strict=True)):
        est = estimate_stripe_period(g, b.mask, readout)
        if est:
            periods[k] = est.period_px
        else:
            failures[k] = est.message or "no stripe period could be measured"
    fa = assign_frequencies(
        periods, fixture_map, camera.row_time_s, periods_spanned=extents / periods
    )
    note = ""
    if fa.row_time_fitted:
        note = "the camera file has no row_time_s: stripe periods were matched to the map's " + (
            f"frequencies by their ratios (fitted row time {1e6 * fa.row_time_s:.2f} us)"
            if np.isfinite(fa.row_time_s)
            else "frequencies by their ratios, and no consistent match was found"
        )
    decodes = []
    for k in range(len(blobs)):
        reason = failures[k] or fa.reasons[k]
        fid = fa.ids[k] if not failures[k] else None
        margin = 0.0
        if fid is not None:
            target = fixture_map.get(fid).frequency_hz
            margin = float(np.clip(1 - 20 * abs(np.log(fa.frequencies_hz[k] / target)), 0, 1))
        decodes.append(
            StripeDecode(
                fid,
                "" if fid is not None else reason,
                -1,
                margin,
                0.5 * periods[k],
                float("nan"),
                "",
                extents[k] / periods[k] if np.isfinite(periods[k]) else 0.0,
            )
        )
    return decodes, fa.frequencies_hz, note


def locate(
    image: np.ndarray,
    camera: Camera,
    fixture_map: FixtureMap,
    settings: LocateSettings | None = None,
    *,
    _keep_stages: bool = False,
):
    """Locate the camera that took a photograph of a room's coded lights.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3) or (H, W)
        The photograph, BGR or gray, 8- or 16-bit, of the camera's size.
    camera : Camera
        The camera's intrinsics, distortion and (optionally) row time.
    fixture_map : FixtureMap
        The room's fixtures.
    settings : LocateSettings, optional
        Tuning options.

    Returns
    -------
    LocateResult
        Falsy (``position`` None, ``error`` set) when the photo could not be located; it still
        lists every fixture found and why each one was or was not used.

    Raises
    ------
    InputError
        The image is not an image of the camera's size.
    """
    st = settings or LocateSettings()
    outlier_px = st.outlier_px if st.outlier_px is not None else max(4.0, 0.01 * camera.focal_px)
    t0 = time.perf_counter()
    img = _check_image(image, camera)
    mirrored = camera.mirrored if st.mirrored is None else bool(st.mirrored)
    if mirrored:
        img = img[:, ::-1]
    given = st.readout or camera.readout
    if given not in READOUTS:
        raise ValueError(f"readout must be one of {READOUTS[1:]}, got {given!r}")
    reverse = bool(given) and given.endswith("-reversed")
    readout = given.removesuffix("-reversed") if given else None
    detection = detect_fixtures(
        img, readout=readout, kernel_px=st.kernel_px, min_diameter_px=st.min_diameter_px
    )
    blobs = detection.blobs
    if readout is None and blobs:
        striped = [b for b in blobs if b.stripe_contrast > 2.0] or list(blobs)
        votes = [b.axis for b in striped]
        readout = max(set(votes), key=votes.count)
    readout = readout or "rows"
    t1 = time.perf_counter()

    gray_rois = [to_gray(img[b.box[1] : b.box[3], b.box[0] : b.box[2]]) for b in blobs]
    extents = np.array([_extent(b, readout) for b in blobs])
    step = -1 if reverse else 1  # each profile in the order the sensor read it
    profiles = [
        row_profile(g, b.mask, readout)[0][::step] for b, g in zip(blobs, gray_rois, strict=True)
    ]
    notes: list[str] = []
    frequencies = np.full(len(blobs), np.nan)
    if fixture_map.mode == "frequency":
        decodes, frequencies, note = _decode_frequencies(
            blobs, gray_rois, extents, readout, camera, fixture_map
        )
        notes += [note] if note else []
    else:
        decodes = [decode_profile(p, fixture_map.frame) for p in profiles]
    t2 = time.perf_counter()

    width = img.shape[1]

    def shown(pixel: np.ndarray) -> np.ndarray:  # pixel in the photo as given
        return np.array([width - 1 - pixel[0], pixel[1]]) if mirrored else pixel

    reasons: list[str] = []
    ids: list[int | None] = []
    for b, dec in zip(blobs, decodes, strict=True):
        fid, reason = dec.id, dec.reason
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
    usable = [k for k, r in enumerate(reasons) if ids[k] is not None and not r]

    pixels = np.array([blobs[k].pixel for k in usable]).reshape(-1, 2)
    fixtures = [fixture_map.get(ids[k]) for k in usable]
    obj = np.array([f.position for f in fixtures]).reshape(-1, 3)
    normals = None
    if any(f.normal is not None for f in fixtures):
        normals = np.array([f.normal if f.normal is not None else [np.nan] * 3 for f in fixtures])
    est: PoseEstimate | None = None
    error = ""
    if len(usable) < 4:
        n_found = len(blobs)
        error = (
            f"{len(usable)} usable fixture{'s' if len(usable) != 1 else ''} "
            f"({n_found} detected), at least 4 are needed"
        )
    else:
        est = estimate_pose(
            pixels, obj, camera, normals=normals, solver=st.solver, outlier_px=outlier_px
        )
        if est and st.correct_perspective and all(f.diameter for f in fixtures):
            offsets = np.array(
                [
                    _perspective_offset(camera, est.pose, f.position, f.diameter, f.normal)
                    for f in fixtures
                ]
            )
            if np.max(np.abs(offsets)) < 0.02:  # facing the lights: nothing to correct
                est2 = None
            else:
                est2 = estimate_pose(
                    pixels - offsets,
                    obj,
                    camera,
                    normals=normals,
                    solver=st.solver,
                    outlier_px=outlier_px,
                )
            if est2:
                est = est2
        if not est:
            error = est.reason
    t3 = time.perf_counter()

    results = []
    for k, (b, dec) in enumerate(zip(blobs, decodes, strict=True)):
        reason = reasons[k]
        used = False
        residual = float("nan")
        if k in usable:
            j = usable.index(k)
            if est is not None and est.pose is not None:
                used = bool(est.used[j])
                residual = float(est.residuals_px[j])
                if not used:
                    reason = f"does not fit the pose of the others ({residual:.1f} px off)"
            elif est is not None:
                reason = "no pose"
            else:
                reason = "fewer than 4 usable fixtures"
        results.append(
            FixtureResult(
                id=ids[k],
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
    timing = {
        "detect": 1e3 * (t1 - t0),
        "decode": 1e3 * (t2 - t1),
        "pose": 1e3 * (t3 - t2),
        "total": 1e3 * (t3 - t0),
    }
    pose = est.pose if est is not None else None
    result = LocateResult(
        position=None if pose is None else pose.position,
        rotation=None if pose is None else pose.world_from_camera,
        euler_deg=None if pose is None else pose.euler_deg,
        reprojection_rms_px=float(est.reprojection_rms_px) if pose is not None else float("nan"),
        fixtures=tuple(results),
        timing_ms=timing,
        error=error,
        readout=readout + ("-reversed" if reverse else ""),
        mirrored=mirrored,
        alternative_position=None
        if est is None or est.alternative is None
        else est.alternative.position,
        alternative_rms_px=float("nan") if est is None else est.alternative_rms_px,
        notes=tuple(notes),
    )
    if _keep_stages:
        return result, _Stages(detection, tuple(gray_rois), tuple(profiles), tuple(decodes))
    return result
