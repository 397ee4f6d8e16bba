"""The running sessions of one server: start, stop, look up, and recover after a crash."""

from __future__ import annotations

import asyncio
import contextlib
import datetime as dt
import json
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final, NoReturn

from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.sessions import schema
from gaitscope.sessions.errors import DataFormatError, DiskFull, disk_full, is_disk_full
from gaitscope.sessions.formats.mcap_io import recover
from gaitscope.sessions.formats.models import default_model_path, load_model
from gaitscope.sessions.live.gp_learning import GPTrainer
from gaitscope.sessions.live.lsl_source import LslDevice, LslRefused, open_stream
from gaitscope.sessions.live.runtime import DiskState, SessionRuntime
from gaitscope.sessions.live.sources import FrameSource, LiveDevice, ReplayDevice, SimulatedDevice
from gaitscope.sessions.live.subscribers import attach_history
from gaitscope.sessions.live.trials import count_states
from gaitscope.sessions.mappings.saved import SavedMappings
from gaitscope.sessions.store import Store
from gaitscope.sessions.store_writer import StoreWriter

log = logging.getLogger("gaitscope")


#: Seconds between two tries to store what the database refused when a session ended (a full disk).
RETRY_S: Final = 2.0


class SessionStateError(RuntimeError):
    """An action that the session's state does not allow (start a running session, ...)."""


@dataclass
class Unsaved:
    """A session that ended here but whose end the database could not store yet (its disk full).

    Attributes:
        session: the session as it is: its final state (what the API shows meanwhile).
        reason: why it ended, in the user's words.
        trials: its trials' final rows, by id, not stored yet (shown meanwhile).
        events: the events that end them or the session (``Store.add_event``'s arguments), not stored yet.
        error: the last failure to store them.
    """

    session: schema.Session
    reason: str
    trials: dict[int, schema.Trial] = field(default_factory=dict)
    events: list[dict[str, Any]] = field(default_factory=list)
    error: Exception | None = None


class ModelStore:
    """Fitted models by name: ``default`` ships with gaitscope; others are ``<data>/models/<name>.npz``."""

    def __init__(self, folder: Path):
        self.folder = folder
        folder.mkdir(parents=True, exist_ok=True)
        self._cache: dict[str, tuple[TrainedModel, schema.ModelProvenance]] = {}

    def path(self, name: str) -> Path:
        return default_model_path() if name == "default" else self.folder / f"{name}.npz"

    def get(self, name: str) -> tuple[TrainedModel, schema.ModelProvenance]:
        if name not in self._cache:
            self._cache[name] = load_model(self.path(name))
        return self._cache[name]

    def names(self) -> list[str]:
        return ["default", *sorted(p.stem for p in self.folder.glob("*.npz"))]


