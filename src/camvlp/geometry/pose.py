"""Stage 3: the camera's pose from identified fixtures (thesis section 5.5, made safe).

* Fewer than four fixtures, or fixtures (nearly) on one line, in the world or in the image:
  a failure that says so, never a pose.
* Candidates come from :func:`camvlp.geometry.pnp.pnp_candidates`: the chosen solver, IPPE's
  two poses for coplanar fixtures (the usual ceiling has a two-fold pose ambiguity) and SQPnP,
  each refined by Levenberg-Marquardt unless the solver is ``ippe`` or ``epnp`` (kept raw so
  that they can be compared as they are).  The candidate that reprojects best with every
  fixture in front of the camera is kept; the other pose of the ambiguity is reported too.
* With five or more fixtures, a fixture that does not fit (a wrong ID, a moved light) is
  dropped instead of pulling the pose: leave-one-out while the reprojection error is large.
* Fixtures may carry a ``normal`` (the way they face).  A pose that puts the camera behind
  them is refused: such a photo looks mirrored.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from itertools import combinations
from typing import NamedTuple

import cv2
import numpy as np

from camvlp.geometry.pnp import candidate_methods, check_solver, other_minima, pnp_candidates
from camvlp.model.camera import Camera, Pose, all_finite, project_camera_points

__all__ = ["PoseEstimate", "estimate_pose"]


@dataclass(frozen=True)
class PoseEstimate:
    """A pose solve: the pose, or why there is none.

    Attributes
    ----------
    pose : Pose or None
        The camera's pose in the map frame; None when it failed.
    reprojection_rms_px : float
        RMS distance between the detected centres and the map points reprojected with the
        pose, over the fixtures used, pixels (NaN on failure).
    used : ndarray of bool, shape (N,)
        Which of the given fixtures the pose uses.
    residuals_px : ndarray, shape (N,)
        Each fixture's reprojection error with the pose, pixels (NaN on failure).
    alternative : Pose or None
        The other candidate of a planar target, when there was one.
    alternative_rms_px : float
        Its reprojection RMS, pixels.
    reason : str
        Why it failed ("" on success).
    mirrored : bool
        The only poses that fit put the camera behind the lights.
    margin : float
        How much better the pose fits than the alternative: ``1 - SSR / SSR_alternative``
        (sums of squared reprojection errors over the fixtures used; 1 without an
        alternative, NaN on failure).  A pose whose alternative fits about as well, within
        what the centres' noise allows, is refused (:data:`AMBIGUITY_CHI2`).
    """

    pose: Pose | None
    reprojection_rms_px: float
    used: np.ndarray
    residuals_px: np.ndarray
    alternative: Pose | None = None
    alternative_rms_px: float = float("nan")
    reason: str = ""
    mirrored: bool = field(default=False)
    margin: float = float("nan")
    close: bool = False

    def __bool__(self) -> bool:
        return self.pose is not None


def _failure(n: int, reason: str, *, mirrored: bool = False) -> PoseEstimate:
    nan = np.full(n, np.nan)
    return PoseEstimate(
        None, float("nan"), np.zeros(n, bool), nan, reason=reason, mirrored=mirrored
    )


def _spread(points: np.ndarray) -> np.ndarray:
    """Singular values of the centred points (N, D), largest first: how far they are from a
    point, a line, a plane."""
    return np.linalg.svd(points - points.mean(axis=0), compute_uv=False)


def _residuals(camera: Camera, pose: Pose, obj: np.ndarray, img: np.ndarray) -> np.ndarray:
    """Each fixture's reprojection error with ``pose``, pixels (N,): inf behind the camera."""
    d = camera.project(pose, obj) - img
    return _distances((d * d).sum(axis=-1))


def _distances(squared: np.ndarray) -> np.ndarray:
    """Reprojection errors (pixels) from their squares (pixels^2), inf where not finite (a
    fixture behind the camera)."""
    return np.where(np.isfinite(squared), np.sqrt(squared), np.inf)


