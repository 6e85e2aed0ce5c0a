"""Stages 4 and 5's decisions: look-alikes and IDs read twice told by the pose, and the readout
direction decided by the pose when the stripes fit both directions.

Each set of IDs weighed is solved as the photo's :class:`~camvlp.pipeline.solve.PoseProblem`
says (with or without gravity), so these decisions are the same either way.
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass

import numpy as np

from camvlp.geometry.gravity import GravityPose
from camvlp.geometry.pose import PoseEstimate
from camvlp.geometry.pose_sigma import pose_covariance
from camvlp.model.camera import project_points
from camvlp.model.readout import Readout
from camvlp.pipeline.decode.manchester import Manchester
from camvlp.pipeline.identified import TWICE, Identified, identified_as, identify
from camvlp.pipeline.identify.by_pose import Spread, assigned_by_pose, told_by_pose
from camvlp.pipeline.solve import PoseProblem

__all__ = ["Decided", "decided", "identified", "with_told"]


def _duplicates_told(problem: PoseProblem, found: Identified, est):
    """An ID read for two fixtures (a light that sends data, a reflection), told by the pose:
    the pose the others give, where they give one, else each claimant's own pose with them
    (too few without it); the one fixture that fits (within ``outlier_px`` of the ID's map
    position) keeps the ID, the others are refused with no ID, and the pose is solved again.
    ``found`` and ``est`` as given when no one fixture fits."""
    camera, fixture_map, blobs = problem.camera, problem.fixture_map, problem.blobs
    twice = [k for k, r in enumerate(found.reasons) if r == TWICE.format(found.ids[k])]
    if not twice:
        return found, est
    posed = est is not None and est.pose is not None
    ids, reasons = list(found.ids), list(found.reasons)
    for fid in sorted({found.ids[k] for k in twice}):
        claims = [k for k in twice if found.ids[k] == fid]
        if posed:
            where = camera.project(est.pose, fixture_map.get(fid).position[None, :])[0]
            off = {k: float(np.hypot(*(blobs[k].pixel - where))) for k in claims}
        else:  # each claimant with the others: does its pose take it?
            off = {k: _claimant_fit(problem, found, k, claims) for k in claims}
        near = [k for k in claims if off[k] <= problem.outlier_px]
        if len(near) != 1:
            continue
        for k in claims:
            if k == near[0]:
                reasons[k] = ""
            else:  # not the ID's fixture: no ID
                ids[k] = None
                reasons[k] = (
                    f"read as ID {fid}, which the pose puts {off[k]:.0f} px away: another "
                    "fixture of the photo is it"
                    if np.isfinite(off[k])
                    else f"read as ID {fid}, which another fixture of the photo is (by the pose)"
                )
    told = identified_as(ids, reasons)
    if told.usable == found.usable:
        return found, est
    est2, _ = problem.solve(told)
    return (told, est2) if est2 else (found, est)


def _claimant_fit(problem: PoseProblem, found: Identified, k: int, claims: list[int]) -> float:
    """How far (pixels) the pose of the usable fixtures and fixture ``k``, given the ID the
    ``claims`` share, puts ``k`` from it (its reprojection error); inf without such a pose
    or where the pose drops a fixture."""
    reasons = [
        "" if j == k else ("another fixture claims this ID" if j in claims else r)
        for j, r in enumerate(found.reasons)
    ]
    trial = identified_as(list(found.ids), reasons)
    e, _ = problem.solve(trial)
    if not e or not all(e.used):
        return float("inf")
    return float(e.residuals_px[trial.usable.index(k)])


def with_told(problem: PoseProblem, decodes, found: Identified, est):
    """Fixtures the stripes leave between look-alike IDs, told apart by the pose
    (:mod:`camvlp.pipeline.identify.by_pose`; when the identified ones are too few for a pose,
    by the only assignment of look-alikes that gives one, whose pose then tells the others) and the
    pose solved again with them.
    Returns ``found, est, told`` (``told``: fixture index -> its candidate IDs); as given
    when none is told."""
    camera, fixture_map, blobs = problem.camera, problem.fixture_map, problem.blobs
    if est is not None and est.pose is None:
        return found, est, {}
    # (a disc cut by the border is told by a pose, never a seed of one)
    cands = [
        getattr(d, "candidates", ()) if i is None and (est or not b.touches_border) else ()
        for b, d, i in zip(blobs, decodes, found.ids, strict=True)
    ]
    if not any(len(c) >= 2 for c in cands):
        return found, est, {}
    pixels = np.array([b.pixel for b in blobs]).reshape(-1, 2)
    fixed = {k: found.ids[k] for k in found.usable}
    if est is not None:
        return _told_round_by_round(problem, pixels, fixed, found, est, cands)

    def pose_of(assigned: dict[int, int]):
        e, _ = problem.solve(_given(found, assigned))
        return e.pose if e and all(e.used) else None

    unread = [i is None and not b.touches_border for b, i in zip(blobs, found.ids, strict=True)]
    told = assigned_by_pose(
        camera,
        fixture_map,
        pixels,
        fixed,
        cands,
        problem.outlier_px,
        pose_of,
        problem.needed,
        unread,
    )
    if not told:
        return found, est, {}
    found2 = _given(found, {**fixed, **told})
    est2, _ = problem.solve(found2)
    if not est2 or not all(est2.used[found2.usable.index(k)] for k in told):
        return found, est, {}
    # the look-alikes left, told by that pose as by one the stripes gave (round by round,
    # with what the pose and their centres are unsure of)
    left = [
        getattr(d, "candidates", ()) if i is None else ()
        for d, i in zip(decodes, found2.ids, strict=True)
    ]
    found3, est3, more = _told_round_by_round(
        problem, pixels, {**fixed, **told}, found2, est2, left
    )
    return found3, est3, {**{k: cands[k] for k in told}, **more}


def _spread(problem: PoseProblem, found: Identified, est) -> Spread:
    """The pose's and the centres' uncertainty (:class:`~camvlp.pipeline.identify.by_pose.Spread`),
    the pose's from the fixtures it uses."""
    camera, fixture_map, blobs = problem.camera, problem.fixture_map, problem.blobs
    used = [k for j, k in enumerate(found.usable) if est.used[j]]
    points = np.array([fixture_map.get(found.ids[k]).position for k in used]).reshape(-1, 3)
    pixels = np.array([blobs[k].pixel for k in used]).reshape(-1, 2)
    return Spread(
        pose_covariance(camera, est.pose, points, pixels),
        np.array([b.centre_sigma_px for b in blobs], dtype=float),
        np.array([0.5 * float(np.min(b.axes_px)) for b in blobs]),
    )


