"""Where a session's sensor frames come from: one interface, three kinds.

- :class:`SimulatedDevice`: a virtual-cohort subject walking a protocol (seed 000 III-E by default)
  through simulated sensors, paced in real time; runs without hardware (offline mode).
- :class:`ReplayDevice`: a stored trial's sensor frames played back at 1x or faster.
- :class:`LiveDevice`: frames pushed by a device over ``/ws/devices/{id}``; the device keeps its own
  clock and receives torque commands back. It is held to its declared rate and to its share of the
  event loop (:class:`DeviceBudget`); :func:`frame_refusal` and :func:`invalid_notice` make the short
  notices for what it sends that is not a frame.

Every source is an async iterator of :class:`~gaitscope.sessions.schema.SensorFrame` whose ``t`` increases;
pacing uses the event loop's monotonic clock against each frame's due time, so a late wake-up catches
up (the frames already due go out at once) instead of drifting.
"""

from __future__ import annotations

import asyncio
import itertools
import math
import time
from collections.abc import AsyncIterator, Callable, Collection
from pathlib import Path
from typing import Final, Protocol

import numpy as np
import pandas as pd
from pydantic import ValidationError

from gaitscope.sessions import schema
from gaitscope.sessions.schema import SensorFrame


class FrameSource(Protocol):
    """What a session runtime consumes.

    A source may also say which channels its frames carry (``channels``, ``SensorFrame`` field names),
    so that the session's estimator stack is checked against them before it starts; without it (a live
    device, which declares none) every estimator may run and a channel that never comes stays missing.
    """

    rate_hz: float | None

    def frames(self) -> AsyncIterator[SensorFrame]: ...


class FrameTable:
    """The sensor frames of a replay-CSV-like table, made one at a time (:meth:`frame`).

    Columns named as channels of :data:`~gaitscope.sessions.schema.CHANNELS` are carried (flags as 0/1 or bool),
    other columns ignored; a non-finite value is an absent channel. The values are kept as one array: a
    fraction of the memory of a list of frames that carry every channel.
    """

    def __init__(self, table: pd.DataFrame):
        self.names = [c for c in schema.CHANNELS if c in table.columns]
        self.flags = frozenset(c for c in self.names if schema.CHANNELS[c].unit == "bool")
        self.t = table[schema.REPLAY_TIME].to_numpy(np.float64)
        self.values = table[self.names].to_numpy(np.float64)

    def __len__(self) -> int:
        return len(self.t)

    def frame(self, k: int) -> SensorFrame:
        """Frame ``k``, with ``seq=k``."""
        fields: dict[str, object] = {
            name: (v > 0.5 if name in self.flags else v)
            for name, v in zip(self.names, self.values[k].tolist(), strict=True)
            if math.isfinite(v)
        }
        fields.update(seq=k, t=float(self.t[k]))
        return SensorFrame.model_validate(fields)


def frames_from_table(table: pd.DataFrame) -> list[SensorFrame]:
    """Sensor frames from a replay-CSV-like table: ``time_s`` and any channels of
    :data:`~gaitscope.sessions.schema.CHANNELS` (the replay signals, ``heel_strike``, schema version 2's others)."""
    rows = FrameTable(table)
    return [rows.frame(k) for k in range(len(rows))]


async def _paced(
    passes: Callable[[], AsyncIterator[SensorFrame]], speed: float, loop: bool
) -> AsyncIterator[SensorFrame]:
    """Yield the frames of ``passes()`` at ``speed`` x real time, again and again if ``loop``.

    Times restart at 0 and continue across passes (one sample period apart), ``seq`` keeps counting,
    and each frame is stamped with its send time (``sent_ns``).
    """
    clock = asyncio.get_running_loop().time
    start = clock()
    offset, seq = 0.0, 0
    while True:
        t0: float | None = None
        last_t, period = 0.0, 0.0
        async for f in passes():
            if t0 is None:
                t0 = f.t
            t = f.t - t0 + offset
            period = t - last_t if t > last_t else period
            last_t = t
            delay = start + t / speed - clock()
            if delay > 0:
                await asyncio.sleep(delay)
            yield f.model_copy(update={"seq": seq, "t": t, "sent_ns": time.time_ns()})
            seq += 1
        if not loop or t0 is None:
            return
        offset = last_t + period


