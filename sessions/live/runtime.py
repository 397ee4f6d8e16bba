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
  (:func:`safe_torque`), whatever the estimators did and whatever the optional intent boost of the gain
  (:mod:`sessions.intent_boost`, off by default, applied by the frame estimator) does; an estimator that fails is
  isolated by the stack (:mod:`gaitscope.sessions.stack`), its failure is a system event and data health lists it;
- a problem an IMU front end reports for long enough (a sensor that stops sending, a saturated gyro, a
  flipped axis, a wrong sample rate: :mod:`gaitscope.sessions.live.imu_events`) is a system event naming the sensor,
  another when it clears, and data health shows the worst one; the front end degrades its own estimate,
  and the torque stays bounded as above;
- the GP-EKF's retraining (:mod:`gaitscope.sessions.live.gp_learning`, when the stack runs ``gp_ekf``) fits in a worker
  process, never on the sample loop; a fit that fails is an event, and the model in use stays;
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
import datetime as dt
import functools
import logging
import math
import threading
import time
from collections import deque
from collections.abc import Awaitable, Callable, Coroutine, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.sessions import schema
from gaitscope.sessions.errors import FREE_SPACE_HINT, DiskFull, disk_full, is_disk_full
from gaitscope.sessions.estimation import DEFAULT_PERIOD, FrameEstimator, FrameRefused, torque_json
from gaitscope.sessions.formats.mcap_io import read_messages, recover, recover_in_place
from gaitscope.sessions.formats.recording import ESTIMATORS_KEY, FINGERPRINT_KEY, SAMPLE_PERIOD_KEY, Recorder
from gaitscope.sessions.imu_calibration import StandingCollector, applied_text, apply_calibration, front_end_segments
from gaitscope.sessions.live.disk import DiskLevel, GrowthRate, estimated_bytes_per_s, minutes
from gaitscope.sessions.live.gp_learning import GPLearning, GPTrainer, Note
from gaitscope.sessions.live.imu_events import ImuWatch
from gaitscope.sessions.live.intent_events import IntentOnsets
from gaitscope.sessions.live.sources import FrameSource, LiveDevice
from gaitscope.sessions.live.subscribers import SUBSCRIBER_CAPACITY, Subscriber
from gaitscope.sessions.schema import GaitState, SensorFrame, SessionSettings, SettingsChange
from gaitscope.sessions.store import Store
from gaitscope.sessions.store_writer import StoreWriter, Write

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

#: Least time between two system events about estimator faults or clock resynchronisations (s).
NOTE_INTERVAL_S = 1.0
#: Data health says the primary lost track for this long after it did (s).
LOST_SHOWN_S = 5.0

DiskState = DiskLevel


class SettingRejected(ValueError):
    """A settings change that breaks a rate-of-change limit; the message says which and why."""


class ChangeNotSaved(RuntimeError):
    """A change that could not be stored, and so was not applied; the message says why."""


def safe_torque(value: float, bound: float) -> float:
    """``value`` clamped to ``[0, bound]``; 0 when it (or the bound) is not a finite number. Never -0.0 (a zero
    torque times a negative profile, at the soft start's first sample): ``+ 0.0`` makes it +0.0."""
    if not (math.isfinite(value) and math.isfinite(bound)):
        return 0.0
    return min(max(value, 0.0), max(bound, 0.0)) + 0.0