def _told_round_by_round(problem: PoseProblem, pixels, fixed, found, est, cands):
    """Look-alikes told by the pose of the identified fixtures (:func:`with_told`), the pose
    solved again with those told and the others told by it, until none is left to tell.

    A round is kept when its pose uses as many fixtures as the pose before it, or more.  A
    fixture told whose centre lies beyond the pose's outlier distance from where its ID
    projects (a glowing lamp's centre may be tens of pixels off) keeps its ID, left out of
    the pose with that reason (within its tolerance, see
    :func:`~camvlp.pipeline.identify.by_pose.told_by_pose`, it would otherwise pull the pose).
    ``pixels`` (n, 2) are the blobs' centres, ``fixed`` the identified fixtures (index -> ID)."""
    camera, fixture_map, blobs = problem.camera, problem.fixture_map, problem.blobs
    outlier_px = problem.outlier_px
    told: dict[int, int] = {}
    near: dict[int, int] = {}
    far: dict[int, str] = {}
    cur_found, cur_est = found, est
    while True:
        left = [() if k in told else c for k, c in enumerate(cands)]
        spread = _spread(problem, cur_found, cur_est)
        taken = set(fixed.values()) | set(told.values())
        new = told_by_pose(
            camera, cur_est.pose, fixture_map, pixels, left, taken, outlier_px, spread
        )
        if not new:
            break
        where = project_points(
            camera, cur_est.pose, [fixture_map.get(i).position for i in new.values()]
        )
        off = dict(zip(new, np.hypot(*(where - pixels[list(new)]).T).tolist(), strict=True))
        add = {k: i for k, i in new.items() if off[k] <= outlier_px and not blobs[k].touches_border}
        nxt, est2 = _given(found, {**fixed, **near, **add}), cur_est
        if add:
            est2, _ = problem.solve(nxt)
            if not est2 or int(np.sum(est2.used)) < int(np.sum(cur_est.used)):
                break
        told.update(new)
        near.update(add)
        for k in set(new) - set(add):
            far[k] = f"told by the pose from its look-alikes, {off[k]:.1f} px from where ID " + (
                f"{new[k]} projects; cut by the image border (its centre would be biased)"
                if blobs[k].touches_border
                else f"{new[k]} projects (beyond the outlier distance): not used"
            )
        cur_found, cur_est = nxt, est2
        if not add:  # the same pose: nothing more to tell
            break
    ids, reasons = list(cur_found.ids), list(cur_found.reasons)
    for k, why in far.items():
        ids[k], reasons[k] = told[k], why
    return identified_as(ids, reasons), cur_est, {k: cands[k] for k in told}


