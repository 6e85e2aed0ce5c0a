"""The plan of a site seen from above: which map axes lie in the floor, and which way is up."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camvlp.model.fixtures import FixtureMap

__all__ = ["PlanView", "plan_view"]

#: Below this horizontal length (of a unit vector) the optical axis is taken as vertical, and
#: the heading is the direction of the top of the image instead (a phone held flat under the
#: ceiling).
_VERTICAL_AXIS_COS = 0.5


@dataclass(frozen=True)
class PlanView:
    """Map coordinates seen from above.

    Attributes
    ----------
    vertical : int
        Index (0, 1, 2 for x, y, z) of the map's vertical axis.
    up : int
        +1 when up is +vertical (z-up maps), -1 when it is -vertical (the thesis' y-down room).
    axes : tuple of int
        The map axes drawn to the right and upwards on the plan, chosen so that the plan is a
        view from above (right-handed: ``e[axes[0]] x e[axes[1]] = up``).
    """

    vertical: int
    up: int
    axes: tuple[int, int]

    @property
    def up_vector(self) -> np.ndarray:
        """Unit vector pointing up, map coordinates, shape (3,)."""
        u = np.zeros(3)
        u[self.vertical] = self.up
        return u

    def project(self, points: np.ndarray) -> np.ndarray:
        """Plan coordinates ``(right, up-on-the-plan)`` of map points, shape (N, 3) -> (N, 2)."""
        return np.asarray(points, dtype=float)[..., list(self.axes)]

    def heading_deg(self, rotation: np.ndarray) -> float | None:
        """Heading of a camera on the plan, degrees counterclockwise from the plan's right.

        The horizontal part of the optical axis; when the camera looks (nearly) straight up or
        down, the direction of the top of its image instead.  None for a degenerate rotation.

        Parameters
        ----------
        rotation : ndarray, shape (3, 3)
            Camera-to-world rotation (the camera's axes as columns, map coordinates).
        """
        r = np.asarray(rotation, dtype=float)
        u = self.up_vector
        forward, top = r[:, 2], -r[:, 1]
        h = forward - np.dot(forward, u) * u
        if np.linalg.norm(h) < _VERTICAL_AXIS_COS:
            h = top - np.dot(top, u) * u
        a, b = h[list(self.axes)]
        if np.hypot(a, b) < 1e-9:
            return None
        return float(np.degrees(np.arctan2(b, a)))

    def to_dict(self) -> dict:
        """JSON form: ``{"vertical", "up", "axes", "axis_names"}``."""
        names = "xyz"
        return {
            "vertical": self.vertical,
            "up": self.up,
            "axes": list(self.axes),
            "axis_names": [names[self.axes[0]], names[self.axes[1]]],
        }


def plan_view(fixture_map: FixtureMap) -> PlanView:
    """How to look at a map from above.

    Up is the map's ``up`` when it has one (its largest axis), else against the fixtures'
    mean ``normal`` when they have one (ceiling lights face down into the room); otherwise the
    vertical axis is the one along which the fixtures spread least (they hang on one ceiling)
    and up points from the floor (vertical coordinate 0) towards them.
    """
    positions = np.array([f.position for f in fixture_map.fixtures], dtype=float)
    normals = [f.normal for f in fixture_map.fixtures if f.normal is not None]
    mean_normal = np.mean(normals, axis=0) if normals else np.zeros(3)
    if fixture_map.up is not None:
        vertical = int(np.argmax(np.abs(fixture_map.up)))
        up = 1 if fixture_map.up[vertical] > 0 else -1
    elif np.linalg.norm(mean_normal) > 1e-6:
        vertical = int(np.argmax(np.abs(mean_normal)))
        up = -1 if mean_normal[vertical] > 0 else 1
    else:
        spread = np.ptp(positions, axis=0) if len(positions) > 1 else np.array([1.0, 1.0, 0.0])
        vertical = int(np.argmin(spread))
        up = -1 if np.mean(positions[:, vertical]) < 0 else 1
    a, b = (vertical + 1) % 3, (vertical + 2) % 3
    return PlanView(vertical, up, (a, b) if up > 0 else (b, a))
