"""The site's page and the API's documentation in headless Chromium: the page draws the plan,
uploads a photo, shows the fix; Swagger UI and ReDoc render with nothing from other hosts.

Skipped when no Chromium (Debian's package) or no playwright is installed.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import httpx
import pytest
from service_helpers import (
    ADMIN,
    CAMERA_JSON,
    CHROMIUM,
    CHROMIUM_ARGS,
    MAP_JSON,
    SCREENSHOTS,
    free_port,
    needs_chromium,
    photo_png,  # noqa: F401  (fixture)
    start_server,
    stop_server,
)

pytestmark = [needs_chromium, pytest.mark.long]  # a browser: run first (tests/conftest.py)


def test_the_page_draws_an_uploaded_fix(tmp_path: Path, photo_png):
    sync_api = pytest.importorskip("playwright.sync_api")
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    proc = start_server(tmp_path / "page.db", port)
    try:
        site = httpx.post(
            f"{base}/api/v1/sites",
            json={"name": "browser", "map": MAP_JSON, "camera": CAMERA_JSON},
            headers=ADMIN,
        ).json()
        photo = tmp_path / "photo.png"
        photo.write_bytes(photo_png)
        with sync_api.sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
            try:
                page = browser.new_page()
                errors: list[str] = []
                page.on("pageerror", lambda exc: errors.append(str(exc)))
                page.goto(f"{base}/sites/{site['id']}#key={site['api_key']}")
                # the plan: one disc per fixture; the key left the address bar
                page.wait_for_selector("g.fixture")
                ids = page.eval_on_selector_all(
                    "g.fixture", "els => els.map(e => Number(e.dataset.fixtureId))"
                )
                assert sorted(ids) == sorted(f["id"] for f in MAP_JSON["fixtures"])
                assert "key=" not in page.url
                assert page.locator("g.fix").count() == 0
                page.wait_for_selector("#status.live")
                # upload a photo: the fix is drawn, its text and picture shown
                page.set_input_files("#photo", str(photo))
                page.fill("#device", "browser-test")
                page.click("#locate-button")
                page.wait_for_selector("g.fix.latest[data-device='browser-test']", timeout=30_000)
                page.wait_for_selector("#annotated:not([hidden])", timeout=30_000)
                assert "position (0.10" in page.inner_text("#result-text")
                sigma = re.search(r"uncertainty \(([^)]*)\) m", page.inner_text("#result-text"))
                assert sigma and 0 < max(map(float, sigma[1].split(", "))) < 0.01
                width = page.eval_on_selector("#annotated", "img => img.naturalWidth")
                assert width == CAMERA_JSON["image_width"]
                # a fix made elsewhere arrives through the stream
                httpx.post(
                    f"{base}/api/v1/sites/{site['id']}/locate",
                    headers={"Authorization": f"Bearer {site['api_key']}"},
                    files={"photo": ("p.png", photo_png, "image/png")},
                    data={"device": "robot-9"},
                    timeout=60,
                )
                page.wait_for_selector("g.fix.latest[data-device='robot-9']", timeout=15_000)
                # a tab without the key asks for it, refuses a wrong one, opens with the right one
                ask = browser.new_page()
                ask.on("pageerror", lambda exc: errors.append(str(exc)))
                ask.goto(f"{base}/sites/{site['id']}")
                ask.wait_for_selector("#key-panel:not([hidden])")
                assert ask.is_hidden("#main")
                ask.fill("#key-input", "cvlp_wrong")
                ask.click("#key-form button")
                ask.wait_for_selector("#key-error:not([hidden])")
                assert ask.inner_text("#key-error") == "wrong API key" and ask.is_hidden("#main")
                ask.fill("#key-input", site["api_key"])
                ask.click("#key-form button")
                ask.wait_for_selector("g.fix.latest[data-device='robot-9']", timeout=15_000)
                assert ask.is_hidden("#key-panel")
                assert errors == []
            finally:
                browser.close()
    finally:
        stop_server(proc)


def test_the_api_documentation_renders_offline(tmp_path: Path):
    """Swagger UI and ReDoc render from the service's own files: every request the pages
    make goes to the service (any other is refused and counted), and the operations show."""
    sync_api = pytest.importorskip("playwright.sync_api")
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    proc = start_server(tmp_path / "docs.db", port)
    elsewhere: list[str] = []

    def only_here(route) -> None:
        if route.request.url.startswith(base + "/"):
            route.continue_()
        else:
            elsewhere.append(route.request.url)
            route.abort()

    try:
        with sync_api.sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
            try:
                page = browser.new_page(viewport={"width": 1200, "height": 900})
                page.route("**/*", only_here)
                page.goto(f"{base}/docs")
                page.wait_for_selector(".opblock-summary-path", timeout=30_000)
                paths = page.eval_on_selector_all(
                    ".opblock-summary-path", "els => els.map(e => e.dataset.path)"
                )
                assert "/api/v1/sites/{site_id}/frames" in paths
                assert "/api/v1/sites/{site_id}/locate" in paths and len(paths) >= 11
                assert page.locator(".opblock-summary-path").first.is_visible()
                _screenshot(page, tmp_path / "docs.png")
                redoc = browser.new_page(viewport={"width": 1200, "height": 900})
                redoc.route("**/*", only_here)
                redoc.goto(f"{base}/redoc")
                # every operation has its section, with its heading, in the page
                operation = redoc.get_by_role("heading", name="Post Frame").first
                operation.wait_for(state="visible", timeout=30_000)
                assert redoc.get_by_role("heading", name="Locate Photo").first.is_visible()
                _screenshot(redoc, tmp_path / "redoc.png")
            finally:
                browser.close()
    finally:
        stop_server(proc)
    assert elsewhere == []


def _screenshot(page, shot: Path) -> None:
    """Take ``page``'s screenshot into ``shot``, and a copy into ``CAMVLP_SCREENSHOTS``."""
    page.screenshot(path=str(shot))
    assert shot.stat().st_size > 0
    if SCREENSHOTS:
        shutil.copy(shot, Path(SCREENSHOTS) / shot.name)