class SessionManager:
    """Owns the :class:`SessionRuntime` of every running session, and the worker their GP-EKFs' fits share
    (:class:`~gaitscope.sessions.live.gp_learning.GPTrainer`: started by the first session that runs ``gp_ekf``, stopped
    by :meth:`stop_all`)."""

    def __init__(
        self,
        store: Store,
        data_dir: Path,
        models: ModelStore,
        on_state: Callable[[int, schema.GaitState, float], None] | None = None,
        disk_check: Callable[[], DiskState] | None = None,
        gp_trainer: GPTrainer | None = None,
        node: str | None = None,
        disk_room: Callable[[], int | None] | None = None,
        writer: StoreWriter | None = None,
        clock: Callable[[], float] = time.monotonic,
    ):
        self.store = store
        self.clock = clock  # monotonic seconds, handed to every session (SessionRuntime's clock)
        self.node = node  # this process's name in the shared database (Settings.node)
        self.data_dir = data_dir
        self.models = models
        self.on_state = on_state
        self.disk_check = disk_check
        self.disk_room = disk_room  # bytes left before the disk guard stops (DiskGuard.room)
        self.runtimes: dict[int, SessionRuntime] = {}
        self.gp_trainer = gp_trainer or GPTrainer()
        self.writer = writer  # the sessions' database writer (sessions.store_writer); None: each starts its own
        #: Sessions that ended here whose end is not stored yet, by id: retried every ``RETRY_S`` (:meth:`reconcile`)
        self.unsaved: dict[int, Unsaved] = {}
        self._retrying: asyncio.Task[None] | None = None

    def recover_after_crash(self, node: str | None = None) -> list[schema.Trial]:
        """At start-up: end every trial and session that a crash left open; returns the recovered trials.

        Only this process's (its :attr:`node`'s, and those of no node): sessions another process runs on the
        same database, and their recordings, are that process's. ``node``: another node's instead, one this
        process declared gone (:meth:`gaitscope.sessions.cluster.nodes.Nodes.claim_gone`): its sessions and
        recordings (and not those of no node), with events that say that node stopped answering.

        Every trial still ``recording`` ends ``recovered`` when :func:`~gaitscope.sessions.formats.mcap_io.recover`
        re-indexes its file (a kill loses at most the last ~0.5 s, :mod:`gaitscope.sessions.formats.recording`), else
        ``damaged``: the file is missing, not MCAP, or could not be rewritten (disk full, no
        permission). Either way its session gets a system event saying so in the user's words,
        without server paths. One trial's failure never stops the others or the server. Every
        session still ``running`` (live, simulated or a replay) becomes ``stopped`` with an event,
        at the last session time known for it, so the event ends its timeline.
        """
        recovered = []
        last_t: dict[int, float] = {}  # session -> latest session time seen in its recovered trials
        mine = node is None or node == self.node
        owner = self.node if mine else node
        why = "server restarted" if mine else f"server process {node} stopped answering"
        running = self.store.running_sessions(owner)
        if not mine:
            running = [s for s in running if s.node == node]  # not those of no node: this process's own
        ids = {s.id for s in running}
        elsewhere = {s.id for s in self.store.running_sessions() if s.id not in ids}
        for trial in self.store.trials_with_status("recording"):
            if trial.session_id in elsewhere or (not mine and trial.session_id not in ids):
                continue  # another process's session, recording now: not this one's to recover
            path = self.data_dir / trial.path
            try:
                result = recover(path)
                samples, duration, end_t = count_states(path)
            except Exception as e:
                expected = isinstance(e, OSError | DataFormatError)  # else a bug: log its traceback
                log.error("trial %d: could not recover %s: %s", trial.id, path, e, exc_info=not expected)
                self.store.finish_trial(trial.id, "damaged", trial.samples, trial.duration_s)
                text = f"{why}: the recording of {trial.name} is lost: {_damage(e)}"
                t = _last_event_t(self.store, trial.session_id)
                self.store.add_event(trial.session_id, t=t, kind="system", text=text, trial_id=trial.id)
                continue
            recovered.append(self.store.finish_trial(trial.id, "recovered", samples, duration))
            last_t[trial.session_id] = max(last_t.get(trial.session_id, 0.0), end_t)
            text = (
                f"{why}: the recording of {trial.name} was interrupted and has been recovered "
                f"({duration:.1f} s kept; the last half second before the interruption may be missing)"
            )
            self.store.add_event(trial.session_id, t=end_t, kind="system", text=text, trial_id=trial.id)
            log.warning("recovered %s (%d messages, %d bytes lost)", path, result.messages, result.lost_bytes)
        for session in running:
            self.store.set_session_state(session.id, "stopped")
            t = max(last_t.get(session.id, 0.0), _last_event_t(self.store, session.id))
            self.store.add_event(session.id, t=t, kind="system", text=f"{why}: session stopped")
        return recovered

    def _source(self, session: schema.Session) -> FrameSource:
        spec = session.source
        if isinstance(spec, schema.SimulatedSource):
            return SimulatedDevice(spec)
        if isinstance(spec, schema.ReplaySource):
            trial = self.store.get_trial(spec.trial_id)
            return ReplayDevice(self.data_dir / trial.path, spec.speed, spec.loop)
        if isinstance(spec, schema.DeviceSource):
            return LiveDevice(spec.rate_hz, channels=spec.channels)
        if isinstance(spec, schema.LslSource):  # blocks while it resolves: a coroutine calls start_async
            return open_stream(spec, SavedMappings(self.store).get)
        raise SessionStateError(f"session {session.id} holds an uploaded log ({spec.filename}); it does not run")

    async def start_async(self, session_id: int, actor: str) -> schema.Session:
        """:meth:`start` for a coroutine: a source that takes time to open (an LSL stream, resolved on the network
        for up to its timeout) is opened in a worker thread first. An LSL source given a mapping saves it for the
        stream's rig once the session runs (``actor`` saved it).

        Raises:
            SessionStateError: as :meth:`start`, and an LSL stream that is not found or does not fit its mapping.
        """
        session = self.store.get_session(session_id)
        spec = session.source
        if not isinstance(spec, schema.LslSource) or session.state != "created":
            return self.start(session_id)
        mappings = SavedMappings(self.store)
        try:
            source = await asyncio.to_thread(open_stream, spec, mappings.get)
        except LslRefused as e:
            self._refuse(session_id, e)
        started = self.start(session_id, source)
        if spec.mapping is not None:  # the rig's next session maps itself
            try:
                await asyncio.to_thread(mappings.save, source.rig, "lsl", json.dumps(source.mapping), actor)
            except Exception:
                log.exception("session %d: the LSL mapping of rig %s was not saved", session_id, source.rig)
        return started

    def _refuse(self, session_id: int, e: Exception) -> NoReturn:
        """Leave a session that cannot start ``failed``, with an event saying why, and raise that."""
        with contextlib.suppress(Exception):
            self.store.add_event(session_id, t=0.0, kind="system", text=f"session refused to start: {e}")
        self.store.set_session_state(session_id, "failed")
        raise SessionStateError(f"session {session_id} cannot start: {e}") from e

    def start(self, session_id: int, source: FrameSource | None = None) -> schema.Session:
        """Start a created session; if it cannot start, it is left ``failed`` with an event saying why.

        ``source``: its source, opened already (:meth:`start_async`); None: opened here.

        Raises:
            SessionStateError: not ``created``, or its estimator stack cannot run on its source (the
                message names the missing channels).
        """
        session = self.store.get_session(session_id)
        if session.state != "created":
            raise SessionStateError(f"session {session_id} is {session.state}; only a created session can start")
        subject = self.store.get_subject(session.subject_id)
        model, _ = self.models.get(session.settings.model)
        if source is None:
            try:
                source = self._source(session)
            except LslRefused as e:
                self._refuse(session_id, e)
        try:
            runtime = SessionRuntime(
                session,
                subject,
                model,
                source,
                self.store,
                self.data_dir,
                self.on_state,
                disk_check=self.disk_check,
                disk_room=self.disk_room,
                on_end=self._ended,
                gp_trainer=self.gp_trainer,
                writer=self.writer,
                clock=self.clock,
            )
        except ValueError as e:  # the estimator stack: unknown names, missing channels (MissingChannels)
            if isinstance(source, LslDevice):
                source.close()
            self._refuse(session_id, e)
        try:
            session = runtime.session = self.store.set_session_state(session_id, "running", self.node)
        except Exception as e:
            if is_disk_full(e):
                raise disk_full(f"session {session_id} did not start", e) from e
            raise
        attach_history(runtime)  # the last 30 s for a browser that opens the session later, from the first sample
        try:
            runtime.start()
        except Exception as e:
            log.exception("session %d did not start", session_id)
            with contextlib.suppress(Exception):
                runtime.stop_recording()
            runtime.unsaved_events.append(
                {"session_id": session_id, "t": 0.0, "kind": "system", "text": f"session failed to start: {e}"}
            )
            self._finish(runtime, "failed", f"session failed to start: {e}")
            if is_disk_full(e) and not isinstance(e, DiskFull):
                raise disk_full(f"session {session_id} did not start", e) from e
            raise
        self.runtimes[session_id] = runtime
        return session

    async def _ended(self, runtime: SessionRuntime, state: schema.SessionState, reason: str) -> None:
        """A session ended by itself: forget its runtime and store its final state (later if it cannot now)."""
        if self.runtimes.get(runtime.session.id) is runtime:
            del self.runtimes[runtime.session.id]
        self._finish(runtime, state, reason)

    def _finish(self, runtime: SessionRuntime, state: schema.SessionState, reason: str) -> schema.Session:
        """Store a session's end: its trials' final rows and events that its runtime could not store, then its
        state. What the database refuses (a full disk) is kept in :attr:`unsaved`, shown by the API as it is,
        and retried every ``RETRY_S`` until stored. Never raises; returns the session as it now is."""
        sid = runtime.session.id
        stamp = dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds")
        ended = runtime.session.model_copy(update={"state": state, "stopped_utc": stamp})
        unsaved = self.unsaved.setdefault(sid, Unsaved(ended, reason))
        unsaved.trials.update(runtime.unsaved_trials)
        unsaved.events += runtime.unsaved_events
        runtime.unsaved_trials, runtime.unsaved_events = {}, []
        if self._store(sid) is None:
            return self.store.get_session(sid)
        log.error("session %d ended (%s) but the database refused it (%s): retried every %g s",
                  sid, reason, unsaved.error, RETRY_S)  # fmt: skip
        with contextlib.suppress(RuntimeError):  # no running loop (start-up): retried by the next call
            if self._retrying is None or self._retrying.done():
                self._retrying = asyncio.get_running_loop().create_task(self._retry(), name="store-unsaved")
        return unsaved.session

    def _store(self, session_id: int) -> Exception | None:
        """Store what :attr:`unsaved` keeps of one session, in order (trials, events, state); stops at the first
        failure, which it returns (None: all stored and forgotten)."""
        unsaved = self.unsaved[session_id]
        try:
            for trial_id, trial in list(unsaved.trials.items()):
                self.store.finish_trial(trial_id, trial.status, trial.samples, trial.duration_s)
                del unsaved.trials[trial_id]
            while unsaved.events:
                self.store.add_event(**unsaved.events[0])
                unsaved.events.pop(0)
            self.store.set_session_state(session_id, unsaved.session.state)
        except Exception as e:
            unsaved.error = e
            return e
        del self.unsaved[session_id]
        return None

    def reconcile(self) -> bool:
        """Try again to store every session's end that the database refused; True when nothing is left."""
        for session_id in list(self.unsaved):
            if self._store(session_id) is None:
                log.warning("session %d: its end is stored now", session_id)
        return not self.unsaved

    async def _retry(self) -> None:
        while not self.reconcile():
            await asyncio.sleep(RETRY_S)

    def shown(self, session: schema.Session) -> schema.Session:
        """``session`` as it is: its final state if it ended here and the database does not have it yet."""
        unsaved = self.unsaved.get(session.id)
        return session if unsaved is None else unsaved.session

    def shown_trial(self, trial: schema.Trial) -> schema.Trial:
        """``trial`` as it is: its final row if it ended here and the database does not have it yet; while it
        records here, with the samples and the duration recorded so far (the row has them once it stops)."""
        runtime = self.runtimes.get(trial.session_id)
        if runtime is not None and trial.id in runtime.unsaved_trials:  # stored when its session ends
            return runtime.unsaved_trials[trial.id]
        current = None if runtime is None else runtime.trial
        recorder = None if runtime is None or current is None or current.id != trial.id else runtime.recorder
        if recorder is not None and trial.status == "recording":
            return trial.model_copy(update={"samples": recorder.samples, "duration_s": float(recorder.duration_s)})
        unsaved = self.unsaved.get(trial.session_id)
        return trial if unsaved is None else unsaved.trials.get(trial.id, trial)

    async def stop(self, session_id: int) -> schema.Session:
        """Stop a running session: the recording is finished and the session stopped, whatever fails.

        Raises:
            SessionStateError: not running (here).
            gaitscope.sessions.errors.DiskFull: it stopped, but the database could not store that (its disk full):
                stored later (:meth:`reconcile`); or it had ended already and that is still not stored.
        """
        session = self.shown(self.store.get_session(session_id))
        runtime = self.runtimes.pop(session_id, None)
        if runtime is None:
            if session_id in self.unsaved:  # it ended here: try to store that again
                self.reconcile()
                if (unsaved := self.unsaved.get(session_id)) is not None:
                    raise self._not_stored(session_id, f"session {session_id} is already {session.state} "
                                           f"({unsaved.reason})", unsaved.error)  # fmt: skip
                raise SessionStateError(f"session {session_id} is {session.state}, not running")
            if session.state == "running" and session.node not in (None, self.node):
                raise SessionStateError(f"session {session_id} runs on {session.node}: stop it there")
            if session.state == "running":  # running in the database but not here: a stale record
                try:
                    return self.store.set_session_state(session_id, "stopped")
                except Exception as e:
                    raise self._not_stored(session_id, f"session {session_id} could not be stopped", e) from e
            raise SessionStateError(f"session {session_id} is {session.state}, not running")
        try:
            await runtime.stop()
        finally:
            session = self._finish(runtime, "stopped", "stopped by the API")
        if (unsaved := self.unsaved.get(session_id)) is not None:
            raise self._not_stored(session_id, f"session {session_id} stopped", unsaved.error)
        return session

    def _not_stored(self, session_id: int, what: str, error: Exception | None) -> Exception:
        """The error for a session's end the database did not take: :class:`DiskFull` when its disk is full."""
        if not is_disk_full(error):
            return error or RuntimeError(f"{what}: not stored")
        later = " (stored as soon as there is room; the API shows it meanwhile)" if session_id in self.unsaved else ""
        return disk_full(f"{what}, but the database could not store that{later}", error)

    def get(self, session_id: int) -> SessionRuntime | None:
        return self.runtimes.get(session_id)

    def running(self) -> list[SessionRuntime]:
        """The runtimes of the running sessions."""
        return list(self.runtimes.values())

    async def stop_all(self) -> None:
        for session_id in list(self.runtimes):
            try:
                await self.stop(session_id)
            except Exception:
                log.exception("session %d: stop at shutdown failed", session_id)
        if self._retrying is not None:
            self._retrying.cancel()
        if not self.reconcile():  # left to the next start-up's recovery (recover_after_crash)
            log.error("sessions %s ended, but the database could not store that", sorted(self.unsaved))
        try:
            await asyncio.to_thread(self.gp_trainer.shutdown)
        except Exception:
            log.exception("the GP fit worker did not stop cleanly")


def _last_event_t(store: Store, session_id: int) -> float:
    """Session time of a session's latest event (0 if none): the last time known for it."""
    return max((e.t for e in store.list_events(session_id)), default=0.0)


def _damage(e: Exception) -> str:
    """Why a recording could not be recovered, in a user's words (no server paths)."""
    if isinstance(e, FileNotFoundError):
        return "its file is missing"
    if isinstance(e, DataFormatError):
        return "its file is damaged beyond repair"
    if isinstance(e, OSError):
        return f"its file could not be repaired ({e.strerror or type(e).__name__})"
    return "its file could not be repaired (see the server log)"
