"""The HTTP API with FastAPI's test client: every endpoint, every error status, the key checks."""

from __future__ import annotations

import copy
import hashlib
import json
import struct
import threading
import time
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
import sqlalchemy as sa
from service_helpers import (
    ADMIN,
    CAMERA_JSON,
    MAP_JSON,
    PHOTO_POSITION,
    client,  # noqa: F401  (fixture)
    create_site,
    encode,
    make_client,
    photo_png,  # noqa: F401  (fixture)
)

from camvlp.cli import main
from camvlp.io import InputError, load_map
from camvlp.service.db import sites


def upload(client, site_id, headers, data: bytes, *, name="p.png", query="", **form):
    """POST a photo to the site's locate endpoint."""
    return client.post(
        f"/api/v1/sites/{site_id}/locate{query}",
        headers=headers,
        files={"photo": (name, data, "application/octet-stream")},
        data=form,
    )


def detail(response) -> str:
    """The one-line ``detail`` of an error answer."""
    body = response.json()
    assert set(body) == {"detail"}, body
    assert isinstance(body["detail"], str) and "\n" not in body["detail"], body
    return body["detail"]


# --- sites -----------------------------------------------------------------------------------


def test_create_site_returns_a_key_that_is_stored_only_as_its_hash(client):
    _, headers = create_site(client)
    key = headers["Authorization"].removeprefix("Bearer ")
    assert key.startswith("cvlp_") and len(key) > 40
    with client.app.state.store.engine.connect() as conn:
        stored = [tuple(map(str, row)) for row in conn.execute(sa.select(sites))]
    dump = repr(stored)
    assert key not in dump
    assert hashlib.sha256(key.encode()).hexdigest() in dump
    _, other = create_site(client, "second")
    assert other != headers  # every site gets its own key


def test_get_site_returns_the_map_cameras_and_plan(client):
    site_id, headers = create_site(client)
    r = client.get(f"/api/v1/sites/{site_id}", headers=headers)
    assert r.status_code == 200
    body = r.json()
    assert body["name"] == "small room" and body["map"] == MAP_JSON
    assert body["cameras"] == {"default": CAMERA_JSON}
    # the small room hangs from a y-down ceiling: the plan is x to the right, z upwards
    assert body["plan"]["vertical"] == 1 and body["plan"]["up"] == -1
    assert body["plan"]["axis_names"] == ["x", "z"]
    plan = {f["id"]: f["plan"] for f in body["fixtures"]}
    for f in MAP_JSON["fixtures"]:
        assert plan[f["id"]] == [f["position"][0], f["position"][2]]


def _bad_map_message(tmp_path: Path, bad: dict) -> str:
    path = tmp_path / "bad_map.json"
    path.write_text(json.dumps(bad))
    with pytest.raises(InputError) as info:
        load_map(path)
    return info.value.what


@pytest.mark.parametrize(
    "change",
    [
        lambda m: m["fixtures"][1].pop("position"),
        lambda m: m["fixtures"][2].update(id=5),  # duplicate ID
        lambda m: m["fixtures"][0].update(id=99),  # does not fit 4 ID bits
        lambda m: m.update(fixtures=[]),
        lambda m: m.update(frame={"mode": "morse"}),
    ],
    ids=["no position", "duplicate id", "id too big", "no fixtures", "bad frame"],
)
def test_a_malformed_map_is_422_with_the_file_loaders_message(client, tmp_path, change):
    bad = copy.deepcopy(MAP_JSON)
    change(bad)
    r = client.post(
        "/api/v1/sites", json={"name": "x", "map": bad, "camera": CAMERA_JSON}, headers=ADMIN
    )
    assert r.status_code == 422
    assert detail(r) == f"{_bad_map_message(tmp_path, bad)} (map)"


def test_a_malformed_camera_or_body_is_422_in_one_line(client):
    bad = {**CAMERA_JSON, "image_width": -5}
    r = client.post(
        "/api/v1/sites", json={"name": "x", "map": MAP_JSON, "camera": bad}, headers=ADMIN
    )
    assert r.status_code == 422
    assert detail(r) == "image_width must be a positive integer, got -5 (camera)"
    r = client.post("/api/v1/sites", json={"map": MAP_JSON, "camera": CAMERA_JSON}, headers=ADMIN)
    assert r.status_code == 422 and detail(r) == "name: Field required"
    r = client.post(
        "/api/v1/sites",
        content=b"{not json",
        headers={**ADMIN, "Content-Type": "application/json"},
    )
    assert r.status_code == 422 and "JSON" in detail(r)


