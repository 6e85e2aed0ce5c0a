"""The whole pipeline: photograph -> fixtures -> IDs -> map -> pose (thesis chapter 5).

:func:`locate` runs the stages in order, each a function of its own here: prepare the image,
detect the fixtures, cut each one's row profile, decode (Manchester IDs or frequencies),
identify them in the map, solve the pose, and report every fixture.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import cv2
import numpy as np

from camvlp.errors import InputError
from camvlp.geometry.disc import centre_sigma, disc_normals, perspective_offsets
from camvlp.geometry.gravity import (
    GravityPose,
    check_gravity,
    check_gravity_view,
    map_up,
    solve_pose_gravity,
)
from camvlp.geometry.pnp import check_solver
from camvlp.geometry.pose import PoseEstimate, estimate_pose
from camvlp.imaging.tone import linear_light
from camvlp.io.images import as_image
from camvlp.model.camera import Camera
from camvlp.model.fixtures import FixtureMap
from camvlp.model.readout import Readout
from camvlp.pipeline.decode.frequency import decode_frequencies
from camvlp.pipeline.decode.manchester import Manchester, decode_manchester
from camvlp.pipeline.decode.profile import shape_profiles
from camvlp.pipeline.decode.runs import StripeDecode
from camvlp.pipeline.detect.candidates import MIN_SIDE_PX, Blob, Detection, detect_fixtures, to_gray
from camvlp.pipeline.identify.by_pose import position_sigma
from camvlp.pipeline.identify.lookup import Identified, decided, identifier, identify
from camvlp.pipeline.lamp.glow import centred_on_glow
from camvlp.pipeline.lamp.glow_split import decode_from_glows
from camvlp.pipeline.later import Later, later_of, replaced
from camvlp.pipeline.results import FixtureResult, LocateResult, LocateStages

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
    readout_hint : Readout, str or None
        A readout the photo's metadata suggests (:func:`camvlp.io.exif_readout`, from its
        EXIF orientation), when neither ``readout`` nor the camera gives one: the stripes
        still decide the axis; where the hint's axis is theirs, its direction is taken, and
        where the stripes do not show the axis, the hint's is read.
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
    centre_sigma_px : float or None
        With gravity: the uncertainty of a detected disc centre, pixels, which weighs the
        reprojection residuals against the gravity residual.  None (the default): each
        disc's own, estimated from its ellipse fit (:attr:`FixtureResult.centre_sigma_px`;
        1 px for a disc too small to fit).
    max_position_sigma : float or None
        The most a located position's standard deviation may be along any of the map's axes,
        map units (:attr:`LocateResult.position_sigma`); a photo whose position is less sure
        (its fixtures on a narrow band of the photo, a centre or a map position off) is not
        located, its reason giving the sigma.  None (the default): no limit.  Not applied to
        a pose solved with gravity (whose sigma is not worked out).
    """

    solver: str = "iterative"
    outlier_px: float | None = None
    kernel_px: int = 16
    min_diameter_px: float = 8.0
    readout: Readout | None = None
    readout_hint: Readout | None = None
    mirrored: bool | None = None
    correct_perspective: bool = True
    keep_stages: bool = False
    gravity_sigma_deg: float = 1.0
    centre_sigma_px: float | None = None
    max_position_sigma: float | None = None

    def __post_init__(self) -> None:
        check_solver(self.solver)
        for name in ("gravity_sigma_deg", "centre_sigma_px", "max_position_sigma"):
            sigma = getattr(self, name)
            if sigma is None and name != "gravity_sigma_deg":
                continue
            if isinstance(sigma, bool) or not (
                isinstance(sigma, (int, float)) and np.isfinite(sigma) and sigma > 0
            ):
                raise InputError(f"{name} must be a positive number, got {sigma!r}")
        object.__setattr__(self, "readout", Readout.parse_optional(self.readout))
        hint = Readout.parse_optional(self.readout_hint, "readout_hint")
        object.__setattr__(self, "readout_hint", hint)


_DEFAULT_SETTINGS = LocateSettings()  # frozen: one instance serves every call without settings


def _check_arguments(camera: object, fixture_map: object, settings: object) -> None:
    for name, value, kind in (
        ("camera", camera, Camera),
        ("fixture_map", fixture_map, FixtureMap),
        ("settings", settings, (LocateSettings, type(None))),
    ):
        if not isinstance(value, kind):
            wanted = "LocateSettings or None" if name == "settings" else kind.__name__
            raise InputError(f"{name} must be a {wanted}, got {type(value).__name__}")


