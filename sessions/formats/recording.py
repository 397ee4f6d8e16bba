"""Recording one trial to an MCAP file; the readers and crash recovery live in :mod:`sessions.formats.mcap_io`.

One JSON-schema channel per entry of :data:`~gaitscope.sessions.schema.MCAP_CHANNELS`, plus the channels a session
registers for its estimator stack (``channels``: ``/estimators/<name>``); every message's log time
and publish time are ``start_ns + round(t * 1e9)``: integer nanoseconds since the Unix epoch, the
session's start wall clock plus the sample time ``t`` (s). Lifecycle: construct (writes the header,
the ``gaitscope`` metadata record and the channels), :meth:`Recorder.write` per message,
:meth:`Recorder.finish` (writes the index; the file is unreadable to Foxglove without it).

What a crash loses. The mcap ``Writer`` builds a chunk in memory. The recorder closes it with
``Writer.flush()`` (public in mcap 1.5 and 1.6; gaitscope needs >= 1.6) once it holds
``flush_interval_s`` of session time, or has been open that long by the wall clock, or reaches
:data:`~gaitscope.sessions.formats.mcap_io.CHUNK_SIZE`, whichever comes first. It then hands the chunk to the
operating system at once. So ``kill -9`` loses at most the open chunk: about ``flush_interval_s``
(0.5 s) of data. Session time bounds that loss in seconds of data, and it makes the rule
deterministic (tests, replays faster than real time). The wall clock bounds how long data waits in
memory when the session clock runs slower than the wall (a replay below 1x, messages logged at the
time of the last sample after the source stopped). The file is fsynced every ``fsync_interval_s`` of
wall time (2 s) and at :meth:`~Recorder.finish`. A power cut therefore loses at most about
``flush_interval_s + fsync_interval_s`` of data. The periodic fsync runs on a worker thread, because
the caller is the session's event loop. On a busy disk one fsync of a 15 KiB chunk took up to 490 ms
(median 0.7 ms), while the ``write`` that hands a chunk to the OS stayed under 0.1 ms. An fsync
error is raised by the next write. :func:`~gaitscope.sessions.formats.mcap_io.recover` re-indexes what is left.

Write errors (a full disk). The ``Writer`` writes into memory, never to the file, so an I/O error
cannot leave it half-updated. The recorder copies its output to the file. When that write fails,
the recorder cuts the file back to the end of the last complete chunk and raises
:class:`RecordingError`. Every later write raises it too, so nothing more is recorded and memory
stays bounded. :meth:`~Recorder.finish` then retries the failed chunk and writes the index. If the
disk is still full, :meth:`~Recorder.finish` leaves the file ending at the last complete chunk and
raises :class:`RecordingError`. Such a file is readable once :func:`~gaitscope.sessions.formats.mcap_io.recover` has
indexed it (start-up recovery does that). What is lost: the messages refused after the failure,
and, if the disk stays full, the chunk whose write failed (at most ``flush_interval_s`` of data).
"""

from __future__ import annotations

import errno as errnos
import io
import json
import os
import threading
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import TracebackType
from typing import IO, TYPE_CHECKING, Final, cast

from mcap.writer import Writer
from pydantic import BaseModel

from gaitscope.sessions import schema
from gaitscope.sessions.formats._mcap_fast import message_adder
from gaitscope.sessions.formats.mcap_io import CHUNK_SIZE

if TYPE_CHECKING:
    from _typeshed import ReadableBuffer

__all__ = [
    "ESTIMATORS_KEY",
    "FINGERPRINT_KEY",
    "FLUSH_INTERVAL_S",
    "FSYNC_INTERVAL_S",
    "METADATA_NAME",
    "SAMPLE_PERIOD_KEY",
    "Recorder",
    "RecordingError",
]

#: Name of the MCAP metadata record holding the trial's key/values (subject code, session id, ...).
METADATA_NAME: Final = "gaitscope"
#: Key in that record of the sample period (s, a float's ``repr``) the live estimator was built with, so
#: that a review re-run (:mod:`gaitscope.sessions.review.rerun`) builds the same one.
SAMPLE_PERIOD_KEY: Final = "sample_period_s"
#: Key of the session's estimator stack (names, comma-separated, in run order), so that a review re-run
#: runs the same estimators.
ESTIMATORS_KEY: Final = "estimators"
#: Key of the gait fingerprint the personalized filter (``fp_ls``) ran with (floats' ``repr``, comma-separated),
#: so that a review re-run "as recorded" runs the same one.
FINGERPRINT_KEY: Final = "fingerprint"
#: Default longest time (s, session or wall) a chunk stays open: what ``kill -9`` can lose.
FLUSH_INTERVAL_S: Final = 0.5
#: Default longest wall time (s) between two fsyncs of a recording: what a power cut adds to that.
FSYNC_INTERVAL_S: Final = 2.0
_DISK_FULL: Final = (errnos.ENOSPC, errnos.EDQUOT)


