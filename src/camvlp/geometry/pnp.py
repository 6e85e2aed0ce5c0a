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

Projection for many poses at once is :mod:`camvlp.geometry.projection`'s, and the pose from a
few points and a prior (a track's) :mod:`camvlp.geometry.pose_prior`'s; :func:`refine_pose`,
:class:`PriorSolve` and :func:`project_moving` are importable from here as well.
"""

from __future__ import annotations

import itertools

import cv2
import numpy as np

from camvlp.geometry.pose_prior import PriorSolve, refine_pose
from camvlp.geometry.projection import project_moving
from camvlp.model.camera import Camera, Pose, all_finite, project_camera_points

__all__ = [
    "IPPE_JITTER_PX",
    "LOCATE_SOLVER",
    "SOLVERS",
    "PriorSolve",
    "candidate_methods",
    "check_solver",
    "other_minima",
    "pnp_candidates",
    "project_moving",
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
    seeds = []  # (rvec, tvec) of every triple's P3P solutions
    for tri in itertools.combinations(range(n), 3):
        t = list(tri)
        try:
            _, rvecs, tvecs = cv2.solveP3P(o[t], i[t], k, d, flags=cv2.SOLVEPNP_AP3P)
        except cv2.error:
            continue
        seeds += [(r, v) for r, v in zip(rvecs, tvecs, strict=True) if all_finite(r, v)]
    if not seeds:
        return []
    # every seed's RMS over all the points, in one projection
    rot = np.array([cv2.Rodrigues(r)[0] for r, _ in seeds])  # (S, 3, 3), world to camera
    shift = np.array([v.reshape(3) for _, v in seeds])  # (S, 3)
    cam = o.reshape(1, n, 3) @ rot.transpose(0, 2, 1) + shift[:, None]  # (S, N, 3)
    err = project_camera_points(camera, cam.reshape(-1, 3)).reshape(-1, n, 2) - i.reshape(n, 2)
    rms = np.sqrt(np.mean(np.sum(err * err, axis=2), axis=1))  # (S,), pixels
    poses = []
    for (rvec, tvec), seed_rms in zip(seeds, rms, strict=True):
        if not seed_rms <= _SEED_RMS_PX:
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
