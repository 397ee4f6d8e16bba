"""The channel_mappings table: a lab's saved channel mappings, by rig (issue #25).

Revision ID: 0007_channel_mappings
Revises: 0006_nodes

An upload of another tool's MCAP recording or of a C3D file maps its fields to gaitscope's channels; the mapping
an import used is kept under the file's rig signature, so the next file of the same rig maps itself.
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0007_channel_mappings"
down_revision: str | Sequence[str] | None = "0006_nodes"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "channel_mappings",
        sa.Column("rig", sa.String(64), primary_key=True),
        sa.Column("kind", sa.String(8), nullable=False),
        sa.Column("mapping", sa.Text(), nullable=False),
        sa.Column("actor", sa.String(128), nullable=False),
        sa.Column("updated_utc", sa.String(40), nullable=False),
    )


def downgrade() -> None:
    op.drop_table("channel_mappings")
