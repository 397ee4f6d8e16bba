"""``gaitscope user``: accounts from the command line (the first admin, a reset, an unlock).

``gaitscope user add --role admin NAME`` asks for the password twice on a terminal, or reads one line from
standard input with ``--password-stdin`` (scripts, containers). The database is the server's
(``GAITSCOPE_DATABASE_URL``, or the SQLite file in ``--data-dir``). What the command does is written to the
audit trail as done by ``cli`` (the person at the server's console).
"""

from __future__ import annotations

import argparse
import getpass
import sys
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from gaitscope.sessions import schema
from gaitscope.sessions.errors import DataFormatError

__all__ = ["register"]


def _password(a: argparse.Namespace) -> str:
    if a.password_stdin:
        line = sys.stdin.readline()
        return line.rstrip("\r\n")
    if not sys.stdin.isatty():
        raise DataFormatError("no terminal to ask the password on: pass --password-stdin and pipe it", file="user")
    first = getpass.getpass("password: ")
    if getpass.getpass("again: ") != first:
        raise DataFormatError("the two passwords differ", file="user")
    return first


def _open(a: argparse.Namespace) -> Any:
    from gaitscope.server.settings import Settings
    from gaitscope.sessions.accounts import Accounts
    from gaitscope.sessions.store import Store

    settings = Settings(**({"data_dir": a.data_dir} if a.data_dir is not None else {}))
    store = Store(settings.database_url)
    return store, Accounts(store)


def _errors(e: ValidationError) -> str:
    return "; ".join(f"{'.'.join(str(x) for x in err['loc'])}: {err['msg']}" for err in e.errors())


def _audit(a: argparse.Namespace, store: Any, action: str, target: str, before: Any = None, after: Any = None) -> None:
    """Write the command's change to the audit trail, before it is made (MAC'd with the server's audit key)."""
    from gaitscope.server.settings import Settings
    from gaitscope.sessions.audit import AuditLog
    from gaitscope.sessions.audit.key import settings_key

    settings = Settings(**({"data_dir": a.data_dir} if a.data_dir is not None else {}))
    key = settings_key(settings, create=True)
    assert key is not None  # created if missing
    log = AuditLog(store, key)
    try:
        log.ensure_keyed(user="cli")  # refused if the server writes with another key
    except ValueError as e:
        raise DataFormatError(str(e), file="audit") from None
    log.record(user="cli", role="admin", action=action, target=target, before=before, after=after)


def cmd_user(a: argparse.Namespace) -> int:
    from gaitscope.sessions.store import Conflict, NotFound

    store, accounts = _open(a)
    try:
        if a.user_command == "list":
            for u in accounts.list_users():
                failed = f"{u.failed_logins} failed logins" if u.failed_logins else "ok"
                held = f"{failed}, failing addresses wait until {u.locked_until_utc}" if u.locked_until_utc else failed
                state = "disabled" if u.disabled else held
                print(f"{u.name:<24} {u.role:<13} {state:<30} last login {u.last_login_utc or 'never'}")
            return 0
        try:
            if a.user_command == "add":
                body = schema.UserCreate(name=a.name, role=a.role, password=_password(a))
                _audit(a, store, "user.add", a.name, after={"role": a.role})
                user = accounts.add_user(body, by="cli")
                print(f"added {user.role} {user.name!r}")
            elif a.user_command == "reset-password":
                change = schema.UserChange(password=_password(a), unlock=True)
                _audit(a, store, "user.reset_password", a.name)
                accounts.change_user(a.name, change, by="cli")
                print(f"new password set for {a.name!r}; their logins ended")
            elif a.user_command == "unlock":
                _audit(a, store, "user.unlock", a.name)
                accounts.change_user(a.name, schema.UserChange(unlock=True), by="cli")
                print(f"{a.name!r} unlocked")
        except ValidationError as e:
            raise DataFormatError(_errors(e), file="user") from None
        except (Conflict, NotFound) as e:
            raise DataFormatError(str(e), file="user") from None
        return 0
    finally:
        store.close()


def register(sub: Any) -> None:
    """Add ``gaitscope user`` to the command line's subcommands."""
    p = sub.add_parser("user", help="accounts: add a user (the first admin), list, reset a password, unlock")
    p.add_argument("--data-dir", type=Path, help="the server's data folder (default GAITSCOPE_DATA_DIR)")
    users = p.add_subparsers(dest="user_command", required=True)
    q = users.add_parser("add", help="add a user")
    q.add_argument("name", help="lower case, 2-32 characters: letters, digits, _ . -")
    q.add_argument("--role", required=True, choices=schema.ROLES)
    q.add_argument("--password-stdin", action="store_true", help="read the password from standard input")
    users.add_parser("list", help="list the users")
    q = users.add_parser("reset-password", help="set a new password (and unlock)")
    q.add_argument("name")
    q.add_argument("--password-stdin", action="store_true")
    q = users.add_parser(
        "unlock", help="forget the account's failed logins (a running server forgets its count at the next attempt)"
    )
    q.add_argument("name")
    p.set_defaults(func=cmd_user)
