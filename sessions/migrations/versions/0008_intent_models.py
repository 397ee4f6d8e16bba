"""The intent_models table: a subject's speed-change intent model (issue #26).

Revision ID: 0008_intent_models
Revises: 0007_channel_mappings

Seed 001's step-length model (kappa) fitted on a trial of the subject's, or the iSCI variant; the subject's
sessions run it from their next start (``gaitscope.sessions.personalization.intent_model``).
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0008_intent_models"
down_revision: str | Sequence[str] | None = "0007_channel_mappings"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_INT = sa.BigInteger().with_variant(sa.Integer(), "sqlite")


def upgrade() -> None:
    op.create_table(
        "intent_models",
        sa.Column("subject_id", _INT, sa.ForeignKey("subjects.id"), primary_key=True),
        sa.Column("variant", sa.String(16), nullable=False),
        sa.Column("kappa", sa.Text(), nullable=False),
        sa.Column("alpha", sa.Text(), nullable=True),
        sa.Column("source", sa.String(200), nullable=False),
        sa.Column("source_trial_id", _INT, nullable=True),
        sa.Column("steps", _INT, nullable=False),
        sa.Column("step_rmse_m", sa.Double(), nullable=True),
        sa.Column("actor", sa.String(128), nullable=False),
        sa.Column("updated_utc", sa.String(40), nullable=False),
        sa.Column("note", sa.Text(), nullable=False),
    )


def downgrade() -> None:
    op.drop_table("intent_models")