def test_put_map_replaces_the_map_after_checking_it(client):
    site_id, headers = create_site(client)
    z_up = {
        "units": "cm",
        "fixtures": [
            {"id": 5, "position": [0, 0, 300]},
            {"id": 6, "position": [100, 0, 300]},
            {"id": 9, "position": [0, 100, 300]},
            {"id": 10, "position": [100, 100, 300]},
        ],
    }
    r = client.put(f"/api/v1/sites/{site_id}/map", headers=headers, json=z_up)
    assert r.status_code == 200 and r.json() == {"site_id": site_id, "fixtures": 4}
    site = client.get(f"/api/v1/sites/{site_id}", headers=headers).json()
    assert site["map"] == z_up and site["units"] == "cm"
    assert site["plan"]["axis_names"] == ["x", "y"] and site["plan"]["up"] == 1
    bad = {"fixtures": [{"id": 5}]}
    r = client.put(f"/api/v1/sites/{site_id}/map", headers=headers, json=bad)
    assert r.status_code == 422 and detail(r) == "fixture 5 has no position (map)"
    assert client.get(f"/api/v1/sites/{site_id}", headers=headers).json()["map"] == z_up
    r = client.put(f"/api/v1/sites/{site_id}/map", headers=headers, json=[1, 2])
    assert r.status_code == 422


def test_a_json_body_that_gives_a_key_twice_is_422_naming_it(client):
    site_id, headers = create_site(client)
    before = client.get(f"/api/v1/sites/{site_id}", headers=headers).json()["map"]
    twice = (
        '{"fixtures": [{"id": 5, "position": [0, 0, 3], "position": [9, 9, 3]},'
        ' {"id": 6, "position": [1, 0, 3]}, {"id": 9, "position": [0, 1, 3]},'
        ' {"id": 10, "position": [1, 1, 3]}]}'
    )
    json_type = {**headers, "Content-Type": "application/json"}
    r = client.put(f"/api/v1/sites/{site_id}/map", headers=json_type, content=twice)
    assert r.status_code == 422 and "'position' is given twice" in detail(r)
    assert client.get(f"/api/v1/sites/{site_id}", headers=headers).json()["map"] == before
    once = twice.replace(', "position": [9, 9, 3]', "")
    r = client.put(f"/api/v1/sites/{site_id}/map", headers=json_type, content=once)
    assert r.status_code == 200 and r.json()["fixtures"] == 4
    # a body that is not JSON at all is the route's to refuse, as before
    r = client.put(f"/api/v1/sites/{site_id}/map", headers=json_type, content="{not json")
    assert r.status_code == 422


def test_put_camera_adds_then_replaces(client):
    site_id, headers = create_site(client)
    url = f"/api/v1/sites/{site_id}/cameras/phone-2"
    r = client.put(url, headers=headers, json=CAMERA_JSON)
    assert r.status_code == 201 and r.json()["created"] is True
    changed = {**CAMERA_JSON, "row_time_s": 3e-5}
    r = client.put(url, headers=headers, json=changed)
    assert r.status_code == 200 and r.json()["created"] is False
    cams = client.get(f"/api/v1/sites/{site_id}", headers=headers).json()["cameras"]
    assert cams == {"default": CAMERA_JSON, "phone-2": changed}
    r = client.put(url, headers=headers, json={"image_width": 10})
    assert r.status_code == 422
    assert detail(r) == "camera file needs image_width and image_height (camera)"
    r = client.put(f"/api/v1/sites/{site_id}/cameras/bad%20name", headers=headers, json=CAMERA_JSON)
    assert r.status_code == 422 and detail(r).startswith("name: ")


# --- keys --------------------------------------------------------------------------------------


