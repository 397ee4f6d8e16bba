"""The standing collector (what a sensor without readings does, a period with none) and the store's IMU
calibrations (per subject and session, the latest the current one, a refused one never stored)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gaitscope.estimators.imu_frontend import G0, imu_inputs
from gaitscope.sessions import schema
from gaitscope.sessions.imu_calibration import StandingCollector
from gaitscope.sessions.store import Conflict, NotFound, Store


def _frame(t: float, segments: dict[str, float], rng: np.random.Generator) -> schema.SensorFrame:
    values: dict[str, float] = {}
    for seg, offset in segments.items():
        a = math.radians(offset)
        z = [*rng.normal(0.0, 0.1, 3), G0 * math.sin(a), G0 * math.cos(a), 0.0]
        values.update(zip(imu_inputs(seg), z, strict=True))
    return schema.SensorFrame(t=t, seq=0, **values)  # type: ignore[arg-type]


def test_a_sensor_without_readings_is_left_out_and_none_at_all_is_refused() -> None:
    rng = np.random.default_rng(0)
    collector = StandingCollector(["foot", "shank"], schema.ImuCalibrationRequest(duration_s=2.0))
    done = [collector.add(k / 50, _frame(k / 50, {"shank": 3.0}, rng)) for k in range(101)]
    assert done.index(True) == 100 and collector.progress == 1.0  # 2 s of samples at 50 Hz
    cal = collector.result(1, 2, None)
    assert cal.ok and [s.segment for s in cal.sensors] == ["shank"] and cal.duration_s == pytest.approx(2.02)
    assert cal.sensors[0].pitch_offset_deg == pytest.approx(3.0, abs=1e-9)

    empty = StandingCollector(["foot"], schema.ImuCalibrationRequest())
    empty.add(0.0, schema.SensorFrame(t=0.0, seq=0))
    cal = empty.result(1, 2, None)
    assert not cal.ok and cal.reason == "no raw IMU readings arrived (from imu_foot)" and cal.sensors == []


def test_too_short_a_period_is_refused_without_the_stand_still_hint() -> None:
    rng = np.random.default_rng(1)
    collector = StandingCollector(["shank"], schema.ImuCalibrationRequest(duration_s=5.0))
    for k in range(50):
        collector.add(k / 50, _frame(k / 50, {"shank": 0.0}, rng))
    cal = collector.result(1, 2, None)
    assert not cal.ok and cal.reason.startswith("imu_shank: only 1.0 s of valid readings (50 samples)")
    assert "try again" not in cal.reason and cal.sensors[0].gyro_motion_dps is None


def test_the_store_keeps_accepted_calibrations_per_subject_and_session(database_url: str) -> None:
    store = Store(database_url)
    subject = store.create_subject(schema.SubjectCreate(code="S1", leg_length_m=0.9, mass_kg=70.0))
    source = schema.DeviceSource()
    s1 = store.create_session(schema.SessionCreate(subject_id=subject.id, source=source, start=False))
    s2 = store.create_session(schema.SessionCreate(subject_id=subject.id, source=source, start=False))
    sensor = schema.ImuSensorCalibration(segment="shank", ok=True, pitch_offset_deg=4.5, gyro_bias_dps=(0.1, 0, -0.2),
                                         gyro_motion_dps=0.4, accel_sd=0.01)  # fmt: skip
    draft = schema.ImuCalibration(subject_id=subject.id, session_id=s1.id, duration_s=5.0, ok=True, sensors=[sensor],
                                  created_by="dr a", note="upright")  # fmt: skip
    assert store.current_imu_calibration(subject.id) is None
    first = store.add_imu_calibration(draft)
    second = store.add_imu_calibration(draft.model_copy(update={"session_id": s2.id}))
    assert first.id == 1 and first.sensors == [sensor] and first.created_utc and first.note == "upright"
    assert store.current_imu_calibration(subject.id) == second
    assert store.list_imu_calibrations(subject_id=subject.id) == [second, first]
    assert store.list_imu_calibrations(session_id=s1.id) == [first]
    with pytest.raises(Conflict):
        store.add_imu_calibration(draft.model_copy(update={"ok": False, "reason": "imu_shank: not still"}))
    with pytest.raises(NotFound):
        store.add_imu_calibration(draft.model_copy(update={"session_id": 99}))
    assert len(store.list_imu_calibrations()) == 2
