"""The record of which special paths ran (camvlp.pipeline.paths)."""

from __future__ import annotations

import time

import pytest

from camvlp.pipeline.paths import PathTime, path, recording


@path("outer")
def _outer(n: int) -> int:
    time.sleep(0.002)
    return sum(_inner(k) for k in range(n))


@path("inner")
def _inner(k: int) -> int:
    if k < 0:
        raise ValueError("negative")
    return k


def test_calls_and_inclusive_times_are_recorded():
    with recording() as paths:
        assert _outer(3) == 3
        _inner(5)
    assert list(paths) == ["outer", "inner"]  # in the order they first ran
    assert paths["outer"].calls == 1 and paths["inner"].calls == 4
    assert isinstance(paths["outer"], PathTime)
    assert paths["outer"].ms >= 2.0  # its sleep, and the inner calls within it
    assert paths["inner"].ms < paths["outer"].ms


def test_nothing_is_recorded_outside_a_recording():
    assert _outer(2) == 1  # runs as it would unmarked
    with recording() as paths:
        pass
    assert paths == {}


def test_a_call_that_raises_still_counts_and_the_record_ends():
    with pytest.raises(ValueError), recording() as paths:
        _inner(-1)
    assert paths["inner"].calls == 1
    with recording() as later:
        _inner(1)
    assert later["inner"].calls == 1  # a new record, not the one before


def test_recordings_nest_without_mixing():
    with recording() as outer:
        _inner(1)
        with recording() as inner:
            _inner(2)
        _inner(3)
    assert inner["inner"].calls == 1
    assert outer["inner"].calls == 2
