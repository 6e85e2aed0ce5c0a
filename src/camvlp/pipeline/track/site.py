"""The video tracker in a map whose IDs repeat (``FixtureMap.reuse``): which fixture an ID
names.

In such a map an ID names many fixtures.  The tracker (:mod:`camvlp.pipeline.track.tracker`)
works on the site's fixtures around the camera, each ID once (a map of its own, its IDs
unique), chosen frame by frame:

* while the track knows the pose, those the predicted pose puts in the picture or near it
  (:meth:`SiteView.around_pose`; where two fixtures of one ID are there, the one in the
  picture, else neither);
* otherwise (the first frame, or after the track was lost), those in view of the place the
  frame's lights give by their IDs and arrangement, as :func:`camvlp.locate` places a photo
  (:meth:`SiteView.placed`): five lights with an ID or more, looked for near the last place
  the track knew first (as far as the camera can have gone since, at
  ``TrackSettings.relocate_speed_m_s``), and before the track knew any, near the prior given
  (``LocateSettings.near`` and ``within``); a frame no place fits is not located, and says
  why.

When the fixture an ID names changes, what the tracker remembered of that ID is forgotten
(:func:`changed_ids`).
"""

from __future__ import annotations

import numpy as np

from camvlp.geometry.projection import in_view
from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.identify.by_geometry import Placement, placed
from camvlp.pipeline.identify.placement import view_map
from camvlp.pipeline.prepare import Prepared
from camvlp.pipeline.solve import PoseProblem
from camvlp.pipeline.track.records import TrackSettings

__all__ = ["RELOCATE_MARGIN_M", "SiteView", "changed_ids"]

#: How far from the track's last place a frame placed anew is looked for, besides how far the
#: camera can have gone since, metres: the last place's error and a step.
RELOCATE_MARGIN_M = 0.5


class SiteView:
    """The fixtures of a site (a map whose IDs repeat) that the track's IDs name.

    Parameters
    ----------
    camera : Camera
        The video's camera.
    site : FixtureMap
        The whole map (``reuse`` True).
    settings : TrackSettings
        The tracker's settings (the prior of its ``locate`` settings, ``relocate_within_m``).

    Attributes
    ----------
    last : ndarray, shape (3,), or None
        The camera's position when the track last had a pose, map units.
    last_t : float or None
        That frame's time, s.
    """

    def __init__(self, camera: Camera, site: FixtureMap, settings: TrackSettings) -> None:
        self.camera = camera
        self.site = site
        self.settings = settings
        self.last: np.ndarray | None = None
        self.last_t: float | None = None
        # a fixture shows when its disc does: the sphere about its centre of its radius
        self._reach = 0.5 * np.nan_to_num(site.diameters, nan=0.0)

    def around_pose(self, pose: Pose) -> FixtureMap:
        """The fixtures ``pose`` (map frame and units) puts in the picture or within a tenth
        of its width of it, each ID once (:func:`~camvlp.pipeline.identify.placement.view_map`)."""
        margin = 0.1 * self.camera.width
        seen = in_view(self.camera, pose, self.site.positions, self._reach, margin_px=margin)
        return view_map(self.site, self.camera, pose, np.flatnonzero(seen))

    def placed(
        self, prepared: Prepared, blobs, decodes, t: float, glowing: tuple[bool, ...] = ()
    ) -> Placement:
        """Where the frame's lights (``blobs`` and their ``decodes``; ``glowing``, one flag
        each when told: see :class:`~camvlp.pipeline.solve.PoseProblem`) place the camera in
        the site at time ``t`` (s): near the last place the track knew first (within
        :data:`RELOCATE_MARGIN_M` and ``relocate_speed_m_s`` times the time since), then
        anywhere; before the track knew any, near the prior given only (the locate
        settings' ``near`` and ``within``), else anywhere."""
        st = self.settings.locate
        problem = PoseProblem(
            prepared.camera,
            self.site,
            tuple(blobs),
            st,
            prepared.outlier_px,
            prepared.gravity,
            tuple(glowing),
        )
        if self.last is not None:
            gone = RELOCATE_MARGIN_M + self.settings.relocate_speed_m_s * (t - self.last_t)
            near = placed(problem, decodes, self.last, gone / self.site.unit_m)
            if near.local is not None:
                return near
        elif st.near is not None:
            return placed(problem, decodes, st.near, st.within)
        return placed(problem, decodes)


def changed_ids(old: FixtureMap, new: FixtureMap) -> set[int]:
    """The IDs of ``old`` that name another fixture in ``new``, or none (a fixture is its
    position); every ID of ``old`` that names more than one fixture there."""
    out = set()
    for fid in old.distinct_ids:
        a, b = old.with_id(fid), new.with_id(fid)
        same = a.size == 1 and b.size == 1
        if not (same and np.array_equal(old.positions[a[0]], new.positions[b[0]])):
            out.add(fid)
    return out
