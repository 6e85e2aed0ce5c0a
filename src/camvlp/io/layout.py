"""A site's layout: the map of its fixtures before they have IDs (``camvlp assign-ids``)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from camvlp.errors import InputError
from camvlp.io.files import map_from_dict
from camvlp.io.textfiles import read_mapping
from camvlp.model.fixtures import FixtureMap

__all__ = ["load_layout", "with_ids"]


def load_layout(path: str | Path) -> FixtureMap:
    """A map file whose fixtures need no ``id`` (those it has are kept until replaced): a
    Manchester map whose IDs repeat (``reuse``), each fixture without one given ID 0.

    Raises
    ------
    InputError
        As :func:`~camvlp.io.files.load_map`; a frequency-coded map (its fixtures are told
        apart by frequency, not by IDs).
    """
    data = dict(read_mapping(path, "layout"))
    frame = dict(data.get("frame") or {})
    if str(frame.get("mode", frame.get("line_code", "manchester"))).lower() != "manchester":
        raise InputError("a layout's fixtures send Manchester frames (not frequencies)", path)
    frame["reuse"] = True
    data["frame"] = frame
    fixtures = data.get("fixtures")
    if isinstance(fixtures, list):
        data["fixtures"] = [
            {"id": 0, **e} if isinstance(e, dict) and "id" not in e else e for e in fixtures
        ]
    return map_from_dict(data, Path(path))


def with_ids(site: FixtureMap, ids: np.ndarray) -> FixtureMap:
    """``site`` with fixture ``k`` given ``ids[k]`` (reused IDs: ``reuse`` set)."""
    fixtures = tuple(
        dataclasses.replace(f, id=int(i)) for f, i in zip(site.fixtures, ids, strict=True)
    )
    return dataclasses.replace(site, fixtures=fixtures, reuse=True)
