"""Stage 5, solve: the camera's pose from the identified fixtures, and how sure its position is.

:class:`PoseProblem` holds what solving a photo's pose needs besides the IDs (the camera, the
map, the lights' centres, the options, the gravity direction when given); the identify stage
solves it for each set of IDs it weighs (:mod:`camvlp.pipeline.identify.decide`).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from camvlp.geometry.disc import disc_normals, perspective_offsets
from camvlp.geometry.gravity import GravityPose, solve_pose_gravity
from camvlp.geometry.pose import PoseEstimate, estimate_pose
from camvlp.geometry.pose_sigma import gravity_position_sigma, position_sigma
from camvlp.model.camera import Camera
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.detect.blob import Blob
from camvlp.pipeline.identified import Identified
from camvlp.pipeline.settings import LocateSettings

__all__ = [
    "UNKNOWN_CENTRE_SIGMA_PX",
    "PoseProblem",
    "finite_sigma",
    "sigma_of",
    "solve_pose",
    "sure_enough",
]


@dataclass(frozen=True)
class PoseProblem:
    """What solving a photo's pose needs besides the IDs.

    Attributes
    ----------
    camera : Camera
    fixture_map : FixtureMap
    blobs : tuple of Blob
        The photo's lights (their centres and centre sigmas).
    settings : LocateSettings
        The solver, the perspective correction, the gravity's and centres' sigmas.
    outlier_px : float
        Reprojection error beyond which a fixture does not fit the pose, pixels.
    gravity : tuple of ndarray, shape (3,) each, or None
        The gravity direction in the camera's frame and the map's up: two fixtures are then
        enough (:mod:`camvlp.geometry.gravity`).
    glowing : tuple of bool
        Per light, whether it glows (:attr:`~camvlp.pipeline.lights.Lights.glowing`); empty
        when not told.  A photo whose lights are all told plain is placed in a map whose IDs
        repeat with their discs' sizes held to :data:`~camvlp.pipeline.identify.placement.
        PLAIN_SLACK`.
    """

    camera: Camera
    fixture_map: FixtureMap
    blobs: tuple[Blob, ...]
    settings: LocateSettings
    outlier_px: float
    gravity: tuple[np.ndarray, np.ndarray] | None = None
    glowing: tuple[bool, ...] = ()

    @property
    def needed(self) -> int:
        """Fixtures a pose needs: 4, or 2 with gravity."""
        return 4 if self.gravity is None else 2

    def solve(self, found: Identified) -> tuple[PoseEstimate | GravityPose | None, str]:
        """:func:`solve_pose` of the usable fixtures of ``found``."""
        return solve_pose(self, found)


#: Centre sigma of a disc whose ellipse fit gives none (the centroid of a small disc), pixels.
UNKNOWN_CENTRE_SIGMA_PX = 1.0


def centre_sigmas(blobs, usable: tuple[int, ...], st: LocateSettings) -> np.ndarray:
    """Each usable disc's centre sigma (pixels): the one given, else the disc's own."""
    if st.centre_sigma_px is not None:
        return np.full(len(usable), float(st.centre_sigma_px))
    sigma = np.array([blobs[k].centre_sigma_px for k in usable], dtype=float)
    return np.where(np.isfinite(sigma), sigma, UNKNOWN_CENTRE_SIGMA_PX)


def solve_pose(
    problem: PoseProblem, found: Identified
) -> tuple[PoseEstimate | GravityPose | None, str]:
    """Stage 5: the pose from the usable fixtures of ``found``, then again with
    perspective-corrected centres; (estimate, or None when too few fixtures; why it failed,
    or "").  With gravity, two fixtures are enough (:mod:`camvlp.geometry.gravity`)."""
    camera, fixture_map, blobs = problem.camera, problem.fixture_map, problem.blobs
    st, outlier_px, gravity = problem.settings, problem.outlier_px, problem.gravity
    usable = found.usable
    needed = problem.needed
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
                pixel_sigma_px=centre_sigmas(blobs, usable, st),
                outlier_px=outlier_px,
            )
        return estimate_pose(
            points,
            obj,
            camera,
            normals=normals,
            solver=st.solver,
            outlier_px=outlier_px,
            centre_sigma_px=lambda: float(np.median(centre_sigmas(blobs, usable, st))),
        )

    est = solve(pixels)
    if est and st.correct_perspective and all(f.diameter for f in fixtures):
        # discs without a map normal lie on the plane of the others, facing the camera
        facing = disc_normals(obj, normals, est.pose.position)
        offsets = perspective_offsets(camera, est.pose, obj, [f.diameter for f in fixtures], facing)
        if np.abs(offsets).max() >= 0.02:  # below: facing the lights, nothing to correct
            corrected = solve(pixels - offsets)
            est = corrected if corrected else est
    return est, "" if est else est.reason


def sigma_of(problem: PoseProblem, est, found: Identified) -> Callable[[], np.ndarray] | None:
    """How sure the position of the pose ``est`` is: a function of no arguments that gives
    its standard deviation along the map's x, y and z (map units, shape (3,)), or None when
    not located.  A pose solved from the pixels alone: from its fixtures' reprojection errors
    (:func:`~camvlp.geometry.pose_sigma.position_sigma`), at least as large along each axis
    as how far an alternative pose that fits about as well lies; one solved with gravity:
    from the centres' and the gravity's sigmas the solver weighed them by
    (:func:`~camvlp.geometry.pose_sigma.gravity_position_sigma`)."""
    pose = est.pose if est is not None else None
    if pose is None:
        return None
    used = [k for j, k in enumerate(found.usable) if est.used[j]]
    fixture_map = problem.fixture_map
    points = np.array([fixture_map.get(found.ids[k]).position for k in used]).reshape(-1, 3)
    residuals = np.asarray(est.residuals_px, dtype=float)[est.used]
    if isinstance(est, GravityPose):
        st = problem.settings
        pixel = centre_sigmas(problem.blobs, found.usable, st)[est.used]
        return functools.partial(
            gravity_position_sigma,
            problem.camera,
            pose,
            points,
            pixel,
            problem.gravity[0],
            st.gravity_sigma_deg,
            residuals,
            est.gravity_residual_deg,
        )
    close = np.zeros(3)
    if est.close and est.alternative is not None:
        close = np.abs(est.alternative.position - pose.position)
    return functools.partial(_position_sigma, problem.camera, pose, points, residuals, close)


def _position_sigma(camera, pose, points, residuals_px, close) -> np.ndarray:
    """:func:`~camvlp.geometry.pose_sigma.position_sigma`, at least as large along each axis
    as ``close`` (how far an alternative pose that fits about as well lies)."""
    return np.maximum(position_sigma(camera, pose, points, residuals_px), close)


def finite_sigma(sigma: Callable[[], np.ndarray]) -> np.ndarray | None:
    """What ``sigma`` (as :func:`sigma_of` gives it) gives, or None when it is not finite."""
    value = sigma()
    return value if np.isfinite(value).all() else None


def sure_enough(
    est: PoseEstimate | GravityPose, sigma: Callable[[], np.ndarray], limit: float
) -> tuple[PoseEstimate | GravityPose, str, np.ndarray | None]:
    """The pose, or no pose and why when its position's standard deviation (``sigma``, as
    :func:`sigma_of` gives it; map units) exceeds ``limit`` along an axis or is not finite;
    and that standard deviation, shape (3,), when the pose is kept."""
    value = sigma()
    finite = np.isfinite(value)
    axis = int(np.argmax(np.where(finite, value, np.inf)))
    if finite.all() and value[axis] <= limit:
        return est, "", value
    told = f"is {value[axis]:.3g} (map units), over" if finite[axis] else "is not finite, for"
    why = (
        f"the position is too unsure: its standard deviation along {'xyz'[axis]} {told} "
        f"the limit of {limit:g}"
    )
    cleared = {"pose": None, "alternative": None, "reason": why}
    if not isinstance(est, GravityPose):
        cleared["alternative_rms_px"] = float("nan")
    return dataclasses.replace(est, **cleared), why, None
