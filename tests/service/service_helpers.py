"""Shared pieces of the service tests: the small room as JSON, a rendered photo, a client."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from conftest import (
    CEILING_Y,
    LOOK_UP,
    SMALL_DIAMETER,
    SMALL_FOCAL_PX,
    SMALL_ROOM_IDS,
    SMALL_ROOM_XZ,
    SMALL_ROW_TIME_S,
    SMALL_SIZE,
    make_small_camera,
    make_small_room,
    small_settings,
)

#: The small test camera as a camera file's keys (JSON).
CAMERA_JSON = {
    "image_width": SMALL_SIZE[0],
    "image_height": SMALL_SIZE[1],
    "focal_length_px": SMALL_FOCAL_PX,
    "row_time_s": SMALL_ROW_TIME_S,
}
#: The small test room as a map file's keys (JSON): y-down, ceiling at y = -2.7 m.
MAP_JSON = {
    "units": "m",
    "fixtures": [
        {"id": i, "position": [x, CEILING_Y, z], "diameter": SMALL_DIAMETER, "normal": [0, 1, 0]}
        for i, (x, z) in zip(SMALL_ROOM_IDS, SMALL_ROOM_XZ, strict=True)
    ],
}
#: The admin key the test services run with (``CAMVLP_ADMIN_KEY``), and its header: it
#: creates sites.
ADMIN_KEY = "test-admin-key-of-the-service"
ADMIN = {"Authorization": f"Bearer {ADMIN_KEY}"}
#: Where the photos of :func:`render_photo` are taken (metres, thesis angles in degrees).
PHOTO_POSITION = (0.1, 0.0, -0.05)
PHOTO_EULER = (LOOK_UP[0], 0.0, 30.0)


def render_photo(position=PHOTO_POSITION, euler=PHOTO_EULER, seed: int = 3) -> np.ndarray:
    """A 1280 x 960 render of the small room (BGR uint8)."""
    from camvlp.model.camera import Pose
    from camvlp.sim.render import render

    pose = Pose.from_euler(list(position), list(euler))
    return render(make_small_camera(), make_small_room(), pose, small_settings(seed=seed)).image


def encode(image: np.ndarray, ext: str = ".png") -> bytes:
    """The image encoded as PNG or JPEG bytes."""
    ok, buf = cv2.imencode(ext, image)
    assert ok
    return buf.tobytes()


@pytest.fixture(scope="session")
def photo_png() -> bytes:
    """PNG bytes of a render of the small room from ``PHOTO_POSITION``."""
    return encode(render_photo())


#: Run the API tests against this database instead of a SQLite file, e.g.
#: ``postgresql+psycopg://user:password@127.0.0.1/camvlp_test`` (its tables are dropped first).
TEST_DB_URL = os.environ.get("CAMVLP_TEST_DB_URL")


def drop_all(url: str) -> None:
    """Drop the service's tables and Alembic's version table from the database at ``url``."""
    import sqlalchemy as sa

    from camvlp.service.db import make_engine, metadata

    engine = make_engine(url)
    try:
        metadata.drop_all(engine)
        with engine.begin() as conn:
            conn.execute(sa.text("DROP TABLE IF EXISTS alembic_version"))
    finally:
        engine.dispose()


def make_client(tmp_path: Path, **settings):
    """A TestClient of a fresh service on a SQLite file in ``tmp_path`` (or ``TEST_DB_URL``)."""
    from fastapi.testclient import TestClient

    from camvlp.service import ServiceSettings, create_app

    settings.setdefault("stream_max_s", 0.5)
    settings.setdefault("admin_key", ADMIN_KEY)
    settings.setdefault("stream_poll_s", 0.05)
    url = f"sqlite:///{tmp_path / 'service.db'}"
    if TEST_DB_URL:
        url = TEST_DB_URL
        drop_all(url)
    return TestClient(create_app(ServiceSettings(db=url, **settings)))


@pytest.fixture
def client(tmp_path: Path):
    """A TestClient of a fresh service (its lifespan runs)."""
    with make_client(tmp_path) as c:
        yield c


def create_site(client, name: str = "small room", **extra) -> tuple[int, dict]:
    """Create the small room's site: ``(site_id, headers with its key)``."""
    r = client.post(
        "/api/v1/sites",
        json={"name": name, "map": MAP_JSON, "camera": CAMERA_JSON, **extra},
        headers=ADMIN,
    )
    assert r.status_code == 201, r.text
    body = r.json()
    return body["id"], {"Authorization": f"Bearer {body['api_key']}"}