@dataclass(frozen=True)
class _SettingsPlan:
    """A checked settings change waiting to be stored: the new settings, the fields that change, their
    events (``Store.add_event`` arguments), the session time and the monotonic time of the change."""

    new: SessionSettings
    fields: list[str]
    events: list[dict[str, Any]]
    t: float
    now: float


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
        disk_room: bytes that can still be recorded before the disk guard stops (None: unknown), read after
            each ``disk_check`` to state what is left as minutes of this session's recording.
        disk_check: returns the state of the recording's disk (``ok``, ``low``, ``critical``); called
            before a recording starts and once a second.
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
        self.session = session
        self.clock = clock
        self.subject = subject
        self.model = model
        self.source = source
        self.store = store
        self._own_writer = writer is None
        self.writer = writer or StoreWriter(name=f"writer-session-{session.id}")
        #: events submitted to the writer and not yet recorded and broadcast, in order, each with the
        #: recorder that was recording when it happened (:meth:`_event_soon`)
        self._pending_events: deque[tuple[Write[schema.Event], Recorder | None]] = deque()
        self._settling = threading.RLock()  # a sync route's thread may settle them too (personalization_changed)
        self.data_dir = data_dir
        self.on_state = on_state
        period = 1.0 / source.rate_hz if source.rate_hz else DEFAULT_PERIOD
        self.sample_period = period  # recorded, so that a review re-run builds the same estimator
        active = store.active_personalization(subject.id, session.settings.model)
        self.fingerprint: list[float] | None = None if active is None else active.fingerprint
        self.estimator = FrameEstimator(
            model,
            subject.leg_length_m,
            subject.mass_kg,
            session.settings,
            period,
            channels=getattr(source, "channels", None),
            fingerprint=self.fingerprint,
        )
        #: onsets of speeding up / slowing down of the stack's intent estimator: each one an ``intent`` event
        self.intent_onsets = IntentOnsets(self.estimator.stack.names, self.estimator.stack.outputs)
        #: problems the IMU front ends report, debounced into episodes: an event at each start and end
        self.imu_watch = ImuWatch(self.estimator.stack.estimators, self.estimator.stack.outputs, subject.side)
        #: IMU mounting calibration: the sensors it can calibrate, the one collecting, the last outcome, and
        #: the one the front ends run (the subject's current one from the start, until this session makes one)
        self.imu_segments = front_end_segments(self.estimator.stack)
        self.imu_collector: StandingCollector | None = None
        self.imu_result: schema.ImuCalibration | None = None
        current = store.current_imu_calibration(subject.id) if self.imu_segments else None
        self._imu_at_start = [] if current is None else apply_calibration(self.estimator.stack, current)
        self.imu_applied = current if self._imu_at_start else None
        #: the GP-EKF's online retraining, freeze and rollback (None: the stack runs no gp_ekf)
        self._own_trainer = gp_trainer is None
        self.gp_learning = GPLearning.of(self.estimator.stack, gp_trainer or GPTrainer())
        self.subscribers: set[Subscriber] = set()
        self.recorder: Recorder | None = None
        self.trial: schema.Trial | None = None
        self.samples = 0
        self.dropped_input = 0
        self._last_change: dict[str, float] = {}
        #: a settings change is being stored (:meth:`change_settings_async`): the session's samples wait for it
        #: (:meth:`settings_applied`), so that it applies at the sample its events name; another change is refused
        self.saving_settings = False
        self._applied = asyncio.Event()
        self._recent_recv: deque[int] = deque(maxlen=4096)
        self._recent_latency: deque[float] = deque(maxlen=4096)
        self._task: asyncio.Task[None] | None = None
        self._health_task: asyncio.Task[None] | None = None
        self.start_ns = time.time_ns()
        self.disk_check = disk_check
        self.on_end = on_end
        self.disk: DiskState = "ok"
        self.disk_room = disk_room
        #: this session's recording rate (bytes/s): estimated from its channels, rate and stack, then measured
        declared = getattr(source, "channels", None)
        n_channels = None if declared is None else len(declared)
        self.disk_rate = GrowthRate(estimated_bytes_per_s(1.0 / period, n_channels, len(self.estimator.stack.names)))
        #: minutes of recording left at that rate before the disk guard stops it (None: unknown)
        self.disk_minutes: float | None = None
        self.torque_faults = 0
        #: The JSON of the last sample's torque command (what the device is sent, as recorded).
        self.last_command = ""
        self.ended: str | None = None  # why the session ended, once it has
        self._stopped = False
        self._recording_failing = False  # _recording_failed is finishing the recording (not re-entered)
        self._last_note = -math.inf
        self._suppressed_notes = 0
        #: What ending the session could not store (the database's disk full): each trial's final row, by id,
        #: and the events that end a trial or the session (``Store.add_event``'s arguments, session id
        #: included). The manager stores them once it can; the API shows the trials meanwhile.
        self.unsaved_trials: dict[int, schema.Trial] = {}
        self.unsaved_events: list[dict[str, Any]] = []
        #: Why the last event that could not be stored was not (None before any)
        self.store_error: Exception | None = None

    # --- lifecycle ------------------------------------------------------------------------------
    def start(self) -> None:
        self.start_recording("trial 1")
        if self.imu_applied is not None:
            self._event(
                "system",
                f"the subject's IMU calibration {self.imu_applied.id} ({self.imu_applied.created_utc}) applied: "
                + applied_text(self.imu_applied, self._imu_at_start),
                field="imu_calibration",
                after=float(self.imu_applied.id or 0),
            )
        s = self.settings
        ramp = max(
            s.torque_gain / schema.SETTING_LIMITS["torque_gain"][2],
            s.max_torque_Nm / schema.SETTING_LIMITS["max_torque_Nm"][2],
        )
        if self.estimator.soft_start and ramp > 0:
            self._event(
                "system",
                f"soft start: assistance ramps up to gain {s.torque_gain:g} and {s.max_torque_Nm:g} N m "
                f"over the first {ramp:.1f} s",
            )
        loop = asyncio.get_running_loop()
        self._task = loop.create_task(self._supervised(self._run()), name=f"session-{self.session.id}")
        self._health_task = loop.create_task(self._supervised(self._health()), name=f"health-{self.session.id}")

    async def stop(self) -> None:
        """Stop the source and the tasks, finish the recording, close the streams; never raises."""
        if self._stopped:
            return
        self._stopped = True
        if isinstance(self.source, LiveDevice):
            self.source.close()
        for task in (self._task, self._health_task):
            if task is not None and task is not asyncio.current_task():
                task.cancel()
                with contextlib.suppress(asyncio.CancelledError, Exception):
                    await task
        if self.gp_learning is not None:
            self.gp_learning.close()
            if self._own_trainer:
                with contextlib.suppress(Exception):
                    await asyncio.to_thread(self.gp_learning.trainer.shutdown)
        try:
            self.stop_recording()
        except Exception:
            log.exception("session %d: finishing the recording failed", self.session.id)
        with contextlib.suppress(Exception):  # events still being stored: sent before the streams close
            await asyncio.to_thread(self.writer.flush)
        self._settle_events()
        if self._own_writer:
            await asyncio.to_thread(self.writer.close)
        for sub in self.subscribers:
            sub.close()

    async def end(self, state: schema.SessionState, reason: str) -> None:
        """The session ends by itself (``stopped`` or ``failed``): event, stop, tell the manager."""
        if self.ended is not None or self._stopped:
            return
        for folder in {str(self.data_dir.resolve()), str(self.data_dir)}:  # no server paths in events
            reason = reason.replace(folder + "/", "").replace(folder, "the data folder")
        self.ended = reason
        self._lasting_event(f"session {state}: {reason}")
        await self.stop()
        if self.on_end is not None:
            await self.on_end(self, state, reason)

    def _lasting_event(self, text: str, trial_id: int | None = None, kind: schema.EventKind = "system") -> None:
        """An event that must reach the database (a trial's or the session's end): when it cannot be stored now
        (a full disk), it is kept in :attr:`unsaved_events` for the manager to store later."""
        trial_id = trial_id if trial_id is not None else self.trial.id if self.trial else None
        if self._event(kind, text) is None:
            self.unsaved_events.append(
                {"session_id": self.session.id, "t": self.estimator.last_t, "kind": kind, "text": text,
                 "trial_id": trial_id}
            )  # fmt: skip

    async def _supervised(self, work: Coroutine[Any, Any, None]) -> None:
        """Run one task of the session; an error fails the session instead of vanishing."""
        try:
            await work
        except asyncio.CancelledError:
            raise
        except Exception as e:
            log.exception("session %d failed", self.session.id)
            await self.end("failed", _describe(e))

    async def _run(self) -> None:
        async for frame in self.source.frames():
            if self._stopped:
                return
            if self.saving_settings:
                await self.settings_applied()
            try:
                self.process(frame, time.time_ns())
            except FrameRefused:
                self.dropped_input += 1
        if not isinstance(self.source, LiveDevice):
            await self.end("stopped", "the source has no more frames")

    async def _health(self) -> None:
        while True:
            await asyncio.sleep(1.0)
            self.check_disk()
            if self.imu_collector is not None and self.imu_collector.overdue():
                self._imu_calibrated()
            self.broadcast_health()

    def check_disk(self) -> DiskState:
        """Look at the disk; warn once when low, stop cleanly when critical; say what is left as minutes of this
        session's recording (:attr:`disk_minutes`, data health)."""
        if self.disk_check is None:
            return "ok"
        state = self.disk_check()
        if self.recorder is not None:
            with contextlib.suppress(OSError):
                self.disk_rate.update(self.recorder.path.stat().st_size, self.clock())
        room = self.disk_room() if self.disk_room is not None else None
        self.disk_minutes = None if room is None else round(minutes(room, self.disk_rate.bytes_per_s), 1)
        if state != self.disk:
            if state == "low":
                left = "" if self.disk_minutes is None else f"about {self.disk_minutes:.0f} min of recording left "
                self._event("system", f"disk space is low: {left}at this session's {self._rate_text()}; the recording "
                            f"stops when it runs out; {FREE_SPACE_HINT}")  # fmt: skip
            elif state == "critical" and self.ended is None:
                asyncio.get_running_loop().create_task(
                    self.end("stopped", "the disk is almost full: recording finished and session stopped")
                )
        self.disk = state
        return state

    def _rate_text(self) -> str:
        """This session's recording rate in words: "305 kB/s (74 channels at 200 Hz, 6 estimators)"."""
        channels = getattr(self.source, "channels", None)
        what = "undeclared channels" if channels is None else f"{len(channels)} channels"
        return (f"{self.disk_rate.bytes_per_s / 1000:.0f} kB/s ({what} at {1.0 / self.sample_period:g} Hz, "
                f"{len(self.estimator.stack.names)} estimators)")  # fmt: skip

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
        if self.estimator.events:
            self._estimator_events()
        if self.estimator.notes:
            self._notes()
        sample = self.estimator.last
        outputs = sample.outputs if sample is not None else []
        if self.intent_onsets.active:
            self._intent_event(outputs)
        if self.imu_watch.active:
            for imu in self.imu_watch.update(state.t, outputs):
                self._event_soon("system", imu.text, field=imu.field, before=imu.before, after=imu.after)
        t = state.t
        self.samples += 1
        self._recent_recv.append(recv_ns)
        if frame.sent_ns is not None:
            self._recent_latency.append((recv_ns - frame.sent_ns) / 1e6)
        command = torque_json(frame.seq, t, state.torque_Nm)
        self.last_command = command
        if self.recorder is not None:
            try:
                self.recorder.write_json(t, self.estimator.recorded_json(frame, state, command.encode()))
            except (OSError, ValueError) as e:
                self._recording_failed(e)
        if self.imu_collector is not None and self.imu_collector.add(t, frame):
            self._imu_calibrated()  # after the frame's record: a re-run applies it from the next frame, as here
        if self.gp_learning is not None:
            for note in self.gp_learning.poll(t):
                self._gp_note(note)
        for sub in self.subscribers:
            sub.offer(state, outputs)
        if self.on_state is not None:
            self.on_state(self.session.id, state, self.subject.leg_length_m)
        return state

    def _estimator_events(self) -> None:
        """Estimator failures and primary switches: each one a system event (they are rare: each estimator
        fails at most once)."""
        for text in self.estimator.events:
            self._event_soon("system", text)
        self.estimator.events.clear()

    def _intent_event(self, outputs: Sequence[NDArray[np.float64] | None]) -> None:
        """An onset of speeding up or slowing down at this sample: an ``intent`` event (at most one per
        mid-stance, see :mod:`gaitscope.sessions.live.intent_events`)."""
        onset = self.intent_onsets.update(outputs)
        if onset is not None:
            before, after = round(onset.desired_before_m_s, 3), round(onset.desired_m_s, 3)
            self._event_soon("intent", onset.text, field="desired_speed_m_s", before=before, after=after)

    def _notes(self) -> None:
        """Turn the estimator's notes into system events, at most one per NOTE_INTERVAL_S."""
        notes = self.estimator.notes
        now = self.clock()
        if now - self._last_note < NOTE_INTERVAL_S:
            self._suppressed_notes += len(notes)
        else:
            more = len(notes) - 1 + self._suppressed_notes
            self._event_soon("system", notes[0] + (f" (and {more} more since the last such event)" if more else ""))
            self._last_note, self._suppressed_notes = now, 0
        notes.clear()

    def _recording_failed(self, e: Exception) -> None:
        """A recording write failed (a full disk): finish what was recorded and stop the session.

        The trial ends at once, readable up to its last complete chunk (:meth:`stop_recording`); the session
        ends on the next turn of the loop, with the reason in its last event and in the device's close."""
        log.error("session %d: recording failed: %s", self.session.id, e)
        if self._recording_failing:  # a write while finishing it (its "recording stopped" event): it is ending
            return
        self._recording_failing = True
        try:
            with contextlib.suppress(Exception):
                self.stop_recording()
        finally:
            self._recording_failing = False
        self.recorder, self.trial = None, None
        if self.ended is None and not self._stopped:
            why = (
                f"{_describe(e)}; {FREE_SPACE_HINT}"
                if is_disk_full(e)
                else f"the recording could not be written ({_describe(e)}); session stopped"
            )
            asyncio.get_running_loop().create_task(self.end("stopped", why))

    def personalization_changed(self, text: str, actor: str) -> None:
        """The subject's personalization was promoted or rolled back: an event in this session's log, and the
        running personalized filter (``fp_ls``) takes the now active fingerprint at its next heel strike.
        A session whose stack has no ``fp_ls`` (none was active when it started) keeps its stack: the
        event says the change applies from the next session."""
        active = self.store.active_personalization(self.subject.id, self.settings.model)
        fp_ls = next((e for e in self.estimator.stack.estimators if e.name == "fp_ls"), None)
        if fp_ls is None:
            self._event("system", f"{text}; fp_ls is not running here: it applies from the next session", actor=actor)
            return
        if active is None:
            self._event("system", f"{text}; fp_ls keeps its fingerprint until the session ends", actor=actor)
            return
        try:
            fp_ls.personalize(np.array(active.fingerprint))  # type: ignore[attr-defined]
        except ValueError as e:
            self._event("system", f"{text}; fp_ls cannot take it ({e})", actor=actor)
            return
        self.fingerprint = active.fingerprint
        self._event("system", f"{text}; fp_ls takes it at the next heel strike", actor=actor)

    def calibrate_imus(self, request: schema.ImuCalibrationRequest) -> schema.ImuCalibrationStatus:
        """Start collecting a standing period of the front ends' raw IMU samples (the caller checked that
        the stack has front ends and that none is collecting); it ends after ``duration_s`` of samples."""
        self.imu_collector = StandingCollector(self.imu_segments, request)
        self.imu_result = None
        who = f" by {request.actor}" + (f" ({request.note})" if request.note else "")
        self._event("system", f"IMU calibration started{who}: stand still for {request.duration_s:g} s",
                    actor=request.actor)  # fmt: skip
        return self.imu_status()

    def imu_status(self) -> schema.ImuCalibrationStatus:
        c, r = self.imu_collector, self.imu_result
        state: schema.ImuCalibrationState = (
            "collecting" if c is not None else "idle" if r is None else "done" if r.ok else "refused"
        )
        return schema.ImuCalibrationStatus(
            session_id=self.session.id,
            state=state,
            progress=c.progress if c is not None else 0.0 if r is None else 1.0,
            duration_s=c.request.duration_s if c is not None else r.duration_s if r is not None else 0.0,
            segments=self.imu_segments,
            result=r,
            applied=self.imu_applied,
        )

    def _imu_calibrated(self) -> None:
        """The standing period is over: calibrate; accepted, store it (the subject's current calibration)
        and only then apply it to the front ends and record it; refused, say why. Either way an event."""
        collector, self.imu_collector = self.imu_collector, None
        assert collector is not None
        actor = collector.request.actor
        result = collector.result(self.subject.id, self.session.id, self.trial.id if self.trial else None)
        if result.ok:
            try:
                result = self.writer.call(
                    functools.partial(self.store.add_imu_calibration, result),
                    f"session {self.session.id}: IMU calibration",
                )
            except Exception as e:
                log.error("session %d: IMU calibration not saved: %s", self.session.id, e)
                why = f"the calibration could not be saved ({_describe(e)}), so it was not applied"
                result = result.model_copy(update={"ok": False, "reason": why})
        self.imu_result = result
        if not result.ok:
            self._event("system", f"IMU calibration refused: {result.reason}", field="imu_calibration", actor=actor)
            return
        names = apply_calibration(self.estimator.stack, result)
        self.imu_applied = result
        if self.recorder is not None:
            try:
                self.recorder.write("/imu_calibration", self.estimator.last_t, result)
            except (OSError, ValueError) as e:
                self._recording_failed(e)
        self._event("system", f"IMU calibration {result.id} applied: {applied_text(result, names)}",
                    field="imu_calibration", after=float(result.id or 0), actor=actor)  # fmt: skip

    def _gp_note(self, note: Note) -> None:
        """A GP-EKF learning note: recorded (``/gp_models``), and its event (field ``gp_ekf``) if it has one."""
        self._gp_record(note.record)
        if note.text:
            self._event_soon(note.kind, note.text, field="gp_ekf", before=note.before, after=note.after,
                             actor=note.record.actor)  # fmt: skip

    def _gp_event(self, note: Note) -> schema.Event | None:
        return self._event(note.kind, note.text, field="gp_ekf", before=note.before, after=note.after,
                           actor=note.record.actor)  # fmt: skip

    def _gp_record(self, record: schema.GPModelRecord) -> None:
        if self.recorder is not None:
            try:
                self.recorder.write("/gp_models", self.estimator.last_t, record)
            except (OSError, ValueError) as e:
                self._recording_failed(e)

    def gp_control(self, control: schema.GPLearningControl) -> schema.GPLearningState:
        """Freeze, unfreeze or roll back the GP-EKF's learning (the caller checked that it runs): logged with
        the actor and stored first, applied only then (at the next heel strike for a rollback), recorded.

        Raises:
            gaitscope.sessions.live.gp_learning.LearningRefused: a rollback to a version not kept; nothing changed.
            ChangeNotSaved: the event could not be stored; nothing changed.
        """
        learning = self.gp_learning
        assert learning is not None
        note = learning.plan(control, self.estimator.last_t)
        if note is not None:
            if self._gp_event(note) is None:
                raise ChangeNotSaved("the change could not be saved, so it was not applied")
            learning.apply(control)
            self._gp_record(note.record)
        return learning.state(self.session.id)

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
        now = time.time_ns()
        recent = [r for r in self._recent_recv if now - r < 1_000_000_000]
        lat = np.array(list(self._recent_latency)[-len(recent) :]) if recent else np.array([])
        dropped_input = self.dropped_input + (self.source.dropped if isinstance(self.source, LiveDevice) else 0)
        imu, imu_note = self.imu_watch.health()
        return schema.Health(
            session_id=self.session.id,
            rate_hz=float(len(recent)),
            latency_ms_p50=float(np.percentile(lat, 50)) if lat.size else None,
            latency_ms_p95=float(np.percentile(lat, 95)) if lat.size else None,
            samples=self.samples,
            dropped_input=dropped_input,
            dropped_client=sub.dropped if sub is not None else 0,
            clients=len(self.subscribers),
            implausible=self.estimator.implausible,
            faults=self.estimator.faults + self.torque_faults,
            disk=self.disk,
            disk_minutes=self.disk_minutes,
            estimators=list(self.estimator.stack.names),
            primary=self.estimator.primary,
            failed_estimators=dict(self.estimator.stack.failed),
            **self._tracking(),
            imu=imu,
            imu_note=imu_note,
        )

    def _tracking(self) -> dict[str, Any]:
        """The primary's tracking for data health: standing, lost in the last ``LOST_SHOWN_S``, walking."""
        e, lost = self.estimator.last, self.estimator.last_lost
        if e is None or e.primary is None:
            return {}
        if lost is not None and self.estimator.last_t - lost[0] <= LOST_SHOWN_S:
            return {"tracking": "lost", "tracking_note": lost[1]}
        return {"tracking": "standing" if e.standing else "walking"}

    def broadcast_health(self) -> None:
        for sub in self.subscribers:
            sub.notify(self.health(sub))

    def _broadcast(self, message: schema.BaseModel) -> None:
        for sub in self.subscribers:
            sub.notify(message)

    # --- clinician actions (between samples) --------------------------------------------------
    def change_settings(self, change: SettingsChange) -> schema.Session:
        """Validate bounds (done by the schema) and rates of change against the settings in effect,
        store the change and its events in one transaction, and only then apply them. This thread waits for
        the database writer; a coroutine uses :meth:`change_settings_async`, which lets the loop run meanwhile.

        Raises:
            SettingRejected: a rate-of-change limit, or another change still being stored; nothing changed.
            ChangeNotSaved: the database refused the write; nothing changed.
        """
        plan = self._plan_settings(change)
        if plan is None:
            return self.session
        self.saving_settings = True
        try:
            stored = self._store_settings(plan).result()
        except Exception as e:
            raise self._not_saved(e) from e
        finally:
            self.saving_settings = False
            self._settle_events()  # the events stored before it are recorded and sent first
        return self._apply_settings(plan, stored)

    async def change_settings_async(self, change: SettingsChange) -> schema.Session:
        """:meth:`change_settings` for a coroutine (the settings route): the samples go on while the database
        writer stores the change, and it is applied once stored, never before. A caller cancelled meanwhile
        does not undo it: the change, stored, is applied when the write completes.

        Raises:
            SettingRejected: a rate-of-change limit, or another change still being stored; nothing changed.
            ChangeNotSaved: the database refused the write; nothing changed.
        """
        plan = self._plan_settings(change)
        if plan is None:
            return self.session
        try:
            future = self._store_settings(plan).future
        except Exception as e:  # the writer is closed
            raise self._not_saved(e) from e
        assert future is not None  # submitted from this loop
        self.saving_settings = True
        self._applied.clear()
        try:
            stored = await asyncio.shield(future)
        except asyncio.CancelledError:
            future.add_done_callback(lambda f: self._settings_stored_late(plan, f))
            raise
        except Exception as e:
            self._settings_done()
            raise self._not_saved(e) from e
        try:
            return self._apply_settings(plan, stored)
        finally:
            self._settings_done()

    async def settings_applied(self) -> None:
        """Wait until the settings change being stored is applied (or refused): the session's next sample runs
        with the settings the database holds, at the time its events name. The other sessions do not wait."""
        while self.saving_settings:
            await self._applied.wait()

    def _settings_done(self) -> None:
        self._settle_events()  # the events stored before it are recorded and sent first
        self.saving_settings = False
        self._applied.set()

    def _plan_settings(self, change: SettingsChange) -> _SettingsPlan | None:
        """The new settings and their events, checked against the limits (None: nothing changes).

        Raises:
            SettingRejected: why not; nothing changed.
        """
        if self.saving_settings:
            raise SettingRejected("another settings change is being saved; try again in a moment")
        current = self.session.settings
        updates = {
            k: v
            for k, v in change.model_dump(exclude={"actor", "reason"}).items()
            if v is not None and v != getattr(current, k)
        }
        now = self.clock()
        for name, value in updates.items():
            if name == "primary":
                self._check_primary(value, now)
                continue
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
            return None
        new = current.model_copy(update=updates)
        t, reason = self.estimator.last_t, change.reason
        events = [
            {
                "t": t,
                "kind": "setting",
                "text": f"{name} {_shown(getattr(current, name))} -> {_shown(value)}"
                + (f", the torque blends over {self.estimator.stack.blend_s:g} s" if name == "primary" else "")
                + (f" ({reason})" if reason else ""),
                "field": name,
                "before": getattr(current, name),
                "after": value,
                "actor": change.actor,
            }
            for name, value in updates.items()
        ]
        return _SettingsPlan(new, list(updates), events, t, now)

    def _store_settings(self, plan: _SettingsPlan) -> Write[tuple[schema.Session, list[schema.Event]]]:
        write = functools.partial(
            self.store.change_settings, self.session.id, plan.new, plan.events,
            trial_id=self.trial.id if self.trial else None,
        )  # fmt: skip
        return self.writer.submit(write, f"session {self.session.id}: settings change")

    def _not_saved(self, e: Exception) -> ChangeNotSaved:
        log.error("session %d: settings change not saved: %s", self.session.id, e)
        return ChangeNotSaved(f"the change could not be saved ({_describe(e)}), so it was not applied")

    def _settings_stored_late(self, plan: _SettingsPlan, future: asyncio.Future[Any]) -> None:
        """A change whose caller was cancelled while it was being stored: applied if it was stored."""
        try:
            if not future.cancelled() and future.exception() is None:
                self._settle_events()
                self._apply_settings(plan, future.result())
        finally:
            self._settings_done()

    def _apply_settings(
        self, plan: _SettingsPlan, stored: tuple[schema.Session, list[schema.Event]]
    ) -> schema.Session:
        """Apply a stored change: the estimator retuned, the settings and their events recorded and sent."""
        session, events = stored
        self.session = session
        self.estimator.retune(plan.new)
        for name in plan.fields:
            self._last_change[name] = plan.now
        if self.recorder is not None:
            try:
                self.recorder.write("/settings", plan.t, plan.new)
                for event in events:
                    self.recorder.write_event(event)
            except (OSError, ValueError) as e:
                self._recording_failed(e)
        self._broadcast(schema.SettingsMessage(session_id=self.session.id, settings=plan.new))
        for event in events:
            self._broadcast(schema.EventMessage(event=event))
        return self.session

    def _check_primary(self, name: str, now: float) -> None:
        """A switch of the primary: to an estimator of the stack that estimates a phase and has not failed,
        at most once per ``PRIMARY_SWITCH_INTERVAL_S``.

        Raises:
            SettingRejected: why not; nothing changed.
        """
        try:
            self.estimator.stack.check_primary(name)
        except ValueError as e:
            raise SettingRejected(f"primary {name}: {e}") from e
        last = self._last_change.get("primary")
        interval = schema.PRIMARY_SWITCH_INTERVAL_S
        if last is not None and now - last < interval:
            raise SettingRejected(
                f"primary changed {now - last:.2f} s ago; switches are at least {interval:g} s apart "
                f"(try again in {interval - (now - last):.2f} s)"
            )

    def annotate(self, text: str, actor: str) -> schema.Event:
        event = self._event("annotation", text, actor=actor)
        if event is None:
            if is_disk_full(self.store_error):
                raise disk_full("the annotation was not saved", self.store_error)
            raise ChangeNotSaved("the annotation could not be saved") from self.store_error
        return event

    def _event(self, kind: schema.EventKind, text: str, **fields: object) -> schema.Event | None:
        """Store an event (waiting for the writer: what must be stored before it counts), then record and
        broadcast it; a failure to store it is logged, not raised (None)."""
        try:
            event = self._submit_event(kind, text, fields).result()
        except Exception as e:
            log.error("session %d: event %r not stored: %s", self.session.id, text, e)
            self.store_error = e
            return None
        finally:
            self._settle_events()  # the writes queued before it are made too: they are published first
        self._publish(event, self.recorder)
        return event

    def _event_soon(self, kind: schema.EventKind, text: str, **fields: object) -> None:
        """Store an event without waiting for the database (the sample path's events: intent onsets, IMU
        and estimator notes, GP-EKF learning), then record and broadcast it once stored, in the order
        they happened. With no running event loop (a caller driving :meth:`process` itself) it waits."""
        try:
            write = self._submit_event(kind, text, fields)
        except Exception as e:  # the writer is closed: the session is stopping
            log.error("session %d: event %r not stored: %s", self.session.id, text, e)
            self.store_error = e
            return
        self._pending_events.append((write, self.recorder))
        if write.future is None:
            self._settle_events(wait=True)
        else:
            write.future.add_done_callback(lambda _: self._settle_events())

    def _submit_event(self, kind: schema.EventKind, text: str, fields: dict[str, object]) -> Write[schema.Event]:
        """Queue an event's write (at the last sample's time, in the trial recording now)."""
        store = functools.partial(
            self.store.add_event,
            self.session.id,
            t=self.estimator.last_t,
            kind=kind,
            text=text,
            trial_id=self.trial.id if self.trial else None,
            **fields,  # type: ignore[arg-type]
        )
        return self.writer.submit(store, f"session {self.session.id}: event {text[:80]!r}")

    def _settle_events(self, wait: bool = False) -> None:
        """Record and broadcast the queued events the writer has stored, oldest first, up to the first one not
        stored yet (``wait``: all of them, waiting for the writer). One it could not store was logged by the
        writer and is left out (:attr:`store_error` says why)."""
        with self._settling:
            while self._pending_events:
                write, recorder = self._pending_events[0]
                if not (wait or write.done()):
                    return
                self._pending_events.popleft()
                try:
                    event = write.result()
                except Exception as e:
                    self.store_error = e
                    continue
                self._publish(event, recorder)

    def _publish(self, event: schema.Event, recorder: Recorder | None) -> None:
        """Record a stored event in the trial it happened in (if that is still recording) and broadcast it."""
        if recorder is not None and recorder is self.recorder:
            try:
                recorder.write_event(event)
            except (OSError, ValueError) as e:
                self._recording_failed(e)
        self._broadcast(schema.EventMessage(event=event))

    def start_recording(self, name: str = "") -> schema.Trial:
        """Start a new trial's recording (or return the one recording).

        Raises:
            DiskFull: the disk is (almost) full; nothing was started.
        """
        if self.trial is not None:
            return self.trial
        if self.disk_check is not None and self.disk_check() == "critical":
            raise DiskFull("the disk is almost full: free some space before recording")
        number = len(self.store.list_trials(self.session.id)) + 1
        rel = f"recordings/session{self.session.id:05d}_trial{number:03d}_{int(time.time())}.mcap"
        self.recorder = Recorder(
            self.data_dir / rel,
            self.start_ns,
            {
                "session_id": str(self.session.id),
                "subject": self.subject.code,
                "source": self.session.source.kind,
                SAMPLE_PERIOD_KEY: repr(self.sample_period),
                ESTIMATORS_KEY: ",".join(self.estimator.stack.names),
                **({} if self.fingerprint is None else {FINGERPRINT_KEY: ",".join(map(repr, self.fingerprint))}),
            },
            channels=self.estimator.recorded_channels(),
        )
        try:
            self.trial = self.writer.call(
                functools.partial(self.store.create_trial, self.session.id, name or f"trial {number}", rel),
                f"session {self.session.id}: trial {number}",
            )
        except BaseException:
            recorder, self.recorder = self.recorder, None
            with contextlib.suppress(Exception):
                recorder.finish()
            recorder.path.unlink(missing_ok=True)  # no row points at it
            raise
        self.recorder.write("/settings", self.estimator.last_t, self.session.settings)
        if self.imu_applied is not None:  # each trial holds the calibration its front ends run, for a re-run
            self.recorder.write("/imu_calibration", self.estimator.last_t, self.imu_applied)
        if self.gp_learning is not None:  # and the GP models its GP-EKF keeps from before it
            for record in self.gp_learning.kept_records(self.estimator.last_t):
                self.recorder.write("/gp_models", self.estimator.last_t, record)
        self._event("recording", f"recording started: {self.trial.name}")
        return self.trial

    def stop_recording(self) -> schema.Trial | None:
        """Finish the recording and its trial row; each step is tried even if an earlier one fails.

        A file whose index cannot be written (the disk still full) is recovered (re-indexed up to its
        last complete chunk, trial ``recovered``) or, failing that, the trial is marked ``damaged``.
        """
        if self.trial is None or self.recorder is None:
            return None
        trial, recorder = self.trial, self.recorder
        self._lasting_event(f"recording stopped: {trial.name}", kind="recording")
        self.trial, self.recorder = None, None
        status: schema.TrialStatus = "finished"
        samples, duration = recorder.samples, recorder.duration_s
        try:
            recorder.finish()
        except Exception as e:
            log.error("session %d: finishing %s failed: %s", self.session.id, recorder.path, e)
            try:
                try:
                    recover(recorder.path)
                except OSError as full:
                    if not is_disk_full(full):
                        raise
                    recover_in_place(recorder.path)  # no room for recover's copy: indexed where it lies
                samples, duration, _ = count_states(recorder.path)
                status = "recovered"
            except Exception as again:
                log.error("session %d: %s cannot be recovered: %s", self.session.id, recorder.path, again)
                status = "damaged"
            kept = f", {duration:.1f} s kept" if status == "recovered" else ""
            self._lasting_event(
                f"the recording of {trial.name} could not be finished ({_describe(e)}): {status}{kept}", trial.id
            )
        try:
            return self.writer.call(
                functools.partial(self.store.finish_trial, trial.id, status, samples, duration),
                f"session {self.session.id}: end of trial {trial.id}",
            )
        except Exception as e:  # the database's disk full: the manager stores it later, the API shows it meanwhile
            log.error("session %d: trial %d ended %s but could not be stored: %s", self.session.id, trial.id, status, e)
            stamp = dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds")
            ended = trial.model_copy(
                update={"status": status, "samples": samples, "duration_s": float(duration), "stopped_utc": stamp}
            )
            self.unsaved_trials[trial.id] = ended
            return ended

    @property
    def settings(self) -> SessionSettings:
        return self.session.settings

    @property
    def last_t(self) -> float:
        """Session time of the last sample processed."""
        return self.estimator.last_t


def count_states(path: Path) -> tuple[int, float, float]:
    """Number of gait states in a recording, the time they span, and the last one's ``t`` (0 if none)."""
    first = last = None
    n = 0
    for _, _, msg in read_messages(path, ["/gait_state"]):
        first = msg["t"] if first is None else first
        last = msg["t"]
        n += 1
    if first is None or last is None:
        return 0, 0.0, 0.0
    return n, last - first, last


def _shown(value: object) -> str:
    """A setting's value in an event's text: numbers as ``%g``."""
    return f"{value:g}" if isinstance(value, float) else str(value)


def _describe(e: BaseException) -> str:
    """An error in a user's words: its message without server paths."""
    if isinstance(e, OSError) and e.strerror:
        return e.strerror
    return str(e) or type(e).__name__
