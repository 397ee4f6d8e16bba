"""Reading, checking and crash recovery of trial MCAP files (the writer is :mod:`gaitscope.sessions.formats.recording`).

A trial file holds the JSON channels of :data:`~gaitscope.sessions.schema.MCAP_CHANNELS`; every message's log
time (integer nanoseconds since the Unix epoch) is the session's start wall clock plus the sample
time ``t`` (s). The readers need a finished file, i.e. one with a summary section indexing its chunks
(Foxglove needs it too); :func:`recover` turns a file left unfinished by a crash into one, losing at
most the chunk that was being filled.

Every problem with a file raises :class:`~gaitscope.sessions.errors.DataFormatError` naming the file.
"""

from __future__ import annotations

import errno
import io
import itertools
import json
import os
import struct
import zlib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, Final

import numpy as np
from mcap.data_stream import ReadDataStream, RecordBuilder
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import McapReader, make_reader
from mcap.records import (
    Attachment,
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Message,
    MessageIndex,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.summary import Summary
from mcap.writer import Writer

from gaitscope.sessions import schema
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.files import atomic_output

__all__ = [
    "CHUNK_SIZE",
    "SERIES_COLUMNS",
    "RecoveryResult",
    "SeriesBuilder",
    "check_mcap",
    "count_messages",
    "decimate",
    "iter_sensor_frames",
    "metadata_of",
    "read_estimator_series",
    "read_events",
    "read_messages",
    "read_sensor_frames",
    "read_series",
    "recover",
    "recover_in_place",
    "series_window",
]

#: Largest uncompressed chunk (bytes). One 200 Hz sample (/sensor + /gait_state + /torque) takes
#: about 1.1 kB, so this is about a second of data. The recorder closes chunks earlier, by time
#: (:data:`~gaitscope.sessions.formats.recording.FLUSH_INTERVAL_S`), so this cap matters only for faster sources.
#: Half-second chunks compress as well as one-second ones: about 29 KiB/s of file at 200 Hz.
CHUNK_SIZE: Final = 224 * 1024

_MAGIC: Final = b"\x89MCAP0\r\n"
_FOOTER_SIZE: Final = 1 + 8 + 8 + 8 + 4  # opcode, length, summary_start, summary_offset_start, crc
_NOT_FINISHED: Final = "the file was not finished (no index); gaitscope can recover it"
#: Errors the mcap library (and the decompressors below it) raise on damaged bytes. Decompressor
#: errors are matched by module so that we do not import zstandard / lz4 ourselves.
_DAMAGE: Final = (McapError, ValueError, struct.error, EOFError, UnicodeDecodeError)

#: /gait_state columns in the order :func:`read_series` returns them: ``t`` first.
SERIES_COLUMNS: Final = ("t", *(f for f in schema.GaitState.model_fields if f != "t"))
#: Columns decimated by min/max per bucket; the others take the value at the bucket's ends.
_PLOT_COLUMNS: Final = tuple(
    f for f, info in schema.GaitState.model_fields.items() if f != "t" and info.annotation in (float, float | None)
)
#: Flags kept True on the decimated row nearest to their first occurrence in the bucket.
_FLAG_COLUMNS: Final = ("heel_strike", "backup_reset", "fault")


def _is_damage(exc: BaseException) -> bool:
    module = type(exc).__module__ or ""
    return isinstance(exc, _DAMAGE) or module.startswith(("zstandard", "lz4", "_lz4"))


def _finished(f: IO[bytes], name: str) -> tuple[McapReader, Summary] | None:
    """A seeking reader and the summary of a finished (indexed) MCAP file; None if unfinished.

    Raises:
        DataFormatError: empty, or not MCAP (bad magic).
    """
    head = f.read(len(_MAGIC))
    if head != _MAGIC:
        raise DataFormatError("not an MCAP file (bad magic)" if head else "empty file", file=name)
    size = f.seek(0, io.SEEK_END)
    f.seek(size - len(_MAGIC))
    if size < 2 * len(_MAGIC) + _FOOTER_SIZE or f.read(len(_MAGIC)) != _MAGIC:
        return None
    f.seek(0)
    reader = make_reader(f, validate_crcs=True)  # a damaged chunk raises instead of misreading
    try:
        summary = reader.get_summary()
    except Exception as exc:
        if not _is_damage(exc):
            raise
        return None
    if summary is None:
        return None
    stats = summary.statistics
    if stats is not None and stats.message_count > 0 and not summary.chunk_indexes:
        return None  # messages but no chunk index: Foxglove cannot seek in it
    return reader, summary


def _indexed_summary(f: IO[bytes], name: str) -> tuple[McapReader, Summary]:
    """As :func:`_finished`, raising DataFormatError when the file is not finished."""
    finished = _finished(f, name)
    if finished is None:
        raise DataFormatError(_NOT_FINISHED, file=name)
    return finished


def check_mcap(path: str | Path, *, name: str | None = None) -> None:
    """Accept a finished (indexed) MCAP file with a JSON ``/sensor`` channel.

    ``name`` is the file named in errors (e.g. an upload's own name rather than its temporary path).

    Raises:
        DataFormatError: not MCAP (bad magic); not finished (no footer or no summary index), which
            :func:`recover` can repair; no ``/sensor`` channel, or one not JSON-encoded.
    """
    name = str(path) if name is None else name
    with open(path, "rb") as f:
        _, summary = _indexed_summary(f, name)
    sensor = [c for c in summary.channels.values() if c.topic == "/sensor"]
    if not sensor:
        raise DataFormatError("no /sensor channel (gaitscope needs the raw sensor frames)", file=name)
    if any(c.message_encoding != "json" for c in sensor):
        raise DataFormatError("the /sensor channel is not JSON-encoded", file=name)


def _iter_raw(
    path: str | Path,
    topics: Sequence[str] | None,
    starting_at: int | None = None,
    ending_at: int | None = None,
    file_order: bool = False,
) -> Iterator[tuple[Channel, Message]]:
    """Messages of a finished file in log-time order; bounds are integer ns, both inclusive.

    ``file_order`` reads the matching chunks one at a time in file order instead of through the
    reader's merge of overlapping chunks (a heap over every message, most of the cost of a long read;
    the reader's own unordered mode reads every chunk before it yields a message, so it is not used).
    gaitscope writes its recordings in time order, so for them file order is log-time order.
    """
    name = str(path)
    with open(path, "rb") as f:
        reader, summary = _indexed_summary(f, name)
        try:
            if file_order:
                yield from _iter_chunks(f, summary, topics, starting_at, ending_at)
                return
            for _, channel, message in reader.iter_messages(
                topics=list(topics) if topics is not None else None,
                starting_at=starting_at,
                ending_at=ending_at,
            ):
                yield channel, message
        except Exception as exc:
            if not _is_damage(exc) or isinstance(exc, DataFormatError):
                raise
            raise DataFormatError(f"damaged MCAP data ({exc})", file=name) from exc


def _iter_chunks(
    f: IO[bytes], summary: Summary, topics: Sequence[str] | None, starting_at: int | None, ending_at: int | None
) -> Iterator[tuple[Channel, Message]]:
    """Messages chunk by chunk in file order (one chunk in memory at a time), bounds inclusive."""
    wanted = None if topics is None else {c.id for c in summary.channels.values() if c.topic in topics}
    for index in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
        if starting_at is not None and index.message_end_time < starting_at:
            continue
        if ending_at is not None and index.message_start_time > ending_at:
            continue
        if wanted is not None and index.message_index_offsets and not wanted & set(index.message_index_offsets):
            continue
        f.seek(index.chunk_start_offset + 1 + 8)  # past the record's opcode and length
        for record in breakup_chunk(Chunk.read(ReadDataStream(f)), validate_crc=True):
            if not isinstance(record, Message) or (wanted is not None and record.channel_id not in wanted):
                continue
            if (starting_at is None or record.log_time >= starting_at) and (
                ending_at is None or record.log_time <= ending_at
            ):
                yield summary.channels[record.channel_id], record


def _decode(name: str, channel: Channel, message: Message) -> Any:
    if channel.message_encoding != "json":
        raise DataFormatError(f"channel {channel.topic} is {channel.message_encoding!r}, not JSON", file=name)
    try:
        return json.loads(message.data)
    except ValueError as exc:
        raise DataFormatError(f"bad JSON on {channel.topic} at {message.log_time} ns", file=name) from exc


def read_messages(path: str | Path, topics: Sequence[str] | None = None) -> Iterator[tuple[str, int, Any]]:
    """Yield ``(topic, log_time_ns, decoded JSON)`` of every message on ``topics`` (all if None),
    in log-time order."""
    for channel, message in _iter_raw(path, topics):
        yield channel.topic, message.log_time, _decode(str(path), channel, message)


def iter_sensor_frames(path: str | Path) -> Iterator[tuple[int, schema.SensorFrame]]:
    """``(log_time_ns, frame)`` of the ``/sensor`` frames of a finished file, validated, in log-time
    order, read lazily (a long trial never sits in memory whole)."""
    name = str(path)
    for _, message in _iter_raw(path, ["/sensor"]):
        try:
            yield message.log_time, schema.SensorFrame.model_validate_json(message.data)
        except ValueError as exc:
            raise DataFormatError(f"bad /sensor frame at {message.log_time} ns: {exc}", file=name) from exc


def read_sensor_frames(path: str | Path) -> list[schema.SensorFrame]:
    """All ``/sensor`` frames of a finished file, validated, in log-time order."""
    return [frame for _, frame in iter_sensor_frames(path)]


def read_events(path: str | Path) -> list[dict[str, Any]]:
    """The ``/events`` of a file as :class:`~gaitscope.sessions.schema.Event`-shaped dicts, plus ``log_time_ns``.

    Keys come from the Foxglove event's metadata (written by :meth:`Recorder.write_event`): ``id`` and
    ``session_id`` as int, ``t`` as float, ``before``/``after`` as float when ``field`` is a numeric
    setting (:data:`~gaitscope.sessions.schema.SETTING_LIMITS`) or the event is an ``intent`` (desired speeds),
    else str; absent keys (events written by other tools) are left out.
    """
    out = []
    for _, log_time, msg in read_messages(path, ["/events"]):
        try:
            event: dict[str, Any] = {"log_time_ns": log_time, **{kv["key"]: kv["value"] for kv in msg["metadata"]}}
            for key, cast in (("id", int), ("session_id", int), ("t", float)):
                if key in event:
                    event[key] = cast(event[key])
            if event.get("field") in schema.SETTING_LIMITS or event.get("kind") == "intent":
                for key in ("before", "after"):
                    if key in event:
                        event[key] = float(event[key])
        except (KeyError, TypeError, ValueError) as exc:
            raise DataFormatError(f"bad /events message at {log_time} ns: {exc!r}", file=str(path)) from exc
        out.append(event)
    return out


def series_window(path: str | Path, t0: float | None, t1: float | None) -> tuple[int | None, int | None] | None:
    """Log-time bounds (ns, inclusive) of session times ``[t0, t1]`` in a gaitscope recording, whose
    every message is logged at ``start + round(t * 1e9)``; None if the file has no gait state."""
    if t0 is None and t1 is None:
        return None, None
    offset = _log_time_offset(path)
    if offset is None:
        return None
    return (
        None if t0 is None else offset + round(t0 * 1e9),
        None if t1 is None else offset + round(t1 * 1e9),
    )


def count_messages(path: str | Path, topic: str, starting_at: int | None, ending_at: int | None) -> int:
    """Number of messages on ``topic`` within the log-time bounds (no JSON is decoded; without bounds,
    read from the file's statistics record when it has one)."""
    if starting_at is None and ending_at is None:
        with open(path, "rb") as f:
            _, summary = _indexed_summary(f, str(path))
        stats = summary.statistics
        if stats is not None and stats.channel_message_counts:
            ids = [c.id for c in summary.channels.values() if c.topic == topic]
            return sum(stats.channel_message_counts.get(i, 0) for i in ids)
    return sum(1 for _ in _iter_raw(path, [topic], starting_at, ending_at, file_order=True))


class SeriesBuilder:
    """Builds :data:`SERIES_COLUMNS` from gait states fed one at a time, in memory bounded by
    ``max_points`` and one bucket: with more than ``max_points`` of the ``n`` expected rows, each of
    ``max_points // 2`` buckets of consecutive rows becomes two rows as :func:`read_series` describes.
    ``extra`` columns (float or None: estimator outputs) are decimated like the plotted floats; ``base``
    replaces :data:`SERIES_COLUMNS` (``("t",)``: an estimator's outputs alone, :func:`read_estimator_series`)."""

    def __init__(self, n: int, max_points: int, extra: Sequence[str] = (), base: Sequence[str] = SERIES_COLUMNS):
        if max_points < 2:
            raise ValueError(f"max_points must be at least 2, got {max_points}")
        self._columns = (*base, *extra)
        self._plot = (*(c for c in _PLOT_COLUMNS if c in base), *extra)
        self._out: dict[str, list[Any]] = {c: [] for c in self._columns}
        self._bucketed = n > max_points
        self._edges = [int(e) for e in np.linspace(0, n, max_points // 2 + 1).round()][1:] if self._bucketed else []
        self._bucket: list[Mapping[str, Any]] = []
        self._seen = 0

    def add(self, row: Mapping[str, Any]) -> None:
        if not self._bucketed:
            for c in self._columns:
                self._out[c].append(row.get(c))
            return
        self._bucket.append(row)
        self._seen += 1
        if self._edges and self._seen >= self._edges[0]:
            self._edges.pop(0)
            self._flush()

    def _flush(self) -> None:
        if self._bucket:
            part = _decimate({c: [r.get(c) for r in self._bucket] for c in self._columns}, 1, self._plot)
            for c in self._columns:
                self._out[c].extend(part[c])
            self._bucket = []

    def result(self) -> dict[str, list[Any]]:
        self._flush()
        return self._out


def read_series(path: str | Path, t0: float | None, t1: float | None, max_points: int) -> dict[str, list[Any]]:
    """Columns of the ``/gait_state`` messages with ``t0 <= t <= t1`` (None: unbounded).

    Keys are :data:`SERIES_COLUMNS` (every GaitState field, ``t`` first). Bounds seek through the
    chunk index, so only the chunks around the window are read, and memory stays bounded by
    ``max_points`` whatever the trial's length (one counting pass, then one decoding pass). Above
    ``max_points`` samples the window is cut into ``max_points // 2`` buckets of consecutive samples and
    each gives two rows: ``t``, ``seq`` and the ns clocks of the bucket's first and last sample, and for
    each plotted float its minimum and maximum in the order they occur, so peaks survive;
    ``heel_strike`` and ``backup_reset`` are True on the row nearer to their first occurrence.
    """
    if max_points < 2:
        raise ValueError(f"max_points must be at least 2, got {max_points}")
    window = series_window(path, t0, t1)
    if window is None:
        return {c: [] for c in SERIES_COLUMNS}
    starting_at, ending_at = window
    builder = SeriesBuilder(count_messages(path, "/gait_state", starting_at, ending_at), max_points)
    for channel, message in _iter_raw(path, ["/gait_state"], starting_at, ending_at, file_order=True):
        row = _decode(str(path), channel, message)
        if not isinstance(row, dict) or not isinstance(row.get("t"), int | float):
            raise DataFormatError(f"/gait_state message without t at {message.log_time} ns", file=str(path))
        builder.add(row)
    return builder.result()


def read_estimator_series(
    path: str | Path, name: str, t0: float | None, t1: float | None, max_points: int
) -> dict[str, list[Any]] | None:
    """Columns ``t`` and each output of estimator ``name`` (``/estimators/<name>``, in the order of its first
    message's ``values``) with ``t0 <= t <= t1``, decimated as :func:`read_series` (min and max per bucket of
    each output; None where it had failed). None: the file records no such estimator.
    """
    if max_points < 2:
        raise ValueError(f"max_points must be at least 2, got {max_points}")
    topic = f"{schema.ESTIMATOR_TOPIC_PREFIX}{name}"
    with open(path, "rb") as f:
        _, summary = _indexed_summary(f, str(path))
    if not any(c.topic == topic for c in summary.channels.values()):
        return None
    window = series_window(path, t0, t1)
    if window is None:
        return {"t": []}
    starting_at, ending_at = window
    n = count_messages(path, topic, starting_at, ending_at)
    builder: SeriesBuilder | None = None
    for channel, message in _iter_raw(path, [topic], starting_at, ending_at, file_order=True):
        msg = _decode(str(path), channel, message)
        values = msg.get("values") if isinstance(msg, dict) else None
        if not isinstance(values, dict) or not isinstance(msg.get("t"), int | float):
            raise DataFormatError(f"{topic} message without t or values at {message.log_time} ns", file=str(path))
        if builder is None:
            builder = SeriesBuilder(n, max_points, tuple(values), base=("t",))
        builder.add({"t": msg["t"], **values})
    return {"t": []} if builder is None else builder.result()


def decimate(rows: Sequence[Mapping[str, Any]], max_points: int) -> dict[str, list[Any]]:
    """Gait states (GaitState dicts) as :data:`SERIES_COLUMNS`, min/max-decimated to at most
    ``max_points`` rows as :func:`read_series` describes."""
    builder = SeriesBuilder(len(rows), max_points)
    for row in rows:
        builder.add(row)
    return builder.result()


def _log_time_offset(path: str | Path) -> int | None:
    """log_time - t (ns) of the first /gait_state message (the session start), None if none."""
    for channel, message in _iter_raw(path, ["/gait_state"]):
        row = _decode(str(path), channel, message)
        t = row.get("t") if isinstance(row, dict) else None
        if not isinstance(t, int | float):
            raise DataFormatError(f"/gait_state message without t at {message.log_time} ns", file=str(path))
        return message.log_time - round(t * 1e9)
    return None


def _decimate(
    columns: dict[str, list[Any]], n_buckets: int, plot_columns: Sequence[str] = _PLOT_COLUMNS
) -> dict[str, list[Any]]:
    n = len(columns["t"])
    edges = [int(e) for e in np.linspace(0, n, n_buckets + 1).round()]  # Python ints: JSON-ready output
    plot = {c: np.array([np.nan if v is None else float(v) for v in columns[c]], dtype=float) for c in plot_columns}
    out: dict[str, list[Any]] = {c: [] for c in columns}
    for lo, hi in itertools.pairwise(edges):
        for c in columns:
            if c in plot:
                out[c].extend(_min_max_in_order(plot[c][lo:hi]))
            elif c in _FLAG_COLUMNS:
                hits = [i for i in range(lo, hi) if columns[c][i]]
                first_half = bool(hits) and hits[0] - lo < (hi - lo) / 2
                out[c].extend([first_half, bool(hits) and not first_half])
            else:
                out[c].extend([columns[c][lo], columns[c][hi - 1]])
    return out


def _min_max_in_order(x: np.ndarray) -> list[float | None]:
    finite = ~np.isnan(x)
    if not finite.any():
        return [None, None]
    i_min = int(np.argmin(np.where(finite, x, np.inf)))
    i_max = int(np.argmax(np.where(finite, x, -np.inf)))
    first, second = sorted((i_min, i_max))
    return [float(x[first]), float(x[second])]


# --- crash recovery ------------------------------------------------------------------------------


@dataclass(frozen=True)
class RecoveryResult:
    """What :func:`recover` did.

    Attributes:
        messages: messages in the (recovered or already finished) file.
        lost_bytes: bytes of the original that could not be carried over: the torn tail and any
            damaged chunk before it (0 when nothing was done).
        recovered: False when the file was already finished and was left untouched.
    """

    messages: int
    lost_bytes: int
    recovered: bool


def recover(path: Path) -> RecoveryResult:
    """Rewrite an MCAP file left unfinished (no index) by a crash as a finished one.

    Reads the file front to back and keeps every complete record: the header, metadata,
    attachments, schemas, channels and the messages of every chunk whose CRC checks; stops at the
    torn tail. The result is written beside the file, synced and moved over it, so if anything fails
    the original is left exactly as it was. A finished file is left untouched. A disk with no room
    for that copy (full) raises OSError ``ENOSPC``: :func:`recover_in_place` needs no copy.

    Raises:
        DataFormatError: not an MCAP file (bad magic).
    """
    with open(path, "rb") as f:
        finished = _finished(f, str(path))
    if finished is not None:
        stats = finished[1].statistics
        return RecoveryResult(messages=stats.message_count if stats else 0, lost_bytes=0, recovered=False)
    with atomic_output(path) as tmp:
        with open(path, "rb") as src, open(tmp, "wb") as dst:
            messages, lost = _copy_complete_records(src, dst)
        with open(tmp, "rb") as f:  # read the index back before it replaces the original
            check = _finished(f, str(tmp))
        stats = check[1].statistics if check is not None else None
        if stats is None or stats.message_count != messages:
            raise DataFormatError("recovery wrote an unreadable file; the original is kept", file=str(path))
    return RecoveryResult(messages=messages, lost_bytes=lost, recovered=True)


def recover_in_place(path: Path) -> RecoveryResult:
    """Index an unfinished MCAP file where it lies: :func:`recover` for a disk with no room for a copy.

    Reads the file's records front to back, as :func:`recover` does, and appends the summary section
    (schemas, channels, statistics, chunk and metadata indexes) and the footer right after the last
    complete chunk and its message indexes, cutting off the torn tail. That takes a few hundred bytes
    per chunk (about 1 MiB for an hour at 200 Hz). When even that does not fit (the disk is full),
    the last chunks are cut off one by one, each freeing its space, until the index fits. The file is
    never copied: an interruption while the index is written leaves it unfinished again, which
    :func:`recover` handles. A finished file is left untouched.

    Raises:
        DataFormatError: not an MCAP file, or a damaged chunk before the end (only :func:`recover`,
            which copies the file, can skip one), or nothing is left to index.
        OSError: the index could not be written even with all data cut off.
    """
    name = str(path)
    with open(path, "r+b") as f:
        finished = _finished(f, name)
        if finished is not None:
            stats = finished[1].statistics
            return RecoveryResult(messages=stats.message_count if stats else 0, lost_bytes=0, recovered=False)
        size = f.seek(0, io.SEEK_END)
        f.seek(0)
        scan = _scan_records(f, name)
        for kept in range(len(scan.chunks), 0, -1):
            end = scan.chunks[kept - 1].end
            summary = scan.summary(kept, end)
            try:
                f.truncate(end)
                f.seek(end)
                f.write(summary)
                f.flush()
                os.fsync(f.fileno())
            except OSError as exc:
                if exc.errno not in (errno.ENOSPC, errno.EDQUOT):
                    raise
                f.truncate(end)  # free what was written, then try with one chunk less
                continue
            messages = sum(c.messages for c in scan.chunks[:kept])
            return RecoveryResult(messages=messages, lost_bytes=size - end, recovered=True)
    raise DataFormatError("no complete chunk to keep" if not scan.chunks else
                          "the disk has no room even for the index of the first chunk", file=name)  # fmt: skip


@dataclass
class _ScannedChunk:
    """A chunk of an unfinished file, as :func:`recover_in_place` indexes it."""

    index: ChunkIndex
    end: int  # offset just past the chunk and its message indexes
    messages: int
    counts: dict[int, int]  # messages per channel id


@dataclass
class _Scan:
    """The complete records of an unfinished file that its summary section lists."""

    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    metadata: list[MetadataIndex] = field(default_factory=list)
    chunks: list[_ScannedChunk] = field(default_factory=list)

    def summary(self, kept: int, start: int) -> bytes:
        """DataEnd, the summary section of the first ``kept`` chunks, footer and magic, for offset ``start``."""
        chunks = self.chunks[:kept]
        counts: dict[int, int] = {}
        for c in chunks:
            for channel_id, n in c.counts.items():
                counts[channel_id] = counts.get(channel_id, 0) + n
        head = RecordBuilder()
        DataEnd(data_section_crc=0).write(head)
        summary_start = start + head.count
        body = RecordBuilder()
        offsets: list[SummaryOffset] = []

        def group(opcode: Opcode, records: Sequence[Any]) -> None:
            begin = body.count
            for record in records:
                record.write(body)
            offsets.append(SummaryOffset(opcode, summary_start + begin, body.count - begin))

        times = [c.index for c in chunks if c.messages]
        group(Opcode.SCHEMA, list(self.schemas.values()))
        group(Opcode.CHANNEL, list(self.channels.values()))
        group(Opcode.STATISTICS, [Statistics(
            attachment_count=0, channel_count=len(self.channels), channel_message_counts=counts,
            chunk_count=len(chunks), message_count=sum(c.messages for c in chunks),
            message_end_time=max((i.message_end_time for i in times), default=0),
            message_start_time=min((i.message_start_time for i in times), default=0),
            metadata_count=len(self.metadata), schema_count=len(self.schemas),
        )])  # fmt: skip
        group(Opcode.CHUNK_INDEX, [c.index for c in chunks])
        group(Opcode.METADATA_INDEX, self.metadata)
        offset_start = summary_start + body.count
        for offset in offsets:
            offset.write(body)
        data = body.end()
        crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 8 + 8 + 4, summary_start, offset_start), zlib.crc32(data))
        tail = RecordBuilder()
        Footer(summary_start=summary_start, summary_offset_start=offset_start, summary_crc=crc).write(tail)
        return head.end() + data + tail.end() + _MAGIC


def _complete_records(f: IO[bytes]) -> Iterator[tuple[object, list[Any] | None, int]]:
    """The records of ``f`` up to its torn tail (a record cut short by a crash, where reading stops), each
    with, for a chunk, its records (``None``: the chunk is damaged or cut short), and the offset where the
    record ends. Errors that are not damage to the file are raised."""
    records = StreamReader(f, skip_magic=False, emit_chunks=True).records
    while True:
        try:
            record = next(records)
        except StopIteration:
            return
        except Exception as exc:
            if not _is_damage(exc):
                raise
            return  # the torn tail
        end = f.tell()
        contents: list[Any] | None = None
        if isinstance(record, Chunk):
            try:
                contents = list(breakup_chunk(record, validate_crc=True))
            except Exception as exc:
                if not _is_damage(exc):
                    raise
        yield record, contents, end


def _scan_records(f: IO[bytes], name: str) -> _Scan:
    """The complete chunks (with their message indexes), schemas, channels and metadata of ``f``, in order,
    up to the torn tail or the first damaged chunk."""
    scan = _Scan()
    good_end = len(_MAGIC)
    for record, contents, end in _complete_records(f):
        begin = good_end
        if isinstance(record, Chunk):
            if contents is None:
                break  # damaged (or cut short): keep what comes before it
            counts: dict[int, int] = {}
            for inner in contents:
                if isinstance(inner, Schema):
                    scan.schemas.setdefault(inner.id, inner)
                elif isinstance(inner, Channel):
                    scan.channels.setdefault(inner.id, inner)
                elif isinstance(inner, Message):
                    counts[inner.channel_id] = counts.get(inner.channel_id, 0) + 1
            index = ChunkIndex(
                chunk_length=end - begin, chunk_start_offset=begin, compression=record.compression,
                compressed_size=len(record.data), message_end_time=record.message_end_time,
                message_index_length=0, message_index_offsets={}, message_start_time=record.message_start_time,
                uncompressed_size=record.uncompressed_size,
            )  # fmt: skip
            scan.chunks.append(_ScannedChunk(index, end, sum(counts.values()), counts))
        elif isinstance(record, MessageIndex) and scan.chunks and scan.chunks[-1].end == begin:
            last = scan.chunks[-1]
            last.index.message_index_offsets[record.channel_id] = begin
            last.index.message_index_length += end - begin
            last.end = end
        elif isinstance(record, Metadata):
            scan.metadata.append(MetadataIndex(offset=begin, length=end - begin, name=record.name))
        elif isinstance(record, Schema):
            scan.schemas.setdefault(record.id, record)
        elif isinstance(record, Channel):
            scan.channels.setdefault(record.id, record)
        elif not isinstance(record, Header | MessageIndex):
            break  # attachments, or records after the data section: not what a recorder leaves; stop here
        good_end = end
    if not scan.channels and not scan.chunks:
        raise DataFormatError("nothing complete to keep", file=name)
    return scan


def _copy_complete_records(src: IO[bytes], dst: IO[bytes]) -> tuple[int, int]:
    """Copy the complete records of ``src`` into a finished MCAP on ``dst``: (messages, lost bytes)."""
    size = src.seek(0, io.SEEK_END)
    src.seek(0)
    writer = Writer(dst, chunk_size=CHUNK_SIZE)
    started = False
    schema_ids: dict[int, int] = {}
    channel_ids: dict[int, int] = {}
    messages = skipped = 0

    def start(header: Header | None) -> None:
        nonlocal started
        if not started:
            writer.start(profile=header.profile if header else "", library=header.library if header else "")
            started = True

    def copy(record: object) -> None:
        nonlocal messages
        if isinstance(record, Header):
            start(record)
            return
        start(None)
        if isinstance(record, Schema) and record.id not in schema_ids:
            schema_ids[record.id] = writer.register_schema(record.name, record.encoding, record.data)
        elif isinstance(record, Channel) and record.id not in channel_ids:
            if record.schema_id == 0 or record.schema_id in schema_ids:
                channel_ids[record.id] = writer.register_channel(
                    record.topic,
                    record.message_encoding,
                    schema_ids.get(record.schema_id, 0),
                    record.metadata,
                )
        elif isinstance(record, Message) and record.channel_id in channel_ids:
            writer.add_message(
                channel_ids[record.channel_id],
                record.log_time,
                record.data,
                record.publish_time,
                record.sequence,
            )
            messages += 1
        elif isinstance(record, Metadata):
            writer.add_metadata(record.name, record.metadata)
        elif isinstance(record, Attachment):
            writer.add_attachment(record.create_time, record.log_time, record.name, record.media_type, record.data)

    good_end = len(_MAGIC)  # end of the last record carried over (or skipped as damaged)
    for record, contents, end in _complete_records(src):
        if isinstance(record, Chunk):
            if contents is None:
                if end >= size:
                    break  # cut short by the crash
                skipped += end - good_end  # damaged but complete: skip it, read on
                good_end = end
                continue
            for inner in contents:
                copy(inner)
        else:
            copy(record)
        good_end = end
    start(None)
    writer.finish()
    dst.flush()
    return messages, size - good_end + skipped


def metadata_of(path: Path, name: str) -> dict[str, str]:
    """Key/values of the MCAP file's metadata record ``name`` (empty without one).

    Raises:
        DataFormatError: the file's metadata cannot be read.
    """
    try:
        with open(path, "rb") as f:
            for record in make_reader(f).iter_metadata():
                if record.name == name:
                    return dict(record.metadata)
    except _DAMAGE as exc:
        raise DataFormatError(f"damaged metadata ({exc})", file=str(path)) from exc
    return {}
