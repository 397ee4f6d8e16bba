"""A session's trials: each one's recording started, finished, and ended early when a write fails.

A trial is a row in the database and an MCAP recording (:class:`~gaitscope.sessions.formats.recording.Recorder`);
the runtime records every sample into the one recording now (``SessionRuntime.recorder``). A recording starts
with what a re-run of it needs (the settings, the whole estimation state at that moment:
:mod:`~gaitscope.sessions.formats.stack_state`, and what the extensions write); it finishes with its row, each
step tried even if an earlier one fails: a file whose index cannot be written is recovered or marked damaged,
and a row that cannot be stored (the database's disk full) is kept for the manager to store later.
"""

from __future__ import annotations

import asyncio
import contextlib
import datetime as dt
import functools
import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from gaitscope.sessions import schema
from gaitscope.sessions.errors import FREE_SPACE_HINT, DiskFull, is_disk_full
from gaitscope.sessions.formats import stack_state
from gaitscope.sessions.formats.mcap_io import read_messages, recover, recover_in_place
from gaitscope.sessions.formats.recording import ESTIMATORS_KEY, FINGERPRINT_KEY, SAMPLE_PERIOD_KEY, Recorder
from gaitscope.sessions.live.extensions import describe
from gaitscope.sessions.personalization.intent_model import INTENT_MODEL_KEY, config_of, to_metadata

if TYPE_CHECKING:
    from gaitscope.sessions.live.runtime import SessionRuntime

__all__ = ["Trials", "count_states"]

log = logging.getLogger("gaitscope")


