"""The routes outside the API: the pages of each site, the API's documentation, ``/metrics``.

The pages' scripts and style sheets are the files in :data:`STATIC_DIR`, served at
``/static``; Swagger UI's and ReDoc's are those that the ``fastapi-offline`` package ships,
served at ``/static-docs`` (both mounted by :func:`camvlp.service.create_app`), so that no
page loads anything from another host.
"""

from importlib.resources import files
from pathlib import Path

from fastapi import APIRouter, Request
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html
from fastapi.responses import FileResponse, HTMLResponse, RedirectResponse, Response

from camvlp.service.deps import MetricsDep
from camvlp.service.metrics import CONTENT_TYPE

__all__ = ["DOCS_ASSETS_DIR", "DOCS_ASSETS_URL", "STATIC_DIR", "router"]

#: The pages' files: ``site.html``, ``capture.html``, their scripts and style sheet.
STATIC_DIR = Path(__file__).resolve().parent / "static"
#: Swagger UI's and ReDoc's scripts and style sheet (the ``fastapi-offline`` package's).
DOCS_ASSETS_DIR = Path(str(files("fastapi_offline") / "static"))
#: Where they are served.
DOCS_ASSETS_URL = "/static-docs"

router = APIRouter(include_in_schema=False)

_NO_CACHE = {"Cache-Control": "no-cache"}


@router.get("/sites/{site_id}")
def site_page(site_id: int) -> FileResponse:
    """The live page of a site (its data come from the API with the site's key)."""
    return FileResponse(STATIC_DIR / "site.html", headers=_NO_CACHE)


@router.get("/sites/{site_id}/capture")
def capture_page(site_id: int) -> FileResponse:
    """The phone's page: the live camera's frames located, the position on the plan."""
    return FileResponse(STATIC_DIR / "capture.html", headers=_NO_CACHE)


@router.get("/")
def root() -> RedirectResponse:
    """The API's documentation."""
    return RedirectResponse("/docs")


@router.get("/docs")
def swagger_ui(request: Request) -> HTMLResponse:
    """Swagger UI, from the package's files."""
    return get_swagger_ui_html(
        openapi_url=request.app.openapi_url,
        title=f"{request.app.title} - Swagger UI",
        swagger_js_url=f"{DOCS_ASSETS_URL}/swagger-ui-bundle.js",
        swagger_css_url=f"{DOCS_ASSETS_URL}/swagger-ui.css",
        swagger_favicon_url=f"{DOCS_ASSETS_URL}/favicon.png",
    )


@router.get("/redoc")
def redoc(request: Request) -> HTMLResponse:
    """ReDoc, from the package's files (no web fonts)."""
    return get_redoc_html(
        openapi_url=request.app.openapi_url,
        title=f"{request.app.title} - ReDoc",
        redoc_js_url=f"{DOCS_ASSETS_URL}/redoc.standalone.js",
        redoc_favicon_url=f"{DOCS_ASSETS_URL}/favicon.png",
        with_google_fonts=False,
    )


@router.get("/metrics")
def metrics(metrics: MetricsDep) -> Response:
    """This process's metrics in Prometheus' text format."""
    return Response(metrics.render(), media_type=CONTENT_TYPE)
