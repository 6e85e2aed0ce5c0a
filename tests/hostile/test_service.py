"""``camvlp serve`` under the second round's hostile input: what is stored can be read back,
headers are parsed defensively, sites need the admin key, bodies are read only once
admitted, slow clients are cut off, a bad database is one line."""

from __future__ import annotations

import json
import socket
import sys
import time
from pathlib import Path

import httpx
import pytest
from bad_inputs import scan_bomb

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "service"))

from service_helpers import (
    ADMIN,
    CAMERA_JSON,
    MAP_JSON,
    create_site,
    free_port,
    make_client,
    start_server,
    stop_server,
)

from conftest import one_error_line


def _detail(r: httpx.Response) -> str:
    return r.json()["detail"]


def _site_body(**map_extra) -> dict:
    return {"name": "x", "map": {**MAP_JSON, **map_extra}, "camera": CAMERA_JSON}


@pytest.mark.parametrize(
    ("text", "words"),
    [
        (json.dumps(_site_body(notes=json.loads("[" * 40 + "]" * 40))), "nested 42 deep"),
        (json.dumps(_site_body())[:-1] + ', "\\ud800": 1}', "not valid Unicode"),
        (json.dumps(_site_body(notes="\\ud83d")).replace("\\\\ud83d", "\\ud83d"), "not valid"),
        (json.dumps(_site_body())[:-1] + ', "notes": NaN}', "is not a number"),
    ],
    ids=["deep unknown key", "lone surrogate key", "lone surrogate value", "NaN"],
)
def test_what_could_not_be_read_back_is_not_stored(tmp_path, text, words):
    with make_client(tmp_path) as client:
        r = client.post(
            "/api/v1/sites", content=text, headers={**ADMIN, "Content-Type": "application/json"}
        )
        assert r.status_code == 422 and words in _detail(r), r.text
        site_id, headers = create_site(client)  # the service goes on, its data intact
        assert client.get(f"/api/v1/sites/{site_id}", headers=headers).status_code == 200
        r = client.put(f"/api/v1/sites/{site_id}/map", content=text, headers=headers)
        assert r.status_code == 422


@pytest.mark.parametrize(
    ("header", "value", "status"),
    [
        ("Last-Event-ID", "²", 400),
        ("Last-Event-ID", "9" * 5000, 422),
        ("Last-Event-ID", "12abc", 400),
        ("Content-Length", "²", 400),
    ],
)
def test_headers_are_parsed_defensively(tmp_path, header, value, status):
    with make_client(tmp_path, stream_max_s=0.1) as client:
        site_id, headers = create_site(client)
        url = f"/api/v1/sites/{site_id}/fixes/stream"
        r = client.get(url, headers={**headers, header: value.encode()})  # "²": UTF-8 bytes
        assert r.status_code == status and header in _detail(r), r.text


def test_only_the_admin_key_creates_sites(tmp_path):
    with make_client(tmp_path) as client:
        for headers, words in (
            ({}, "needs the admin key"),
            ({"Authorization": "Bearer not-the-admin-key"}, "wrong admin key"),
        ):
            r = client.post("/api/v1/sites", json=_site_body(), headers=headers)
            assert r.status_code == 401 and words in _detail(r)
        _site_id, headers = create_site(client)  # a site's own key creates no site either
        assert client.post("/api/v1/sites", json=_site_body(), headers=headers).status_code == 401
    (tmp_path / "none").mkdir()
    with make_client(tmp_path / "none", admin_key="") as client:  # no admin key: no sites
        r = client.post("/api/v1/sites", json=_site_body(), headers=ADMIN)
        assert r.status_code == 401 and "CAMVLP_ADMIN_KEY" in _detail(r)


def test_a_photo_is_read_only_once_admitted(tmp_path):
    """With the locate queue full the answer is 503, whatever the body holds: the body was
    not read (a header check before the gate would answer 415 to this one)."""
    with make_client(tmp_path, locate_threads=1, max_queued=1) as client:
        site_id, headers = create_site(client)
        gate = client.app.state.gate
        gate.busy = gate.limit
        files = {"photo": ("p.jpg", b"GIF89a not a photo", "image/jpeg")}
        r = client.post(f"/api/v1/sites/{site_id}/locate", headers=headers, files=files)
        assert r.status_code == 503, r.text
        gate.busy = 0
        r = client.post(f"/api/v1/sites/{site_id}/locate", headers=headers, files=files)
        assert r.status_code == 415
        bomb = {"photo": ("b.jpg", scan_bomb(500, 64), "image/jpeg")}
        r = client.post(f"/api/v1/sites/{site_id}/locate", headers=headers, files=bomb)
        assert r.status_code == 400 and "scans" in _detail(r)


def _read_all(sock: socket.socket, seconds: float) -> tuple[bytes, float]:
    """What the server sends until it closes the connection (or ``seconds`` pass)."""
    sock.settimeout(seconds)
    t0, data = time.monotonic(), b""
    try:
        while chunk := sock.recv(4096):
            data += chunk
    except TimeoutError:
        return data + b"<still open>", time.monotonic() - t0
    return data, time.monotonic() - t0


def test_slow_clients_are_cut_off_and_others_served(tmp_path, monkeypatch):
    """Slow headers, a body that stops, a chunk announcing 2^76 bytes: each gets 408 and its
    connection closed within the timeouts (1 s here), while a normal request is answered."""
    monkeypatch.setenv("CAMVLP_HEADER_TIMEOUT_S", "1")
    monkeypatch.setenv("CAMVLP_BODY_TIMEOUT_S", "1")
    port = free_port()
    proc = start_server(tmp_path / "slow.db", port)
    try:
        head = f"POST /api/v1/sites HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n".encode()
        openings = [
            b"GET /api/v1/health HTTP/1.1\r\nHost: x\r\nX-Slow: ",  # headers never finish
            head + b"Content-Length: 100\r\n\r\n{",  # a body that stops
            head + b"Transfer-Encoding: chunked\r\n\r\nfffffffffffffffffff\r\nab",
        ]
        socks = [socket.create_connection(("127.0.0.1", port)) for _ in range(10)]
        for k, sock in enumerate(socks):
            sock.sendall(openings[k % len(openings)])
        t0 = time.monotonic()
        r = httpx.get(f"http://127.0.0.1:{port}/api/v1/health", timeout=5)
        assert r.status_code == 200 and time.monotonic() - t0 < 1.0
        for sock in socks:
            data, _ = _read_all(sock, 5.0)
            sock.close()
            assert data.startswith(b"HTTP/1.1 408"), data[:80]
        assert time.monotonic() - t0 < 5.0
    finally:
        _, err = stop_server(proc)
    assert "Traceback" not in err


def test_a_database_that_is_not_one_is_one_line(tmp_path, capsys):
    from camvlp.cli import main

    gif = tmp_path / "photo.gif"
    gif.write_bytes(b"GIF89a" + bytes(2000))
    for db in (f"sqlite:///{gif}", f"sqlite:///{tmp_path}"):
        assert main(["serve", "--db", db, "--port", str(free_port())]) == 2
        assert "cannot open the database" in one_error_line(capsys.readouterr().err)
