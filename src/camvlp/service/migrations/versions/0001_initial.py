"""The schema of camvlp 0.1.0, the first release of ``camvlp serve`` (before migrations).

A database made by that release has these tables and no ``alembic_version``:
``camvlp serve --migrate`` marks it as this revision, then upgrades it.

Revision ID: 0001
Revises:
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None

_Id = sa.BigInteger().with_variant(sa.Integer(), "sqlite")


def upgrade() -> None:
    op.create_table(
        "sites",
        sa.Column("id", _Id, primary_key=True, autoincrement=True),
        sa.Column("name", sa.String(200), nullable=False),
        sa.Column("key_hash", sa.String(64), nullable=False, unique=True),
        sa.Column("map", sa.JSON, nullable=False),
        sa.Column("created", sa.Float, nullable=False),
    )
    op.create_table(
        "cameras",
        sa.Column("site_id", _Id, sa.ForeignKey("sites.id"), primary_key=True),
        sa.Column("name", sa.String(100), primary_key=True),
        sa.Column("camera", sa.JSON, nullable=False),
        sa.Column("updated", sa.Float, nullable=False),
    )
    op.create_table(
        "fixes",
        sa.Column("id", _Id, primary_key=True, autoincrement=True),
        sa.Column("site_id", _Id, sa.ForeignKey("sites.id"), nullable=False),
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
    )
    op.create_index("ix_fixes_site_id_id", "fixes", ["site_id", "id"])
    op.create_table(
        "pictures",
        sa.Column("fix_id", _Id, sa.ForeignKey("fixes.id"), primary_key=True),
        sa.Column("jpeg", sa.LargeBinary, nullable=False),
    )


def downgrade() -> None:
    for table in ("pictures", "fixes", "cameras", "sites"):
        op.drop_table(table)
