"""The coverage study: where on the floor a fix is possible, over a range of tilts."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from camvlp.analysis.stats import error_stats
from camvlp.analysis.study.common import (
    Progress,
    mean_over_last_axis,
    nonneg,
    rotations,
    study_inputs,
)
from camvlp.analysis.study.coverage_sweep import KnownGravity, sweep_poses
from camvlp.analysis.study.site_views import SiteGeometry, view_ambiguous
from camvlp.geometry.disc import rim_points
from camvlp.io.writers import jsonable
from camvlp.model.camera import DEFAULT_ROW_TIME_S, Camera
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.identify.by_geometry import GRAVITY_NEEDED, LIGHTS_NEEDED
from camvlp.sim.grid import axis_values, floor_grid, plane_axes, up_sign

__all__ = ["CoverageStudy", "coverage_study"]

#: How closely another place of a site must repeat a view's IDs and arrangement to leave it
#: ambiguous, metres (:func:`~camvlp.analysis.study.site_views.view_ambiguous`).
_PLACE_TOL_M = 0.05


@dataclass(frozen=True)
class CoverageStudy:
    """Where on the floor a camera gets a fix, over a set of orientations.

    A fix needs at least four fixtures, not all on one line, each facing the camera, with
    its whole disc inside the image and spanning at least ``min_rows`` rows along the
    readout axis; with gravity, at least ``min_fixtures`` (2, 3 or 4), not all on one line
    along gravity.  In a map whose IDs repeat, the fixtures in view must also say where the
    camera is (:attr:`ambiguous`).

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
    gravity : bool
        Whether the camera knows the direction of gravity.
    gravity_sigma_deg : float
        Its uncertainty (the noise drawn, per axis, and the weight of the gravity residual),
        degrees; NaN without gravity.
    min_fixtures : int
        Fixtures a fix needs.
    fix_four : ndarray of bool, shape (NV, NU, O), or None
        Where four fixtures without gravity give a fix (None: the same as ``fix``).
    ambiguous : ndarray of bool, shape (NV, NU, O), or None
        In a map whose IDs repeat (``FixtureMap.reuse``): where the fixtures in view were
        enough for a fix but do not say where the camera is (fewer than
        :data:`~camvlp.pipeline.identify.by_geometry.LIGHTS_NEEDED`, or the same IDs in the
        same arrangement elsewhere in the site, with any one of them missing too:
        :func:`~camvlp.analysis.study.site_views.view_ambiguous`); None for other maps.
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
    gravity: bool = False
    gravity_sigma_deg: float = float("nan")
    min_fixtures: int = 4
    fix_four: np.ndarray | None = None
    ambiguous: np.ndarray | None = None

    @property
    def fraction(self) -> np.ndarray:
        """Fraction of orientations with a fix at each floor point, shape (NV, NU)."""
        return self.fix.mean(axis=-1)

    @property
    def fraction_four(self) -> np.ndarray:
        """The same for four fixtures without gravity, shape (NV, NU)."""
        return (self.fix if self.fix_four is None else self.fix_four).mean(axis=-1)

    @property
    def error_map_m(self) -> np.ndarray:
        """Mean error over orientations with a fix and trials, shape (NV, NU); NaN if none."""
        return mean_over_last_axis(self.errors_m.reshape(*self.fix.shape[:2], -1))

    def summary(self) -> dict:
        """JSON-ready summary of the coverage and the errors where there is a fix."""
        frac = self.fraction
        stats = error_stats(self.errors_m[self.fix])
        return jsonable(
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
                "gravity": self.gravity,
                "gravity_sigma_deg": self.gravity_sigma_deg if self.gravity else None,
                "min_fixtures": self.min_fixtures,
                "mean_fix_fraction_four_no_gravity": float(self.fraction_four.mean()),
                "poses_seeing_at_least": {
                    str(k): float((self.usable >= k).mean()) for k in range(1, 7)
                },
                "reuse": self.ambiguous is not None,
                "ambiguous_views": (
                    int(self.ambiguous.sum()) if self.ambiguous is not None else None
                ),
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
    gravity: bool = False,
    gravity_sigma_deg: float = 1.0,
    min_fixtures: int | None = None,
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
        Seconds per sensor row; default the camera's ``row_time_s``, else
        :data:`~camvlp.model.readout.DEFAULT_ROW_TIME_S` (20 us).
    min_frames : float
        Frames of rows a disc must span (1 for cyclic decoding; 1.2 leaves a margin).
    default_diameter_m : float, optional
        Diameter for fixtures the map gives none, metres.
    noise_px : float
        Sigma of the detection noise on each image coordinate, pixels.
    trials : int
        Noise draws per position and orientation.
    seed, solver, rounding, progress
        As for :func:`~camvlp.analysis.study.rounding.rounding_study`.
    n_rim : int
        Points per rim (8 or more).
    gravity : bool
        The camera knows the direction of gravity (a phone's accelerometer): a fix needs
        ``min_fixtures`` fixtures, not all on a line along the map's up (``FixtureMap.up``,
        else away from the floor), and its error comes from the gravity solver's cost
        (:func:`~camvlp.geometry.gravity.refine_gravity_batch`: reprojection residuals of one
        pixel each and a gravity residual weighted by ``gravity_sigma_deg``), minimised from
        the true pose, with gravity drawn with a Gaussian error of ``gravity_sigma_deg`` per
        axis.
    gravity_sigma_deg : float
        The accelerometer's uncertainty, degrees.
    min_fixtures : int, optional
        Fixtures a fix needs: 2, 3 or 4 with gravity (default 2), 4 without.  In a map
        whose IDs repeat (``FixtureMap.reuse``) a fix needs, besides, fixtures in view that
        place the camera as :func:`camvlp.locate` would (:attr:`CoverageStudy.ambiguous`).
        The fixtures near each camera centre only are projected (blocks of
        :data:`~camvlp.analysis.study.coverage_sweep.POINTS_AT_ONCE` points), so a site of
        thousands of fixtures is swept as a room is.

    Returns
    -------
    CoverageStudy
    """
    least = _min_fixtures(gravity, gravity_sigma_deg, min_fixtures)
    inp = study_inputs(
        fixture_map,
        solver=solver,
        rounding=rounding,
        noise_px=noise_px,
        trials=trials,
        seed=seed,
        min_fixtures=least,
    )
    rt = _row_time(camera, row_time_s, chip_rate_hz, min_frames, n_rim)
    pts = inp.fixtures_m
    u, v, pos = floor_grid(
        pts, plane=plane, u_range_m=u_range_m, v_range_m=v_range_m, step_m=step_m, height_m=height_m
    )
    normals, rims = _fixture_discs(fixture_map, plane, default_diameter_m, int(n_rim))
    frame_rows = fixture_map.frame.n_chips / (chip_rate_hz * rt)
    eul, rots = _orientations(base_euler_deg, tilt_max_deg, tilt_step_deg)
    grav = None
    up = _floor_up(pts, plane) if fixture_map.up is None else fixture_map.up
    if gravity:
        grav = KnownGravity(up, float(gravity_sigma_deg), least)
    usable, fix, fix_four, errors, untold = sweep_poses(
        camera,
        inp,
        pos.reshape(-1, 3),
        rots,
        (normals, rims),
        min_frames * frame_rows,
        grav,
        progress,
        _told_apart(fixture_map, pts, up, gravity) if fixture_map.reuse else None,
    )
    shape = (v.size, u.size, eul.shape[0])
    return CoverageStudy(
        plane,
        u,
        v,
        float(height_m),
        pos,
        eul,
        usable.reshape(shape),
        fix.reshape(shape),
        errors.reshape(*shape, inp.trials),
        float(frame_rows),
        float(min_frames * frame_rows),
        "gravity" if gravity else solver,
        inp.noise_px,
        inp.rounding,
        int(seed),
        bool(gravity),
        float(gravity_sigma_deg) if gravity else float("nan"),
        least,
        fix_four.reshape(shape),
        untold.reshape(shape) if fixture_map.reuse else None,
    )


def _told_apart(fixture_map: FixtureMap, points_m: np.ndarray, up: np.ndarray, gravity: bool):
    """For a map whose IDs repeat: whether the fixtures a pose sees (indices) say where it
    is, as :func:`camvlp.locate` would place it without a prior: :data:`LIGHTS_NEEDED`
    lights or more (:data:`GRAVITY_NEEDED` with gravity), and no other place with those IDs
    in that arrangement (with any one of four or more missing too)."""
    site = SiteGeometry(
        points_m, np.asarray(up, dtype=float), fixture_map.id_array, fixture_map.frame.n_ids
    )
    least = GRAVITY_NEEDED if gravity else LIGHTS_NEEDED
    answers: dict[bytes, bool] = {}  # neighbouring poses and tilts see the same fixtures

    def told_apart(members: np.ndarray) -> bool:
        key = np.sort(members).tobytes()
        if key not in answers:
            answers[key] = not view_ambiguous(site, members, _PLACE_TOL_M, True, least)
        return answers[key]

    return told_apart


def _min_fixtures(gravity: bool, sigma_deg: float, min_fixtures: int | None) -> int:
    """Fixtures a fix needs (default 2 with gravity, 4 without), after checking the
    gravity arguments (ValueError naming the one at fault)."""
    least = (2 if gravity else 4) if min_fixtures is None else min_fixtures
    if least not in ((2, 3, 4) if gravity else (4,)):
        raise ValueError(
            f"min_fixtures must be 2, 3 or 4 with gravity and 4 without, got {min_fixtures!r}"
        )
    if gravity and not (np.isfinite(sigma_deg) and sigma_deg > 0):
        raise ValueError(f"gravity_sigma_deg must be positive, got {sigma_deg!r}")
    return int(least)


def _row_time(
    camera: Camera, row_time_s: float | None, chip_rate_hz: float, min_frames: float, n_rim: int
) -> float:
    """The row time to use (s), after checking the timing arguments."""
    if not (np.isfinite(chip_rate_hz) and chip_rate_hz > 0):
        raise ValueError(f"chip_rate_hz must be positive, got {chip_rate_hz!r}")
    if row_time_s is not None:
        rt = row_time_s
    elif camera.row_time_s is not None:
        rt = camera.row_time_s
    else:
        rt = DEFAULT_ROW_TIME_S
    if not (np.isfinite(rt) and 0 < rt < 1):
        raise ValueError(f"row_time_s must be a positive number of seconds, got {row_time_s!r}")
    if not (np.isfinite(min_frames) and min_frames >= 0):
        raise ValueError(f"min_frames must be non-negative, got {min_frames!r}")
    if int(n_rim) < 8:
        raise ValueError(f"n_rim must be at least 8, got {n_rim!r}")
    return float(rt)


def _fixture_discs(
    fixture_map: FixtureMap, plane: str, default_diameter_m: float | None, n_rim: int
) -> tuple[np.ndarray, np.ndarray]:
    """Each fixture's normal (N, 3) and ``n_rim`` points on its rim (N, n_rim, 3), metres.

    A fixture without a normal faces the floor of ``plane``; one without a diameter takes
    ``default_diameter_m``, and ValueError when there is none.
    """
    pts = fixture_map.positions * fixture_map.unit_m
    down = -_floor_up(pts, plane)
    diam = []
    for f in fixture_map.fixtures:
        d = f.diameter * fixture_map.unit_m if f.diameter is not None else default_diameter_m
        if d is None or not (np.isfinite(d) and d > 0):
            raise ValueError(
                f"fixture {f.id} has no diameter; coverage needs one "
                f"({fixture_map.source or 'map'})"
            )
        diam.append(d)
    normals = np.array([f.normal if f.normal is not None else down for f in fixture_map.fixtures])
    return normals, rim_points(pts, np.asarray(diam), normals, n_rim)


def _floor_up(points_m: np.ndarray, plane: str) -> np.ndarray:
    """Unit vector (3,) along the vertical axis of ``plane``, from the floor towards the
    fixtures ``points_m`` (N, 3)."""
    _, _, vert = plane_axes(plane)
    up = np.zeros(3)
    up[vert] = up_sign(points_m, vert)
    return up


def _orientations(
    base_euler_deg: Sequence[float], tilt_max_deg: float, tilt_step_deg: float
) -> tuple[np.ndarray, np.ndarray]:
    """Angles (O, 3), degrees, of every tilt pair about x and y, and their rotations."""
    tmax = nonneg(tilt_max_deg, "tilt_max_deg")
    if not (np.isfinite(tilt_step_deg) and tilt_step_deg > 0):
        raise ValueError(f"tilt_step_deg must be positive, got {tilt_step_deg!r}")
    tilts = axis_values((-tmax, tmax), tilt_step_deg, "tilt range")
    ta, tb = np.meshgrid(tilts, tilts, indexing="ij")
    base = np.asarray(base_euler_deg, dtype=float).reshape(3)
    eul = np.stack([base[0] + ta.ravel(), base[1] + tb.ravel(), np.full(ta.size, base[2])], axis=1)
    return rotations(eul)
