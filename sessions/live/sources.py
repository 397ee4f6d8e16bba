"""Where a session's sensor frames come from: one interface, three kinds.

- :class:`SimulatedDevice`: a virtual-cohort subject walking a protocol (seed 000 III-E by default)
  through simulated sensors, paced in real time; runs without hardware (offline mode).
- :class:`ReplayDevice`: a stored trial's sensor frames played back at 1x or faster.
- :class:`LiveDevice`: frames pushed by a device over ``/ws/devices/{id}``; the device keeps its own
  clock and receives torque commands back.

Every source is an async iterator of :class:`~sessions.schema.SensorFrame` whose ``t`` increases;
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
from typing import Protocol

import numpy as np
import pandas as pd

from sessions import schema
from sessions.schema import SensorFrame


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

    Columns named as channels of :data:`~sessions.schema.CHANNELS` are carried (flags as 0/1 or bool),
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
    :data:`~sessions.schema.CHANNELS` (the replay signals, ``heel_strike``, schema version 2's others)."""
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
        from sessions.synth.trials import sensor_trial

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
        from sessions.synth.cohort import CohortSpec, make_subjects

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
        from sessions.errors import DataFormatError
        from sessions.formats.mcap_io import iter_sensor_frames
        from sessions.registry import channels_of

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
        from sessions.formats.mcap_io import iter_sensor_frames

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


class LiveDevice:
    """Frames pushed by a device over its websocket, limited to its declared rate.

    The websocket handler processes each frame it admits at once (the torque reply goes back on the
    same socket); :meth:`admit` is a token bucket that lets through ``headroom x rate_hz`` frames per
    second with a burst of ``burst_s`` seconds' worth (frames a network stall delayed arrive together
    and must not be dropped), so that a device flooding the server costs it a counter increment per
    excess frame rather than a filter step, and cannot starve other sessions.

    Attributes:
        rate_hz: the declared rate (Hz).
        dropped: frames dropped over the rate.
        connected: a device is connected now (one at a time).
        revoked: ids of device tokens revoked while the session runs; a device connected with one of
            them is disconnected at its next frame.
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
