"""Sessions name the server process that runs them (several may share one PostgreSQL database).

Revision ID: 0004_session_node
Revises: 0003_accounts

A process recovers after a crash only the sessions and recordings it ran (``SessionManager.recover_after_crash``),
and refuses to stop another's.
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0004_session_node"
down_revision: str | Sequence[str] | None = "0003_accounts"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column("sessions", sa.Column("node", sa.String(128), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("sessions") as batch:  # SQLite drops a column by copying the table
        batch.drop_column("node")
