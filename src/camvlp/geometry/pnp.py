"""Perspective-n-Point, the one home of every ``solvePnP`` call: one pose, many, or the
locator's candidates.

Frames follow the package conventions (``camera.py``): a pose is ``world_from_camera``
``R`` (camera axes as columns) and the camera centre ``C``; OpenCV's ``rvec, tvec`` are
``camera_from_world``, so ``R = Rodrigues(rvec).T`` and ``C = -R @ tvec``.

Solvers (:data:`SOLVERS`):

``iterative``
    Levenberg-Marquardt on the reprojection error, started from a homography (planar
    targets) or DLT; the thesis' choice.  OpenCV refuses fewer than six points that are
    not coplanar (fixtures at different heights); :func:`solve_pnp` then starts the
    Levenberg-Marquardt refinement from the ``sqpnp`` solution.
``sqpnp``
    Globally optimal sequential quadratic programming; as accurate as ``iterative``.
``ippe``
    Infinitesimal plane-based pose; needs coplanar object points.  OpenCV 5.0 returns NaN
    when the image points form an exact rectangle (common with a camera parallel to the
    ceiling and rounded pixels); :func:`solve_pnp` then retries once with the image points
    moved by at most :data:`IPPE_JITTER_PX`.
``epnp``
    Efficient PnP; fast but poorly conditioned with four coplanar points (metres off).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import cv2
import numpy as np

from camvlp.model.camera import Camera, Pose, all_finite, in_front

__all__ = [
    "IPPE_JITTER_PX",
    "LOCATE_SOLVER",
    "SOLVERS",
    "PriorSolve",
    "candidate_methods",
    "check_solver",
    "other_minima",
    "pnp_candidates",
    "project_batch",
    "refine_pose",
    "rodrigues_batch",
    "solve_pnp",
    "solve_pnp_batch",
]

#: Solver names and the OpenCV flags they select.
SOLVERS: dict[str, int] = {
    "iterative": cv2.SOLVEPNP_ITERATIVE,
    "sqpnp": cv2.SOLVEPNP_SQPNP,
    "ippe": cv2.SOLVEPNP_IPPE,
    "epnp": cv2.SOLVEPNP_EPNP,
}

#: Largest move (pixels) of an image point when IPPE is retried after returning NaN.
IPPE_JITTER_PX = 1e-6

# Deterministic, tiny, non-rectangular moves for the IPPE retry (pixels), cycled over points.
_JITTER = IPPE_JITTER_PX * np.array([[1.0, 0.3], [-0.7, 0.9], [0.2, -1.0], [-0.4, -0.6]])


#: The locator's own pose path (:func:`camvlp.geometry.pose.estimate_pose`), which the error
#: study can run beside OpenCV's methods to measure what ``locate`` gives.
LOCATE_SOLVER = "locate"


def check_solver(solver: str, *, allow_locate: bool = False) -> str:
    """``solver`` if it names a PnP method (and ``"locate"`` when allowed).

    Raises
    ------
    ValueError
        One line listing the accepted names.
    """
    names = [*SOLVERS, LOCATE_SOLVER] if allow_locate else list(SOLVERS)
    if not isinstance(solver, str) or solver not in names:
        raise ValueError(f"solver must be one of {', '.join(names)}, got {solver!r}")
    return solver


def _solver_flag(solver: str) -> int:
    return SOLVERS[check_solver(solver)]


def _check_points(object_points, image_points, *, batch: bool) -> tuple[np.ndarray, np.ndarray]:
    """Validate and convert to contiguous float64; object points (N,3) or (B,N,3)."""
    obj = np.ascontiguousarray(object_points, dtype=np.float64)
    img = np.ascontiguousarray(image_points, dtype=np.float64)
    want_img = "(B, N, 2)" if batch else "(N, 2)"
    if img.ndim != (3 if batch else 2) or img.shape[-1] != 2:
        raise ValueError(f"image_points must have shape {want_img}, got {img.shape}")
    n = img.shape[-2]
    if batch:
        if obj.ndim not in (2, 3) or obj.shape[-1] != 3:
            raise ValueError(f"object_points must have shape (N, 3) or (B, N, 3), got {obj.shape}")
        if obj.ndim == 3 and obj.shape[0] != img.shape[0]:
            raise ValueError(
                f"object_points has {obj.shape[0]} poses but image_points has {img.shape[0]}"
            )
    elif obj.ndim != 2 or obj.shape[-1] != 3:
        raise ValueError(f"object_points must have shape (N, 3), got {obj.shape}")
    if obj.shape[-2] != n:
        raise ValueError(f"object_points has {obj.shape[-2]} points but image_points has {n}")
    if n < 4:
        raise ValueError(f"object_points and image_points need at least 4 points, got {n}")
    if not np.all(np.isfinite(obj)):
        raise ValueError("object_points must be finite")
    return obj, img


def _call(obj: np.ndarray, img: np.ndarray, k: np.ndarray, dist, flag: int, guess=None):
    """One ``cv2.solvePnP`` call; (rvec, tvec) as (3,) arrays, or None on failure."""
    try:
        if guess is None:
            ok, rvec, tvec = cv2.solvePnP(obj, img, k, dist, flags=flag)
        else:
            rv0 = guess[0].reshape(3, 1).copy()
            tv0 = guess[1].reshape(3, 1).copy()
            ok, rvec, tvec = cv2.solvePnP(obj, img, k, dist, rv0, tv0, True, flags=flag)
    except cv2.error:
        return None
    if not ok or not (np.all(np.isfinite(rvec)) and np.all(np.isfinite(tvec))):
        return None
    return rvec.reshape(3), tvec.reshape(3)


def _solve_one(obj: np.ndarray, img: np.ndarray, k: np.ndarray, dist, flag: int):
    """Solve with the documented fall-backs; (rvec, tvec) or None."""
    res = _call(obj, img, k, dist, flag)
    if res is not None:
        return res
    if flag == cv2.SOLVEPNP_IPPE:
        moved = img + _JITTER[np.arange(img.shape[0]) % len(_JITTER)]
        return _call(obj, moved, k, dist, flag)
    if flag == cv2.SOLVEPNP_ITERATIVE:
        # OpenCV's ITERATIVE needs 6 points unless they are (nearly) coplanar: start
        # Levenberg-Marquardt from SQPnP's answer instead of its own DLT.
        init = _call(obj, img, k, dist, cv2.SOLVEPNP_SQPNP)
        if init is None:
            return None
        return _call(obj, img, k, dist, flag, guess=init) or init
    return None


def candidate_methods(solver: str, planar: bool, n: int) -> list[int]:
    """The OpenCV methods :func:`pnp_candidates` takes its seeds from, in order: the chosen
    solver's, IPPE's when the object points are coplanar, SQPnP's (four points or more)."""
    methods = [_solver_flag(solver)]
    if planar:
        methods.append(cv2.SOLVEPNP_IPPE)
    # SQPnP as well, planar or not: IPPE's homography degenerates when three of four
    # fixtures are on one line (a grid's diagonal) and then gives no candidate at all
    if n >= 4:
        methods.append(cv2.SOLVEPNP_SQPNP)
    return list(dict.fromkeys(methods))


