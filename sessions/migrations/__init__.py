"""Alembic migrations of the gaitscope database: one chain of revisions for SQLite and PostgreSQL.

:class:`gaitscope.sessions.store.Store` calls :func:`migrate` when it opens a database, so that a new database
is created by the migrations (never by ``create_all``), one made before migrations existed is upgraded
in place, and a versioned one is brought to the newest revision. ``gaitscope db`` (:mod:`.cli`) runs
the same code by hand; Alembic's own command line works too, through ``env.py`` here
(``alembic -x url=sqlite:///gaitscope-data/gaitscope.db -c sessions/migrations/alembic.ini current``).

Why not plain ``alembic.command.upgrade``: it re-reads and re-compiles every revision file on each
call, and the test suite opens hundreds of stores. :func:`script_directory` reads them once per
process, and :func:`migrate` returns at once when the database is already at head.

Revisions live in ``versions/``, one file each, named ``NNNN_what.py`` with ``revision = "NNNN_what"``.
Every revision must run on both databases: on SQLite, altering a column or constraint of an existing
table needs ``op.batch_alter_table`` (``render_as_batch`` is on, so ``alembic revision --autogenerate``
writes it that way).
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

if TYPE_CHECKING:  # alembic is imported by the functions that use it: every gaitscope command imports this
    # package (it registers ``gaitscope db``), and alembic takes a noticeable part of a second to import
    from alembic.config import Config
    from alembic.runtime.environment import EnvironmentContext
    from alembic.runtime.migration import MigrationContext
    from alembic.script import ScriptDirectory
    from sqlalchemy import Connection

__all__ = [
    "BASELINE",
    "BASELINE_TABLES",
    "LOCK_KEY",
    "SCRIPT_LOCATION",
    "config",
    "configure",
    "current",
    "migrate",
    "run",
    "script_directory",
]

#: This folder: ``env.py``, ``script.py.mako`` and ``versions/``.
SCRIPT_LOCATION: Final = Path(__file__).resolve().parent
#: The first revision: the tables as they were before migrations (issue #13).
BASELINE: Final = "0001_baseline"
#: The tables of :data:`BASELINE`, which a database made before migrations already has.
BASELINE_TABLES: Final = (
    "subjects", "sessions", "trials", "events", "personalizations", "imu_calibrations", "review_annotations",
)  # fmt: skip
#: Key of the PostgreSQL advisory lock that serialises migrations and the store's write transactions
#: (``pg_advisory_xact_lock``): the first 8 bytes of "gaitscop" as a signed 64-bit integer.
LOCK_KEY: Final = int.from_bytes(b"gaitscop", "big", signed=True)


@functools.cache
def script_directory() -> ScriptDirectory:
    """The revision scripts, read once per process (Alembic parses them lazily, then keeps the map)."""
    from alembic.script import ScriptDirectory

    return ScriptDirectory(str(SCRIPT_LOCATION))


def config(url: str | None = None) -> Config:
    """An Alembic configuration with no ini file: this folder as the scripts, ``url`` as the database."""
    from alembic.config import Config

    cfg = Config()
    cfg.set_main_option("script_location", str(SCRIPT_LOCATION))
    if url is not None:
        cfg.set_main_option("sqlalchemy.url", url.replace("%", "%%"))  # ConfigParser interpolation
    return cfg


def configure(context: EnvironmentContext, connection: Connection, **kwargs: Any) -> None:
    """Configure a migration run on ``connection``: the same options for the store, ``gaitscope db`` and
    ``alembic``. ``render_as_batch`` because SQLite alters tables by copying them."""
    from gaitscope.sessions.store import all_metadata

    context.configure(
        connection=connection,
        target_metadata=all_metadata(),
        render_as_batch=True,
        compare_type=True,
        transaction_per_migration=False,
        **kwargs,
    )


def current(connection: Connection) -> tuple[str, ...]:
    """The revisions the database is at (``()``: unversioned, new or made before migrations)."""
    from alembic.runtime.migration import MigrationContext

    return MigrationContext.configure(connection).get_current_heads()


def run(connection: Connection, target: str, *, downgrade: bool = False, cfg: Config | None = None) -> None:
    """Upgrade (or downgrade) the database on ``connection`` to revision ``target``, inside the caller's
    transaction when one is open (then nothing is committed here)."""
    from alembic.runtime.environment import EnvironmentContext

    script = script_directory()

    def step(rev: Any, _context: MigrationContext) -> Any:
        # What alembic.command.upgrade / downgrade do, with the cached script directory.
        return script._downgrade_revs(target, rev) if downgrade else script._upgrade_revs(target, rev)

    with EnvironmentContext(cfg or config(), script, fn=step, destination_rev=target) as env:
        configure(env, connection)
        with env.begin_transaction():
            env.run_migrations()


def migrate(connection: Connection) -> None:
    """Bring the database on ``connection`` to the newest revision, in the caller's (write) transaction.

    - already at head: nothing (one query);
    - made before migrations (the baseline's tables exist, no ``alembic_version``): stamped
      :data:`BASELINE` (its rows are kept as they are), then upgraded. If it predates some of the
      baseline's tables, the baseline instead creates just the missing ones;
    - new or versioned: upgraded to head.

    The caller holds the database's write lock (SQLite ``BEGIN IMMEDIATE``, PostgreSQL
    :data:`LOCK_KEY`), so two processes opening one new database do not both create it.
    """
    from alembic.runtime.migration import MigrationContext
    from sqlalchemy import inspect

    script = script_directory()
    heads = current(connection)
    if set(heads) == set(script.get_heads()):
        return
    if not heads:
        tables = set(inspect(connection).get_table_names())
        if tables.issuperset(BASELINE_TABLES):
            MigrationContext.configure(connection).stamp(script, BASELINE)
    run(connection, "heads")
