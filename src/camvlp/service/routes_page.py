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

#: What the pages may load: their own files and the API, nothing from another host (the
#: browser refuses the rest, e.g. the logo ReDoc's script would fetch from its maker's site).
_PAGE_POLICY = (
    "default-src 'self'; img-src 'self' blob: data:; connect-src 'self'; "
    "frame-ancestors 'none'; base-uri 'none'; form-action 'self'"
)
#: The same for Swagger UI and ReDoc, whose pages start them with inline scripts and styles
#: (ReDoc's search runs in a worker made from a blob).
_DOCS_POLICY = (
    "default-src 'self'; script-src 'self' 'unsafe-inline'; style-src 'self' 'unsafe-inline'; "
    "img-src 'self' data:; worker-src 'self' blob:; connect-src 'self'; frame-ancestors 'none'"
)
_NO_CACHE = {"Cache-Control": "no-cache", "Content-Security-Policy": _PAGE_POLICY}


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
    page = get_swagger_ui_html(
        openapi_url=request.app.openapi_url,
        title=f"{request.app.title} - Swagger UI",
        swagger_js_url=f"{DOCS_ASSETS_URL}/swagger-ui-bundle.js",
        swagger_css_url=f"{DOCS_ASSETS_URL}/swagger-ui.css",
        swagger_favicon_url=f"{DOCS_ASSETS_URL}/favicon.png",
    )
    page.headers["Content-Security-Policy"] = _DOCS_POLICY
    return page


@router.get("/redoc")
def redoc(request: Request) -> HTMLResponse:
    """ReDoc, from the package's files (no web fonts)."""
    page = get_redoc_html(
        openapi_url=request.app.openapi_url,
        title=f"{request.app.title} - ReDoc",
        redoc_js_url=f"{DOCS_ASSETS_URL}/redoc.standalone.js",
        redoc_favicon_url=f"{DOCS_ASSETS_URL}/favicon.png",
        with_google_fonts=False,
    )
    page.headers["Content-Security-Policy"] = _DOCS_POLICY
    return page


@router.get("/metrics")
def metrics(metrics: MetricsDep) -> Response:
    """This process's metrics in Prometheus' text format."""
    return Response(metrics.render(), media_type=CONTENT_TYPE)