def pnp_candidates(
    object_points,
    image_points,
    camera: Camera,
    solver: str = "iterative",
    *,
    planar: bool,
    methods: list[int] | None = None,
) -> list[Pose]:
    """Every candidate pose for the locator to choose from (no check of which is valid).

    The chosen solver's poses, IPPE's two poses when the object points are coplanar (a
    planar target's two-fold ambiguity) and SQPnP's (IPPE's homography degenerates when three
    of four points are on one line), each refined by Levenberg-Marquardt
    (``cv2.solvePnPRefineLM``) unless the solver is ``ippe`` or ``epnp``, which are kept raw.

    ``object_points``, ``image_points``, ``camera`` and ``solver`` are as in
    :func:`solve_pnp`; ``planar`` says the object points are coplanar (add IPPE's two
    candidates); ``methods`` (OpenCV ``SOLVEPNP_*`` flags) takes the seeds from these only,
    as a part of :func:`candidate_methods`.

    Returns
    -------
    list of Pose
        Possibly empty; non-finite solutions are left out.
    """
    o = np.ascontiguousarray(object_points, dtype=np.float64).reshape(-1, 1, 3)
    i = np.ascontiguousarray(image_points, dtype=np.float64).reshape(-1, 1, 2)
    k, d = camera.matrix, camera.dist_or_none
    if methods is None:
        methods = candidate_methods(solver, planar, o.shape[0])
    refine = solver != "epnp" and solver != "ippe"
    poses = []
    for method in methods:
        try:
            n, rvecs, tvecs, _ = cv2.solvePnPGeneric(o, i, k, d, flags=method)
        except cv2.error:
            continue
        for j in range(n):
            rvec, tvec = rvecs[j], tvecs[j]  # (this call's own arrays: refined in place)
            if not all_finite(rvec, tvec):
                continue
            if refine:
                rvec, tvec = cv2.solvePnPRefineLM(o, i, k, d, rvec, tvec)
            try:
                poses.append(Pose.from_rvec_tvec(rvec, tvec))
            except ValueError:
                continue
    return poses


