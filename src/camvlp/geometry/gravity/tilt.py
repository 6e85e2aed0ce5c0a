"""Gravity and the map's up: a measured gravity checked, the map's up, the tilt they fix.

The rotation ``R`` (camera-to-world) of a camera that agrees with its accelerometer takes the
measured gravity direction ``g`` (camera frame) onto the map's down: ``R g = -up``.  This
fixes two of its three angles (the tilt); the heading about ``up`` is left.
"""

from __future__ import annotations

import numpy as np

from camvlp.errors import InputError
from camvlp.format import format_vector
from camvlp.model.camera import Camera, rotation_from_vector

__all__ = ["check_gravity", "check_gravity_view", "map_up", "tilt_error_deg", "tilt_rotation"]


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
        raise InputError(f"gravity must be finite, got {format_vector(g)}")
    norm = float(np.linalg.norm(g))
    if norm < 1e-9 * max(1.0, float(np.max(np.abs(g)))) or norm == 0:
        raise InputError("gravity has zero length: its direction is not known")
    return g / norm


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
        return rotation_from_vector(np.pi * perp / np.linalg.norm(perp))
    return rotation_from_vector(axis / s * np.arctan2(s, c))


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
        f"gravity {format_vector(g)} is {axis_deg:.0f} degrees from the optical axis: the "
        f"camera would look down, its whole view at least {-np.max(elevation):.0f} degrees "
        "below the horizon, and cannot see lights that face down (wrong sign or axes of gravity?)"
    )
