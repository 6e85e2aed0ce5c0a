"""Schema migrations: a database made by camvlp 0.1.0 (the previous release) is refused until
``camvlp serve --migrate`` upgrades it, and keeps every fix; the migrations and the tables the
code uses agree.  On a SQLite file, or on ``CAMVLP_TEST_DB_URL`` (PostgreSQL in CI)."""

from __future__ import annotations

from pathlib import Path

import pytest
import sqlalchemy as sa
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from fastapi.testclient import TestClient
from service_helpers import ADMIN_KEY, CAMERA_JSON, MAP_JSON, TEST_DB_URL, drop_all, free_port

from camvlp.cli import main
from camvlp.service import ServiceSettings, create_app
from camvlp.service.auth import new_key
from camvlp.service.db import fixes, make_engine, metadata
from camvlp.service.migrate import SchemaError, head, schema_state, upgrade
from conftest import one_error_line


def previous_schema() -> sa.MetaData:
    """The tables as camvlp 0.1.0 made them (``src/camvlp/service/db.py`` of that release),
    copied here as they were: no ``alembic_version``, no source, status or sigma of a fix."""
    old = sa.MetaData()
    row_id = sa.BigInteger().with_variant(sa.Integer(), "sqlite")
    sa.Table(
        "sites",
        old,
        sa.Column("id", row_id, primary_key=True, autoincrement=True),
        sa.Column("name", sa.String(200), nullable=False),
        sa.Column("key_hash", sa.String(64), nullable=False, unique=True),
        sa.Column("map", sa.JSON, nullable=False),
        sa.Column("created", sa.Float, nullable=False),
    )
    sa.Table(
        "cameras",
        old,
        sa.Column("site_id", row_id, sa.ForeignKey("sites.id"), primary_key=True),
        sa.Column("name", sa.String(100), primary_key=True),
        sa.Column("camera", sa.JSON, nullable=False),
        sa.Column("updated", sa.Float, nullable=False),
    )
    sa.Table(
        "fixes",
        old,
        sa.Column("id", row_id, primary_key=True, autoincrement=True),
        sa.Column("site_id", row_id, sa.ForeignKey("sites.id"), nullable=False),
        sa.Column("time", sa.Float, nullable=False),
        sa.Column("device", sa.String(200), nullable=False),
        sa.Column("camera", sa.String(100), nullable=False),
        sa.Column("located", sa.Boolean, nullable=False),
        sa.Column("position", sa.JSON),
        sa.Column("rotation", sa.JSON),
        sa.Column("euler_deg", sa.JSON),
        sa.Column("rms_px", sa.Float),
        sa.Column("fixtures_used", sa.JSON, nullable=False),
        sa.Column("error", sa.Text, nullable=False),
        sa.Column("result", sa.JSON, nullable=False),
        sa.Column("has_picture", sa.Boolean, nullable=False),
        sa.Column("gravity", sa.JSON),
        sa.Index("ix_fixes_site_id_id", "site_id", "id"),
    )
    sa.Table(
        "pictures",
        old,
        sa.Column("fix_id", row_id, sa.ForeignKey("fixes.id"), primary_key=True),
        sa.Column("jpeg", sa.LargeBinary, nullable=False),
    )
    return old


#: The fix that the previous release recorded.
OLD_FIX = {
    "time": 1_700_000_000.25,
    "device": "phone-0.1",
    "camera": "default",
    "located": True,
    "position": [0.1, 0.0, -0.05],
    "rotation": [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]],
    "euler_deg": [90.0, 0.0, 30.0],
    "rms_px": 0.42,
    "fixtures_used": [5, 6, 9, 10],
    "error": "",
    "result": {"position": [0.1, 0.0, -0.05], "fixtures": [{"id": 5, "used": True}], "x": 1},
    "has_picture": True,
    "gravity": [0.0, 0.0, -9.8],
}


@pytest.fixture
def db_url(tmp_path: Path) -> str:
    """An empty database: a SQLite file, or CAMVLP_TEST_DB_URL emptied."""
    if TEST_DB_URL:
        drop_all(TEST_DB_URL)
        return TEST_DB_URL
    return f"sqlite:///{tmp_path / 'old.db'}"


