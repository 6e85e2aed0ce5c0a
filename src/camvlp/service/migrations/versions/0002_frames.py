"""Fixes from video frames: where a fix came from, a frame's status, the position's sigma,
and an index for one device's fixes.

Existing fixes keep every value; they are marked as photos (``source = 'photo'``), with no
status and no sigma.

Revision ID: 0002
Revises: 0001
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column(
        "fixes", sa.Column("source", sa.String(10), nullable=False, server_default="photo")
    )
    op.add_column("fixes", sa.Column("status", sa.String(16)))
    op.add_column("fixes", sa.Column("position_sigma", sa.JSON))
    op.create_index("ix_fixes_site_id_device_id", "fixes", ["site_id", "device", "id"])


def downgrade() -> None:
    op.drop_index("ix_fixes_site_id_device_id", "fixes")
    with op.batch_alter_table("fixes") as batch:  # SQLite drops columns by copying the table
        batch.drop_column("position_sigma")
        batch.drop_column("status")
        batch.drop_column("source")
