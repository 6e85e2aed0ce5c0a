"""What a photo shows besides beacons gets no ID: a light that sends data, and the date and
time a camera burns into its photos.  Real photos show both; an ID given to either is the
worst failure ``locate`` can make."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from camvlp import locate
from camvlp.model.camera import Pose
from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.sim.render import render
from conftest import make_small_camera, make_small_room, small_settings

STAMP = "2017-02-15 17:47:52"
DATA_ID = 14
#: Where the light that sends data hangs (x, z), metres: between two beacons, clear of the text.
DATA_XZ = (0.0, -0.9)
FREQS_HZ = (2500.0, 3000.0, 3500.0, 4000.0, 4500.0)


def _rooms(frequency: bool) -> tuple[FixtureMap, FixtureMap]:
    """The room as rendered (the small room's five beacons and one light that sends data)
    and as the map ``locate`` gets (the beacons only)."""
    beacons = make_small_room()
    if frequency:
        beacons = FixtureMap(
            tuple(
                dataclasses.replace(f, frequency_hz=hz)
                for f, hz in zip(beacons.fixtures, FREQS_HZ, strict=True)
            ),
            mode="frequency",
        )
    data = Fixture(
        DATA_ID,
        np.array([DATA_XZ[0], beacons.fixtures[0].position[1], DATA_XZ[1]]),
        beacons.fixtures[0].diameter,
        np.array([0.0, 1.0, 0.0]),
        frequency_hz=1000.0 if frequency else None,
    )
    return FixtureMap((*beacons.fixtures, data), mode=beacons.mode), beacons


UP = Pose.from_euler([0.03, 0.0, -0.02], [90.0, 0.0, 0.0])
#: A tilted camera, and lights that blink the data at 5 kHz: an earlier version gave the
#: burned-in text ID 10 in this photo.
TILTED = Pose.from_euler([-0.082, 0.0, -0.023], [87.61, -4.53, 6.0])


@pytest.mark.parametrize(
    ("frequency", "seed", "pose", "chip_rate_hz", "exposure_s"),
    [
        (False, 1, UP, 10e3, None),
        (False, 2, UP, 10e3, None),
        (True, 1, UP, 10e3, 40e-6),
        (True, 2, UP, 10e3, 40e-6),
        (True, 27, TILTED, 5e3, 34.8e-6),
    ],
)
def test_a_data_light_and_a_burned_in_date_get_no_id(
    frequency, seed, pose, chip_rate_hz, exposure_s
):
    rendered, given = _rooms(frequency)
    camera = make_small_camera()
    settings = small_settings(
        seed=seed, data_lights=(DATA_ID,), stamp=STAMP, chip_rate_hz=chip_rate_hz
    )
    if exposure_s is not None:
        settings = dataclasses.replace(settings, exposure_s=exposure_s)
    photo = render(camera, rendered, pose, settings)
    res = locate(photo.image, camera, given)
    assert res, res.error
    assert np.linalg.norm(res.position - pose.position) < 5e-3
    # every beacon identified, at its place
    truth = {t.id: t for t in photo.fixtures}
    named = sorted(f.id for f in res.fixtures if f.id is not None)
    assert named == sorted(given.ids)
    for f in res.fixtures:
        if f.id is not None:
            assert np.hypot(*(f.pixel - truth[f.id].pixel)) < 1.0
    # the light that sends data is seen, and named nothing
    data = truth[DATA_ID]
    assert data.sends_data
    near = [f for f in res.fixtures if np.hypot(*(f.pixel - data.pixel)) < 20]
    assert near, "the light that sends data was not detected"
    assert all(f.id is None for f in near)
    # the text is seen (its strokes are bright), and named nothing
    u0, v0, u1, v1 = photo.stamp_box
    on_text = [f for f in res.fixtures if u0 <= f.pixel[0] <= u1 and v0 <= f.pixel[1] <= v1]
    assert on_text, "the burned-in text was not detected"
    assert all(f.id is None for f in on_text)
