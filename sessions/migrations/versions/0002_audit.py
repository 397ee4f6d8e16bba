"""The audit trail (issue #13): the append-only ``audit`` table and the triggers that keep it so.

Revision ID: 0002_audit
Revises: 0001_baseline

Runs on SQLite and PostgreSQL. The table is written out here, as it is at this revision (a later change of
:class:`gaitscope.sessions.audit.tables.AuditRow` gets its own revision); the triggers' DDL is shared with the tests
(:func:`gaitscope.sessions.audit.tables.create_triggers`), so that what the tests check is what the migration makes.
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

from gaitscope.sessions.audit.tables import create_triggers, drop_triggers

revision: str = "0002_audit"
down_revision: str | Sequence[str] | None = "0001_baseline"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_INT = sa.BigInteger().with_variant(sa.Integer(), "sqlite")  # as 0001_baseline: BIGINT on PostgreSQL


def upgrade() -> None:
    op.create_table(
        "audit",
        sa.Column("id", _INT, primary_key=True, autoincrement=True),
        sa.Column("seq", _INT, nullable=False),
        sa.Column("time_utc", sa.String(length=40), nullable=False),
        sa.Column("user", sa.String(length=64), nullable=False),
        sa.Column("role", sa.String(length=16), nullable=False),
        sa.Column("action", sa.String(length=128), nullable=False),
        sa.Column("target", sa.Text(), nullable=False),
        sa.Column("before", sa.Text(), nullable=True),
        sa.Column("after", sa.Text(), nullable=True),
        sa.Column("outcome", sa.String(length=16), nullable=False),
        sa.Column("detail", sa.Text(), nullable=False),
        sa.Column("prev_hash", sa.String(length=64), nullable=False),
        sa.Column("hash", sa.String(length=64), nullable=False),
        sa.UniqueConstraint("seq"),
    )
    op.create_index("ix_audit_time_utc", "audit", ["time_utc"])
    op.create_index("ix_audit_user", "audit", ["user"])
    op.create_index("ix_audit_action", "audit", ["action"])
    create_triggers(op.get_bind())


def downgrade() -> None:
    drop_triggers(op.get_bind())
    op.drop_index("ix_audit_action", table_name="audit")
    op.drop_index("ix_audit_user", table_name="audit")
    op.drop_index("ix_audit_time_utc", table_name="audit")
    op.drop_table("audit")
