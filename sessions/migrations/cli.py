"""``gaitscope db``: the database's migrations by hand (``upgrade``, ``downgrade``, ``current``, ``history``).

The server needs none of this (it upgrades the database when it opens it); this is for an operator who
wants to upgrade before starting the servers, look at the version, or step back after a bad release.
The database is ``--database-url``, else ``GAITSCOPE_DATABASE_URL``, else the default of
:class:`gaitscope.server.settings.Settings` (the SQLite file in the data folder). Each command runs in one
transaction holding the database's write lock, as the store's own upgrade does. Errors (an unknown
revision, a database that cannot be reached) exit with status 2 and one line naming the database.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

__all__ = ["register"]

EXIT_ERROR = 2


def _url(a: argparse.Namespace) -> str:
    if a.database_url:
        return str(a.database_url)
    from gaitscope.server.settings import Settings  # the server's one settings object: env var, then its default

    return Settings().database_url


def _heads_label(revision: str, current: tuple[str, ...], heads: tuple[str, ...]) -> str:
    tags = [t for t, on in (("head", revision in heads), ("current", revision in current)) if on]
    return f" ({', '.join(tags)})" if tags else ""


def cmd_db(a: argparse.Namespace) -> int:
    # imported here, not with the module: every gaitscope command registers ``db``, and alembic takes a
    # noticeable part of a second to import (a replay's start-up)
    from alembic.util.exc import CommandError
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import SQLAlchemyError

    from gaitscope.sessions import migrations
    from gaitscope.sessions.store import make_engine, write_transaction

    url = _url(a)
    shown = make_url(url).render_as_string(hide_password=True)
    engine = make_engine(url)
    script = migrations.script_directory()
    try:
        with write_transaction(engine) as connection:
            if a.db_command == "upgrade":
                if a.revision == "head":
                    migrations.migrate(connection)  # also stamps a database made before migrations
                else:
                    migrations.run(connection, a.revision)
                print(f"{shown}: at {', '.join(migrations.current(connection)) or 'base'}")
            elif a.db_command == "downgrade":
                migrations.run(connection, a.revision, downgrade=True)
                print(f"{shown}: at {', '.join(migrations.current(connection)) or 'base'}")
            elif a.db_command == "current":
                current = migrations.current(connection)
                heads = tuple(script.get_heads())
                print("\n".join(f"{r}{_heads_label(r, current, heads)}" for r in current) or "base (unversioned)")
            else:  # history, newest first
                current, heads = migrations.current(connection), tuple(script.get_heads())
                for rev in script.walk_revisions():
                    title = (rev.doc or "").strip().splitlines()[0] if rev.doc else ""
                    print(f"{rev.revision}{_heads_label(rev.revision, current, heads)}  {title}")
    except (CommandError, SQLAlchemyError) as e:
        message = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        print(f"gaitscope: error: database {shown}: {message}", file=sys.stderr)
        return EXIT_ERROR
    finally:
        engine.dispose()
    return 0


def register(sub: Any) -> None:
    """Add ``gaitscope db`` to the command line's subparsers (``gaitscope.server.cli.build_parser``)."""
    p = sub.add_parser("db", help="database migrations: upgrade, downgrade, current, history")
    p.add_argument(
        "--database-url",
        help="SQLAlchemy URL (sqlite:///path, postgresql+psycopg://user:password@host/db); default "
        "GAITSCOPE_DATABASE_URL, else the SQLite file in the data folder",
    )
    commands = p.add_subparsers(dest="db_command", required=True, metavar="{upgrade,downgrade,current,history}")
    up = commands.add_parser("upgrade", help="upgrade to a revision (default: the newest, head)")
    up.add_argument("revision", nargs="?", default="head")
    down = commands.add_parser("downgrade", help="downgrade to a revision ('base': drop every table; '-1': one step)")
    down.add_argument("revision")
    commands.add_parser("current", help="the revision the database is at")
    commands.add_parser("history", help="every revision, newest first")
    p.set_defaults(func=cmd_db)
