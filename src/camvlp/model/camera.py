"""Camera model: pinhole intrinsics with OpenCV lens distortion, poses, and the thesis' angles.

Conventions (see ``docs/conventions.md``):

* Camera frame: OpenCV's (x right, y down, z forward, out of the lens).
* A :class:`Pose` stores ``world_from_camera``, the camera-to-world rotation ``R`` whose
  columns are the camera's axes in world coordinates, and the camera centre ``C``.  A world
  point ``X`` is at ``R.T @ (X - C)`` in camera coordinates.
* The thesis' Euler angles ``(theta_x, theta_y, theta_z)`` in degrees give
  ``R = Rx(theta_x) @ Ry(theta_y) @ Rz(theta_z)`` (Tait-Bryan z-y-x, thesis equation 3.5).
  ``(90, 0, 0)`` makes the camera look along world -y, at the thesis' ceiling.
* Image origin: the centre of the top-left pixel (OpenCV's convention).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from camvlp.model.readout import DEFAULT_ROW_TIME_S, Readout

__all__ = [
    "DEFAULT_ROW_TIME_S",
    "PLANE_ROUNDING",
    "Camera",
    "Pose",
    "all_finite",
    "euler_to_matrix",
    "finite_rows",
    "in_front",
    "matrix_to_euler",
    "project_points",
    "rotation_from_vector",
    "rotation_x",
    "rotation_y",
    "rotation_z",
]


#: Readout values of a camera: the image axis the sensor's rows follow, and ``-reversed``
#: when time runs up (right to left) rather than down (left to right); None: find the axis
#: from the stripes and take the forward direction.


def rotation_x(theta_deg: float) -> np.ndarray:
    """Rotation about x by ``theta_deg`` degrees (right-hand rule), shape (3, 3)."""
    t = np.deg2rad(theta_deg)
    c, s = np.cos(t), np.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rotation_y(theta_deg: float) -> np.ndarray:
    """Rotation about y by ``theta_deg`` degrees (right-hand rule), shape (3, 3)."""
    t = np.deg2rad(theta_deg)
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rotation_z(theta_deg: float) -> np.ndarray:
    """Rotation about z by ``theta_deg`` degrees (right-hand rule), shape (3, 3)."""
    t = np.deg2rad(theta_deg)
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rotation_from_vector(rotvec) -> np.ndarray:
    """Rotation matrix, shape (3, 3), of a rotation vector (shape (3,): the axis times the
    angle, radians), as OpenCV's ``cv2.Rodrigues`` gives it."""
    return cv2.Rodrigues(np.asarray(rotvec, dtype=np.float64).reshape(3, 1))[0]


def euler_to_matrix(euler_deg) -> np.ndarray:
    """Camera-to-world rotation from the thesis' angles.

    Parameters
    ----------
    euler_deg : array_like, shape (3,)
        ``(theta_x, theta_y, theta_z)`` in degrees.

    Returns
    -------
    ndarray, shape (3, 3)
        ``Rx(theta_x) @ Ry(theta_y) @ Rz(theta_z)``; its columns are the camera axes in
        world coordinates.
    """
    tx, ty, tz = _vector(euler_deg, 3, "euler_deg")
    return rotation_x(tx) @ rotation_y(ty) @ rotation_z(tz)


