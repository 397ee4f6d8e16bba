"""The replay CSV: the input of ``gaitscope replay INPUT.csv`` (and of a CSV upload) and the file it writes.

Input: a header row, then one row per sample. ``time_s`` is required and strictly increasing; any channel of
the channel table (:data:`~gaitscope.sessions.schema.CHANNELS`: the ``SensorFrame`` field names, units in the
name, the table's sign conventions) may follow, flags (``heel_strike``, ``foot_contact``, ...) as 0/1. Columns
that are not channels are listed back (:attr:`ReplayInput.ignored`), never read. Which estimators the file's
channels can feed is the registry's one rule (:func:`gaitscope.sessions.registry.feeds`); the reader checks
that the estimators it is asked for (by default the phase EKF of seed 000's replay) can run, and names what
they lack.

Every problem raises :class:`~gaitscope.sessions.errors.DataFormatError` naming the file, the line (the header
is line 1) and, where one is at fault, the column, e.g.
``file trial.csv, column 'time_s', row 7: time goes backwards (1.23 after 1.24)``.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import BinaryIO, Final

import numpy as np

from gaitscope.sessions import schema
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.files import atomic_output
from gaitscope.sessions.formats import _fastcsv

__all__ = [
    "DEFAULT_NEEDS",
    "FLAGS",
    "RAW_IMUS",
    "ReplayInput",
    "ReplayOutput",
    "check_feeds",
    "header_columns",
    "read_replay_csv",
    "write_replay_output",
]

_MIN_ROWS: Final = 2
#: Median sample periods accepted (s): 10 kHz to 1 Hz. Outside, the times are not in seconds, or
#: not a gait recording (and the heel filter's discretisation would be meaningless).
MIN_PERIOD_S = 1e-4
MAX_PERIOD_S = 1.0
#: The flag channels (0/1 in a file).
FLAGS: Final = frozenset(c for c, ch in schema.CHANNELS.items() if ch.unit == "bool")
#: What ``gaitscope replay`` runs by default needs its file to feed: seed 000's phase EKF.
DEFAULT_NEEDS: Final = ("phase_ekf",)


@dataclass(frozen=True)
class ReplayInput:
    """One replay trial, as read from the CSV.

    Attributes:
        time_s: (n,) float64 sample times in seconds, strictly increasing.
        signals: every channel column of the file but ``heel_strike``, in
            :data:`~gaitscope.sessions.schema.CHANNELS` order, each (n,) float64 (a flag as 0.0/1.0).
        heel_strike: (n,) bool, or None when the file has no ``heel_strike`` column.
    """

    time_s: np.ndarray
    signals: dict[str, np.ndarray]
    heel_strike: np.ndarray | None
    #: the header's columns that are not channels (not read), in file order; ``(column 3)`` for a blank name
    ignored: tuple[str, ...] = ()


def read_replay_csv(path: str | Path, estimators: Sequence[str] = DEFAULT_NEEDS) -> ReplayInput:
    """Read and validate a replay CSV whose channels feed ``estimators`` (registry names; empty: any file
    with a channel).

    A plain file (ASCII, unquoted, every cell a finite number, ...) is parsed by Arrow's C++ reader;
    any other, and any file with a problem, by a validating Python reader that finds the earliest bad
    cell. Both return the same arrays for a file both accept (``tests/.../test_replay_io_properties.py``).

    Raises:
        DataFormatError: empty file; missing ``time_s``; no channel column, or none that feeds one of
            ``estimators`` (the message names what each lacks); a repeated column name; a row with the
            wrong number of fields; an empty, non-numeric, NaN or infinite cell in a used column; a flag
            other than 0/1; fewer than 2 data rows; time not strictly increasing; a median time step outside
            [MIN_PERIOD_S, MAX_PERIOD_S]. When several cells are bad, the earliest line is reported.
    """
    name = str(path)
    fast = _read_plain(Path(path), name, estimators)
    return fast if fast is not None else _read_validated(Path(path), name, estimators)


def write_replay_output(path: str | Path, columns: Mapping[str, np.ndarray]) -> None:
    """Write the replay output CSV atomically, in one part (see :class:`ReplayOutput`).

    Args:
        path: the output CSV.
        columns: exactly the :data:`~gaitscope.sessions.schema.REPLAY_OUTPUT` names, each (n,) numeric;
            ``heel_strike`` bool or 0/1.

    Raises:
        ValueError: missing or extra column names, arrays that are not 1-D or differ in length, or a
            ``heel_strike`` value other than 0/1.
    """
    with ReplayOutput(path) as output:
        output.add(columns)


class ReplayOutput:
    """The replay output CSV, written atomically in consecutive parts; a context manager.

    Columns are written in the order of :data:`~gaitscope.sessions.schema.REPLAY_OUTPUT` under a header row:
    floats at full (shortest round-trip) precision as Python's ``repr`` writes them (NaN as ``nan``),
    ``heel_strike`` as 0/1. The file is written beside ``path``; leaving the ``with`` block normally
    moves it over ``path``, an exception deletes it and leaves ``path`` as it was.

    :meth:`add` checks a part and formats it on a background thread (in Arrow and compiled code,
    outside the GIL), so the caller computes the next part meanwhile; parts are written in order.
    """

    def __init__(self, path: str | Path):
        self._path = Path(path)
        self._stack: ExitStack | None = None
        self._file: BinaryIO | None = None
        self._pool: ThreadPoolExecutor | None = None
        self._pending: Future[memoryview] | None = None

    def __enter__(self) -> ReplayOutput:
        with ExitStack() as stack:
            tmp = stack.enter_context(atomic_output(self._path))
            with tmp.open("w", newline="") as header:  # the csv module quotes as pandas does (minimal)
                csv.writer(header, lineterminator="\n").writerow(schema.REPLAY_OUTPUT)
            self._file = stack.enter_context(tmp.open("ab"))
            self._pool = stack.enter_context(ThreadPoolExecutor(1, thread_name_prefix="replay-output"))
            self._stack = stack.pop_all()
        return self

    def add(self, columns: Mapping[str, np.ndarray]) -> None:
        """Append rows: ``columns`` as for :func:`write_replay_output`.

        Raises:
            ValueError: as :func:`write_replay_output`.
        """
        if self._pool is None:
            raise RuntimeError("ReplayOutput.add outside its with block")
        values = _output_values(columns)
        self._write_pending()
        self._pending = self._pool.submit(_fastcsv.format_rows, values)

    def _write_pending(self) -> None:
        if self._pending is not None and self._file is not None:
            rows, self._pending = self._pending.result(), None
            self._file.write(rows)

    def __exit__(self, kind: type[BaseException] | None, err: BaseException | None, tb: TracebackType | None) -> bool:
        stack, self._stack, self._pool = self._stack, None, None
        if stack is None:
            return False
        if kind is None:
            try:
                self._write_pending()
            except BaseException as failed:  # delete the partial file, then raise
                if not stack.__exit__(type(failed), failed, failed.__traceback__):
                    raise
                return False
        return bool(stack.__exit__(kind, err, tb))


# --- private helpers -----------------------------------------------------------------------------


def _read_validated(path: Path, name: str, estimators: Sequence[str]) -> ReplayInput:
    """The validating reader: Python's ``csv`` module, every cell checked, the earliest problem named."""
    header, rows, lines = _read_rows(path, name)
    where, used, ignored = header_columns(header, name)
    check_feeds(used, estimators, name)

    for row, line in zip(rows, lines, strict=True):
        if len(row) != len(header):
            raise DataFormatError(f"expected {len(header)} fields, found {len(row)}", file=name, row=line)
    if len(rows) < _MIN_ROWS:
        raise DataFormatError(f"need at least {_MIN_ROWS} data rows, found {len(rows)}", file=name)

    cells = {column: [row[where[column]] for row in rows] for column in used}

    values: dict[str, np.ndarray] = {}
    problems: list[tuple[int, int, str, str]] = []  # (row index, column position, column, message)
    for column in used:
        column_values, problem = parse_cells(cells[column], column in FLAGS)
        if problem is not None:
            problems.append((problem[0], where[column], column, problem[1]))
        values[column] = column_values
    if problems:
        i, _, column, message = min(problems)
        raise DataFormatError(message, file=name, column=column, row=lines[i])

    time_s = values[schema.REPLAY_TIME]
    step = np.diff(time_s)
    bad = step <= 0.0
    if bad.any():
        i = int(np.argmax(bad)) + 1
        text = cells[schema.REPLAY_TIME]
        how = "goes backwards" if step[i - 1] < 0.0 else "repeats"
        raise DataFormatError(
            f"time {how} ({text[i].strip()} after {text[i - 1].strip()})",
            file=name,
            column=schema.REPLAY_TIME,
            row=lines[i],
        )

    period = float(np.median(step))
    if not _period_ok(period):
        raise DataFormatError(
            f"the median time step is {period:.3g} s; gaitscope takes sample periods from {MIN_PERIOD_S:g} s "
            f"to {MAX_PERIOD_S:g} s (10 kHz to 1 Hz): is the column in seconds?",
            file=name,
            column=schema.REPLAY_TIME,
        )

    return _replay_input(values, ignored)