class Trials:
    """The trials of one session (see the module docstring)."""

    def __init__(self, runtime: SessionRuntime):
        self.rt = runtime
        self._failing = False  # failed() is finishing the recording (not re-entered)
        #: the estimation state being encoded off the loop: its recording, session time and encoding
        self._state: tuple[Recorder, float, Callable[[], bytes]] | None = None

    def start(self, name: str = "") -> schema.Trial:
        """Start a new trial's recording (or return the one recording).

        Raises:
            DiskFull: the disk is (almost) full; nothing was started.
        """
        rt = self.rt
        if rt.trial is not None:
            return rt.trial
        if rt.disk_check is not None and rt.disk_check() == "critical":
            raise DiskFull("the disk is almost full: free some space before recording")
        number = len(rt.store.list_trials(rt.session.id)) + 1
        rel = f"recordings/session{rt.session.id:05d}_trial{number:03d}_{int(time.time())}.mcap"
        rt.recorder = Recorder(
            rt.data_dir / rel,
            rt.start_ns,
            {
                "session_id": str(rt.session.id),
                "subject": rt.subject.code,
                "source": rt.session.source.kind,
                SAMPLE_PERIOD_KEY: repr(rt.sample_period),
                ESTIMATORS_KEY: ",".join(rt.estimator.stack.names),
                **({} if rt.fingerprint is None else {FINGERPRINT_KEY: ",".join(map(repr, rt.fingerprint))}),
                **({} if (m := rt.intent_model) is None else {INTENT_MODEL_KEY: to_metadata(config_of(m), m.variant)}),
            },
            channels=rt.estimator.recorded_channels(),
        )
        try:
            rt.trial = rt.writer.call(
                functools.partial(rt.store.create_trial, rt.session.id, name or f"trial {number}", rel),
                f"session {rt.session.id}: trial {number}",
            )
        except BaseException:
            recorder, rt.recorder = rt.recorder, None
            with contextlib.suppress(Exception):
                recorder.finish()
            recorder.path.unlink(missing_ok=True)  # no row points at it
            raise
        rt.recorder.write("/settings", rt.estimator.last_t, rt.session.settings)
        self._record_state()
        for extension in rt.extensions:  # what a re-run of the trial needs from before it
            extension.on_trial(rt.recorder, rt.estimator.last_t)
        rt.event("recording", f"recording started: {rt.trial.name}")
        return rt.trial

    def _record_state(self) -> None:
        """Record the estimation state a re-run resumes from (:mod:`~gaitscope.sessions.formats.stack_state`).

        Taken on the loop, between two samples: the pickle is the copy (under 1 ms for the default stack,
        ``docs/results.md``). Its encoding (base64 and SHA-256, a quarter of that) runs on a worker thread when
        there is a loop; the message is written when it is back, at the session time of the trial's start
        (:meth:`stop` writes it first if it is not back yet). A stack that cannot be pickled (a test double) is
        recorded without it: its re-runs start from fresh filters, and say so."""
        rt = self.rt
        recorder = rt.recorder
        assert recorder is not None
        t = rt.estimator.last_t
        try:
            data = stack_state.capture(rt.estimator, rt.model)
        except Exception as e:  # whatever pickling an estimator raises
            log.warning("session %d: the estimation state cannot be recorded: %s", rt.session.id, describe(e))
            return
        encode = functools.partial(stack_state.encoded, t, rt.estimator.stack.names, data)
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:  # driven without a loop (tests, tools): encoded here
            self._write_state(recorder, t, encode())
            return
        self._state = (recorder, t, encode)
        future = loop.run_in_executor(None, encode)

        def done(f: asyncio.Future[bytes]) -> None:
            if self._state is None or self._state[0] is not recorder:
                return  # written by stop(), or another trial's
            self._state = None
            if f.cancelled() or f.exception() is not None:
                log.warning("session %d: the estimation state could not be encoded: %s", rt.session.id, f)
                return
            self._write_state(recorder, t, f.result())

        future.add_done_callback(done)

    def _write_state(self, recorder: Recorder, t: float, data: bytes) -> None:
        """Write an encoded estimation state to ``recorder`` if it is still the trial's recording."""
        if self.rt.recorder is recorder:
            self.rt.write_recording(lambda r: r.write_json(t, ((stack_state.TOPIC, data),)))

    def stop(self) -> schema.Trial | None:
        """Finish the recording and its trial row; each step is tried even if an earlier one fails.

        A file whose index cannot be written (the disk still full) is recovered (re-indexed up to its
        last complete chunk, trial ``recovered``) or, failing that, the trial is marked ``damaged``.
        """
        rt = self.rt
        if rt.trial is None or rt.recorder is None:
            return None
        trial, recorder = rt.trial, rt.recorder
        if self._state is not None:  # the state's encoding is not back yet: it goes in before the trial ends
            state, self._state = self._state, None
            if state[0] is recorder:
                try:
                    self._write_state(recorder, state[1], state[2]())
                except Exception as e:  # the trial ends whatever happens
                    log.warning("session %d: the estimation state could not be encoded: %s", rt.session.id, e)
        rt.events.lasting_event(f"recording stopped: {trial.name}", kind="recording")
        rt.trial, rt.recorder = None, None
        status: schema.TrialStatus = "finished"
        samples, duration = recorder.samples, recorder.duration_s
        try:
            recorder.finish()
        except Exception as e:
            log.error("session %d: finishing %s failed: %s", rt.session.id, recorder.path, e)
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
                log.error("session %d: %s cannot be recovered: %s", rt.session.id, recorder.path, again)
                status = "damaged"
            kept = f", {duration:.1f} s kept" if status == "recovered" else ""
            rt.events.lasting_event(
                f"the recording of {trial.name} could not be finished ({describe(e)}): {status}{kept}", trial.id
            )
        try:
            return rt.writer.call(
                functools.partial(rt.store.finish_trial, trial.id, status, samples, duration),
                f"session {rt.session.id}: end of trial {trial.id}",
            )
        except Exception as e:  # the database's disk full: the manager stores it later, the API shows it meanwhile
            log.error("session %d: trial %d ended %s but could not be stored: %s", rt.session.id, trial.id, status, e)
            stamp = dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds")
            ended = trial.model_copy(
                update={"status": status, "samples": samples, "duration_s": float(duration), "stopped_utc": stamp}
            )
            rt.unsaved_trials[trial.id] = ended
            return ended

    def failed(self, e: Exception) -> None:
        """A recording write failed (a full disk): finish what was recorded and stop the session.

        The trial ends at once, readable up to its last complete chunk (:meth:`stop`); the session
        ends on the next turn of the loop, with the reason in its last event and in the device's close."""
        rt = self.rt
        log.error("session %d: recording failed: %s", rt.session.id, e)
        if self._failing:  # a write while finishing it (its "recording stopped" event): it is ending
            return
        self._failing = True
        try:
            with contextlib.suppress(Exception):
                self.stop()
        finally:
            self._failing = False
        rt.recorder, rt.trial = None, None
        if rt.ended is None and not rt.stopped:
            why = (
                f"{describe(e)}; {FREE_SPACE_HINT}"
                if is_disk_full(e)
                else f"the recording could not be written ({describe(e)}); session stopped"
            )
            asyncio.get_running_loop().create_task(rt.end("stopped", why))


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