def matrix_to_euler(rotation) -> np.ndarray:
    """Thesis angles ``(theta_x, theta_y, theta_z)`` in degrees of a rotation matrix.

    Inverse of :func:`euler_to_matrix`, with ``theta_y`` in [-90, 90].  At gimbal lock
    (``|theta_y| = 90``) ``theta_z`` is set to 0.

    Parameters
    ----------
    rotation : array_like, shape (3, 3)
        Camera-to-world rotation.

    Returns
    -------
    ndarray, shape (3,)
        Angles in degrees, each in (-180, 180].
    """
    r = np.asarray(rotation, dtype=float)
    if r.shape != (3, 3):
        raise ValueError(f"rotation must have shape (3, 3), got {r.shape}")
    # R = Rx Ry Rz: R[0,2] = sin(ty); R[0,0] = cy cz; R[0,1] = -cy sz;
    # R[1,2] = -sx cy; R[2,2] = cx cy.
    sy = np.clip(r[0, 2], -1.0, 1.0)
    if abs(sy) < 1.0 - 1e-12:
        tx, tz = np.arctan2(-r[1, 2], r[2, 2]), np.arctan2(-r[0, 1], r[0, 0])
    else:  # gimbal lock: only tx + sign*tz is defined; put it all in tx
        tx, tz = np.arctan2(r[2, 1], r[1, 1]), 0.0
    return np.rad2deg(np.array([tx, np.arcsin(sy), tz], dtype=float))


def all_finite(*arrays: np.ndarray) -> bool:
    """Whether every value of these (small) float arrays is finite: ``np.isfinite(a).all()``
    of each, in Python floats (every pose made checks its rotation and position, some 25
    times in a pose's solve: for these few values 0.8 us a call against NumPy's 3.5 us,
    about 6 % of the solve)."""
    for a in arrays:
        if not all(map(math.isfinite, a.ravel().tolist())):
            return False
    return True


def finite_rows(a: np.ndarray) -> list[bool]:
    """Whether each row of a 2-D float array is finite throughout, as a list of bool."""
    return np.isfinite(a).all(axis=1).tolist()


