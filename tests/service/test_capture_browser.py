"""The camera page in headless Chromium, its camera a video of known truth.

Chromium's fake camera plays a video that ``camvlp render-video`` made (see
``capture_video.py``), the phone's gravity is given to the page as motion events, and the
page locates frame after frame through a real ``camvlp serve``.  Each frame the page sends is
caught on its way (playwright's routing) and told apart from the video's other frames by its
pixels, so that every position the page shows is compared with the truth of that very frame.

Skipped when no Chromium (Debian's package) or no playwright is installed.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import cv2
import httpx
import numpy as np
import pytest
from capture_video import CAMERA_JSON, make_capture_video
from service_helpers import (
    ADMIN,
    CHROMIUM,
    CHROMIUM_ARGS,
    MAP_JSON,
    SCREENSHOTS,
    free_port,
    needs_chromium,
    start_server,
    stop_server,
)

pytestmark = [needs_chromium, pytest.mark.long]  # a browser: run first (tests/conftest.py)

#: Frames the page must answer before the test looks, then photos (takePhoto) after them.
FRAMES, PHOTOS = 45, 5
#: The most a used fixture's pixel may be from the truth's pixel of that ID, pixels.
ID_PIXEL_TOLERANCE = 8.0
#: Gravity's size, m/s^2 (the accelerometer reads its reaction).
G = 9.81


def _run_page(video, tmp_path: Path) -> dict:
    """Open the camera page on a real ``camvlp serve`` with the video as Chromium's camera
    and the video's gravity as motion events; after ``FRAMES`` answers, what it showed."""
    sync_api = pytest.importorskip("playwright.sync_api")
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    proc = start_server(tmp_path / "capture.db", port)
    sent: dict[int, tuple[int, float]] = {}  # page's seq -> (video frame, match ratio)
    errors: list[str] = []
    try:
        site = httpx.post(
            f"{base}/api/v1/sites",
            json={"name": "capture test", "map": MAP_JSON, "camera": CAMERA_JSON},
            headers=ADMIN,
        ).json()
        args = [
            *CHROMIUM_ARGS,
            "--use-fake-ui-for-media-stream",
            "--use-fake-device-for-media-stream",
            f"--use-file-for-fake-video-capture={video.y4m}",
        ]

        def catch(route) -> None:  # which frame of the video the page is sending
            body = route.request.post_data_buffer
            gray = cv2.imdecode(np.frombuffer(body, np.uint8), cv2.IMREAD_GRAYSCALE)
            sent[int(route.request.headers["x-frame-seq"])] = video.which_frame(gray)
            route.continue_()

        # the phone's accelerometer: the reaction to gravity, in the device's axes (x right,
        # y up the screen, z out of it) of a phone upright whose rear camera has the video's
        # gravity: camera (x, y, z) = device (x, -y, -z)
        gc = video.gravity
        reaction = {"x": -G * gc[0], "y": G * gc[1], "z": G * gc[2]}
        with sync_api.sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=args)
            try:
                page = browser.new_page(viewport={"width": 1200, "height": 860})
                page.on("pageerror", lambda exc: errors.append(str(exc)))
                page.route("**/api/v1/sites/*/frames?*", catch)
                page.goto(f"{base}/sites/{site['id']}/capture#key={site['api_key']}")
                page.wait_for_selector("g.fixture")
                page.evaluate(
                    """(a) => setInterval(() => window.dispatchEvent(new DeviceMotionEvent(
                        "devicemotion", {accelerationIncludingGravity: a, interval: 20})), 20)""",
                    reaction,
                )
                page.click("#start")
                page.wait_for_function(
                    f"() => window.camvlpCapture.results.length >= {FRAMES}", timeout=90_000
                )
                shot = tmp_path / "capture.png"
                page.screenshot(path=str(shot), full_page=True)  # running: the video shows
                if SCREENSHOTS:
                    shutil.copy(shot, Path(SCREENSHOTS) / "capture.png")
                page.click("#stop")
                page.wait_for_function("() => window.camvlpCapture.idle", timeout=30_000)
                frames = len(page.evaluate("window.camvlpCapture.results"))
                position = page.inner_text("#st-position")
                # full-resolution photos instead (Chromium's fake camera takes PNG photos)
                page.select_option("#mode", "photos")
                page.click("#start")
                page.wait_for_function(
                    f"() => window.camvlpCapture.results.length >= {frames + PHOTOS}",
                    timeout=60_000,
                )
                page.click("#stop")
                page.wait_for_function("() => window.camvlpCapture.idle", timeout=30_000)
                results = page.evaluate("window.camvlpCapture.results")
                return {
                    "results": results[:frames],
                    "photos": results[frames:],
                    "sent": sent,
                    "errors": errors,
                    "position": position,
                    "exposure": page.inner_text("#exposure-note"),
                    "gravity": page.inner_text("#gravity-note"),
                }
            finally:
                browser.close()
    finally:
        stop_server(proc)


