"""IMU mounting calibration of a session's front ends: collect a standing period's raw samples, calibrate
them (:func:`gaitscope.estimators.imu_calibration.calibrate_standing`), and apply an accepted calibration to the
stack's ``imu_*`` front ends, live (:mod:`gaitscope.sessions.live.runtime`) and in a re-run
(:mod:`gaitscope.sessions.review.rerun`, from the recording's ``/imu_calibration`` messages).

Collecting is cheap: one list of floats per frame, only while a calibration runs. The period is measured
in session time (the device's clock), so it ends after ``duration_s`` of samples, however fast they came.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Final

import numpy as np

from gaitscope.estimators.imu_calibration import Calibration, calibrate_standing
from gaitscope.estimators.imu_frontend import SEGMENTS, ImuFrontEnd, imu_inputs
from gaitscope.sessions import schema
from gaitscope.sessions.stack import EstimatorStack

__all__ = ["GRACE_S", "StandingCollector", "applied_text", "apply_calibration", "front_end_segments"]

#: Wall-clock time beyond the period after which a calibration ends with what it has (frames stopped).
GRACE_S: Final = 5.0
_FRONT_ENDS: Final = {f"imu_{seg}": seg for seg in SEGMENTS}


def front_end_segments(stack: EstimatorStack) -> list[str]:
    """The segments whose IMU front end (``imu_<segment>``) is in the stack, in stack order."""
    return [_FRONT_ENDS[name] for name in stack.names if name in _FRONT_ENDS]


def apply_calibration(stack: EstimatorStack, cal: schema.ImuCalibration) -> list[str]:
    """Retune the stack's front ends with an accepted calibration's offsets; the names of those retuned
    (none for a refused calibration, or one of sensors this stack has no front end for)."""
    if not cal.ok:
        return []
    done = []
    for est in stack.estimators:
        sensor = next((s for s in cal.sensors if s.ok and _FRONT_ENDS.get(est.name) == s.segment), None)
        if sensor is not None and isinstance(est, ImuFrontEnd):
            bx, by, bz = sensor.gyro_bias_dps
            est.retune(pitch_offset_deg=sensor.pitch_offset_deg, gyro_bias_x_dps=bx, gyro_bias_y_dps=by,
                       gyro_bias_z_dps=bz)  # fmt: skip
            done.append(est.name)
    return done


def applied_text(cal: schema.ImuCalibration, names: Sequence[str]) -> str:
    """What an event says the front ends ``names`` took: each one's pitch offset and gyro bias."""
    by_name = {f"imu_{s.segment}": s for s in cal.sensors}
    return "; ".join(
        f"{n} pitch offset {by_name[n].pitch_offset_deg:+.1f} deg, gyro bias "
        f"({', '.join(f'{b:+.2f}' for b in by_name[n].gyro_bias_dps)}) deg/s"
        for n in names
    )


class StandingCollector:
    """The raw IMU samples of a standing period, then its calibration.

    Args:
        segments: the sensors to calibrate (those with a front end in the stack).
        request: the period, who asked and the posture note.
    """

    def __init__(self, segments: Sequence[str], request: schema.ImuCalibrationRequest):
        self.segments = tuple(segments)
        self.request = request
        self.started = time.monotonic()
        self._channels = tuple(c for seg in self.segments for c in imu_inputs(seg))
        self._rows: list[list[float]] = []
        self._t0: float | None = None
        self._t = 0.0

    def add(self, t: float, frame: schema.SensorFrame) -> bool:
        """One frame at session time ``t`` (s); True once the period is covered."""
        if self._t0 is None:
            self._t0 = t
        self._t = t
        self._rows.append([math.nan if (v := getattr(frame, c)) is None else v for c in self._channels])
        return self.progress >= 1.0

    @property
    def progress(self) -> float:
        """Share of the period covered by the samples so far (0..1)."""
        if self._t0 is None:
            return 0.0
        return min(1.0, max(0.0, (self._t - self._t0) / self.request.duration_s))

    def overdue(self) -> bool:
        """The period is long past by the wall clock (the frames stopped coming): end with what there is."""
        return time.monotonic() - self.started > self.request.duration_s + GRACE_S

    def result(self, subject_id: int, session_id: int, trial_id: int | None) -> schema.ImuCalibration:
        """Calibrate the sensors that sent readings; refused (with each sensor's reason) unless all of them
        were still, or when none sent any."""
        n, k = len(self._rows), len(self.segments)
        data = np.array(self._rows, dtype=np.float64).reshape(n, 6 * k)
        rate = (n - 1) / (self._t - self._t0) if self._t0 is not None and self._t > self._t0 else 1.0
        imus = {}
        for i, seg in enumerate(self.segments):
            block = data[:, 6 * i : 6 * i + 6]
            if np.isfinite(block).all(axis=1).any():  # a sensor without a single reading has no data: left out
                imus[seg] = (block[:, :3], block[:, 3:])
        cal = calibrate_standing(imus, rate) if imus else Calibration((), 0.0)
        sensors = [
            schema.ImuSensorCalibration(
                segment=s.segment,
                ok=s.ok,
                reason=s.reason + (": stand still and try again" if s.reason.startswith("not still") else ""),
                pitch_offset_deg=s.pitch_offset_deg,
                gyro_bias_dps=s.gyro_bias_dps,
                gyro_motion_dps=s.gyro_motion_dps if math.isfinite(s.gyro_motion_dps) else None,
                accel_sd=s.accel_sd if math.isfinite(s.accel_sd) else None,
            )
            for s in cal.sensors
        ]
        if not sensors:
            reason = f"no raw IMU readings arrived (from {', '.join(f'imu_{s}' for s in self.segments)})"
        else:
            reason = "; ".join(f"imu_{s.segment}: {s.reason}" for s in sensors if not s.ok)
        return schema.ImuCalibration(
            subject_id=subject_id,
            session_id=session_id,
            trial_id=trial_id,
            duration_s=round(cal.duration_s, 3),
            ok=bool(sensors) and not reason,
            reason=reason,
            sensors=sensors,
            created_by=self.request.actor,
            note=self.request.note,
        )
