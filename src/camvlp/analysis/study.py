"""Error study and deployment planning (thesis chapter 4), geometry only.

Every study projects the fixtures' centres with an ideal camera onto an infinite image
plane, rounds them to whole pixels (the thesis' pixelisation; optional), perturbs what the
study asks for, solves PnP (:mod:`camvlp.pnp`) and measures how far the estimated camera
centre is from the true one.

* :func:`rounding_study`: camera on a grid over the floor at one orientation; the only error
  is the pixel rounding (thesis figure 4.2), optionally with Gaussian noise.
* :func:`forced_error_study`: a forced offset on one fixture's image coordinate (pixels) or
  world coordinate (metres), for several camera poses (figures 4.3 to 4.5).
* :func:`monte_carlo_study`: Gaussian noise on every fixture's image point and/or world
  point, many trials per pose (mean, median, 95th percentile).
* :func:`coverage_study`: where on the floor a fix is possible (at least four fixtures
  wholly in the image and spanning enough rows to decode), over a range of tilts, and the
  expected error there.

Units: the study works in metres whatever the map's unit (converted with
:attr:`FixtureMap.unit_m`); errors are in metres; image quantities in pixels.  The floor is
the plane where the map's vertical coordinate is 0; "up" points from it towards the
fixtures, so in the thesis' room (y down, ceiling at y = -2.7 m) a camera height ``h``
means ``y = -h``.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camvlp.geometry.disc import rim_points
from camvlp.geometry.pnp import LOCATE_SOLVER, check_solver, project_batch, solve_pnp_batch
from camvlp.model.camera import Camera, euler_to_matrix
from camvlp.model.fixtures import FixtureMap
from camvlp.model.readout import Readout

__all__ = [
    "CoverageStudy",
    "ForcedErrorStudy",
    "MonteCarloStudy",
    "RoundingStudy",
    "axis_values",
    "coverage_study",
    "error_stats",
    "floor_grid",
    "forced_error_study",
    "monte_carlo_study",
    "plot_coverage",
    "plot_forced_error",
    "plot_monte_carlo",
    "plot_rounding",
    "round_pixels",
    "rounding_study",
    "set_height",
    "write_csv",
    "write_outputs",
]

#: Progress callback: ``progress(done, total)`` in poses.
Progress = Callable[[int, int], None]

_AXES = "xyz"
_CHUNK = 4096  # poses per batch between progress reports


# ----------------------------------------------------------------------------- helpers


def _check_solver(solver: str) -> str:
    return check_solver(solver, allow_locate=True)


def solve_positions(object_points, image_points, camera: Camera, solver: str) -> np.ndarray:
    """Camera centres for many sets of correspondences, by any solver the study knows.

    ``solver`` is an OpenCV method (:data:`camvlp.geometry.pnp.SOLVERS`, one
    ``cv2.solvePnP`` call per set) or ``"locate"``: the locator's own pose stage
    (:func:`camvlp.pipeline.pose.estimate_pose`: candidates from several solvers, refined,
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
    if _check_solver(solver) != LOCATE_SOLVER:
        return solve_pnp_batch(object_points, image_points, camera, solver)
    from camvlp.pipeline.pose import estimate_pose

    img = np.asarray(image_points, dtype=float)
    obj = np.broadcast_to(np.asarray(object_points, dtype=float), (*img.shape[:2], 3))
    out = np.full((img.shape[0], 3), np.nan)
    for i in range(img.shape[0]):
        if np.all(np.isfinite(img[i])):
            est = estimate_pose(img[i], obj[i], camera, outlier_px=np.inf)
            if est:
                out[i] = est.pose.position
    return out


def _plane_axes(plane: str) -> tuple[int, int, int]:
    """Indices of the two floor axes and the vertical axis of a plane name like ``"xz"``."""
    if (
        not isinstance(plane, str)
        or len(plane) != 2
        or plane[0] == plane[1]
        or any(a not in _AXES for a in plane)
    ):
        raise ValueError(f"plane must be two different axes of x, y, z (e.g. 'xz'), got {plane!r}")
    i, j = _AXES.index(plane[0]), _AXES.index(plane[1])
    return i, j, 3 - i - j


def _up_sign(fixtures_m: np.ndarray, vertical: int) -> float:
    """+1 or -1: the direction, along the vertical axis, from the floor to the fixtures."""
    mean = float(np.mean(fixtures_m[:, vertical]))
    if mean == 0:
        raise ValueError(
            f"plane: the fixtures are not above the floor (mean {_AXES[vertical]} is 0)"
        )
    return float(np.sign(mean))


def _nonneg(value: float, name: str) -> float:
    v = float(value)
    if not np.isfinite(v) or v < 0:
        raise ValueError(f"{name} must be a non-negative number, got {value!r}")
    return v


def _trials(trials: int, noisy: bool) -> int:
    if isinstance(trials, bool) or int(trials) != trials or trials < 1:
        raise ValueError(f"trials must be a positive integer, got {trials!r}")
    return int(trials) if noisy else 1


def axis_values(value_range: Sequence[float], step: float, name: str = "range") -> np.ndarray:
    """Values from ``lo`` to ``hi`` inclusive every ``step`` (``hi`` kept when it is a step away).

    Parameters
    ----------
    value_range : (lo, hi)
        Ends, lo <= hi.
    step : float
        Spacing, > 0.
    name : str
        Argument name for error messages.

    Returns
    -------
    ndarray, shape (K,)
        ``lo + k * step`` for k = 0, 1, ... while <= hi (to 1e-9 of a step).
    """
    lo, hi = (float(v) for v in value_range)
    if not (np.isfinite(lo) and np.isfinite(hi)) or hi < lo:
        raise ValueError(f"{name} must be two finite numbers lo <= hi, got {value_range!r}")
    if not (np.isfinite(step) and step > 0):
        raise ValueError(f"step for {name} must be positive, got {step!r}")
    n = int(np.floor((hi - lo) / step + 1e-9)) + 1
    if n > 100_000:
        raise ValueError(f"{name} with step {step} gives {n} values (at most 100000)")
    return np.round(lo + step * np.arange(n), 12)


def floor_grid(
    fixtures_m,
    *,
    plane: str = "xz",
    u_range_m: Sequence[float] = (-1.0, 1.0),
    v_range_m: Sequence[float] = (-1.0, 1.0),
    step_m: float = 0.1,
    height_m: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Camera centres on a grid over the floor.

    Parameters
    ----------
    fixtures_m : array_like, shape (N, 3)
        Fixture centres in metres (they fix which way is up).
    plane : str
        The two world axes spanning the floor, e.g. ``"xz"`` (the thesis) or ``"xy"``.
    u_range_m, v_range_m : (lo, hi)
        Extent along the first and second axis of ``plane``, metres.
    step_m : float
        Grid spacing, metres.
    height_m : float
        Camera height above the floor (vertical coordinate 0), metres, towards the fixtures.

    Returns
    -------
    u_m : ndarray, shape (NU,)
    v_m : ndarray, shape (NV,)
    positions_m : ndarray, shape (NV, NU, 3)
        Camera centres in world coordinates, metres.
    """
    i, j, k = _plane_axes(plane)
    pts = np.asarray(fixtures_m, dtype=float).reshape(-1, 3)
    u = axis_values(u_range_m, step_m, f"{plane[0]} range")
    v = axis_values(v_range_m, step_m, f"{plane[1]} range")
    pos = np.zeros((v.size, u.size, 3))
    pos[..., i] = u[None, :]
    pos[..., j] = v[:, None]
    pos[..., k] = _up_sign(pts, k) * float(height_m) + 0.0  # no -0.0
    return u, v, pos


def set_height(positions_m, fixtures_m, *, plane: str = "xz", height_m: float) -> np.ndarray:
    """Camera centres with their vertical coordinate replaced by a height above the floor.

    Parameters
    ----------
    positions_m : array_like, shape (P, 3)
        Camera centres, metres.
    fixtures_m : array_like, shape (N, 3)
        Fixture centres, metres (they fix which way is up).
    plane : str
        The floor's two axes, e.g. ``"xz"``.
    height_m : float
        Height above the floor, metres.

    Returns
    -------
    ndarray, shape (P, 3)
    """
    _, _, k = _plane_axes(plane)
    out = np.array(positions_m, dtype=float).reshape(-1, 3)
    up = _up_sign(np.asarray(fixtures_m, dtype=float).reshape(-1, 3), k)
    out[:, k] = up * float(height_m) + 0.0  # no -0.0
    return out


def round_pixels(uv: np.ndarray) -> np.ndarray:
    """Round pixel coordinates to the nearest pixel centre (halves up), like the thesis."""
    return np.floor(uv + 0.5)


def error_stats(errors_m) -> dict:
    """Mean, median, 95th percentile and max of position errors (metres), NaN = failure.

    Returns
    -------
    dict
        ``poses``, ``failures`` and ``mean_error_m``, ``median_error_m``, ``p95_error_m``,
        ``max_error_m`` over the poses that were solved (None when none was).
    """
    e = np.asarray(errors_m, dtype=float).reshape(-1)
    ok = e[np.isfinite(e)]
    stats = {"poses": int(e.size), "failures": int(e.size - ok.size)}
    for key, fn in (
        ("mean_error_m", np.mean),
        ("median_error_m", np.median),
        ("p95_error_m", lambda a: np.percentile(a, 95)),
        ("max_error_m", np.max),
    ):
        stats[key] = float(fn(ok)) if ok.size else None
    return stats


def _map_m(fixture_map: FixtureMap) -> np.ndarray:
    pts = fixture_map.positions * fixture_map.unit_m
    if pts.shape[0] < 4:
        raise ValueError(
            f"the map has {pts.shape[0]} fixtures; a position needs at least 4 "
            f"({fixture_map.source or 'map'})"
        )
    return pts


def _rotations(euler_deg) -> tuple[np.ndarray, np.ndarray]:
    e = np.asarray(euler_deg, dtype=float).reshape(-1, 3)
    if not np.all(np.isfinite(e)):
        raise ValueError("euler_deg must be finite angles in degrees")
    return e, np.stack([euler_to_matrix(a) for a in e])


def _errors(
    camera: Camera,
    fixtures_m: np.ndarray,
    R: np.ndarray,
    C: np.ndarray,
    *,
    solver: str,
    rounding: bool,
    image_offset: np.ndarray | None = None,
    world_offset: np.ndarray | None = None,
    noise_px: float = 0.0,
    survey_error_m: float = 0.0,
    rng: np.random.Generator | None = None,
    progress: Progress | None = None,
) -> np.ndarray:
    """Position error (metres) of each pose (B,); NaN where the solve failed.

    ``R`` (B,3,3), ``C`` (B,3); image_offset (B,N,2) px and world_offset (B,N,3) m are added
    after rounding; Gaussian noise of ``noise_px`` / ``survey_error_m`` on every fixture.
    """
    b = C.shape[0]
    n = fixtures_m.shape[0]
    distort = camera.dist_or_none is not None
    out = np.empty(b)
    for s in range(0, b, _CHUNK):
        e = min(b, s + _CHUNK)
        uv = project_batch(camera, R[s:e], C[s:e], fixtures_m, distort=distort)
        if rounding:
            uv = round_pixels(uv)
        if image_offset is not None:
            uv = uv + image_offset[s:e]
        if noise_px > 0:
            uv = uv + rng.normal(0.0, noise_px, (e - s, n, 2))
        obj = fixtures_m
        if world_offset is not None or survey_error_m > 0:
            obj = np.broadcast_to(fixtures_m, (e - s, n, 3)).copy()
            if world_offset is not None:
                obj += world_offset[s:e]
            if survey_error_m > 0:
                obj += rng.normal(0.0, survey_error_m, (e - s, n, 3))
        est = solve_positions(obj, uv, camera, solver)
        out[s:e] = np.linalg.norm(est - C[s:e], axis=1)
        if progress is not None:
            progress(e, b)
    return out


def _noise_settings(noise_px: float, survey_error_m: float, trials: int, seed: int):
    noise_px = _nonneg(noise_px, "noise_px")
    survey_error_m = _nonneg(survey_error_m, "survey_error_m")
    noisy = noise_px > 0 or survey_error_m > 0
    return noise_px, survey_error_m, _trials(trials, noisy), np.random.default_rng(seed)


def write_csv(path: str | Path, header: Sequence[str], rows) -> None:
    """Write rows (2-D array or list of sequences) under a header line, floats with %.9g."""
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for row in rows:
            w.writerow(
                [
                    ("" if not np.isfinite(v) else f"{v:.9g}")
                    if isinstance(v, (float, np.floating))
                    else v
                    for v in row
                ]
            )


def _jsonable(obj):
    if isinstance(obj, dict):
        return {k: _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def _fmt3(v) -> str:
    return "(" + ", ".join(f"{x:g}" for x in np.asarray(v, dtype=float)) + ")"


# ------------------------------------------------------------------------- rounding study


@dataclass(frozen=True)
class RoundingStudy:
    """Position error over a floor grid at one orientation (thesis figure 4.2).

    Attributes
    ----------
    solver : str
        PnP method.
    euler_deg : ndarray, shape (3,)
        Camera orientation, the thesis' angles in degrees.
    plane : str
        Floor axes, e.g. ``"xz"``.
    u_m, v_m : ndarray, shapes (NU,), (NV,)
        Grid values along the first and second floor axis, metres.
    height_m : float
        Camera height above the floor, metres.
    positions_m : ndarray, shape (NV, NU, 3)
        True camera centres, world frame, metres.
    errors_m : ndarray, shape (NV, NU, T)
        Distance from true to estimated centre per trial, metres; NaN where PnP failed.
    rounding : bool
        Image points rounded to whole pixels.
    noise_px, survey_error_m : float
        Gaussian noise (sigma) on image points (pixels) and world points (metres).
    seed : int
        Seed of the noise.
    """

    solver: str
    euler_deg: np.ndarray
    plane: str
    u_m: np.ndarray
    v_m: np.ndarray
    height_m: float
    positions_m: np.ndarray
    errors_m: np.ndarray
    rounding: bool
    noise_px: float
    survey_error_m: float
    seed: int

    @property
    def error_map_m(self) -> np.ndarray:
        """Mean error over trials at each grid point, shape (NV, NU), metres."""
        e = self.errors_m
        with np.errstate(invalid="ignore"):
            ok = np.isfinite(e)
            return np.where(ok.any(-1), np.where(ok, e, 0).sum(-1) / ok.sum(-1).clip(1), np.nan)

    @property
    def mean_error_m(self) -> float:
        """Mean position error over all poses solved, metres."""
        return float(np.nanmean(self.errors_m))

    @property
    def max_error_m(self) -> float:
        """Largest position error, metres."""
        return float(np.nanmax(self.errors_m))

    def summary(self) -> dict:
        """JSON-ready summary (``mean_error_m``, ``max_error_m``, ``poses``, ...)."""
        return _jsonable(
            {
                "study": "rounding",
                "solver": self.solver,
                "euler_deg": self.euler_deg,
                "plane": self.plane,
                "height_m": self.height_m,
                "grid": {
                    f"{self.plane[0]}_range_m": [self.u_m[0], self.u_m[-1]],
                    f"{self.plane[1]}_range_m": [self.v_m[0], self.v_m[-1]],
                    "points": int(self.u_m.size * self.v_m.size),
                    "step_m": round(float(self.u_m[1] - self.u_m[0]), 9)
                    if self.u_m.size > 1
                    else None,
                },
                "rounding": self.rounding,
                "noise_px": self.noise_px,
                "survey_error_m": self.survey_error_m,
                "trials": int(self.errors_m.shape[-1]),
                "seed": self.seed,
                **error_stats(self.errors_m),
            }
        )

    def rows(self) -> list[list]:
        """CSV rows: position (m), mean error (m), trials solved."""
        pos = self.positions_m.reshape(-1, 3)
        em = self.error_map_m.reshape(-1)
        solved = np.isfinite(self.errors_m).sum(-1).reshape(-1)
        return [[*p, e, int(s)] for p, e, s in zip(pos, em, solved, strict=True)]

    csv_header = ("x_m", "y_m", "z_m", "error_m", "trials_solved")


def rounding_study(
    camera: Camera,
    fixture_map: FixtureMap,
    *,
    euler_deg: Sequence[float] = (90.0, 0.0, 0.0),
    plane: str = "xz",
    u_range_m: Sequence[float] = (-1.0, 1.0),
    v_range_m: Sequence[float] = (-1.0, 1.0),
    step_m: float = 0.1,
    height_m: float = 0.0,
    solver: str = "iterative",
    rounding: bool = True,
    noise_px: float = 0.0,
    survey_error_m: float = 0.0,
    trials: int = 1,
    seed: int = 0,
    progress: Progress | None = None,
) -> RoundingStudy:
    """Camera position error over a grid on the floor at a fixed orientation.

    The thesis' figure 4.2: fixtures' centres projected (infinite image plane), rounded to
    whole pixels, PnP; the error is the distance between true and estimated camera centres.

    Parameters
    ----------
    camera : Camera
        Intrinsics (the image size does not limit the view here).
    fixture_map : FixtureMap
        At least four fixtures; any length unit.
    euler_deg : (3,)
        Camera orientation, the thesis' angles (degrees); (90, 0, 0) faces the ceiling.
    plane, u_range_m, v_range_m, step_m, height_m
        The floor grid, see :func:`floor_grid`.
    solver : str
        PnP method, a key of :data:`camvlp.pnp.SOLVERS`.
    rounding : bool
        Round image points to whole pixels.
    noise_px, survey_error_m : float
        Gaussian noise sigma on every image point (pixels, after rounding) and on every
        world point given to the solver (metres).  With either, ``trials`` draws per point.
    trials : int
        Monte Carlo trials per grid point (1 without noise).
    seed : int
        Seed of the noise.
    progress : callable, optional
        ``progress(done, total)``, in poses.

    Returns
    -------
    RoundingStudy
    """
    _check_solver(solver)
    pts = _map_m(fixture_map)
    noise_px, survey_error_m, trials, rng = _noise_settings(noise_px, survey_error_m, trials, seed)
    e, r = _rotations(euler_deg)
    u, v, pos = floor_grid(
        pts,
        plane=plane,
        u_range_m=u_range_m,
        v_range_m=v_range_m,
        step_m=step_m,
        height_m=height_m,
    )
    c = np.repeat(pos.reshape(-1, 3), trials, axis=0)
    rr = np.broadcast_to(r[0], (c.shape[0], 3, 3))
    err = _errors(
        camera,
        pts,
        rr,
        c,
        solver=solver,
        rounding=rounding,
        noise_px=noise_px,
        survey_error_m=survey_error_m,
        rng=rng,
        progress=progress,
    )
    return RoundingStudy(
        solver,
        e[0],
        plane,
        u,
        v,
        float(height_m),
        pos,
        err.reshape(v.size, u.size, trials),
        bool(rounding),
        noise_px,
        survey_error_m,
        int(seed),
    )


# --------------------------------------------------------------------- forced-error study


@dataclass(frozen=True)
class ForcedErrorStudy:
    """Position error against a forced error on one fixture (thesis figures 4.3 to 4.5).

    Attributes
    ----------
    kind : {"image", "world"}
        Where the offset is forced: the fixture's image point (pixels) or its world
        position given to the solver (metres).
    axis : str
        ``"x"`` or ``"y"`` (image), ``"x"``, ``"y"`` or ``"z"`` (world).
    fixture_id : int
        The fixture whose coordinate is moved.
    offsets : ndarray, shape (K,)
        Forced offsets, pixels (image) or metres (world).
    positions_m : ndarray, shape (P, 3)
        True camera centres, metres.
    euler_deg : ndarray, shape (P, 3)
        Camera orientations, degrees.
    errors_m : ndarray, shape (P, K)
        Position error, metres; NaN where PnP failed.
    solver : str
    rounding : bool
    """

    kind: str
    axis: str
    fixture_id: int
    offsets: np.ndarray
    positions_m: np.ndarray
    euler_deg: np.ndarray
    errors_m: np.ndarray
    solver: str
    rounding: bool

    @property
    def offset_unit(self) -> str:
        """``"px"`` or ``"m"``."""
        return "px" if self.kind == "image" else "m"

    def fits(self) -> list[dict]:
        """Per pose: least-squares line of error against ``|offset|`` and its R squared."""
        x = np.abs(self.offsets)
        out = []
        for e in self.errors_m:
            ok = np.isfinite(e)
            if ok.sum() < 3 or np.ptp(x[ok]) == 0:
                out.append({"slope": None, "intercept": None, "r2": None})
                continue
            slope, icpt = np.polyfit(x[ok], e[ok], 1)
            resid = e[ok] - (slope * x[ok] + icpt)
            tot = np.sum((e[ok] - e[ok].mean()) ** 2)
            r2 = 1.0 - np.sum(resid**2) / tot if tot > 0 else 1.0
            out.append({"slope": float(slope), "intercept": float(icpt), "r2": float(r2)})
        return out

    def summary(self) -> dict:
        """JSON-ready summary, one entry per pose."""
        unit = self.offset_unit
        series = []
        for p, a, e, f in zip(
            self.positions_m, self.euler_deg, self.errors_m, self.fits(), strict=True
        ):
            ok = np.isfinite(e)
            series.append(
                {
                    "position_m": p,
                    "euler_deg": a,
                    "max_error_m": float(np.max(e[ok])) if ok.any() else None,
                    "error_at_min_offset_m": e[0],
                    "error_at_max_offset_m": e[-1],
                    f"slope_m_per_{unit}": f["slope"],
                    "intercept_m": f["intercept"],
                    "r2_linear": f["r2"],
                    "failures": int((~ok).sum()),
                }
            )
        return _jsonable(
            {
                "study": f"{self.kind}-error",
                "solver": self.solver,
                "fixture_id": self.fixture_id,
                "axis": self.axis,
                f"offset_range_{unit}": [self.offsets[0], self.offsets[-1]],
                "offsets": int(self.offsets.size),
                "rounding": self.rounding,
                "series": series,
                **error_stats(self.errors_m),
            }
        )

    @property
    def csv_header(self) -> tuple[str, ...]:
        return (
            "pose",
            "x_m",
            "y_m",
            "z_m",
            "theta_x_deg",
            "theta_y_deg",
            "theta_z_deg",
            f"offset_{self.offset_unit}",
            "error_m",
        )

    def rows(self) -> list[list]:
        """CSV rows: pose index, position (m), angles (deg), offset, error (m)."""
        rows = []
        for i, (p, a, e) in enumerate(
            zip(self.positions_m, self.euler_deg, self.errors_m, strict=True)
        ):
            rows.extend([i, *p, *a, o, ei] for o, ei in zip(self.offsets, e, strict=True))
        return rows


def _poses(positions_m, euler_deg) -> tuple[np.ndarray, np.ndarray]:
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


def _fixture_index(fixture_map: FixtureMap, fixture_id: int) -> int:
    ids = fixture_map.ids
    if fixture_id not in ids:
        raise ValueError(f"fixture {fixture_id} is not in the map ({fixture_map.source or 'map'})")
    return ids.index(fixture_id)


def forced_error_study(
    camera: Camera,
    fixture_map: FixtureMap,
    *,
    kind: str,
    axis: str,
    offsets,
    positions_m,
    euler_deg,
    fixture_id: int | None = None,
    solver: str = "iterative",
    rounding: bool = True,
    progress: Progress | None = None,
) -> ForcedErrorStudy:
    """Position error as one fixture's image or world coordinate is forced off.

    Parameters
    ----------
    camera : Camera
    fixture_map : FixtureMap
    kind : {"image", "world"}
        Offset the fixture's image point (pixels, added after rounding) or the world
        position the solver is given (metres; the photo is of the true position).
    axis : str
        ``"x"`` or ``"y"`` for image, ``"x"``, ``"y"`` or ``"z"`` for world.
    offsets : array_like, shape (K,)
        Forced offsets, pixels or metres.
    positions_m : array_like, shape (P, 3) or (3,)
        Camera centres, metres.
    euler_deg : array_like, shape (P, 3) or (3,)
        Camera orientations (degrees); one of the two may be given once for all poses.
    fixture_id : int, optional
        The fixture to move; default: the map's first fixture (thesis: ID 5 at
        (0.7935, -2.7, 0.5935)).
    solver : str
    rounding : bool
    progress : callable, optional

    Returns
    -------
    ForcedErrorStudy
    """
    _check_solver(solver)
    if kind not in ("image", "world"):
        raise ValueError(f"kind must be 'image' or 'world', got {kind!r}")
    axes = "xy" if kind == "image" else "xyz"
    if axis not in axes:
        raise ValueError(f"axis must be one of {', '.join(axes)} for {kind} errors, got {axis!r}")
    pts = _map_m(fixture_map)
    fid = fixture_map.ids[0] if fixture_id is None else int(fixture_id)
    idx = _fixture_index(fixture_map, fid)
    off = np.asarray(offsets, dtype=float).reshape(-1)
    if off.size == 0 or not np.all(np.isfinite(off)):
        raise ValueError("offsets must be finite numbers, at least one")
    c, e = _poses(positions_m, euler_deg)
    _, r = _rotations(e)
    p, k, n = c.shape[0], off.size, pts.shape[0]
    cc = np.repeat(c, k, axis=0)
    rr = np.repeat(r, k, axis=0)
    a = axes.index(axis)
    if kind == "image":
        image_offset = np.zeros((p * k, n, 2))
        image_offset[:, idx, a] = np.tile(off, p)
        world_offset = None
    else:
        world_offset = np.zeros((p * k, n, 3))
        world_offset[:, idx, a] = np.tile(off, p)
        image_offset = None
    err = _errors(
        camera,
        pts,
        rr,
        cc,
        solver=solver,
        rounding=rounding,
        image_offset=image_offset,
        world_offset=world_offset,
        progress=progress,
    )
    return ForcedErrorStudy(kind, axis, fid, off, c, e, err.reshape(p, k), solver, bool(rounding))


# ------------------------------------------------------------------------- Monte Carlo


@dataclass(frozen=True)
class MonteCarloStudy:
    """Position error under Gaussian noise on every fixture, many trials per pose.

    Attributes
    ----------
    positions_m : ndarray, shape (P, 3)
        True camera centres, metres.
    euler_deg : ndarray, shape (P, 3)
        Orientations, degrees.
    errors_m : ndarray, shape (P, T)
        Position error per trial, metres; NaN where PnP failed.
    noise_px : float
        Sigma of the noise on each image coordinate, pixels.
    survey_error_m : float
        Sigma of the noise on each world coordinate given to the solver, metres.
    seed : int
    solver : str
    rounding : bool
    """

    positions_m: np.ndarray
    euler_deg: np.ndarray
    errors_m: np.ndarray
    noise_px: float
    survey_error_m: float
    seed: int
    solver: str
    rounding: bool

    def summary(self) -> dict:
        """JSON-ready summary: overall and per-pose mean, median, 95th percentile, max."""
        per_pose = [
            {"position_m": p, "euler_deg": a, **error_stats(e)}
            for p, a, e in zip(self.positions_m, self.euler_deg, self.errors_m, strict=True)
        ]
        return _jsonable(
            {
                "study": "monte-carlo",
                "solver": self.solver,
                "noise_px": self.noise_px,
                "survey_error_m": self.survey_error_m,
                "trials": int(self.errors_m.shape[1]),
                "seed": self.seed,
                "rounding": self.rounding,
                **error_stats(self.errors_m),
                "per_pose": per_pose,
            }
        )

    csv_header = (
        "pose",
        "x_m",
        "y_m",
        "z_m",
        "theta_x_deg",
        "theta_y_deg",
        "theta_z_deg",
        "trial",
        "error_m",
    )

    def rows(self) -> list[list]:
        """CSV rows: pose index, position (m), angles (deg), trial, error (m)."""
        rows = []
        for i, (p, a, e) in enumerate(
            zip(self.positions_m, self.euler_deg, self.errors_m, strict=True)
        ):
            rows.extend([i, *p, *a, t, et] for t, et in enumerate(e))
        return rows


def monte_carlo_study(
    camera: Camera,
    fixture_map: FixtureMap,
    *,
    positions_m,
    euler_deg,
    noise_px: float = 0.0,
    survey_error_m: float = 0.0,
    trials: int = 1000,
    seed: int = 0,
    solver: str = "iterative",
    rounding: bool = True,
    progress: Progress | None = None,
) -> MonteCarloStudy:
    """Position error statistics with Gaussian noise on all fixtures' image and world points.

    Parameters
    ----------
    camera : Camera
    fixture_map : FixtureMap
    positions_m, euler_deg : array_like, shape (P, 3) or (3,)
        Camera poses (metres, degrees); one of the two may be given once.
    noise_px : float
        Sigma on each image coordinate (pixels), added after rounding.
    survey_error_m : float
        Sigma on each world coordinate given to the solver (metres).
    trials : int
        Draws per pose.
    seed : int
    solver : str
    rounding : bool
    progress : callable, optional

    Returns
    -------
    MonteCarloStudy
    """
    _check_solver(solver)
    pts = _map_m(fixture_map)
    noise_px, survey_error_m, trials, rng = _noise_settings(noise_px, survey_error_m, trials, seed)
    c, e = _poses(positions_m, euler_deg)
    _, r = _rotations(e)
    err = _errors(
        camera,
        pts,
        np.repeat(r, trials, axis=0),
        np.repeat(c, trials, axis=0),
        solver=solver,
        rounding=rounding,
        noise_px=noise_px,
        survey_error_m=survey_error_m,
        rng=rng,
        progress=progress,
    )
    return MonteCarloStudy(
        c,
        e,
        err.reshape(c.shape[0], trials),
        noise_px,
        survey_error_m,
        int(seed),
        solver,
        bool(rounding),
    )


# ---------------------------------------------------------------------------- coverage


@dataclass(frozen=True)
class CoverageStudy:
    """Where on the floor a camera gets a fix, over a set of orientations.

    A fix needs at least four fixtures, not all on one line, each facing the camera, with
    its whole disc inside the image and spanning at least ``min_rows`` rows along the
    readout axis.

    Attributes
    ----------
    plane : str
        Floor axes.
    u_m, v_m : ndarray, shapes (NU,), (NV,)
        Grid values, metres.
    height_m : float
        Camera height above the floor, metres.
    positions_m : ndarray, shape (NV, NU, 3)
        Camera centres, metres.
    euler_deg : ndarray, shape (O, 3)
        The orientations tried, degrees.
    usable : ndarray of int, shape (NV, NU, O)
        Fixtures usable (in view, facing, decodable) per position and orientation.
    fix : ndarray of bool, shape (NV, NU, O)
        A position can be computed.
    errors_m : ndarray, shape (NV, NU, O, T)
        Position error per trial where there is a fix, metres; NaN elsewhere.
    frame_rows : float
        Sensor rows one frame of chips lasts.
    min_rows : float
        Rows a fixture's disc must span to be decodable.
    solver : str
    noise_px : float
    rounding : bool
    seed : int
    """

    plane: str
    u_m: np.ndarray
    v_m: np.ndarray
    height_m: float
    positions_m: np.ndarray
    euler_deg: np.ndarray
    usable: np.ndarray
    fix: np.ndarray
    errors_m: np.ndarray
    frame_rows: float
    min_rows: float
    solver: str
    noise_px: float
    rounding: bool
    seed: int

    @property
    def fraction(self) -> np.ndarray:
        """Fraction of orientations with a fix at each floor point, shape (NV, NU)."""
        return self.fix.mean(axis=-1)

    @property
    def error_map_m(self) -> np.ndarray:
        """Mean error over orientations with a fix and trials, shape (NV, NU); NaN if none."""
        e = self.errors_m.reshape(*self.fix.shape[:2], -1)
        ok = np.isfinite(e)
        with np.errstate(invalid="ignore"):
            return np.where(ok.any(-1), np.where(ok, e, 0).sum(-1) / ok.sum(-1).clip(1), np.nan)

    def summary(self) -> dict:
        """JSON-ready summary of the coverage and the errors where there is a fix."""
        frac = self.fraction
        stats = error_stats(self.errors_m[self.fix])
        return _jsonable(
            {
                "study": "coverage",
                "solver": self.solver,
                "plane": self.plane,
                "height_m": self.height_m,
                "floor_points": int(frac.size),
                "orientations": int(self.euler_deg.shape[0]),
                "frame_rows": self.frame_rows,
                "min_rows": self.min_rows,
                "noise_px": self.noise_px,
                "rounding": self.rounding,
                "seed": self.seed,
                "mean_fix_fraction": float(frac.mean()),
                "floor_fraction_any_fix": float((frac > 0).mean()),
                "floor_fraction_all_fix": float((frac == 1).mean()),
                "fixes": int(self.fix.sum()),
                **{k: v for k, v in stats.items() if k not in ("poses", "failures")},
                "solves": stats["poses"],
                "failures": stats["failures"],
            }
        )

    csv_header = (
        "x_m",
        "y_m",
        "z_m",
        "fix_fraction",
        "orientations_with_fix",
        "mean_usable_fixtures",
        "mean_error_m",
    )

    def rows(self) -> list[list]:
        """CSV rows per floor point."""
        pos = self.positions_m.reshape(-1, 3)
        frac = self.fraction.reshape(-1)
        nfix = self.fix.sum(-1).reshape(-1)
        usable = self.usable.mean(-1).reshape(-1)
        err = self.error_map_m.reshape(-1)
        return [
            [*p, f, int(k), float(u), e]
            for p, f, k, u, e in zip(pos, frac, nfix, usable, err, strict=True)
        ]


def _not_collinear(points: np.ndarray, mask: np.ndarray, tol_m: float = 1e-3) -> np.ndarray:
    """True where the masked points (B, N) of ``points`` (N, 3) do not all lie on one line."""
    w = mask.astype(float)
    cnt = w.sum(1).clip(1)
    mean = (w @ points) / cnt[:, None]
    d = points[None, :, :] - mean[:, None, :]
    scatter = np.einsum("bn,bni,bnj->bij", w, d, d) / cnt[:, None, None]
    ev = np.linalg.eigvalsh(scatter)  # ascending
    return ev[:, 1] > tol_m**2


def coverage_study(
    camera: Camera,
    fixture_map: FixtureMap,
    *,
    plane: str = "xz",
    u_range_m: Sequence[float] = (-1.0, 1.0),
    v_range_m: Sequence[float] = (-1.0, 1.0),
    step_m: float = 0.1,
    height_m: float = 0.0,
    base_euler_deg: Sequence[float] = (90.0, 0.0, 0.0),
    tilt_max_deg: float = 15.0,
    tilt_step_deg: float = 5.0,
    chip_rate_hz: float = 10_000.0,
    row_time_s: float | None = None,
    min_frames: float = 1.2,
    default_diameter_m: float | None = None,
    noise_px: float = 0.5,
    trials: int = 1,
    seed: int = 0,
    solver: str = "iterative",
    rounding: bool = True,
    n_rim: int = 16,
    progress: Progress | None = None,
) -> CoverageStudy:
    """Map of the floor where a fix is possible, over a range of tilts, and its error.

    Orientations: ``base_euler_deg + (a, b, 0)`` for tilts ``a`` (about x) and ``b`` (about
    y) each from ``-tilt_max_deg`` to ``tilt_max_deg`` every ``tilt_step_deg``.  A fixture
    is usable when it faces the camera, its whole rim (``n_rim`` points on a disc of its
    diameter) projects inside the image, and the disc spans at least ``min_frames`` frames
    of rows along the camera's readout axis, one frame lasting
    ``n_chips / (chip_rate_hz * row_time_s)`` rows.  With four or more usable fixtures, not
    all on a line, the centres are projected, rounded, given Gaussian noise of ``noise_px``
    and solved with the usable fixtures, ``trials`` times.

    Parameters
    ----------
    camera : Camera
        Intrinsics, image size, distortion (used for what is in view), readout axis.
    fixture_map : FixtureMap
        Fixtures with diameters (else ``default_diameter_m``) and, optionally, normals
        (default: facing down, towards the floor).
    plane, u_range_m, v_range_m, step_m, height_m
        The floor grid, see :func:`floor_grid`.
    base_euler_deg : (3,)
        Orientation with no tilt, degrees; (90, 0, 0) faces the thesis' ceiling.
    tilt_max_deg, tilt_step_deg : float
        Tilt range and step, degrees.
    chip_rate_hz : float
        Line-code chips per second.
    row_time_s : float, optional
        Seconds per sensor row; default the camera's ``row_time_s``, else 20e-6.
    min_frames : float
        Frames of rows a disc must span (1 for cyclic decoding; 1.2 leaves a margin).
    default_diameter_m : float, optional
        Diameter for fixtures the map gives none, metres.
    noise_px : float
        Sigma of the detection noise on each image coordinate, pixels.
    trials : int
        Noise draws per position and orientation.
    seed : int
    solver : str
    rounding : bool
    n_rim : int
        Points per rim (8 or more).
    progress : callable, optional

    Returns
    -------
    CoverageStudy
    """
    _check_solver(solver)
    pts = _map_m(fixture_map)
    noise_px, _, trials, rng = _noise_settings(noise_px, 0.0, trials, seed)
    if not (np.isfinite(chip_rate_hz) and chip_rate_hz > 0):
        raise ValueError(f"chip_rate_hz must be positive, got {chip_rate_hz!r}")
    rt = row_time_s if row_time_s is not None else (camera.row_time_s or 20e-6)
    if not (np.isfinite(rt) and 0 < rt < 1):
        raise ValueError(f"row_time_s must be a positive number of seconds, got {row_time_s!r}")
    if not (np.isfinite(min_frames) and min_frames >= 0):
        raise ValueError(f"min_frames must be non-negative, got {min_frames!r}")
    if int(n_rim) < 8:
        raise ValueError(f"n_rim must be at least 8, got {n_rim!r}")
    tmax = _nonneg(tilt_max_deg, "tilt_max_deg")
    if not (np.isfinite(tilt_step_deg) and tilt_step_deg > 0):
        raise ValueError(f"tilt_step_deg must be positive, got {tilt_step_deg!r}")
    u, v, pos = floor_grid(
        pts,
        plane=plane,
        u_range_m=u_range_m,
        v_range_m=v_range_m,
        step_m=step_m,
        height_m=height_m,
    )
    _, _, vert = _plane_axes(plane)
    up = np.zeros(3)
    up[vert] = _up_sign(pts, vert)

    # fixture discs, metres
    diam = []
    for f in fixture_map.fixtures:
        d = f.diameter * fixture_map.unit_m if f.diameter is not None else default_diameter_m
        if d is None or not (np.isfinite(d) and d > 0):
            raise ValueError(
                f"fixture {f.id} has no diameter; coverage needs one "
                f"({fixture_map.source or 'map'})"
            )
        diam.append(d)
    normals = np.array([f.normal if f.normal is not None else -up for f in fixture_map.fixtures])
    rims = rim_points(pts, np.asarray(diam), normals, int(n_rim))  # (N, K, 3)
    n = pts.shape[0]

    frame_rows = fixture_map.frame.n_chips / (chip_rate_hz * rt)
    min_rows = min_frames * frame_rows
    read_axis = (camera.readout or Readout.ROWS).pixel_index

    tilts = axis_values((-tmax, tmax), tilt_step_deg, "tilt range")
    ta, tb = np.meshgrid(tilts, tilts, indexing="ij")
    base = np.asarray(base_euler_deg, dtype=float).reshape(3)
    eul = np.stack([base[0] + ta.ravel(), base[1] + tb.ravel(), np.full(ta.size, base[2])], axis=1)
    _, rots = _rotations(eul)

    c = pos.reshape(-1, 3)
    g, o = c.shape[0], eul.shape[0]
    distort = camera.dist_or_none is not None
    w, h = camera.width, camera.height
    usable = np.zeros((g, o), dtype=np.int64)
    fix = np.zeros((g, o), dtype=bool)
    errors = np.full((g, o, trials), np.nan)
    facing = np.einsum("ni,gni->gn", normals, c[:, None, :] - pts[None, :, :]) > 0  # (G, N)
    for j in range(o):
        rr = np.broadcast_to(rots[j], (g, 3, 3))
        uv = project_batch(camera, rr, c, rims.reshape(-1, 3), distort=distort)
        uv = uv.reshape(g, n, -1, 2)
        with np.errstate(invalid="ignore"):
            inside = np.all(
                (uv[..., 0] >= -0.5)
                & (uv[..., 0] <= w - 0.5)
                & (uv[..., 1] >= -0.5)
                & (uv[..., 1] <= h - 0.5),
                axis=2,
            )
            span = np.ptp(uv[..., read_axis], axis=2)
            ok = inside & facing & (span >= min_rows)
        usable[:, j] = ok.sum(1)
        good = (usable[:, j] >= 4) & _not_collinear(pts, ok)
        fix[:, j] = good
        # solve each group of positions sharing the same set of usable fixtures
        idx = np.flatnonzero(good)
        if idx.size:
            patterns, inverse = np.unique(ok[idx], axis=0, return_inverse=True)
            for q, pattern in enumerate(patterns):
                members = idx[inverse.reshape(-1) == q]
                sub = pts[pattern]
                cm = np.repeat(c[members], trials, axis=0)
                err = _errors(
                    camera,
                    sub,
                    np.broadcast_to(rots[j], (cm.shape[0], 3, 3)),
                    cm,
                    solver=solver,
                    rounding=rounding,
                    noise_px=noise_px,
                    rng=rng,
                )
                errors[members, j] = err.reshape(-1, trials)
        if progress is not None:
            progress(j + 1, o)
    shape = (v.size, u.size)
    return CoverageStudy(
        plane,
        u,
        v,
        float(height_m),
        pos,
        eul,
        usable.reshape(*shape, o),
        fix.reshape(*shape, o),
        errors.reshape(*shape, o, trials),
        float(frame_rows),
        float(min_rows),
        solver,
        noise_px,
        bool(rounding),
        int(seed),
    )


# ------------------------------------------------------------------------------- plots


def _figure(width: float = 6.4, height: float = 4.8):
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), dpi=120, layout="constrained")


def _heat(
    ax, fig, u, v, values, label: str, plane: str, cmap: str = "viridis", vmin=None, vmax=None
):
    du = (u[1] - u[0]) if u.size > 1 else 0.1
    dv = (v[1] - v[0]) if v.size > 1 else 0.1
    ue = np.append(u - du / 2, u[-1] + du / 2)
    ve = np.append(v - dv / 2, v[-1] + dv / 2)
    masked = np.ma.masked_invalid(values)
    mesh = ax.pcolormesh(ue, ve, masked, cmap=cmap, shading="flat", vmin=vmin, vmax=vmax)
    ax.set_xlabel(f"Camera {plane[0]} (m)")
    ax.set_ylabel(f"Camera {plane[1]} (m)")
    ax.set_aspect("equal")
    ax.set_facecolor("0.85")
    fig.colorbar(mesh, ax=ax, label=label)


def plot_rounding(study: RoundingStudy, path: str | Path) -> None:
    """Heat map of the position error over the floor (mm), like the thesis' figure 4.2."""
    fig = _figure()
    ax = fig.add_subplot()
    _heat(
        ax, fig, study.u_m, study.v_m, study.error_map_m * 1e3, "Position error (mm)", study.plane
    )
    noise = ""
    if study.noise_px or study.survey_error_m:
        noise = f", noise {study.noise_px:g} px / {study.survey_error_m:g} m"
    ax.set_title(
        f"θ = {_fmt3(study.euler_deg)}°, height {study.height_m:g} m, {study.solver}{noise}\n"
        f"mean = {study.mean_error_m * 1e3:.2f} mm, max = {study.max_error_m * 1e3:.2f} mm"
    )
    fig.savefig(path)


def _draw_forced_error(ax, study: ForcedErrorStudy, label: str = "") -> None:
    big = np.nanmax(study.errors_m) if np.isfinite(study.errors_m).any() else 0.0
    scale, unit = (1.0, "m") if big >= 0.5 else (1e2, "cm") if big >= 0.005 else (1e3, "mm")
    vary_pos = len({tuple(p) for p in study.positions_m.round(9)}) > 1
    vary_ang = len({tuple(a) for a in study.euler_deg.round(9)}) > 1
    for p, a, e in zip(study.positions_m, study.euler_deg, study.errors_m, strict=True):
        parts = []
        if vary_pos or not vary_ang:
            parts.append(f"C = {_fmt3(p)} m")
        if vary_ang or not vary_pos:
            parts.append(f"θ = {_fmt3(a)}°")
        ax.plot(study.offsets, e * scale, marker=".", ms=4, label=", ".join(parts))
    what = "image" if study.kind == "image" else "world"
    ax.set_xlabel(
        f"Forced error on fixture {study.fixture_id}'s {what} {study.axis} coordinate "
        f"({study.offset_unit})"
    )
    ax.set_ylabel(f"Position error ({unit})")
    common = []
    if not vary_pos:
        common.append(f"C = {_fmt3(study.positions_m[0])} m")
    if not vary_ang:
        common.append(f"θ = {_fmt3(study.euler_deg[0])}°")
    ax.set_title(
        f"{label}{what.capitalize()} {study.axis} coordinate, {study.solver}"
        + (f"\n{', '.join(common)}" if common else "")
    )
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")


def plot_forced_error(
    study: ForcedErrorStudy | Sequence[ForcedErrorStudy], path: str | Path, *, ncols: int = 2
) -> None:
    """Position error against the forced error, one line per camera pose.

    Parameters
    ----------
    study : ForcedErrorStudy or sequence of them
        One panel per study (panels labelled (a), (b), ... when there are several).
    path : str or Path
        PNG file to write.
    ncols : int
        Panels per row.
    """
    studies = [study] if isinstance(study, ForcedErrorStudy) else list(study)
    cols = min(ncols, len(studies))
    rows = -(-len(studies) // cols)
    fig = _figure(6.4 * cols, 4.8 * rows)
    axes = np.atleast_1d(fig.subplots(rows, cols)).reshape(-1)
    for i, (ax, s) in enumerate(zip(axes, studies, strict=False)):
        _draw_forced_error(ax, s, f"({chr(97 + i)}) " if len(studies) > 1 else "")
    for ax in axes[len(studies) :]:
        ax.set_visible(False)
    fig.savefig(path)


def plot_monte_carlo(study: MonteCarloStudy, path: str | Path) -> None:
    """Cumulative distribution of the position error, one line per pose."""
    fig = _figure()
    ax = fig.add_subplot()
    big = np.nanmax(study.errors_m) if np.isfinite(study.errors_m).any() else 0.0
    scale, unit = (1.0, "m") if big >= 0.5 else (1e2, "cm") if big >= 0.005 else (1e3, "mm")
    for p, a, e in zip(study.positions_m, study.euler_deg, study.errors_m, strict=True):
        s = np.sort(e[np.isfinite(e)]) * scale
        frac = np.arange(1, s.size + 1) / e.size
        ax.step(s, frac, where="post", label=f"C = {_fmt3(p)} m, θ = {_fmt3(a)}°")
    ax.axhline(0.95, color="0.5", lw=0.8, ls="--", label="95 %")
    ax.set_xlabel(f"Position error ({unit})")
    ax.set_ylabel("Fraction of trials")
    ax.set_ylim(0, 1.02)
    ax.set_title(
        f"Monte Carlo: σ = {study.noise_px:g} px on image points, "
        f"{study.survey_error_m:g} m on world points\n"
        f"{study.errors_m.shape[1]} trials per pose, {study.solver}"
    )
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    fig.savefig(path)


def plot_coverage(study: CoverageStudy, path: str | Path) -> None:
    """Two maps: fraction of orientations with a fix, and the mean error where there is one."""
    fig = _figure(12.0, 5.0)
    ax1, ax2 = fig.subplots(1, 2)
    _heat(
        ax1,
        fig,
        study.u_m,
        study.v_m,
        study.fraction,
        "Fraction of orientations with a fix",
        study.plane,
        cmap="magma",
        vmin=0.0,
        vmax=float(study.fraction.max()) if study.fix.any() else 1.0,
    )
    t = np.ptp(study.euler_deg[:, 0]) / 2
    ax1.set_title(
        f"Fix possible: ≥ 4 fixtures in view and decodable\n"
        f"tilts up to ±{t:g}° about x and y, camera height {study.height_m:g} m"
    )
    _heat(
        ax2,
        fig,
        study.u_m,
        study.v_m,
        study.error_map_m * 1e3,
        "Mean position error (mm)",
        study.plane,
    )
    ax2.set_title(
        f"Mean position error where a fix is possible\n"
        f"σ = {study.noise_px:g} px detection noise, {study.solver}"
    )
    fig.savefig(path)


def write_outputs(out_dir: str | Path, name: str, study, plot: Callable) -> dict:
    """Write ``<name>.csv``, ``<name>.png`` and ``summary.json`` into ``out_dir``.

    Returns
    -------
    dict
        The summary written.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / f"{name}.csv", study.csv_header, study.rows())
    plot(study, out / f"{name}.png")
    summary = study.summary()
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    return summary