# --- a real server ---------------------------------------------------------------------------


def free_port() -> int:
    """A TCP port on 127.0.0.1 that is free right now."""
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_server(
    db_path: Path,
    port: int,
    *args: str,
    timeout_s: float = 30.0,
    tls: tuple[Path, Path] | None = None,
):
    """Start ``camvlp serve`` on 127.0.0.1:port with a SQLite file; wait until it answers.

    With ``tls`` (a certificate and its key), it serves HTTPS, checked against that
    certificate.  Returns the ``subprocess.Popen``; stop it with :func:`stop_server`.
    """
    import os
    import subprocess
    import sys
    import time

    import httpx

    import camvlp

    env = dict(os.environ)
    env.setdefault("CAMVLP_ADMIN_KEY", ADMIN_KEY)
    src = str(Path(camvlp.__file__).resolve().parents[1])
    env["PYTHONPATH"] = os.pathsep.join([src, env.get("PYTHONPATH", "")])
    cmd = [sys.executable, "-m", "camvlp", "serve", "--db", f"sqlite:///{db_path}"]
    cmd += ["--host", "127.0.0.1", "--port", str(port), "--log-level", "warning", *args]
    health, verify = f"http://127.0.0.1:{port}/api/v1/health", True
    if tls is not None:
        cmd += ["--tls-cert", str(tls[0]), "--tls-key", str(tls[1])]
        health, verify = health.replace("http:", "https:"), tls_context(tls[0])
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            _, err = proc.communicate()
            raise RuntimeError(f"camvlp serve exited {proc.returncode}: {err.decode()[-2000:]}")
        try:
            if httpx.get(health, timeout=1.0, verify=verify).status_code == 200:
                return proc
        except httpx.HTTPError:
            pass
        time.sleep(0.1)
    stop_server(proc)
    raise RuntimeError(f"camvlp serve did not answer within {timeout_s} s")


def tls_context(cert: Path):
    """An SSL context that trusts ``cert`` alone (a self-signed certificate)."""
    import ssl

    return ssl.create_default_context(cafile=str(cert))


def self_signed(folder: Path) -> tuple[Path, Path] | None:
    """A certificate for 127.0.0.1 and its key (openssl, 2 days), or None without openssl."""
    import subprocess

    openssl = shutil.which("openssl")
    if openssl is None:
        return None
    cert, key = folder / "cert.pem", folder / "key.pem"
    subprocess.run(
        [openssl, "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "2", "-subj",
         "/CN=127.0.0.1", "-addext", "subjectAltName=IP:127.0.0.1", "-keyout", str(key),
         "-out", str(cert)],
        check=True, capture_output=True,
    )  # fmt: skip
    return cert, key


def stop_server(proc) -> tuple[str, str]:
    """Stop a server of :func:`start_server` (SIGTERM, then SIGKILL); its stdout and stderr."""
    import subprocess

    proc.terminate()
    try:
        out, err = proc.communicate(timeout=15)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
    return out.decode(errors="replace"), err.decode(errors="replace")


# --- a real browser --------------------------------------------------------------------------

#: Debian's Chromium, driven by playwright (its own browser downloads are not used).
CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
#: Headless, and quiet: no connection of its own to anywhere.
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
#: Skips a test when there is no Chromium to drive.
needs_chromium = pytest.mark.skipif(not Path(CHROMIUM).exists(), reason="no chromium installed")
#: When set, the browser tests also save their screenshots into this folder (docs/serve).
SCREENSHOTS = os.environ.get("CAMVLP_SCREENSHOTS")
