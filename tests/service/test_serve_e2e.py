"""``camvlp serve`` for real: a server process on 127.0.0.1, a SQLite file, a restart."""

from __future__ import annotations

import json
from pathlib import Path

import httpx
import numpy as np
import pytest
from service_helpers import (
    ADMIN,
    CAMERA_JSON,
    MAP_JSON,
    PHOTO_POSITION,
    free_port,
    photo_png,  # noqa: F401  (fixture)
    self_signed,
    start_server,
    stop_server,
    tls_context,
)

from camvlp.cli import main
from conftest import one_error_line

pytestmark = pytest.mark.long  # seconds a test: run first (tests/conftest.py)


def test_a_fix_survives_a_restart(tmp_path: Path, photo_png):
    db = tmp_path / "camvlp.db"
    port = free_port()
    base = f"http://127.0.0.1:{port}/api/v1"
    proc = start_server(db, port)
    try:
        r = httpx.post(
            f"{base}/sites",
            json={"name": "e2e", "map": MAP_JSON, "camera": CAMERA_JSON},
            headers=ADMIN,
        )
        assert r.status_code == 201, r.text
        site_id, key = r.json()["id"], r.json()["api_key"]
        headers = {"Authorization": f"Bearer {key}"}
        r = httpx.post(
            f"{base}/sites/{site_id}/locate",
            headers=headers,
            files={"photo": ("photo.png", photo_png, "image/png")},
            data={"device": "e2e-phone"},
            timeout=60,
        )
        assert r.status_code == 200, r.text
        fix = r.json()
        np.testing.assert_allclose(fix["position"], PHOTO_POSITION, atol=2e-3)
    finally:
        stop_server(proc)
    assert db.exists()

    proc = start_server(db, port)
    try:
        r = httpx.get(f"{base}/sites/{site_id}/fixes", headers=headers)
        assert r.status_code == 200
        fixes = r.json()["fixes"]
        assert [f["id"] for f in fixes] == [fix["fix_id"]]
        assert fixes[0]["position"] == fix["position"] and fixes[0]["device"] == "e2e-phone"
        assert httpx.get(f"{base}/sites/{site_id}").status_code == 401  # keys still checked
    finally:
        _, err = stop_server(proc)
    assert "Traceback" not in err


def test_serve_refuses_bad_options_in_one_line(tmp_path: Path, capsys):
    from camvlp.cli import main

    db = f"sqlite:///{tmp_path / 'x.db'}"
    (tmp_path / "x.db").write_bytes(b"")  # a file: no folder can be made in its place
    for args, words in (
        (["--port", "0"], "--port must be 1 to 65535"),
        (["--workers", "0"], "--workers must be a positive number"),
        (["--max-upload-mb", "-1"], "--max-upload-mb must be a positive number"),
        (["--db", "nosuchdb://x"], "cannot open the database"),
        (["--db", f"sqlite:///{tmp_path / 'x.db' / 'dir.db'}"], "the database's folder"),
        (["--log-level", "loud"], "--log-level must be one of critical, error"),
        (["--host", "256.1.1.1"], "cannot listen on 256.1.1.1:8000"),
    ):
        code = main(["serve", *(["--db", db] if "--db" not in args else []), *args])
        assert code == 2, args
        assert words in one_error_line(capsys.readouterr().err), args


def test_serve_refuses_a_port_in_use_in_one_line(tmp_path: Path, capsys, monkeypatch):
    """A port another process listens on: one line and exit 2, before the service starts."""
    import os
    import socket

    from camvlp.cli import main

    monkeypatch.setattr(os, "environ", dict(os.environ))  # serve exports its settings
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        code = main(["serve", "--db", f"sqlite:///{tmp_path / 'x.db'}", "--port", str(port)])
    assert code == 2
    assert f"cannot listen on 127.0.0.1:{port}" in one_error_line(capsys.readouterr().err)