class RecordingError(OSError):
    """Writing a recording's file failed (disk full, I/O error); nothing more is recorded.

    ``str()`` is a sentence for the user (no server paths). ``errno`` is the operating system's
    error (``errno.ENOSPC`` when the disk is full), ``filename`` the recording file.
    """

    def __str__(self) -> str:
        return str(self.strerror)


class _MemorySink(io.BufferedIOBase):
    """The mcap Writer's output: bytes kept in memory until the recorder moves them to the file.

    ``tell()`` counts every byte ever written, which is the offset in the file that the Writer
    records in its index.
    """

    def __init__(self) -> None:
        super().__init__()
        self._parts: list[bytes] = []
        self._offset = 0

    def writable(self) -> bool:
        return True

    def write(self, data: ReadableBuffer, /) -> int:
        part = bytes(data)
        self._parts.append(part)
        self._offset += len(part)
        return len(part)

    def tell(self) -> int:
        return self._offset

    def has_data(self) -> bool:
        return bool(self._parts)

    def take(self) -> bytes:
        data = b"".join(self._parts)
        self._parts.clear()
        return data


def _write_all(file: io.FileIO, data: bytes) -> None:
    """Write all of ``data`` at the file's position; a short write is continued; OSError propagates."""
    view = memoryview(data)
    while view:
        n = file.write(view)
        if not n:
            raise OSError(errnos.EIO, "the operating system accepted no bytes")
        view = view[n:]


