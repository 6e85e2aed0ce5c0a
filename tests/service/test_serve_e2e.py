"""``camvlp serve`` for real: a server process on 127.0.0.1, a SQLite file, a restart."""

from __future__ import annotations

from pathlib import Path

import httpx
import numpy as np
from service_helpers import (
    CAMERA_JSON,
    MAP_JSON,
    PHOTO_POSITION,
    free_port,
    photo_png,  # noqa: F401  (fixture)
    start_server,
    stop_server,
)


def test_a_fix_survives_a_restart(tmp_path: Path, photo_png):
    db = tmp_path / "camvlp.db"
    port = free_port()
    base = f"http://127.0.0.1:{port}/api/v1"
    proc = start_server(db, port)
    try:
        r = httpx.post(
            f"{base}/sites", json={"name": "e2e", "map": MAP_JSON, "camera": CAMERA_JSON}
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


def test_serve_refuses_bad_options_in_one_line(tmp_path: Path):
    import subprocess
    import sys

    for args in (["--port", "0"], ["--workers", "0"], ["--db", "nosuchdb://x"]):
        r = subprocess.run(
            [sys.executable, "-m", "camvlp", "serve", *args],
            capture_output=True,
            text=True,
            timeout=60,
            cwd=tmp_path,
        )
        assert r.returncode == 2, (args, r.stderr)
        lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
        assert len(lines) == 1 and lines[0].startswith("error: "), r.stderr
