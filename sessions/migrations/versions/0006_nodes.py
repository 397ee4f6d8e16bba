"""The nodes table: gaitscope processes sharing one database, their addresses and heartbeats (issue #24).

Revision ID: 0006_nodes
Revises: 0005_audit_mac

A process started with ``GAITSCOPE_CLUSTER=true`` (``gaitscope serve --workers N``, docker compose) registers
itself and beats every second; the proxy asks any node where a session's traffic goes, and a node whose beat
stops has its sessions stopped and its recordings recovered by another (``sessions/cluster``).
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0006_nodes"
down_revision: str | Sequence[str] | None = "0005_audit_mac"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "nodes",
        sa.Column("name", sa.String(128), primary_key=True),
        sa.Column("address", sa.String(256), nullable=False),
        sa.Column("state", sa.String(8), nullable=False),
        sa.Column("started_utc", sa.String(40), nullable=False),
        sa.Column("seen_utc", sa.String(40), nullable=False),
        sa.Column("gone_by", sa.String(128), nullable=True),
    )


def downgrade() -> None:
    op.drop_table("nodes")
