"""Perspective offsets of the fixtures' discs for the video tracker
(:mod:`camvlp.pipeline.track.tracker`), kept per fixture while the camera barely moves."""

from __future__ import annotations

import numpy as np

from camvlp.geometry.disc import perspective_offset
from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import FixtureMap

__all__ = ["PerspectiveOffsets"]


class PerspectiveOffsets:
    """Offsets of each disc's ellipse centre from its projected centre, cached per fixture.

    An offset is kept while the camera moves less than 10 % of its distance to the fixture
    and turns less than a degree (the offset changes slowly and is a fraction of a pixel).

    Parameters
    ----------
    camera : Camera
    fixture_map : FixtureMap
        The room (fixtures with a diameter and a normal are offset).
    enabled : bool
        False: every offset is zero (``LocateSettings.correct_perspective`` off).
    """

    def __init__(self, camera: Camera, fixture_map: FixtureMap, *, enabled: bool) -> None:
        self.camera = camera
        self.map = fixture_map
        self.enabled = enabled
        self._positions = fixture_map.positions
        self._cache: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def __call__(self, values: np.ndarray, obj: np.ndarray) -> np.ndarray:
        """Offsets (N, 2), pixels, of the fixtures at ``obj`` (N, 3), map units, seen from the
        pose ``values`` (6,): position (map units) and angles (degrees)."""
        out = np.zeros((obj.shape[0], 2))
        if not self.enabled:
            return out
        pose = None
        for j, p in enumerate(obj):
            k = int(np.argmin(np.linalg.norm(self._positions - p, axis=1)))
            f = self.map.fixtures[k]
            if not (f.diameter and f.normal is not None):
                continue
            cached = self._cache.get(k)
            if cached is not None:
                at, offset = cached
                near = np.linalg.norm(at[:3] - values[:3]) <= 0.1 * np.linalg.norm(p - at[:3])
                if near and np.max(np.abs(at[3:] - values[3:])) <= 1.0:
                    out[j] = offset
                    continue
            if pose is None:
                pose = Pose.from_euler(values[:3], values[3:])
            out[j] = perspective_offset(self.camera, pose, f.position, f.diameter, f.normal)
            self._cache[k] = (values.copy(), out[j].copy())
        return out
