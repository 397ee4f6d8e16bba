"""Fast paths for numeric CSV tables (the replay CSV). Private: use :mod:`gaitscope.sessions.formats.replay_io`.

Reading: Arrow's multi-threaded C++ parser, but only for files that every CSV reader splits the same
way (:func:`simple_body`) and only when every cell parses (:func:`read_numbers`); otherwise the caller
takes its validating Python path, which finds and names the bad cell. Arrow parses decimals with
correct rounding (``fast_float``), so the values equal Python's ``float(cell)`` bit for bit.

Writing: :func:`format_rows` writes each float exactly as Python's ``repr`` does (what the pandas
writer it replaces wrote: ``0.0``, ``0.1``, ``1e-05``, ``1e+16``, ``nan``, ``-inf``). Arrow finds each
float's shortest round-trip digits (C++, as Python's own ``repr`` does, and the same digits: tested),
and a compiled pass lays them out in ``repr``'s format, rows and commas included.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pa_csv
from numba import njit
from numpy.typing import NDArray

_BOM = b"\xef\xbb\xbf"


def simple_body(raw: bytes) -> tuple[str, bytes] | None:
    """``(header line, the rest)`` of a CSV file whose rows any reader splits alike, else None.

    Simple means: ASCII (after an optional UTF-8 byte-order mark), no quote character, no NUL, every
    CR followed by LF, and a line break after the header. Then a row is a line, a cell is what lies
    between commas, and Python's ``csv`` module and Arrow agree on both.
    """
    if raw.startswith(_BOM):
        raw = raw[len(_BOM) :]
    if not raw.isascii() or b'"' in raw or b"\0" in raw or raw.count(b"\r") != raw.count(b"\r\n"):
        return None
    end = raw.find(b"\n")
    if end < 0:
        return None
    return raw[:end].rstrip(b"\r").decode("ascii"), raw[end + 1 :]


def read_numbers(body: bytes, n_fields: int, columns: dict[str, int]) -> dict[str, NDArray[np.float64]] | None:
    """The ``columns`` (name: field position) of a simple CSV body of ``n_fields`` fields per row, as
    float64; None if any row has another number of fields or any of these cells is not a finite
    number. Blank lines are skipped; the other fields are split but not read."""
    names = [f"f{j}" for j in range(n_fields)]
    try:
        table = pa_csv.read_csv(
            pa.py_buffer(body),
            read_options=pa_csv.ReadOptions(column_names=names),
            parse_options=pa_csv.ParseOptions(quote_char=False, ignore_empty_lines=True),
            convert_options=pa_csv.ConvertOptions(
                column_types={names[j]: pa.float64() for j in columns.values()},
                include_columns=[names[j] for j in columns.values()],
            ),
        )
    except pa.ArrowException:  # a row of another length, a cell that is not a number, ...
        return None
    out: dict[str, NDArray[np.float64]] = {}
    for column, j in columns.items():
        values = table.column(names[j])
        if values.null_count:  # empty, "nan", "NA", ...
            return None
        # the float64 chunks' data buffers, copied into one writable array: Arrow's own to_numpy imports
        # pandas (a third of a second of a replay's start-up); no nulls here, so the buffers are the values
        parts = [np.frombuffer(c.buffers()[1], np.float64, len(c), c.offset * 8) for c in values.chunks]
        array = np.concatenate(parts) if parts else np.empty(0)
        if not np.isfinite(array).all():
            return None
        out[column] = array
    return out


def format_rows(columns: Sequence[NDArray[np.generic]]) -> memoryview:
    """CSV rows (``\\n``-terminated) of equal-length 1-D columns: floats as Python's ``repr``, integer
    and boolean columns as integers."""
    n = len(columns[0]) if columns else 0
    offsets = np.empty((len(columns), n + 1), dtype=np.int64)  # cell (c, i) is data[offsets[c, i]:offsets[c, i + 1]]
    chunks = []
    verbatim = np.empty(len(columns), dtype=np.bool_)
    base = 0
    for c, column in enumerate(columns):
        verbatim[c] = not np.issubdtype(column.dtype, np.floating)
        values = np.ascontiguousarray(column, dtype=np.int64 if verbatim[c] else np.float64)
        # an Arrow array over the values' buffer (pa.array(values) would import pandas: a third of a
        # second of a replay's start-up), cast to text by Arrow's shortest round-trip formatting
        arrow = pa.Array.from_buffers(pa.int64() if verbatim[c] else pa.float64(), n, [None, pa.py_buffer(values)])
        text = pc.cast(arrow, pa.string())
        _, off_buf, data_buf = text.buffers()
        off = np.frombuffer(off_buf, dtype=np.int32, count=n + 1, offset=4 * text.offset).astype(np.int64)
        data = np.frombuffer(data_buf, dtype=np.uint8) if data_buf is not None else np.empty(0, dtype=np.uint8)
        chunks.append(data[off[0] : off[-1]])
        offsets[c] = off - off[0] + base
        base += int(off[-1] - off[0])
    data = np.concatenate(chunks) if chunks else np.empty(0, dtype=np.uint8)
    buf = np.empty(n * (len(columns) * (_MAX_REPR + 1) + 1), dtype=np.uint8)
    return buf[: _layout(offsets, data, verbatim, buf)].data


#: Longest ``repr`` of a float64: ``-1.2345678901234567e-308``.
_MAX_REPR = 24
_ZERO, _DOT, _MINUS, _PLUS, _E, _COMMA, _NL = (ord(c) for c in "0.-+e,\n")


@njit(cache=True, nogil=True)
def _put(buf: NDArray[np.uint8], k: int, text: str) -> int:
    for ch in text:
        buf[k] = ord(ch)
        k += 1
    return k


@njit(cache=True, nogil=True)
def _repr_float(s: NDArray[np.uint8], a: int, n: int, buf: NDArray[np.uint8], k: int, digits: NDArray[np.uint8]) -> int:
    """Write the float that Arrow wrote as ``s[a:n]`` the way Python's ``repr`` writes it; return the end.

    Arrow writes shortest digits as ``[-]I[.F][e[+-]X]`` (``0``, ``100``, ``0.00001``, ``1e+16``, ``1e-7``)
    and ``nan``, ``inf``, ``-inf``; ``repr`` puts the same digits ``d1 d2 ...`` with the decimal point
    after ``decpt`` of them: fixed notation for ``-4 < decpt <= 16`` (``0.0001``, ``100.0``), else
    ``d1.d2...e[+-]XX`` with at least two exponent digits.
    """
    neg = n > a and s[a] == _MINUS
    start = a + 1 if neg else a
    # Most cells read the same both ways: copy, and keep the copy when the text has a decimal point, no
    # exponent and no "0.0000" start (below 1e-4 repr switches to an exponent); nan and inf too
    k0 = k
    dot = exponent = special = False
    for j in range(a, n):
        c = s[j]
        buf[k] = c
        k += 1
        if c == _DOT:
            dot = True
        elif c == _E:
            exponent = True
        elif c == ord("n") or c == ord("i"):
            special = True
    if special:
        return k
    if dot and not exponent:
        tiny = n - start > 5 and s[start] == _ZERO
        for j in range(start + 2, min(start + 6, n)):
            tiny = tiny and s[j] == _ZERO
        if not tiny:
            return k
    k = k0
    # mantissa digits without leading and trailing zeros (into ``digits``), decimal exponent
    nd = 0
    decpt = 0
    seen_dot = False
    leading = True
    exp10 = 0
    i = start
    while i < n:
        c = s[i]
        if c == _DOT:
            seen_dot = True
        elif c == _E:
            sign = 1
            i += 1
            if s[i] == _MINUS:
                sign = -1
                i += 1
            elif s[i] == _PLUS:
                i += 1
            e = 0
            while i < n:
                e = 10 * e + (s[i] - _ZERO)
                i += 1
            exp10 = sign * e
            break
        else:
            if leading and c == _ZERO:
                if seen_dot:
                    decpt -= 1
            else:
                leading = False
                digits[nd] = c
                nd += 1
                if not seen_dot:
                    decpt += 1
        i += 1
    while nd > 0 and digits[nd - 1] == _ZERO:
        nd -= 1
    if neg:
        buf[k] = _MINUS
        k += 1
    if nd == 0:  # a zero
        return _put(buf, k, "0.0")
    decpt += exp10
    if -4 < decpt <= 16:
        if decpt <= 0:
            buf[k], buf[k + 1] = _ZERO, _DOT
            k += 2
            for _ in range(-decpt):
                buf[k] = _ZERO
                k += 1
            for j in range(nd):
                buf[k] = digits[j]
                k += 1
        elif decpt >= nd:
            for j in range(nd):
                buf[k] = digits[j]
                k += 1
            for _ in range(decpt - nd):
                buf[k] = _ZERO
                k += 1
            buf[k], buf[k + 1] = _DOT, _ZERO
            k += 2
        else:
            for j in range(nd):
                if j == decpt:
                    buf[k] = _DOT
                    k += 1
                buf[k] = digits[j]
                k += 1
        return k
    buf[k] = digits[0]
    k += 1
    if nd > 1:
        buf[k] = _DOT
        k += 1
        for j in range(1, nd):
            buf[k] = digits[j]
            k += 1
    e = decpt - 1
    buf[k] = _E
    buf[k + 1] = _MINUS if e < 0 else _PLUS
    k += 2
    e = abs(e)
    if e >= 100:
        buf[k] = _ZERO + e // 100
        k += 1
    buf[k] = _ZERO + (e // 10) % 10
    buf[k + 1] = _ZERO + e % 10
    return k + 2


@njit(cache=True, nogil=True)
def _layout(
    offsets: NDArray[np.int64], data: NDArray[np.uint8], verbatim: NDArray[np.bool_], buf: NDArray[np.uint8]
) -> int:
    """Rows of comma-separated cells into ``buf``; cell (c, i) is ``data[offsets[c, i]:offsets[c, i + 1]]``."""
    n_cols, n = offsets.shape[0], offsets.shape[1] - 1
    k = 0
    digits = np.empty(_MAX_REPR, dtype=np.uint8)
    for i in range(n):
        for c in range(n_cols):
            if c:
                buf[k] = _COMMA
                k += 1
            a, b = offsets[c, i], offsets[c, i + 1]
            if verbatim[c]:
                for j in range(a, b):
                    buf[k] = data[j]
                    k += 1
            else:
                k = _repr_float(data, a, b, buf, k, digits)
        buf[k] = _NL
        k += 1
    return k
