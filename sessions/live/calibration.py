"""IMU mounting calibration during a session, as a session extension.

The clinician asks for a standing period (:meth:`ImuCalibrating.calibrate`); the front ends' raw IMU samples
are collected for its ``duration_s`` (:class:`~gaitscope.sessions.imu_calibration.StandingCollector`), then
the calibration is made: accepted, it is stored first (the subject's current calibration) and only then
applied to the front ends and recorded; refused, an event says why. A session starts with the subject's
current calibration, if its stack runs front ends, until it makes its own; each trial records the one its
front ends run, so that a re-run applies the same.
"""

from __future__ import annotations

import functools
import logging

from gaitscope.sessions import schema
from gaitscope.sessions.formats.recording import Recorder
from gaitscope.sessions.imu_calibration import StandingCollector, applied_text, apply_calibration, front_end_segments
from gaitscope.sessions.live.extensions import SessionExtension, SessionHost, describe

__all__ = ["ImuCalibrating"]

log = logging.getLogger("gaitscope")


class ImuCalibrating(SessionExtension):
    """A session's IMU calibration.

    Attributes:
        segments: the sensors it can calibrate (none: the stack runs no IMU front end).
        collector: the standing period being collected (None: none).
        result: the last calibration's outcome (None: none yet).
        applied: the calibration the front ends run (the subject's current one from the start, until this
            session makes one; None: none).
    """

    def __init__(self, host: SessionHost):
        self.host = host
        stack = host.estimator.stack
        self.segments = front_end_segments(stack)
        self.collector: StandingCollector | None = None
        self.result: schema.ImuCalibration | None = None
        current = host.store.current_imu_calibration(host.subject.id) if self.segments else None
        self._at_start = [] if current is None else apply_calibration(stack, current)
        self.applied = current if self._at_start else None

    def start(self) -> None:
        if self.applied is not None:
            self.host.event(
                "system",
                f"the subject's IMU calibration {self.applied.id} ({self.applied.created_utc}) applied: "
                + applied_text(self.applied, self._at_start),
                field="imu_calibration",
                after=float(self.applied.id or 0),
            )

    def on_trial(self, recorder: Recorder, t: float) -> None:
        if self.applied is not None:  # each trial holds the calibration its front ends run, for a re-run
            recorder.write("/imu_calibration", t, self.applied)

    def after_record(self, frame: schema.SensorFrame, t: float) -> None:
        if self.collector is not None and self.collector.add(t, frame):
            self._calibrated()  # after the frame's record: a re-run applies it from the next frame, as here

    def on_tick(self) -> None:
        if self.collector is not None and self.collector.overdue():
            self._calibrated()

    def calibrate(self, request: schema.ImuCalibrationRequest) -> schema.ImuCalibrationStatus:
        """Start collecting a standing period of the front ends' raw IMU samples (the caller checked that
        the stack has front ends and that none is collecting); it ends after ``duration_s`` of samples."""
        self.collector = StandingCollector(self.segments, request)
        self.result = None
        who = f" by {request.actor}" + (f" ({request.note})" if request.note else "")
        self.host.event("system", f"IMU calibration started{who}: stand still for {request.duration_s:g} s",
                        actor=request.actor)  # fmt: skip
        return self.status()

    def status(self) -> schema.ImuCalibrationStatus:
        c, r = self.collector, self.result
        state: schema.ImuCalibrationState = (
            "collecting" if c is not None else "idle" if r is None else "done" if r.ok else "refused"
        )
        return schema.ImuCalibrationStatus(
            session_id=self.host.session.id,
            state=state,
            progress=c.progress if c is not None else 0.0 if r is None else 1.0,
            duration_s=c.request.duration_s if c is not None else r.duration_s if r is not None else 0.0,
            segments=self.segments,
            result=r,
            applied=self.applied,
        )

    def _calibrated(self) -> None:
        """The standing period is over: calibrate; accepted, store it (the subject's current calibration)
        and only then apply it to the front ends and record it; refused, say why. Either way an event."""
        host = self.host
        collector, self.collector = self.collector, None
        assert collector is not None
        actor = collector.request.actor
        result = collector.result(host.subject.id, host.session.id, host.trial.id if host.trial else None)
        if result.ok:
            try:
                result = host.writer.call(
                    functools.partial(host.store.add_imu_calibration, result),
                    f"session {host.session.id}: IMU calibration",
                )
            except Exception as e:
                log.error("session %d: IMU calibration not saved: %s", host.session.id, e)
                why = f"the calibration could not be saved ({describe(e)}), so it was not applied"
                result = result.model_copy(update={"ok": False, "reason": why})
        self.result = result
        if not result.ok:
            host.event("system", f"IMU calibration refused: {result.reason}", field="imu_calibration", actor=actor)
            return
        names = apply_calibration(host.estimator.stack, result)
        self.applied = result
        host.record("/imu_calibration", result)
        host.event("system", f"IMU calibration {result.id} applied: {applied_text(result, names)}",
                   field="imu_calibration", after=float(result.id or 0), actor=actor)  # fmt: skip