def _scores(camera: Camera, poses: list[Pose], obj: np.ndarray, img: np.ndarray, normals) -> list:
    """``(rms, in_front, facing, pose, squared)`` of each candidate: its reprojection RMS
    (pixels; inf with a fixture behind the camera), whether every fixture is in front of it,
    whether it is in front of every fixture with a normal, the pose, and its fixtures'
    squared reprojection errors (pixels^2, (N,); :func:`_distances` gives the errors): all
    candidates in one projection (a candidate with a fixture behind it is projected too, its
    values not used)."""
    n = obj.shape[0]
    rot = np.array([p.world_from_camera for p in poses])  # (B, 3, 3)
    pos = np.array([p.position for p in poses])  # (B, 3)
    cam = (obj - pos[:, None]) @ rot  # (B, N, 3): Pose.to_camera of each
    in_front = (cam[:, :, 2] > 0).all(axis=1)
    facing = np.ones(len(poses), bool)
    if normals is not None:
        has = np.isfinite(normals).all(axis=1)
        if has.any():
            ahead = (normals[has] * (pos[:, None] - obj[has])).sum(axis=2)  # (B, N')
            facing = (ahead > 0).all(axis=1)
    uv = project_camera_points(camera, cam.reshape(-1, 3))
    e = uv.reshape(len(poses), n, 2) - img
    r2 = (e * e).sum(axis=2)  # squared residuals, (B, N)
    total = r2.sum(axis=1)
    # inf unless every squared residual is finite (a sum of finite squares that overflows
    # gives inf either way)
    ok = in_front & np.isfinite(total)
    rms = np.where(ok, np.sqrt(np.where(ok, total, 0.0) / n), np.inf)
    return [
        (float(rms[k]), bool(in_front[k]), bool(facing[k]), poses[k], r2[k])
        for k in range(len(poses))
    ]


#: Reprojection RMS (pixels) within which the better of IPPE's two refined poses is taken as
#: the right minimum without the other solvers' seeds.
CLEAR_FIT_PX = 1.0


def _scored(camera: Camera, obj, img, normals, solver: str, planar: bool, methods) -> list:
    """:func:`_scores` of the candidates from ``methods``."""
    if not methods:
        return []
    poses = pnp_candidates(obj, img, camera, solver, planar=planar, methods=methods)
    return _scores(camera, poses, obj, img, normals) if poses else []


def _choose(
    camera: Camera,
    obj: np.ndarray,
    img: np.ndarray,
    normals: np.ndarray | None,
    solver: str,
    planar: bool,
) -> tuple[Pose | None, float, Pose | None, float, bool, np.ndarray | None]:
    """Best valid candidate and the runner-up; flags a best fit that is behind the lights;
    and the best one's reprojection errors (pixels, per fixture).

    Coplanar fixtures with the default solver: IPPE's two poses (the planar ambiguity's two
    minima, refined) first; when the better one is valid and reprojects within
    :data:`CLEAR_FIT_PX`, the other solvers' seeds, which converge to one of the two, are
    not tried (about a third of the time of the pose).
    """
    methods = candidate_methods(solver, planar, obj.shape[0])
    if solver != "iterative" or cv2.SOLVEPNP_IPPE not in methods:
        scored = _scored(camera, obj, img, normals, solver, planar, methods)
    else:
        k = methods.index(cv2.SOLVEPNP_IPPE)
        scored = _scored(camera, obj, img, normals, solver, planar, methods[k : k + 1])
        if not any(s[1] and s[2] and s[0] <= CLEAR_FIT_PX for s in scored):
            # not clearly right: every candidate, in the order of candidate_methods
            scored = (
                _scored(camera, obj, img, normals, solver, planar, methods[:k])
                + scored
                + _scored(camera, obj, img, normals, solver, planar, methods[k + 1 :])
            )
    # a few points: every local minimum, from each triple's P3P (two minima a few pixels
    # apart that IPPE's pair does not hold, when three points are nearly on a line)
    minima = other_minima(obj, img, camera)
    if minima:
        scored += _scores(camera, minima, obj, img, normals)
    valid = sorted((s for s in scored if s[1] and s[2]), key=lambda s: s[0])
    behind = sorted((s for s in scored if s[1] and not s[2]), key=lambda s: s[0])
    mirrored = bool(behind) and (not valid or behind[0][0] < 0.25 * valid[0][0])
    if not valid:
        return None, np.inf, None, np.nan, mirrored, None
    # The runner-up must be another pose, not the best one again: seeds that converge to
    # the same minimum differ by the optimiser's tolerance (up to about 1e-4 of the distance
    # for a small target), the planar ambiguity's other pose by about twice the tilt.
    best = valid[0][3]
    alt = (np.nan, None, None, None, None)
    if len(valid) > 1:
        scale = np.linalg.norm(best.position - obj.mean(axis=0))
        for s in valid[1:]:
            # the turn between the two: trace(R1^T R2) = sum of the elementwise products
            cos_turn = (np.sum(s[3].world_from_camera * best.world_from_camera) - 1.0) / 2.0
            turn_deg = math.degrees(math.acos(min(max(cos_turn, -1.0), 1.0)))
            if np.linalg.norm(s[3].position - best.position) > 1e-3 * scale or turn_deg > 0.1:
                alt = s
                break
    return best, valid[0][0], alt[3], float(alt[0]), mirrored, _distances(valid[0][4])


