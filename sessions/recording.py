"""Recording one trial to an MCAP file; the readers and crash recovery live in :mod:`sessions.mcap_io`.

One JSON-schema channel per entry of :data:`~sessions.schema.MCAP_CHANNELS`; every message's log time
and publish time are ``start_ns + round(t * 1e9)``: integer nanoseconds since the Unix epoch, the
session's start wall clock plus the sample time ``t`` (s). Lifecycle: construct (writes the header,
the ``gaitscope`` metadata record and the channels), :meth:`Recorder.write` per message,
:meth:`Recorder.finish` (writes the index; the file is unreadable to Foxglove without it).

Chunks of :data:`~sessions.mcap_io.CHUNK_SIZE` (about a second at 200 Hz) are handed to the operating
system as soon as they are complete, so a crash of the process loses at most the chunk being filled;
:func:`~sessions.mcap_io.recover` re-indexes what is left. (They are not fsynced one by one: a power
cut can lose what the OS had not yet written back.)
"""

from __future__ import annotations

import io
import json
import os
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Final

from mcap.writer import Writer
from pydantic import BaseModel

from sessions import schema
from sessions.mcap_io import CHUNK_SIZE

if TYPE_CHECKING:
    from _typeshed import ReadableBuffer

__all__ = ["METADATA_NAME", "Recorder"]

#: Name of the MCAP metadata record holding the trial's key/values (subject code, session id, ...).
METADATA_NAME: Final = "gaitscope"


class _PassThrough(io.BufferedWriter):
    """A buffered file that hands every write to the OS at once.

    The MCAP writer buffers a chunk itself and writes it in a few large calls, so this costs a few
    system calls per chunk and means a killed process leaves every completed chunk in the file.
    """

    def write(self, data: ReadableBuffer, /) -> int:
        n = super().write(data)
        self.flush()
        return n


class Recorder:
    """Writes one trial's MCAP file.

    Args:
        path: the file to create (its folder is created); an existing file is never overwritten.
        start_ns: the session's start wall clock, integer ns since the Unix epoch.
        metadata: key/values of the ``gaitscope`` metadata record (subject code, session id, ...);
            ``start_ns`` is added.

    Attributes:
        samples: number of ``/gait_state`` messages written.
        duration_s: last minus first ``t`` of the ``/gait_state`` messages (0 before two).

    Raises:
        FileExistsError: ``path`` exists.
    """

    def __init__(self, path: Path, start_ns: int, metadata: dict[str, str]):
        self.path = path
        self.start_ns = start_ns
        self.samples = 0
        self.duration_s = 0.0
        self._first_t: float | None = None
        self._finished = False
        path.parent.mkdir(parents=True, exist_ok=True)
        self._file = _PassThrough(io.FileIO(path, "xb"))
        try:
            self._writer = Writer(self._file, chunk_size=CHUNK_SIZE)
            self._writer.start(profile="", library="gaitscope")
            self._writer.add_metadata(METADATA_NAME, {**metadata, "start_ns": str(start_ns)})
            self._channels: dict[str, tuple[int, type[BaseModel]]] = {}
            for topic, (schema_name, cls) in schema.MCAP_CHANNELS.items():
                schema_id = self._writer.register_schema(
                    name=schema_name,
                    encoding="jsonschema",
                    data=json.dumps(cls.model_json_schema()).encode(),
                )
                channel_id = self._writer.register_channel(topic=topic, message_encoding="json", schema_id=schema_id)
                self._channels[topic] = (channel_id, cls)
        except BaseException:
            self._file.close()
            raise

    def log_time_ns(self, t: float) -> int:
        """The log time of session time ``t`` (s): ``start_ns + round(t * 1e9)``."""
        return self.start_ns + round(t * 1e9)

    def write(self, topic: str, t: float, message: BaseModel) -> None:
        """Write ``message`` (the topic's class in MCAP_CHANNELS) at session time ``t`` (s).

        Raises:
            ValueError: unknown topic, or the recorder is finished.
            TypeError: ``message`` is not the topic's class.
        """
        if self._finished:
            raise ValueError(f"recorder of {self.path} is finished")
        if topic not in self._channels:
            raise ValueError(f"unknown MCAP topic {topic!r}; expected one of {sorted(self._channels)}")
        channel_id, cls = self._channels[topic]
        if not isinstance(message, cls):
            raise TypeError(f"{topic} carries {cls.__name__}, not {type(message).__name__}")
        log_time = self.log_time_ns(t)
        self._writer.add_message(
            channel_id=channel_id,
            log_time=log_time,
            data=message.model_dump_json().encode(),
            publish_time=log_time,
        )
        if topic == "/gait_state":
            self.samples += 1
            if self._first_t is None:
                self._first_t = t
            self.duration_s = t - self._first_t

    def write_event(self, event: schema.Event) -> None:
        """Write ``event`` on ``/events`` as a ``foxglove.Event`` at its ``t``.

        Its fields become the metadata key/values (absent ones left out), so Foxglove lists them and
        :func:`~sessions.mcap_io.read_events` gives them back.
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
        """Write the index (summary and footer), sync the file to disk and close it; idempotent."""
        if self._finished:
            return
        self._finished = True
        try:
            self._writer.finish()
            self._file.flush()
            os.fsync(self._file.fileno())
        finally:
            self._file.close()

    def __enter__(self) -> Recorder:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        # Finish even on an error: what was recorded is good, and an indexed file needs no recovery.
        self.finish()