def fitted_camera(camera: Camera, width: int, height: int) -> tuple[Camera, str]:
    """The camera for a photo of ``width`` x ``height`` pixels, and a note ("" or why it was
    turned): the camera itself, or turned a quarter turn (:meth:`Camera.turned`) for a photo
    stored the other way round when the way it was turned does not matter.

    Raises
    ------
    InputError
        The photo is of another size, or turned where the way it was turned would matter.
    """
    if (width, height) == (camera.width, camera.height):
        return camera, ""
    turned = camera.turned() if (height, width) == (camera.width, camera.height) else None
    if turned is not None:
        return turned, (
            f"the photo is {width} x {height}, the camera file's {camera.width} x "
            f"{camera.height} turned a quarter turn: the camera is turned with it"
        )
    hint = (
        " (turned? the camera file describes the other orientation, and its principal point "
        "or distortion depend on which way: write a camera file for this orientation)"
        if (height, width) == (camera.width, camera.height)
        else ""
    )
    raise InputError(
        f"image is {width} x {height} but the camera file says {camera.width} x "
        f"{camera.height}{hint}"
    )


def _check_dims(image) -> np.ndarray:
    """The image as an array (:func:`~camvlp.io.images.as_image`) of a photo's dimensions."""
    img = as_image(image)
    if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] not in (1, 3, 4)):
        raise InputError(f"image must be (H, W) gray or (H, W, 3) BGR, got shape {img.shape}")
    return img


def _check_image(image: np.ndarray, camera: Camera) -> np.ndarray:
    img = _check_dims(image)
    h, w = img.shape[:2]
    if (w, h) != (camera.width, camera.height):
        raise InputError(
            f"image is {w} x {h} but the camera file says {camera.width} x {camera.height}"
        )
    if min(h, w) < MIN_SIDE_PX:
        raise InputError(
            f"image is {w} x {h} pixels, too small to locate "
            f"(at least {MIN_SIDE_PX} x {MIN_SIDE_PX})"
        )
    return img


def _extent(blob: Blob, axis: str) -> float:
    """Sensor rows a detected disc spans along the readout axis ("rows" or "columns"): the
    side of its mask's bounding box (0 for an empty mask)."""
    _, _, w, h = cv2.boundingRect(blob.mask.view(np.uint8))
    return float(h if axis == "rows" else w)


def _in_box(blob: Blob) -> tuple[float, float]:
    """A blob's centre ``(x, y)`` in its region of interest's pixels (Python floats: two
    subtractions, where NumPy's of a tuple from an array builds two arrays)."""
    x, y = blob.pixel.tolist()
    return x - blob.box[0], y - blob.box[1]


def _prepare(image: np.ndarray, camera: Camera, st: LocateSettings) -> tuple[np.ndarray, bool]:
    """Stage 0: the checked image, its levels mapped back to light when the camera gives its
    tone curve, flipped left-right when the photo is mirrored."""
    img = _check_image(image, camera)
    if camera.tone_gamma is not None:
        img = linear_light(img, camera.tone_gamma)
    mirrored = camera.mirrored if st.mirrored is None else bool(st.mirrored)
    # flipped into a new array: a view of negative stride costs every later OpenCV call a
    # copy (the decimation of a 34 MP photo: 0.7 s against 10 ms)
    return (cv2.flip(img, 1) if mirrored else img), mirrored


#: A blob counts as striped, and votes for its readout axis, when the stripes' variation
#: along one axis is at least this many times that along the other
#: (:attr:`Blob.stripe_contrast`)...
_STRIPED = 2.0
#: ...and its lines along that axis explain at least this share of its pixels' variance
#: (:attr:`Blob.stripe_share`: 0.6 to 0.98 for the real photos' lights and plain renders,
#: 0.37 to 0.42 for their lamps saturated 7 times over, 0.15 to 0.44 for renders of lamps
#: whose hot core is 5 times their rim's level, with soft stripes; a camera's burned-in text
#: spreads from 0.02 to 0.6: the share weighs a blob's vote, and the decoders refuse text).
_STRIPE_SHARE = 0.1
#: Lights whose stripe contrast times share (:attr:`Blob.stripe_contrast`,
#: :attr:`Blob.stripe_share`) reaches this are all alike clearly striped (the stress grid's
#: lamps: 2.2 and up; a burned-in text's characters: 1.2 at most): the photo-wide parameters
#: are fitted to the longest of them first.
_CLEAR = 2.0
#: The photo's readout axis is clear when the striped blobs' votes for it (each its share)
#: outweigh those for the other axis this many times over.
_AXIS_MARGIN = 3.0


