"""The forced-error studies: one fixture's image or world coordinate forced off (figs. 4.3-4.5)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camvlp.analysis.stats import error_stats
from camvlp.analysis.study.common import (
    POSE_COLUMNS,
    Progress,
    fixture_index,
    pose_rows,
    poses,
    position_errors,
    rotations,
    study_inputs,
)
from camvlp.io.writers import jsonable
from camvlp.model.camera import Camera
from camvlp.model.fixtures import FixtureMap

__all__ = ["ForcedErrorStudy", "forced_error_study"]


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
        return jsonable(
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
        """CSV columns: the pose's, the offset and the error."""
        return (*POSE_COLUMNS, f"offset_{self.offset_unit}", "error_m")

    def rows(self) -> list[list]:
        """CSV rows: pose index, position (m), angles (deg), offset, error (m)."""
        return pose_rows(self.positions_m, self.euler_deg, self.errors_m, self.offsets)


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
    inp = study_inputs(fixture_map, solver=solver, rounding=rounding)
    if kind not in ("image", "world"):
        raise ValueError(f"kind must be 'image' or 'world', got {kind!r}")
    axes = "xy" if kind == "image" else "xyz"
    if axis not in axes:
        raise ValueError(f"axis must be one of {', '.join(axes)} for {kind} errors, got {axis!r}")
    fid = fixture_map.ids[0] if fixture_id is None else int(fixture_id)
    idx = fixture_index(fixture_map, fid)
    off = np.asarray(offsets, dtype=float).reshape(-1)
    if off.size == 0 or not np.all(np.isfinite(off)):
        raise ValueError("offsets must be finite numbers, at least one")
    c, e = poses(positions_m, euler_deg)
    _, r = rotations(e)
    p, k, n = c.shape[0], off.size, inp.fixtures_m.shape[0]
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
    err = position_errors(
        camera, inp, rr, cc, image_offset=image_offset, world_offset=world_offset, progress=progress
    )
    return ForcedErrorStudy(kind, axis, fid, off, c, e, err.reshape(p, k), solver, bool(rounding))