def test_every_site_request_needs_the_sites_key(client, photo_png):
    a, key_a = create_site(client, "a")
    b, key_b = create_site(client, "b")
    assert upload(client, a, key_a, photo_png, device="a-phone").status_code == 200
    urls = [
        ("GET", f"/api/v1/sites/{a}"),
        ("GET", f"/api/v1/sites/{a}/fixes"),
        ("GET", f"/api/v1/sites/{a}/fixes/1"),
        ("GET", f"/api/v1/sites/{a}/fixes/1/picture"),
        ("GET", f"/api/v1/sites/{a}/fixes/stream"),
        ("PUT", f"/api/v1/sites/{a}/map"),
        ("PUT", f"/api/v1/sites/{a}/cameras/x"),
        ("POST", f"/api/v1/sites/{a}/locate"),
    ]
    body = {"PUT": {"json": MAP_JSON}, "GET": {}, "POST": {"files": {"photo": ("p", b"x")}}}
    for method, url in urls:
        kw = body[method]
        none = client.request(method, url, **kw)
        assert none.status_code == 401, (url, none.text)
        assert none.headers["www-authenticate"] == "Bearer"
        wrong = client.request(method, url, headers={"Authorization": "Bearer nope"}, **kw)
        assert wrong.status_code == 401, url
        basic = client.request(method, url, headers={"Authorization": "Basic eDp5"}, **kw)
        assert basic.status_code == 401, url
        other = client.request(method, url, headers=key_b, **kw)
        assert other.status_code == 403, url
        assert "a-phone" not in other.text and "small room" not in other.text
    # a site that does not exist: 404 for a valid key, 401 without one
    assert client.get("/api/v1/sites/999", headers=key_b).status_code == 404
    assert client.get("/api/v1/sites/999").status_code == 401
    # nothing of a leaks into b
    assert client.get(f"/api/v1/sites/{b}/fixes", headers=key_b).json()["fixes"] == []
    assert client.get(f"/api/v1/sites/{b}/fixes/1", headers=key_b).status_code == 404
    assert client.get(f"/api/v1/sites/{b}/fixes/1/picture", headers=key_b).status_code == 404
    assert client.get(f"/api/v1/sites/{a}/fixes/1", headers=key_a).status_code == 200


def test_ids_beyond_64_bits_are_422_not_a_server_error(tmp_path):
    """A site or fix id, or a paging id, past what a database row id can hold is bad input."""
    with make_client(tmp_path, stream_max_s=0.1) as c:
        site_id, headers = create_site(c)
        big = str(2**63)
        urls = [
            f"/api/v1/sites/{big}",
            f"/api/v1/sites/-{2**63 + 1}",
            f"/api/v1/sites/{big}/fixes",
            f"/api/v1/sites/{site_id}/fixes/{big}",
            f"/api/v1/sites/{site_id}/fixes/{big}/picture",
            f"/api/v1/sites/{site_id}/fixes?before={big}",
            f"/api/v1/sites/{site_id}/fixes?before=-{2**63 + 1}",
            f"/api/v1/sites/{site_id}/fixes/stream?after={big}",
        ]
        for url in urls:
            r = c.get(url, headers=headers)
            assert r.status_code == 422, (url, r.status_code, r.text)
        stream = f"/api/v1/sites/{site_id}/fixes/stream"
        r = c.get(stream, headers={**headers, "Last-Event-ID": big})
        assert r.status_code == 422 and "Last-Event-ID" in detail(r)
        # the largest id is fine: there is no such site
        assert c.get(f"/api/v1/sites/{2**63 - 1}", headers=headers).status_code == 404


# --- locate --------------------------------------------------------------------------------------


def test_locate_returns_the_cli_json_plus_fix_id(client, photo_png, tmp_path, capsys):
    site_id, headers = create_site(client)
    r = upload(client, site_id, headers, photo_png, device="phone-1", gravity="0,0,-9.8")
    assert r.status_code == 200, r.text
    got = r.json()
    np.testing.assert_allclose(got["position"], PHOTO_POSITION, atol=2e-3)
    assert got["solver"] == "pnp+gravity"  # the locator was given the gravity
    (tmp_path / "cam.json").write_text(json.dumps(CAMERA_JSON))
    (tmp_path / "map.json").write_text(json.dumps(MAP_JSON))
    (tmp_path / "photo.png").write_bytes(photo_png)
    code = main(
        ["locate", str(tmp_path / "photo.png"), "--camera", str(tmp_path / "cam.json"),
         "--map", str(tmp_path / "map.json"), "--gravity", "0,0,-9.8", "--json"]
    )  # fmt: skip
    assert code == 0
    cli = json.loads(capsys.readouterr().out)
    assert set(got) == set(cli) | {"fix_id"}
    for key in set(cli) - {"timing_ms"}:
        assert got[key] == cli[key], key
    assert set(got["timing_ms"]) == set(cli["timing_ms"])
    # the fix is recorded with everything the answer said
    fix = client.get(f"/api/v1/sites/{site_id}/fixes/{got['fix_id']}", headers=headers).json()
    assert fix["result"] == {k: v for k, v in got.items() if k != "fix_id"}
    assert fix["device"] == "phone-1" and fix["camera"] == "default" and fix["located"]
    assert fix["position"] == got["position"] and fix["rotation"] == got["rotation"]
    assert sorted(fix["fixtures_used"]) == sorted(f["id"] for f in got["fixtures"] if f["used"])
    assert fix["reprojection_rms_px"] == got["reprojection_rms_px"] and fix["error"] == ""
    assert fix["plan"]["position"] == [got["position"][0], got["position"][2]]


