"""A running session: source -> estimator stack -> recording and subscribers.

One :class:`SessionRuntime` per running session, driven by one asyncio task on the server's loop.
Each sensor frame is processed synchronously (pipeline step, MCAP record, fan-out), so anything else
that runs on the loop (a settings change, an annotation, a recording toggle) happens *between* two
samples: a change takes effect at the next sample, and its event carries the time of the last sample
processed before it. Subscribers never slow the pipeline: each has a bounded buffer that drops its
oldest entries (counted) when the client does not keep up. The database writes are made by a writer
thread (:mod:`gaitscope.sessions.store_writer`), never on the loop: the events the sample path raises (intent
onsets, IMU and estimator notes, GP-EKF learning) are stored without a sample waiting for them, then
recorded and sent, in the order they happened.

Safety:

- the torque that leaves the runtime is always a finite number in ``[0, max_torque_Nm]``
  (:func:`~gaitscope.sessions.torque_gain.safe_torque`), whatever the estimators did and whatever the gain's
  owner (:mod:`gaitscope.sessions.torque_gain`: set gain, soft start, intent boost) does; an estimator that fails
  is isolated by the stack (:mod:`gaitscope.sessions.stack`), its failure is a system event and data health lists it;
- what only some sessions need (IMU problems and calibration, GP-EKF learning, intent events, fingerprint
  promotion, the disk watch) is a session extension (:mod:`gaitscope.sessions.live.extensions`), called in a loop
  at fixed points of the sample path; the GP-EKF's fits run in a worker, never on the sample loop;
- a change of settings is stored with its events in one transaction first and applied only then, so
  that what runs is always what the database (and the rate limits) say (the settings route waits for
  the writer without holding up the samples: :meth:`SessionRuntime.change_settings_async`);
- every task of the session is supervised: an error ends the session as ``failed`` with an event,
  the recording finished and the browsers told; the disk is checked every second, with a warning
  when it runs low and a clean stop before it is full;
- :meth:`SessionRuntime.stop` always finishes the recording and the session, whatever else fails.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from collections import deque
from collections.abc import Awaitable, Callable, Coroutine
from pathlib import Path
from typing import Any

from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.sessions import schema
from gaitscope.sessions.errors import DiskFull, disk_full, is_disk_full
from gaitscope.sessions.estimation import DEFAULT_PERIOD, FrameEstimator, FrameRefused, torque_json
from gaitscope.sessions.formats.recording import Recorder
from gaitscope.sessions.live.calibration import ImuCalibrating
from gaitscope.sessions.live.disk import DiskLevel, GrowthRate
from gaitscope.sessions.live.disk_watch import DiskWatch
from gaitscope.sessions.live.event_log import EventLog
from gaitscope.sessions.live.extensions import SessionExtension, describe, hooked
from gaitscope.sessions.live.gp_learning import GPLearning, GPTrainer
from gaitscope.sessions.live.health import health
from gaitscope.sessions.live.imu_events import ImuEvents
from gaitscope.sessions.live.intent_events import IntentEvents
from gaitscope.sessions.live.learning import GPLearningExtension
from gaitscope.sessions.live.lsl_outlet import GaitStateOutlet
from gaitscope.sessions.live.lsl_source import LslWatch
from gaitscope.sessions.live.notes import EstimatorNotes
from gaitscope.sessions.live.personalization import Personalization
from gaitscope.sessions.live.settings_change import ChangeNotSaved, SettingRejected, SettingsChanges
from gaitscope.sessions.live.sources import FrameSource, LiveDevice
from gaitscope.sessions.live.subscribers import SUBSCRIBER_CAPACITY, Subscriber
from gaitscope.sessions.live.trials import Trials
from gaitscope.sessions.personalization.intent_model import IntentModels, config_of
from gaitscope.sessions.schema import GaitState, SensorFrame, SessionSettings, SettingsChange
from gaitscope.sessions.store import Store
from gaitscope.sessions.store_writer import StoreWriter
from gaitscope.sessions.torque_gain import safe_torque

__all__ = [
    "SUBSCRIBER_CAPACITY",
    "ChangeNotSaved",
    "DiskFull",
    "SessionRuntime",
    "SettingRejected",
    "Subscriber",
    "safe_torque",
]

log = logging.getLogger("gaitscope")

DiskState = DiskLevel


class SessionRuntime:
    """Runs one session.

    Args:
        session: the stored session.
        subject: its subject (leg length and mass parameterise the pipeline).
        model: the trained models.
        source: where frames come from (its ``channels``, when it says, are checked against the stack).
        store: the database.
        data_dir: where recordings go (``recordings/`` below it).
        on_state: called with every gait state (the leg view takes what it needs).
        disk_check, disk_room: the state of the recording's disk (``ok``, ``low``, ``critical``) and the bytes
            that can still be recorded (None: unknown), read before a recording starts and once a second.
        on_end: called once when the session ends by itself (source finished, fault, disk full), after
            the runtime stopped, with the session's final state; the manager stores it.
        gp_trainer: the worker the GP-EKF's fits go to (the server's, shared); None: the session starts its
            own if its stack runs ``gp_ekf`` (and stops it with the session).
        writer: the thread that makes the session's database writes (:mod:`gaitscope.sessions.store_writer`; the
            server's, shared); None: the session starts its own (and closes it when it stops).
        clock: monotonic seconds, for the rate limits of settings changes and events and the disk's growth rate
            (injected: a test drives it instead of sleeping).

    Raises:
        ValueError: the settings name an unknown estimator, or a primary the stack cannot run.
        gaitscope.sessions.registry.MissingChannels: an estimator asked for whose required channels the source lacks.
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
        disk_check: Callable[[], DiskState] | None = None,
        disk_room: Callable[[], int | None] | None = None,
        on_end: Callable[[SessionRuntime, schema.SessionState, str], Awaitable[None]] | None = None,
        gp_trainer: GPTrainer | None = None,
        writer: StoreWriter | None = None,
        clock: Callable[[], float] = time.monotonic,
    ):
        self.session, self.subject, self.model, self.source, self.store = session, subject, model, source, store
        self.clock = clock
        self._own_writer = writer is None
        self.writer = writer or StoreWriter(name=f"writer-session-{session.id}")
        #: the session's events (:mod:`gaitscope.sessions.live.event_log`): ``event`` waits for the database,
        #: ``event_soon`` does not, ``settle_events`` records and sends those stored so far
        self.events = EventLog(self)
        self.event, self.event_soon, self.settle_events = self.events.event, self.events.event_soon, self.events.settle
        self.trials = Trials(self)  # the recordings (:mod:`gaitscope.sessions.live.trials`)
        self.stop_recording = self.trials.stop
        self.data_dir, self.on_state = data_dir, on_state
        period = 1.0 / source.rate_hz if source.rate_hz else DEFAULT_PERIOD
        self.sample_period = period  # recorded, so that a review re-run builds the same estimator
        active = store.active_personalization(subject.id, session.settings.model)
        fingerprint = None if active is None else active.fingerprint
        #: the subject's speed-change intent model as it was when the session started (recorded with each trial)
        self.intent_model = IntentModels(store).get(subject.id)
        self.estimator = FrameEstimator(
            model,
            subject.leg_length_m,
            subject.mass_kg,
            session.settings,
            period,
            channels=getattr(source, "channels", None),
            fingerprint=fingerprint,
            intent=config_of(self.intent_model) if self.intent_model is not None else None,
        )
        self.settings_changes = SettingsChanges(self)
        self.subscribers: set[Subscriber] = set()
        self.recorder: Recorder | None = None
        self.trial: schema.Trial | None = None
        self.samples = self.dropped_input = self.torque_faults = 0  # samples processed, frames refused, torques clamped
        self.recent_recv: deque[int] = deque(maxlen=4096)  # the samples' receive times (ns), for data health
        self.recent_latency: deque[float] = deque(maxlen=4096)  # and their latencies (ms)
        self._task: asyncio.Task[None] | None = None
        self._health_task: asyncio.Task[None] | None = None  # data health and the extensions' ticks, once a second
        self.start_ns = time.time_ns()
        self.disk_check, self.disk_room, self.on_end = disk_check, disk_room, on_end
        #: The JSON of the last sample's torque command (what the device is sent, as recorded).
        self.last_command = ""
        self.ended: str | None = None  # why the session ended, once it has
        self.stopped = False  # stop() has run (or is running)
        #: What ending the session could not store (the database's disk full): each trial's final row, by id,
        #: and the events that end a trial or the session (``Store.add_event``'s arguments, session id
        #: included). The manager stores them once it can; the API shows the trials meanwhile.
        self.unsaved_trials: dict[int, schema.Trial] = {}
        self.unsaved_events: list[dict[str, Any]] = []
        #: Why the last event that could not be stored was not (None before any)
        self.store_error: Exception | None = None
        #: the extensions (:mod:`gaitscope.sessions.live.extensions`), called in this order
        self.disk_watch = DiskWatch(self)
        self.personalization = Personalization(self, fingerprint)
        self.imu_calibration = ImuCalibrating(self)
        self.learning = GPLearningExtension.of(self, gp_trainer)
        #: the GP-EKF's online retraining, freeze and rollback (None: the stack runs no gp_ekf)
        self.gp_learning: GPLearning | None = None if self.learning is None else self.learning.learning
        extensions = (self.disk_watch, EstimatorNotes(self), IntentEvents.of(self), ImuEvents(self),
                      self.imu_calibration, self.learning, self.personalization, LslWatch.of(self),
                      GaitStateOutlet.of(self))  # fmt: skip
        self.extensions: list[SessionExtension] = [e for e in extensions if e is not None]
        self._on_sample = hooked(self.extensions, "on_sample")
        self._after_record = hooked(self.extensions, "after_record")
        self._on_tick = hooked(self.extensions, "on_tick")

    # --- lifecycle ------------------------------------------------------------------------------
    def start(self) -> None:
        self.start_recording("trial 1")
        for extension in self.extensions:
            extension.start()
        if (soft_start := self.estimator.gain.soft_start_text()) is not None:
            self.event("system", soft_start)
        loop = asyncio.get_running_loop()
        self._task = loop.create_task(self._supervised(self._run()), name=f"session-{self.session.id}")
        self._health_task = loop.create_task(self._supervised(self._health()), name=f"health-{self.session.id}")

    async def stop(self) -> None:
        """Stop the source and the tasks, finish the recording, close the streams; never raises."""
        if self.stopped:
            return
        self.stopped = True
        if isinstance(self.source, LiveDevice):
            self.source.close()
        for task in (self._task, self._health_task):
            if task is not None and task is not asyncio.current_task():
                task.cancel()
                with contextlib.suppress(asyncio.CancelledError, Exception):
                    await task
        for extension in self.extensions:
            with contextlib.suppress(Exception):
                await extension.stop()
        try:
            self.stop_recording()
        except Exception:
            log.exception("session %d: finishing the recording failed", self.session.id)
        with contextlib.suppress(Exception):  # events still being stored: sent before the streams close
            await asyncio.to_thread(self.writer.flush)
        self.settle_events()
        if self._own_writer:
            await asyncio.to_thread(self.writer.close)
        for sub in self.subscribers:
            sub.close()

    async def end(self, state: schema.SessionState, reason: str) -> None:
        """The session ends by itself (``stopped`` or ``failed``): event, stop, tell the manager."""
        if self.ended is not None or self.stopped:
            return
        for folder in {str(self.data_dir.resolve()), str(self.data_dir)}:  # no server paths in events
            reason = reason.replace(folder + "/", "").replace(folder, "the data folder")
        self.ended = reason
        self.events.lasting_event(f"session {state}: {reason}")
        await self.stop()
        if self.on_end is not None:
            await self.on_end(self, state, reason)

    async def _supervised(self, work: Coroutine[Any, Any, None]) -> None:
        """Run one task of the session; an error fails the session instead of vanishing."""
        try:
            await work
        except asyncio.CancelledError:
            raise
        except Exception as e:
            log.exception("session %d failed", self.session.id)
            await self.end("failed", describe(e))

    async def _run(self) -> None:
        async for frame in self.source.frames():
            if self.stopped:
                return
            if self.settings_changes.saving:
                await self.settings_changes.applied()
            try:
                self.process(frame, time.time_ns())
            except FrameRefused:
                self.dropped_input += 1
        if not isinstance(self.source, LiveDevice):
            await self.end("stopped", "the source has no more frames")

    async def _health(self) -> None:
        while True:
            await asyncio.sleep(1.0)
            for tick in self._on_tick:
                tick()
            self.broadcast_health()

    # --- per sample -----------------------------------------------------------------------------
    def process(self, frame: SensorFrame, recv_ns: int) -> GaitState:
        """Estimate, record and publish one frame; returns the state (its torque goes to the device).

        Raises:
            FrameRefused: a reordered or repeated frame; nothing changed.
        """
        state = self.estimator.step(frame, recv_ns)
        torque = safe_torque(state.torque_Nm, self.settings.max_torque_Nm)
        if torque != state.torque_Nm:
            self.torque_faults += 1
            state = state.model_copy(update={"torque_Nm": torque, "fault": True})
        elif math.copysign(1.0, state.torque_Nm) < 0:  # -0.0: no fault, but shown and recorded as the wire's +0.0
            state = state.model_copy(update={"torque_Nm": torque})
        sample = self.estimator.last
        outputs = sample.outputs if sample is not None else []
        for on_sample in self._on_sample:
            on_sample(state, outputs)
        t = state.t
        self.samples += 1
        self.recent_recv.append(recv_ns)
        if frame.sent_ns is not None:
            self.recent_latency.append((recv_ns - frame.sent_ns) / 1e6)
        command = torque_json(frame.seq, t, state.torque_Nm)
        self.last_command = command
        if self.recorder is not None:
            record = self.estimator.recorded_json
            self.write_recording(lambda r: r.write_json(t, record(frame, state, command.encode())))
        for after_record in self._after_record:
            after_record(frame, t)
        for sub in self.subscribers:
            sub.offer(state, outputs)
        if self.on_state is not None:
            self.on_state(self.session.id, state, self.subject.leg_length_m)
        return state

    def start_recording(self, name: str = "") -> schema.Trial:
        """Start a trial's recording (:meth:`Trials.start`); its first state says where the estimates come from.

        Raises:
            DiskFull: the disk is (almost) full; nothing was started.
        """
        self.estimator.stack.announce_sources()  # before the trial's start: a re-run restores it announcing
        return self.trials.start(name)

    def write_recording(self, write: Callable[[Recorder], object]) -> None:
        """``write`` to the trial recording now, if any; a write that fails (a full disk) ends it and the session."""
        if self.recorder is not None:
            try:
                write(self.recorder)
            except (OSError, ValueError) as e:
                self.trials.failed(e)

    def record(self, topic: str, message: schema.BaseModel) -> None:
        """Write ``message`` on ``topic`` to the trial recording now (if any), at the last sample's time."""
        self.write_recording(lambda r: r.write(topic, self.estimator.last_t, message))

    def accepts(self, frame: SensorFrame) -> bool:
        """Whether a device frame's time can be placed after the last one (a device may restart its clock)."""
        return self.estimator.accepts(frame)

    def device_connected(self) -> None:
        """A device (re)connected: its clock may have restarted, so session time resynchronises."""
        if self.samples:
            self.estimator.resync((time.time_ns() - self.start_ns) / 1e9)

    # --- subscribers and health ---------------------------------------------------------------
    def subscribe(self, max_rate_hz: float) -> Subscriber:
        rate = self.source.rate_hz or 1.0 / DEFAULT_PERIOD
        decimation = 1 if max_rate_hz <= 0 else max(1, math.ceil(rate / max_rate_hz))
        stack = self.estimator.stack
        sub = Subscriber(decimation=decimation, layout=list(zip(stack.names, stack.outputs, strict=True)))
        self.subscribers.add(sub)
        return sub

    def unsubscribe(self, sub: Subscriber) -> None:
        self.subscribers.discard(sub)

    def health(self, sub: Subscriber | None = None) -> schema.Health:
        """Data health now, as ``sub`` sees it (:mod:`gaitscope.sessions.live.health`)."""
        return health(self, sub)

    @property
    def disk(self) -> DiskState:
        """The recording disk's state at the last check (:class:`~gaitscope.sessions.live.disk_watch.DiskWatch`)."""
        return self.disk_watch.state

    @property
    def disk_rate(self) -> GrowthRate:
        """This session's recording rate (bytes/s), estimated, then measured."""
        return self.disk_watch.rate

    def broadcast_health(self) -> None:
        for sub in self.subscribers:
            sub.notify(self.health(sub))

    def broadcast(self, message: schema.BaseModel) -> None:
        for sub in self.subscribers:
            sub.notify(message)

    # --- clinician actions (between samples) --------------------------------------------------
    def change_settings(self, change: SettingsChange) -> schema.Session:
        """Check a change against the limits, store it with its events and only then apply it; this thread
        waits for the database writer (:mod:`gaitscope.sessions.live.settings_change`).

        Raises:
            SettingRejected: a rate-of-change limit, or another change still being stored; nothing changed.
            ChangeNotSaved: the database refused the write; nothing changed.
        """
        return self.settings_changes.change(change)

    async def change_settings_async(self, change: SettingsChange) -> schema.Session:
        """:meth:`change_settings` for a coroutine (the settings route): the loop runs while the change is stored.
        A caller cancelled meanwhile does not undo it: stored, it is applied when the write completes."""
        return await self.settings_changes.change_async(change)

    def annotate(self, text: str, actor: str) -> schema.Event:
        """A clinician's note in the session's log, stored before it counts.

        Raises:
            DiskFull: the database's disk is full; ChangeNotSaved: it could not be stored otherwise.
        """
        event = self.event("annotation", text, actor=actor)
        if event is None:
            if is_disk_full(self.store_error):
                raise disk_full("the annotation was not saved", self.store_error)
            raise ChangeNotSaved("the annotation could not be saved") from self.store_error
        return event

    @property
    def fingerprint(self) -> list[float] | None:
        """The fingerprint the stack's ``fp_ls`` runs (None: none; :mod:`gaitscope.sessions.live.personalization`)."""
        return self.personalization.fingerprint

    @property
    def settings(self) -> SessionSettings:
        return self.session.settings

    @property
    def last_t(self) -> float:
        """Session time of the last sample processed."""
        return self.estimator.last_t
