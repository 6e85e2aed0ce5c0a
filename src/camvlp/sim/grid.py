"""Camera centres on a grid over the floor: the poses of studies and rendered surveys.

Two ways to ask for the same grid:

* :func:`floor_grid` names the floor by its two world axes (``"xz"`` for the thesis) and the
  camera's height above it, in metres, "up" pointing from the floor towards the fixtures
  (so in the thesis' room, whose ``y`` points down, height ``h`` is ``y = -h``).  The
  error study uses it.
* :func:`grid_points` takes ``start, stop, step`` per axis and the third coordinate's value,
  in map units, and returns a flat list of positions.  Rendered surveys use it.

Both build on :func:`axis_values` (``stop`` included when it is a whole number of steps
away).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["axis_values", "floor_grid", "grid_points", "plane_axes", "set_height", "up_sign"]

_AXES = "xyz"

#: Most values one grid axis may have.
MAX_AXIS_VALUES = 100_000


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

    Raises
    ------
    ValueError
        Ends that are not finite or not in order, a step that is not positive, or more than
        100000 values.
    """
    lo, hi = (float(v) for v in value_range)
    if not (np.isfinite(lo) and np.isfinite(hi)) or hi < lo:
        raise ValueError(f"{name} must be two finite numbers lo <= hi, got {value_range!r}")
    if not (np.isfinite(step) and step > 0):
        raise ValueError(f"step for {name} must be positive, got {step!r}")
    n = int(np.floor((hi - lo) / step + 1e-9)) + 1
    if n > MAX_AXIS_VALUES:
        raise ValueError(f"{name} with step {step} gives {n} values (at most {MAX_AXIS_VALUES})")
    return np.round(lo + step * np.arange(n), 12)


def plane_axes(plane: str) -> tuple[int, int, int]:
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


def up_sign(fixtures_m: np.ndarray, vertical: int) -> float:
    """+1 or -1: the direction, along the vertical axis, from the floor to the fixtures."""
    mean = float(np.mean(np.asarray(fixtures_m, dtype=float).reshape(-1, 3)[:, vertical]))
    if mean == 0:
        raise ValueError(
            f"plane: the fixtures are not above the floor (mean {_AXES[vertical]} is 0)"
        )
    return float(np.sign(mean))


def _place(u: np.ndarray, v: np.ndarray, level: float, i: int, j: int, k: int) -> np.ndarray:
    """Positions (NV, NU, 3): ``u`` along axis ``i``, ``v`` along ``j``, ``level`` on ``k``."""
    pos = np.zeros((v.size, u.size, 3))
    pos[..., i] = u[None, :]
    pos[..., j] = v[:, None]
    pos[..., k] = float(level) + 0.0  # + 0.0: no negative zero
    return pos


def floor_grid(
    fixtures_m,
    *,
    plane: str = "xz",
    u_range_m: Sequence[float] = (-1.0, 1.0),
    v_range_m: Sequence[float] = (-1.0, 1.0),
    step_m: float = 0.1,
    height_m: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Camera centres on a grid over the floor, at a height above it.

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
    i, j, k = plane_axes(plane)
    u = axis_values(u_range_m, step_m, f"{plane[0]} range")
    v = axis_values(v_range_m, step_m, f"{plane[1]} range")
    return u, v, _place(u, v, up_sign(fixtures_m, k) * float(height_m), i, j, k)


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
    _, _, k = plane_axes(plane)
    out = np.array(positions_m, dtype=float).reshape(-1, 3)
    out[:, k] = up_sign(fixtures_m, k) * float(height_m) + 0.0  # no -0.0
    return out


def grid_points(
    first: tuple[float, float, float],
    second: tuple[float, float, float],
    level: float,
    *,
    axes: tuple[int, int] = (0, 2),
) -> np.ndarray:
    """Camera centres on a regular grid over a plane of constant coordinate, as a list.

    Parameters
    ----------
    first, second : tuple of (start, stop, step)
        The grid along the two in-plane axes, map units; ``stop`` is included when it falls
        on the grid.
    level : float
        Value of the third coordinate (for the thesis' room, ``y``: 0 on the floor, and
        ``-h`` at height ``h`` since its ``y`` points down).
    axes : tuple of int
        Indices of the two in-plane axes; default ``(0, 2)``, the thesis' floor ``x, z``.

    Returns
    -------
    ndarray, shape (N, 3)
        The positions, the first axis varying slowest.

    Raises
    ------
    ValueError
        A step that is not positive, a stop below its start, or bad axes.
    """
    a, b = (int(k) for k in axes)
    if {a, b} - {0, 1, 2} or a == b:
        raise ValueError(f"axes must be two different indices from 0, 1, 2, got {axes!r}")
    (s0, e0, d0), (s1, e1, d1) = first, second
    u = axis_values((s0, e0), d0, "first grid")
    v = axis_values((s1, e1), d1, "second grid")
    # (NV, NU, 3) with v along rows; the first axis varies slowest in the flat list
    return _place(u, v, level, a, b, 3 - a - b).transpose(1, 0, 2).reshape(-1, 3)
