"""The ways to try unread fixtures for a readout direction are counted lazily."""

from __future__ import annotations

import types

import numpy as np

from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.pipeline.identify.lookup import (
    DIRECTION_HYPOTHESES,
    Decided,
    _identified,
    _unread_hypotheses,
)


def test_many_unread_fixtures_give_the_cap_and_one_not_every_way():
    """30 unread lights, 16 IDs and 4 needed are 27,405 sets of lights times 43,680 ways to
    give them IDs: built whole, they filled 24 GB; counted lazily, the cap and one more are
    enough to know there are too many."""
    room = FixtureMap(tuple(Fixture(i, np.array([i, 0.0, 2.0]), 0.2) for i in range(16)))
    blobs = [types.SimpleNamespace(touches_border=False) for _ in range(30)]
    decodes = [types.SimpleNamespace(id=None, candidates=()) for _ in blobs]
    found = _identified([None] * 30, ["no ID"] * 30)
    d = Decided(decodes, found, None, "no pose", {})
    got = _unread_hypotheses(blobs, room, d, 4, DIRECTION_HYPOTHESES)
    assert len(got) == DIRECTION_HYPOTHESES + 1
    assert all(len(set(h.values())) == 4 and len(h) == 4 for h in got)
    few = _unread_hypotheses(
        blobs[:4],
        room,
        Decided(decodes[:4], _identified([None] * 4, ["x"] * 4), None, "", {}),
        4,
        10**9,
    )
    assert len(few) == 16 * 15 * 14 * 13  # every way when there are few
