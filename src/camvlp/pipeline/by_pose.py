"""Look-alike IDs told apart by the pose.

Where the stripes cannot say an ID (at an exposure of a whole chip a single dark chip between
bright ones leaves no trace, and IDs whose frames differ only there read alike), the model
fit refuses the fixture and lists the IDs of the map that fit it almost equally
(:attr:`camvlp.pipeline.model_decode.ModelDecode.candidates`).  Once the pose is solved from
the fixtures that were decoded, each of those IDs' map positions projects to one place in the
photo: the fixture is the one that projects onto it, when exactly one does and every other
projects far away.  The stripes narrow the fixture to a few IDs and the geometry picks one;
neither alone would.
"""

from __future__ import annotations

import numpy as np

from camvlp.model.camera import Camera, Pose, project_points
from camvlp.model.fixtures import FixtureMap

__all__ = ["TOLD_APART", "told_by_pose"]

#: A candidate ID is taken when its map position projects within the pose's outlier distance
#: of the fixture and every other candidate's farther than this many times that distance.
TOLD_APART = 4.0


def told_by_pose(
    camera: Camera,
    pose: Pose,
    fixture_map: FixtureMap,
    pixels: np.ndarray,
    candidates: list[tuple[int, ...]],
    taken: set[int],
    outlier_px: float,
) -> dict[int, int]:
    """The IDs the pose tells apart among each fixture's look-alikes.

    Parameters
    ----------
    camera : Camera
        The camera (intrinsics and distortion).
    pose : Pose
        The camera's pose, solved from the decoded fixtures.
    fixture_map : FixtureMap
        The map the candidates' positions come from.
    pixels : ndarray, shape (n, 2)
        Each fixture's centre in the photo, pixels (the frame the pose was solved in).
    candidates : list of tuple of int, length n
        Each fixture's candidate IDs (empty or one: nothing to tell apart).
    taken : set of int
        IDs already given to a fixture (a map's IDs are unique: none of them is a candidate).
    outlier_px : float
        The pose's outlier distance, pixels.

    Returns
    -------
    dict
        Fixture index -> the ID whose map position alone projects onto it, for the fixtures
        told apart (each ID at most once).
    """
    told: dict[int, int] = {}
    for k, ids in enumerate(candidates):
        ids = tuple(i for i in ids if fixture_map.get(i) is not None)
        if len(ids) < 2:
            continue
        where = project_points(camera, pose, [fixture_map.get(i).position for i in ids])
        dist = np.hypot(*(where - np.asarray(pixels[k], dtype=float)).T)
        dist = np.where(np.isfinite(dist), dist, np.inf)  # behind the camera: not there
        order = np.argsort(dist)
        best = ids[int(order[0])]
        if (
            best not in taken
            and dist[order[0]] <= outlier_px
            and dist[order[1]] > TOLD_APART * outlier_px
        ):
            told[k] = best
    # an ID told for two fixtures: neither
    seen = list(told.values())
    return {k: i for k, i in told.items() if seen.count(i) == 1}