def _near(ssr: float, alt_ssr: float, n: int, centre_sigma_px) -> bool:
    """Whether a second pose fits ``n`` fixtures about as well as the best: their sums of
    squared reprojection errors (pixels^2) within :data:`AMBIGUITY_CHI2` times the centres'
    noise variance, the noise being the largest of the fit's own residual per degree of
    freedom, :data:`MIN_NOISE_PX` and ``centre_sigma_px`` (a number, or a function that gives
    it, called only when the answer depends on it)."""
    gap = alt_ssr - ssr
    noise2 = max(ssr / max(2 * n - 6, 1), MIN_NOISE_PX**2)
    if gap < AMBIGUITY_CHI2 * noise2:
        return True
    if centre_sigma_px is None:
        return False
    sigma = centre_sigma_px() if callable(centre_sigma_px) else centre_sigma_px
    return gap < AMBIGUITY_CHI2 * float(sigma) ** 2


#: Two poses that fit about equally are two answers when the camera centres lie further
#: apart than this share of the distance from the camera to the fixtures (a metre at 2.5 m
#: for Luxapose's four lights, three on a diagonal); nearer, they are one answer, less sure
#: (:attr:`PoseEstimate.close`: the position's sigma covers the other).
APART = 0.02


def _apart(pose: Pose, other: Pose, points: np.ndarray) -> bool:
    """Whether two poses' camera centres are further apart than :data:`APART` of the
    distance from the first to the fixtures (``points``, shape (N, 3))."""
    reach = float(np.linalg.norm(points.mean(axis=0) - pose.position))
    return float(np.linalg.norm(other.position - pose.position)) > APART * reach


#: Two poses fit about equally when their sums of squared reprojection errors differ by
#: less than this many times the centres' noise variance (three standard deviations).
AMBIGUITY_CHI2 = 9.0
#: The least noise (pixels) a centre is taken to have when telling two poses apart.
MIN_NOISE_PX = 0.1


def estimate_pose(
    image_points,
    object_points,
    camera: Camera,
    *,
    normals=None,
    solver: str = "iterative",
    outlier_px: float = 4.0,
    centre_sigma_px=None,
) -> PoseEstimate:
    """Solve Perspective-n-Point for identified fixtures.

    Parameters
    ----------
    image_points : array_like, shape (N, 2)
        Detected fixture centres, pixels (distorted image).
    object_points : array_like, shape (N, 3)
        The same fixtures' map positions, map units.
    camera : Camera
        Intrinsics and distortion.
    normals : array_like, shape (N, 3), optional
        The way each fixture faces (rows of NaN where unknown); a pose behind them is refused.
    solver : {"iterative", "sqpnp", "ippe", "epnp"}
        OpenCV's solver for the first estimate (the thesis uses iterative).
    outlier_px : float
        With five or more fixtures, a fixture whose reprojection error exceeds this (pixels)
        after the others are fitted is dropped.
    centre_sigma_px : float or callable, optional
        The centres' noise, pixels, or a function that gives it (called only when needed):
        a second pose that fits within :data:`AMBIGUITY_CHI2` times its variance (at least
        the fit's own residual per degree of freedom, and :data:`MIN_NOISE_PX`) makes the
        pose ambiguous, refused with both positions.

    Returns
    -------
    PoseEstimate
        Falsy, with a reason, when no pose can be trusted.
    """
    check_solver(solver)
    img, obj, nrm = _points(image_points, object_points, normals)
    n = obj.shape[0]
    if n < 4:
        return _failure(n, f"{n} identified fixture{'s' if n != 1 else ''}, at least 4 are needed")
    if not all_finite(img, obj):
        raise ValueError("image_points and object_points must be finite")
    undetermined = _undetermined(img, obj)
    if undetermined:
        return _failure(n, undetermined)

    def solve(idx: np.ndarray):
        sub_normals = None if nrm is None else nrm[idx]
        return _choose(camera, obj[idx], img[idx], sub_normals, solver, _planar(obj[idx]))

    idx = np.arange(n)
    pose, rms, alt, alt_rms, mirrored, errors = solve(idx)
    if pose is None:
        reason = MIRRORED if mirrored else "no pose puts every fixture in front of the camera"
        return _failure(n, reason, mirrored=mirrored)
    fit = _leave_one_out(solve, _Fit(idx, pose, rms, alt, alt_rms, errors), outlier_px)
    return _judged(camera, obj, img, fit, outlier_px, centre_sigma_px)


