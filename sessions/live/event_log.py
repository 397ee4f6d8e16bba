"""A session's events: stored by the database writer, then recorded in the trial and sent to the browsers.

Two ways in: :meth:`EventLog.event` waits for the writer (what must be stored before it counts: a clinician's
annotation, a calibration), :meth:`EventLog.event_soon` does not (the sample path's events: intent onsets, IMU
and estimator notes, GP-EKF learning), so that a sample never waits for the database. Either way the events
are recorded and sent once stored, in the order they happened, each in the trial that was recording when it
happened. An event that must reach the database (a trial's or the session's end) and cannot now (a full disk)
is kept for the manager to store later (:meth:`EventLog.lasting_event`).
"""

from __future__ import annotations

import functools
import logging
import threading
from collections import deque
from typing import TYPE_CHECKING

from gaitscope.sessions import schema
from gaitscope.sessions.formats.recording import Recorder
from gaitscope.sessions.store_writer import Write

if TYPE_CHECKING:
    from gaitscope.sessions.live.runtime import SessionRuntime

__all__ = ["EventLog"]

log = logging.getLogger("gaitscope")


class EventLog:
    """The events of one session (see the module docstring); failures to store are logged and kept in the
    runtime's ``store_error``, never raised."""

    def __init__(self, runtime: SessionRuntime):
        self.rt = runtime
        #: events submitted to the writer and not yet recorded and broadcast, in order, each with the
        #: recorder that was recording when it happened (:meth:`event_soon`)
        self._pending: deque[tuple[Write[schema.Event], Recorder | None]] = deque()
        self._settling = threading.RLock()  # a sync route's thread may settle them too (a promotion)

    def event(self, kind: schema.EventKind, text: str, **fields: object) -> schema.Event | None:
        """Store an event (waiting for the writer: what must be stored before it counts), then record and
        broadcast it; a failure to store it is logged, not raised (None)."""
        try:
            event = self._submit_event(kind, text, fields).result()
        except Exception as e:
            log.error("session %d: event %r not stored: %s", self.rt.session.id, text, e)
            self.rt.store_error = e
            return None
        finally:
            self.settle()  # the writes queued before it are made too: they are published first
        self._publish(event, self.rt.recorder)
        return event

    def event_soon(self, kind: schema.EventKind, text: str, **fields: object) -> None:
        """Store an event without waiting for the database (the sample path's events: intent onsets, IMU
        and estimator notes, GP-EKF learning), then record and broadcast it once stored, in the order
        they happened. With no running event loop (a caller driving :meth:`process` itself) it waits."""
        try:
            write = self._submit_event(kind, text, fields)
        except Exception as e:  # the writer is closed: the session is stopping
            log.error("session %d: event %r not stored: %s", self.rt.session.id, text, e)
            self.rt.store_error = e
            return
        self._pending.append((write, self.rt.recorder))
        if write.future is None:
            self.settle(wait=True)
        else:
            write.future.add_done_callback(lambda _: self.settle())

    def _submit_event(self, kind: schema.EventKind, text: str, fields: dict[str, object]) -> Write[schema.Event]:
        """Queue an event's write (at the last sample's time, in the trial recording now)."""
        store = functools.partial(
            self.rt.store.add_event,
            self.rt.session.id,
            t=self.rt.estimator.last_t,
            kind=kind,
            text=text,
            trial_id=self.rt.trial.id if self.rt.trial else None,
            **fields,  # type: ignore[arg-type]
        )
        return self.rt.writer.submit(store, f"session {self.rt.session.id}: event {text[:80]!r}")

    def settle(self, wait: bool = False) -> None:
        """Record and broadcast the queued events the writer has stored, oldest first, up to the first one not
        stored yet (``wait``: all of them, waiting for the writer). One it could not store was logged by the
        writer and is left out (:attr:`store_error` says why)."""
        with self._settling:
            while self._pending:
                write, recorder = self._pending[0]
                if not (wait or write.done()):
                    return
                self._pending.popleft()
                try:
                    event = write.result()
                except Exception as e:
                    self.rt.store_error = e
                    continue
                self._publish(event, recorder)

    def _publish(self, event: schema.Event, recorder: Recorder | None) -> None:
        """Record a stored event in the trial it happened in (if that is still recording) and broadcast it."""
        if recorder is not None and recorder is self.rt.recorder:
            self.rt.write_recording(lambda r: r.write_event(event))
        self.rt.broadcast(schema.EventMessage(event=event))

    def lasting_event(self, text: str, trial_id: int | None = None, kind: schema.EventKind = "system") -> None:
        """An event that must reach the database (a trial's or the session's end): when it cannot be stored now
        (a full disk), it is kept in :attr:`unsaved_events` for the manager to store later."""
        trial_id = trial_id if trial_id is not None else self.rt.trial.id if self.rt.trial else None
        if self.event(kind, text) is None:
            self.rt.unsaved_events.append(
                {"session_id": self.rt.session.id, "t": self.rt.estimator.last_t, "kind": kind, "text": text,
                 "trial_id": trial_id}
            )  # fmt: skip
