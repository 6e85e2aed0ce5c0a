"""Running the service: the admin key, per-key rate limits, /metrics, the JSON log lines and
the API's documentation served from the package."""

from __future__ import annotations

import json
import logging
import re
from pathlib import Path

import pytest
from prometheus_client.parser import text_string_to_metric_families
from service_helpers import (
    ADMIN,
    CAMERA_JSON,
    MAP_JSON,
    client,  # noqa: F401  (fixture)
    create_site,
    make_client,
    photo_png,  # noqa: F401  (fixture)
)

from camvlp.service.logs import ACCESS_LOGGER, JsonFormatter
from camvlp.service.ratelimit import RateLimiter

SITE = {"name": "ops", "map": MAP_JSON, "camera": CAMERA_JSON}


def test_creating_a_site_needs_the_admin_key(client):
    assert client.post("/api/v1/sites", json=SITE).status_code == 401
    wrong = {"Authorization": "Bearer not-the-admin-key-at-all"}
    assert client.post("/api/v1/sites", json=SITE, headers=wrong).status_code == 401
    _, site_key = create_site(client)  # a site's key is no admin key either
    assert client.post("/api/v1/sites", json=SITE, headers=site_key).status_code == 401
    assert client.post("/api/v1/sites", json=SITE, headers=ADMIN).status_code == 201


def test_a_key_over_its_rate_gets_429_with_retry_after(tmp_path: Path):
    with make_client(tmp_path, rate_per_s=0.5, rate_burst=3) as c:
        site_id, headers = create_site(c)
        statuses = [c.get(f"/api/v1/sites/{site_id}", headers=headers) for _ in range(5)]
        assert [r.status_code for r in statuses] == [200, 200, 200, 429, 429]
        r = statuses[3]
        assert r.headers["Retry-After"] == "2"  # one token at 0.5 per second
        assert r.json() == {
            "detail": "rate limit: 0.5 requests per second per key (bursts of 3); retry in 2 s"
        }
        # another key has its own bucket; the admin key too (one of its 3 went on the site)
        other_id, other = create_site(c, "second")
        assert c.get(f"/api/v1/sites/{other_id}", headers=other).status_code == 200
        assert c.post("/api/v1/sites", json=SITE, headers=ADMIN).status_code == 201
        assert c.post("/api/v1/sites", json=SITE, headers=ADMIN).status_code == 429
        assert c.get("/api/v1/health").status_code == 200  # no key, no limit
        families = _metrics(c)
        assert _value(families, "camvlp_rate_limited_total") == 3


def test_the_token_bucket_refills_at_its_rate():
    now = [0.0]
    limiter = RateLimiter(rate=2.0, burst=2, max_keys=2, clock=lambda: now[0])
    assert [limiter.take("a") for _ in range(3)] == [0.0, 0.0, 0.5]
    now[0] = 0.5  # one token back after half a second at 2 per second
    assert limiter.take("a") == 0.0 and limiter.take("a") == pytest.approx(0.5)
    limiter.take("b"), limiter.take("c")  # "a" is forgotten (two keys kept): a full bucket
    assert limiter.take("a") == 0.0 and limiter.take("a") == 0.0
    assert RateLimiter.retry_after(0.01) == "1" and RateLimiter.retry_after(2.5) == "3"
    with pytest.raises(ValueError):
        RateLimiter(rate=0.0, burst=1)


def _metrics(c) -> dict:
    r = c.get("/metrics")
    assert r.status_code == 200
    assert r.headers["content-type"].startswith("text/plain; version=")
    return {f.name: f for f in text_string_to_metric_families(r.text)}


def _value(families: dict, sample: str, **labels) -> float:
    total = 0.0
    for family in families.values():
        for s in family.samples:
            if s.name == sample and all(s.labels.get(k) == v for k, v in labels.items()):
                total += s.value
    return total


