"""Errors raised when an input file or value is malformed."""

from __future__ import annotations


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