def stripes_axis(blobs) -> tuple[str | None, float, float]:
    """The readout axis the photo's stripes show, voted by its striped blobs.

    Each blob whose stripes run clearly one way (:data:`_STRIPED`) and whose lines along
    that way explain most of its pixels (:data:`_STRIPE_SHARE`) votes for its axis with that
    share; a text, a steady light or a blob of noise has no say.  Returns the axis ("rows"
    or "columns"), or None when the votes do not clear :data:`_AXIS_MARGIN` (no striped
    blob, or blobs striped both ways), and the votes for rows and for columns.
    """
    votes = {"rows": 0.0, "columns": 0.0}
    for b in blobs:
        share = float(b.stripe_share)
        if b.stripe_contrast > _STRIPED and share >= _STRIPE_SHARE:
            votes[b.axis] += share
    rows, cols = votes["rows"], votes["columns"]
    if max(rows, cols) <= 0 or max(rows, cols) < _AXIS_MARGIN * min(rows, cols):
        return None, rows, cols
    return ("rows" if rows > cols else "columns"), rows, cols


def _detect(
    img: np.ndarray, given: Readout | None, st: LocateSettings
) -> tuple[Detection, Readout | None, bool, str]:
    """Stage 1: the fixtures, and the readout: ``given`` (the call's or the camera file's),
    else the axis the stripes show (:func:`stripes_axis`), its direction the photo's EXIF
    hint's (``st.readout_hint``) where that hint's axis is the same, else forward and found
    later.  Returns the detection, the readout (None: the axis is unclear), whether its
    direction is known, and a note ("" or where the hint was overruled or needed)."""

    def detect(axis: str | None) -> Detection:
        return detect_fixtures(
            img, readout=axis, kernel_px=st.kernel_px, min_diameter_px=st.min_diameter_px
        )

    if given is not None:
        return detect(given.axis), given, True, ""
    detection = detect(None)
    axis, rows, cols = stripes_axis(detection.blobs)
    hint, note = st.readout_hint, ""
    if axis is None and hint is not None:
        axis = hint.axis
        note = (
            f"the stripes do not show the readout axis (votes rows {rows:.1f}, columns "
            f"{cols:.1f}): the photo's EXIF orientation gives {hint}"
        )
    elif axis is not None and hint is not None and hint.axis != axis:
        note = (
            f"the photo's EXIF orientation suggests a {hint} readout; its stripes run along {axis}"
        )
        hint = None
    if axis is None:
        return detection, None, False, ""
    if any(b.axis != axis for b in detection.blobs):  # each disc bridged along the photo's axis
        detection = detect(axis)
    if hint is not None:
        return detection, hint, True, note
    return detection, Readout.of(axis), False, note


def _profiles(
    img: np.ndarray, blobs, readout: Readout
) -> tuple[list[np.ndarray], np.ndarray, list[np.ndarray]]:
    """Stage 2: each blob's gray region, its extent along the readout (rows) and row profile.

    Each profile is in the order the sensor read it (reversed for a reversed readout).
    """
    gray_rois = [
        b.gray if b.gray is not None else to_gray(img[b.box[1] : b.box[3], b.box[0] : b.box[2]])
        for b in blobs
    ]
    extents = np.array([_extent(b, readout.axis) for b in blobs])
    step = -1 if readout.reversed else 1
    shaped = shape_profiles(
        gray_rois,
        [b.mask for b in blobs],
        readout.axis,
        [_in_box(b) for b in blobs],
        [b.axes_px for b in blobs],
        [b.angle_deg for b in blobs],
    )
    return gray_rois, extents, [p[::step] for p, _, _ in shaped], [w[::step] for _, _, w in shaped]