def _given(found: Identified, ids: dict[int, int]) -> Identified:
    """``found`` with the fixtures of ``ids`` (index -> ID) given those IDs, and only they
    and those already usable usable."""
    new = [ids.get(k, i) for k, i in enumerate(found.ids)]
    reasons = ["" if k in ids else r for k, r in enumerate(found.reasons)]
    return identified_as(new, reasons)


def _same_answer(a: Identified, b: Identified) -> bool:
    return [a.ids[k] for k in a.usable] == [b.ids[k] for k in b.usable] and a.usable == b.usable


def _pick_direction(est1, est2, found1: Identified, found2: Identified) -> int:
    """Which direction's pose to keep (1 or 2); 0 when both fit and cannot be told apart,
    -1 when neither gives a pose."""
    ok1, ok2 = bool(est1), bool(est2)
    if _same_answer(found1, found2):
        return 1
    if ok1 != ok2:
        return 1 if ok1 else 2
    if not ok1:
        return -1  # neither locates
    n1, n2 = int(np.sum(est1.used)), int(np.sum(est2.used))
    r1, r2 = est1.reprojection_rms_px, est2.reprojection_rms_px
    if n1 > n2 and r1 <= r2:
        return 1
    if n2 > n1 and r2 <= r1:
        return 2
    if r1 * 5 < r2:
        return 1
    if r2 * 5 < r1:
        return 2
    return 0


@dataclass(frozen=True)
class Decided:
    """One direction's decodes, identities, pose (or None), why it failed, and the fixtures
    told by the pose (internal)."""

    decodes: list
    found: Identified
    est: PoseEstimate | GravityPose | None
    reason: str
    told: dict[int, tuple[int, ...]]


def identified(problem: PoseProblem, decodes: list) -> Decided:
    """Stages 4 and 5 for one readout direction: the IDs looked up, the pose solved, IDs read
    twice and look-alikes told by the pose."""
    found = identify(problem.blobs, decodes, problem.fixture_map)
    est, reason = problem.solve(found)
    found, est = _duplicates_told(problem, found, est)
    found, est, told = with_told(problem, decodes, found, est)
    return Decided(decodes, found, est, "" if est else reason, told)


def _withheld(decodes, decodes2) -> list:
    """The decodes with every ID that depends on the readout direction withheld."""

    def shown(d):
        return d.id if d.id is not None else getattr(d, "outside_id", None)

    def withheld(d1, d2):
        reason = f"readout direction undecided: ID {shown(d1)} read one way, {shown(d2)} the other"
        extra = {"outside_id": None} if hasattr(d1, "outside_id") else {}
        return dataclasses.replace(d1, id=None, reason=reason, **extra)

    return [
        withheld(d1, d2) if shown(d1) != shown(d2) else d1
        for d1, d2 in zip(decodes, decodes2, strict=True)
    ]


#: Most assignments of unread fixtures :func:`_direction_by_unread` tries (both directions
#: together).  A wrong assignment of four fixtures fits a pose by chance about once in 500
#: (8 of 3993 on the stress benchmark's scenes, seed 11: three fixtures' IDs permuted, the
#: fourth any other ID of the map), so a handful keeps the chance of a wrong direction
#: confirmed within a few per cent, and a wrong ID needs the right direction's fixtures not
#: to fit as well.
DIRECTION_HYPOTHESES = 8