class Recorder:
    """Writes one trial's MCAP file.

    Args:
        path: the file to create (its folder is created); an existing file is never overwritten.
        start_ns: the session's start wall clock, integer ns since the Unix epoch.
        metadata: key/values of the ``gaitscope`` metadata record (subject code, session id, ...);
            ``start_ns`` is added.
        flush_interval_s: a chunk is closed and handed to the OS once it spans this much session
            time or has been open this long by the wall clock (see the module docstring).
        fsync_interval_s: the file is fsynced when a chunk is handed over this long (wall clock)
            after the last fsync; 0 fsyncs every chunk, ``math.inf`` only at :meth:`finish`.
        channels: more channels, as :data:`~gaitscope.sessions.schema.MCAP_CHANNELS` (topic -> schema name and
            class): a stack's ``/estimators/<name>`` (:func:`~gaitscope.sessions.schema.estimator_channels`).

    Attributes:
        samples: number of ``/gait_state`` messages written.
        duration_s: last minus first ``t`` of the ``/gait_state`` messages (0 before two).
        saved_t: the latest session time (s) of the messages handed to the OS (None before the
            first chunk).
        error: the failure that stopped the recording, None while it is healthy.

    Raises:
        FileExistsError: ``path`` exists.
        RecordingError: the header could not be written (the file is removed).
        ValueError: ``flush_interval_s`` not above 0 or ``fsync_interval_s`` below 0.
    """

    def __init__(
        self,
        path: Path,
        start_ns: int,
        metadata: dict[str, str],
        *,
        flush_interval_s: float = FLUSH_INTERVAL_S,
        fsync_interval_s: float = FSYNC_INTERVAL_S,
        channels: Mapping[str, tuple[str, type[BaseModel]]] | None = None,
    ):
        if not flush_interval_s > 0:
            raise ValueError(f"flush_interval_s must be above 0, got {flush_interval_s}")
        if not fsync_interval_s >= 0:
            raise ValueError(f"fsync_interval_s must be at least 0, got {fsync_interval_s}")
        self.path = path
        self.start_ns = start_ns
        self.flush_interval_s = flush_interval_s
        self.fsync_interval_s = fsync_interval_s
        self.samples = 0
        self.duration_s = 0.0
        self.saved_t: float | None = None
        self.error: RecordingError | None = None
        self._first_t: float | None = None
        self._finished = False
        self._chunk_t0: float | None = None  # session time of the open chunk's first message
        self._chunk_wall0 = 0.0  # monotonic time it was opened
        self._open_t: float | None = None  # latest t in the open chunk
        self._closed_t: float | None = None  # latest t in the chunks closed so far
        self._written = 0  # bytes in the file: the end of its last complete record
        self._pending = b""  # bytes of a write that failed, retried by finish()
        self._syncer: threading.Thread | None = None
        self._sync_error: OSError | None = None  # set by the syncer thread
        path.parent.mkdir(parents=True, exist_ok=True)
        self._file = io.FileIO(path, "xb")
        self._synced_at = time.monotonic()
        self._sink = _MemorySink()
        try:
            # The Writer calls only write, tell and flush on its output.
            self._writer = Writer(cast(IO[bytes], self._sink), chunk_size=CHUNK_SIZE)
            self._writer.start(profile="", library="gaitscope")
            self._add = message_adder(self._writer)
            self._writer.add_metadata(METADATA_NAME, {**metadata, "start_ns": str(start_ns)})
            self._channels: dict[str, tuple[int, type[BaseModel]]] = {}
            schema_ids: dict[str, int] = {}  # one schema record per schema, however many channels use it
            for topic, (schema_name, cls) in {**schema.MCAP_CHANNELS, **(channels or {})}.items():
                if schema_name not in schema_ids:
                    schema_ids[schema_name] = self._writer.register_schema(
                        name=schema_name,
                        encoding="jsonschema",
                        data=json.dumps(cls.model_json_schema()).encode(),
                    )
                schema_id = schema_ids[schema_name]
                channel_id = self._writer.register_channel(topic=topic, message_encoding="json", schema_id=schema_id)
                self._channels[topic] = (channel_id, cls)
            self._commit()  # the header and the metadata; schemas and channels open the first chunk
        except BaseException:
            self._file.close()
            path.unlink(missing_ok=True)
            raise

    def log_time_ns(self, t: float) -> int:
        """The log time of session time ``t`` (s): ``start_ns + round(t * 1e9)``."""
        return self.start_ns + round(t * 1e9)

    def write(self, topic: str, t: float, message: BaseModel) -> None:
        """Write ``message`` (the topic's class in MCAP_CHANNELS) at session time ``t`` (s).

        Raises:
            ValueError: unknown topic, or the recorder is finished.
            TypeError: ``message`` is not the topic's class.
            RecordingError: the file could not be written, now or earlier. The message that hit the
                error is held in memory for :meth:`finish` to retry; later ones are refused.
        """
        cls = self._channel(topic)[1]
        if not isinstance(message, cls):
            raise TypeError(f"{topic} carries {cls.__name__}, not {type(message).__name__}")
        # a sensor frame's absent channels (None) are left out: most devices send a few of dozens
        data = message.model_dump_json(exclude_none=isinstance(message, schema.SensorFrame)).encode()
        self.write_json(t, ((topic, data),))

    def write_json(self, t: float, messages: Sequence[tuple[str, bytes]]) -> None:
        """Write ``messages`` at session time ``t`` (s), each ``(topic, data)`` with ``data`` already the
        JSON of the topic's class: the hot path, which writes one sample's sensor frame, state, torque
        and estimator outputs (:meth:`~gaitscope.sessions.estimation.FrameEstimator.output_json`) in one call
        rather than building and dumping a model for each. Not validated here; tests check that what
        the hot path builds is what the class would dump.

        Raises:
            As :meth:`write`; an unknown topic is refused before anything is written.
        """
        ids = [self._channel(topic)[0] for topic, _ in messages]
        self._raise_if_failed()
        log_time = self.log_time_ns(t)
        add = self._add
        for channel_id, (topic, data) in zip(ids, messages, strict=True):
            add(channel_id, log_time, data)
            if topic == "/gait_state":
                self.samples += 1
                if self._first_t is None:
                    self._first_t = t
                self.duration_s = t - self._first_t
        self._after_write(t)

    def _channel(self, topic: str) -> tuple[int, type[BaseModel]]:
        """The channel id and message class of ``topic``; ValueError when unknown or finished."""
        if self._finished:
            raise ValueError(f"recorder of {self.path} is finished")
        entry = self._channels.get(topic)
        if entry is None:
            raise ValueError(f"unknown MCAP topic {topic!r}; expected one of {sorted(self._channels)}")
        return entry

    def _after_write(self, t: float) -> None:
        """Close the chunk when it is full or due (see the module docstring)."""
        self._open_t = t if self._open_t is None else max(self._open_t, t)
        if self._sink.has_data():  # the Writer closed the chunk at CHUNK_SIZE
            self._chunk_closed()
        elif self._chunk_due(t):
            self._writer.flush()
            self._chunk_closed()
        elif self._chunk_t0 is None:
            self._chunk_t0, self._chunk_wall0 = t, time.monotonic()

    def write_event(self, event: schema.Event) -> None:
        """Write ``event`` on ``/events`` as a ``foxglove.Event`` at its ``t``.

        Its fields become the metadata key/values (absent ones left out), so Foxglove lists them and
        :func:`~gaitscope.sessions.formats.mcap_io.read_events` gives them back.
        """
        log_time = self.log_time_ns(event.t)
        stamp = schema.TimeStamp(sec=log_time // 1_000_000_000, nsec=log_time % 1_000_000_000)
        values = {
            "kind": event.kind,
            "text": event.text,
            "field": event.field,
            "before": event.before,
            "after": event.after,
            "actor": event.actor,
            "id": event.id,
            "session_id": event.session_id,
            "t": event.t,
            "wall_utc": event.wall_utc,
        }
        meta = [schema.KeyValuePair(key=k, value=str(v)) for k, v in values.items() if v is not None]
        self.write("/events", event.t, schema.FoxgloveEvent(start_time=stamp, end_time=stamp, metadata=meta))

    def finish(self) -> None:
        """Write the open chunk and the index (summary and footer), fsync and close; idempotent.

        After a write error it first retries what failed, so a disk that has room again gets a
        complete file.

        Raises:
            RecordingError: the file could not be completed; it ends at its last complete chunk,
                which :func:`~gaitscope.sessions.formats.mcap_io.recover` indexes (see the module docstring).
        """
        if self._finished:
            return
        self._finished = True
        try:
            self._commit(sync=False)  # the chunk that failed, if any, before the index that names it
            self._writer.finish()
            self._commit(sync=True)
        finally:
            if self._syncer is not None:
                self._syncer.join()
            self._file.close()

    # --- moving the Writer's output to the file ------------------------------------------------

    def _chunk_due(self, t: float) -> bool:
        """Whether the open chunk has been open for ``flush_interval_s`` of session or wall time."""
        if self._chunk_t0 is None:
            return False
        span = max(t - self._chunk_t0, time.monotonic() - self._chunk_wall0)
        return span >= self.flush_interval_s

    def _chunk_closed(self) -> None:
        if self._open_t is not None:
            self._closed_t = self._open_t if self._closed_t is None else max(self._closed_t, self._open_t)
        self._chunk_t0 = self._open_t = None
        self._commit()

    def _commit(self, sync: bool = False) -> None:
        """Append what the Writer has produced to the file. Then fsync: here when ``sync``, else on
        the worker thread when one is due.

        On a write error the file is cut back to its last complete record and the bytes are kept
        for :meth:`finish`; ``self.error`` is set and raised.
        """
        data = self._pending + self._sink.take()
        if data:
            try:
                _write_all(self._file, data)
            except OSError as exc:
                self._pending = data
                self._cut_back()
                raise self._fail(exc) from exc
            self._written += len(data)
            self._pending = b""
            self.saved_t = self._closed_t
        if sync:
            if self._syncer is not None:
                self._syncer.join()
            try:
                os.fsync(self._file.fileno())
            except OSError as exc:
                self._sync_error = exc
        # Before a new worker starts: only the worker that finished may have set the error.
        self._raise_sync_error()
        if not sync and data and time.monotonic() - self._synced_at >= self.fsync_interval_s:
            if self._syncer is None or not self._syncer.is_alive():
                self._synced_at = time.monotonic()
                self._syncer = threading.Thread(
                    target=self._fsync, args=(self._file.fileno(),), name=f"fsync {self.path.name}", daemon=True
                )
                self._syncer.start()

    def _raise_sync_error(self) -> None:
        """Raise a failed fsync (of the worker thread, or of :meth:`finish`) as the recording's error."""
        if self._sync_error is not None:
            failed, self._sync_error = self._sync_error, None
            raise self._fail(failed, uncertain=True) from failed

    def _raise_if_failed(self) -> None:
        """Raise the error that stopped the recording: a failed write or fsync, now or earlier."""
        self._raise_sync_error()
        if self.error is not None:
            raise RecordingError(self.error.errno, self.error.strerror, self.error.filename) from self.error

    def _fsync(self, fd: int) -> None:
        """The worker thread's body; :meth:`finish` joins it before it closes ``fd``."""
        try:
            os.fsync(fd)
        except OSError as exc:
            self._sync_error = exc

    def _cut_back(self) -> None:
        """Drop a torn write so the file ends at a record boundary (best effort: recovery copes)."""
        try:
            self._file.truncate(self._written)
            self._file.seek(self._written)
        except OSError:
            pass

    def _fail(self, exc: OSError, uncertain: bool = False) -> RecordingError:
        """Record ``exc`` as the error that stopped the recording, in words for the user."""
        if exc.errno in _DISK_FULL:
            why = "the disk is full"
        else:
            why = f"the disk could not be written ({exc.strerror or exc})"
        if uncertain:
            kept = "what was written may not all be on the disk"
        elif self.saved_t is None:
            kept = "no data is kept"
        else:
            kept = f"data up to {self.saved_t:.1f} s is kept"
        self.error = RecordingError(exc.errno, f"recording stopped: {why}; {kept}", str(self.path))
        return self.error

    def __enter__(self) -> Recorder:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        # Finish even on an error: what was recorded is good, and an indexed file needs no recovery.
        self.finish()