def make_previous_release_db(url: str) -> tuple[int, int, str]:
    """A database as camvlp 0.1.0 left it: a site, its camera, a fix and its picture.
    Returns ``(site id, fix id, the site's key)``."""
    key, key_hash = new_key()
    engine = make_engine(url)
    old = previous_schema()
    old.create_all(engine)
    with engine.begin() as conn:
        site_id = conn.execute(
            old.tables["sites"]
            .insert()
            .values(name="old site", key_hash=key_hash, map=MAP_JSON, created=1.7e9)
        ).inserted_primary_key[0]
        conn.execute(
            old.tables["cameras"]
            .insert()
            .values(site_id=site_id, name="default", camera=CAMERA_JSON, updated=1.7e9)
        )
        fix_id = conn.execute(
            old.tables["fixes"].insert().values(site_id=site_id, **OLD_FIX)
        ).inserted_primary_key[0]
        conn.execute(old.tables["pictures"].insert().values(fix_id=fix_id, jpeg=b"\xff\xd8old"))
    engine.dispose()
    return int(site_id), int(fix_id), key


def _schema_differences(url: str) -> list:
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            return compare_metadata(MigrationContext.configure(conn), metadata)
    finally:
        engine.dispose()


def test_a_previous_release_database_is_migrated_with_its_fixes_intact(db_url, capsys):
    site_id, fix_id, key = make_previous_release_db(db_url)
    settings = ServiceSettings(db=db_url, admin_key=ADMIN_KEY)
    with pytest.raises(SchemaError, match="revision 0001 and this camvlp needs 0002"):
        create_app(settings)
    # camvlp serve refuses it in one line, before listening
    assert main(["serve", "--db", db_url, "--port", str(free_port())]) == 2
    line = one_error_line(capsys.readouterr().err)
    assert "upgrade it first with camvlp serve --migrate" in line
    assert main(["serve", "--db", db_url, "--migrate"]) == 0
    assert "upgraded the database from revision 0001 to 0002" in capsys.readouterr().out
    assert _schema_differences(db_url) == []
    assert main(["serve", "--db", db_url, "--migrate"]) == 0
    assert "at revision 0002 already" in capsys.readouterr().out
    with TestClient(create_app(settings)) as client:
        headers = {"Authorization": f"Bearer {key}"}  # the old key still opens the site
        fix = client.get(f"/api/v1/sites/{site_id}/fixes/{fix_id}", headers=headers).json()
        for name in ("device", "camera", "located", "position", "rotation", "euler_deg"):
            assert fix[name] == OLD_FIX[name], name
        assert fix["fixtures_used"] == OLD_FIX["fixtures_used"] and fix["error"] == ""
        assert fix["reprojection_rms_px"] == OLD_FIX["rms_px"]
        assert fix["time_unix"] == OLD_FIX["time"] and fix["result"] == OLD_FIX["result"]
        assert (fix["source"], fix["status"], fix["position_sigma"]) == ("photo", None, None)
        picture = client.get(f"/api/v1/sites/{site_id}/fixes/{fix_id}/picture", headers=headers)
        assert picture.content == b"\xff\xd8old"
        with client.app.state.store.engine.connect() as conn:
            gravity = conn.execute(sa.select(fixes.c.gravity)).scalar_one()
        assert gravity == OLD_FIX["gravity"]


def test_migrations_from_nothing_make_the_tables_the_code_uses(db_url):
    engine = make_engine(db_url)
    try:
        assert schema_state(engine).empty
        assert upgrade(engine) == (None, head())
        assert schema_state(engine).current
    finally:
        engine.dispose()
    assert _schema_differences(db_url) == []


def test_a_database_of_a_newer_camvlp_is_refused(db_url, capsys):
    engine = make_engine(db_url)
    try:
        upgrade(engine)
        with engine.begin() as conn:
            conn.execute(sa.text("UPDATE alembic_version SET version_num = '9999'"))
        with pytest.raises(SchemaError, match="revision 9999, which this camvlp does not know"):
            upgrade(engine)
    finally:
        engine.dispose()
    assert main(["serve", "--db", db_url, "--port", str(free_port())]) == 2
    assert "a newer camvlp made it" in one_error_line(capsys.readouterr().err)
