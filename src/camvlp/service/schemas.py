"""Request and response bodies of the HTTP API (pydantic models, shown in /docs)."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, Field

__all__ = [
    "CameraPut",
    "FixFields",
    "FixOut",
    "FixPage",
    "LocateForm",
    "PlanFixture",
    "SiteCreate",
    "SiteCreated",
    "SiteOut",
]


class SiteCreate(BaseModel):
    """A new site: its name, map and first camera."""

    name: str = Field(min_length=1, max_length=200, examples=["warehouse 3"])
    map: dict[str, Any] = Field(description="The map file's keys (units, frame, fixtures).")
    camera: dict[str, Any] = Field(description="The camera file's keys.")
    camera_name: str = Field("default", min_length=1, max_length=100, pattern=r"^[A-Za-z0-9._-]+$")


class SiteCreated(BaseModel):
    """The new site's id and its API key: shown this once, stored only as a hash."""

    id: int
    api_key: str
    camera: str


class PlanFixture(BaseModel):
    """A fixture on the plan seen from above (plan coordinates in map units)."""

    id: int
    plan: list[float]
    diameter: float | None


class SiteOut(BaseModel):
    """A site: name, map and cameras as stored, and how to draw the map from above."""

    id: int
    name: str
    created: str
    map: dict[str, Any]
    cameras: dict[str, dict[str, Any]]
    units: str
    plan: dict[str, Any]
    fixtures: list[PlanFixture]


class CameraPut(BaseModel):
    """Answer to storing a camera."""

    site_id: int
    name: str
    created: bool


class FixFields(BaseModel):
    """What a stored fix and its HTTP view share (see the ``fixes`` table)."""

    id: int
    device: str
    camera: str
    located: bool
    position: list[float] | None
    rotation: list[list[float]] | None
    euler_deg: list[float] | None
    fixtures_used: list[int]
    error: str
    source: str = Field("photo", description="photo (POST .../locate) or frame (POST .../frames)")
    status: str | None = Field(
        None, description="A frame's status: fix, tracked, gravity, predicted or lost."
    )
    position_sigma: list[float] | None = Field(
        None, description="Standard deviation of the position along x, y, z (map units)."
    )


class FixOut(FixFields):
    """One recorded fix.

    ``position`` (map units) and ``rotation`` (camera-to-world) are in the map's frame;
    ``plan`` is the position and heading on the plan seen from above (``heading_deg``
    counterclockwise from the plan's first axis), for drawing.
    """

    time: str
    time_unix: float
    reprojection_rms_px: float | None
    plan: dict[str, Any]
    has_picture: bool = False
    result: dict[str, Any] | None = None


class FixPage(BaseModel):
    """A page of fixes, newest first; ``next_before`` fetches the next (older) page."""

    fixes: list[FixOut]
    next_before: int | None


class LocateForm(BaseModel):
    """The fields of ``POST /sites/{id}/locate`` beside the photo (multipart form)."""

    device: str = Field("", max_length=200, description="The client's name.")
    readout: str | None = Field(
        None, description="rows, columns, rows-reversed or columns-reversed."
    )
    mirrored: bool | None = Field(None, description="The photo is a mirror image.")
    gravity: str | None = Field(
        None,
        description="gx,gy,gz: the phone's gravity in the camera frame (OpenCV axes, any "
        "length); the locator uses it (two or three fixtures are then enough) and it is kept "
        "with the fix.",
    )
    annotate: bool = Field(
        False, description="Keep an annotated picture of the fix (for the page)."
    )
    max_sigma: float | None = Field(
        None,
        description="The most the position's standard deviation may be along an axis (map "
        "units): a photo whose position is less sure is not located (as --max-sigma).",
    )
