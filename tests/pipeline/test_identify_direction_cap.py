"""The ways to try unread fixtures for a readout direction are counted lazily."""

from __future__ import annotations

import types

import numpy as np

from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.pipeline.identified import identified_as
from camvlp.pipeline.identify.decide import DIRECTION_HYPOTHESES, Decided, unread_hypotheses
from camvlp.pipeline.solve import PoseProblem


def _problem(room: FixtureMap, blobs: list) -> PoseProblem:
    """A pose problem of these lights in this room (no camera needed to count the ways)."""
    return PoseProblem(None, room, tuple(blobs), None, 0.0)


def test_many_unread_fixtures_give_the_cap_and_one_not_every_way():
    """30 unread lights, 16 IDs and 4 needed are 27,405 sets of lights times 43,680 ways to
    give them IDs: built whole, they filled 24 GB; counted lazily, the cap and one more are
    enough to know there are too many."""
    room = FixtureMap(tuple(Fixture(i, np.array([i, 0.0, 2.0]), 0.2) for i in range(16)))
    blobs = [types.SimpleNamespace(touches_border=False) for _ in range(30)]
    decodes = [types.SimpleNamespace(id=None, candidates=()) for _ in blobs]
    found = identified_as([None] * 30, ["no ID"] * 30)
    d = Decided(decodes, found, None, "no pose", {})
    got = unread_hypotheses(_problem(room, blobs), d, DIRECTION_HYPOTHESES)
    assert len(got) == DIRECTION_HYPOTHESES + 1
    assert all(len(set(h.values())) == 4 and len(h) == 4 for h in got)
    few = unread_hypotheses(
        _problem(room, blobs[:4]),
        Decided(decodes[:4], identified_as([None] * 4, ["x"] * 4), None, "", {}),
        10**9,
    )
    assert len(few) == 16 * 15 * 14 * 13  # every way when there are few
