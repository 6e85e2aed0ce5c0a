"""The service's small parts: image headers, API keys, the plan seen from above."""

from __future__ import annotations

import hashlib

import cv2
import numpy as np
import pytest

from camvlp.model.fixtures import Fixture, FixtureMap
from camvlp.service.auth import hash_key, keys_match, new_key
from camvlp.service.imagesize import read_image_header
from camvlp.service.plan import plan_view

# --- image headers ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("ext", "params", "kind"),
    [
        (".png", [], "png"),
        (".jpg", [], "jpeg"),
        (".jpg", [cv2.IMWRITE_JPEG_PROGRESSIVE, 1], "jpeg"),  # SOF2
    ],
)
def test_header_size_matches_the_decoded_image(ext, params, kind):
    rng = np.random.default_rng(4)
    for h, w in ((23, 37), (480, 640), (1, 3000)):
        image = rng.integers(0, 255, (h, w, 3), dtype=np.uint8)
        ok, buf = cv2.imencode(ext, image, params)
        assert ok
        header = read_image_header(buf.tobytes())
        assert header is not None and header.kind == kind
        assert (header.width, header.height) == (w, h) and header.pixels == w * h


def test_jpeg_header_behind_a_large_exif_segment():
    _, buf = cv2.imencode(".jpg", np.zeros((20, 30), np.uint8))
    raw = buf.tobytes()
    app1 = b"\xff\xe1" + (60_002).to_bytes(2, "big") + b"Exif\x00\x00" + b"\xff" * 59_994
    header = read_image_header(raw[:2] + app1 + raw[2:])
    assert header is not None and (header.width, header.height) == (30, 20)


@pytest.mark.parametrize(
    "data",
    [
        b"",
        b"GIF89a....",
        b"\x89PNG\r\n\x1a\n\x00\x00",
        b"\xff\xd8\xff\xda\x00\x02",
        b"\xff\xd8\x00",
    ],
    ids=["empty", "gif", "short png", "scan before frame", "broken chain"],
)
def test_not_a_readable_header(data):
    assert read_image_header(data) is None


# --- keys ----------------------------------------------------------------------------------


def test_keys_are_random_and_stored_as_sha256():
    keys = {new_key() for _ in range(20)}
    assert len(keys) == 20
    key, stored = next(iter(keys))
    assert stored == hashlib.sha256(key.encode()).hexdigest() == hash_key(key)
    assert keys_match(key, stored)
    assert not keys_match(key + "x", stored) and not keys_match("", stored)


# --- plan ------------------------------------------------------------------------------------


def _map(positions, normal=None) -> FixtureMap:
    n = None if normal is None else np.array(normal, dtype=float)
    return FixtureMap(
        tuple(Fixture(i + 1, np.array(p, dtype=float), 0.1, n) for i, p in enumerate(positions))
    )


SQUARE = [(0.8, 0.6), (0.8, -0.6), (-0.8, -0.6), (-0.8, 0.6)]


@pytest.mark.parametrize("with_normals", [True, False])
def test_plan_of_a_y_down_room_is_x_right_z_up(with_normals):
    view = plan_view(_map([(a, -2.7, b) for a, b in SQUARE], (0, 1, 0) if with_normals else None))
    assert (view.vertical, view.up, view.axes) == (1, -1, (0, 2))
    np.testing.assert_array_equal(view.project(np.array([[1.0, -2.7, 2.0]])), [[1.0, 2.0]])


@pytest.mark.parametrize("with_normals", [True, False])
def test_plan_of_a_z_up_room_is_x_right_y_up(with_normals):
    view = plan_view(_map([(a, b, 3.0) for a, b in SQUARE], (0, 0, -1) if with_normals else None))
    assert (view.vertical, view.up, view.axes) == (2, 1, (0, 1))


def test_the_maps_up_decides_the_plan():
    # two lights without normals spread only along z: without up, x looks like the vertical
    pair = [(0.8, -2.7, 0.6), (0.8, -2.7, -0.6)]
    assert plan_view(_map(pair)).vertical == 0
    view = plan_view(FixtureMap(_map(pair).fixtures, up=[0, -1, 0]))
    assert (view.vertical, view.up, view.axes) == (1, -1, (0, 2))
    # up wins over the lights' normals, which here face sideways
    view = plan_view(FixtureMap(_map(pair, (1, 0, 0)).fixtures, up=[0, 0, 2]))
    assert (view.vertical, view.up, view.axes) == (2, 1, (0, 1))


def test_the_plan_is_a_view_from_above():
    """Right x up-on-the-plan = up, for every vertical axis and sign."""
    for vertical in range(3):
        for sign in (1, -1):
            pts = [[0.0, 0.0, 0.0] for _ in SQUARE]
            for p, (a, b) in zip(pts, SQUARE, strict=True):
                p[vertical] = 2.5 * sign
                p[(vertical + 1) % 3], p[(vertical + 2) % 3] = a, b
            view = plan_view(_map(pts))
            e = np.eye(3)
            np.testing.assert_array_equal(
                np.cross(e[view.axes[0]], e[view.axes[1]]), view.up_vector
            )
            assert view.up_vector[vertical] == sign


def test_heading_of_a_level_camera_is_its_optical_axis():
    view = plan_view(_map([(a, -2.7, b) for a, b in SQUARE], (0, 1, 0)))
    down = np.array([0.0, 1.0, 0.0])  # y-down room
    for forward, expected in (((1, 0, 0), 0.0), ((0, 0, 1), 90.0), ((-1, 0, 1), 135.0)):
        z = np.array(forward, dtype=float) / np.linalg.norm(forward)
        r = np.column_stack([np.cross(down, z), down, z])  # x = y cross z; image down = world down
        assert np.isclose(np.linalg.det(r), 1.0)
        assert view.heading_deg(r) == pytest.approx(expected)


def test_heading_of_a_camera_looking_up_turns_with_its_roll():
    from camvlp.model.camera import euler_to_matrix

    view = plan_view(_map([(a, -2.7, b) for a, b in SQUARE], (0, 1, 0)))
    # theta = (90, 0, 0) looks up with the top of the image towards -z: -90 deg on the plan;
    # a roll about the (upward) optical axis turns it counterclockwise seen from above
    assert view.heading_deg(euler_to_matrix([90.0, 0.0, 0.0])) == pytest.approx(-90.0)
    for roll in (10.0, 45.0, 120.0, -70.0):
        turned = view.heading_deg(euler_to_matrix([90.0, 0.0, roll]))
        assert (turned + 90.0 - roll + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=1e-9)
