"""The running sessions of one server: start, stop, look up, and recover after a crash."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Callable
from pathlib import Path

from estimators.pipeline import TrainedModel
from sessions import schema
from sessions.errors import DataFormatError
from sessions.formats.mcap_io import read_messages, recover
from sessions.formats.models import default_model_path, load_model
from sessions.live.gp_learning import GPTrainer
from sessions.live.runtime import DiskState, SessionRuntime
from sessions.live.sources import FrameSource, LiveDevice, ReplayDevice, SimulatedDevice
from sessions.live.subscribers import attach_history
from sessions.store import Store

log = logging.getLogger("gaitscope")


class SessionStateError(RuntimeError):
    """An action that the session's state does not allow (start a running session, ...)."""


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
    (:class:`~sessions.live.gp_learning.GPTrainer`: started by the first session that runs ``gp_ekf``, stopped
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
    ):
        self.store = store
        self.node = node  # this process's name in the shared database (Settings.node)
        self.data_dir = data_dir
        self.models = models
        self.on_state = on_state
        self.disk_check = disk_check
        self.runtimes: dict[int, SessionRuntime] = {}
        self.gp_trainer = gp_trainer or GPTrainer()

    def recover_after_crash(self) -> list[schema.Trial]:
        """At start-up: end every trial and session that a crash left open; returns the recovered trials.

        Only this process's (its :attr:`node`'s, and those of no node): sessions another process runs on the
        same database, and their recordings, are that process's.

        Every trial still ``recording`` ends ``recovered`` when :func:`~sessions.formats.mcap_io.recover`
        re-indexes its file (a kill loses at most the last ~0.5 s, :mod:`sessions.formats.recording`), else
        ``damaged``: the file is missing, not MCAP, or could not be rewritten (disk full, no
        permission). Either way its session gets a system event saying so in the user's words,
        without server paths. One trial's failure never stops the others or the server. Every
        session still ``running`` (live, simulated or a replay) becomes ``stopped`` with an event,
        at the last session time known for it, so the event ends its timeline.
        """
        recovered = []
        last_t: dict[int, float] = {}  # session -> latest session time seen in its recovered trials
        elsewhere = {s.id for s in self.store.running_sessions() if s.node not in (None, self.node)}
        for trial in self.store.trials_with_status("recording"):
            if trial.session_id in elsewhere:
                continue  # another process's session, recording now: not this one's to recover
            path = self.data_dir / trial.path
            try:
                result = recover(path)
                samples, duration, end_t = _count(path)
            except Exception as e:
                expected = isinstance(e, OSError | DataFormatError)  # else a bug: log its traceback
                log.error("trial %d: could not recover %s: %s", trial.id, path, e, exc_info=not expected)
                self.store.finish_trial(trial.id, "damaged", trial.samples, trial.duration_s)
                text = f"server restarted: the recording of {trial.name} is lost: {_damage(e)}"
                t = _last_event_t(self.store, trial.session_id)
                self.store.add_event(trial.session_id, t=t, kind="system", text=text, trial_id=trial.id)
                continue
            recovered.append(self.store.finish_trial(trial.id, "recovered", samples, duration))
            last_t[trial.session_id] = max(last_t.get(trial.session_id, 0.0), end_t)
            text = (
                f"server restarted: the recording of {trial.name} was interrupted and has been recovered "
                f"({duration:.1f} s kept; the last half second before the interruption may be missing)"
            )
            self.store.add_event(trial.session_id, t=end_t, kind="system", text=text, trial_id=trial.id)
            log.warning("recovered %s (%d messages, %d bytes lost)", path, result.messages, result.lost_bytes)
        for session in self.store.running_sessions(self.node):
            self.store.set_session_state(session.id, "stopped")
            t = max(last_t.get(session.id, 0.0), _last_event_t(self.store, session.id))
            self.store.add_event(session.id, t=t, kind="system", text="server restarted: session stopped")
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
        raise SessionStateError(f"session {session.id} holds an uploaded log ({spec.filename}); it does not run")

    def start(self, session_id: int) -> schema.Session:
        """Start a created session; if it cannot start, it is left ``failed`` with an event saying why.

        Raises:
            SessionStateError: not ``created``, or its estimator stack cannot run on its source (the
                message names the missing channels).
        """
        session = self.store.get_session(session_id)
        if session.state != "created":
            raise SessionStateError(f"session {session_id} is {session.state}; only a created session can start")
        subject = self.store.get_subject(session.subject_id)
        model, _ = self.models.get(session.settings.model)
        source = self._source(session)
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
                on_end=self._ended,
                gp_trainer=self.gp_trainer,
            )
        except ValueError as e:  # the estimator stack: unknown names, missing channels (MissingChannels)
            with contextlib.suppress(Exception):
                self.store.add_event(session_id, t=0.0, kind="system", text=f"session refused to start: {e}")
            self.store.set_session_state(session_id, "failed")
            raise SessionStateError(f"session {session_id} cannot start: {e}") from e
        session = runtime.session = self.store.set_session_state(session_id, "running", self.node)
        attach_history(runtime)  # the last 30 s for a browser that opens the session later, from the first sample
        try:
            runtime.start()
        except Exception as e:
            log.exception("session %d did not start", session_id)
            with contextlib.suppress(Exception):
                self.store.add_event(session_id, t=0.0, kind="system", text=f"session failed to start: {e}")
            with contextlib.suppress(Exception):
                runtime.stop_recording()
            self.store.set_session_state(session_id, "failed")
            raise
        self.runtimes[session_id] = runtime
        return session

    async def _ended(self, runtime: SessionRuntime, state: schema.SessionState, reason: str) -> None:
        """A session ended by itself: forget its runtime and store its final state."""
        if self.runtimes.get(runtime.session.id) is runtime:
            del self.runtimes[runtime.session.id]
        try:
            self.store.set_session_state(runtime.session.id, state)
        except Exception:
            log.exception("session %d ended (%s) but its state could not be stored", runtime.session.id, reason)

    async def stop(self, session_id: int) -> schema.Session:
        """Stop a running session: the recording is finished and the session stopped, whatever fails."""
        session = self.store.get_session(session_id)
        runtime = self.runtimes.pop(session_id, None)
        if runtime is None:
            if session.state == "running" and session.node not in (None, self.node):
                raise SessionStateError(f"session {session_id} runs on {session.node}: stop it there")
            if session.state == "running":  # running in the database but not here: a stale record
                return self.store.set_session_state(session_id, "stopped")
            raise SessionStateError(f"session {session_id} is {session.state}, not running")
        try:
            await runtime.stop()
        finally:
            session = self.store.set_session_state(session_id, "stopped")
        return session

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
        try:
            await asyncio.to_thread(self.gp_trainer.shutdown)
        except Exception:
            log.exception("the GP fit worker did not stop cleanly")


def _count(path: Path) -> tuple[int, float, float]:
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
