"""What every study shares: checks, the batch of poses, the solve and the error per pose."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from camvlp.geometry.pnp import LOCATE_SOLVER, check_solver, solve_pnp_batch
from camvlp.geometry.projection import project_batch
from camvlp.model.camera import Camera, euler_to_matrix
from camvlp.model.fixtures import FixtureMap

__all__ = [
    "Progress",
    "StudyInputs",
    "check_study_solver",
    "fixture_index",
    "map_m",
    "nonneg",
    "observed_pixels",
    "poses",
    "position_errors",
    "rotations",
    "round_pixels",
    "solve_positions",
    "study_inputs",
]

#: Progress callback: ``progress(done, total)`` in poses.
Progress = Callable[[int, int], None]

_CHUNK = 4096  # poses per batch between progress reports


def check_study_solver(solver: str) -> str:
    """``solver`` if the study knows it (an OpenCV method or ``"locate"``), else ValueError."""
    return check_solver(solver, allow_locate=True)


def solve_positions(object_points, image_points, camera: Camera, solver: str) -> np.ndarray:
    """Camera centres for many sets of correspondences, by any solver the study knows.

    ``solver`` is an OpenCV method (:data:`camvlp.geometry.pnp.SOLVERS`, one
    ``cv2.solvePnP`` call per set) or ``"locate"``: the locator's own pose stage
    (:func:`camvlp.geometry.pose.estimate_pose`: candidates from several solvers, refined,
    the best in front of the camera), so that the study measures what ``locate`` gives.

    Parameters
    ----------
    object_points : array_like, shape (N, 3) or (B, N, 3)
        World points, metres.
    image_points : array_like, shape (B, N, 2)
        Pixels.
    camera : Camera
        Intrinsics and distortion.
    solver : str
        A key of ``SOLVERS`` or ``"locate"``.

    Returns
    -------
    ndarray, shape (B, 3)
        Camera centres, metres; NaN rows where no pose was found.
    """
    if check_study_solver(solver) != LOCATE_SOLVER:
        return solve_pnp_batch(object_points, image_points, camera, solver)
    from camvlp.geometry.pose import estimate_pose

    img = np.asarray(image_points, dtype=float)
    obj = np.broadcast_to(np.asarray(object_points, dtype=float), (*img.shape[:2], 3))
    out = np.full((img.shape[0], 3), np.nan)
    for i in range(img.shape[0]):
        if np.all(np.isfinite(img[i])):
            est = estimate_pose(img[i], obj[i], camera, outlier_px=np.inf)
            if est:
                out[i] = est.pose.position
    return out


def nonneg(value: float, name: str) -> float:
    """``value`` as a float if it is finite and >= 0, else ValueError naming ``name``."""
    v = float(value)
    if not np.isfinite(v) or v < 0:
        raise ValueError(f"{name} must be a non-negative number, got {value!r}")
    return v


def _trials(trials: int, noisy: bool) -> int:
    if isinstance(trials, bool) or int(trials) != trials or trials < 1:
        raise ValueError(f"trials must be a positive integer, got {trials!r}")
    return int(trials) if noisy else 1


@dataclass(frozen=True)
class StudyInputs:
    """What every study checks and sets up first, before its own poses.

    Attributes
    ----------
    fixtures_m : ndarray, shape (N, 3)
        The map's fixture centres, metres (at least four).
    solver : str
        A solver :func:`solve_positions` knows.
    rounding : bool
        Round image points to whole pixels.
    noise_px, survey_error_m : float
        Gaussian sigma on every image point (px) and on every world point given to the
        solver (m).
    trials : int
        Draws per pose (1 without noise).
    rng : numpy.random.Generator
        The seeded source of the noise.
    """

    fixtures_m: np.ndarray
    solver: str
    rounding: bool
    noise_px: float
    survey_error_m: float
    trials: int
    rng: np.random.Generator


def study_inputs(
    fixture_map: FixtureMap,
    *,
    solver: str,
    rounding: bool,
    noise_px: float = 0.0,
    survey_error_m: float = 0.0,
    trials: int = 1,
    seed: int = 0,
    min_fixtures: int = 4,
) -> StudyInputs:
    """Check a study's common arguments (ValueError naming the one at fault) and bundle them.

    ``min_fixtures`` is the fewest fixtures the map may have (see :func:`map_m`).
    """
    check_study_solver(solver)
    pts = map_m(fixture_map, min_fixtures)
    noise_px = nonneg(noise_px, "noise_px")
    survey_error_m = nonneg(survey_error_m, "survey_error_m")
    noisy = noise_px > 0 or survey_error_m > 0
    trials = _trials(trials, noisy)
    return StudyInputs(
        pts, solver, bool(rounding), noise_px, survey_error_m, trials, np.random.default_rng(seed)
    )


def round_pixels(uv: np.ndarray) -> np.ndarray:
    """Round pixel coordinates to the nearest pixel centre (halves up), like the thesis."""
    return np.floor(uv + 0.5)


def map_m(fixture_map: FixtureMap, least: int = 4) -> np.ndarray:
    """The map's fixture centres in metres, shape (N, 3); ValueError with fewer than ``least``
    (four, or two or three when the camera also knows gravity)."""
    pts = fixture_map.positions * fixture_map.unit_m
    if pts.shape[0] < least:
        raise ValueError(
            f"the map has {pts.shape[0]} fixtures; a position needs at least {least} "
            f"({fixture_map.source or 'map'})"
        )
    return pts


def fixture_index(fixture_map: FixtureMap, fixture_id: int) -> int:
    """Row of fixture ``fixture_id`` in the map; ValueError when it is not there."""
    ids = fixture_map.ids
    if fixture_id not in ids:
        raise ValueError(f"fixture {fixture_id} is not in the map ({fixture_map.source or 'map'})")
    return ids.index(fixture_id)


def rotations(euler_deg) -> tuple[np.ndarray, np.ndarray]:
    """Angles (P, 3) in degrees and their rotation matrices (P, 3, 3)."""
    e = np.asarray(euler_deg, dtype=float).reshape(-1, 3)
    if not np.all(np.isfinite(e)):
        raise ValueError("euler_deg must be finite angles in degrees")
    return e, np.stack([euler_to_matrix(a) for a in e])


def poses(positions_m, euler_deg) -> tuple[np.ndarray, np.ndarray]:
    """Positions (P, 3) and angles (P, 3), one of them repeated when it was given once."""
    c = np.asarray(positions_m, dtype=float).reshape(-1, 3)
    e = np.asarray(euler_deg, dtype=float).reshape(-1, 3)
    if not np.all(np.isfinite(c)):
        raise ValueError("positions_m must be finite")
    if c.shape[0] == 0 or e.shape[0] == 0:
        raise ValueError("positions_m and euler_deg need at least one pose")
    if c.shape[0] != e.shape[0]:
        if c.shape[0] == 1:
            c = np.repeat(c, e.shape[0], axis=0)
        elif e.shape[0] == 1:
            e = np.repeat(e, c.shape[0], axis=0)
        else:
            raise ValueError(
                f"positions_m has {c.shape[0]} poses and euler_deg {e.shape[0]}: give one of "
                "them once or both the same number of times"
            )
    return c, e


def observed_pixels(
    uv: np.ndarray, inputs: StudyInputs, image_offset: np.ndarray | None = None
) -> np.ndarray:
    """True image points (B, N, 2) as a study's solver sees them, pixels: rounded (when
    ``inputs.rounding``), moved by ``image_offset`` (B, N, 2) and given Gaussian noise of
    ``inputs.noise_px`` drawn from ``inputs.rng``."""
    if inputs.rounding:
        uv = round_pixels(uv)
    if image_offset is not None:
        uv = uv + image_offset
    if inputs.noise_px > 0:
        uv = uv + inputs.rng.normal(0.0, inputs.noise_px, uv.shape)
    return uv


def _solver_inputs(
    uv: np.ndarray,
    fixtures_m: np.ndarray,
    sl: slice,
    inputs: StudyInputs,
    image_offset: np.ndarray | None,
    world_offset: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray]:
    """The image points (B, N, 2) and world points the solver is given for one chunk."""
    b, n = uv.shape[:2]
    offset = None if image_offset is None else image_offset[sl]
    uv = observed_pixels(uv, inputs, offset)
    obj = fixtures_m
    if world_offset is not None or inputs.survey_error_m > 0:
        obj = np.broadcast_to(fixtures_m, (b, n, 3)).copy()
        if world_offset is not None:
            obj += world_offset[sl]
        if inputs.survey_error_m > 0:
            obj += inputs.rng.normal(0.0, inputs.survey_error_m, (b, n, 3))
    return uv, obj


def position_errors(
    camera: Camera,
    inputs: StudyInputs,
    R: np.ndarray,
    C: np.ndarray,
    *,
    fixtures_m: np.ndarray | None = None,
    image_offset: np.ndarray | None = None,
    world_offset: np.ndarray | None = None,
    progress: Progress | None = None,
) -> np.ndarray:
    """Position error of each pose: project, round, perturb, solve, compare.

    Parameters
    ----------
    camera : Camera
    inputs : StudyInputs
        Fixtures, solver, rounding and noise (drawn from ``inputs.rng``).
    R : ndarray, shape (B, 3, 3)
        World-to-camera rotations.
    C : ndarray, shape (B, 3)
        True camera centres, metres.
    fixtures_m : ndarray, shape (N, 3), optional
        The fixtures to use instead of all of ``inputs.fixtures_m`` (metres).
    image_offset : ndarray, shape (B, N, 2), optional
        Added to the image points after rounding, pixels.
    world_offset : ndarray, shape (B, N, 3), optional
        Added to the world points the solver is given, metres.
    progress : callable, optional
        ``progress(done, B)`` after each chunk of poses.

    Returns
    -------
    ndarray, shape (B,)
        Distance between true and estimated centres, metres; NaN where the solve failed.
    """
    pts = inputs.fixtures_m if fixtures_m is None else fixtures_m
    b = C.shape[0]
    distort = camera.dist_or_none is not None
    out = np.empty(b)
    for s in range(0, b, _CHUNK):
        sl = slice(s, min(b, s + _CHUNK))
        uv = project_batch(camera, R[sl], C[sl], pts, distort=distort)
        uv, obj = _solver_inputs(uv, pts, sl, inputs, image_offset, world_offset)
        est = solve_positions(obj, uv, camera, inputs.solver)
        out[sl] = np.linalg.norm(est - C[sl], axis=1)
        if progress is not None:
            progress(sl.stop, b)
    return out


def mean_over_last_axis(errors_m: np.ndarray) -> np.ndarray:
    """Mean of the finite errors along the last axis (trials); NaN where none is finite."""
    e = np.asarray(errors_m, dtype=float)
    ok = np.isfinite(e)
    with np.errstate(invalid="ignore"):
        return np.where(ok.any(-1), np.where(ok, e, 0).sum(-1) / ok.sum(-1).clip(1), np.nan)


#: CSV columns naming a pose: its index, centre (m) and thesis angles (deg).
POSE_COLUMNS = ("pose", "x_m", "y_m", "z_m", "theta_x_deg", "theta_y_deg", "theta_z_deg")


def pose_rows(positions_m, euler_deg, values, columns) -> list[list]:
    """CSV rows ``pose, x, y, z, angles, column value, error`` for (P, K) errors per pose.

    ``values`` (P, K) are the errors (m); ``columns`` (K,) the second-to-last cell of each
    row (an offset or a trial number).
    """
    rows = []
    for i, (p, a, e) in enumerate(zip(positions_m, euler_deg, values, strict=True)):
        rows.extend([i, *p, *a, c, ei] for c, ei in zip(columns, e, strict=True))
    return rows
