"""Stages 4 and 5 together, identify and solve: the IDs looked up in the map and the pose
solved, the two weighed together (look-alikes and IDs read twice told by the pose, the readout
direction decided by the pose when the stripes fit both ways), then how sure the position is.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from camvlp.geometry.gravity import GravityPose
from camvlp.geometry.pose import PoseEstimate
from camvlp.model.fixtures import FixtureMap
from camvlp.model.readout import Readout
from camvlp.pipeline.decode.manchester import Manchester, decode_manchester
from camvlp.pipeline.decode.stage import Decoded, read_profiles
from camvlp.pipeline.identified import Identified, identified_as, identify
from camvlp.pipeline.identify.by_geometry import Placement, placed
from camvlp.pipeline.identify.decide import decided
from camvlp.pipeline.lights import UNCLEAR_AXIS, Lights, striped
from camvlp.pipeline.prepare import Prepared
from camvlp.pipeline.settings import LocateSettings
from camvlp.pipeline.solve import PoseProblem, finite_sigma, sigma_of, sure_enough

__all__ = ["Solved", "identify_and_solve", "readout_direction"]


@dataclass(frozen=True)
class Solved:
    """The identify and solve stages' answer (:func:`identify_and_solve`).

    Attributes
    ----------
    decodes : tuple
        Per light, its decode in the direction kept (IDs that depend on an undecided
        direction withheld).
    found : Identified
        Per light, its ID (or None) and why it cannot be used.
    est : PoseEstimate or GravityPose or None
        The pose (its ``pose`` None when refused), None when too few fixtures.
    reason : str
        Why the photo was not located ("" when it was).
    told : dict
        Light index -> the look-alike IDs the pose told it from.
    readout : Readout
        The readout the stripes were read with (the direction the pose decided).
    manchester : Manchester or None
        The Manchester decode in the direction kept.
    sigma_of : callable or None
        A function of no arguments that gives the position's standard deviation along the
        map's axes, shape (3,) (worked out when first read), or None without a position.
    fixture_map : FixtureMap or None
        In a map whose IDs repeat (``reuse``), the part of it the IDs were looked up in (the
        fixtures in view of the place :func:`~camvlp.pipeline.identify.by_geometry.placed`
        found); None otherwise (the map given).
    """

    decodes: tuple
    found: Identified
    est: PoseEstimate | GravityPose | None
    reason: str
    told: dict
    readout: Readout
    manchester: Manchester | None
    sigma_of: Callable[[], np.ndarray | None] | None = None
    fixture_map: FixtureMap | None = None


def identify_and_solve(
    prepared: Prepared,
    lights: Lights,
    decoded: Decoded,
    fixture_map: FixtureMap,
    settings: LocateSettings,
) -> Solved:
    """Stages 4 and 5: the IDs looked up, the pose solved, and the two weighed together
    (:func:`~camvlp.pipeline.identify.decide.decided`); then the position's standard
    deviation, and the pose refused when it is over ``settings.max_position_sigma``.

    In a map whose IDs repeat, the photo is first placed by its lights' IDs and geometry
    (:func:`~camvlp.pipeline.identify.by_geometry.placed`, narrowed by ``settings.near`` and
    ``settings.within``; from two lights with gravity), and the stages run on the fixtures
    in view there; a photo that cannot be placed is refused with the reason."""
    problem = PoseProblem(
        prepared.camera,
        fixture_map,
        decoded.blobs,
        settings,
        prepared.outlier_px,
        prepared.gravity,
        lights.glowing,
    )
    local, whole = None, fixture_map
    if fixture_map.reuse:
        place = _placed(problem, decoded, settings)
        if place.local is None:
            return _unplaced(problem, lights, decoded, place.reason)
        local = fixture_map = place.local
        problem = dataclasses.replace(problem, fixture_map=local)
        decoded = _without(decoded, place.withheld)
    man, kept = decided(problem, decoded.manchester, list(decoded.decodes))
    if local is not None:
        kept = dataclasses.replace(kept, found=_outside_view(kept.found, whole))
    est, reason = kept.est, kept.reason
    if lights.readout is None:
        reason = UNCLEAR_AXIS
    readout = man.readout if man is not None else (lights.readout or Readout.ROWS)
    sigma = sigma_of(problem, est, kept.found)
    position_sigma = None if sigma is None else functools.partial(finite_sigma, sigma)
    if sigma is not None and settings.max_position_sigma is not None:  # now, against the limit
        est, reason, value = sure_enough(est, sigma, settings.max_position_sigma)
        position_sigma = functools.partial(_given, value)
    return Solved(
        tuple(kept.decodes), kept.found, est, reason, kept.told, readout, man, position_sigma, local
    )


def _placed(problem: PoseProblem, decoded: Decoded, settings: LocateSettings) -> Placement:
    """:func:`~camvlp.pipeline.identify.by_geometry.placed` with the IDs read in the readout
    direction the stripes favour; when those fit no place and the stripes fit the other
    direction about as well (``manchester.other``), with that direction's IDs (the pose
    then decides the direction among the fixtures in view)."""
    place = placed(problem, decoded.decodes, settings.near, settings.within)
    man = decoded.manchester
    if place.local is None and len(place.places) <= 1 and man is not None and man.other:
        other = placed(problem, man.other, settings.near, settings.within)
        place = other if other.local is not None else place
    return place


def _without(decoded: Decoded, withheld) -> Decoded:
    """``decoded`` with the lights of ``withheld`` ((light, ID) pairs: each a light the place
    found gives a fixture whose ID another light's fixture has there) read as no ID."""
    if not withheld:
        return decoded
    decodes = list(decoded.decodes)
    for k, fid in withheld:
        decodes[k] = dataclasses.replace(
            decodes[k],
            id=None,
            reason=f"sends ID {fid}, which another light of the photo sends: the place found "
            "gives it another fixture with that ID, which the pose of so few lights does "
            "not tell apart (that light keeps the ID)",
        )
    return dataclasses.replace(decoded, decodes=tuple(decodes))


def _outside_view(found: Identified, whole: FixtureMap) -> Identified:
    """``found`` (looked up in the fixtures in view of the place found in ``whole``, a map
    whose IDs repeat) with the lights that send an ID of ``whole`` none of them has saying
    so."""
    reasons = [
        f"sends ID {i}, which no fixture in view of the place found has"
        if r == f"sends ID {i}, which is not in the map" and whole.with_id(i).size
        else r
        for i, r in zip(found.ids, found.reasons, strict=True)
    ]
    return identified_as(found.ids, reasons)


def _unplaced(problem: PoseProblem, lights: Lights, decoded: Decoded, reason: str) -> Solved:
    """The answer for a photo that a map whose IDs repeat cannot place: no pose, and each
    light whose ID the map gives to many fixtures says so."""
    fmap = problem.fixture_map
    found = identify(problem.blobs, decoded.decodes, fmap)
    reasons = [
        f"ID {i} is given to {fmap.with_id(i).size} fixtures of the map: which one is not told"
        if i is not None and fmap.with_id(i).size > 1 and d.id == i
        else r
        for i, r, d in zip(found.ids, found.reasons, decoded.decodes, strict=True)
    ]
    man = decoded.manchester
    readout = man.readout if man is not None else (lights.readout or Readout.ROWS)
    reason = UNCLEAR_AXIS if lights.readout is None else reason
    return Solved(
        tuple(decoded.decodes), identified_as(found.ids, reasons), None, reason, {}, readout, man
    )


def _given(value):
    """``value`` (what :func:`functools.partial` of it gives when called)."""
    return value


def readout_direction(
    prepared: Prepared, lights: Lights, fixture_map: FixtureMap, settings: LocateSettings
) -> Readout | None:
    """The readout's direction as one photo decides it, for a camera that does not say.

    As :func:`~camvlp.pipeline.locate.locate` decides it: by the stripes read both ways, else
    (when they fit both about equally) by which direction's IDs give a pose.  A
    frequency-coded map keeps the axis the lights' stripes show once one shows stripes (a
    frequency reads the same either way).  Returns None when the photo does not decide (the
    axis unclear, no ID read, or the directions cannot be told apart).
    """
    readout, blobs = lights.readout, lights.blobs
    if readout is None:
        return None
    if fixture_map.mode == "frequency":
        return readout if any(striped(b) for b in blobs) else None
    profiles = read_profiles(prepared.image, blobs, readout)
    camera = prepared.camera
    man = decode_manchester(
        list(profiles.profiles), readout, False, camera, fixture_map, list(profiles.weights)
    )
    if man.other is None:
        found = identify(blobs, list(man.decodes), fixture_map)
        return man.readout if found.usable else None
    problem = PoseProblem(camera, fixture_map, tuple(blobs), settings, prepared.outlier_px)
    man, kept = decided(problem, man, list(man.decodes))
    return man.readout if kept.est is not None else None
