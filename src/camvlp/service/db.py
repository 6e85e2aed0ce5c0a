"""The service's database: sites, their cameras and maps, fixes, and annotated pictures.

SQLAlchemy Core with portable types only, so the default SQLite file and a PostgreSQL URL
work alike; several service processes may share one database.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import sqlalchemy as sa
from pydantic import ConfigDict
from sqlalchemy.engine import Engine

from camvlp.service.schemas import FixFields
from camvlp.service.settings import sqlite_file

__all__ = ["FixRow", "SiteRow", "Store", "make_engine", "metadata"]

metadata = sa.MetaData()

#: Integer keys: BIGINT where the database has it, SQLite's INTEGER (its rowid) otherwise.
_Id = sa.BigInteger().with_variant(sa.Integer(), "sqlite")

sites = sa.Table(
    "sites",
    metadata,
    sa.Column("id", _Id, primary_key=True, autoincrement=True),
    sa.Column("name", sa.String(200), nullable=False),
    sa.Column("key_hash", sa.String(64), nullable=False, unique=True),
    sa.Column("map", sa.JSON, nullable=False),
    sa.Column("created", sa.Float, nullable=False),
)

cameras = sa.Table(
    "cameras",
    metadata,
    sa.Column("site_id", _Id, sa.ForeignKey("sites.id"), primary_key=True),
    sa.Column("name", sa.String(100), primary_key=True),
    sa.Column("camera", sa.JSON, nullable=False),
    sa.Column("updated", sa.Float, nullable=False),
)

fixes = sa.Table(
    "fixes",
    metadata,
    sa.Column("id", _Id, primary_key=True, autoincrement=True),
    sa.Column("site_id", _Id, sa.ForeignKey("sites.id"), nullable=False),
    sa.Column("time", sa.Float, nullable=False),  # seconds since 1970 (UTC)
    sa.Column("device", sa.String(200), nullable=False),
    sa.Column("camera", sa.String(100), nullable=False),
    sa.Column("located", sa.Boolean, nullable=False),
    sa.Column("position", sa.JSON),  # [x, y, z] in map units, or null
    sa.Column("rotation", sa.JSON),  # 3 x 3 camera-to-world, or null
    sa.Column("euler_deg", sa.JSON),
    sa.Column("rms_px", sa.Float),
    sa.Column("fixtures_used", sa.JSON, nullable=False),  # list of fixture IDs
    sa.Column("error", sa.Text, nullable=False),
    sa.Column("result", sa.JSON, nullable=False),  # the locate JSON, whole
    sa.Column("has_picture", sa.Boolean, nullable=False),
    sa.Column("gravity", sa.JSON),  # [gx, gy, gz] as the client sent it, or null
    # since migration 0002: where the fix came from, the frame's status, the position's sigma
    sa.Column("source", sa.String(10), nullable=False, server_default="photo"),  # or "frame"
    sa.Column("status", sa.String(16)),  # a frame's: fix, tracked, gravity, predicted, lost
    sa.Column("position_sigma", sa.JSON),  # [sx, sy, sz] in map units, or null
    sa.Index("ix_fixes_site_id_id", "site_id", "id"),
    sa.Index("ix_fixes_site_id_device_id", "site_id", "device", "id"),
)

pictures = sa.Table(
    "pictures",
    metadata,
    sa.Column("fix_id", _Id, sa.ForeignKey("fixes.id"), primary_key=True),
    sa.Column("jpeg", sa.LargeBinary, nullable=False),
)


def make_engine(url: str) -> Engine:
    """An engine for ``url``; SQLite files get WAL journaling and a busy timeout, and their
    folder is created when missing.

    WAL lets readers (the fix streams) go on while a writer commits, and the timeout makes
    concurrent writers from several processes wait for each other instead of failing.

    Raises
    ------
    OSError
        A SQLite file's folder cannot be created.
    """
    path = sqlite_file(url)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
    engine = sa.create_engine(url, pool_pre_ping=True)
    if engine.dialect.name == "sqlite":

        @sa.event.listens_for(engine, "connect")
        def _sqlite_pragmas(dbapi_conn, _record) -> None:  # pragma: no cover - trivial
            cur = dbapi_conn.cursor()
            cur.execute("PRAGMA journal_mode=WAL")
            cur.execute("PRAGMA busy_timeout=30000")
            cur.execute("PRAGMA foreign_keys=ON")
            cur.close()

    return engine


@dataclass(frozen=True)
class SiteRow:
    """One site: its id, name, map (the map file's keys) and when it was created."""

    id: int
    name: str
    map: dict[str, Any]
    created: float


class FixRow(FixFields):
    """One recorded fix (see the ``fixes`` table)."""

    model_config = ConfigDict(frozen=True)

    site_id: int
    time: float
    rms_px: float | None
    has_picture: bool
    result: dict[str, Any]


_FIX_COLUMNS = [c for c in fixes.c if c.name != "result"]


class Store:
    """All the service's reads and writes, one short transaction each.

    Parameters
    ----------
    engine : Engine
        From :func:`make_engine`.
    """

    def __init__(self, engine: Engine):
        self.engine = engine

    # --- sites -----------------------------------------------------------------------------

    def create_site(
        self, name: str, key_hash: str, map_data: dict, camera_name: str, camera: dict
    ) -> int:
        """Insert a site with its first camera; returns the site's id."""
        now = time.time()
        with self.engine.begin() as conn:
            site_id = conn.execute(
                sa.insert(sites).values(name=name, key_hash=key_hash, map=map_data, created=now)
            ).inserted_primary_key[0]
            conn.execute(
                sa.insert(cameras).values(
                    site_id=site_id, name=camera_name, camera=camera, updated=now
                )
            )
        return int(site_id)

    def site(self, site_id: int) -> SiteRow | None:
        """The site, or None."""
        with self.engine.connect() as conn:
            row = conn.execute(
                sa.select(sites.c.id, sites.c.name, sites.c.map, sites.c.created).where(
                    sites.c.id == site_id
                )
            ).first()
        return None if row is None else SiteRow(*row)

    def site_key_hash(self, site_id: int) -> str | None:
        """The hash of the site's API key, or None when there is no such site."""
        with self.engine.connect() as conn:
            return conn.execute(
                sa.select(sites.c.key_hash).where(sites.c.id == site_id)
            ).scalar_one_or_none()

    def key_hash_exists(self, key_hash: str) -> bool:
        """Whether any site has this key hash."""
        with self.engine.connect() as conn:
            found = conn.execute(sa.select(sites.c.id).where(sites.c.key_hash == key_hash)).first()
        return found is not None

    def set_map(self, site_id: int, map_data: dict) -> None:
        """Replace the site's map."""
        with self.engine.begin() as conn:
            conn.execute(sa.update(sites).where(sites.c.id == site_id).values(map=map_data))

    # --- cameras ---------------------------------------------------------------------------

    def cameras(self, site_id: int) -> dict[str, dict]:
        """The site's cameras by name (the camera file's keys)."""
        with self.engine.connect() as conn:
            rows = conn.execute(
                sa.select(cameras.c.name, cameras.c.camera)
                .where(cameras.c.site_id == site_id)
                .order_by(cameras.c.name)
            ).all()
        return {name: cam for name, cam in rows}

    def put_camera(self, site_id: int, name: str, camera: dict) -> bool:
        """Create or replace a camera; True when it was created."""
        now = time.time()
        with self.engine.begin() as conn:
            updated = conn.execute(
                sa.update(cameras)
                .where(cameras.c.site_id == site_id, cameras.c.name == name)
                .values(camera=camera, updated=now)
            ).rowcount
            if updated:
                return False
            conn.execute(
                sa.insert(cameras).values(site_id=site_id, name=name, camera=camera, updated=now)
            )
        return True

    # --- fixes -----------------------------------------------------------------------------

    def add_fix(
        self,
        site_id: int,
        device: str,
        camera: str,
        result: dict[str, Any],
        picture_jpeg: bytes | None = None,
        gravity: list[float] | None = None,
        *,
        source: str = "photo",
        status: str | None = None,
    ) -> int:
        """Record a locate result (the ``locate --json`` object, or a frame's answer with
        ``source="frame"`` and its tracker ``status``); returns the fix's id."""
        used = [f["id"] for f in result.get("fixtures", ()) if f.get("used")]
        with self.engine.begin() as conn:
            fix_id = conn.execute(
                sa.insert(fixes).values(
                    site_id=site_id,
                    time=time.time(),
                    device=device,
                    camera=camera,
                    located=result.get("position") is not None,
                    position=result.get("position"),
                    rotation=result.get("rotation"),
                    euler_deg=result.get("euler_deg"),
                    rms_px=result.get("reprojection_rms_px"),
                    fixtures_used=used,
                    error=result.get("error", ""),
                    result=result,
                    has_picture=picture_jpeg is not None,
                    gravity=gravity,
                    source=source,
                    status=status,
                    position_sigma=result.get("position_sigma"),
                )
            ).inserted_primary_key[0]
            if picture_jpeg is not None:
                conn.execute(sa.insert(pictures).values(fix_id=fix_id, jpeg=picture_jpeg))
        return int(fix_id)

    def fixes(
        self,
        site_id: int,
        *,
        device: str | None = None,
        since: float | None = None,
        before: int | None = None,
        after: int | None = None,
        limit: int = 50,
        newest_first: bool = True,
        with_result: bool = False,
    ) -> list[FixRow]:
        """The site's fixes, filtered.

        Parameters
        ----------
        device : str, optional
            Only this device's fixes.
        since : float, optional
            Only fixes at or after this time (seconds since 1970, UTC).
        before, after : int, optional
            Only fixes with an id below / above this one (paging cursors).
        limit : int
            At most this many.
        newest_first : bool
            Order by id descending (else ascending).
        with_result : bool
            Also read the whole locate JSON of each fix.
        """
        cols = list(fixes.c) if with_result else _FIX_COLUMNS
        q = sa.select(*cols).where(fixes.c.site_id == site_id)
        if device is not None:
            q = q.where(fixes.c.device == device)
        if since is not None:
            q = q.where(fixes.c.time >= since)
        if before is not None:
            q = q.where(fixes.c.id < before)
        if after is not None:
            q = q.where(fixes.c.id > after)
        q = q.order_by(fixes.c.id.desc() if newest_first else fixes.c.id.asc()).limit(limit)
        with self.engine.connect() as conn:
            rows = conn.execute(q).mappings().all()
        return [_fix_row(r) for r in rows]

    def fix(self, site_id: int, fix_id: int) -> FixRow | None:
        """One fix of the site (with its locate JSON), or None."""
        with self.engine.connect() as conn:
            row = (
                conn.execute(
                    sa.select(fixes).where(fixes.c.site_id == site_id, fixes.c.id == fix_id)
                )
                .mappings()
                .first()
            )
        return None if row is None else _fix_row(row)

    def last_fix_id(self, site_id: int) -> int:
        """The id of the site's newest fix, or 0."""
        with self.engine.connect() as conn:
            value = conn.execute(
                sa.select(sa.func.max(fixes.c.id)).where(fixes.c.site_id == site_id)
            ).scalar()
        return int(value or 0)

    def picture(self, site_id: int, fix_id: int) -> bytes | None:
        """The annotated picture (JPEG) of one of the site's fixes, or None."""
        with self.engine.connect() as conn:
            return conn.execute(
                sa.select(pictures.c.jpeg)
                .join(fixes, fixes.c.id == pictures.c.fix_id)
                .where(fixes.c.site_id == site_id, fixes.c.id == fix_id)
            ).scalar_one_or_none()


def _fix_row(r) -> FixRow:
    return FixRow(
        id=int(r["id"]),
        site_id=int(r["site_id"]),
        time=float(r["time"]),
        device=r["device"],
        camera=r["camera"],
        located=bool(r["located"]),
        position=r["position"],
        rotation=r["rotation"],
        euler_deg=r["euler_deg"],
        rms_px=r["rms_px"],
        fixtures_used=list(r["fixtures_used"] or []),
        error=r["error"],
        has_picture=bool(r["has_picture"]),
        source=r["source"],
        status=r["status"],
        position_sigma=r["position_sigma"],
        result=r.get("result") or {},
    )