#: Fewest and most points for which :func:`other_minima` seeds from every triple.
_TRIPLE_POINTS = (4, 6)
#: A P3P seed whose RMS over all points exceeds this many pixels is not refined: it lies in
#: no minimum worth comparing.
_SEED_RMS_PX = 50.0


def other_minima(object_points, image_points, camera: Camera) -> list[Pose]:
    """Poses from P3P on every triple of a few points, each refined on all of them: the
    local minima of the reprojection error that IPPE's two poses and the solvers' seeds may
    all miss.

    Four points with three (nearly) on a line have two minima a few pixels apart that are
    not the planar ambiguity's pair; P3P's up to four solutions per triple find both.  Only
    seeds that reproject within :data:`_SEED_RMS_PX` over every point are refined
    (Levenberg-Marquardt).  Empty for fewer than four or more than six points.

    Parameters
    ----------
    object_points : array_like, shape (N, 3)
        World coordinates, map units.
    image_points : array_like, shape (N, 2)
        Pixels in the (distorted) image.
    camera : Camera
        Intrinsics and distortion.

    Returns
    -------
    list of Pose
        Possibly empty; not checked for which side of the points the camera is.
    """
    o = np.ascontiguousarray(object_points, dtype=np.float64).reshape(-1, 1, 3)
    i = np.ascontiguousarray(image_points, dtype=np.float64).reshape(-1, 1, 2)
    n = o.shape[0]
    if not _TRIPLE_POINTS[0] <= n <= _TRIPLE_POINTS[1]:
        return []
    k, d = camera.matrix, camera.dist_or_none
    poses = []
    for tri in itertools.combinations(range(n), 3):
        t = list(tri)
        try:
            _, rvecs, tvecs = cv2.solveP3P(o[t], i[t], k, d, flags=cv2.SOLVEPNP_AP3P)
        except cv2.error:
            continue
        for rvec, tvec in zip(rvecs, tvecs, strict=True):
            if not all_finite(rvec, tvec):
                continue
            uv, _ = cv2.projectPoints(o, rvec, tvec, k, d)
            err = uv.reshape(-1, 2) - i.reshape(-1, 2)
            rms = float(np.sqrt(np.mean(np.sum(err * err, axis=1))))
            if not rms <= _SEED_RMS_PX:
                continue
            rvec, tvec = cv2.solvePnPRefineLM(o, i, k, d, rvec.copy(), tvec.copy())
            try:
                poses.append(Pose.from_rvec_tvec(rvec, tvec))
            except ValueError:
                continue
    return poses