def _output_values(columns: Mapping[str, np.ndarray]) -> list[np.ndarray]:
    """The output columns in :data:`~gaitscope.sessions.schema.REPLAY_OUTPUT` order, checked; floats as float64,
    ``heel_strike`` as int64."""
    missing = [c for c in schema.REPLAY_OUTPUT if c not in columns]
    extra = [c for c in columns if c not in schema.REPLAY_OUTPUT]
    if missing or extra:
        raise ValueError(f"replay output columns: missing {missing}, unexpected {extra}")
    arrays = {c: np.asarray(columns[c]) for c in schema.REPLAY_OUTPUT}
    shapes = {c: a.shape for c, a in arrays.items()}
    if any(a.ndim != 1 for a in arrays.values()) or len(set(shapes.values())) != 1:
        raise ValueError(f"replay output columns must be 1-D and of equal length, got shapes {shapes}")
    values: list[np.ndarray] = []
    for column, array in arrays.items():
        if column == schema.REPLAY_HEEL_STRIKE:
            if not np.isin(array, (0, 1)).all():
                raise ValueError(f"replay output column {column!r} must hold only 0/1")
            values.append(array.astype(np.int64))
        else:
            values.append(array.astype(np.float64))
    return values


#: Raw IMU channels a file may carry instead of (or beside) angles, by leg IMU: the six of one IMU
#: (``imu_{seg}_gyro_{x,y,z}_dps``, ``imu_{seg}_accel_{x,y,z}_m_s2``); the stack's IMU front end derives
#: that segment's angle from them (``docs/api.md``, "Raw IMU input").
_IMU_KINDS: Final = (("gyro", "dps"), ("accel", "m_s2"))
RAW_IMUS: Final = {
    seg: tuple(f"imu_{seg}_{kind}_{axis}_{unit}" for kind, unit in _IMU_KINDS for axis in "xyz")
    for seg in ("foot", "shank", "thigh", "foot_contra", "shank_contra", "thigh_contra")
}