def test_a_photo_that_cannot_be_located_is_recorded_with_its_reason(client):
    site_id, headers = create_site(client)
    dark = encode(np.zeros((960, 1280, 3), np.uint8))
    r = upload(client, site_id, headers, dark, device="d")
    assert r.status_code == 200
    body = r.json()
    assert body["position"] is None and body["error"]
    fix = client.get(f"/api/v1/sites/{site_id}/fixes/{body['fix_id']}", headers=headers).json()
    assert fix["located"] is False and fix["error"] == body["error"]
    assert fix["plan"] == {"position": None, "heading_deg": None}


def test_max_sigma_refuses_a_position_less_sure(client, photo_png):
    """``max_sigma``: below the photo's sigma the fix is recorded unlocated, with the sigma
    in its reason; above it, located."""
    site_id, headers = create_site(client)
    sigma = max(upload(client, site_id, headers, photo_png).json()["position_sigma"])
    r = upload(client, site_id, headers, photo_png, max_sigma=str(0.5 * sigma))
    assert r.status_code == 200
    body = r.json()
    assert body["position"] is None and "too unsure" in body["error"]
    r = upload(client, site_id, headers, photo_png, max_sigma=str(2 * sigma))
    assert r.json()["position"] is not None


def test_locate_picks_the_named_camera(client, photo_png):
    site_id, headers = create_site(client, camera_name="front")
    # one camera: used without being named
    assert upload(client, site_id, headers, photo_png).json()["position"] is not None
    small = {**CAMERA_JSON, "image_width": 640, "image_height": 480, "focal_length_px": 500}
    client.put(f"/api/v1/sites/{site_id}/cameras/half", headers=headers, json=small)
    r = upload(client, site_id, headers, photo_png)
    assert r.status_code == 422 and "?camera=NAME" in detail(r)
    r = upload(client, site_id, headers, photo_png, query="?camera=front")
    assert r.status_code == 200 and r.json()["position"] is not None
    r = upload(client, site_id, headers, photo_png, query="?camera=half")
    assert r.status_code == 422
    assert detail(r) == "image is 1280 x 960 but the camera file says 640 x 480 (photo)"
    r = upload(client, site_id, headers, photo_png, query="?camera=nope")
    assert r.status_code == 404 and detail(r) == f"no camera 'nope' in site {site_id}"


def _png_header(width: int, height: int) -> bytes:
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + struct.pack(">I", 13)
        + b"IHDR"
        + ihdr
        + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr))
    )


def _jpeg_header(width: int, height: int) -> bytes:
    sof = b"\xff\xc0" + struct.pack(">HBHHB", 11, 8, height, width, 1) + b"\x01\x11\x00"
    return b"\xff\xd8" + sof + b"\xff\xda\x00\x02" + b"\x00" * 64


