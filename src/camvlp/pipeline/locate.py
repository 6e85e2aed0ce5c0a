"""The whole pipeline: photograph -> fixtures -> IDs -> map -> pose (thesis chapter 5).

:func:`locate` runs the stages in order, each a public function of its own stage's module,
with the same stages as the video tracker (:mod:`camvlp.pipeline.track`) and the service:

0. :func:`~camvlp.pipeline.prepare.prepare`: the photo checked against its camera, its levels
   mapped back to light, flipped back when mirrored;
1. :func:`~camvlp.pipeline.lights.find_lights`: the lights, the readout axis their
   stripes show, each readable light centred as its look asks;
2. :func:`~camvlp.pipeline.decode.stage.read_profiles`: each light's level per sensor line;
3. :func:`~camvlp.pipeline.decode.stage.decode`: the ID or frequency each light's stripes say;
4. and 5. :func:`~camvlp.pipeline.identify.stage.identify_and_solve`: the IDs looked up in the
   map and the pose solved, weighed together;
6. :func:`~camvlp.pipeline.report.report`: every light with its ID or why it has none, the
   pose and how sure it is, and each stage's time.
"""

from __future__ import annotations

import time

import numpy as np

from camvlp.model.camera import Camera
from camvlp.model.fixtures import FixtureMap
from camvlp.model.readout import Readout
from camvlp.pipeline.decode.stage import decode, read_profiles
from camvlp.pipeline.identify.stage import identify_and_solve
from camvlp.pipeline.lights import find_lights
from camvlp.pipeline.paths import recording
from camvlp.pipeline.prepare import prepare
from camvlp.pipeline.report import report
from camvlp.pipeline.results import FixtureResult, LocateResult, LocateStages
from camvlp.pipeline.settings import DEFAULT_SETTINGS, LocateSettings, check_arguments

__all__ = ["FixtureResult", "LocateResult", "LocateSettings", "LocateStages", "locate"]


class StageClock:
    """Milliseconds per stage: :meth:`lap` after each stage takes the time since the last."""

    def __init__(self) -> None:
        self.start = self.last = time.perf_counter()
        self.ms: dict[str, float] = {}

    def lap(self, stage: str) -> None:
        """Record the time since the last lap (or the start) as ``stage``'s, ms."""
        now = time.perf_counter()
        self.ms[stage] = 1e3 * (now - self.last)
        self.last = now

    def total(self) -> dict[str, float]:
        """Each stage's time and the total, ms."""
        return {**self.ms, "total": 1e3 * (self.last - self.start)}


def locate(
    image: np.ndarray,
    camera: Camera,
    fixture_map: FixtureMap,
    settings: LocateSettings | None = None,
    *,
    gravity=None,
) -> LocateResult:
    """Locate the camera that took a photograph of a room's coded lights.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3) or (H, W)
        The photograph, BGR or gray, 8- or 16-bit, of the camera's size.
    camera : Camera
        The camera's intrinsics, distortion and (optionally) row time and readout.
    fixture_map : FixtureMap
        The room's fixtures.
    settings : LocateSettings, optional
        Tuning options (``keep_stages=True`` keeps the intermediate results).
    gravity : array_like, shape (3,), optional
        The direction of gravity in the camera's frame when the photo was taken (OpenCV axes:
        x right, y down, z forward, of the camera itself, so of a mirrored photo once flipped
        back; any length), e.g. from the phone's accelerometer.  With
        it, two or three identified fixtures are enough (``result.solver`` says how the pose
        was solved); the map's ``up`` says which way is up in its frame.

    Returns
    -------
    LocateResult
        Falsy (``position`` None, ``reason`` set) when the photo could not be located; it
        still lists every fixture found and why each one was or was not used.

    Raises
    ------
    InputError
        The image is not an image of the camera's size; gravity is not three finite numbers,
        is of zero length, or leaves the map's lights out of the camera's view (a camera
        looking along gravity, at the floor, cannot see lights that face down).
    """

    check_arguments(camera, fixture_map, settings)
    st = settings or DEFAULT_SETTINGS
    clock = StageClock()
    with recording() as paths:  # the special paths that run, and their time
        # -- 0. prepare: the photo checked, its levels mapped back to light, unmirrored ---
        prepared = prepare(image, camera, fixture_map, st, gravity)
        clock.lap("prepare")

        # -- 1. detect: the lights, the readout axis, each readable light centred ---------
        lights = find_lights(prepared, fixture_map, st)
        clock.lap("detect")

        # -- 2. profile: each light's level per sensor line --------------------------------
        profiles = read_profiles(prepared.image, lights.blobs, lights.readout or Readout.ROWS)
        clock.lap("profile")

        # -- 3. decode: the ID or frequency each light's stripes say, or why not ----------
        decoded = decode(prepared, lights, profiles, fixture_map)
        clock.lap("decode")

        # -- 4 and 5. identify and solve: IDs looked up, the pose solved, weighed together
        solved = identify_and_solve(prepared, lights, decoded, fixture_map, st)
        clock.lap("pose")

    # -- 6. report --------------------------------------------------------------------------
    return report(prepared, lights, decoded, solved, fixture_map, st, clock.total(), paths)
