"""Alembic's entry point for its own command line (``alembic -c sessions/migrations/alembic.ini ...``).

The store and ``gaitscope db`` do not come here (:func:`gaitscope.sessions.migrations.run` configures the
migration itself); this file serves ``alembic revision --autogenerate`` and friends. The database is
``-x url=...``, else ``sqlalchemy.url`` of the configuration, else ``GAITSCOPE_DATABASE_URL``, else
the default SQLite file of :class:`gaitscope.server.settings.Settings`.
"""

from __future__ import annotations

from alembic import context
from sqlalchemy import create_engine

from gaitscope.sessions.migrations import LOCK_KEY, configure


def _url() -> str:
    url = context.get_x_argument(as_dictionary=True).get("url") or context.config.get_main_option("sqlalchemy.url")
    if url:
        return url
    from gaitscope.server.settings import Settings

    return Settings().database_url


def _offline() -> None:
    context.configure(url=_url(), literal_binds=True, render_as_batch=True)
    with context.begin_transaction():
        context.run_migrations()


def _online() -> None:
    engine = create_engine(_url())
    try:
        with engine.connect() as connection:
            configure(context, connection)  # type: ignore[arg-type]  # the module proxies EnvironmentContext
            with context.begin_transaction():
                if connection.dialect.name == "postgresql":
                    connection.exec_driver_sql(f"SELECT pg_advisory_xact_lock({LOCK_KEY})")
                context.run_migrations()
    finally:
        engine.dispose()


if context.is_offline_mode():
    _offline()
else:
    _online()
