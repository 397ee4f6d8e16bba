"""The audit trail as CSV: RFC 4180 (the ``csv`` module, CRLF line ends, a header row), safe to open in a
spreadsheet.

Formula injection (OWASP, "CSV Injection"): a cell starting with ``=``, ``+``, ``-``, ``@``, a tab or a carriage
return is prefixed with a single quote, so that a spreadsheet shows it as text instead of running it. The audit
trail holds text that callers chose (a refused request's path, an error's detail), so every cell is treated so.
The CSV is for reading; the chain is verified on the database (``gaitscope audit verify``), not on the CSV.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable, Iterator
from typing import Final

from gaitscope.sessions import schema

__all__ = ["COLUMNS", "csv_chunks", "safe_cell"]

#: The CSV's columns, in order (the fields of :class:`gaitscope.sessions.schema.AuditEntry` but the row key).
COLUMNS: Final = ("seq", "time_utc", "user", "role", "action", "target", "before", "after", "outcome", "detail",
                  "prev_hash", "hash", "mac")  # fmt: skip
_FORMULA_START: Final = ("=", "+", "-", "@", "\t", "\r")
#: Rows per yielded piece of text.
_ROWS_PER_CHUNK: Final = 500


def safe_cell(value: object) -> str:
    """``value`` as a CSV cell a spreadsheet will not run as a formula (None: empty)."""
    text = "" if value is None else str(value)
    return "'" + text if text.startswith(_FORMULA_START) else text


def csv_chunks(entries: Iterable[schema.AuditEntry]) -> Iterator[str]:
    """The CSV text of ``entries``, header first, in pieces of a few hundred rows (for a streamed answer)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer)  # the "excel" dialect: RFC 4180's quoting and CRLF line ends
    writer.writerow(COLUMNS)
    rows = 0
    for entry in entries:
        writer.writerow([safe_cell(getattr(entry, c)) for c in COLUMNS])
        rows += 1
        if rows % _ROWS_PER_CHUNK == 0:
            yield buffer.getvalue()
            buffer.seek(0)
            buffer.truncate()
    yield buffer.getvalue()