#: Why there is no pose when the only poses that fit put the camera behind the lights.
MIRRORED = (
    "the only pose that fits puts the camera behind the lights: the photo looks mirrored "
    "(try --mirrored)"
)


class _Fit(NamedTuple):
    """A pose fitted to some of the fixtures."""

    idx: np.ndarray  # the fixtures it uses, indices
    pose: Pose
    rms: float  # reprojection RMS over them, pixels
    alt: Pose | None  # the runner-up
    alt_rms: float
    errors: np.ndarray  # reprojection errors of those in idx, pixels


def _points(image_points, object_points, normals):
    """The image points (N, 2), map points (N, 3) and normals ((N, 3) or None) as float
    arrays; ValueError when there are not as many image points as map points."""
    img = np.asarray(image_points, dtype=float).reshape(-1, 2)
    obj = np.asarray(object_points, dtype=float).reshape(-1, 3)
    if img.shape[0] != obj.shape[0]:
        raise ValueError("image_points and object_points must have the same length")
    nrm = None if normals is None else np.asarray(normals, dtype=float).reshape(-1, 3)
    return img, obj, nrm


def _undetermined(img: np.ndarray, obj: np.ndarray) -> str:
    """Why the fixtures (four or more, finite) cannot determine a pose, "" when they can."""
    sw, si = _spread(obj), _spread(img)
    if sw[1] <= 1e-3 * sw[0] or si[1] <= 1e-3 * si[0]:
        return "the fixtures are (nearly) on one line: the pose is not determined"
    if len(set(map(tuple, img.round(3).tolist()))) < img.shape[0]:
        return "two fixtures were detected at the same pixel"
    return ""


def _planar(obj: np.ndarray) -> bool:
    """Whether map points (N, 3) are (nearly) coplanar."""
    spread = _spread(obj)
    return bool(spread[2] <= 1e-4 * spread[0])


def _leave_one_out(solve, fit: _Fit, outlier_px: float) -> _Fit:
    """While a fixture does not fit (an error over ``outlier_px`` pixels) and five or more are
    used, the best fit of all but one (``solve(idx)``: :func:`_choose` on those fixtures)."""
    while fit.idx.size >= 5 and np.max(fit.errors) > outlier_px:
        best = None
        for subset in combinations(range(fit.idx.size), fit.idx.size - 1):
            sub = fit.idx[list(subset)]
            p, r, a, ar, _, e = solve(sub)
            if p is not None and (best is None or r < best.rms):
                best = _Fit(sub, p, r, a, ar, e)
        if best is None:
            break
        fit = best
    return fit


def _judged(camera: Camera, obj, img, fit: _Fit, outlier_px: float, centre_sigma_px):
    """The :class:`PoseEstimate` of a fit: refused when a fixture it uses does not fit, or
    when its runner-up fits about as well with the camera elsewhere."""
    n = obj.shape[0]
    if fit.idx.size == n:  # every fixture used: the chosen candidate's own errors
        residuals, used = fit.errors, np.ones(n, bool)
    else:
        residuals, used = _residuals(camera, fit.pose, obj, img), np.zeros(n, bool)
        used[fit.idx] = True
    worst = float(residuals[used].max())
    if worst > outlier_px:
        return PoseEstimate(
            None,
            float("nan"),
            np.zeros(n, bool),
            residuals,
            reason=f"the fixtures do not fit one pose (reprojection error up to "
            f"{worst:.1f} px): a wrong ID, map or camera file",
        )
    pose, rms, alt, alt_rms = fit.pose, fit.rms, fit.alt, fit.alt_rms
    n_used = int(used.sum())
    ssr, alt_ssr = n_used * rms * rms, n_used * alt_rms * alt_rms
    margin = 1.0 - ssr / alt_ssr if alt is not None and alt_ssr > 0 else 1.0
    near = alt is not None and _near(ssr, alt_ssr, n_used, centre_sigma_px)
    if near and _apart(pose, alt, obj[used]):
        where = ", ".join(f"{v:.4g}" for v in pose.position)
        other = ", ".join(f"{v:.4g}" for v in alt.position)
        return PoseEstimate(
            None,
            float("nan"),
            np.zeros(n, bool),
            residuals,
            alt,
            alt_rms,
            reason=f"two poses fit the fixtures about equally ({rms:.2f} and {alt_rms:.2f} px "
            f"RMS): the camera at ({where}) or at ({other}); a fixture more, gravity or a "
            "prior would tell",
            margin=margin,
        )
    return PoseEstimate(pose, rms, used, residuals, alt, alt_rms, margin=margin, close=near)
