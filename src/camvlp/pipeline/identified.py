"""Stage 4, identify: the IDs the stripes say looked up in the map."""

from __future__ import annotations

from dataclasses import dataclass

from camvlp.model.fixtures import FixtureMap

__all__ = ["TWICE", "Identified", "identified_as", "identify"]


@dataclass(frozen=True)
class Identified:
    """The identify stage: each blob's ID (or None) and why it cannot be used ("" if it can)."""

    ids: tuple[int | None, ...]
    reasons: tuple[str, ...]
    usable: tuple[int, ...]  # indices of blobs with an ID and no reason


def identified_as(ids, reasons) -> Identified:
    """The identities of blobs with these IDs (or None) and reasons ("" if usable)."""
    usable = tuple(k for k, r in enumerate(reasons) if ids[k] is not None and not r)
    return Identified(tuple(ids), tuple(reasons), usable)


def identify(blobs, decodes, fixture_map: FixtureMap) -> Identified:
    """Stage 4: IDs looked up in the map; cut discs, unknown and repeated IDs set aside."""
    reasons: list[str] = []
    ids: list[int | None] = []
    for b, dec in zip(blobs, decodes, strict=True):
        fid, reason = dec.id, dec.reason
        outside = getattr(dec, "outside_id", None)
        if fid is None and outside is not None:  # a light that sends an ID the map lacks
            ids.append(outside)
            reasons.append(f"sends ID {outside}, which is not in the map")
            continue
        if fid is not None and fixture_map.get(fid) is None:
            reason, fid = f"sends ID {dec.id}, which is not in the map", None
        elif fid is not None and b.touches_border:
            reason = "cut by the image border (its centre would be biased)"
        ids.append(dec.id if fid is None and dec.id is not None else fid)
        reasons.append(reason)
    # the same ID twice: neither can be trusted (unless a pose tells which it is:
    # :func:`_duplicates_told`)
    decoded = [i for i, r in zip(ids, reasons, strict=True) if i is not None and not r]
    for k, (i, r) in enumerate(zip(ids, reasons, strict=True)):
        if i is not None and not r and decoded.count(i) > 1:
            reasons[k] = TWICE.format(i)
    return identified_as(ids, reasons)


#: Why a fixture whose ID another fixture of the photo was read as too is not used.
TWICE = "ID {} was decoded for two fixtures"
