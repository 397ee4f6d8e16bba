"""The audit trail is keyed (issue #21): each entry carries ``mac``, the HMAC-SHA256 of its hash under the audit key.

Revision ID: 0005_audit_mac
Revises: 0004_session_node

Runs on SQLite and PostgreSQL. Existing entries keep no MAC (null): the key did not exist when they were written,
and making their MACs now would vouch for whatever the table holds today. The first server start after the
upgrade appends an ``audit.keyed`` entry, the first with a MAC (:meth:`gaitscope.sessions.audit.AuditLog.ensure_keyed`);
verification checks the entries before it by the SHA-256 chain alone, and says so.

The downgrade drops the column, and with it the MACs (the code of revision 0004 cannot check them). On SQLite the
column is dropped by copying the table, which drops its append-only triggers: they are made again.
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

from gaitscope.sessions.audit.tables import create_triggers

revision: str = "0005_audit_mac"
down_revision: str | Sequence[str] | None = "0004_session_node"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    # ADD COLUMN on both databases: no copy of the table, so the triggers stay; a new column's nulls are no UPDATE.
    op.add_column("audit", sa.Column("mac", sa.String(64), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("audit") as batch:
        batch.drop_column("mac")
    create_triggers(op.get_bind())