def test_the_stream_carries_fixes_of_every_worker(tmp_path: Path, photo_png):
    """With two service processes, one stream sees every fix, whichever process made it."""
    import json
    import threading

    port = free_port()
    base = f"http://127.0.0.1:{port}/api/v1"
    proc = start_server(tmp_path / "two.db", port, "--workers", "2")
    try:
        r = httpx.post(
            f"{base}/sites",
            json={"name": "two", "map": MAP_JSON, "camera": CAMERA_JSON},
            headers=ADMIN,
        )
        site_id, headers = r.json()["id"], {"Authorization": f"Bearer {r.json()['api_key']}"}
        seen: list[int] = []
        opened = threading.Event()

        def follow() -> None:
            with httpx.stream(
                "GET", f"{base}/sites/{site_id}/fixes/stream", headers=headers, timeout=30
            ) as stream:
                opened.set()
                for line in stream.iter_lines():
                    if line.startswith("data: "):
                        seen.append(json.loads(line[6:])["id"])
                        if len(seen) == 4:
                            return

        reader = threading.Thread(target=follow, daemon=True)
        reader.start()
        assert opened.wait(15)
        made = []
        for i in range(4):
            with httpx.Client() as fresh:  # a new connection each: either process may take it
                r = fresh.post(
                    f"{base}/sites/{site_id}/locate",
                    headers=headers,
                    files={"photo": ("photo.png", photo_png, "image/png")},
                    data={"device": f"w{i}"},
                    timeout=60,
                )
            assert r.status_code == 200, r.text
            made.append(r.json()["fix_id"])
        reader.join(20)
        assert seen == made
    finally:
        stop_server(proc)


def test_serve_https_with_a_self_signed_certificate(tmp_path: Path, capsys):
    tls = self_signed(tmp_path)
    if tls is None:
        pytest.skip("no openssl to make a certificate")
    port = free_port()
    proc = start_server(tmp_path / "tls.db", port, "--log-level", "info", tls=tls)
    try:
        base = f"https://127.0.0.1:{port}"
        trust = tls_context(tls[0])
        r = httpx.get(f"{base}/sites/1/capture?device=phone-3", verify=trust)
        assert r.status_code == 200 and "capture.js" in r.text
        with pytest.raises(httpx.ConnectError):  # a client that does not trust it stops
            httpx.get(f"{base}/api/v1/health")
        with pytest.raises(httpx.HTTPError):  # and plain HTTP gets no answer
            httpx.get(f"http://127.0.0.1:{port}/api/v1/health", timeout=3)
    finally:
        _, err = stop_server(proc)
    # every line of the log is one JSON object; each request one line, without its query
    lines = [json.loads(line) for line in err.splitlines() if line.strip()]
    requests = [line for line in lines if line["logger"] == "camvlp.access"]
    page = [line for line in requests if line["path"] == "/sites/1/capture"]
    assert len(page) == 1 and page[0]["status"] == 200 and page[0]["device"] == "phone-3"
    assert page[0]["route"] == "/sites/{site_id}/capture" and page[0]["site"] == 1
    assert any(line["logger"].startswith("uvicorn") for line in lines)
    # a key without its certificate, a file that is not a key, a key of another certificate
    (tmp_path / "other").mkdir()
    other = self_signed(tmp_path / "other")
    cases = [
        (["--tls-cert", str(tls[0])], "--tls-cert and --tls-key go together"),
        (["--tls-cert", str(tls[0]), "--tls-key", str(tmp_path / "tls.db")], "cannot use"),
        (["--tls-cert", str(tls[0]), "--tls-key", str(other[1])], "cannot use"),
        (["--tls-cert", str(tmp_path / "none.pem"), "--tls-key", str(tls[1])], "is not a file"),
    ]
    for args, words in cases:
        assert main(["serve", "--db", f"sqlite:///{tmp_path / 'x.db'}", *args]) == 2
        assert words in one_error_line(capsys.readouterr().err), args
