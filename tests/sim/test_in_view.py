"""Which fixtures a render draws: only those whose disc and glow may reach the picture."""

from __future__ import annotations

import numpy as np
import pytest

from camvlp.geometry.projection import in_view
from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.sim.render import RenderSettings, light_patches, render
from camvlp.sim.scene import fixture_truths

LOOK_UP = (90.0, 0.0, 0.0)  # the thesis' angles looking along world -y (at the ceiling)


def camera(distortion=None) -> Camera:
    """A 160 x 120 camera, f = 100 px (a wide view: 77 degrees across)."""
    extra = {} if distortion is None else {"distortion": distortion}
    return Camera.from_focal(160, 120, 100.0, row_time_s=20e-6, **extra)


@pytest.mark.parametrize("distortion", [None, np.array([-0.25, 0.06, 0.0, 0.0])])
def test_a_sphere_that_shows_in_the_picture_is_in_view_and_most_others_are_not(distortion):
    cam = camera(distortion)
    pose = Pose.from_euler([0.0, 0.0, 0.0], (80.0, 5.0, 30.0))
    rng = np.random.default_rng(7)
    centres = rng.uniform(-4.0, 4.0, (400, 3))
    radii = rng.uniform(0.05, 0.6, 400)
    seen = in_view(cam, pose, centres, radii)
    # points inside and on each sphere: any that projects into the picture must be in view
    u = rng.normal(size=(400, 300, 3))
    u /= np.linalg.norm(u, axis=2, keepdims=True)
    points = centres[:, None, :] + radii[:, None, None] * rng.uniform(0, 1, (400, 300, 1)) * u
    px = cam.project(pose, points.reshape(-1, 3)).reshape(400, 300, 2)
    inside = np.all((px >= -0.5) & (px <= np.array([159.5, 119.5])), axis=2).any(axis=1)
    assert inside.sum() >= 20  # the draw puts spheres in the picture...
    assert not np.any(inside & ~seen)  # ...and none of them is left out
    assert (~seen).sum() >= 200  # most of the others are culled


def test_a_blur_margin_widens_the_view():
    cam = camera()
    pose = Pose.from_euler([0.0, 0.0, 0.0], LOOK_UP)
    # a point 1 m up (world -y), 0.85 m to the side: 85 px from the centre, 5 px beyond the
    # picture's left border (the principal point is 79.5 px from it)
    centre = np.array([[-0.85, -1.0, 0.0]])
    assert not in_view(cam, pose, centre, [0.0])[0]
    assert in_view(cam, pose, centre, [0.0], margin_px=6.0)[0]


def test_a_far_disc_across_the_cameras_plane_is_not_drawn():
    """A fixture far to the side, its centre just in front of the camera and its rim across
    the camera's plane, projects nowhere near the picture: it is not searched for over the
    whole picture (a 10,000-fixture site's renders took minutes so), and the photo is the
    same without it."""
    cam = camera()
    pose = Pose.from_euler([0.0, 0.0, 0.0], LOOK_UP)
    up = np.array([0.0, 1.0, 0.0])
    near = Fixture(3, np.array([0.0, -1.0, 0.0]), 0.3, up)
    far = Fixture(5, np.array([50.0, -0.1, 0.0]), 0.6, np.array([-1.0, 1.0, 0.0]) / np.sqrt(2))
    both, alone = FixtureMap((near, far)), FixtureMap((near,))
    s = RenderSettings(full_well_e=0.0, read_noise=0.0, seed=1)
    truths = fixture_truths(cam, both, pose, s)
    assert truths[1].in_front and not np.all(np.isfinite(truths[1].rows_spanned))
    assert [p.index for p in light_patches(cam, both, pose, s)] == [0]
    assert np.array_equal(render(cam, both, pose, s).image, render(cam, alone, pose, s).image)


def test_fixtures_without_a_diameter_are_seen_at_their_centres():
    cam = camera()
    pose = Pose.from_euler([0.0, 0.0, 0.0], LOOK_UP)
    fixtures = (
        Fixture(1, np.array([0.1, -1.0, 0.0]), None, None),
        Fixture(2, np.array([-0.2, -1.0, 0.1]), 0.2, None),
    )
    truths = fixture_truths(cam, FixtureMap(fixtures), pose)
    expected = cam.project(pose, np.array([f.position for f in fixtures]))
    np.testing.assert_allclose([t.pixel for t in truths], expected)
    assert truths[0].rows_spanned == 0.0 and truths[0].fully_inside
    assert truths[1].rows_spanned > 10.0