def _vector(value, n: int, name: str) -> np.ndarray:
    v = np.asarray(value, dtype=float).reshape(-1)
    if v.shape != (n,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be {n} finite numbers, got {value!r}")
    return v


def _is_rotation(r: np.ndarray) -> bool:
    """Whether a finite (3, 3) matrix is a rotation: orthonormal columns (``r.T @ r`` the
    identity within 1e-6) and no reflection (``det r >= 0``)."""
    return bool(np.allclose(r.T @ r, np.eye(3), atol=1e-6) and np.linalg.det(r) >= 0)


@dataclass(frozen=True)
class Pose:
    """A camera pose in the map's world frame.

    Attributes
    ----------
    world_from_camera : ndarray, shape (3, 3)
        Camera-to-world rotation ``R`` (camera axes as columns, in world coordinates).
    position : ndarray, shape (3,)
        Camera centre ``C`` in world coordinates (map units).
    """

    world_from_camera: np.ndarray
    position: np.ndarray

    def __post_init__(self) -> None:
        r = np.asarray(self.world_from_camera, dtype=float)
        if r.shape != (3, 3) or not np.all(np.isfinite(r)):
            raise ValueError("world_from_camera must be a finite (3, 3) matrix")
        if not _is_rotation(r):
            raise ValueError("world_from_camera must be a proper rotation matrix")
        object.__setattr__(self, "world_from_camera", r)
        object.__setattr__(self, "position", _vector(self.position, 3, "position"))

    @classmethod
    def from_euler(cls, position, euler_deg) -> Pose:
        """Pose from a camera centre (map units) and the thesis' angles (degrees)."""
        return cls(euler_to_matrix(euler_deg), position)

    @classmethod
    def from_rvec_tvec(cls, rvec, tvec) -> Pose:
        """Pose from OpenCV's ``camera_from_world`` Rodrigues vector and translation."""
        r_cw = rotation_from_vector(rvec)
        t = np.asarray(tvec, dtype=float).reshape(3)
        if not all_finite(r_cw, t):
            raise ValueError("rvec and tvec must be finite")
        # a rotation by construction: the checks of __init__ are not needed
        pose = object.__new__(cls)
        object.__setattr__(pose, "world_from_camera", r_cw.T)
        object.__setattr__(pose, "position", -r_cw.T @ t)
        return pose

    @property
    def euler_deg(self) -> np.ndarray:
        """The thesis' angles ``(theta_x, theta_y, theta_z)`` in degrees, shape (3,)."""
        return matrix_to_euler(self.world_from_camera)

    @property
    def camera_from_world(self) -> np.ndarray:
        """World-to-camera rotation ``R.T``, shape (3, 3)."""
        return self.world_from_camera.T

    def rvec_tvec(self) -> tuple[np.ndarray, np.ndarray]:
        """OpenCV's ``camera_from_world`` Rodrigues vector and translation, each shape (3,)."""
        r_cw = self.camera_from_world
        skew = 0.5 * (r_cw - r_cw.T)
        v = np.array([skew[2, 1], skew[0, 2], skew[1, 0]])
        s, c = float(np.linalg.norm(v)), 0.5 * (float(np.trace(r_cw)) - 1.0)
        angle = math.atan2(s, c)
        if angle < math.pi - 1e-3:  # sin(angle) * axis = v: exact to the last bit near 0 too
            rvec = v * (angle / s if s > 0 else 1.0)
        else:  # near a half turn the axis is in the symmetric part: OpenCV's formula
            rvec = cv2.Rodrigues(r_cw)[0].reshape(3)
        return rvec, -r_cw @ self.position

    def to_camera(self, points_world) -> np.ndarray:
        """World points (N, 3) to camera coordinates (N, 3), same units."""
        p = np.asarray(points_world, dtype=float).reshape(-1, 3)
        return (p - self.position) @ self.world_from_camera


#: The range of a camera's ``tone_gamma`` (beyond it no camera's curve is a power law).
MIN_TONE_GAMMA, MAX_TONE_GAMMA = 0.25, 4.0


@dataclass(frozen=True)
class Camera:
    """A calibrated camera: pinhole intrinsics, OpenCV distortion, and sensor timing.

    Attributes
    ----------
    width, height : int
        Image size in pixels.
    matrix : ndarray, shape (3, 3)
        Intrinsic matrix ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` in pixels.
    distortion : ndarray, shape (N,)
        OpenCV distortion coefficients (k1 k2 p1 p2 [k3 ...]); empty for none.
    row_time_s : float or None
        Seconds between the starts of two consecutive sensor rows (rolling shutter).
    mirrored : bool
        The stored photographs are mirror images (flip them left-right before locating).
    readout : {"rows", "columns", "rows-reversed", "columns-reversed", None}
        Which image axis the sensor reads out along: ``"rows"`` when sensor rows are image
        rows, read from the top down (stripes horizontal), ``"columns"`` for a photo stored
        in portrait, read from left to right (stripes vertical); ``-reversed`` when time runs
        the other way (bottom up, right to left).  None finds the axis from the stripes and
        takes the forward direction.  The direction matters for Manchester IDs: read
        backwards, some IDs' frames are other IDs' frames (0 and 14, 2 and 6, 4 and 10,
        8 and 12 in the default format).
    tone_gamma : float or None
        The camera's tone curve: a stored level ``x`` (0 to 1) was made by light
        ``x ** tone_gamma`` (about 2.2 for a phone's sRGB JPEG).  ``locate`` undoes it before
        anything else, so that a lamp's glow and its stripes' levels add as light does.  None
        (or 1) takes the levels as linear in light.
    """

    width: int
    height: int
    matrix: np.ndarray
    distortion: np.ndarray = field(default_factory=lambda: np.zeros(0))
    row_time_s: float | None = None
    mirrored: bool = False
    readout: Readout | None = None
    tone_gamma: float | None = None

    def __post_init__(self) -> None:
        if int(self.width) <= 0 or int(self.height) <= 0:
            raise ValueError(f"image size must be positive, got {self.width} x {self.height}")
        k = np.asarray(self.matrix, dtype=float)
        if k.shape != (3, 3) or not np.all(np.isfinite(k)):
            raise ValueError("camera matrix must be a finite 3 x 3 matrix")
        if k[0, 0] <= 0 or k[1, 1] <= 0 or not np.allclose(k[2], [0, 0, 1]):
            raise ValueError("camera matrix must have positive focal lengths and last row 0 0 1")
        if abs(k[0, 1]) > 1e-9 * k[0, 0] or k[1, 0] != 0:
            raise ValueError(
                f"camera matrix must have zero skew (OpenCV's model has none), got {k[0, 1]:g}"
            )
        d = np.asarray(self.distortion, dtype=float).reshape(-1)
        if d.size not in (0, 4, 5, 8, 12, 14) or not np.all(np.isfinite(d)):
            raise ValueError(
                f"distortion coefficients must be 4, 5, 8, 12 or 14 finite numbers, got {d.size}"
            )
        if self.row_time_s is not None and not (0 < float(self.row_time_s) < 1):
            raise ValueError(
                f"row_time_s must be a positive number of seconds, got {self.row_time_s}"
            )
        if self.tone_gamma is not None and (
            isinstance(self.tone_gamma, bool)
            or not isinstance(self.tone_gamma, (int, float))
            or not MIN_TONE_GAMMA <= self.tone_gamma <= MAX_TONE_GAMMA
        ):
            raise ValueError(
                f"tone_gamma must be a number from {MIN_TONE_GAMMA:g} to {MAX_TONE_GAMMA:g}, "
                f"got {self.tone_gamma!r}"
            )
        object.__setattr__(self, "readout", Readout.parse_optional(self.readout))
        object.__setattr__(self, "width", int(self.width))
        object.__setattr__(self, "height", int(self.height))
        object.__setattr__(self, "matrix", k)
        object.__setattr__(self, "distortion", d)

    @classmethod
    def from_focal(
        cls, width: int, height: int, focal_px: float, principal_point=None, **kwargs
    ) -> Camera:
        """A camera with square pixels; the principal point defaults to the image centre."""
        if principal_point is None:
            principal_point = ((width - 1) / 2.0, (height - 1) / 2.0)
        cx, cy = principal_point
        k = np.array([[focal_px, 0.0, cx], [0.0, focal_px, cy], [0.0, 0.0, 1.0]])
        return cls(width, height, k, **kwargs)

    @property
    def size(self) -> tuple[int, int]:
        """``(width, height)`` in pixels."""
        return self.width, self.height

    @property
    def focal_px(self) -> float:
        """Mean focal length ``(fx + fy) / 2`` in pixels."""
        return float(0.5 * (self.matrix[0, 0] + self.matrix[1, 1]))

    @property
    def dist_or_none(self) -> np.ndarray | None:
        """Distortion coefficients for OpenCV calls, or None when there are none."""
        return self.distortion if self.distortion.size and np.any(self.distortion) else None

    def project(self, pose: Pose, points_world) -> np.ndarray:
        """Project world points into the image, with lens distortion.

        Parameters
        ----------
        pose : Pose
            The camera's pose.
        points_world : array_like, shape (N, 3)
            Points in world coordinates (map units).

        Returns
        -------
        ndarray, shape (N, 2)
            Pixel coordinates ``[u, v]``.  Points behind the camera get NaN.
        """
        return project_points(self, pose, points_world)

    def undistort_pixels(self, pixels) -> np.ndarray:
        """Normalised, undistorted image coordinates ``(x/z, y/z)`` of pixels, shape (N, 2)."""
        p = np.asarray(pixels, dtype=np.float64).reshape(-1, 1, 2)
        if self.dist_or_none is None:
            k = self.matrix
            return (p.reshape(-1, 2) - k[:2, 2]) / np.array([k[0, 0], k[1, 1]])
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-10)
        if hasattr(cv2, "undistortPointsIter"):  # OpenCV 4
            out = cv2.undistortPointsIter(p, self.matrix, self.distortion, None, None, crit)
        else:  # OpenCV 5: undistortPoints takes the criteria itself
            out = cv2.undistortPoints(p, self.matrix, self.distortion, criteria=crit)
        return out.reshape(-1, 2)

    def turned(self) -> Camera | None:
        """This camera for photos stored turned a quarter turn (portrait for a landscape
        camera file, or the other way), or None when which way they were turned would matter.

        A phone may turn a portrait photo's pixels itself before storing it, with no EXIF
        orientation to say which way.  Either way round, the turned camera has the width and
        height swapped, ``fx`` and ``fy`` swapped and the principal point moved with the
        pixels; the two ways agree when the principal point is the image's centre (within
        half a pixel) and the lens distortion is radial only (``k1 k2 k3 k4 k5 k6``; no
        tangential, thin-prism or tilt terms), which a camera file made from the focal length
        alone always is.  The readout is not kept: its direction depends on the way turned,
        so the stripes tell it.
        """
        k = self.matrix
        w, h = self.width, self.height
        centred = abs(k[0, 2] - (w - 1) / 2) <= 0.5 and abs(k[1, 2] - (h - 1) / 2) <= 0.5
        d = self.distortion
        radial = not any(d[i] for i in range(d.size) if i in (2, 3) or i >= 8)
        if not (centred and radial and k[0, 1] == 0):
            return None
        matrix = np.array([[k[1, 1], 0.0, (h - 1) / 2], [0.0, k[0, 0], (w - 1) / 2], [0, 0, 1.0]])
        return Camera(h, w, matrix, d, self.row_time_s, self.mirrored, None, self.tone_gamma)

    def with_size(self, width: int, height: int) -> Camera:
        """This camera with a new image size (the intrinsics are kept)."""
        return Camera(
            width,
            height,
            self.matrix,
            self.distortion,
            self.row_time_s,
            self.mirrored,
            self.readout,
            self.tone_gamma,
        )


