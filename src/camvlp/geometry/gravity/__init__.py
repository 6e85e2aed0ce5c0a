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

The package: :mod:`~camvlp.geometry.gravity.tilt` (checking gravity, the map's up, the
tilt), :mod:`~camvlp.geometry.gravity.two_fixtures` (the closed form, also for many pairs at once),
:mod:`~camvlp.geometry.gravity.solve` (:func:`solve_pose_gravity` and its result) and
:mod:`~camvlp.geometry.gravity.refine` (the vectorised refinement, also used by the
coverage study).
"""

from __future__ import annotations

from camvlp.geometry.gravity.refine import refine_gravity_batch
from camvlp.geometry.gravity.solve import (
    MAX_TILT_SIGMAS,
    SOLVER_NAMES,
    GravityPose,
    solve_pose_gravity,
)
from camvlp.geometry.gravity.tilt import (
    check_gravity,
    check_gravity_view,
    map_up,
    tilt_error_deg,
    tilt_rotation,
)
from camvlp.geometry.gravity.two_fixtures import pair_ray_lengths, solve_two_fixtures

__all__ = [
    "MAX_TILT_SIGMAS",
    "SOLVER_NAMES",
    "GravityPose",
    "check_gravity",
    "check_gravity_view",
    "map_up",
    "pair_ray_lengths",
    "refine_gravity_batch",
    "solve_pose_gravity",
    "solve_two_fixtures",
    "tilt_error_deg",
    "tilt_rotation",
]
