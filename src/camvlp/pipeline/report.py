"""Stage 6, report: what :func:`~camvlp.pipeline.locate.locate` answers, every light seen with
its ID or why it has none, the pose, how sure it is, and the time each stage took."""

from __future__ import annotations

import numpy as np

from camvlp.geometry.gravity import GravityPose
from camvlp.geometry.pose import PoseEstimate
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.decode.stage import Decoded, Profiles
from camvlp.pipeline.identified import Identified
from camvlp.pipeline.identify.stage import Solved
from camvlp.pipeline.lights import Lights
from camvlp.pipeline.paths import PathTime
from camvlp.pipeline.prepare import Prepared
from camvlp.pipeline.results import FixtureResult, LocateResult, LocateStages
from camvlp.pipeline.settings import LocateSettings

__all__ = ["fixture_results", "report"]


def report(
    prepared: Prepared,
    lights: Lights,
    decoded: Decoded,
    solved: Solved,
    fixture_map: FixtureMap,
    settings: LocateSettings,
    timing_ms: dict[str, float],
    paths: dict[str, PathTime] | None = None,
) -> LocateResult:
    """Stage 6: the :class:`~camvlp.pipeline.results.LocateResult` of the stages' answers
    (pixels in the photo as given, mirrored back), with ``timing_ms`` (milliseconds per
    stage), ``paths`` (the special paths that ran, :mod:`camvlp.pipeline.paths`) and, with
    ``settings.keep_stages``, the intermediate results."""
    est, man = solved.est, solved.manchester
    pose = est.pose if est is not None else None
    gravity = isinstance(est, GravityPose)
    fixtures = fixture_results(
        decoded.blobs,
        solved.decodes,
        solved.found,
        est,
        decoded.profiles.extents,
        decoded.frequencies,
        prepared.shown,
        4 if prepared.gravity is None else 2,
        solved.told,
        fixture_map if solved.fixture_map is None else solved.fixture_map,
    )
    nan = float("nan")
    return LocateResult(
        position=None if pose is None else pose.position,
        rotation=None if pose is None else pose.world_from_camera,
        euler_deg=None if pose is None else pose.euler_deg,
        reprojection_rms_px=float(est.reprojection_rms_px) if pose is not None else nan,
        fixtures=fixtures,
        timing_ms=timing_ms,
        paths=dict(paths or {}),
        reason=solved.reason,
        readout=solved.readout,
        mirrored=prepared.mirrored,
        rows_per_chip=nan if man is None else man.rows_per_chip,
        exposure_chips=nan if man is None else man.exposure_chips,
        alternative_position=None
        if est is None or est.alternative is None
        else est.alternative.position,
        alternative_rms_px=nan if est is None else est.alternative_rms_px,
        pose_margin=float(getattr(est, "margin", nan)) if est is not None else nan,
        notes=prepared.notes + lights.notes + decoded.notes,
        stages=_stages(lights, decoded.profiles, decoded, solved) if settings.keep_stages else None,
        solver=est.solver if gravity else ("pnp" if prepared.gravity is None else "gravity"),
        tilt_disagreement_deg=est.tilt_disagreement_deg if gravity and pose is not None else nan,
        gravity_residual_deg=est.gravity_residual_deg if gravity and pose is not None else nan,
        sigma_of=solved.sigma_of,
    )


def _stages(lights: Lights, profiles: Profiles, decoded: Decoded, solved: Solved) -> LocateStages:
    """The intermediate results, for debug pictures: the profiles in the order the sensor read
    them (the direction the pose decided)."""
    rows = profiles.profiles
    if lights.readout is not None and solved.readout != lights.readout:
        rows = tuple(p[::-1] for p in rows)
    return LocateStages(
        lights.detection,
        profiles.gray_rois,
        rows,
        solved.decodes,
        profiles.weights,
        decoded.beacons,
    )


def fixture_results(
    blobs,
    decodes,
    found: Identified,
    est: PoseEstimate | GravityPose | None,
    extents: np.ndarray,
    frequencies: np.ndarray,
    shown,
    needed: int = 4,
    told: dict[int, tuple[int, ...]] | None = None,
    fixture_map: FixtureMap | None = None,
) -> tuple[FixtureResult, ...]:
    """Every fixture seen, identified or not, with why it was not used.  A
    fixture's ``id`` is one of the map's or None: an ID read that the map lacks, or that the
    pose does not vouch for, is told in its reason only."""
    results = []
    at = {k: j for j, k in enumerate(found.usable)}  # a usable fixture's place in the pose's
    posed = est is not None and est.pose is not None
    if posed:  # (as Python bools and floats, once)
        used_by_pose, residuals = est.used.tolist(), est.residuals_px.tolist()
    for k, (b, dec) in enumerate(zip(blobs, decodes, strict=True)):
        reason = found.reasons[k]
        fid = found.ids[k]
        if fid is not None and fixture_map is not None and fixture_map.get(fid) is None:
            fid = None  # (its reason says what it sends)
        used = False
        residual = float("nan")
        j = at.get(k)
        if j is not None:
            if posed:
                used, residual = used_by_pose[j], residuals[j]
                if not used:  # the pose does not vouch for its ID: none reported
                    reason = (
                        f"read as ID {fid}, which does not fit the pose of the others "
                        f"({residual:.1f} px off)"
                    )
                    fid = None
            elif est is not None:
                reason = "no pose"
            else:
                reason = f"fewer than {needed} usable fixtures"
        results.append(
            FixtureResult(
                id=fid,
                pixel=shown(b.pixel),
                used=used,
                margin=dec.margin,
                reason=reason,
                hamming=dec.hamming,
                run_margin=dec.run_margin,
                rows_spanned=float(extents[k]),
                rows_per_chip=dec.rows_per_chip,
                residual_px=residual,
                frequency_hz=float(frequencies[k]),
                edge_fit=b.edge_fit,
                look_alikes=(told or {}).get(k, ()),
            )
        )
    return tuple(results)
