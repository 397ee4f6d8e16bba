"""Baseline: the tables as they were before migrations.

Subjects, sessions, trials, events, personalizations, IMU calibrations and review annotations.

Revision ID: 0001_baseline
Revises:
Create Date: 2026-11-24

Written out, not ``create_all``: later revisions change the models, and this one must keep creating
what a database made before migrations holds. Ids and integer columns are BIGINT on PostgreSQL and
INTEGER on SQLite (where only ``INTEGER PRIMARY KEY`` is the rowid that numbers rows by itself).

A table that already exists is left as it is: a database made before migrations that predates some
of these tables gets just the missing ones (:func:`gaitscope.sessions.migrations.migrate` stamps one that has
them all instead of running this).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0001_baseline"
down_revision: str | Sequence[str] | None = None
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_INT = sa.BigInteger().with_variant(sa.Integer(), "sqlite")


def _id() -> sa.Column[int]:
    return sa.Column("id", _INT, primary_key=True, autoincrement=True)


def _subjects() -> None:
    op.create_table(
        "subjects",
        _id(),
        sa.Column("code", sa.String(32), nullable=False),
        sa.Column("leg_length_m", sa.Double(), nullable=False),
        sa.Column("mass_kg", sa.Double(), nullable=False),
        sa.Column("side", sa.String(8), nullable=False),
        sa.Column("notes", sa.Text(), nullable=False),
        sa.Column("created_utc", sa.String(40), nullable=False),
        sa.UniqueConstraint("code"),
    )


def _sessions() -> None:
    op.create_table(
        "sessions",
        _id(),
        sa.Column("subject_id", _INT, sa.ForeignKey("subjects.id"), nullable=False),
        sa.Column("source", sa.Text(), nullable=False),
        sa.Column("settings", sa.Text(), nullable=False),
        sa.Column("state", sa.String(16), nullable=False),
        sa.Column("created_utc", sa.String(40), nullable=False),
        sa.Column("started_utc", sa.String(40), nullable=True),
        sa.Column("stopped_utc", sa.String(40), nullable=True),
    )
    op.create_index("ix_sessions_subject_id", "sessions", ["subject_id"])
    op.create_index("ix_sessions_state", "sessions", ["state"])


def _trials() -> None:
    op.create_table(
        "trials",
        _id(),
        sa.Column("session_id", _INT, sa.ForeignKey("sessions.id"), nullable=False),
        sa.Column("name", sa.Text(), nullable=False),
        sa.Column("status", sa.String(16), nullable=False),
        sa.Column("path", sa.Text(), nullable=False),
        sa.Column("started_utc", sa.String(40), nullable=False),
        sa.Column("stopped_utc", sa.String(40), nullable=True),
        sa.Column("samples", _INT, nullable=False),
        sa.Column("duration_s", sa.Double(), nullable=False),
    )
    op.create_index("ix_trials_session_id", "trials", ["session_id"])
    op.create_index("ix_trials_status", "trials", ["status"])


def _events() -> None:
    op.create_table(
        "events",
        _id(),
        sa.Column("session_id", _INT, sa.ForeignKey("sessions.id"), nullable=False),
        sa.Column("trial_id", _INT, sa.ForeignKey("trials.id"), nullable=True),
        sa.Column("t", sa.Double(), nullable=False),
        sa.Column("wall_utc", sa.String(40), nullable=False),
        sa.Column("kind", sa.String(16), nullable=False),
        sa.Column("text", sa.Text(), nullable=False),
        sa.Column("field", sa.String(64), nullable=True),
        sa.Column("before", sa.Text(), nullable=True),
        sa.Column("after", sa.Text(), nullable=True),
        sa.Column("actor", sa.String(64), nullable=False),
    )
    op.create_index("ix_events_trial_id", "events", ["trial_id"])
    op.create_index("ix_events_session_t", "events", ["session_id", "t"])


def _personalizations() -> None:
    op.create_table(
        "personalizations",
        _id(),
        sa.Column("subject_id", _INT, sa.ForeignKey("subjects.id"), nullable=False),
        sa.Column("version", _INT, nullable=False),
        sa.Column("model", sa.String(32), nullable=False),
        sa.Column("fingerprint", sa.Text(), nullable=False),
        sa.Column("fit_rmse_avg_deg", sa.Double(), nullable=False),
        sa.Column("fit_rmse_personal_deg", sa.Double(), nullable=False),
        sa.Column("source_trial_id", _INT, sa.ForeignKey("trials.id"), nullable=True),
        sa.Column("strides_used", _INT, nullable=False),
        sa.Column("strides_excluded", _INT, nullable=False),
        sa.Column("seconds_used", sa.Double(), nullable=False),
        sa.Column("excluded", sa.Text(), nullable=False),
        sa.Column("stride_length_source", sa.String(64), nullable=False),
        sa.Column("state", sa.String(16), nullable=False),
        sa.Column("created_utc", sa.String(40), nullable=False),
        sa.Column("created_by", sa.String(64), nullable=False),
        sa.Column("promoted_utc", sa.String(40), nullable=True),
        sa.Column("promoted_by", sa.String(64), nullable=True),
        sa.Column("retired_utc", sa.String(40), nullable=True),
        sa.Column("retired_by", sa.String(64), nullable=True),
        sa.Column("replaced_id", _INT, nullable=True),
        sa.Column("note", sa.Text(), nullable=False),
    )
    op.create_index("ix_personalizations_subject_model", "personalizations", ["subject_id", "model"])


def _imu_calibrations() -> None:
    op.create_table(
        "imu_calibrations",
        _id(),
        sa.Column("subject_id", _INT, sa.ForeignKey("subjects.id"), nullable=False),
        sa.Column("session_id", _INT, sa.ForeignKey("sessions.id"), nullable=False),
        sa.Column("trial_id", _INT, sa.ForeignKey("trials.id"), nullable=True),
        sa.Column("duration_s", sa.Double(), nullable=False),
        sa.Column("sensors", sa.Text(), nullable=False),
        sa.Column("created_utc", sa.String(40), nullable=False),
        sa.Column("created_by", sa.String(64), nullable=False),
        sa.Column("note", sa.Text(), nullable=False),
    )
    op.create_index("ix_imu_calibrations_subject_id", "imu_calibrations", ["subject_id"])
    op.create_index("ix_imu_calibrations_session_id", "imu_calibrations", ["session_id"])


def _review_annotations() -> None:
    op.create_table(
        "review_annotations",
        _id(),
        sa.Column("trial_id", _INT, sa.ForeignKey("trials.id"), nullable=False),
        sa.Column("t", sa.Double(), nullable=False),
        sa.Column("t_end", sa.Double(), nullable=True),
        sa.Column("text", sa.Text(), nullable=False),
        sa.Column("actor", sa.String(64), nullable=False),
        sa.Column("created_utc", sa.String(40), nullable=False),
    )
    op.create_index("ix_review_annotations_trial_id", "review_annotations", ["trial_id"])


#: Each table and how to create it (with its indexes), parents before children.
_TABLES: dict[str, Callable[[], None]] = {
    "subjects": _subjects,
    "sessions": _sessions,
    "trials": _trials,
    "events": _events,
    "personalizations": _personalizations,
    "imu_calibrations": _imu_calibrations,
    "review_annotations": _review_annotations,
}


def upgrade() -> None:
    existing = set(sa.inspect(op.get_bind()).get_table_names())
    for name, create in _TABLES.items():
        if name not in existing:
            create()


def downgrade() -> None:
    for name in reversed(_TABLES):
        op.drop_table(name)  # its indexes go with it