def solve_pnp(
    object_points, image_points, camera: Camera, solver: str = "iterative"
) -> Pose | None:
    """Camera pose from point correspondences.

    Parameters
    ----------
    object_points : array_like, shape (N, 3)
        World coordinates of the points (map units), N >= 4.
    image_points : array_like, shape (N, 2)
        Their pixel coordinates ``[u, v]`` in the (distorted) image, same order.
    camera : Camera
        Intrinsics and distortion.
    solver : {"iterative", "sqpnp", "ippe", "epnp"}
        The OpenCV method (:data:`SOLVERS`).

    Returns
    -------
    Pose or None
        The camera pose in the world frame (position in map units), or None when OpenCV
        fails or returns a non-finite pose.  No check that the points lie in front of the
        camera is made here.

    Raises
    ------
    ValueError
        Bad shapes, fewer than four points, non-finite object points, or an unknown solver.
    """
    flag = _solver_flag(solver)
    obj, img = _check_points(object_points, image_points, batch=False)
    if not np.all(np.isfinite(img)):
        return None
    res = _solve_one(obj, img, camera.matrix, camera.dist_or_none, flag)
    if res is None:
        return None
    try:
        return Pose.from_rvec_tvec(*res)
    except ValueError:
        return None


def rodrigues_batch(rvecs) -> np.ndarray:
    """Rotation matrices from Rodrigues vectors, vectorised.

    Parameters
    ----------
    rvecs : array_like, shape (B, 3)
        Axis times angle (radians).

    Returns
    -------
    ndarray, shape (B, 3, 3)
        The rotations (same as ``cv2.Rodrigues`` one by one).
    """
    r = np.asarray(rvecs, dtype=np.float64).reshape(-1, 3)
    theta = np.linalg.norm(r, axis=1)
    small = theta < 1e-12
    k = r / np.where(small, 1.0, theta)[:, None]
    kx = np.zeros((r.shape[0], 3, 3))
    kx[:, 0, 1], kx[:, 0, 2] = -k[:, 2], k[:, 1]
    kx[:, 1, 0], kx[:, 1, 2] = k[:, 2], -k[:, 0]
    kx[:, 2, 0], kx[:, 2, 1] = -k[:, 1], k[:, 0]
    s = np.sin(theta)[:, None, None]
    c = (1.0 - np.cos(theta))[:, None, None]
    return np.eye(3)[None] + s * kx + c * (kx @ kx)


def solve_pnp_batch(
    object_points, image_points, camera: Camera, solver: str = "iterative"
) -> np.ndarray:
    """Camera positions for many sets of correspondences (one OpenCV call per set).

    The parameters and the ValueError of :func:`solve_pnp`, for ``B`` sets:
    ``object_points`` of shape (N, 3) (shared by every set) or (B, N, 3), map units;
    ``image_points`` of shape (B, N, 2), a set with a non-finite coordinate not solved.

    Returns
    -------
    ndarray, shape (B, 3)
        Camera centres in world coordinates (map units); NaN rows where the solve failed.
    """
    flag = _solver_flag(solver)
    obj, img = _check_points(object_points, image_points, batch=True)
    b = img.shape[0]
    k = np.ascontiguousarray(camera.matrix, dtype=np.float64)
    dist = camera.dist_or_none
    rvecs = np.full((b, 3), np.nan)
    tvecs = np.full((b, 3), np.nan)
    finite = np.all(np.isfinite(img), axis=(1, 2))
    shared = obj.ndim == 2
    solve = cv2.solvePnP
    for i in np.flatnonzero(finite).tolist():
        o = obj if shared else obj[i]
        try:
            ok, rv, tv = solve(o, img[i], k, dist, flags=flag)
        except cv2.error:
            continue
        if ok:
            rvecs[i] = rv.ravel()
            tvecs[i] = tv.ravel()
    # Rare: OpenCV failed or returned NaN (IPPE on an exact rectangle, ITERATIVE with four
    # non-coplanar points); redo those with the fall-backs of solve_pnp.
    bad = finite & ~(np.all(np.isfinite(rvecs), axis=1) & np.all(np.isfinite(tvecs), axis=1))
    for i in np.flatnonzero(bad).tolist():
        res = _solve_one(obj if shared else obj[i], img[i], k, dist, flag)
        if res is not None:
            rvecs[i], tvecs[i] = res
    r_cw = rodrigues_batch(np.nan_to_num(rvecs))
    centres = -np.einsum("bji,bj->bi", r_cw, tvecs)  # C = -R_cw^T t
    return centres


