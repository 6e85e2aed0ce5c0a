"""The routes outside the API: the live page of each site, and ``/`` to the documentation.

The page's script and style sheet are the files in :data:`STATIC_DIR`, served at ``/static``
(mounted by :func:`camvlp.service.create_app`).
"""

from pathlib import Path

from fastapi import APIRouter
from fastapi.responses import FileResponse, RedirectResponse

__all__ = ["STATIC_DIR", "router"]

#: The page's files: ``site.html``, ``site.js``, ``site.css``.
STATIC_DIR = Path(__file__).resolve().parent / "static"

router = APIRouter(include_in_schema=False)


@router.get("/sites/{site_id}")
def site_page(site_id: int) -> FileResponse:
    """The live page of a site (its data come from the API with the site's key)."""
    return FileResponse(STATIC_DIR / "site.html", headers={"Cache-Control": "no-cache"})


@router.get("/")
def root() -> RedirectResponse:
    """The API's documentation."""
    return RedirectResponse("/docs")
