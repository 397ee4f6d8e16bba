"""Session extensions: what a running session does beyond estimate, record and publish.

The core of a session (:class:`~gaitscope.sessions.live.runtime.SessionRuntime`) runs a frame through the
estimator stack, records it and sends it to the browsers. Everything that only some stacks need, or that
acts between samples, is an extension with a small lifecycle that the runtime calls in a loop, in the order
the extensions were given (their events are stored in that order):

- :meth:`SessionExtension.start`: the session started (its first trial is recording);
- :meth:`SessionExtension.on_trial`: a trial's recording started: write what a re-run of it needs from before;
- :meth:`SessionExtension.on_sample`: a sample was estimated, before it is recorded (its events);
- :meth:`SessionExtension.after_record`: the sample is recorded (what applies from the next sample on);
- :meth:`SessionExtension.on_tick`: once a second, between samples;
- :meth:`SessionExtension.health`: its part of data health;
- :meth:`SessionExtension.stop`: the session is stopping (never raises).

The extensions of the code base, in the runtime's order: :class:`~gaitscope.sessions.live.disk_watch.DiskWatch`,
:class:`~gaitscope.sessions.live.notes.EstimatorNotes`, :class:`~gaitscope.sessions.live.intent_events.IntentEvents`,
:class:`~gaitscope.sessions.live.imu_events.ImuEvents`,
:class:`~gaitscope.sessions.live.calibration.ImuCalibrating`,
:class:`~gaitscope.sessions.live.learning.GPLearningExtension`,
:class:`~gaitscope.sessions.live.personalization.Personalization`, :class:`~gaitscope.sessions.live.lsl_source.LslWatch`
and :class:`~gaitscope.sessions.live.lsl_outlet.GaitStateOutlet`. An extension reaches the session only
through :class:`SessionHost` (the disk watch, which ends the session, through the runtime itself).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray

from gaitscope.sessions import schema

if TYPE_CHECKING:
    from gaitscope.sessions.estimation import FrameEstimator
    from gaitscope.sessions.formats.recording import Recorder
    from gaitscope.sessions.store import Store
    from gaitscope.sessions.store_writer import StoreWriter

__all__ = ["Outputs", "SessionExtension", "SessionHost", "describe", "hooked"]

#: Every estimator's outputs at one sample, in the stack's order (None: it gave none).
Outputs = Sequence[NDArray[np.float64] | None]


class SessionHost(Protocol):
    """What a session offers its extensions."""

    session: schema.Session
    subject: schema.Subject
    store: Store
    writer: StoreWriter
    estimator: FrameEstimator
    trial: schema.Trial | None
    #: monotonic seconds (the session's injected clock)
    clock: Callable[[], float]

    def event(self, kind: schema.EventKind, text: str, **fields: object) -> schema.Event | None:
        """Store an event (waiting for the database), then record and broadcast it; None: not stored (logged)."""
        ...

    def event_soon(self, kind: schema.EventKind, text: str, **fields: object) -> None:
        """Store an event without waiting (the sample path's), recorded and broadcast once stored, in order."""
        ...

    def record(self, topic: str, message: schema.BaseModel) -> None:
        """Write a message to the trial recording now (if any) at the last sample's time; a failed write ends
        the recording and the session."""
        ...


class SessionExtension:
    """One concern of a running session; every hook does nothing unless overridden."""

    def start(self) -> None:
        """The session started; its first trial is recording."""

    def on_trial(self, recorder: Recorder, t: float) -> None:
        """A trial's recording started at session time ``t``: write to its ``recorder`` what a re-run of the
        trial needs from before it (a failed write is the trial's start failing: it raises)."""

    def on_sample(self, state: schema.GaitState, outputs: Outputs) -> None:
        """A sample was estimated (``state``, every estimator's ``outputs``), before it is recorded."""

    def after_record(self, frame: schema.SensorFrame, t: float) -> None:
        """The sample of ``frame`` at session time ``t`` is recorded."""

    def on_tick(self) -> None:
        """Once a second, between samples."""

    def health(self) -> dict[str, Any]:
        """This extension's fields of :class:`~gaitscope.sessions.schema.Health`."""
        return {}

    async def stop(self) -> None:
        """The session is stopping (before its recording is finished); must not raise."""


def hooked(extensions: Sequence[SessionExtension], hook: str) -> list[Any]:
    """The bound ``hook`` of each extension that overrides it, in order: the runtime calls only these (the
    sample path pays nothing for an extension that has nothing to do per sample)."""
    base = getattr(SessionExtension, hook)
    return [getattr(e, hook) for e in extensions if getattr(type(e), hook) is not base]


def describe(e: BaseException) -> str:
    """An error in a user's words: its message without server paths."""
    if isinstance(e, OSError) and e.strerror:
        return e.strerror
    return str(e) or type(e).__name__