def test_bad_photos_get_4xx_and_the_service_goes_on(tmp_path, photo_png):
    with make_client(tmp_path, max_pixels=2_000_000, max_upload_bytes=3_000_000) as client:
        site_id, headers = create_site(client)
        cases = [
            # over the pixel limit: refused from the header alone (the rest is not an image)
            (_png_header(40_000, 30_000) + b"garbage" * 100, 413, "40000 x 30000 pixels"),
            (_jpeg_header(6000, 4000), 413, "6000 x 4000 pixels"),
            (b"\x00" * 3_100_000, 413, "request body over the limit of 2.86102 MB"),
            (b"", 400, "photo is empty (photo)"),
            (b"GIF89a not a photo", 415, "photo must be a JPEG or PNG (photo)"),
            (photo_png[:2000], 400, "not an image, or a corrupt one (photo)"),
            (encode(np.zeros((480, 640, 3), np.uint8)), 422, "image is 640 x 480 but the "),
        ]
        for data, status, words in cases:
            r = upload(client, site_id, headers, data)
            assert r.status_code == status, (status, r.text)
            if words:
                assert words in detail(r)
        for form, words in [
            ({"readout": "diagonal"}, "readout must be rows, columns, rows-reversed or columns-"),
            ({"gravity": "1,2"}, "gravity must be three numbers"),
            ({"mirrored": "perhaps"}, "mirrored: "),
            ({"max_sigma": "-1"}, "max_position_sigma must be a positive number"),
            ({"max_sigma": "a lot"}, "max_sigma: "),
        ]:
            r = upload(client, site_id, headers, photo_png, **form)
            assert r.status_code == 422 and words in detail(r), r.text
        # a body without Content-Length (chunked) is counted as it arrives
        head = b'--b0\r\nContent-Disposition: form-data; name="photo"; filename="p.png"\r\n\r\n'
        chunks = iter([head] + [b"\x00" * 100_000] * 40)
        multipart = {**headers, "Content-Type": "multipart/form-data; boundary=b0"}
        r = client.post(f"/api/v1/sites/{site_id}/locate", headers=multipart, content=chunks)
        assert r.status_code == 413 and "over the limit" in detail(r)
        r = client.post(f"/api/v1/sites/{site_id}/locate", headers=headers, data={"x": "1"})
        assert r.status_code == 422 and detail(r) == "photo: Field required"
        # still serving, and nothing of the refused photos was recorded
        assert upload(client, site_id, headers, photo_png).status_code == 200
        fixes = client.get(f"/api/v1/sites/{site_id}/fixes", headers=headers).json()["fixes"]
        assert len(fixes) == 1


def test_a_full_locate_queue_is_503(tmp_path, photo_png, monkeypatch):
    import camvlp.service.routes_api as service_app

    release = threading.Event()
    real_job = service_app._locate_job

    def slow_job(*args):
        release.wait(10)
        return real_job(*args)

    monkeypatch.setattr(service_app, "_locate_job", slow_job)
    with make_client(tmp_path, locate_threads=1, max_queued=1) as client:
        site_id, headers = create_site(client)
        answers: list[int] = []
        threads = [
            threading.Thread(
                target=lambda: answers.append(
                    upload(client, site_id, headers, photo_png).status_code
                )
            )
            for _ in range(2)
        ]
        for t in threads:
            t.start()
        time.sleep(1.0)  # both admitted: one locating, one waiting
        r = upload(client, site_id, headers, photo_png)
        release.set()
        for t in threads:
            t.join(30)
        assert r.status_code == 503 and r.headers["retry-after"] == "1"
        assert detail(r).startswith("busy: 2 photos")
        assert answers == [200, 200]


# --- fixes ----------------------------------------------------------------------------------


def test_fixes_are_listed_newest_first_with_paging_and_filters(client, photo_png):
    site_id, headers = create_site(client)
    ids = []
    for i in range(5):
        ids.append(upload(client, site_id, headers, photo_png, device=f"d{i % 2}").json()["fix_id"])
        if i == 2:
            time.sleep(0.05)
            middle = time.time()
    url = f"/api/v1/sites/{site_id}/fixes"
    page = client.get(url, headers=headers, params={"limit": 2}).json()
    assert [f["id"] for f in page["fixes"]] == ids[::-1][:2]
    assert page["next_before"] == ids[3]
    page2 = client.get(url, headers=headers, params={"limit": 2, "before": ids[3]}).json()
    assert [f["id"] for f in page2["fixes"]] == [ids[2], ids[1]]
    page3 = client.get(url, headers=headers, params={"limit": 2, "before": ids[1]}).json()
    assert [f["id"] for f in page3["fixes"]] == [ids[0]] and page3["next_before"] is None
    d1 = client.get(url, headers=headers, params={"device": "d1"}).json()["fixes"]
    assert [f["id"] for f in d1] == [ids[3], ids[1]]
    since = time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(middle)) + f"{middle % 1:.3f}"[1:]
    recent = client.get(url, headers=headers, params={"since": since + "Z"}).json()["fixes"]
    assert [f["id"] for f in recent] == [ids[4], ids[3]]
    for bad in ({"limit": 0}, {"limit": 5000}, {"since": "yesterday"}, {"before": "x"}):
        r = client.get(url, headers=headers, params=bad)
        assert r.status_code == 422, bad
        detail(r)