async def _from_table(rows: FrameTable) -> AsyncIterator[SensorFrame]:
    for k in range(len(rows)):
        yield rows.frame(k)


class SimulatedDevice:
    """A virtual subject on a treadmill (``SimulatedSource``), with simulated sensor noise.

    The walk is generated once (deterministic from the spec's seed) and looped if asked; its frames
    (every channel of the sensor frame) are made as they are sent.
    """

    def __init__(self, spec: schema.SimulatedSource):
        self.spec = spec
        self.rate_hz: float | None = spec.rate_hz
        #: The simulated sensors send every channel (the true heel strikes included).
        self.channels: frozenset[str] | None = frozenset(schema.CHANNELS)
        self._rows: FrameTable | None = None

    def _generate(self) -> FrameTable:
        from gaitscope.sessions.synth.trials import sensor_trial

        schedule = [(p.speed_m_s, p.incline_deg, p.strides) for p in self.spec.protocol]
        sensors, _, _ = sensor_trial(
            schedule, subject=self.spec.cohort_subject, rate_hz=self.spec.rate_hz, seed=self.spec.seed
        )
        return FrameTable(sensors)

    async def frames(self) -> AsyncIterator[SensorFrame]:
        if self._rows is None:
            self._rows = await asyncio.to_thread(self._generate)
        rows = self._rows
        async for f in _paced(lambda: _from_table(rows), 1.0, self.spec.loop):
            yield f

    def subject_body(self) -> tuple[float, float]:
        """Leg length (m) and mass (kg) of the virtual subject walking."""
        from gaitscope.sessions.synth.cohort import CohortSpec, make_subjects

        subj = make_subjects(CohortSpec())[self.spec.cohort_subject]
        return subj.leg_length_m, subj.mass_kg


class ReplayDevice:
    """A stored trial (its ``/sensor`` channel) played back at ``speed`` x real time.

    Frames are read lazily in batches on a worker thread, so a long trial never sits in memory whole
    and the event loop never waits on the disk.
    """

    BATCH = 2000

    #: Frames read at construction to learn the trial's channels.
    PROBE = 200

    def __init__(self, path: Path, speed: float = 1.0, loop: bool = False):
        from gaitscope.sessions.errors import DataFormatError
        from gaitscope.sessions.formats.mcap_io import iter_sensor_frames
        from gaitscope.sessions.registry import channels_of

        self.path = path
        self.speed = speed
        self.loop = loop
        self.rate_hz: float | None = None
        # The channels of the trial's first frames, for the session's estimator stack. A file that cannot
        # be read says nothing here (None: every estimator may run): playing it fails the session, as
        # it always did, with an event saying why.
        self.channels: frozenset[str] | None = None
        probe = iter_sensor_frames(path)
        try:
            self.channels = frozenset(channels_of(f for _, f in itertools.islice(probe, self.PROBE)))
        except (DataFormatError, OSError):
            pass
        finally:
            getattr(probe, "close", lambda: None)()  # a generator: close its file now

    async def _read(self) -> AsyncIterator[SensorFrame]:
        from gaitscope.sessions.formats.mcap_io import iter_sensor_frames

        frames = iter_sensor_frames(self.path)
        while True:
            batch = await asyncio.to_thread(lambda: [f for _, f in itertools.islice(frames, self.BATCH)])
            if not batch:
                return
            if self.rate_hz is None and len(batch) > 1 and batch[-1].t > batch[0].t:
                self.rate_hz = (len(batch) - 1) / (batch[-1].t - batch[0].t) * self.speed
            for f in batch:
                yield f

    async def frames(self) -> AsyncIterator[SensorFrame]:
        async for f in _paced(self._read, self.speed, self.loop):
            yield f