def _distort(x: np.ndarray, y: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV's lens model on normalised coordinates (up to 12 coefficients)."""
    c = np.zeros(12)
    c[: d.size] = d
    k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = c
    r2 = x * x + y * y
    radial = (1 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1 + r2 * (k4 + r2 * (k5 + r2 * k6)))
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) + r2 * (s1 + s2 * r2)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y + r2 * (s3 + s4 * r2)
    return xd, yd


def project_batch(camera: Camera, R, C, points, *, distort: bool = False) -> np.ndarray:
    """Project the same world points for many camera poses at once.

    Pinhole projection ``K R^T (X - C)``; lens distortion is ignored unless ``distort`` is
    set (the error study uses a distortion-free camera, as the thesis does).  The image
    plane is infinite: points outside the sensor still get coordinates.

    Parameters
    ----------
    camera : Camera
        Intrinsics (and distortion, with ``distort=True``; up to 12 coefficients).
    R : array_like, shape (B, 3, 3) or (3, 3)
        ``world_from_camera`` rotations (camera axes as columns).
    C : array_like, shape (B, 3) or (3,)
        Camera centres, world coordinates (map units).
    points : array_like, shape (N, 3)
        World points (map units).
    distort : bool
        Apply the camera's OpenCV distortion model.

    Returns
    -------
    ndarray, shape (B, N, 2)
        Pixel coordinates ``[u, v]``; NaN for points on or behind the camera plane.

    Raises
    ------
    ValueError
        Bad shapes, or ``distort`` with a 14-coefficient (tilted sensor) model.
    """
    r = np.asarray(R, dtype=np.float64)
    c = np.asarray(C, dtype=np.float64)
    if r.ndim == 2:
        r = r[None]
    if c.ndim == 1:
        c = c[None]
    if r.ndim != 3 or r.shape[1:] != (3, 3):
        raise ValueError(f"R must have shape (B, 3, 3), got {np.shape(R)}")
    if c.ndim != 2 or c.shape[1] != 3:
        raise ValueError(f"C must have shape (B, 3), got {np.shape(C)}")
    if r.shape[0] != c.shape[0]:
        raise ValueError(f"R has {r.shape[0]} poses but C has {c.shape[0]}")
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {p.shape}")
    # camera coordinates: X_c = R^T (X - C), for every pose and point
    xc = np.einsum("bji,bnj->bni", r, p[None, :, :] - c[:, None, :])
    z = xc[..., 2]
    on_plane = ~in_front(xc)  # (within float64 rounding of the camera's plane: not imaged)
    with np.errstate(divide="ignore", invalid="ignore"):
        z_safe = np.where(on_plane, np.nan, z)
        x = xc[..., 0] / z_safe
        y = xc[..., 1] / z_safe
    if distort and camera.distortion.size and np.any(camera.distortion):
        if camera.distortion.size > 12:
            raise ValueError("project_batch supports at most 12 distortion coefficients")
        x, y = _distort(x, y, camera.distortion)
    k = camera.matrix
    u = k[0, 0] * x + k[0, 1] * y + k[0, 2]
    v = k[1, 1] * y + k[1, 2]
    return np.stack([u, v], axis=-1)


def _euler_matrices(euler_deg: np.ndarray) -> np.ndarray:
    """``Rx Ry Rz`` for many sets of the thesis' angles: (N, 3) degrees -> (N, 3, 3)."""
    a = np.deg2rad(np.asarray(euler_deg, dtype=np.float64).reshape(-1, 3))
    c, s = np.cos(a), np.sin(a)
    n = a.shape[0]
    one, zero = np.ones(n), np.zeros(n)
    rx = np.stack([one, zero, zero, zero, c[:, 0], -s[:, 0], zero, s[:, 0], c[:, 0]], 1)
    ry = np.stack([c[:, 1], zero, s[:, 1], zero, one, zero, -s[:, 1], zero, c[:, 1]], 1)
    rz = np.stack([c[:, 2], -s[:, 2], zero, s[:, 2], c[:, 2], zero, zero, zero, one], 1)
    return rx.reshape(n, 3, 3) @ ry.reshape(n, 3, 3) @ rz.reshape(n, 3, 3)