def test_the_annotated_picture_is_kept_when_asked_for(client, photo_png):
    site_id, headers = create_site(client)
    with_picture = upload(client, site_id, headers, photo_png, annotate="true").json()["fix_id"]
    without = upload(client, site_id, headers, photo_png).json()["fix_id"]
    r = client.get(f"/api/v1/sites/{site_id}/fixes/{with_picture}/picture", headers=headers)
    assert r.status_code == 200 and r.headers["content-type"] == "image/jpeg"
    picture = cv2.imdecode(np.frombuffer(r.content, np.uint8), cv2.IMREAD_COLOR)
    assert picture.shape == (960, 1280, 3)
    r = client.get(f"/api/v1/sites/{site_id}/fixes/{without}/picture", headers=headers)
    assert r.status_code == 404
    fixes = client.get(f"/api/v1/sites/{site_id}/fixes", headers=headers).json()["fixes"]
    assert [f["has_picture"] for f in fixes] == [False, True]
    assert client.get(f"/api/v1/sites/{site_id}/fixes/999", headers=headers).status_code == 404


def _events(text: str) -> list[dict]:
    events = []
    for block in text.split("\n\n"):
        fields = dict(line.split(": ", 1) for line in block.splitlines() if ": " in line)
        if fields.get("event") == "fix":
            events.append({"id": int(fields["id"]), "data": json.loads(fields["data"])})
    return events


def test_the_stream_sends_fixes_after_the_last_one_seen(client, photo_png):
    site_id, headers = create_site(client)
    ids = [
        upload(client, site_id, headers, photo_png, device="s").json()["fix_id"] for _ in range(3)
    ]
    url = f"/api/v1/sites/{site_id}/fixes/stream"
    r = client.get(url, headers=headers, params={"after": ids[0]})  # closes after stream_max_s
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/event-stream")
    events = _events(r.text)
    assert [e["id"] for e in events] == ids[1:]
    assert events[0]["data"]["device"] == "s" and events[0]["data"]["position"] is not None
    resumed = client.get(url, headers={**headers, "Last-Event-ID": str(ids[1])})
    assert [e["id"] for e in _events(resumed.text)] == ids[2:]
    assert _events(client.get(url, headers=headers).text) == []  # default: only new fixes


def test_the_stream_delivers_a_fix_made_while_it_is_open(tmp_path, photo_png):
    with make_client(tmp_path, stream_max_s=2.0) as client:
        site_id, headers = create_site(client)
        got: list[str] = []
        reader = threading.Thread(
            target=lambda: got.append(
                client.get(f"/api/v1/sites/{site_id}/fixes/stream", headers=headers).text
            )
        )
        reader.start()
        time.sleep(0.5)
        fix_id = upload(client, site_id, headers, photo_png, device="live").json()["fix_id"]
        reader.join(10)
        assert [e["id"] for e in _events(got[0])] == [fix_id]


# --- page and documentation -----------------------------------------------------------------


def test_the_page_and_the_docs_are_served(client):
    r = client.get("/sites/1")
    assert r.status_code == 200 and "text/html" in r.headers["content-type"]
    assert '<script type="module" src="/static/site.js">' in r.text
    r = client.get("/sites/1/capture")
    assert r.status_code == 200 and '<script type="module" src="/static/capture.js">' in r.text
    for asset in ("site.js", "site.css", "common.js", "capture.js"):
        assert client.get(f"/static/{asset}").status_code == 200
    assert client.get("/static/nope.js").status_code == 404
    spec = client.get("/openapi.json").json()
    for path in (
        "/api/v1/sites",
        "/api/v1/sites/{site_id}",
        "/api/v1/sites/{site_id}/map",
        "/api/v1/sites/{site_id}/cameras/{name}",
        "/api/v1/sites/{site_id}/locate",
        "/api/v1/sites/{site_id}/fixes",
        "/api/v1/sites/{site_id}/fixes/stream",
        "/api/v1/sites/{site_id}/fixes/{fix_id}",
        "/api/v1/sites/{site_id}/fixes/{fix_id}/picture",
        "/api/v1/sites/{site_id}/frames",
    ):
        assert path in spec["paths"], path
    assert client.get("/docs").status_code == 200
    assert client.get("/api/v1/health").json()["ok"] is True