def test_metrics_parse_as_prometheus_text_and_count_the_fixes(client, photo_png):
    site_id, headers = create_site(client)
    r = client.post(
        f"/api/v1/sites/{site_id}/locate",
        headers=headers,
        files={"photo": ("p.png", photo_png, "image/png")},
    )
    assert r.status_code == 200
    client.get(f"/api/v1/sites/{site_id}/fixes", headers=headers)
    client.get("/api/v1/sites/999", headers=headers)
    families = _metrics(client)
    kinds = {name: f.type for name, f in families.items()}
    assert kinds["camvlp_http_requests"] == "counter"
    assert kinds["camvlp_http_request_duration_seconds"] == "histogram"
    assert kinds["camvlp_frame_queue_depth"] == "gauge"
    assert kinds["camvlp_locate_in_hand"] == "gauge"
    assert _value(families, "camvlp_fixes_total", source="photo", located="true") == 1
    assert _value(families, "camvlp_locate_duration_seconds_count", source="photo") == 1
    route = "/api/v1/sites/{site_id}/locate"
    assert _value(families, "camvlp_http_requests_total", route=route, status="200") == 1
    assert _value(families, "camvlp_http_requests_total", status="404") == 1
    assert _value(families, "camvlp_frame_queue_depth") == 0
    # histogram buckets are cumulative and end at +Inf with the count
    buckets = [
        s
        for s in families["camvlp_http_request_duration_seconds"].samples
        if s.name.endswith("_bucket") and s.labels["route"] == route
    ]
    values = [s.value for s in buckets]
    assert values == sorted(values) and buckets[-1].labels["le"] == "+Inf" and values[-1] == 1


def test_each_request_is_one_json_log_line_without_keys(client, photo_png, caplog):
    site_id, headers = create_site(client)
    key = headers["Authorization"].removeprefix("Bearer ")
    caplog.clear()
    with caplog.at_level(logging.INFO, logger=ACCESS_LOGGER):
        client.post(
            f"/api/v1/sites/{site_id}/locate?annotate=1",
            headers=headers,
            files={"photo": ("p.png", photo_png, "image/png")},
            data={"device": "robot-7"},
        )
        client.get(f"/api/v1/sites/{site_id}/fixes?device=robot-7&limit=2", headers=headers)
        client.get("/nowhere")
    records = [r for r in caplog.records if r.name == ACCESS_LOGGER]
    lines = [JsonFormatter().format(r) for r in records]
    assert len(lines) == 3
    parsed = [json.loads(line) for line in lines]
    assert all("\n" not in line and key not in line for line in lines)
    first = parsed[0]
    assert first["method"] == "POST" and first["status"] == 200 and first["level"] == "info"
    assert first["path"] == f"/api/v1/sites/{site_id}/locate"  # no query string
    assert first["site"] == site_id and first["device"] == "robot-7"
    assert first["route"] == "/api/v1/sites/{site_id}/locate" and first["latency_ms"] > 0
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z", first["time"])
    assert parsed[1]["device"] == "robot-7" and parsed[1]["path"].endswith("/fixes")
    assert parsed[2]["status"] == 404 and parsed[2]["route"] == "unmatched"


def test_the_documentation_pages_load_nothing_from_other_hosts(client):
    for path, asset in (("/docs", "swagger-ui-bundle.js"), ("/redoc", "redoc.standalone.js")):
        page = client.get(path)
        assert page.status_code == 200
        urls = re.findall(r"""(?:src|href)=["']([^"']+)""", page.text)
        urls += re.findall(r"""url: ?["']([^"']+)""", page.text)
        assert urls and all(u.startswith("/") and not u.startswith("//") for u in urls), urls
        assert f"/static-docs/{asset}" in urls
        script = client.get(f"/static-docs/{asset}")
        assert script.status_code == 200 and len(script.content) > 100_000
    assert "fonts.googleapis" not in client.get("/redoc").text