def project_moving(camera: Camera, values, rates, points, dt_s) -> np.ndarray:
    """Project points, each seen from the pose the camera has at its own time.

    The pose at time ``dt`` is ``values + dt * rates`` in (camera centre, thesis angles):
    a camera moving at constant velocity, as a rolling shutter sees it row by row.

    Parameters
    ----------
    camera : Camera
        Intrinsics and distortion (up to 12 coefficients).
    values : array_like, shape (6,) or (B, 6)
        ``(x, y, z, theta_x, theta_y, theta_z)`` at ``dt = 0``, map units and degrees; or B
        such poses at once.
    rates : array_like, shape (6,) or (B, 6)
        Their rates, per s.
    points : array_like, shape (N, 3)
        World points, map units.
    dt_s : array_like, shape (N,)
        Each point's time, s.

    Returns
    -------
    ndarray, shape (N, 2) or (B, N, 2)
        Pixels; NaN for points behind the camera.
    """
    v = np.asarray(values, dtype=np.float64)
    single = v.ndim == 1
    v = v.reshape(-1, 6)
    r = np.broadcast_to(np.asarray(rates, dtype=np.float64).reshape(-1, 6), v.shape)
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    dt = np.asarray(dt_s, dtype=np.float64).reshape(1, -1, 1)
    pose = v[:, None, :] + dt * r[:, None, :]  # (B, N, 6)
    b, n = pose.shape[:2]
    rot = _euler_matrices(pose[..., 3:].reshape(-1, 3)).reshape(b, n, 3, 3)
    xc = np.einsum("bnji,bnj->bni", rot, p[None] - pose[..., :3])
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(xc[..., 2] > 0, xc[..., 2], np.nan)
        x, y = xc[..., 0] / z, xc[..., 1] / z
    if camera.distortion.size and np.any(camera.distortion):
        x, y = _distort(x, y, camera.distortion)
    k = camera.matrix
    uv = np.stack([k[0, 0] * x + k[0, 1] * y + k[0, 2], k[1, 1] * y + k[1, 2]], axis=-1)
    return uv[0] if single else uv


@dataclass(frozen=True)
class PriorSolve:
    """A pose fitted to a few points and a prior (:func:`refine_pose`).

    Attributes
    ----------
    pose : Pose
        The fitted pose (at ``dt = 0``).
    values : ndarray, shape (6,)
        The same as ``(x, y, z, theta_x, theta_y, theta_z)``, map units and degrees.
    rates : ndarray, shape (6,)
        Their fitted rates per s (the prior's when no times were given).
    residuals_px : ndarray, shape (N,)
        Each point's reprojection error with it, pixels.
    jacobian_px : ndarray, shape (2N, 6) or (2N, 12)
        Derivative of the points' pixels (u0, v0, u1, ...) with respect to the values (and
        the rates, when times were given) at the fit.
    """

    pose: Pose
    values: np.ndarray
    rates: np.ndarray
    residuals_px: np.ndarray
    jacobian_px: np.ndarray

    @property
    def reprojection_rms_px(self) -> float:
        """RMS of :attr:`residuals_px`, pixels."""
        return float(np.sqrt(np.mean(self.residuals_px**2)))