#: OpenCV's rotation and translation of points already in the camera frame.
_ZERO3 = np.zeros(3)


def project_camera_points(camera: Camera, points_camera) -> np.ndarray:
    """Project points given in the camera's frame into the image, with lens distortion.

    Parameters
    ----------
    camera : Camera
        Intrinsics and distortion.
    points_camera : array_like, shape (N, 3)
        Points in camera coordinates (x right, y down, z forward), map units.

    Returns
    -------
    ndarray, shape (N, 2)
        Pixel coordinates ``[u, v]``, also for points behind the camera (no check).
    """
    p = np.asarray(points_camera, dtype=float).reshape(-1, 3)
    if p.shape[0] == 0:
        return np.zeros((0, 2))
    d = camera.distortion if camera.distortion.size else None
    uv, _ = cv2.projectPoints(p, _ZERO3, _ZERO3, camera.matrix, d)
    return uv.reshape(-1, 2)


#: Depth, as a share of a point's distance, at or under which a point counts as on the
#: camera's plane, not imaged: 64 float64 roundings (a point turned into the camera's frame
#: at distance d is good to a few eps * d; one seen edge-on at 1e-16 of its distance would
#: land 1e16 focal lengths out).
PLANE_ROUNDING = 64 * np.finfo(np.float64).eps


def in_front(points_camera) -> np.ndarray:
    """Whether points in camera coordinates, shape (..., 3), lie in front of the camera,
    beyond float64 rounding of its plane (:data:`PLANE_ROUNDING`): bool, shape (...)."""
    p = np.asarray(points_camera, dtype=float)
    return p[..., 2] > PLANE_ROUNDING * np.linalg.norm(p, axis=-1)


def project_points(camera: Camera, pose: Pose, points_world) -> np.ndarray:
    """Project world points with a camera at a pose; see :meth:`Camera.project`."""
    p = np.asarray(points_world, dtype=float).reshape(-1, 3)
    if p.shape[0] == 0:
        return np.zeros((0, 2))
    # the points in the camera frame, projected as they are: through a Rodrigues vector,
    # rotations below 1e-5 rad would come out as none (OpenCV's cv2.Rodrigues rounds them)
    cam = pose.to_camera(p)
    uv = project_camera_points(camera, cam)
    behind = ~in_front(cam)
    if behind.any():
        uv[behind] = np.nan
    return uv
