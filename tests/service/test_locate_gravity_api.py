"""Locating through the service with the phone's gravity: two fixtures in view are enough."""

from __future__ import annotations

import numpy as np
from service_helpers import (
    CAMERA_JSON,
    MAP_JSON,
    client,  # noqa: F401  (fixture)
    create_site,
    encode,
)
from test_api import detail, upload

from conftest import SMALL_ROOM_XZ, make_small_camera, make_small_room, small_settings

#: The first two lights of the small room, and where the camera sees exactly them.
TWO_IDS = (5, 6)
TWO_POSITION = (0.1, 0.0, -0.1)
TWO_EULER = (96.0, 4.0, 20.0)


def _two_fixture_photo():
    """A render with exactly two lights in view: (PNG bytes, true pose)."""
    from camvlp.model.camera import Pose
    from camvlp.sim.render import render

    room = make_small_room(ids=TWO_IDS, xz=SMALL_ROOM_XZ[:2])
    pose = Pose.from_euler(list(TWO_POSITION), list(TWO_EULER))
    r = render(make_small_camera(), room, pose, small_settings(seed=32))
    assert sum(t.fully_inside for t in r.fixtures) == 2
    return encode(r.image), pose


def _gravity_text(pose, sign: float = 1.0) -> str:
    """The true gravity in the camera frame (m/s^2) as ``gx,gy,gz``; y points down."""
    g = sign * 9.81 * (pose.world_from_camera.T @ np.array([0.0, 1.0, 0.0]))
    return ",".join(f"{v:.6f}" for v in g)


def test_a_gravity_upload_of_a_two_fixture_photo_is_located(client):
    png, pose = _two_fixture_photo()
    two = {**MAP_JSON, "fixtures": MAP_JSON["fixtures"][:2], "up": [0, -1, 0]}
    assert [f["id"] for f in two["fixtures"]] == list(TWO_IDS)
    site_id, headers = create_site(client, map=two, camera=CAMERA_JSON)
    # without gravity two fixtures are not enough
    plain = upload(client, site_id, headers, png, device="phone")
    assert plain.status_code == 200, plain.text
    assert plain.json()["position"] is None and "at least 4" in plain.json()["error"]
    # with it the service locates the photo, from those two fixtures
    r = upload(client, site_id, headers, png, device="phone", gravity=_gravity_text(pose))
    assert r.status_code == 200, r.text
    got = r.json()
    assert got["solver"] == "gravity-2" and got["fixtures_used"] == 2
    np.testing.assert_allclose(got["position"], TWO_POSITION, atol=2e-3)
    fix = client.get(f"/api/v1/sites/{site_id}/fixes/{got['fix_id']}", headers=headers).json()
    assert fix["located"] and sorted(fix["fixtures_used"]) == list(TWO_IDS)
    # the plan uses the map's up: the floor is x, z
    assert fix["plan"]["position"] == [got["position"][0], got["position"][2]]


def test_gravity_that_hides_the_ceiling_is_422(client):
    png, pose = _two_fixture_photo()
    site_id, headers = create_site(client)
    # gravity the wrong way round: the camera would look at the floor
    r = upload(client, site_id, headers, png, gravity=_gravity_text(pose, -1.0))
    assert r.status_code == 422 and "optical axis" in detail(r), r.text
    fixes = client.get(f"/api/v1/sites/{site_id}/fixes", headers=headers).json()["fixes"]
    assert fixes == []
