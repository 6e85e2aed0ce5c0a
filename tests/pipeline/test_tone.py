"""Tests of undoing a camera's tone curve (camvlp.imaging.tone and the camera's tone_gamma)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from camvlp import LocateSettings, locate
from camvlp.imaging.tone import linear_light
from camvlp.io import load_map
from camvlp.model.camera import Camera, Pose
from camvlp.sim.render import RenderSettings, render


def test_levels_map_back_to_light():
    img = np.arange(256, dtype=np.uint8).reshape(16, 16)
    lin = linear_light(img, 2.2)
    assert lin.dtype == np.uint16 and lin.shape == img.shape
    np.testing.assert_allclose(lin / 65535, (img / 255.0) ** 2.2, atol=0.6 / 65535)
    wide = linear_light(np.array([[0, 32768, 65535]], np.uint16), 2.0)
    np.testing.assert_allclose(wide / 65535, [[0, (32768 / 65535) ** 2, 1]], atol=0.6 / 65535)
    assert linear_light(img, 1) is img


@pytest.fixture(scope="module")
def scene(thesis_room_path):
    """A 1280 x 960 camera under the thesis' four lamps, with a glow: 2.5 rows per chip."""
    camera = Camera.from_focal(1280, 960, 1250.0, row_time_s=20e-6)
    return camera, load_map(thesis_room_path), Pose.from_euler([0, 0, 0], [90, 0, 0])


@pytest.mark.parametrize("seed", [0, 1])
def test_a_phone_photo_given_its_tone_curve_reads_as_a_linear_camera(scene, seed):
    """The same scene through a linear sensor and through a tone curve of 2.2, without noise:
    given its tone curve, the second photo's row profiles are the first's (to the 8-bit steps
    of the stored levels); taken as linear, they are not."""
    camera, fmap, pose = scene
    base = RenderSettings(
        chip_rate_hz=20000,
        exposure_s=0.6 / 20000,
        halo=0.3,
        off_level=0.05,
        brightness=0.9,
        full_well_e=0,
        read_noise=0,
        seed=seed,
    )
    linear = render(camera, fmap, pose, dataclasses.replace(base, gamma=1.0 + 1e-12)).image
    toned = render(camera, fmap, pose, dataclasses.replace(base, gamma=2.2)).image
    keep = LocateSettings(keep_stages=True)
    ref = locate(linear, camera, fmap, settings=keep).stages.profiles
    given = locate(toned, dataclasses.replace(camera, tone_gamma=2.2), fmap, settings=keep)
    taken = locate(toned, camera, fmap, settings=keep)
    for a, b, c in zip(ref, given.stages.profiles, taken.stages.profiles, strict=True):
        assert a.size == b.size
        scale = np.ptp(a)  # the profile's swing, gray levels
        assert np.max(np.abs(b - a)) < 0.03 * scale  # (in gray levels, 16-bit or 8-bit)
        assert c.size != a.size or np.max(np.abs(c - a)) > 0.15 * scale  # (its glow swells)
