"""Fixture association for the video tracker (:mod:`camvlp.pipeline.track.tracker`).

Each blob of a frame gets an ID from its decoded stripes when the track's prediction of that
fixture agrees (a decoded ID far from where the track puts that fixture is refused), else the
ID of the one predicted fixture within a gate of it when no other prediction is nearly as
close (the ID is carried over).  IDs are never swapped between fixtures.
"""

from __future__ import annotations

import numpy as np

from camvlp.model.fixtures import FixtureMap

__all__ = ["associate", "known_blobs", "predicted_near"]


def associate(
    blobs,
    found_ids,
    found_reasons,
    predicted: dict[int, np.ndarray],
    fixture_map: FixtureMap,
    gate: float,
    ambiguity: float,
) -> tuple[list[int | None], list[str], list[str]]:
    """IDs per blob (decoded, carried or None), their sources, and reasons.

    Parameters
    ----------
    blobs : sequence of Blob
        The frame's blobs (``pixel``, ``axes_px``, ``touches_border``).
    found_ids, found_reasons : sequence
        Per blob, the decoded ID (or None) and the reason it has none ("" when decoded).
    predicted : dict of int to ndarray, shape (2,)
        Each map fixture's predicted pixel.
    fixture_map : FixtureMap
    gate : float
        Largest distance from a prediction to its blob, pixels.
    ambiguity : float
        A rival prediction (or blob) within ``ambiguity`` times the nearest distance makes the
        carried ID ambiguous.
    """
    n = len(blobs)
    ids: list[int | None] = [None] * n
    sources = [""] * n
    reasons = list(found_reasons)
    pred_ids = list(predicted)
    pred_px = np.array([predicted[i] for i in pred_ids]).reshape(-1, 2)
    pixels = np.array([b.pixel for b in blobs]).reshape(-1, 2)
    dist = np.linalg.norm(pixels[:, None, :] - pred_px[None, :, :], axis=2)  # (n, m)
    # decoded IDs, checked against the prediction
    for k in range(n):
        fid = found_ids[k]
        decoded = fid is not None and (not found_reasons[k] or blobs[k].touches_border)
        if not decoded or fixture_map.get(fid) is None:
            continue
        if fid in predicted:
            d = dist[k, pred_ids.index(fid)]
            if d > gate + _cut_slack(blobs[k]):
                reasons[k] = f"decoded ID {fid}, but the track puts that fixture {d:.0f} px away"
                continue
        ids[k], sources[k] = fid, "decoded"
        if reasons[k].startswith("ID ") and "decoded for two" in reasons[k]:
            reasons[k] = ""
    # the same ID decoded twice: keep neither
    for k in range(n):
        if ids[k] is not None and sum(i == ids[k] for i in ids) > 1:
            reasons[k] = f"ID {ids[k]} was decoded for two fixtures"
    for k in range(n):
        if reasons[k].startswith(f"ID {ids[k]} was decoded for two"):
            ids[k], sources[k] = None, ""
    slack = np.array([_cut_slack(b) for b in blobs])
    _carry(ids, sources, reasons, dist, pred_ids, gate + slack, ambiguity)
    for k in range(n):
        if ids[k] is not None:
            border = blobs[k].touches_border
            reasons[k] = "cut by the image border (its centre would be biased)" if border else ""
    return ids, sources, reasons


def _cut_slack(blob) -> float:
    """How much farther than the gate a light may lie from its fixture's prediction, pixels:
    half its outline's larger axis when the border cuts it (a cut disc's centre is off by up
    to its radius), else 0."""
    return 0.5 * float(np.max(blob.axes_px)) if blob.touches_border else 0.0


def _carry(ids, sources, reasons, dist, pred_ids, gate: np.ndarray, ambiguity: float) -> None:
    """Carried IDs, in place: the one prediction within each blob's gate (pixels, one a
    blob), no rival nearly as close."""
    n = len(ids)
    claimed = {i for i in ids if i is not None}
    for k in range(n):
        if ids[k] is not None or dist.shape[1] == 0:
            continue
        order = np.argsort(dist[k])
        j = int(order[0])
        d = dist[k, j]
        fid = pred_ids[j]
        if d > gate[k]:
            continue
        if order.size > 1 and dist[k, order[1]] < ambiguity * max(d, 1.0):
            reasons[k] = reasons[k] or "ambiguous: two fixtures are predicted near it"
            continue
        others = [q for q in range(n) if q != k and ids[q] is None]
        if any(dist[q, j] < ambiguity * max(d, 1.0) for q in others):
            reasons[k] = reasons[k] or "ambiguous: two blobs near one predicted fixture"
            continue
        if fid in claimed:
            continue
        ids[k], sources[k] = fid, "carried"
        claimed.add(fid)


def known_blobs(
    blobs,
    predicted: dict[int, np.ndarray],
    verified: dict[int, int],
    index: int,
    verify_every: int,
    gate: float,
    ambiguity: float,
) -> set[int]:
    """Indices of the blobs whose ID the track already knows.

    Each is near the one prediction of a fixture (:func:`predicted_near`: within ``gate``
    pixels, plus half its outline for a light the border cuts, no rival within
    ``ambiguity`` times as far) whose stripes were decoded in the last ``verify_every``
    frames (``verified``: fixture ID -> frame index of its last decode, ``index`` the
    current frame's).  Their stripes need not be decoded again: a light entering or leaving
    the picture is not decoded frame after frame while the border cuts it (it is not used).
    """
    known = set()
    for k, b in enumerate(blobs):
        fid = predicted_near(b, predicted, gate, ambiguity)
        last = None if fid is None else verified.get(fid)
        if last is not None and index - last < verify_every:
            known.add(k)
    return known


def predicted_near(blob, predicted: dict[int, np.ndarray], gate: float, ambiguity: float):
    """The fixture predicted near a blob: the only prediction within ``gate`` pixels of it
    (plus half its outline's larger axis when it touches the border: a cut disc's outline
    centre is off by up to its radius), no rival within ``ambiguity`` times as far; None
    when there is none or the nearest has such a rival."""
    if not predicted:
        return None
    pred_ids = list(predicted)
    d = np.linalg.norm(np.array([predicted[i] for i in pred_ids]) - blob.pixel, axis=1)
    order = np.argsort(d)
    j = int(order[0])
    if d[j] > gate + _cut_slack(blob):
        return None
    if order.size > 1 and d[order[1]] < ambiguity * max(d[j], 1.0):
        return None
    return pred_ids[j]
