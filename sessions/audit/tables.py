"""The audit trail's table, and the triggers that make it append-only in the database itself.

Declared on :data:`sessions.store.Base`, so that the audit trail lives in the same database (and the same chain
of Alembic migrations, ``sessions/migrations/versions/0002_audit.py``) as what it audits. The triggers' DDL is
here, as functions, so that the migration and the tests create exactly the same triggers.

The triggers refuse ``UPDATE`` and ``DELETE`` (and, on PostgreSQL, ``TRUNCATE``) on the table: a bug, or a person
with an SQL shell who does not mean harm, cannot change the trail. Someone who can drop triggers can; that is what
the hash chain (:mod:`gaitscope.sessions.audit.log`) is for: ``gaitscope audit verify`` finds the change.
"""

from __future__ import annotations

from typing import Final

from sqlalchemy import Connection, Index, String, Text
from sqlalchemy.orm import Mapped, mapped_column

from gaitscope.sessions.store import Base

__all__ = ["TABLE", "TRIGGERS", "AuditRow", "create_triggers", "drop_triggers"]

#: The table's name.
TABLE: Final = "audit"
#: The triggers' names (on PostgreSQL also the function they call, :data:`_PG_FUNCTION`).
TRIGGERS: Final = ("audit_no_update", "audit_no_delete", "audit_no_truncate")
_PG_FUNCTION: Final = "audit_append_only"
#: The message both databases give when the table is written to other than by an INSERT.
REFUSED: Final = "the audit trail is append-only"


class AuditRow(Base):
    """One entry; ``seq`` numbers the chain 1..n without gaps, ``id`` is only the database's row key.

    ``before`` and ``after`` hold JSON text exactly as it was hashed (``None``: SQL NULL, hashed as JSON null).
    """

    __tablename__ = TABLE
    __table_args__ = (
        Index("ix_audit_time_utc", "time_utc"),
        Index("ix_audit_user", "user"),
        Index("ix_audit_action", "action"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    seq: Mapped[int] = mapped_column(unique=True)
    time_utc: Mapped[str] = mapped_column(String(40))
    user: Mapped[str] = mapped_column(String(64))
    role: Mapped[str] = mapped_column(String(16))
    action: Mapped[str] = mapped_column(String(128))
    target: Mapped[str] = mapped_column(Text)
    before: Mapped[str | None] = mapped_column(Text)
    after: Mapped[str | None] = mapped_column(Text)
    outcome: Mapped[str] = mapped_column(String(16))
    detail: Mapped[str] = mapped_column(Text)
    prev_hash: Mapped[str] = mapped_column(String(64))
    hash: Mapped[str] = mapped_column(String(64))
    #: HMAC-SHA256 of ``hash`` under the audit key (``sessions/audit/key.py``); None for the entries written
    #: before the trail was keyed (migration ``0005_audit_mac``).
    mac: Mapped[str | None] = mapped_column(String(64))


def _sqlite_ddl() -> list[str]:
    return [
        f"CREATE TRIGGER IF NOT EXISTS {name} BEFORE {op} ON {TABLE} "
        f"BEGIN SELECT RAISE(ABORT, '{REFUSED}: {op} refused'); END"
        for name, op in (("audit_no_update", "UPDATE"), ("audit_no_delete", "DELETE"))
    ]


def _postgresql_ddl() -> list[str]:
    return [
        f"CREATE OR REPLACE FUNCTION {_PG_FUNCTION}() RETURNS trigger LANGUAGE plpgsql AS $$ "
        # No "%" placeholder in the message: the driver would take it for a parameter.
        f"BEGIN RAISE EXCEPTION USING MESSAGE = '{REFUSED}: ' || TG_OP || ' refused', "
        "ERRCODE = 'insufficient_privilege'; END $$",
        *(
            f"DROP TRIGGER IF EXISTS {name} ON {TABLE}"  # CREATE OR REPLACE TRIGGER needs PostgreSQL 14
            for name in TRIGGERS
        ),
        f"CREATE TRIGGER audit_no_update BEFORE UPDATE ON {TABLE} FOR EACH ROW EXECUTE FUNCTION {_PG_FUNCTION}()",
        f"CREATE TRIGGER audit_no_delete BEFORE DELETE ON {TABLE} FOR EACH ROW EXECUTE FUNCTION {_PG_FUNCTION}()",
        f"CREATE TRIGGER audit_no_truncate BEFORE TRUNCATE ON {TABLE} "
        f"FOR EACH STATEMENT EXECUTE FUNCTION {_PG_FUNCTION}()",
    ]


def create_triggers(connection: Connection) -> None:
    """Create the append-only triggers on ``connection``'s database (SQLite or PostgreSQL); idempotent.

    Raises:
        NotImplementedError: another database, for which nobody has written (or tested) the triggers.
    """
    dialect = connection.dialect.name
    if dialect == "sqlite":
        ddl = _sqlite_ddl()
    elif dialect == "postgresql":
        ddl = _postgresql_ddl()
    else:
        raise NotImplementedError(f"no append-only triggers for {dialect} databases (SQLite and PostgreSQL only)")
    for statement in ddl:
        connection.exec_driver_sql(statement)


def drop_triggers(connection: Connection) -> None:
    """Drop the append-only triggers (the migration's downgrade); idempotent."""
    dialect = connection.dialect.name
    for name in TRIGGERS:
        if dialect == "postgresql":
            connection.exec_driver_sql(f"DROP TRIGGER IF EXISTS {name} ON {TABLE}")
        else:
            connection.exec_driver_sql(f"DROP TRIGGER IF EXISTS {name}")
    if dialect == "postgresql":
        connection.exec_driver_sql(f"DROP FUNCTION IF EXISTS {_PG_FUNCTION}()")
