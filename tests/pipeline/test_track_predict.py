"""Tests of the tracker's image predictions: the rows' times and where a fixture last seen
is expected."""

from __future__ import annotations

import numpy as np
import pytest

from camvlp.model.camera import Camera
from camvlp.model.readout import Readout
from camvlp.pipeline.track.predict import Sighting, row_offset_s, sighted_pixels

CAMERA = Camera.from_focal(640, 360, 483.0, row_time_s=40e-6)
SHAPE = (360, 640)


@pytest.mark.parametrize("readout", list(Readout))
def test_row_times_are_centred_on_the_middle_row_and_follow_the_readout(readout):
    rng = np.random.default_rng(3)
    n = SHAPE[0] if readout.by_rows else SHAPE[1]
    middle = 0.5 * (n - 1)
    pixels = rng.uniform(0, min(SHAPE) - 1, (6, 2))
    centre = np.full((1, 2), middle)
    first = np.zeros((1, 2))  # the first row or column of the image
    dts = row_offset_s(CAMERA, readout, np.vstack([centre, first, pixels]), SHAPE)
    assert dts[0] == pytest.approx(0.0, abs=1e-15)
    # the top (left) is read first going forward, last reversed
    assert dts[1] == pytest.approx((1 if readout.reversed else -1) * middle * 40e-6)
    step = np.diff(dts[2:]) / np.diff(pixels[:, readout.pixel_index])
    assert np.allclose(step, -40e-6 if readout.reversed else 40e-6)


def test_without_a_row_time_or_a_readout_every_row_is_the_frame_time():
    pixels = np.array([[0.0, 0.0], [639.0, 359.0]])
    still = Camera.from_focal(640, 360, 483.0)
    assert not row_offset_s(still, Readout.ROWS, pixels, SHAPE).any()
    assert not row_offset_s(CAMERA, None, pixels, SHAPE).any()


def test_a_fixture_last_seen_moves_on_at_its_velocity_until_the_gap_is_too_long():
    seen = {
        7: Sighting(np.array([100.0, 50.0]), 1.0, np.array([20.0, -10.0])),
        9: Sighting(np.array([300.0, 80.0]), 0.2, np.zeros(2)),
    }
    out = sighted_pixels(seen, 1.5, max_gap_s=0.5)
    assert set(out) == {7}
    assert np.allclose(out[7], [110.0, 45.0])
