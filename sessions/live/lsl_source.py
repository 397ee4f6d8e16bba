"""A Lab Streaming Layer stream as a session's source (:class:`~gaitscope.sessions.schema.LslSource`).

Labs stream IMUs, EMG and motion capture with LSL (``pylsl``, which bundles ``liblsl``). :func:`open_stream`
resolves the stream on the local network (by name and/or type, and source id), opens an inlet, reads its
full description (channel labels) and maps its channels to gaitscope's (:func:`channel_map`); it blocks for up
to the source's timeout, so the manager calls it in a worker thread before the session starts. The session
then reads the stream through :class:`LslDevice`, whose worker thread pulls chunks (``pull_chunk`` with
``min_samples=1``: a sample is handed over as soon as it arrives) and hands them to the event loop, which
never waits on the inlet.

Time: a sample's LSL timestamp is the sender's clock; ``time_correction()`` (re-read once a second, liblsl
keeps it up to date) maps it to this machine's LSL clock, and frame time is that, from 0 at the first sample.
A stream that goes quiet (no sample for the source's ``quiet_s``) holds the session as a disconnected device
does: the inlet recovers the stream when its sender comes back, and :class:`LslWatch` says both in the
session's events.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import hashlib
import json
import logging
import math
import threading
import time
from collections.abc import AsyncIterator, Callable
from typing import TYPE_CHECKING, Any, Final

import numpy as np
from numpy.typing import NDArray

from gaitscope.sessions import schema
from gaitscope.sessions.live.extensions import SessionExtension
from gaitscope.sessions.schema import SensorFrame

if TYPE_CHECKING:
    from gaitscope.sessions.live.runtime import SessionRuntime

__all__ = ["LslDevice", "LslRefused", "LslWatch", "channel_map", "open_stream", "rig_of", "stream_query"]

log = logging.getLogger("gaitscope")

#: Seconds a pull waits for a sample before the worker looks at its stop flag and the quiet timer.
PULL_S: Final = 0.1
#: Samples handed over at most per pull.
MAX_CHUNK: Final = 1024
#: Seconds between two readings of the clock offset (liblsl refreshes it every few seconds).
CORRECTION_S: Final = 1.0


class LslRefused(ValueError):
    """The stream cannot be a session's source: not found, or its channels do not fit the mapping."""


def stream_query(spec: schema.LslSource) -> str:
    """The XPath predicate of ``resolve_bypred`` for the source's name, type and source id (no quotes in them:
    the schema refuses those)."""
    parts = [f"{k}='{v}'" for k, v in (("name", spec.name), ("type", spec.type), ("source_id", spec.source_id)) if v]
    return " and ".join(parts)


def _described(spec: schema.LslSource) -> str:
    """The stream as the user named it, for errors and events."""
    parts = [f"{k} {v!r}" for k, v in (("name", spec.name), ("type", spec.type), ("source id", spec.source_id)) if v]
    return "LSL stream " + ", ".join(parts)


def rig_of(name: str, type_: str, channel_count: int, source_id: str) -> str:
    """The rig of a stream: ``lsl-`` and a hash (16 hex digits) of its name, type, channel count and source id,
    the key its channel mapping is saved under (:class:`~gaitscope.sessions.mappings.saved.SavedMappings`)."""
    text = json.dumps([name, type_, channel_count, source_id])
    return "lsl-" + hashlib.sha256(text.encode()).hexdigest()[:16]


def labels_of(info: Any) -> list[str]:
    """The channel labels of a stream's full description (``<channels><channel><label>``); "" for a channel
    without one, [] when the description has none."""
    labels = []
    channel = info.desc().child("channels").child("channel")
    while not channel.empty():
        labels.append(channel.child_value("label"))
        channel = channel.next_sibling("channel")
    return labels


def channel_map(mapping: dict[str, str], count: int, labels: list[str]) -> list[tuple[int, str]]:
    """``mapping``'s (stream channel index, SensorFrame channel) pairs, in stream order.

    A key of digits is an index from 0; any other key a label of the stream's description.

    Raises:
        LslRefused: an index beyond the stream's channels, a label it does not have, one channel mapped twice.
    """
    pairs: dict[int, str] = {}
    for key, channel in mapping.items():
        if key.isdigit():
            index = int(key)
            if index >= count:
                raise LslRefused(f"stream channel {key} mapped to {channel}, but the stream has {count} channels")
        elif key in labels:
            index = labels.index(key)
        else:
            known = ", ".join(repr(x) for x in labels[:12] if x) or "none"
            raise LslRefused(f"stream channel {key!r} mapped to {channel} is not a label of the stream (its: {known})")
        if index in pairs:
            raise LslRefused(f"stream channel {index} is mapped twice ({pairs[index]} and {channel})")
        pairs[index] = channel
    return sorted(pairs.items())