def header_columns(header: list[str], name: str) -> tuple[dict[str, int], list[str], list[str]]:
    """Position of each channel column, the used ones (``time_s``, the channels in
    :data:`~gaitscope.sessions.schema.CHANNELS` order, ``heel_strike`` last) and the ignored ones (the
    header's other names, in file order).

    Raises:
        DataFormatError: no ``time_s``, a name twice, or no channel column at all.
    """
    where: dict[str, int] = {}
    ignored: list[str] = []
    for j, column in enumerate(header):
        if column != schema.REPLAY_TIME and column not in schema.CHANNELS:
            ignored.append(column or f"(column {j + 1})")
            continue
        if column in where:
            raise DataFormatError("column name appears twice", file=name, column=column, row=1)
        where[column] = j
    if schema.REPLAY_TIME not in where:
        raise DataFormatError("missing required column", file=name, column=schema.REPLAY_TIME, row=1)
    channels = [c for c in schema.CHANNELS if c in where and c != schema.REPLAY_HEEL_STRIKE]
    if not channels and schema.REPLAY_HEEL_STRIKE not in where:
        near = [c for c in ignored if c.lower().replace(" ", "_") in schema.CHANNELS]
        hint = f" ({', '.join(near)}: names are lower case, with underscores)" if near else ""
        raise DataFormatError(
            f"no sensor channel column{hint}; the columns gaitscope reads are named as its channels, units in the "
            "name (foot_angle_deg, shank_angle_deg, thigh_angle_deg, knee_angle_deg, imu_shank_gyro_z_dps, ...: "
            "docs/api.md, Channels)",
            file=name,
            row=1,
        )
    used = [schema.REPLAY_TIME, *channels]
    if schema.REPLAY_HEEL_STRIKE in where:
        used.append(schema.REPLAY_HEEL_STRIKE)
    return where, used, ignored


