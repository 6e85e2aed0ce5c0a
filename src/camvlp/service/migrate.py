"""The database's schema version: Alembic migrations (``camvlp serve --migrate``).

The migrations live in ``migrations/versions/`` beside this module; the tables as this code
reads and writes them are :data:`camvlp.service.db.metadata`, the last revision's schema.

* A new, empty database is created at the last revision (the tables, then Alembic's
  ``alembic_version`` stamped), whenever the service starts on it.
* A database made by camvlp 0.1.0 (the tables and no ``alembic_version``) is that release's
  schema, revision :data:`BASELINE`; it and any database at an older revision are upgraded by
  :func:`upgrade` (``camvlp serve --migrate``), never behind the operator's back: the service
  refuses to start on them (:func:`prepare`, :class:`SchemaError`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import sqlalchemy as sa
from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy.engine import Connection, Engine

from camvlp.service.db import metadata

__all__ = ["BASELINE", "SchemaError", "SchemaState", "head", "prepare", "schema_state", "upgrade"]

#: The folder with ``env.py`` and ``versions/``.
MIGRATIONS_DIR = Path(__file__).resolve().parent / "migrations"
#: The revision of a database that camvlp 0.1.0 made (it kept no version).
BASELINE = "0001"


class SchemaError(Exception):
    """The database is not at the revision this code needs; the message says what to do."""


@dataclass(frozen=True)
class SchemaState:
    """Where a database stands.

    Attributes
    ----------
    revision : str or None
        Its Alembic revision; :data:`BASELINE` for camvlp 0.1.0's tables without a version;
        None for an empty database.
    head : str
        The revision this code reads and writes.
    """

    revision: str | None
    head: str

    @property
    def empty(self) -> bool:
        """No tables of the service yet."""
        return self.revision is None

    @property
    def current(self) -> bool:
        """At the revision this code needs."""
        return self.revision == self.head


def _config(connection: Connection | None = None) -> Config:
    cfg = Config()
    cfg.set_main_option("script_location", str(MIGRATIONS_DIR))
    cfg.attributes["connection"] = connection
    return cfg


@functools.cache
def _scripts() -> ScriptDirectory:
    return ScriptDirectory.from_config(_config())


def head() -> str:
    """The last revision (the schema of :data:`camvlp.service.db.metadata`)."""
    top = _scripts().get_current_head()
    assert top is not None
    return top


def _known(revision: str) -> bool:
    try:
        return _scripts().get_revision(revision) is not None
    except Exception:  # alembic's ResolutionError and friends: a revision of some other code
        return False


def schema_state(engine: Engine) -> SchemaState:
    """The database's revision (see :class:`SchemaState`)."""
    with engine.connect() as conn:
        tables = set(sa.inspect(conn).get_table_names())
        revision = MigrationContext.configure(conn).get_current_revision()
    if revision is None and "sites" in tables:
        revision = BASELINE
    return SchemaState(revision, head())


def prepare(engine: Engine) -> SchemaState:
    """Make an empty database at the last revision; check that any other one is there.

    Raises
    ------
    SchemaError
        The database is at an older revision (``camvlp serve --migrate`` upgrades it) or at
        one this code does not know (a newer camvlp made it).
    """
    state = schema_state(engine)
    if state.empty:
        with engine.begin() as conn:
            metadata.create_all(conn)
            command.stamp(_config(conn), state.head)
        return SchemaState(state.head, state.head)
    if state.current:
        return state
    if not _known(state.revision):
        raise SchemaError(
            f"the database is at revision {state.revision}, which this camvlp does not know "
            f"(it needs {state.head}): a newer camvlp made it"
        )
    raise SchemaError(
        f"the database is at revision {state.revision} and this camvlp needs {state.head}: "
        "upgrade it first with camvlp serve --migrate (back it up before)"
    )


def upgrade(engine: Engine) -> tuple[str | None, str]:
    """Upgrade the database to the last revision; returns ``(from, to)`` revisions.

    An empty database is built by running every migration; camvlp 0.1.0's tables are first
    marked as :data:`BASELINE`.  Each step runs in one transaction (PostgreSQL's DDL is
    transactional: a failed step leaves the database as it was).

    Raises
    ------
    SchemaError
        The database is at a revision this code does not know.
    """
    state = schema_state(engine)
    if state.revision is not None and not _known(state.revision):
        raise SchemaError(
            f"the database is at revision {state.revision}, which this camvlp does not know "
            f"(it has {state.head}): a newer camvlp made it"
        )
    with engine.begin() as conn:
        cfg = _config(conn)
        if state.revision == BASELINE and not _versioned(conn):
            command.stamp(cfg, BASELINE)
        command.upgrade(cfg, "head")
    return state.revision, state.head


def _versioned(conn: Connection) -> bool:
    return MigrationContext.configure(conn).get_current_revision() is not None