def open_stream(
    spec: schema.LslSource, saved: Callable[[str], schema.SavedMapping | None] = lambda rig: None
) -> LslDevice:
    """Resolve the source's stream, open an inlet on it and map its channels; blocks up to about twice
    ``spec.resolve_timeout_s`` (resolving, then the inlet's description and clock offset).

    Args:
        spec: the session's source.
        saved: the mapping saved for a rig (``SavedMappings.get``), used when ``spec.mapping`` is null.

    Raises:
        LslRefused: no such stream within the timeout (the message names it), a stream of text (markers) or
            faster than :data:`~gaitscope.sessions.schema.MAX_DEVICE_RATE_HZ`, no mapping given or saved, or a
            mapping that does not fit its channels.
    """
    import pylsl

    what = _described(spec)
    found = pylsl.resolve_bypred(stream_query(spec), 1, spec.resolve_timeout_s)
    if not found:
        raise LslRefused(f"{what} not found on the network within {spec.resolve_timeout_s:g} s")
    inlet = pylsl.StreamInlet(found[0], max_buflen=30, recover=True, as_numpy=True)
    try:
        try:
            info = inlet.info(spec.resolve_timeout_s)
            inlet.open_stream(spec.resolve_timeout_s)
            correction = inlet.time_correction(spec.resolve_timeout_s)
        except (TimeoutError, pylsl.util.LostError) as e:
            raise LslRefused(f"{what} was found but did not answer within {spec.resolve_timeout_s:g} s") from e
        name, type_, count, rate = info.name(), info.type(), info.channel_count(), info.nominal_srate()
        rig = rig_of(name, type_, count, info.source_id())
        if info.channel_format() == pylsl.cf_string:
            raise LslRefused(f"{what} carries text (markers), not numbers")
        if rate > schema.MAX_DEVICE_RATE_HZ:
            raise LslRefused(f"{what} samples at {rate:g} Hz; a source may send at most {schema.MAX_DEVICE_RATE_HZ:g}")
        mapping = spec.mapping
        if mapping is None:
            kept = saved(rig)
            if kept is None:
                raise LslRefused(f"{what} (rig {rig}) has no channel mapping: none given and none saved for its rig")
            mapping = json.loads(kept.mapping)
            schema.LslSource.model_validate({**spec.model_dump(), "mapping": mapping})  # still gaitscope's channels
        pairs = channel_map(mapping, count, labels_of(info))
    except BaseException:
        inlet.close_stream()
        raise
    return LslDevice(inlet, pairs, rate or None, correction, spec, rig, mapping)


