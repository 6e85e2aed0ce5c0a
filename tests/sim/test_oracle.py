"""The oracle of a rendered lamp's ID (camvlp.sim.oracle.id_separation)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from camvlp.pipeline.decode.model_choice import MIN_MARGIN
from camvlp.sim.oracle import id_separation
from conftest import stress_scene, stress_settings

#: Three lamps ``(id, x, y, diameter)``, metres, 2 m above a 640 x 480 camera (f = 1400 px):
#: the first spans about 2 frames of the code at 4 rows per chip.
_LAMPS = ((9, 0.0, 0.0, 0.36), (2, 0.45, 0.1, 0.2), (5, -0.45, -0.1, 0.2))


def _scene(**look):
    look = {"off_level": 0.0, "blur_px": 0.8, "seed": 5, **look}
    settings = stress_settings(4.0, 0.5, **look)
    _, room, photo, _ = stress_scene((640, 480), _LAMPS, settings, 90)
    return photo, room


@pytest.mark.parametrize("readout", ["rows", "columns-reversed"])
def test_a_lamp_drawn_plainly_is_told_by_far_and_a_faint_one_is_not(readout):
    """The ratio grows with the square of the light: a lamp at 0.8 of full scale is told from
    every other ID by far more than a decoder's margin; at 1/10,000 of that, by less (its
    stripes are under the noise)."""
    bright, room = _scene(brightness=0.8, readout=readout)
    faint, _ = _scene(brightness=0.8 / 10_000, readout=readout)
    got, _ = id_separation(bright, room, 0)
    low, _ = id_separation(faint, room, 0)
    assert got > 100 * MIN_MARGIN, got
    assert low < MIN_MARGIN, low
    # the sensor's shot noise grows with the light: the ratio grows less than 10,000 ** 2 times
    assert 1e3 < got / low < 10_000**2, (got, low)


def test_a_lamp_clipped_in_its_dark_chips_too_tells_its_id_by_what_lies_beyond_the_clip():
    """At 30 times full scale with the LED at 10 % when off, every row of the disc clips:
    only light beyond the clip carries the code.  The blurred rim's tail tells it by far less
    than the same lamp unclipped; a halo tells it by far more than the rim."""
    plain, room = _scene(brightness=0.8)
    clipped, _ = _scene(brightness=30.0, off_level=0.1)
    halo, _ = _scene(brightness=30.0, off_level=0.1, halo=0.3)
    unclipped = id_separation(plain, room, 0)[0]
    rim = id_separation(clipped, room, 0)[0]
    with_halo = id_separation(halo, room, 0)[0]
    assert MIN_MARGIN < rim < unclipped / 30, (rim, unclipped)
    assert with_halo > 30 * rim, (with_halo, rim)


def test_a_phone_render_is_not_redrawn():
    photo, room = _scene(brightness=0.8)
    phone = dataclasses.replace(photo, settings=dataclasses.replace(photo.settings, gamma=2.2))
    assert id_separation(phone, room, 0) is None
    assert id_separation(photo, room, 7) is None  # no such lamp


def test_the_columns_compared_are_a_sample():
    """Every eighth column or so, the sum scaled by the stride: the same ratio within 5 %."""
    photo, room = _scene(brightness=0.8)
    whole = id_separation(photo, room, 0, max_columns=10_000)
    half = id_separation(photo, room, 0, max_columns=int(np.ceil(photo.camera.width / 8)))
    assert whole[1] == half[1]
    assert half[0] == pytest.approx(whole[0], rel=0.05)
