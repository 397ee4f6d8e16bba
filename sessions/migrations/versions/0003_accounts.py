"""Accounts (issue #13): users, their logins, device tokens, the experimenters' assistance limits.

Revision ID: 0003_accounts
Revises: 0002_audit

Runs on SQLite and PostgreSQL. The tables as :mod:`gaitscope.sessions.accounts.tables` declares them at this revision.
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0003_accounts"
down_revision: str | Sequence[str] | None = "0002_audit"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_INT = sa.BigInteger().with_variant(sa.Integer(), "sqlite")  # as 0001_baseline: BIGINT on PostgreSQL


def _id() -> sa.Column[int]:
    return sa.Column("id", _INT, primary_key=True, autoincrement=True)


def upgrade() -> None:
    op.create_table(
        "users",
        _id(),
        sa.Column("name", sa.String(32), nullable=False),
        sa.Column("role", sa.String(16), nullable=False),
        sa.Column("password_hash", sa.Text(), nullable=False),
        sa.Column("disabled", sa.Boolean(), nullable=False),
        sa.Column("created_utc", sa.String(40), nullable=False),
        sa.Column("created_by", sa.String(64), nullable=False),
        sa.Column("last_login_utc", sa.String(40), nullable=True),
        sa.Column("failed_logins", _INT, nullable=False),
        sa.Column("locked_until_utc", sa.String(40), nullable=True),
        sa.UniqueConstraint("name"),
    )
    op.create_table(
        "logins",
        _id(),
        sa.Column("user_id", _INT, sa.ForeignKey("users.id"), nullable=False),
        sa.Column("token_sha256", sa.String(64), nullable=False),
        sa.Column("csrf_token", sa.String(64), nullable=False),
        sa.Column("created_utc", sa.String(40), nullable=False),
        sa.Column("seen_utc", sa.String(40), nullable=False),
        sa.Column("expires_utc", sa.String(40), nullable=False),
        sa.Column("ended_utc", sa.String(40), nullable=True),
        sa.UniqueConstraint("token_sha256"),
    )
    op.create_index("ix_logins_user_id", "logins", ["user_id"])
    op.create_table(
        "device_tokens",
        _id(),
        sa.Column("session_id", _INT, sa.ForeignKey("sessions.id"), nullable=False),
        sa.Column("token_sha256", sa.String(64), nullable=False),
        sa.Column("prefix", sa.String(16), nullable=False),
        sa.Column("created_utc", sa.String(40), nullable=False),
        sa.Column("created_by", sa.String(64), nullable=False),
        sa.Column("revoked_utc", sa.String(40), nullable=True),
        sa.Column("revoked_by", sa.String(64), nullable=True),
        sa.UniqueConstraint("token_sha256"),
    )
    op.create_index("ix_device_tokens_session_id", "device_tokens", ["session_id"])
    op.create_table(
        "assistance_limits",
        sa.Column("subject_id", _INT, sa.ForeignKey("subjects.id"), primary_key=True, autoincrement=False),
        sa.Column("torque_gain", sa.Double(), nullable=False),
        sa.Column("max_torque_Nm", sa.Double(), nullable=False),
        sa.Column("intent_gain_boost", sa.Double(), nullable=False),
        sa.Column("set_by", sa.String(64), nullable=False),
        sa.Column("set_utc", sa.String(40), nullable=False),
    )


def downgrade() -> None:
    op.drop_table("assistance_limits")
    op.drop_index("ix_device_tokens_session_id", table_name="device_tokens")
    op.drop_table("device_tokens")
    op.drop_index("ix_logins_user_id", table_name="logins")
    op.drop_table("logins")
    op.drop_table("users")
