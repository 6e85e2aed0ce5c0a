"""The frame endpoint (``POST /api/v1/sites/{id}/frames``): a track per device, gravity for a
frame the track cannot place, stale and superseded frames, and every refusal in one line."""

from __future__ import annotations

import asyncio
import copy

import cv2
import numpy as np
import pytest
from capture_video import CAMERA_JSON
from service_helpers import (
    ADMIN,
    MAP_JSON,
    client,  # noqa: F401  (fixture)
    encode,
)

from conftest import make_small_room, small_settings

#: Poses of the test frames: 2 m under the ceiling, looking up, moving 1 cm a frame.
POSES = [((0.10 + 0.01 * k, -0.7, 0.05), (93.0, 2.0, 10.0)) for k in range(4)]
#: The map's down in its own frame (the small room is y-down).
DOWN = np.array([0.0, 1.0, 0.0])


def _render(k: int, keep: tuple[int, ...] | None = None):
    """Frame ``k`` (JPEG bytes, as a phone's page sends) and its render; with ``keep``, every
    other fixture is painted out (a frame that shows only those)."""
    from camvlp.model.camera import Camera, Pose
    from camvlp.sim.render import render

    camera = Camera.from_focal(640, 480, CAMERA_JSON["focal_length_px"], row_time_s=40e-6)
    pose = Pose.from_euler(*POSES[k])
    out = render(camera, make_small_room(), pose, small_settings(seed=10 + k, row_time_s=40e-6))
    image = out.image.copy()
    if keep is not None:
        for f in out.fixtures:
            if f.id not in keep:
                centre = tuple(int(v) for v in np.rint(f.pixel))
                cv2.circle(image, centre, int(f.rows_spanned / 2 + 12), (0, 0, 0), -1)
    return encode(image, ".jpg"), out


@pytest.fixture(scope="module")
def frames():
    """The four frames whole, and frame 3 showing fixtures 12 and 5 only."""
    return [_render(k) for k in range(4)], _render(3, keep=(12, 5))


def _site(client) -> tuple[int, dict]:
    r = client.post(
        "/api/v1/sites",
        json={"name": "frames", "map": MAP_JSON, "camera": CAMERA_JSON},
        headers=ADMIN,
    )
    assert r.status_code == 201, r.text
    return r.json()["id"], {"Authorization": f"Bearer {r.json()['api_key']}"}


def post(client, site_id, headers, body, *, kind="image/jpeg", **params):
    """POST a frame."""
    params.setdefault("device", "phone-1")
    return client.post(
        f"/api/v1/sites/{site_id}/frames",
        content=body,
        params=params,
        headers={**headers, "Content-Type": kind},
    )


def _gravity(out) -> str:
    g = out.pose.world_from_camera.T @ DOWN
    return ",".join(f"{v:.6f}" for v in g)


def test_a_device_is_tracked_frame_after_frame(client, frames):
    whole, (two_lights, _) = frames
    site_id, headers = _site(client)
    answers = []
    for k, (jpeg, out) in enumerate(whole[:3]):
        r = post(client, site_id, headers, jpeg, t=0.1 * k)
        assert r.status_code == 200, r.text
        answers.append(r.json())
        a = answers[-1]
        assert a["status"] == "fix" and a["located"] and a["frame"] == k
        assert np.linalg.norm(np.array(a["position"]) - out.pose.position) < 0.005
        assert sorted(a["fixtures_used"]) == sorted(f["id"] for f in MAP_JSON["fixtures"])
        assert 0 < max(a["position_sigma"]) < 0.005
        assert a["plan"]["position"] == pytest.approx(
            [a["position"][0], a["position"][2]], abs=1e-6
        )
        assert a["readout"] == "rows" and a["device"] == "phone-1"
    # two lights only: the track's prior places it (tracked), where a new device cannot
    r = post(client, site_id, headers, two_lights, t=0.3)
    a = r.json()
    assert a["status"] == "tracked", a
    assert sorted(a["fixtures_used"]) == [5, 12]
    assert np.linalg.norm(np.array(a["position"]) - whole[3][1].pose.position) < 0.01
    fresh = post(client, site_id, headers, two_lights, t=0.3, device="phone-2").json()
    assert fresh["status"] == "lost" and not fresh["located"] and fresh["position"] is None
    # the fixes are recorded as frames, with their status and sigma
    listed = client.get(f"/api/v1/sites/{site_id}/fixes", headers=headers).json()["fixes"]
    assert [f["status"] for f in listed] == ["lost", "tracked", "fix", "fix", "fix"]
    assert {f["source"] for f in listed} == {"frame"}
    assert listed[-1]["position_sigma"] == answers[0]["position_sigma"]
    assert listed[-1]["id"] == answers[0]["fix_id"]


def test_a_frame_the_track_cannot_place_is_located_with_gravity(client, frames):
    _, (two_lights, out) = frames
    site_id, headers = _site(client)
    without = post(client, site_id, headers, two_lights, t=1.0).json()
    assert without["status"] == "lost"
    r = post(client, site_id, headers, two_lights, t=2.0, gravity=_gravity(out))
    a = r.json()
    assert a["status"] == "gravity" and a["located"], a
    assert sorted(a["fixtures_used"]) == [5, 12]
    assert np.linalg.norm(np.array(a["position"]) - out.pose.position) < 0.02
    assert 0 < max(a["position_sigma"]) < 0.2  # (two fixtures: the gravity's 1 degree, in cm)
    stored = client.get(f"/api/v1/sites/{site_id}/fixes/{a['fix_id']}", headers=headers).json()
    assert stored["status"] == "gravity" and stored["located"]
    assert stored["result"]["fixtures_used"] == a["fixtures_used"]