def _decode(
    blobs,
    gray_rois,
    profiles,
    readout: Readout,
    camera: Camera,
    fixture_map: FixtureMap,
    weights=None,
) -> tuple[list, np.ndarray, list[str], list[Blob], list]:
    """Stage 3 with the readout taken as known: each blob's decode, measured frequencies (Hz,
    NaN in Manchester mode), notes, the blobs (new ones, where a frequency-coded light's
    centre moved to its whole striped area), and each frequency-coded light's beacon fit
    (:func:`~camvlp.pipeline.decode.frequency.decode_frequencies`; empty in Manchester mode);
    ``weights``, the profiles' row weights for the model fit (:func:`_profiles`).
    (:func:`locate` itself decides an unknown direction.)"""
    if fixture_map.mode != "frequency":
        man = decode_manchester(profiles, readout, True, camera, fixture_map, weights)
        return list(man.decodes), np.full(len(blobs), np.nan), [], list(blobs), []
    decodes, frequencies, centres, note, beacons = decode_frequencies(
        blobs, gray_rois, readout.axis, camera, fixture_map
    )
    moved = [
        b if np.array_equal(c, b.pixel) else replaced(b, pixel=c)
        for b, c in zip(blobs, centres, strict=True)
    ]
    return decodes, frequencies, [note] if note else [], moved, beacons


def striped(blob) -> bool:
    """Whether a blob shows stripes to read: they vary clearly along one axis
    (:data:`_STRIPED`) and its lines along it explain a share of its pixels' variance
    (:data:`_STRIPE_SHARE`).  A camera's burned-in text, a steady light or a reflection does
    not; it is neither centred, nor decoded, nor let to tell the photo's chip length."""
    return blob.stripe_contrast > _STRIPED and float(blob.stripe_share) >= _STRIPE_SHARE


def _no_stripes(blob) -> StripeDecode:
    """The decode of a blob that shows no stripes to read (:func:`striped`), with why."""
    share = float(blob.stripe_share)
    if not np.isfinite(share):
        why = "no stripes to read"
    elif share < _STRIPE_SHARE:
        why = (
            f"no stripes to read: its lines explain {100 * share:.0f} % of its pixels (text, "
            "a steady light, or not a coded light)"
        )
    else:
        why = (
            f"no stripes to read along the {blob.axis}: its level varies {blob.stripe_contrast:.1f}"
            f" times as much from line to line along them as across (more than {_STRIPED:g} "
            "needed)"
        )
    return StripeDecode(None, why, -1, 0.0, np.nan, np.nan, "", np.nan)


def _spread_out(values, keep: list[int], default: list) -> list:
    """``default`` with ``values`` (one per index of ``keep``) put at those indices."""
    out = list(default)
    for k, v in zip(keep, values, strict=True):
        out[k] = v
    return out


def _read_manchester(
    img, blobs, keep: list[int], profiles, weights, readout, direction_known, camera, fixture_map
) -> Manchester:
    """:func:`decode_manchester` and :func:`_from_glows` of the readable blobs (``keep``),
    the others refused (:func:`_no_stripes`); the profiles and weights read again from the
    glows put back in their places."""
    sub_p, sub_w = [profiles[k] for k in keep], [weights[k] for k in keep]
    # the photo-wide parameters from the clearly striped lights, the longest first
    rank = [min(blobs[k].stripe_contrast * float(blobs[k].stripe_share), _CLEAR) for k in keep]
    man = decode_manchester(sub_p, readout, direction_known, camera, fixture_map, sub_w, rank)
    man = _from_glows(img, [blobs[k] for k in keep], man, fixture_map, sub_p, sub_w, readout)
    for j, k in enumerate(keep):
        profiles[k], weights[k] = sub_p[j], sub_w[j]
    if len(keep) == len(blobs):
        return man
    none = [_no_stripes(b) for b in blobs]
    other = None if man.other is None else tuple(_spread_out(man.other, keep, none))
    return dataclasses.replace(
        man, decodes=tuple(_spread_out(man.decodes, keep, none)), other=other
    )


#: Why no light of a photo is read when its stripes do not say the readout axis.
UNCLEAR_AXIS = (
    "the stripes do not show which way the sensor read (rows or columns): give the readout "
    "(--readout, or readout in the camera file)"
)


def _unread(blobs) -> list[StripeDecode]:
    """Every blob left unread, as when the photo's readout axis is unclear."""
    return [StripeDecode(None, UNCLEAR_AXIS, -1, 0.0, np.nan, np.nan, "", np.nan) for _ in blobs]


def _from_glows(img, blobs, man: Manchester, fixture_map, profiles, weights, readout) -> Manchester:
    """:func:`~camvlp.pipeline.lamp.glow_split.decode_from_glows`; the lights read again get their
    waveforms as their profiles and weights (in place, in ``readout``'s order, as the others)."""
    man, waves = decode_from_glows(img, blobs, man, fixture_map)
    step = -1 if readout.reversed else 1
    for k, wave in waves.items():
        profiles[k], weights[k] = wave.level[::step], wave.weight[::step]
    return man


