"""The running sessions of one server: start, stop, look up, and recover after a crash."""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

from estimators.pipeline import TrainedModel
from sessions import schema
from sessions.mcap_io import read_messages, recover
from sessions.models import default_model_path, load_model
from sessions.runtime import SessionRuntime
from sessions.sources import FrameSource, LiveDevice, ReplayDevice, SimulatedDevice
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
    """Owns the :class:`SessionRuntime` of every running session."""

    def __init__(
        self,
        store: Store,
        data_dir: Path,
        models: ModelStore,
        on_state: Callable[[int, schema.GaitState, float], None] | None = None,
    ):
        self.store = store
        self.data_dir = data_dir
        self.models = models
        self.on_state = on_state
        self.runtimes: dict[int, SessionRuntime] = {}

    def recover_after_crash(self) -> list[schema.Trial]:
        """Re-index recordings a crash left unfinished; mark sessions that were running as stopped."""
        recovered = []
        for trial in self.store.trials_with_status("recording"):
            path = self.data_dir / trial.path
            try:
                result = recover(path)
            except (OSError, ValueError) as e:
                log.error("could not recover %s: %s", path, e)
                continue
            samples, duration = _count(path)
            recovered.append(self.store.finish_trial(trial.id, "recovered", samples, duration))
            log.warning("recovered %s (%d messages, %d bytes lost)", path, result.messages, result.lost_bytes)
        for session in self.store.running_sessions():
            self.store.set_session_state(session.id, "stopped")
            self.store.add_event(session.id, t=0.0, kind="system", text="server restarted: session stopped")
        return recovered

    def _source(self, session: schema.Session) -> FrameSource:
        spec = session.source
        if isinstance(spec, schema.SimulatedSource):
            return SimulatedDevice(spec)
        if isinstance(spec, schema.ReplaySource):
            trial = self.store.get_trial(spec.trial_id)
            return ReplayDevice(self.data_dir / trial.path, spec.speed, spec.loop)
        if isinstance(spec, schema.DeviceSource):
            return LiveDevice()
        raise SessionStateError(f"session {session.id} holds an uploaded log ({spec.filename}); it does not run")

    def start(self, session_id: int) -> schema.Session:
        session = self.store.get_session(session_id)
        if session.state != "created":
            raise SessionStateError(f"session {session_id} is {session.state}; only a created session can start")
        subject = self.store.get_subject(session.subject_id)
        model, _ = self.models.get(session.settings.model)
        source = self._source(session)
        session = self.store.set_session_state(session_id, "running")
        runtime = SessionRuntime(session, subject, model, source, self.store, self.data_dir, self.on_state)
        self.runtimes[session_id] = runtime
        runtime.start()
        return session

    async def stop(self, session_id: int) -> schema.Session:
        session = self.store.get_session(session_id)
        runtime = self.runtimes.pop(session_id, None)
        if runtime is None:
            if session.state == "running":  # running in the database but not here: a stale record
                return self.store.set_session_state(session_id, "stopped")
            raise SessionStateError(f"session {session_id} is {session.state}, not running")
        await runtime.stop()
        return self.store.set_session_state(session_id, "stopped")

    def get(self, session_id: int) -> SessionRuntime | None:
        return self.runtimes.get(session_id)

    async def stop_all(self) -> None:
        for session_id in list(self.runtimes):
            await self.stop(session_id)


def _count(path: Path) -> tuple[int, float]:
    """Number of gait states in a recording and the time they span."""
    first = last = None
    n = 0
    for _, _, msg in read_messages(path, ["/gait_state"]):
        first = msg["t"] if first is None else first
        last = msg["t"]
        n += 1
    return n, (last - first) if first is not None and last is not None else 0.0
