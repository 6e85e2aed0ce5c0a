"""The camera's pose from two or more identified fixtures and gravity: the solver.

Two fixtures go to the closed form (:mod:`~camvlp.geometry.gravity.two_fixtures`); three or
more to least squares over heading and position with the tilt held, then a refinement of
the whole pose with a gravity residual (:mod:`~camvlp.geometry.gravity.refine`); with four or
more, fixtures that do not fit are dropped and the tilt the pixels alone give is compared
with the accelerometer's.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations

import numpy as np

from camvlp.format import format_vector
from camvlp.geometry.gravity.refine import refine_gravity_batch
from camvlp.geometry.gravity.tilt import check_gravity, map_up, tilt_error_deg
from camvlp.geometry.gravity.two_fixtures import solve_two_fixtures
from camvlp.model.camera import Camera, Pose

__all__ = ["MAX_TILT_SIGMAS", "SOLVER_NAMES", "GravityPose", "solve_pose_gravity"]

#: What :attr:`GravityPose.solver` may say, and what each means.
SOLVER_NAMES = {
    "gravity-2": "two fixtures and gravity, closed form",
    "gravity-3": "three fixtures and gravity, least squares",
    "pnp+gravity": "four or more fixtures: PnP refined with the gravity residual",
}


#: A pose whose down is more than this many sigmas from the measured gravity is refused.
MAX_TILT_SIGMAS = 5.0


@dataclass(frozen=True)
class GravityPose:
    """A pose solved with gravity, or why there is none.

    Attributes
    ----------
    pose : Pose or None
        The camera's pose in the map frame; None when it failed.
    solver : str
        Which solver gave it: a key of :data:`SOLVER_NAMES`.
    n_fixtures : int
        Fixtures the pose uses.
    used : ndarray of bool, shape (N,)
        Which of the given fixtures it uses.
    residuals_px : ndarray, shape (N,)
        Each fixture's reprojection error with the pose, pixels (NaN on failure).
    reprojection_rms_px : float
        RMS over the fixtures used, pixels (NaN on failure).
    gravity_residual_deg : float
        Angle between the pose's down and the measured gravity, degrees.
    tilt_disagreement_deg : float
        Four or more fixtures: the angle between the down of the pose the pixels alone give
        and the measured gravity, degrees (NaN with fewer).
    alternative : Pose or None
        The other two-fixture solution, when it was valid too (ambiguous: a failure).
    reason : str
        Why it failed ("" on success).
    """

    pose: Pose | None
    solver: str
    n_fixtures: int
    used: np.ndarray
    residuals_px: np.ndarray
    reprojection_rms_px: float = float("nan")
    gravity_residual_deg: float = float("nan")
    tilt_disagreement_deg: float = float("nan")
    alternative: Pose | None = None
    reason: str = ""
    candidates: tuple[Pose, ...] = field(default_factory=tuple)

    def __bool__(self) -> bool:
        return self.pose is not None

    @property
    def alternative_rms_px(self) -> float:
        """Reprojection RMS of :attr:`alternative`, pixels (NaN when there is none)."""
        return float("nan")


def _solver_for(n: int) -> str:
    return "gravity-2" if n == 2 else "gravity-3" if n == 3 else "pnp+gravity"


def _failure(n: int, reason: str, **kwargs) -> GravityPose:
    return GravityPose(
        None, _solver_for(n), 0, np.zeros(n, bool), np.full(n, np.nan), reason=reason, **kwargs
    )


def _valid(pose: Pose, points: np.ndarray, normals: np.ndarray | None) -> tuple[bool, bool]:
    """(every fixture in front of the camera, the camera on every lit side)."""
    in_front = bool(np.all(pose.to_camera(points)[:, 2] > 0))
    lit = True
    if normals is not None:
        has = np.all(np.isfinite(normals), axis=1)
        lit = bool(np.all(np.einsum("ij,ij->i", normals[has], pose.position - points[has]) > 0))
    return in_front, lit


def _pixel_residuals(pose: Pose, points, bearings, focal_px) -> np.ndarray:
    pc = pose.to_camera(points)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = focal_px * np.linalg.norm(pc[:, :2] / pc[:, 2:3] - bearings, axis=1)
    return np.where((pc[:, 2] > 0) & np.isfinite(r), r, np.inf)


#: Gravity sigma (degrees) that holds the tilt while heading and position are fitted.
_TILT_HELD_DEG = 1e-4


def _fit_heading_position(
    starts: list[Pose], points, bearings, gravity, up, focal_px, pixel_sigma_px=1.0
) -> list[Pose]:
    """Least squares over heading and position with the tilt held, from each start (each
    fixture's residual over its ``pixel_sigma_px``)."""
    if not starts:
        return []
    rots, centres = refine_gravity_batch(
        np.array([p.world_from_camera for p in starts]),
        np.array([p.position for p in starts]),
        points,
        np.broadcast_to(bearings, (len(starts), *bearings.shape)),
        np.broadcast_to(gravity, (len(starts), 3)),
        up,
        focal_px=focal_px,
        sigma_deg=_TILT_HELD_DEG,
        pixel_sigma_px=pixel_sigma_px,
    )
    out = []
    for r, c in zip(rots, centres, strict=True):
        if np.all(np.isfinite(r)) and np.all(np.isfinite(c)):
            u, _, vt = np.linalg.svd(r)
            out.append(Pose(u @ vt, c))
    return out


def _refine(
    start: Pose,
    points,
    bearings,
    focal_px: float,
    *,
    gravity=None,
    up=None,
    sigma_deg: float = 1.0,
    pixel_sigma_px=1.0,
) -> Pose:
    """Full six-degree refinement: reprojection (pixels / pixel sigma) and gravity residual;
    without ``gravity``, the reprojection alone."""
    if gravity is None:  # the pose's own down, weighted by nothing
        up = np.array([0.0, 0.0, 1.0])
        gravity, sigma_deg = start.world_from_camera.T @ -up, 1e12
    rots, centres = refine_gravity_batch(
        start.world_from_camera[None],
        start.position[None],
        points,
        bearings[None],
        np.asarray(gravity, float)[None],
        up,
        focal_px=focal_px,
        sigma_deg=sigma_deg,
        pixel_sigma_px=pixel_sigma_px,
    )
    if not (np.all(np.isfinite(rots)) and np.all(np.isfinite(centres))):
        return start
    u, _, vt = np.linalg.svd(rots[0])
    return Pose(u @ vt, centres[0])


def solve_pose_gravity(
    image_points,
    object_points,
    camera: Camera,
    gravity,
    *,
    up,
    normals=None,
    sigma_deg: float = 1.0,
    pixel_sigma_px=1.0,
    outlier_px: float = 4.0,
) -> GravityPose:
    """The camera's pose from two or more identified fixtures and the gravity direction.

    Parameters
    ----------
    image_points : array_like, shape (N, 2)
        Detected fixture centres, pixels (distorted image as taken), N >= 2.
    object_points : array_like, shape (N, 3)
        The same fixtures' map positions, map units.
    camera : Camera
        Intrinsics and distortion; the centres are undistorted to normalised bearings.
    gravity : array_like, shape (3,)
        Gravity in the camera's frame (x right, y down, z forward), any length.
    up : array_like, shape (3,)
        The map's up, world frame (see :func:`map_up`).
    normals : array_like, shape (N, 3), optional
        The way each fixture faces (rows of NaN where unknown); poses behind them are refused.
    sigma_deg : float
        The accelerometer's uncertainty, degrees: weighs the gravity residual against the
        reprojection residuals.
    pixel_sigma_px : float or array_like, shape (N,)
        The centres' uncertainty, pixels (1-sigma per axis): one for all, or one per fixture
        (e.g. :attr:`camvlp.pipeline.detect.blob.Blob.centre_sigma_px`), which weighs each
        fixture's reprojection residual.
    outlier_px : float
        A fixture whose reprojection error exceeds this (pixels) does not fit, nor does a
        pose whose down is more than :data:`MAX_TILT_SIGMAS` sigmas from gravity: with four or
        more fixtures that miss by pixels, the one whose removal fits best is dropped while
        at least three remain; otherwise a failure.

    Returns
    -------
    GravityPose
        Falsy, with a reason, when no pose can be trusted.

    Raises
    ------
    InputError
        Gravity not three finite numbers or of zero length.
    ValueError
        Mismatched or non-finite points, or non-positive sigmas.
    """
    g = check_gravity(gravity)
    img = np.asarray(image_points, dtype=float).reshape(-1, 2)
    obj = np.asarray(object_points, dtype=float).reshape(-1, 3)
    if img.shape[0] != obj.shape[0]:
        raise ValueError("image_points and object_points must have the same length")
    if not (np.all(np.isfinite(img)) and np.all(np.isfinite(obj))):
        raise ValueError("image_points and object_points must be finite")
    if not (np.isfinite(sigma_deg) and sigma_deg > 0):
        raise ValueError(f"sigma_deg must be positive, got {sigma_deg!r}")
    pix_sigma = np.asarray(pixel_sigma_px, dtype=float)
    if pix_sigma.ndim > 1 or pix_sigma.size not in (1, img.shape[0]):
        raise ValueError("pixel_sigma_px must be one number or one per fixture")
    if not np.all(np.isfinite(pix_sigma) & (pix_sigma > 0)):
        raise ValueError(f"pixel_sigma_px must be positive, got {pixel_sigma_px!r}")
    pix_sigma = np.broadcast_to(pix_sigma.reshape(-1), (img.shape[0],))
    u = map_up(obj, up=up)
    nrm = None if normals is None else np.asarray(normals, dtype=float).reshape(-1, 3)
    n = obj.shape[0]
    if n < 2:
        return _failure(
            n, f"{n} identified fixture{'s' if n != 1 else ''}, at least 2 are needed with gravity"
        )
    bearings = camera.undistort_pixels(img)
    focal = camera.focal_px
    if n == 2:
        return _two(bearings, obj, g, u, nrm, focal)
    return _three_or_more(
        bearings,
        obj,
        g,
        u,
        nrm,
        focal,
        sigma_deg,
        pixel_sigma_px=pix_sigma,
        outlier_px=outlier_px,
    )


def _three_or_more(
    bearings: np.ndarray,
    obj: np.ndarray,
    g: np.ndarray,
    u: np.ndarray,
    nrm: np.ndarray | None,
    focal: float,
    sigma_deg: float,
    *,
    pixel_sigma_px: np.ndarray,
    outlier_px: float,
) -> GravityPose:
    """:func:`solve_pose_gravity` for N >= 3 fixtures: bearings (N, 2), map points (N, 3),
    unit gravity ``g`` (camera frame) and up ``u``, centre sigmas (N,) pixels; the worst
    fixture dropped while the rest do not fit and at least three remain."""
    n = obj.shape[0]
    idx = np.arange(n)
    while True:
        pose, reason = _fit(idx, bearings, obj, g, u, nrm, focal, sigma_deg, pixel_sigma_px)
        if pose is None:
            return _failure(n, reason)
        worst = float(np.max(_pixel_residuals(pose, obj[idx], bearings[idx], focal)))
        tilt = tilt_error_deg(pose.world_from_camera, g, u)
        if worst <= outlier_px and tilt <= MAX_TILT_SIGMAS * sigma_deg:
            break
        if idx.size <= 3 or worst <= outlier_px:
            why = (
                f"reprojection error up to {worst:.1f} px"
                if worst > outlier_px
                else f"only with a tilt {tilt:.1f} degrees from gravity, more than "
                f"{MAX_TILT_SIGMAS:g} x {sigma_deg:g}"
            )
            return GravityPose(
                None,
                _solver_for(n),
                0,
                np.zeros(n, bool),
                _pixel_residuals(pose, obj, bearings, focal),
                gravity_residual_deg=tilt,
                reason=f"the fixtures do not fit one pose with this gravity ({why}): a wrong "
                "ID, map, camera file or gravity",
            )
        idx = _drop_worst(idx, bearings, obj, g, u, nrm, focal, pixel_sigma_px)
    return _kept(pose, idx, bearings, obj, g, u, nrm, focal, pixel_sigma_px)


def _fit(
    idx: np.ndarray, bearings, obj, g, u, nrm, focal: float, sigma_deg: float, pixel_sigma_px
) -> tuple[Pose | None, str]:
    """The pose of the fixtures ``idx``: least squares over heading and position with the tilt
    held, then the whole pose refined with the gravity residual; or None and why."""
    pose, reason = _least_squares(
        bearings[idx],
        obj[idx],
        g,
        u,
        None if nrm is None else nrm[idx],
        focal,
        pixel_sigma_px[idx],
    )
    if pose is None:
        return None, reason
    pose = _refine(
        pose,
        obj[idx],
        bearings[idx],
        focal,
        gravity=g,
        up=u,
        sigma_deg=sigma_deg,
        pixel_sigma_px=pixel_sigma_px[idx],
    )
    return pose, reason


def _kept(
    pose: Pose, idx: np.ndarray, bearings, obj, g, u, nrm, focal: float, pixel_sigma_px
) -> GravityPose:
    """The result of the pose that the fixtures ``idx`` fit: refused when a fixture is behind
    the camera or seen from its back; with four or more, the tilt the pixels alone give
    compared with gravity's."""
    n = obj.shape[0]
    in_front, lit = _valid(pose, obj[idx], None if nrm is None else nrm[idx])
    if not (in_front and lit):
        return _failure(
            n,
            "no pose with this gravity puts every fixture in front of the camera, on its lit side",
        )
    residuals = _pixel_residuals(pose, obj, bearings, focal)
    used = np.zeros(n, bool)
    used[idx] = True
    disagreement = float("nan")
    if idx.size >= 4:
        photo = _refine(pose, obj[idx], bearings[idx], focal, pixel_sigma_px=pixel_sigma_px[idx])
        disagreement = tilt_error_deg(photo.world_from_camera, g, u)
    return GravityPose(
        pose,
        _solver_for(int(idx.size)),
        int(idx.size),
        used,
        residuals,
        float(np.sqrt(np.mean(residuals[used] ** 2))),
        tilt_error_deg(pose.world_from_camera, g, u),
        disagreement,
    )


def _drop_worst(idx, bearings, obj, g, u, nrm, focal, pixel_sigma_px) -> np.ndarray:
    """The subset, one fixture fewer, that fits best (centre sigmas (N,), pixels)."""
    best, best_cost = idx[:-1], np.inf
    for sub in combinations(idx.tolist(), idx.size - 1):
        sub = np.array(sub)
        pose, _ = _least_squares(
            bearings[sub],
            obj[sub],
            g,
            u,
            None if nrm is None else nrm[sub],
            focal,
            pixel_sigma_px[sub],
        )
        if pose is None:
            continue
        cost = float(np.max(_pixel_residuals(pose, obj[sub], bearings[sub], focal)))
        if cost < best_cost:
            best, best_cost = sub, cost
    return best


def _two(bearings, obj, g, u, nrm, focal) -> GravityPose:
    poses, reason = solve_two_fixtures(bearings, obj, g, u)
    if not poses:
        return _failure(2, reason)
    ok = [p for p in poses if all(_valid(p, obj, nrm))]
    if not ok:
        return _failure(
            2,
            "no pose with this gravity puts both fixtures in front of the "
            "camera, on their lit side",
            candidates=tuple(poses),
        )
    if len(ok) == 2:
        far = float(np.linalg.norm(ok[0].position - ok[1].position))
        if far > 1e-6 * float(np.linalg.norm(obj[0] - obj[1])):
            return _failure(
                2,
                "two poses fit the two fixtures and gravity equally (at "
                f"{format_vector(ok[0].position)} and {format_vector(ok[1].position)}): a third "
                "fixture is needed",
                alternative=ok[1],
                candidates=tuple(ok),
            )
    pose = ok[0]
    residuals = _pixel_residuals(pose, obj, bearings, focal)
    return GravityPose(
        pose,
        "gravity-2",
        2,
        np.ones(2, bool),
        residuals,
        float(np.sqrt(np.mean(residuals**2))),
        tilt_error_deg(pose.world_from_camera, g, u),
        candidates=tuple(poses),
    )


def _least_squares(bearings, obj, g, u, nrm, focal, pixel_sigma_px) -> tuple[Pose | None, str]:
    """Heading and position with the tilt held, from the two-fixture solutions of pairs;
    each fixture's residual weighed by its centre sigma ``pixel_sigma_px`` (N,), pixels."""
    n = obj.shape[0]
    pairs = sorted(
        combinations(range(n), 2),
        key=lambda ij: -float(np.linalg.norm(np.cross(obj[ij[0]] - obj[ij[1]], u))),
    )[:4]
    starts, reasons = [], []
    for i, j in pairs:
        found, reason = solve_two_fixtures(bearings[[i, j]], obj[[i, j]], g, u)
        reasons += [reason] if reason else []
        starts += [p for p in found if _valid(p, obj[[i, j]], None)[0]]
    best, best_cost = None, np.inf
    for pose in _fit_heading_position(starts, obj, bearings, g, u, focal, pixel_sigma_px):
        in_front, lit = _valid(pose, obj, nrm)
        if not (in_front and lit):
            continue
        cost = float(np.sum((_pixel_residuals(pose, obj, bearings, focal) / pixel_sigma_px) ** 2))
        if cost < best_cost:
            best, best_cost = pose, cost
    if best is None:
        return None, (
            reasons[0]
            if reasons and len(reasons) == len(pairs)
            else "no pose with this gravity puts every fixture in front of the camera, "
            "on its lit side"
        )
    return best, ""