def unread_hypotheses(problem: PoseProblem, d: Decided, limit: int) -> list[dict]:
    """Direction ``d``'s identified fixtures and, for as many of its unread fixtures (no ID,
    not cut by the border) as a pose needs besides, an ID each: its look-alikes when the
    stripes list some, else any ID of the map not identified that way; every way, or the
    first ``limit`` + 1 when there are more (a photo of many unread lights has billions)."""
    blobs, fixture_map, needed = problem.blobs, problem.fixture_map, problem.needed
    found = d.found
    fixed = {k: found.ids[k] for k in found.usable}
    m = needed - len(fixed)
    free = [
        k
        for k, (b, i) in enumerate(zip(blobs, found.ids, strict=True))
        if i is None and not b.touches_border
    ]
    if m <= 0 or len(free) < m:
        return []
    taken = set(fixed.values())
    rest = [f.id for f in fixture_map.fixtures if f.id not in taken]

    def options(k: int) -> list[int]:
        c = getattr(d.decodes[k], "candidates", ())
        return [i for i in c if i not in taken] if len(c) >= 2 else rest

    ways = (
        {**fixed, **dict(zip(seeds, ids, strict=True))}
        for seeds in itertools.combinations(free, m)
        for ids in itertools.product(*(options(k) for k in seeds))
        if len(set(ids)) == m
    )
    return list(itertools.islice(ways, limit + 1))


def _direction_by_unread(problem: PoseProblem, one: Decided, two: Decided) -> int:
    """1 or 2, the direction whose IDs, with the fixtures whose stripes it could not read,
    give a pose (when neither direction's IDs alone are enough); 0 when both or neither do,
    or when the ways to try are more than :data:`DIRECTION_HYPOTHESES`.

    An unread fixture is still one of the map's: given one of the IDs left (its look-alikes
    when it has some), the pose that fits every fixture says that direction's IDs are
    where the map has them.  Read the wrong way, the IDs are the reverses' and their
    places are not where the map has them (the pose fits no assignment)."""
    hyps = [unread_hypotheses(problem, d, DIRECTION_HYPOTHESES) for d in (one, two)]
    if not 0 < len(hyps[0]) + len(hyps[1]) <= DIRECTION_HYPOTHESES:
        return 0

    def fits(d: Decided, given: dict[int, int]) -> bool:
        e, _ = problem.solve(_given(d.found, given))
        return bool(e) and bool(np.all(e.used))

    ok = [any(fits(d, h) for h in hs) for d, hs in zip((one, two), hyps, strict=True)]
    return 0 if ok[0] == ok[1] else (1 if ok[0] else 2)


def _direction_by_pose(problem: PoseProblem, man: Manchester, one: Decided):
    """The direction whose IDs give a pose, when the stripes fit both about equally (when
    neither gives one alone, the direction whose IDs with its unread fixtures do:
    :func:`_direction_by_unread`); else no pose and every ID that depends on the direction
    withheld.  Returns ``man`` and the :class:`Decided` of the direction kept
    (``man.readout`` says which)."""
    two = identified(problem, list(man.other))
    pick = _pick_direction(one.est, two.est, one.found, two.found)
    if pick == -1:
        pick = _direction_by_unread(problem, one, two) or -1
    if pick == 2:
        flipped = Readout.of(man.readout.axis, not man.readout.reversed)
        man = Manchester(tuple(two.decodes), flipped, man.rows_per_chip, man.other_model)
        return man, two
    if pick == 1:
        return man, one
    # undecided: no ID that depends on the direction is reported, and no pose
    decodes = _withheld(one.decodes, two.decodes)
    reason = (
        "readout direction ambiguous: read either way, the stripes give IDs of the map "
        "that fit a pose; give the camera's readout (e.g. rows or rows-reversed)"
        if pick == 0
        else f"{one.reason} (and the readout direction is undecided)"
    )
    found = identify(problem.blobs, decodes, problem.fixture_map)
    return man, Decided(decodes, found, None, reason, {})


def decided(problem: PoseProblem, man: Manchester | None, decodes: list):
    """Stages 4 and 5 (:func:`identified`); when the stripes fit both readout directions
    about equally (``man.other``: IDs whose reversed frames are other IDs'), the direction
    whose IDs give a pose decides (also with the fixtures whose stripes were not read), else
    the photo is refused.  Returns ``man`` and the :class:`Decided` of the direction kept
    (``man.readout`` says which)."""
    one = identified(problem, decodes)
    if man is not None and man.other is not None:
        return _direction_by_pose(problem, man, one)
    return man, one