#: Centre sigma of a disc whose ellipse fit gives none (the centroid of a small disc), pixels.
UNKNOWN_CENTRE_SIGMA_PX = 1.0


def _centre_sigmas(blobs, usable: tuple[int, ...], st: LocateSettings) -> np.ndarray:
    """Each usable disc's centre sigma (pixels): the one given, else the disc's own."""
    if st.centre_sigma_px is not None:
        return np.full(len(usable), float(st.centre_sigma_px))
    sigma = np.array([blobs[k].centre_sigma_px for k in usable], dtype=float)
    return np.where(np.isfinite(sigma), sigma, UNKNOWN_CENTRE_SIGMA_PX)


def _solve(
    camera: Camera,
    fixture_map: FixtureMap,
    blobs,
    found: Identified,
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
                pixel_sigma_px=_centre_sigmas(blobs, usable, st),
                outlier_px=outlier_px,
            )
        return estimate_pose(
            points,
            obj,
            camera,
            normals=normals,
            solver=st.solver,
            outlier_px=outlier_px,
            centre_sigma_px=lambda: float(np.median(_centre_sigmas(blobs, usable, st))),
        )

    est = solve(pixels)
    if est and st.correct_perspective and all(f.diameter for f in fixtures):
        # discs without a map normal lie on the plane of the others, facing the camera
        facing = disc_normals(obj, normals, est.pose.position)
        offsets = perspective_offsets(camera, est.pose, obj, [f.diameter for f in fixtures], facing)
        # below: facing the lights, nothing to correct (the ufuncs' own calls: NumPy's max)
        if np.maximum.reduce(np.abs(offsets), axis=None) >= 0.02:
            corrected = solve(pixels - offsets)
            est = corrected if corrected else est
    return est, "" if est else est.reason


def _sigma_inputs(camera, fixture_map, est, found: Identified, down):
    """What ``LocateResult.position_sigma`` needs (the camera, the pose, the used fixtures'
    map positions and reprojection errors, and how far an alternative pose that fits about
    as well lies along each axis: zeros when none does), or None: not located, or solved
    with gravity (its covariance weighs the gravity too)."""
    pose = est.pose if est is not None else None
    if pose is None or down is not None or isinstance(est, GravityPose):
        return None
    used = [k for j, k in enumerate(found.usable) if est.used[j]]
    points = np.array([fixture_map.get(found.ids[k]).position for k in used]).reshape(-1, 3)
    close = np.zeros(3)
    if est.close and est.alternative is not None:
        close = np.abs(est.alternative.position - pose.position)
    return camera, pose, points, np.asarray(est.residuals_px, dtype=float)[est.used], close


def _position_sigma(camera, pose, points, residuals_px, close) -> np.ndarray:
    """:func:`~camvlp.pipeline.identify.by_pose.position_sigma`, at least as large along each axis
    as ``close`` (how far an alternative pose that fits about as well lies)."""
    return np.maximum(position_sigma(camera, pose, points, residuals_px), close)


def _finite_sigma(*inputs) -> np.ndarray | None:
    """:func:`_position_sigma`, or None when it is not finite."""
    sigma = _position_sigma(*inputs)
    return sigma if np.isfinite(sigma).all() else None


def _sure_enough(
    est: PoseEstimate, sigma_inputs, limit: float
) -> tuple[PoseEstimate, str, np.ndarray | None]:
    """The pose, or no pose and why when its position's standard deviation
    (:func:`~camvlp.pipeline.identify.by_pose.position_sigma`, map units) exceeds ``limit`` along an
    axis or is not finite; and that standard deviation, shape (3,), when the pose is kept."""
    sigma = _position_sigma(*sigma_inputs)
    finite = np.isfinite(sigma)
    axis = int(np.argmax(np.where(finite, sigma, np.inf)))
    if finite.all() and sigma[axis] <= limit:
        return est, "", sigma
    told = f"is {sigma[axis]:.3g} (map units), over" if finite[axis] else "is not finite, for"
    why = (
        f"the position is too unsure: its standard deviation along {'xyz'[axis]} {told} "
        f"the limit of {limit:g}"
    )
    refused = dataclasses.replace(
        est, pose=None, alternative=None, alternative_rms_px=float("nan"), reason=why
    )
    return refused, why, None