def refine_pose(
    object_points,
    image_points,
    camera: Camera,
    prior_position,
    prior_euler_deg,
    *,
    sigma_position=0.05,
    sigma_euler_deg=1.0,
    sigma_px: float = 1.0,
    dt_s=None,
    prior_rates=None,
    sigma_rates=None,
    prior_covariance=None,
) -> PriorSolve | None:
    """The pose that best fits a few points (one or more) and a Gaussian prior on the pose.

    With fewer than four points (or points on a line) PnP alone has no unique answer; a
    prior (a track's prediction) fills in what the points leave open.  Least squares
    (Levenberg-Marquardt, from the prior) over the camera centre and the thesis' angles of
    ``[reprojection / sigma_px, (C - C0) / sigma_position, (theta - theta0) / sigma_euler]``.
    With ``dt_s`` (each point's time, a rolling shutter's rows), the camera moves at constant
    rates (:func:`project_moving`) and the rates are fitted too, with their own prior.

    Parameters
    ----------
    object_points, image_points, camera
        As in :func:`solve_pnp`, but N >= 1.
    prior_position : array_like, shape (3,)
        The prior camera centre, map units.
    prior_euler_deg : array_like, shape (3,)
        The prior's thesis angles, degrees.
    sigma_position : float or array_like, shape (3,)
        The prior's standard deviation per axis, map units.
    sigma_euler_deg : float or array_like, shape (3,)
        The prior's standard deviation per angle, degrees.
    sigma_px : float
        Standard deviation of an image point, pixels.
    dt_s : array_like, shape (N,), optional
        Each point's time relative to the pose's, s.
    prior_rates, sigma_rates : array_like, shape (6,), optional
        The rates' prior (map units and degrees per s) and its standard deviation; needed
        with ``dt_s``.
    prior_covariance : array_like, shape (6, 6) or (12, 12), optional
        The prior's full covariance (values, then rates with ``dt_s``), used instead of the
        standard deviations (which then only scale the steps).

    Returns
    -------
    PriorSolve or None
        None when the fit does not converge to a finite pose with the points in front.
    """
    obj = np.asarray(object_points, dtype=np.float64).reshape(-1, 3)
    img = np.asarray(image_points, dtype=np.float64).reshape(-1, 2)
    n = obj.shape[0]
    if img.shape[0] != n or n < 1:
        raise ValueError("object_points and image_points need the same number (>= 1) of points")
    moving = dt_s is not None
    dt = np.zeros(n) if not moving else np.asarray(dt_s, dtype=np.float64).reshape(n)
    x0, sig, r0 = _prior_vector(
        (prior_position, prior_euler_deg),
        (sigma_position, sigma_euler_deg),
        (prior_rates, sigma_rates),
        moving=moving,
    )
    if not (np.all(sig > 0) and np.all(np.isfinite(sig)) and sigma_px > 0):
        raise ValueError("the prior's standard deviations and sigma_px must be positive")
    whiten = _prior_whitening(sig, prior_covariance)
    steps = 1e-6 * np.maximum(np.abs(x0), 1.0)

    def pixel_terms(x: np.ndarray, with_jacobian: bool):
        """Whitened pixel residuals (2N,) and, optionally, their Jacobian (2N, P)."""
        xs = x[None, :]
        if with_jacobian:
            xs = np.vstack([x, x + np.diag(steps)])
        rates = xs[:, 6:] if moving else np.broadcast_to(r0, (xs.shape[0], 6))
        uv = project_moving(camera, xs[:, :6], rates, obj, dt).reshape(xs.shape[0], -1)
        res = (uv[0] - img.ravel()) / sigma_px
        if not with_jacobian:
            return res, None
        return res, ((uv[1:] - uv[0]) / steps[:, None]).T / sigma_px

    x = _levenberg_marquardt(pixel_terms, x0, whiten, sig)
    if x is None:
        return None
    try:
        pose = Pose.from_euler(x[:3], x[3:6])
    except ValueError:
        return None
    if np.any(pose.to_camera(obj)[:, 2] <= 0):
        return None
    res_w, jac = pixel_terms(x, True)
    res = np.hypot(*(res_w.reshape(-1, 2) * sigma_px).T)
    if not (np.all(np.isfinite(res)) and np.all(np.isfinite(jac))):
        return None
    jac = jac * sigma_px
    return PriorSolve(pose, x[:6].copy(), x[6:].copy() if moving else r0, res, jac)