class DeviceBudget:
    """A device's share of the event loop: the time its messages take there, from receipt to reply.

    The websocket handler charges each message's work (:meth:`charge`: the CPU time of the loop's
    thread, ``time.thread_time``, so that other processes on a busy machine do not count against the
    device) against a credit that refills at ``share`` seconds per second of ``clock``, up to
    ``burst_s`` seconds' worth. Before reading the next message it asks :meth:`pause`:

    - while the credit is spent, how long until it is earned back: the device's socket is not read
      meanwhile, so TCP holds the device back and what it sends costs the server nothing;
    - after each ``slice_s`` of work, 0 (a turn of the loop): many frames that arrive in one read cannot
      keep the other sessions waiting for more than a slice;
    - otherwise None: read on.

    A device held back for ``close_after_s`` without a break (its credit back to half the burst), most
    of that time's work on messages that were refused (dropped over its rate, malformed, too large, out
    of order), keeps sending what it should not (:attr:`exhausted`): the handler disconnects it. One whose
    frames are valid but costly is only held back (it is read late), never disconnected for it.
    ``clock`` (monotonic seconds) is injected for tests.

    Attributes:
        share: seconds of work per second the device may take.
        used: seconds of work charged in all.
    """

    def __init__(
        self,
        share: float,
        burst_s: float = 1.0,
        slice_s: float = 0.001,
        close_after_s: float = 5.0,
        clock: Callable[[], float] = time.monotonic,
    ):
        if not (0 < share <= 1 and burst_s > 0 and slice_s > 0 and close_after_s > 0):
            raise ValueError(f"a budget needs 0 < share <= 1 and positive times, got share={share}")
        self.share = share
        self.slice_s = slice_s
        self.close_after_s = close_after_s
        self._clock = clock
        self._capacity = share * burst_s
        self._credit = self._capacity
        self._last = clock()
        self._slice = 0.0
        self._over_since: float | None = None
        self._over_work = self._over_wasted = 0.0  # work since the device was first held back, and refused
        self.used = 0.0

    def _refill(self) -> float:
        now = self._clock()
        self._credit = min(self._capacity, self._credit + (now - self._last) * self.share)
        self._last = now
        return now

    def charge(self, seconds: float, refused: bool = False) -> None:
        """Count ``seconds`` of work on the loop (one message's; ``refused``: the message was)."""
        self._refill()
        self._credit -= seconds
        self._slice += seconds
        self.used += seconds
        if self._credit >= self._capacity / 2:  # a break: back to half its burst (hovering near 0 is no break)
            self._over_since = None
            self._over_work = self._over_wasted = 0.0
        elif self._over_since is not None:
            self._over_work += seconds
            self._over_wasted += seconds if refused else 0.0

    def pause(self) -> float | None:
        """Seconds to give the loop before the next message is read (0: a turn), or None to read on."""
        now = self._refill()
        if self._credit < 0:
            if self._over_since is None:
                self._over_since = now
            self._slice = 0.0
            return -self._credit / self.share
        if self._slice >= self.slice_s:
            self._slice = 0.0
            return 0.0
        return None

    @property
    def exhausted(self) -> bool:
        """Held back for ``close_after_s`` without a break, mostly for messages that were refused."""
        if self._over_since is None or self._clock() - self._over_since < self.close_after_s:
            return False
        return self._over_wasted >= 0.5 * self._over_work


#: Seconds of the event loop a device may take per admitted frame (its share is that times the frames
#: per second it may send): a frame of every channel takes about 0.4 ms from parse to reply with the
#: default estimators on a busy 2-core machine, so 1 ms leaves room for heavier stacks.
FRAME_WORK_S: Final = 0.001
#: A device's share of the loop, whatever its rate: at least 5 % (a slow device's invalid frames cost
#: more than its valid ones), at most half (1 kHz of frames of every channel fit; two such devices are
#: the most one server process hosts).
SHARE_RANGE: Final = (0.05, 0.5)
#: Work charged per message on top of what the handler measures: reading it off the socket (the websocket
#: parser's 5-8 us a message, measured with ``websockets`` 16, and the handoff to the handler).
RECEIVE_S: Final = 10e-6
#: Work charged per connection, which happens before the handler can measure it: the HTTP upgrade, the
#: token's look-up and the handshake (about 3 ms, measured as a device reconnecting 50 times a second).
CONNECT_S: Final = 0.003