def _fixture_results(
    blobs,
    decodes,
    found: Identified,
    est: PoseEstimate | GravityPose | None,
    extents: np.ndarray,
    frequencies: np.ndarray,
    shown,
    needed: int = 4,
    told: dict[int, tuple[int, ...]] | None = None,
    fixture_map: FixtureMap | None = None,
) -> tuple[FixtureResult, ...]:
    """Stage 6: every fixture seen, identified or not, with why it was not used.  A
    fixture's ``id`` is one of the map's or None: an ID read that the map lacks, or that the
    pose does not vouch for, is told in its reason only."""
    results = []
    at = {k: j for j, k in enumerate(found.usable)}  # a usable fixture's place in the pose's
    posed = est is not None and est.pose is not None
    if posed:  # (as Python bools and floats, once)
        used_by_pose, residuals = est.used.tolist(), est.residuals_px.tolist()
    for k, (b, dec) in enumerate(zip(blobs, decodes, strict=True)):
        reason = found.reasons[k]
        fid = found.ids[k]
        if fid is not None and fixture_map is not None and fixture_map.get(fid) is None:
            fid = None  # (its reason says what it sends)
        used = False
        residual = float("nan")
        j = at.get(k)
        if j is not None:
            if posed:
                used, residual = used_by_pose[j], residuals[j]
                if not used:  # the pose does not vouch for its ID: none reported
                    reason = (
                        f"read as ID {fid}, which does not fit the pose of the others "
                        f"({residual:.1f} px off)"
                    )
                    fid = None
            elif est is not None:
                reason = "no pose"
            else:
                reason = f"fewer than {needed} usable fixtures"
        results.append(
            FixtureResult(
                id=fid,
                pixel=shown(b.pixel),
                used=used,
                margin=dec.margin,
                reason=reason,
                hamming=dec.hamming,
                rows_spanned=float(extents[k]),
                rows_per_chip=dec.rows_per_chip,
                residual_px=residual,
                frequency_hz=float(frequencies[k]),
                centre_sigma_px=later_of(b, "centre_cov_px2", centre_sigma),
                look_alikes=(told or {}).get(k, ()),
            )
        )
    return tuple(results)


def readout_direction(
    img: np.ndarray,
    blobs,
    readout: Readout,
    camera: Camera,
    fixture_map: FixtureMap,
    st: LocateSettings,
    outlier_px: float,
) -> Readout | None:
    """The readout's direction as one photo decides it, for a camera that does not say.

    As :func:`locate` decides it: by the stripes read both ways, else (when they fit both
    about equally) by which direction's IDs give a pose.  ``readout`` is the axis the blobs'
    stripes show; a frequency-coded map keeps it as is once a blob shows stripes (a frequency
    reads the same either way).  Returns None when the photo does not decide (no ID read, or
    the directions cannot be told apart).
    """
    if fixture_map.mode == "frequency":
        return readout if any(b.stripe_contrast > 2.0 for b in blobs) else None
    _, _, profiles, weights = _profiles(img, blobs, readout)
    man = decode_manchester(profiles, readout, False, camera, fixture_map, weights)
    if man.other is None:
        found = identify(blobs, list(man.decodes), fixture_map)
        return man.readout if found.usable else None

    def solve(f: Identified):
        return _solve(camera, fixture_map, blobs, f, st, outlier_px, None)

    identified = identifier(camera, fixture_map, blobs, outlier_px, solve, 4)
    man, kept = decided(blobs, fixture_map, man, list(man.decodes), identified, solve)
    return man.readout if kept.est is not None else None


def _gravity(gravity, camera: Camera, fixture_map: FixtureMap) -> tuple[np.ndarray, np.ndarray]:
    """The checked gravity direction (the camera's own frame: that of the photo unmirrored)
    and the map's up; InputError when the lights are out of the camera's view."""
    g = check_gravity(gravity)
    normals = np.array(
        [f.normal if f.normal is not None else [np.nan] * 3 for f in fixture_map.fixtures]
    )
    up = map_up(fixture_map.positions, up=fixture_map.up, normals=normals)
    check_gravity_view(g, camera, up, normals)
    return g, up


