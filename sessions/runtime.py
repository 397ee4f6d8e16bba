"""A running session: source -> estimator pipeline -> recording and subscribers.

One :class:`SessionRuntime` per running session, driven by one asyncio task on the server's loop.
Each sensor frame is processed synchronously (pipeline step, MCAP record, fan-out), so anything else
that runs on the loop (a settings change, an annotation, a recording toggle) happens *between* two
samples: a change takes effect at the next sample, and its event carries the time of the last sample
processed before it. Subscribers never slow the pipeline: each has a bounded buffer that drops its
oldest entries (counted) when the client does not keep up.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from estimators.pipeline import TrainedModel
from sessions import schema
from sessions.estimation import DEFAULT_PERIOD, FrameEstimator
from sessions.recording import Recorder
from sessions.schema import GaitState, SensorFrame, SessionSettings, SettingsChange
from sessions.sources import FrameSource, LiveDevice
from sessions.store import Store

#: Samples a subscriber may have waiting before its oldest are dropped (about 5 s at 200 Hz).
SUBSCRIBER_CAPACITY = 1000


class SettingRejected(ValueError):
    """A settings change that breaks a rate-of-change limit; the message says which and why."""


@dataclass(eq=False)
class Subscriber:
    """One browser's view of a session's stream.

    Attributes:
        decimation: every n-th sample is kept.
        pending: samples not yet sent (bounded; the oldest go first when it is full).
        dropped: samples lost because the client was too slow.
    """

    decimation: int
    pending: deque[GaitState] = field(default_factory=lambda: deque(maxlen=SUBSCRIBER_CAPACITY))
    messages: deque[schema.BaseModel] = field(default_factory=lambda: deque(maxlen=100))
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    dropped: int = 0
    closed: bool = False
    _count: int = 0
    _carry_hs: bool = False

    def offer(self, state: GaitState) -> None:
        self._count += 1
        if (self._count - 1) % self.decimation:
            self._carry_hs = self._carry_hs or state.heel_strike
            return
        if self._carry_hs and not state.heel_strike:
            state = state.model_copy(update={"heel_strike": True})
        self._carry_hs = False
        if len(self.pending) == self.pending.maxlen:
            self.dropped += 1
        self.pending.append(state)
        self.wake.set()

    def close(self) -> None:
        """The session ended: the stream sends what it has, then closes."""
        self.closed = True
        self.wake.set()

    def notify(self, message: schema.BaseModel) -> None:
        self.messages.append(message)
        self.wake.set()


class SessionRuntime:
    """Runs one session.

    Args:
        session: the stored session.
        subject: its subject (leg length and mass parameterise the pipeline).
        model: the trained models.
        source: where frames come from.
        store: the database.
        data_dir: where recordings go (``recordings/`` below it).
        on_state: called with every gait state (the leg view takes what it needs).
    """

    def __init__(
        self,
        session: schema.Session,
        subject: schema.Subject,
        model: TrainedModel,
        source: FrameSource,
        store: Store,
        data_dir: Path,
        on_state: Callable[[int, GaitState, float], None] | None = None,
    ):
        self.session = session
        self.subject = subject
        self.model = model
        self.source = source
        self.store = store
        self.data_dir = data_dir
        self.on_state = on_state
        period = 1.0 / source.rate_hz if source.rate_hz else DEFAULT_PERIOD
        self.estimator = FrameEstimator(model, subject.leg_length_m, subject.mass_kg, session.settings, period)
        self.subscribers: set[Subscriber] = set()
        self.recorder: Recorder | None = None
        self.trial: schema.Trial | None = None
        self.samples = 0
        self.dropped_input = 0
        self._last_change: dict[str, float] = {}
        self._recent_recv: deque[int] = deque(maxlen=4096)
        self._recent_latency: deque[float] = deque(maxlen=4096)
        self._task: asyncio.Task[None] | None = None
        self._health_task: asyncio.Task[None] | None = None
        self.start_ns = time.time_ns()

    # --- lifecycle ------------------------------------------------------------------------------
    def start(self) -> None:
        self.start_recording("trial 1")
        self._task = asyncio.get_running_loop().create_task(self._run(), name=f"session-{self.session.id}")
        self._health_task = asyncio.get_running_loop().create_task(self._health(), name="health")

    async def stop(self) -> None:
        if isinstance(self.source, LiveDevice):
            self.source.close()
        for task in (self._task, self._health_task):
            if task is not None and task is not asyncio.current_task():
                task.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await task
        self.stop_recording()
        for sub in self.subscribers:
            sub.close()

    async def _run(self) -> None:
        async for frame in self.source.frames():
            self.process(frame, time.time_ns())

    async def _health(self) -> None:
        while True:
            await asyncio.sleep(1.0)
            self.broadcast_health()

    # --- per sample -----------------------------------------------------------------------------
    def process(self, frame: SensorFrame, recv_ns: int) -> GaitState:
        """Estimate, record and publish one frame; returns the state (its torque goes to the device)."""
        state = self.estimator.step(frame, recv_ns)
        t = state.t
        self.samples += 1
        self._recent_recv.append(recv_ns)
        if frame.sent_ns is not None:
            self._recent_latency.append((recv_ns - frame.sent_ns) / 1e6)
        if self.recorder is not None:
            self.recorder.write("/sensor", t, frame.model_copy(update={"t": t}))  # session time, as the rest
            self.recorder.write("/gait_state", t, state)
            self.recorder.write("/torque", t, schema.TorqueCommand(seq=frame.seq, t=t, torque_Nm=state.torque_Nm))
        for sub in self.subscribers:
            sub.offer(state)
        if self.on_state is not None:
            self.on_state(self.session.id, state, self.subject.leg_length_m)
        return state

    def accepts(self, frame: SensorFrame) -> bool:
        """Whether a device frame's time follows the last one (a device may restart its clock)."""
        return self.estimator.accepts(frame)

    # --- subscribers and health ---------------------------------------------------------------
    def subscribe(self, max_rate_hz: float) -> Subscriber:
        rate = self.source.rate_hz or 1.0 / DEFAULT_PERIOD
        decimation = 1 if max_rate_hz <= 0 else max(1, math.ceil(rate / max_rate_hz))
        sub = Subscriber(decimation=decimation)
        self.subscribers.add(sub)
        return sub

    def unsubscribe(self, sub: Subscriber) -> None:
        self.subscribers.discard(sub)

    def health(self, sub: Subscriber | None = None) -> schema.Health:
        now = time.time_ns()
        recent = [r for r in self._recent_recv if now - r < 1_000_000_000]
        lat = np.array(list(self._recent_latency)[-len(recent) :]) if recent else np.array([])
        dropped_input = self.dropped_input + (self.source.dropped if isinstance(self.source, LiveDevice) else 0)
        return schema.Health(
            session_id=self.session.id,
            rate_hz=float(len(recent)),
            latency_ms_p50=float(np.percentile(lat, 50)) if lat.size else None,
            latency_ms_p95=float(np.percentile(lat, 95)) if lat.size else None,
            samples=self.samples,
            dropped_input=dropped_input,
            dropped_client=sub.dropped if sub is not None else 0,
            clients=len(self.subscribers),
        )

    def broadcast_health(self) -> None:
        for sub in self.subscribers:
            sub.notify(self.health(sub))

    def _broadcast(self, message: schema.BaseModel) -> None:
        for sub in self.subscribers:
            sub.notify(message)

    # --- clinician actions (between samples) --------------------------------------------------
    def change_settings(self, change: SettingsChange) -> schema.Session:
        """Validate bounds (done by the schema) and rates of change, apply, record one event per field."""
        current = self.session.settings
        updates = {
            k: v
            for k, v in change.model_dump(exclude={"actor", "reason"}).items()
            if v is not None and v != getattr(current, k)
        }
        now = time.monotonic()
        for name, value in updates.items():
            _, _, per_second = schema.SETTING_LIMITS[name]
            step = abs(value - getattr(current, name))
            if step > per_second + 1e-12:
                raise SettingRejected(
                    f"{name} may change by at most {per_second:g} per step and per second; "
                    f"{getattr(current, name):g} -> {value:g} is a step of {step:g}"
                )
            last = self._last_change.get(name)
            if last is not None and now - last < step / per_second:
                wait = step / per_second - (now - last)
                raise SettingRejected(
                    f"{name} changed {now - last:.2f} s ago; a step of {step:g} needs "
                    f"{step / per_second:.2f} s between changes (try again in {wait:.2f} s)"
                )
        if not updates:
            return self.session
        new = current.model_copy(update=updates)
        self.estimator.retune(new)
        self.session = self.store.set_session_settings(self.session.id, new)
        for name, value in updates.items():
            self._last_change[name] = now
            text = f"{name} {getattr(current, name):g} -> {value:g}" + (f" ({change.reason})" if change.reason else "")
            self._event("setting", text, field=name, before=getattr(current, name), after=value, actor=change.actor)
        if self.recorder is not None:
            self.recorder.write("/settings", self.estimator.last_t, new)
        self._broadcast(schema.SettingsMessage(session_id=self.session.id, settings=new))
        return self.session

    def annotate(self, text: str, actor: str) -> schema.Event:
        return self._event("annotation", text, actor=actor)

    def _event(self, kind: schema.EventKind, text: str, **fields: object) -> schema.Event:
        event = self.store.add_event(
            self.session.id,
            t=self.estimator.last_t,
            kind=kind,
            text=text,
            trial_id=self.trial.id if self.trial else None,
            **fields,  # type: ignore[arg-type]
        )
        if self.recorder is not None:
            self.recorder.write_event(event)
        self._broadcast(schema.EventMessage(event=event))
        return event

    def start_recording(self, name: str = "") -> schema.Trial:
        if self.trial is not None:
            return self.trial
        number = len(self.store.list_trials(self.session.id)) + 1
        rel = f"recordings/session{self.session.id:05d}_trial{number:03d}_{int(time.time())}.mcap"
        self.recorder = Recorder(
            self.data_dir / rel,
            self.start_ns,
            {
                "session_id": str(self.session.id),
                "subject": self.subject.code,
                "source": self.session.source.kind,
            },
        )
        self.trial = self.store.create_trial(self.session.id, name or f"trial {number}", rel)
        self.recorder.write("/settings", self.estimator.last_t, self.session.settings)
        self._event("recording", f"recording started: {self.trial.name}")
        return self.trial

    def stop_recording(self) -> schema.Trial | None:
        if self.trial is None or self.recorder is None:
            return None
        self._event("recording", f"recording stopped: {self.trial.name}")
        self.recorder.finish()
        trial = self.store.finish_trial(self.trial.id, "finished", self.recorder.samples, self.recorder.duration_s)
        self.trial, self.recorder = None, None
        return trial

    @property
    def settings(self) -> SessionSettings:
        return self.session.settings

    @property
    def last_t(self) -> float:
        """Session time of the last sample processed."""
        return self.estimator.last_t
