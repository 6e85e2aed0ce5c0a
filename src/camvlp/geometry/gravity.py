"""The camera's pose from two, three or more fixtures and the direction of gravity.

A phone's (or robot's) accelerometer says which way is down in the camera's frame.  With the
map's ``up``, that fixes the camera's tilt: the rotation ``R`` (camera-to-world) must take the
measured gravity direction ``g`` onto the map's down, ``R g = -up``.  What is left is the
heading (a rotation about ``up``) and the position: four unknowns.

* **Two fixtures** (:func:`solve_two_fixtures`): two bearing rays give four equations, solved
  in closed form.  The height difference of the two fixtures gives one linear equation in the
  two ray lengths, the horizontal distance between them a quadratic one: two solutions, of
  which the one with both fixtures in front of the camera (and the camera on the lit side of
  fixtures that have a ``normal``) is kept.  Two fixtures on a line along gravity leave the
  heading free: a failure that says so.
* **Three or more** (:func:`solve_pose_gravity`): least squares over heading and position
  with the tilt held, started from the two-fixture solutions of several pairs; then the full
  pose is refined with the reprojection residuals (pixels) and a gravity residual weighted
  by the accelerometer's uncertainty ``sigma_deg``.
* **Four or more**: the same, and the pose from the pixels alone (no gravity) is refined from
  it to report how far the photo's tilt disagrees with the accelerometer (degrees).

Conventions (``docs/conventions.md``): camera frame OpenCV's (x right, y down, z forward);
``R`` has the camera's axes, in world coordinates, as columns; a world point ``X`` is at
``R^T (X - C)`` in camera coordinates.  Gravity is given in the camera frame, any length.
Bearings are undistorted normalised image coordinates ``(x, y, 1)`` (``Camera.undistort_pixels``,
i.e. ``cv2.undistortPoints`` with the camera's matrix and distortion).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations

import cv2
import numpy as np

from camvlp.errors import InputError
from camvlp.model.camera import Camera, Pose

__all__ = [
    "MAX_TILT_SIGMAS",
    "SOLVER_NAMES",
    "GravityPose",
    "check_gravity",
    "check_gravity_view",
    "map_up",
    "refine_gravity_batch",
    "solve_pose_gravity",
    "solve_two_fixtures",
    "tilt_error_deg",
    "tilt_rotation",
]

#: What :attr:`GravityPose.solver` may say, and what each means.
SOLVER_NAMES = {
    "gravity-2": "two fixtures and gravity, closed form",
    "gravity-3": "three fixtures and gravity, least squares",
    "pnp+gravity": "four or more fixtures: PnP refined with the gravity residual",
}

#: A pose whose down is more than this many sigmas from the measured gravity is refused.
MAX_TILT_SIGMAS = 5.0

# Two fixtures are taken to lie on a line along gravity when the horizontal part of their
# separation is below this fraction of the whole.
_VERTICAL_LINE_TOL = 1e-3


def check_gravity(gravity) -> np.ndarray:
    """The unit direction of a measured gravity vector.

    Parameters
    ----------
    gravity : array_like, shape (3,)
        Gravity in the camera's frame (OpenCV axes: x right, y down, z forward), any length
        (m/s^2 from an accelerometer, or a unit vector).

    Returns
    -------
    ndarray, shape (3,)
        Unit vector, camera frame.

    Raises
    ------
    InputError
        Not three numbers, NaN or infinite, or of zero length.
    """
    try:
        g = np.asarray(gravity, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(f"gravity must be three numbers GX,GY,GZ, got {gravity!r}") from None
    if g.shape != (3,):
        raise InputError(f"gravity must be three numbers GX,GY,GZ, got {g.size}")
    if not np.all(np.isfinite(g)):
        raise InputError(f"gravity must be finite, got {_fmt(g)}")
    norm = float(np.linalg.norm(g))
    if norm < 1e-9 * max(1.0, float(np.max(np.abs(g)))) or norm == 0:
        raise InputError("gravity has zero length: its direction is not known")
    return g / norm


def _fmt(v: np.ndarray) -> str:
    return "(" + ", ".join(f"{x:g}" for x in np.asarray(v, float).reshape(-1)) + ")"


def map_up(positions, *, up=None, normals=None) -> np.ndarray:
    """The map's up direction, unit, world frame.

    Parameters
    ----------
    positions : array_like, shape (N, 3)
        All of the map's fixture centres, map units.
    up : array_like, shape (3,), optional
        The map's ``up`` key; returned normalised when given.
    normals : array_like, shape (N, 3), optional
        The fixtures' normals (rows of NaN where unknown).

    Returns
    -------
    ndarray, shape (3,)
        Without ``up``: the normal of the fixtures' plane on the side the lights face away
        from (lights face down into the room, so up is opposite to their normals; with
        fewer than three fixtures, or not in one plane, the opposite of their mean normal);
        fixtures without normals are taken to hang above the map's origin (the floor), so
        up points from the origin towards their plane.

    Raises
    ------
    InputError
        ``up`` is not a non-zero finite 3-vector; or without ``up`` and normals, the
        fixtures are not in one plane, or it passes through the origin.
    """
    if up is not None:
        u = np.asarray(up, dtype=float).reshape(-1)
        if u.shape != (3,) or not np.all(np.isfinite(u)) or np.linalg.norm(u) == 0:
            raise InputError(f"up must be a non-zero 3-vector, got {up!r}")
        return u / np.linalg.norm(u)
    p = np.asarray(positions, dtype=float).reshape(-1, 3)
    hint = "give the map an 'up' key (for example up: [0, 0, 1])"
    facing = None  # the mean way the lights face, when the map says
    if normals is not None:
        nr = np.asarray(normals, dtype=float).reshape(-1, 3)
        known = nr[np.all(np.isfinite(nr), axis=1)]
        if known.size and np.linalg.norm(known.mean(axis=0)) > 0.5:
            facing = known.mean(axis=0) / np.linalg.norm(known.mean(axis=0))
    plane = None
    if p.shape[0] >= 3:
        centre = p.mean(axis=0)
        _, s, vt = np.linalg.svd(p - centre)
        if s[1] > 1e-6 * s[0] and s[2] <= 1e-3 * s[0]:
            plane = vt[2]
    if facing is not None:
        if plane is None:
            return -facing
        return -plane * np.sign(float(plane @ facing)) if abs(plane @ facing) > 1e-6 else -facing
    if plane is None:
        raise InputError(
            f"the map's fixtures do not span one plane and have no normals, so which way is "
            f"up is not known: {hint}"
        )
    side = float(p.mean(axis=0) @ plane)
    if abs(side) <= 1e-6 * float(np.ptp(p, axis=0).max()):
        raise InputError(
            f"the map's fixtures are in a plane through its origin and have no normals, so "
            f"which way is up is not known: {hint}"
        )
    return plane * np.sign(side)


def tilt_rotation(gravity_camera, up_world) -> np.ndarray:
    """The smallest rotation taking the measured gravity direction onto the map's down.

    Parameters
    ----------
    gravity_camera : array_like, shape (3,)
        Gravity in the camera frame (any length, non-zero).
    up_world : array_like, shape (3,)
        The map's up (any length, non-zero).

    Returns
    -------
    ndarray, shape (3, 3)
        A camera-to-world rotation ``R0`` with ``R0 @ g = -up`` (unit vectors); every pose
        that agrees with the accelerometer is ``Rot(up, psi) @ R0`` for a heading ``psi``.
    """
    g = np.asarray(gravity_camera, float) / np.linalg.norm(gravity_camera)
    d = -np.asarray(up_world, float) / np.linalg.norm(up_world)
    axis = np.cross(g, d)
    s, c = float(np.linalg.norm(axis)), float(g @ d)
    if s < 1e-12:
        if c > 0:
            return np.eye(3)
        # opposite: half a turn about any axis perpendicular to g
        perp = np.cross(g, [1.0, 0.0, 0.0] if abs(g[0]) < 0.9 else [0.0, 1.0, 0.0])
        return _rotvec_matrix(np.pi * perp / np.linalg.norm(perp))
    return _rotvec_matrix(axis / s * np.arctan2(s, c))


def tilt_error_deg(rotation, gravity_camera, up_world) -> float:
    """Angle between a pose's down and the measured gravity, degrees.

    Parameters
    ----------
    rotation : array_like, shape (3, 3)
        Camera-to-world rotation.
    gravity_camera, up_world : array_like, shape (3,)
        Measured gravity (camera frame) and the map's up (world frame), any length.
    """
    g = np.asarray(rotation, float) @ (
        np.asarray(gravity_camera, float) / np.linalg.norm(gravity_camera)
    )
    d = -np.asarray(up_world, float) / np.linalg.norm(up_world)
    return float(np.degrees(np.arctan2(np.linalg.norm(np.cross(g, d)), g @ d)))


def check_gravity_view(gravity, camera: Camera, up_world, normals=None) -> None:
    """Refuse a gravity that leaves the lights out of the camera's view whatever the heading.

    A camera looking along gravity (straight at the floor) cannot see lights that face down
    from the ceiling; the usual cause is a gravity vector given with the wrong sign or axes.

    Parameters
    ----------
    gravity : array_like, shape (3,)
        Gravity in the camera frame.
    camera : Camera
        Its image corners give the field of view.
    up_world : array_like, shape (3,)
        The map's up.
    normals : array_like, shape (N, 3), optional
        The fixtures' normals (rows of NaN where unknown: taken to face down).

    Raises
    ------
    InputError
        Every direction in the camera's view is below the horizon while every light faces
        down (its normal has a downward component).
    """
    g = check_gravity(gravity)
    up = np.asarray(up_world, float) / np.linalg.norm(up_world)
    if normals is not None:
        nr = np.asarray(normals, float).reshape(-1, 3)
        nr = nr[np.all(np.isfinite(nr), axis=1)]
        if nr.size and np.any(nr @ up >= -1e-9):
            return  # some light faces sideways or up: no general rule
    w, h = camera.width, camera.height
    border = np.concatenate(
        [
            np.stack([np.linspace(0, w - 1, 33), np.zeros(33)], 1),
            np.stack([np.linspace(0, w - 1, 33), np.full(33, h - 1.0)], 1),
            np.stack([np.zeros(33), np.linspace(0, h - 1, 33)], 1),
            np.stack([np.full(33, w - 1.0), np.linspace(0, h - 1, 33)], 1),
        ]
    )
    xy = camera.undistort_pixels(border)
    rays = np.column_stack([xy, np.ones(len(xy))])
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    # a ray's elevation above the horizon is asin(-g . ray): the same for every heading.
    # The view is a convex cone: its highest direction is on its border or is the axis' top.
    elevation = np.degrees(np.arcsin(np.clip(-(rays @ g), -1, 1)))
    if np.max(elevation) > 0 or -g[2] > 0:
        return
    axis_deg = float(np.degrees(np.arccos(np.clip(g[2], -1, 1))))
    raise InputError(
        f"gravity {_fmt(g)} is {axis_deg:.0f} degrees from the optical axis: the camera would "
        f"look down, its whole view at least {-np.max(elevation):.0f} degrees below the "
        "horizon, and cannot see lights that face down (wrong sign or axes of gravity?)"
    )


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


def _rays(bearings: np.ndarray) -> np.ndarray:
    b = np.column_stack([bearings, np.ones(len(bearings))]) if bearings.shape[1] == 2 else bearings
    return b / np.linalg.norm(b, axis=1, keepdims=True)


def _rotvec_matrix(rotvec) -> np.ndarray:
    """Rotation matrix (3, 3) of a rotation vector (axis times angle, radians)."""
    return cv2.Rodrigues(np.asarray(rotvec, dtype=np.float64).reshape(3, 1))[0]


def _basis(up: np.ndarray) -> np.ndarray:
    """Columns e1, e2, up: a right-handed world basis with up as its third axis."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(helper, up)
    e1 /= np.linalg.norm(e1)
    return np.column_stack([e1, np.cross(up, e1), up])


