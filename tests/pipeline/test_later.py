"""Fields worked out when first read (:mod:`camvlp.pipeline.later`)."""

from __future__ import annotations

import dataclasses
import pickle
from dataclasses import dataclass

import numpy as np
import pytest

from camvlp.pipeline.later import Later, LaterField, later_of

CALLS: list[int] = []


def _costly(x: float) -> float:
    CALLS.append(1)
    return 2.0 * x


@dataclass(frozen=True)
class Thing:
    name: str
    value: float = LaterField(float("nan"))  # a descriptor: read per instance
    cov: np.ndarray = LaterField(missing=lambda: np.full((2, 2), np.nan))  # noqa: RUF009


@pytest.fixture(autouse=True)
def _no_calls():
    CALLS.clear()


def test_a_value_given_is_the_value_and_a_later_one_is_worked_out_once():
    assert Thing("a", 3.0).value == 3.0
    assert np.isnan(Thing("a").value)
    t = Thing("b", Later(_costly, 4.0))
    assert CALLS == []  # not at construction
    assert t.value == 8.0 and t.value == 8.0
    assert CALLS == [1]  # once, then kept


def test_missing_gives_a_fresh_default_each_time():
    t = Thing("a")
    first = t.cov
    first[0, 0] = 1.0
    assert np.isnan(t.cov).all()


def test_replace_pickle_and_later_of_keep_the_value():
    t = Thing("a", Later(_costly, 5.0))
    back = pickle.loads(pickle.dumps(t))  # pickled unread: still to be worked out
    assert CALLS == [] and back.value == 10.0 and CALLS == [1]
    derived = later_of(Thing("c", Later(_costly, 1.5)), "value", lambda v: v + 1.0)
    assert isinstance(derived, Later) and CALLS == [1]
    assert Thing("d", derived).value == 4.0 and CALLS == [1, 1]
    assert later_of(Thing("e", 2.0), "value", lambda v: v + 1.0) == 3.0  # read: at once
    assert dataclasses.replace(t, name="z").value == 10.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        t.value = 1.0  # type: ignore[misc]
