"""Fixtures and the map of a room: which ID (or frequency) is where."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from camvlp.format import UNITS_TO_M
from camvlp.model.linecode import FrameFormat

if TYPE_CHECKING:
    from scipy.spatial import cKDTree

__all__ = ["UNITS_TO_M", "Fixture", "FixtureMap"]


@dataclass(frozen=True)
class Fixture:
    """One light fixture.

    Attributes
    ----------
    id : int
        The ID it sends (Manchester mode), or its index in the map (frequency mode).
    position : ndarray, shape (3,)
        Centre of the fixture's disc, in map units and frame.
    diameter : float or None
        Diameter of the emitting disc, map units; None when not known.
    normal : ndarray, shape (3,), or None
        Unit vector the fixture faces (into the room); None when not given.
    frequency_hz : float or None
        Blinking frequency of a frequency-coded fixture, Hz.
    """

    id: int
    position: np.ndarray
    diameter: float | None = None
    normal: np.ndarray | None = None
    frequency_hz: float | None = None

    def __post_init__(self) -> None:
        # (``ndarray.all`` and ``math.sqrt``, not their NumPy functions: a map of 10,000
        # fixtures is checked a tenth of a second sooner)
        p = np.asarray(self.position, dtype=float).reshape(-1)
        if p.shape != (3,) or not np.isfinite(p).all():
            raise ValueError(f"position must be three finite numbers, got {self.position!r}")
        object.__setattr__(self, "position", p)
        if self.normal is not None:
            n = np.asarray(self.normal, dtype=float).reshape(-1)
            length = math.sqrt(float(n @ n)) if n.shape == (3,) else 0.0
            if not (math.isfinite(length) and length > 0):
                got = n.tolist() if n.size <= 8 else f"{n.size} numbers"
                raise ValueError(f"normal must be a non-zero 3-vector, got {got}")
            object.__setattr__(self, "normal", n / length)
        if self.diameter is not None and not (np.isfinite(self.diameter) and self.diameter > 0):
            raise ValueError(f"diameter must be a positive number, got {self.diameter!r}")
        if self.frequency_hz is not None and not (
            np.isfinite(self.frequency_hz) and self.frequency_hz > 0
        ):
            raise ValueError(f"frequency_hz must be a positive number, got {self.frequency_hz!r}")


@dataclass(frozen=True)
class FixtureMap:
    """A room's fixtures and how they identify themselves.

    Attributes
    ----------
    fixtures : tuple of Fixture
        The fixtures, IDs unique (unless ``reuse``).
    units : str
        Length unit of positions and diameters: ``"m"``, ``"cm"`` or ``"mm"``.
    mode : str
        ``"manchester"`` (IDs in Manchester frames) or ``"frequency"`` (one square-wave
        frequency per fixture).
    frame : FrameFormat
        The Manchester frame format (also present, unused, in frequency mode).
    source : str
        Where the map was read from ("" when built in code).
    up : ndarray, shape (3,), or None
        Unit vector pointing up in the map's frame (against gravity); None when not given.
        Used only with a measured gravity direction (``locate(..., gravity=...)``).
    chip_rate_hz : float or None
        Manchester chips per second every fixture sends, when known (with the camera's
        ``row_time_s`` it gives the chip length in sensor rows); None otherwise.
    reuse : bool
        The map gives one ID to many fixtures (Manchester mode only): a photo's fixtures are
        then told apart by their geometry (:mod:`camvlp.pipeline.identify.by_geometry`).
        False (the default): a repeated ID is an error.
    """

    fixtures: tuple[Fixture, ...]
    units: str = "m"
    mode: str = "manchester"
    frame: FrameFormat = FrameFormat()  # noqa: RUF009 (frozen, so sharing it is safe)
    source: str = ""
    up: np.ndarray | None = None
    chip_rate_hz: float | None = None
    reuse: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "fixtures", tuple(self.fixtures))
        if self.up is not None:
            u = np.asarray(self.up, dtype=float).reshape(-1)
            if u.shape != (3,) or not np.all(np.isfinite(u)) or np.linalg.norm(u) == 0:
                raise ValueError(f"up must be a non-zero 3-vector, got {self.up!r}")
            object.__setattr__(self, "up", u / np.linalg.norm(u))
        if self.units not in UNITS_TO_M:
            raise ValueError(f"units must be one of {', '.join(UNITS_TO_M)}, got {self.units!r}")
        if self.mode not in ("manchester", "frequency"):
            raise ValueError(f"mode must be 'manchester' or 'frequency', got {self.mode!r}")
        if self.chip_rate_hz is not None and not (
            isinstance(self.chip_rate_hz, (int, float))
            and not isinstance(self.chip_rate_hz, bool)
            and np.isfinite(self.chip_rate_hz)
            and self.chip_rate_hz > 0
        ):
            raise ValueError(f"chip_rate_hz must be a positive number, got {self.chip_rate_hz!r}")
        if not isinstance(self.reuse, bool):
            raise ValueError(f"reuse must be true or false, got {self.reuse!r}")
        if self.reuse and self.mode != "manchester":
            raise ValueError("reuse (one ID for many fixtures) needs the manchester mode")
        ids = [f.id for f in self.fixtures]
        if not self.reuse and len(set(ids)) != len(ids):
            dup = sorted({i for i in ids if ids.count(i) > 1})
            raise ValueError(f"duplicate fixture ID {dup[0]}")
        # two fixtures at one point: a copied line (the pose would be solved from a map in
        # which one lamp stands for two)
        pos = self.positions
        _, first, counts = np.unique(pos, axis=0, return_index=True, return_counts=True)
        if np.any(counts > 1):
            twin = pos[first[counts > 1].min()]
            a, b = [f.id for f, q in zip(self.fixtures, pos, strict=True) if np.all(q == twin)][:2]
            where = ", ".join(f"{v:g}" for v in twin)
            raise ValueError(f"fixtures {a} and {b} are both at position [{where}]")
        if self.mode == "manchester":
            for i in self.distinct_ids:
                self.frame.check_id(i)
        else:
            missing = [f.id for f in self.fixtures if f.frequency_hz is None]
            if missing:
                raise ValueError(f"fixture {missing[0]} has no frequency_hz (frequency mode)")
            freqs = [f.frequency_hz for f in self.fixtures]
            if len(set(freqs)) != len(freqs):
                raise ValueError("two fixtures share a frequency_hz")

    @property
    def unit_m(self) -> float:
        """Size of one map unit in metres."""
        return UNITS_TO_M[self.units]

    @property
    def ids(self) -> list[int]:
        """The fixtures' IDs, in map order."""
        return [f.id for f in self.fixtures]

    @cached_property
    def distinct_ids(self) -> list[int]:
        """The IDs the map's fixtures send, each once, in map order (``ids`` without
        repeats: the same list in a map without ``reuse``)."""
        return list(dict.fromkeys(f.id for f in self.fixtures))

    @cached_property
    def positions(self) -> np.ndarray:
        """Fixture centres, shape (N, 3), map units (read-only: built once)."""
        pos = np.array([f.position for f in self.fixtures], dtype=float).reshape(-1, 3)
        pos.flags.writeable = False
        return pos

    @cached_property
    def id_array(self) -> np.ndarray:
        """The fixtures' IDs, shape (N,), int64, in map order (read-only: built once)."""
        out = np.array([f.id for f in self.fixtures], dtype=np.int64)
        out.flags.writeable = False
        return out

    @cached_property
    def diameters(self) -> np.ndarray:
        """The fixtures' diameters, shape (N,), map units, NaN where not given (read-only)."""
        out = np.array([f.diameter or np.nan for f in self.fixtures], dtype=float)
        out.flags.writeable = False
        return out

    @cached_property
    def normals(self) -> np.ndarray:
        """The fixtures' unit normals, shape (N, 3), rows of NaN where not given
        (read-only)."""
        nan = (np.nan, np.nan, np.nan)
        out = np.array([nan if f.normal is None else f.normal for f in self.fixtures], float)
        out = out.reshape(-1, 3)
        out.flags.writeable = False
        return out

    @cached_property
    def index(self) -> cKDTree:
        """A k-d tree over :attr:`positions` (map units), built when first asked for: the
        fixtures near a point or within a distance of each other, in logarithmic time."""
        from scipy.spatial import cKDTree  # here: SciPy's import costs half a second

        return cKDTree(self.positions)

    def with_id(self, fixture_id: int) -> np.ndarray:
        """Indices into ``fixtures`` of the fixtures that send ``fixture_id``, shape (k,)
        (one at most without ``reuse``; empty for an ID the map lacks)."""
        try:
            return self._indices_by_id.get(fixture_id, _NONE)
        except TypeError:  # (an unhashable ID is no fixture's)
            return _NONE

    def get(self, fixture_id: int) -> Fixture | None:
        """The fixture with this ID, or None (looked up by ID: a map of thousands of
        fixtures costs no more than one of four).  In a map with ``reuse``, an ID given to
        more than one fixture names none of them: None."""
        try:
            return self._by_id.get(fixture_id)
        except TypeError:  # (an unhashable ID is no fixture's)
            return None

    @cached_property
    def _by_id(self) -> dict[int, Fixture]:
        """The fixtures by ID (``fixtures`` is a tuple and the map frozen: built once); the
        IDs given to one fixture only."""
        if not self.reuse:
            return {f.id: f for f in self.fixtures}
        one = {i for i, k in self._indices_by_id.items() if k.size == 1}
        return {f.id: f for f in self.fixtures if f.id in one}

    @cached_property
    def _indices_by_id(self) -> dict[int, np.ndarray]:
        """Each ID's fixtures' indices (read-only arrays)."""
        lists: dict[int, list[int]] = {}
        for k, f in enumerate(self.fixtures):
            lists.setdefault(f.id, []).append(k)
        out = {}
        for key, part in lists.items():
            out[key] = np.array(part, dtype=np.int64)
            out[key].flags.writeable = False
        return out


_NONE = np.zeros(0, dtype=np.int64)
_NONE.flags.writeable = False