def _about_up(up: np.ndarray, psi: float) -> np.ndarray:
    return _rotvec_matrix(psi * up)


def _valid(pose: Pose, points: np.ndarray, normals: np.ndarray | None) -> tuple[bool, bool]:
    """(every fixture in front of the camera, the camera on every lit side)."""
    in_front = bool(np.all(pose.to_camera(points)[:, 2] > 0))
    lit = True
    if normals is not None:
        has = np.all(np.isfinite(normals), axis=1)
        lit = bool(np.all(np.einsum("ij,ij->i", normals[has], pose.position - points[has]) > 0))
    return in_front, lit


def solve_two_fixtures(bearings, points, gravity, up) -> tuple[list[Pose], str]:
    """Both poses that put two fixtures on their bearing rays with the measured tilt.

    Parameters
    ----------
    bearings : array_like, shape (2, 2) or (2, 3)
        Undistorted normalised image coordinates ``(x, y)`` (or rays ``(x, y, z)``) of the
        two fixtures, camera frame.
    points : array_like, shape (2, 3)
        Their map positions, map units.
    gravity : array_like, shape (3,)
        Gravity in the camera frame, any length.
    up : array_like, shape (3,)
        The map's up, world frame.

    Returns
    -------
    poses : list of Pose
        Zero, one or two poses, each with ``R @ gravity`` along ``-up``; the rays may point
        away from a fixture (behind the camera): the caller checks.
    reason : str
        Why there are none ("" otherwise).
    """
    rays = _rays(np.asarray(bearings, float).reshape(2, -1))
    x = np.asarray(points, float).reshape(2, 3)
    g = check_gravity(gravity)
    u = np.asarray(up, float) / np.linalg.norm(up)
    r0 = tilt_rotation(g, u)
    w = _basis(u)
    v = (r0 @ rays.T).T @ w  # leveled rays in (e1, e2, up) coordinates
    delta = (x[0] - x[1]) @ w
    sep = float(np.linalg.norm(delta))
    if sep == 0:
        return [], "the two fixtures are at the same place"
    dh = delta[:2]
    if np.linalg.norm(dh) <= _VERTICAL_LINE_TOL * sep:
        return [], (
            "the two fixtures are on a line along gravity: the heading is not determined "
            "(a third fixture is needed)"
        )
    a = np.array([v[0, 2], -v[1, 2]])  # lambda1 a1 - lambda2 a2 = dz
    if np.linalg.norm(a) < 1e-9:
        return [], "both fixtures are on the camera's horizon: their distances are not determined"
    l0 = a * delta[2] / (a @ a)
    nvec = np.array([-a[1], a[0]]) / np.linalg.norm(a)
    m = np.column_stack([v[0, :2], -v[1, :2]])  # horizontal of lambda1 v1 - lambda2 v2
    mn, ml = m @ nvec, m @ l0
    qa, qb, qc = mn @ mn, ml @ mn, ml @ ml - dh @ dh
    if qa < 1e-12:
        return [], "the two fixtures are seen in the same direction: the pose is not determined"
    disc = qb * qb - qa * qc
    if disc < 0:
        # measurement noise near a double root: keep it when it is within the noise
        if disc < -1e-6 * (qb * qb + abs(qa * qc)):
            return [], "no pose puts both fixtures on their rays with this gravity"
        disc = 0.0
    roots = {(-qb + np.sqrt(disc)) / qa, (-qb - np.sqrt(disc)) / qa}
    poses = []
    for t in sorted(roots):
        lam = l0 + t * nvec
        wh = m @ lam
        psi = float(np.arctan2(wh[0] * dh[1] - wh[1] * dh[0], wh @ dh))
        rot = _about_up(u, psi) @ r0
        centre = x[0] - lam[0] * (rot @ rays[0])
        poses.append(Pose(rot, centre))
    return poses, ""


