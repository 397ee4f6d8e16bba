"""Errors raised when an input file or value is malformed, or when the disk is full."""

from __future__ import annotations

import errno
import sqlite3
from typing import Final


class DataFormatError(ValueError):
    """An input table or file is malformed.

    The message always names the file and, where they apply, the column and the row, so a user can
    find the problem without reading code. ``row`` is the 1-based line number in the file for text
    formats (the header is line 1) and the 1-based data row for binary formats.
    """

    def __init__(self, message: str, *, file: str, column: str | None = None, row: int | None = None):
        where = [f"file {file}"]
        if column is not None:
            where.append(f"column {column!r}")
        if row is not None:
            where.append(f"row {row}")
        super().__init__(f"{', '.join(where)}: {message}")
        self.file = file
        self.column = column
        self.row = row


#: What a full disk says: ``ENOSPC`` (no space), ``EDQUOT`` (over quota).
_DISK_FULL_ERRNOS: Final = (errno.ENOSPC, errno.EDQUOT)
#: PostgreSQL's SQLSTATE for "disk full" (class 53, insufficient resources).
_PG_DISK_FULL: Final = "53100"
#: What to do about it, ending every message of :class:`DiskFull`.
FREE_SPACE_HINT: Final = "free space on the server's data disk (old recordings, exports) and try again"


class DiskFull(OSError):
    """A write failed, or was refused beforehand, because the server's disk is (almost) full.

    The one error every full-disk failure becomes, whichever layer met it: a recording's file
    (``OSError`` ``ENOSPC``), SQLite ("database or disk is full"), PostgreSQL (SQLSTATE 53100), or the
    disk guard refusing to start a recording. The server answers it with 507 Insufficient Storage;
    ``str()`` says what was not done and what to do, without server paths.
    """

    def __init__(self, message: str):
        super().__init__(errno.ENOSPC, message)

    def __str__(self) -> str:
        return str(self.strerror)


def is_disk_full(exc: BaseException | None) -> bool:
    """Whether ``exc``, or an exception it was raised from or wraps, says the disk is full.

    Looks through ``__cause__``, ``__context__`` and a database driver's wrapped error (SQLAlchemy's
    ``orig``), so an error re-raised by a layer above still counts.
    """
    seen: set[int] = set()
    stack = [exc]
    while stack:
        e = stack.pop()
        if e is None or id(e) in seen:
            continue
        seen.add(id(e))
        if isinstance(e, DiskFull) or (isinstance(e, OSError) and e.errno in _DISK_FULL_ERRNOS):
            return True
        if isinstance(e, sqlite3.OperationalError) and "database or disk is full" in str(e):
            return True  # SQLITE_FULL
        if getattr(e, "sqlstate", None) == _PG_DISK_FULL:  # psycopg's DiskFull
            return True
        orig = getattr(e, "orig", None)
        stack += [e.__cause__, e.__context__, orig if isinstance(orig, BaseException) else None]
    return False


def disk_full(what: str, exc: BaseException | None = None) -> DiskFull:
    """The :class:`DiskFull` for ``what`` was not done (a sentence's start: "the annotation was not saved")."""
    error = DiskFull(f"{what}: the server's disk is full; {FREE_SPACE_HINT}")
    if exc is not None:
        error.__cause__ = exc
    return error