def _prior_vector(
    values: tuple, sigmas: tuple, rates: tuple, *, moving: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The prior's mean (6,) or (12,), its standard deviations (same) and the rates (6,).

    ``values`` is ``(prior_position, prior_euler_deg)``, ``sigmas`` their standard deviations
    and ``rates`` ``(prior_rates, sigma_rates)`` as :func:`refine_pose` takes them.  The mean
    is ``(x, y, z, theta_x, theta_y, theta_z)`` (map units, degrees), followed by the rates
    per s when the camera is ``moving`` (which needs both of ``rates``).
    """
    prior_position, prior_euler_deg = values
    sigma_position, sigma_euler_deg = sigmas
    prior_rates, sigma_rates = rates
    x0 = np.concatenate(
        [
            np.asarray(prior_position, dtype=float).reshape(3),
            np.asarray(prior_euler_deg, dtype=float).reshape(3),
        ]
    )
    sig = np.concatenate(
        [
            np.broadcast_to(np.asarray(sigma_position, dtype=np.float64), (3,)),
            np.broadcast_to(np.asarray(sigma_euler_deg, dtype=np.float64), (3,)),
        ]
    )
    if moving:
        if prior_rates is None or sigma_rates is None:
            raise ValueError("dt_s needs prior_rates and sigma_rates")
        r0 = np.asarray(prior_rates, dtype=np.float64).reshape(6)
        x0 = np.concatenate([x0, r0])
        sig = np.concatenate([sig, np.broadcast_to(np.asarray(sigma_rates, dtype=float), (6,))])
    else:
        r0 = np.zeros(6) if prior_rates is None else np.asarray(prior_rates, dtype=float)
    return x0, sig, r0


def _prior_whitening(sig: np.ndarray, prior_covariance) -> np.ndarray:
    """The matrix W (P, P) with ``|W (x - x0)|^2`` the prior's cost: ``diag(1 / sig)``, or
    ``L^T`` with ``L L^T`` the inverse of ``prior_covariance`` (P, P) when given."""
    if prior_covariance is None:
        return np.diag(1.0 / sig)
    cov = np.asarray(prior_covariance, dtype=np.float64)
    if cov.shape != (sig.size, sig.size) or not np.all(np.isfinite(cov)):
        raise ValueError(f"prior_covariance must be a finite {sig.size} x {sig.size} matrix")
    try:
        return np.linalg.cholesky(np.linalg.inv(cov)).T
    except np.linalg.LinAlgError:
        raise ValueError("prior_covariance must be positive definite") from None


def _levenberg_marquardt(pixel_terms, x0: np.ndarray, whiten: np.ndarray, sig: np.ndarray):
    """Minimise the pixel terms plus the prior's (linear) terms from the prior ``x0`` (P,).

    ``pixel_terms(x, with_jacobian)`` gives the whitened pixel residuals (2N,) and their
    Jacobian (2N, P); ``whiten`` (P, P) the prior's; ``sig`` (P,) scales the step that counts
    as converged.  Returns the fitted values (P,), or None when a cost is not finite or a
    step cannot be solved.
    """

    def cost(x: np.ndarray) -> float:
        res, _ = pixel_terms(x, False)
        return float(res @ res + np.sum((whiten @ (x - x0)) ** 2))

    x = x0.copy()
    current = cost(x)
    if not np.isfinite(current):
        return None
    damping = 1e-3
    for _ in range(30):
        res, jac = pixel_terms(x, True)
        if not (np.all(np.isfinite(res)) and np.all(np.isfinite(jac))):
            return None
        prior = whiten @ (x - x0)
        h = jac.T @ jac + whiten.T @ whiten
        g = jac.T @ res + whiten.T @ prior
        improved = False
        while damping < 1e10:
            try:
                step = np.linalg.solve(h + damping * np.diag(np.diag(h)), -g)
            except np.linalg.LinAlgError:
                return None
            trial = x + step
            new = cost(trial)
            if np.isfinite(new) and new <= current:
                x, damping, improved = trial, max(damping / 10, 1e-9), True
                break
            damping *= 10
        if not improved or abs(current - new) <= 1e-6 * max(current, 1e-12):
            break
        current = new
        if np.all(np.abs(step) <= 1e-3 * np.maximum(sig, 1e-12)):
            break
    return x