def frame_refusal(text: str) -> schema.DeviceNotice | None:
    """A ``too_large`` notice for a frame's text that is not worth parsing, else None.

    Longer than :data:`~gaitscope.sessions.schema.MAX_FRAME_BYTES`, or with more keys than a frame has
    (:data:`~gaitscope.sessions.schema.MAX_FRAME_KEYS`; counted by its colons, which a frame has one per key):
    both are checked in microseconds, where parsing 500,000 unknown keys took seconds.
    """
    if len(text) > schema.MAX_FRAME_BYTES:
        detail = f"frame of {len(text)} characters, over the limit of {schema.MAX_FRAME_BYTES}: refused unread"
        return schema.DeviceNotice(kind="too_large", detail=detail)
    keys = text.count(":")
    if keys > schema.MAX_FRAME_KEYS:
        detail = f"frame of about {keys} keys, more than a frame's {schema.MAX_FRAME_KEYS}: refused unread"
        return schema.DeviceNotice(kind="too_large", detail=detail)
    return None


def invalid_notice(e: ValidationError) -> schema.DeviceNotice:
    """An ``invalid`` notice for a frame that failed validation: its first few errors (where and what,
    never the input, which may be long and may hold NaN, which JSON cannot carry) and how many there were."""
    errors = [
        {
            "loc": [x[:40] if isinstance(x, str) else x for x in err["loc"]],  # an unknown key's name is the device's
            "msg": err["msg"][:200],
            "type": err["type"],
        }
        for err in e.errors(include_url=False, include_input=False, include_context=False)[: schema.MAX_NOTICE_ERRORS]
    ]
    return schema.DeviceNotice(kind="invalid", detail=errors, errors=e.error_count())


class LiveDevice:
    """Frames pushed by a device over its websocket, limited to its declared rate and its share of the loop.

    The websocket handler processes each frame it admits at once (the torque reply goes back on the
    same socket); :meth:`admit` is a token bucket that lets through ``headroom x rate_hz`` frames per
    second with a burst of ``burst_s`` seconds' worth (frames a network stall delayed arrive together
    and must not be dropped), so that a device flooding the server costs it a counter increment per
    excess frame rather than a filter step, and cannot starve other sessions. What the device's messages
    cost all the same (reading them, refusing them, processing them) is held to its :attr:`budget`:
    :data:`FRAME_WORK_S` per frame it may send, within :data:`SHARE_RANGE` of the loop. The budget is the
    session's, not the connection's: reconnecting does not renew it.

    Attributes:
        rate_hz: the declared rate (Hz).
        dropped: frames dropped over the rate.
        connected: a device is connected now (one at a time).
        revoked: ids of device tokens revoked while the session runs; a device connected with one of
            them is disconnected at its next frame.
        budget: the device's share of the event loop.
    """

    def __init__(
        self,
        rate_hz: float = 200.0,
        headroom: float = 1.25,
        burst_s: float = 2.0,
        channels: Collection[str] | None = None,
    ):
        if not (math.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"rate_hz must be a positive number, got {rate_hz}")
        self.rate_hz: float | None = rate_hz
        # the channels the device declared (its session's stack is chosen for them); None: every estimator
        # may run, on whatever arrives
        self.channels: frozenset[str] | None = None if channels is None else frozenset(channels)
        self._fill = rate_hz * headroom
        self._capacity = max(1.0, self._fill * burst_s)
        low, high = SHARE_RANGE
        self.budget = DeviceBudget(min(high, max(low, self._fill * FRAME_WORK_S)))
        self._tokens = self._capacity
        self._last = time.monotonic()
        self._closed = asyncio.Event()
        self.dropped = 0
        self.connected = False
        self.revoked: set[int] = set()

    def admit(self, now: float | None = None) -> bool:
        """Take one frame's token at monotonic time ``now``; False (and counted) when over the rate."""
        now = time.monotonic() if now is None else now
        self._tokens = min(self._capacity, self._tokens + (now - self._last) * self._fill)
        self._last = now
        if self._tokens >= 1.0:
            self._tokens -= 1.0
            return True
        self.dropped += 1
        return False

    def close(self) -> None:
        """End the stream (the session is stopping)."""
        self._closed.set()

    @property
    def closed(self) -> bool:
        return self._closed.is_set()

    async def frames(self) -> AsyncIterator[SensorFrame]:
        """Yields nothing: frames arrive through the websocket handler; ends when closed."""
        await self._closed.wait()
        return
        yield  # an async generator
