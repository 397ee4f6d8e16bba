"""The audit trail's key: the secret that makes the chain's entries and the admin's checkpoints unforgeable.

The key lives outside the database, so that someone who can write the database (an SQL shell, a stolen backup
restored elsewhere, a bug) cannot re-make the entries' MACs after changing them (:mod:`gaitscope.sessions.audit.log`).
It is, in order:

1. ``GAITSCOPE_AUDIT_KEY`` (``Settings.audit_key``): at least :data:`MIN_CHARS` characters; what every server
   process sharing one PostgreSQL database must be given, the same on each;
2. the file ``audit.key`` in the data folder: 64 hex characters (32 random bytes) and a newline, created with
   permissions 0600 the first time a server or a ``gaitscope`` command that writes to the trail runs.

The key is the text (stripped of surrounding white space) as UTF-8 bytes, so that an auditor with the file can
re-check an entry with ``openssl dgst -sha256 -hmac "$(cat audit.key)"``. Losing the key loses the proof that
the entries were written by the server (the SHA-256 chain still checks); keep a copy where the database's
backups are not.
"""

from __future__ import annotations

import logging
import os
import secrets
import stat
from pathlib import Path
from typing import Any, Final

from gaitscope.sessions.errors import DataFormatError

__all__ = ["KEY_FILE", "MIN_CHARS", "audit_key", "key_file", "settings_key"]

log = logging.getLogger("gaitscope")

#: The key file's name in the data folder.
KEY_FILE: Final = "audit.key"
#: The shortest key accepted (128 bits as hex; the file holds 256).
MIN_CHARS: Final = 32


def key_file(data_dir: Path) -> Path:
    """Where the key file of a server with this data folder is."""
    return data_dir / KEY_FILE


def _checked(text: str, where: str) -> bytes:
    key = text.strip()
    if len(key) < MIN_CHARS:
        raise DataFormatError(f"the audit key must be at least {MIN_CHARS} characters, got {len(key)}", file=where)
    return key.encode("utf-8")


def _create(path: Path) -> None:
    """Write a new random key to ``path`` (0600), unless another process got there first: written whole to a
    file of this process's own, then linked into place (which fails if the key exists), so that a process
    starting at the same moment never reads a key half written."""
    path.parent.mkdir(parents=True, exist_ok=True)
    draft = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}")
    fd = os.open(draft, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    try:
        with os.fdopen(fd, "w", encoding="ascii") as f:
            f.write(secrets.token_hex(32) + "\n")
            f.flush()
            os.fsync(f.fileno())
        try:
            os.link(draft, path)
        except FileExistsError:
            return
    finally:
        draft.unlink(missing_ok=True)
    log.warning("created the audit trail's key %s (0600): keep a copy apart from the database's backups", path)


def audit_key(data_dir: Path, from_env: str | None, *, create: bool) -> bytes | None:
    """The audit key: ``from_env`` (``GAITSCOPE_AUDIT_KEY``) if given, else the data folder's key file, made
    first if ``create`` (else None when there is none).

    Raises:
        DataFormatError: the key is shorter than :data:`MIN_CHARS` characters, or the file cannot be read.
    """
    if from_env:
        return _checked(from_env, "GAITSCOPE_AUDIT_KEY")
    path = key_file(data_dir)
    if create and not path.exists():
        _create(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError) as e:
        raise DataFormatError(f"cannot read the audit key: {e}", file=str(path)) from None
    mode = stat.S_IMODE(path.stat().st_mode)
    if os.name == "posix" and mode & 0o077:
        log.warning("the audit key %s can be read by others (mode %o): chmod 600 it", path, mode)
    return _checked(text, str(path))


def settings_key(settings: Any, *, create: bool) -> bytes | None:
    """:func:`audit_key` for a :class:`gaitscope.server.settings.Settings` (its ``data_dir`` and ``audit_key``)."""
    secret = settings.audit_key
    return audit_key(settings.data_dir, None if secret is None else secret.get_secret_value(), create=create)