def check_feeds(channels: Sequence[str], estimators: Sequence[str], name: str) -> None:
    """Refuse a file whose ``channels`` feed none of ``estimators`` (the registry's rule,
    :meth:`~gaitscope.sessions.registry.Declared.lacking`), naming what each lacks; nothing when
    ``estimators`` is empty or one of them can run."""
    if not estimators:
        return
    from gaitscope.sessions.registry import feeds  # the estimators' registry: only when a file is read

    fed = feeds([c for c in channels if c != schema.REPLAY_TIME], among=estimators)
    lacking = {e: fed[e].missing for e in estimators if e in fed}
    if not lacking or any(not missing for missing in lacking.values()):
        return
    what = "; ".join(f"{e} needs {', '.join(missing)}" for e, missing in lacking.items())
    raws = [seg for seg, imu in RAW_IMUS.items() if set(imu) <= set(channels)]
    hint = ""
    if raws:
        fronts = ",".join(f"imu_{seg}" for seg in raws)
        hint = (
            f". The file has raw IMU columns ({', '.join(raws)}): the IMU front ends derive the angles from them "
            f"(gaitscope replay --estimators {fronts},{','.join(estimators)}, or upload it in the dashboard)"
        )
    raise DataFormatError(f"the file's channels cannot feed the estimators asked for: {what}{hint}", file=name, row=1)


def _period_ok(period: float) -> bool:
    return MIN_PERIOD_S <= period <= MAX_PERIOD_S


def _replay_input(values: dict[str, np.ndarray], ignored: Sequence[str] = ()) -> ReplayInput:
    heel_strike = values.get(schema.REPLAY_HEEL_STRIKE)
    return ReplayInput(
        time_s=values[schema.REPLAY_TIME],
        signals={c: values[c] for c in schema.CHANNELS if c in values and c != schema.REPLAY_HEEL_STRIKE},
        heel_strike=None if heel_strike is None else heel_strike == 1.0,
        ignored=tuple(ignored),
    )


def _read_plain(path: Path, name: str, estimators: Sequence[str]) -> ReplayInput | None:
    """The fast path of :func:`read_replay_csv`: the input of a plain, valid file, else None (then the
    validating reader runs and names the problem)."""
    try:
        raw = path.read_bytes()
    except OSError:
        return None  # the validating reader raises the same error
    split = _fastcsv.simple_body(raw)
    if split is None:
        return None
    header_line, body = split
    header = [h.strip() for h in header_line.split(",")]
    if not any(header):
        return None
    try:
        where, used, ignored = header_columns(header, name)
        check_feeds(used, estimators, name)
    except DataFormatError:
        return None
    values = _fastcsv.read_numbers(body, len(header), {c: where[c] for c in used})
    if values is None or values[schema.REPLAY_TIME].size < _MIN_ROWS:
        return None
    for flag in FLAGS.intersection(values):
        if not ((values[flag] == 0.0) | (values[flag] == 1.0)).all():
            return None
    step = np.diff(values[schema.REPLAY_TIME])
    if not (step > 0.0).all() or not _period_ok(float(np.median(step))):
        return None
    return _replay_input(values, ignored)


def _read_rows(path: Path, name: str) -> tuple[list[str], list[list[str]], list[int]]:
    """Header (names stripped), data rows and the file line of each row; blank lines are skipped."""
    rows: list[list[str]] = []
    lines: list[int] = []
    try:
        with path.open(newline="", encoding="utf-8-sig") as file:
            reader = csv.reader(file)
            header = next(reader, None)
            if header is None:
                raise DataFormatError("the file is empty", file=name)
            for row in reader:
                if row:
                    rows.append(row)
                    lines.append(reader.line_num)
    except (UnicodeDecodeError, csv.Error) as err:
        raise DataFormatError(f"not a readable CSV file ({err})", file=name) from None
    header = [h.strip() for h in header]
    if not any(header):
        raise DataFormatError("the header row is empty", file=name, row=1)
    return header, rows, lines


def parse_cells(text: list[str], zero_one: bool = False) -> tuple[np.ndarray, tuple[int, str] | None]:
    """Cells as float64, and the first bad one (index, message) if any: empty, not a number, NaN,
    infinite, or (``zero_one``) other than 0/1. Shared with the streaming upload reader."""
    try:
        values = np.array(text, dtype=np.float64)
    except ValueError:
        values = np.full(len(text), np.nan)
        for i, cell in enumerate(text):  # slow path, only for cells that hold a bad one
            if not cell.strip():
                return values, (i, "empty cell")
            try:
                values[i] = float(cell)
            except ValueError:
                return values, (i, f"not a number: {cell.strip()!r}")
    bad = ~np.isfinite(values)
    if bad.any():
        i = int(np.argmax(bad))
        what = "NaN" if math.isnan(values[i]) else "infinite value"
        return values, (i, f"{what} ({text[i].strip()}) is not allowed")
    if zero_one and ((values != 0.0) & (values != 1.0)).any():
        i = int(np.argmax((values != 0.0) & (values != 1.0)))
        return values, (i, f"must be 0 or 1, got {text[i].strip()!r}")
    return values, None
