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
import math
import time
from collections.abc import AsyncIterator, Sequence
from pathlib import Path
from typing import Protocol

import numpy as np
import pandas as pd

from sessions import schema
from sessions.schema import SensorFrame


class FrameSource(Protocol):
    """What a session runtime consumes."""

    rate_hz: float | None

    def frames(self) -> AsyncIterator[SensorFrame]: ...


def frames_from_table(table: pd.DataFrame) -> list[SensorFrame]:
    """Sensor frames from a replay-CSV-like table (``time_s``, replay signals, optional extras)."""
    cols = [c for c in (*schema.REPLAY_SIGNALS, "thigh_angle_deg") if c in table.columns]
    t = table[schema.REPLAY_TIME].to_numpy(np.float64)
    values = {c: table[c].to_numpy(np.float64) for c in cols}
    hs = table[schema.REPLAY_HEEL_STRIKE].to_numpy() if schema.REPLAY_HEEL_STRIKE in table.columns else None
    out = []
    for k in range(len(t)):
        fields: dict[str, object] = {c: float(v[k]) for c, v in values.items() if math.isfinite(v[k])}
        fields.update(seq=k, t=float(t[k]), heel_strike=None if hs is None else bool(hs[k] > 0.5))
        out.append(SensorFrame.model_validate(fields))
    return out


async def _paced(frames: Sequence[SensorFrame], speed: float, loop: bool) -> AsyncIterator[SensorFrame]:
    """Yield ``frames`` at ``speed`` x real time (their ``t`` shifted to continue across loops)."""
    if not frames:
        return
    clock = asyncio.get_running_loop().time
    span = frames[-1].t - frames[0].t
    period = span / max(len(frames) - 1, 1)
    offset, seq = 0.0, 0
    t0 = frames[0].t
    start = clock()
    while True:
        for f in frames:
            t = f.t - t0 + offset
            due = start + t / speed
            delay = due - clock()
            if delay > 0:
                await asyncio.sleep(delay)
            sent = time.time_ns()
            yield f.model_copy(update={"seq": seq, "t": t, "sent_ns": sent})
            seq += 1
        if not loop:
            return
        offset += span + period


class SimulatedDevice:
    """A virtual subject on a treadmill (``SimulatedSource``), with simulated sensor noise.

    The walk is generated once (deterministic from the spec's seed) and looped if asked.
    """

    def __init__(self, spec: schema.SimulatedSource):
        self.spec = spec
        self.rate_hz: float | None = spec.rate_hz
        self._frames: list[SensorFrame] | None = None

    def _generate(self) -> list[SensorFrame]:
        from sessions.trials import sensor_trial

        schedule = [(p.speed_m_s, p.incline_deg, p.strides) for p in self.spec.protocol]
        sensors, _, _ = sensor_trial(
            schedule, subject=self.spec.cohort_subject, rate_hz=self.spec.rate_hz, seed=self.spec.seed
        )
        return frames_from_table(sensors)

    async def frames(self) -> AsyncIterator[SensorFrame]:
        if self._frames is None:
            self._frames = await asyncio.to_thread(self._generate)
        async for f in _paced(self._frames, 1.0, self.spec.loop):
            yield f

    def subject_body(self) -> tuple[float, float]:
        """Leg length (m) and mass (kg) of the virtual subject walking."""
        from sessions.cohort import CohortSpec, make_subjects

        subj = make_subjects(CohortSpec())[self.spec.cohort_subject]
        return subj.leg_length_m, subj.mass_kg


class ReplayDevice:
    """A stored trial (its ``/sensor`` channel) played back at ``speed`` x real time."""

    def __init__(self, path: Path, speed: float = 1.0, loop: bool = False):
        self.path = path
        self.speed = speed
        self.loop = loop
        self.rate_hz: float | None = None

    async def frames(self) -> AsyncIterator[SensorFrame]:
        from sessions.recording import read_sensor_frames

        frames = await asyncio.to_thread(read_sensor_frames, self.path)
        if len(frames) > 1:
            self.rate_hz = (len(frames) - 1) / (frames[-1].t - frames[0].t) * self.speed
        async for f in _paced(frames, self.speed, self.loop):
            yield f


class LiveDevice:
    """Frames pushed by a device; bounded queue so a flood cannot exhaust memory.

    Attributes:
        dropped: frames refused because the queue was full or their time did not increase.
    """

    def __init__(self, capacity: int = 2000):
        self.rate_hz: float | None = None
        self._queue: asyncio.Queue[SensorFrame | None] = asyncio.Queue(maxsize=capacity)
        self._last_t = -math.inf
        self.dropped = 0
        self.connected = False

    def push(self, frame: SensorFrame) -> bool:
        """Offer a frame from the device; False (and counted) if out of order or the queue is full."""
        if not frame.t > self._last_t:
            self.dropped += 1
            return False
        try:
            self._queue.put_nowait(frame)
        except asyncio.QueueFull:
            self.dropped += 1
            return False
        self._last_t = frame.t
        return True

    def close(self) -> None:
        """End the stream (the session is stopping)."""
        try:
            self._queue.put_nowait(None)
        except asyncio.QueueFull:
            pass

    async def frames(self) -> AsyncIterator[SensorFrame]:
        while True:
            f = await self._queue.get()
            if f is None:
                return
            yield f