def _timings(t0: float, t1: float, t2: float, t3: float) -> dict[str, float]:
    """Milliseconds per stage from the stages' start and end times, seconds."""
    return {
        "detect": 1e3 * (t1 - t0),
        "decode": 1e3 * (t2 - t1),
        "pose": 1e3 * (t3 - t2),
        "total": 1e3 * (t3 - t0),
    }


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
    st = settings or _DEFAULT_SETTINGS
    outlier_px = st.outlier_px if st.outlier_px is not None else max(4.0, 0.01 * camera.focal_px)
    t0 = time.perf_counter()
    image = _check_dims(image)
    camera, turned_note = fitted_camera(camera, image.shape[1], image.shape[0])
    img, mirrored = _prepare(image, camera, st)
    down = None if gravity is None else _gravity(gravity, camera, fixture_map)
    detection, found_readout, direction_known, axis_note = _detect(
        img, st.readout or camera.readout, st
    )
    readout = found_readout or Readout.ROWS  # (an unclear axis: nothing is decoded below)
    blobs = detection.blobs
    keep = [k for k, b in enumerate(blobs) if striped(b)]  # (text, steady lights: no)
    if fixture_map.mode != "frequency" and found_readout is not None:
        # the readable lights, each centred on its glow (frequency: centred as measured)
        sub = centred_on_glow(img, [blobs[k] for k in keep], readout.axis)
        blobs = _spread_out(sub, keep, list(blobs))
    t1 = time.perf_counter()
    gray_rois, extents, profiles, weights = _profiles(img, blobs, readout)
    man: Manchester | None = None
    beacons: list = []
    notes = [n for n in (turned_note, axis_note) if n]
    if found_readout is None:
        decodes, frequencies = _unread(blobs), np.full(len(blobs), np.nan)
    elif fixture_map.mode == "frequency":
        sub = [blobs[k] for k in keep]
        got, freqs, more, moved, fits = _decode(
            sub,
            [gray_rois[k] for k in keep],
            [profiles[k] for k in keep],
            readout,
            camera,
            fixture_map,
        )
        decodes = _spread_out(got, keep, [_no_stripes(b) for b in blobs])
        frequencies = np.full(len(blobs), np.nan)
        frequencies[keep] = freqs
        blobs = _spread_out(moved, keep, list(blobs))
        beacons = _spread_out(fits, keep, [(None, None, None)] * len(blobs))
        notes += more
    else:
        man = _read_manchester(
            img, blobs, keep, profiles, weights, readout, direction_known, camera, fixture_map
        )
        decodes, frequencies = list(man.decodes), np.full(len(blobs), np.nan)
        notes += [man.note] if man.note else []
    t2 = time.perf_counter()

    def solve(f: Identified):
        return _solve(camera, fixture_map, blobs, f, st, outlier_px, down)

    needed = 4 if down is None else 2
    identified = identifier(camera, fixture_map, blobs, outlier_px, solve, needed)
    man, kept = decided(blobs, fixture_map, man, decodes, identified, solve, needed)
    decodes, found, est, reason, told = kept.decodes, kept.found, kept.est, kept.reason, kept.told
    if found_readout is None:
        reason = UNCLEAR_AXIS
    if man is not None:
        if man.readout != readout:  # read the other way: keep the profiles in sensor order
            profiles = [p[::-1] for p in profiles]
        readout = man.readout
    inputs = _sigma_inputs(camera, fixture_map, est, found, down)
    sigma = None if inputs is None else Later(_finite_sigma, *inputs)  # when first read
    if inputs is not None and st.max_position_sigma is not None:  # now, against the limit
        est, reason, sigma = _sure_enough(est, inputs, st.max_position_sigma)
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
            blobs, decodes, found, est, extents, frequencies, shown, needed, told, fixture_map
        ),
        timing_ms=_timings(t0, t1, t2, t3),
        reason=reason,
        readout=readout,
        mirrored=mirrored,
        rows_per_chip=float("nan") if man is None else man.rows_per_chip,
        exposure_chips=float("nan") if man is None else man.exposure_chips,
        alternative_position=None
        if est is None or est.alternative is None
        else est.alternative.position,
        alternative_rms_px=float("nan") if est is None else est.alternative_rms_px,
        pose_margin=float(getattr(est, "margin", float("nan"))) if est is not None else np.nan,
        notes=tuple(notes),
        stages=LocateStages(
            detection,
            tuple(gray_rois),
            tuple(profiles),
            tuple(decodes),
            tuple(weights),
            tuple(beacons),
        )
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
        position_sigma=sigma,
    )