def _pixel_residuals(pose: Pose, points, bearings, focal_px) -> np.ndarray:
    pc = pose.to_camera(points)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = focal_px * np.linalg.norm(pc[:, :2] / pc[:, 2:3] - bearings, axis=1)
    return np.where((pc[:, 2] > 0) & np.isfinite(r), r, np.inf)


#: Gravity sigma (degrees) that holds the tilt while heading and position are fitted.
_TILT_HELD_DEG = 1e-4


def _fit_heading_position(
    starts: list[Pose], points, bearings, gravity, up, focal_px
) -> list[Pose]:
    """Least squares over heading and position with the tilt held, from each start."""
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
    pixel_sigma_px: float = 1.0,
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
    pixel_sigma_px: float = 1.0,
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
    pixel_sigma_px : float
        The centres' uncertainty, pixels.
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
    if not (np.isfinite(pixel_sigma_px) and pixel_sigma_px > 0):
        raise ValueError(f"pixel_sigma_px must be positive, got {pixel_sigma_px!r}")
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

    idx = np.arange(n)
    while True:
        pose, reason = _least_squares(
            bearings[idx], obj[idx], g, u, None if nrm is None else nrm[idx], focal
        )
        if pose is None:
            return _failure(n, reason)
        pose = _refine(
            pose,
            obj[idx],
            bearings[idx],
            focal,
            gravity=g,
            up=u,
            sigma_deg=sigma_deg,
            pixel_sigma_px=pixel_sigma_px,
        )
        res = _pixel_residuals(pose, obj[idx], bearings[idx], focal)
        tilt = tilt_error_deg(pose.world_from_camera, g, u)
        if float(np.max(res)) <= outlier_px and tilt <= MAX_TILT_SIGMAS * sigma_deg:
            break
        if idx.size <= 3 or float(np.max(res)) <= outlier_px:
            why = (
                f"reprojection error up to {float(np.max(res)):.1f} px"
                if float(np.max(res)) > outlier_px
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
        idx = _drop_worst(idx, bearings, obj, g, u, nrm, focal)
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
        photo = _refine(pose, obj[idx], bearings[idx], focal)
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


def _drop_worst(idx, bearings, obj, g, u, nrm, focal) -> np.ndarray:
    """The subset, one fixture fewer, that fits best."""
    best, best_cost = idx[:-1], np.inf
    for sub in combinations(idx.tolist(), idx.size - 1):
        sub = np.array(sub)
        pose, _ = _least_squares(
            bearings[sub], obj[sub], g, u, None if nrm is None else nrm[sub], focal
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
                f"{_fmt(ok[0].position)} and {_fmt(ok[1].position)}): a third fixture is needed",
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


def _least_squares(bearings, obj, g, u, nrm, focal) -> tuple[Pose | None, str]:
    """Heading and position with the tilt held, from the two-fixture solutions of pairs."""
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
    for pose in _fit_heading_position(starts, obj, bearings, g, u, focal):
        in_front, lit = _valid(pose, obj, nrm)
        if not (in_front and lit):
            continue
        cost = float(np.sum(_pixel_residuals(pose, obj, bearings, focal) ** 2))
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


def refine_gravity_batch(
    rotations,
    centres,
    points,
    bearings,
    gravity,
    up,
    *,
    focal_px: float,
    sigma_deg: float = 1.0,
    pixel_sigma_px: float = 1.0,
    mask=None,
    iterations: int = 12,
) -> tuple[np.ndarray, np.ndarray]:
    """Many poses refined at once on the cost of :func:`solve_pose_gravity`.

    Gauss-Newton (forward-difference Jacobians, a little Levenberg-Marquardt damping) on the
    reprojection residuals (pixels / ``pixel_sigma_px``) and the gravity residual
    (``(R g) x down / sigma``), for studies that start each pose near its answer (the
    true pose): it finds the same local minimum as the solver, without its search for a
    start.

    Parameters
    ----------
    rotations : array_like, shape (B, 3, 3)
        Starting camera-to-world rotations.
    centres : array_like, shape (B, 3)
        Starting camera centres, map units.
    points : array_like, shape (N, 3)
        Fixture positions, map units.
    bearings : array_like, shape (B, N, 2)
        Undistorted normalised image coordinates of each fixture in each pose.
    gravity : array_like, shape (B, 3)
        Measured gravity per pose, camera frame (any length).
    up : array_like, shape (3,)
        The map's up.
    focal_px : float
        Focal length (pixels per unit of normalised coordinates).
    sigma_deg, pixel_sigma_px : float
        Uncertainties of the gravity direction (degrees) and of the centres (pixels).
    mask : array_like of bool, shape (B, N), optional
        Which fixtures each pose uses (default all).
    iterations : int
        Gauss-Newton steps.

    Returns
    -------
    rotations : ndarray, shape (B, 3, 3)
    centres : ndarray, shape (B, 3)
    """
    from camvlp.geometry.pnp import rodrigues_batch

    r0 = np.asarray(rotations, float).reshape(-1, 3, 3)
    c = np.asarray(centres, float).reshape(-1, 3).copy()
    x = np.asarray(points, float).reshape(-1, 3)
    b_obs = np.asarray(bearings, float).reshape(r0.shape[0], x.shape[0], 2)
    g = np.asarray(gravity, float).reshape(-1, 3)
    g = g / np.linalg.norm(g, axis=1, keepdims=True)
    down = -np.asarray(up, float) / np.linalg.norm(up)
    w = np.ones(b_obs.shape[:2]) if mask is None else np.asarray(mask, float)
    sigma = np.radians(sigma_deg)
    nb = r0.shape[0]

    def residuals(q: np.ndarray) -> np.ndarray:
        """Residuals (7B, M) of the parameters (7, B, 6): each pose and its 6 nudges."""
        rot = (rodrigues_batch(q[..., :3].reshape(-1, 3)).reshape(7, nb, 3, 3)) @ r0
        pc = np.einsum("kbni,kbij->kbnj", x[None, None] - q[..., None, 3:], rot)
        z = np.where(np.abs(pc[..., 2]) < 1e-12, 1e-12, pc[..., 2])
        rp = focal_px * (pc[..., :2] / z[..., None] - b_obs) * w[..., None] / pixel_sigma_px
        gw = np.einsum("kbij,bj->kbi", rot, g)
        rg = np.stack(
            [
                gw[..., 1] * down[2] - gw[..., 2] * down[1],
                gw[..., 2] * down[0] - gw[..., 0] * down[2],
                gw[..., 0] * down[1] - gw[..., 1] * down[0],
            ],
            axis=-1,
        )
        return np.concatenate([rp.reshape(7, nb, -1), rg / sigma], axis=2)

    p = np.concatenate([np.zeros((nb, 3)), c], axis=1)
    step = np.array([1e-7] * 3 + [1e-7 * max(1.0, float(np.abs(x).max()))] * 3)
    nudges = np.concatenate([np.zeros((1, 6)), np.diag(step)])[:, None, :]  # (7, 1, 6)
    for _ in range(iterations):
        f = residuals(p[None] + nudges)
        jac = np.moveaxis((f[1:] - f[0]) / step[:, None, None], 0, -1)  # (B, M, 6)
        jtj = np.einsum("bmi,bmj->bij", jac, jac)
        jtf = np.einsum("bmi,bm->bi", jac, f[0])
        damp = 1e-9 * np.trace(jtj, axis1=1, axis2=2)[:, None, None] * np.eye(6)
        delta = np.linalg.solve(jtj + damp, jtf[..., None])[..., 0]
        p = p - delta
        if np.all(np.abs(delta) <= 1e-12 * (1.0 + np.abs(p))):
            break
    return rodrigues_batch(p[:, :3]) @ r0, p[:, 3:]