class LslDevice:
    """Frames from an open LSL inlet (:func:`open_stream` makes it).

    Attributes:
        rate_hz: the stream's nominal rate (None: irregular).
        channels: the SensorFrame channels its frames carry (the mapping's).
        rig: the stream's rig (:func:`rig_of`); mapping: the mapping in use (stream channel -> channel).
        origin: this machine's LSL time (s) of frame time 0 (None before the first sample).
        quiet: the stream has sent nothing for the source's ``quiet_s`` (the session holds).
        notices: what happened to the stream, for the session's events (:class:`LslWatch` takes them).
    """

    def __init__(
        self,
        inlet: Any,
        pairs: list[tuple[int, str]],
        rate_hz: float | None,
        correction: float,
        spec: schema.LslSource,
        rig: str,
        mapping: dict[str, str],
    ):
        self.inlet, self.spec, self.rig, self.mapping = inlet, spec, rig, mapping
        self.rate_hz: float | None = rate_hz
        self.channels: frozenset[str] | None = frozenset(c for _, c in pairs)
        self._index = np.array([i for i, _ in pairs], dtype=np.intp)
        self._names = [c for _, c in pairs]
        self._flags = [schema.CHANNELS[c].unit == "bool" for c in self._names]
        self.correction = correction
        self.origin: float | None = None
        self.quiet = False
        self.notices: collections.deque[str] = collections.deque(maxlen=32)
        self._stop = threading.Event()
        self._worker: threading.Thread | None = None
        self._seq = 0
        self._last_t = -math.inf

    def close(self) -> None:
        """Stop pulling; the worker thread closes the inlet (an inlet never read is closed here)."""
        self._stop.set()
        if self._worker is None:
            with contextlib.suppress(Exception):
                self.inlet.close_stream()

    async def frames(self) -> AsyncIterator[SensorFrame]:
        loop = asyncio.get_running_loop()
        chunks: asyncio.Queue[tuple[NDArray[np.float64], NDArray[np.float64], float]] = asyncio.Queue()
        self._worker = worker = threading.Thread(target=self._pull, args=(loop, chunks), name="lsl-inlet", daemon=True)
        worker.start()
        try:
            while True:
                values, stamps, correction = await chunks.get()
                for row, stamp in zip(values, stamps.tolist(), strict=True):
                    yield self._frame(row, stamp + correction)
        finally:
            self._stop.set()
            with contextlib.suppress(BaseException):  # the inlet closed before the session says it stopped
                await asyncio.to_thread(worker.join, 2 * PULL_S + 1.0)

    def _frame(self, row: NDArray[np.float64], local: float) -> SensorFrame:
        """The frame of one sample at this machine's LSL time ``local``."""
        from pylsl import local_clock

        if self.origin is None:
            self.origin = local
        t = local - self.origin
        if t <= self._last_t:  # samples of one chunk stamped alike (an irregular stream), or a sender restarted
            t = self._last_t + (1.0 / self.rate_hz if self.rate_hz else 1e-6)
        self._last_t = t
        fields: dict[str, object] = {}
        for name, flag, v in zip(self._names, self._flags, row[self._index].tolist(), strict=True):
            if math.isfinite(v):
                fields[name] = v > 0.5 if flag else v
        sent_ns = time.time_ns() - int(max(0.0, local_clock() - local) * 1e9)  # the sender's time, on our clocks
        fields.update(seq=self._seq, t=t, sent_ns=sent_ns)
        self._seq += 1
        return SensorFrame.model_validate(fields)

    def _pull(self, loop: asyncio.AbstractEventLoop, chunks: asyncio.Queue[Any]) -> None:
        """The worker thread: pull chunks until stopped, hand them to the loop, watch for a quiet stream."""
        inlet, what = self.inlet, _described(self.spec)
        last = time.monotonic()
        corrected = last
        try:
            while not self._stop.is_set():
                values, stamps = inlet.pull_chunk(timeout=PULL_S, max_samples=MAX_CHUNK, min_samples=1)
                now = time.monotonic()
                if len(stamps) == 0:
                    if not self.quiet and now - last >= self.spec.quiet_s:
                        self.quiet = True
                        self.notices.append(f"{what} went quiet (no sample for {self.spec.quiet_s:g} s): the "
                                            "session holds until it resumes")  # fmt: skip
                    continue
                if self.quiet:
                    self.quiet = False
                    self.notices.append(f"{what} resumed after {now - last:.1f} s")
                last = now
                if now - corrected >= CORRECTION_S:
                    with contextlib.suppress(Exception):  # keep the last offset
                        self.correction = inlet.time_correction(0.0)
                    corrected = now
                chunk = (np.asarray(values, dtype=np.float64), np.asarray(stamps, dtype=np.float64), self.correction)
                loop.call_soon_threadsafe(chunks.put_nowait, chunk)
        except Exception as e:  # the loop closed (server stopping), or liblsl failed: the session holds
            if not self._stop.is_set():
                log.error("%s: reading it failed: %s", what, e)
                self.notices.append(f"{what}: reading it failed ({e}); restart the session")
        finally:
            with contextlib.suppress(Exception):
                inlet.close_stream()

    def lsl_time(self, t: float) -> float | None:
        """This machine's LSL time of frame time ``t`` (None before the first sample)."""
        return None if self.origin is None else self.origin + t


class LslWatch(SessionExtension):
    """Says in the session's events when its LSL stream goes quiet and when it resumes (checked once a second)."""

    def __init__(self, host: SessionRuntime, source: LslDevice):
        self.host, self.source = host, source

    @classmethod
    def of(cls, host: SessionRuntime) -> LslWatch | None:
        return cls(host, host.source) if isinstance(host.source, LslDevice) else None

    def on_tick(self) -> None:
        while self.source.notices:
            self.host.event_soon("system", self.source.notices.popleft())

    async def stop(self) -> None:
        self.source.close()