def test_the_camera_page_locates_a_rendered_video(tmp_path: Path):
    pytest.importorskip("playwright.sync_api")
    video = make_capture_video(tmp_path / "video")
    shown = _run_page(video, tmp_path)
    results, sent, errors = shown["results"], shown["sent"], shown["errors"]
    assert errors == []
    assert len(results) >= FRAMES
    assert all(r["seq"] in sent for r in results), "a frame the page sent was not caught"
    ratios = [sent[r["seq"]][1] for r in results]
    assert max(ratios) < 0.5, f"a sent frame is not clearly one of the video's: {max(ratios)}"
    located = [r for r in results if r["located"]]
    share = len(located) / len(results)
    errors_mm, wrong = [], 0
    for r in located:
        k = sent[r["seq"]][0]
        errors_mm.append(1e3 * np.linalg.norm(np.array(r["position"]) - video.positions[k]))
        for f in r["fixtures"]:
            if f["used"]:
                truth = video.fixtures[k].get(f["id"])
                off = np.inf if truth is None else np.linalg.norm(np.array(f["pixel"]) - truth)
                wrong += bool(off > ID_PIXEL_TOLERANCE)
    median_mm = float(np.median(errors_mm))
    frames_seen = len({sent[r["seq"]][0] for r in results})
    print(
        f"capture page: {len(located)} of {len(results)} frames located ({100 * share:.1f} %), "
        f"{frames_seen} different video frames, median position error {median_mm:.2f} mm, "
        f"max {max(errors_mm):.2f} mm (video frame "
        f"{sent[located[int(np.argmax(errors_mm))]['seq']][0]}), {wrong} wrong IDs; statuses "
        f"{sorted({r['status'] for r in results})}; median latency "
        f"{np.median([r['latency_ms'] for r in results]):.0f} ms; photos: "
        f"{sum(p['located'] for p in shown['photos'])} of {len(shown['photos'])} located"
    )
    assert share >= 0.9
    assert median_mm <= 5.0
    assert wrong == 0
    assert frames_seen >= 10  # the page followed the video, not one frame over and over
    # what the page shows: the last located position, the fake camera's exposure, the gravity
    last = located[-1]["position"]
    assert shown["position"] == f"({', '.join(f'{v:.3f}' for v in last)}) m"
    # the photos, each located alone (a new track for each)
    photos = shown["photos"]
    assert len(photos) >= PHOTOS and all(p["located"] for p in photos), photos
    photo_mm = [
        1e3 * np.linalg.norm(np.array(p["position"]) - video.positions[sent[p["seq"]][0]])
        for p in photos
    ]
    assert max(photo_mm) <= 10.0, photo_mm
    assert "cannot set the exposure time" in shown["exposure"]
    assert "Gravity (camera frame)" in shown["gravity"]