def test_stale_and_bad_frames_get_one_line_4xx(client, frames):
    whole, _ = frames
    jpeg, out = whole[0]
    site_id, headers = _site(client)
    assert post(client, site_id, headers, jpeg, t=5.0).status_code == 200
    stale = post(client, site_id, headers, jpeg, t=5.0)
    assert stale.status_code == 409 and "not after the device's last frame" in _one_line(stale)
    assert post(client, site_id, headers, jpeg, t=1.0, reset="true").status_code == 200
    gray = cv2.cvtColor(out.image, cv2.COLOR_BGR2GRAY)
    r = post(client, site_id, headers, gray.tobytes(), kind="application/octet-stream", t=2.0)
    assert r.status_code == 200 and r.json()["status"] == "fix"
    cases = [
        (dict(body=jpeg, kind="text/plain"), 415, "Content-Type must be image/jpeg"),
        (dict(body=b"", kind="image/jpeg"), 400, "frame is empty"),
        (dict(body=b"\xff\xd8\xff junk", kind="image/jpeg"), 415, "must be a JPEG or PNG"),
        (dict(body=gray.tobytes()[:-1], kind="application/octet-stream"), 422, "640 x 480"),
        (dict(body=encode(out.image[:240, :320], ".jpg")), 422, "frame is 320 x 240 pixels"),
        (dict(body=jpeg, gravity="0,0,0"), 422, "gravity must be three numbers"),
        (dict(body=jpeg, t="nan"), 422, "t"),
        (dict(body=jpeg, camera="other"), 404, "no camera 'other'"),
        (dict(body=jpeg, device=""), 422, "device"),
    ]
    for n, (kw, status, words) in enumerate(cases):
        kw.setdefault("t", 10.0 + n)
        r = post(client, site_id, headers, kw.pop("body"), kind=kw.pop("kind", "image/jpeg"), **kw)
        assert r.status_code == status, (kw, r.text)
        assert words in _one_line(r), (kw, r.text)
    assert post(client, site_id, {}, jpeg, t=99.0).status_code == 401


def _one_line(response) -> str:
    body = response.json()
    assert set(body) == {"detail"} and "\n" not in body["detail"], body
    return body["detail"]


def test_a_device_never_has_more_than_one_frame_waiting():
    """Ten frames of one device at once: the first is located, the newest waits and is
    located next, the eight between are answered as dropped at once; never more than one
    waits."""
    from camvlp.service.frames import FrameDropped, FrameTracks

    async def scenario():
        tracks = FrameTracks(max_devices=4, idle_s=60)
        track = tracks.track(("s", "c", "d"), {}, {}, lambda: _camera_and_map())
        gate, depth, located, dropped = asyncio.Event(), [], [], []

        async def run(tr, pending):
            depth.append(tracks.waiting())
            await gate.wait()  # the first frame holds its device's turn until released
            located.append(pending.t)
            return {"t": pending.t}

        async def send(t):
            try:
                return await tracks.submit(track, b"", "encoded", t, None, run, dropped.append)
            except FrameDropped as exc:
                return exc.reason

        tasks = [asyncio.create_task(send(0.0))]
        for _ in range(3):  # the first frame's turn begins
            await asyncio.sleep(0)
        tasks += [asyncio.create_task(send(float(t))) for t in range(1, 10)]
        for _ in range(5):
            await asyncio.sleep(0)
            depth.append(tracks.waiting())
        gate.set()
        answers = await asyncio.gather(*tasks)
        return answers, located, dropped, depth, tracks.waiting()

    answers, located, dropped, depth, left = asyncio.run(scenario())
    assert located == [0.0, 9.0]
    assert answers[0][0] == {"t": 0.0} and answers[9][0] == {"t": 9.0}
    assert answers[1:9] == ["superseded"] * 8 and dropped == ["superseded"] * 8
    assert max(depth) == 1 and left == 0


def _camera_and_map():
    from camvlp.io import camera_from_dict, map_from_dict

    return camera_from_dict(CAMERA_JSON, "camera"), map_from_dict(MAP_JSON, "map")


def test_a_map_whose_ids_repeat_is_tracked(client, frames):
    # the room with a second fixture of its first one's ID 5 m off: its frame is placed by
    # its lights' IDs and arrangement, and the fix's sigma worked out from the fixtures the
    # frame's IDs name there
    jpeg, out = frames[0][0]
    site_map = copy.deepcopy(MAP_JSON)
    site_map.setdefault("frame", {})["reuse"] = True
    first = site_map["fixtures"][0]
    site_map["fixtures"].append({**first, "position": [p + 5.0 for p in first["position"]]})
    r = client.post(
        "/api/v1/sites",
        json={"name": "reused", "map": site_map, "camera": CAMERA_JSON},
        headers=ADMIN,
    )
    assert r.status_code == 201, r.text
    headers = {"Authorization": f"Bearer {r.json()['api_key']}"}
    r = post(client, r.json()["id"], headers, jpeg, t=0.0)
    assert r.status_code == 200, r.text
    answer = r.json()
    assert answer["status"] == "fix", answer
    assert np.linalg.norm(np.array(answer["position"]) - out.pose.position) < 0.005
    assert 0 < max(answer["position_sigma"]) < 0.01
