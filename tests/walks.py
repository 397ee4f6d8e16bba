"""Synthetic sensor data the tests of several packages feed the real app: a walk as device frames, a replay
CSV, and IMU frames of a subject standing still or walking with the sensors mounted as :data:`MOUNTING`."""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np

from gaitscope.estimators.imu_frontend import G0, imu_inputs
from gaitscope.sessions.live.sources import frames_from_table
from gaitscope.sessions.schema import SensorFrame
from gaitscope.sessions.synth.trials import replay_columns, sensor_trial

#: The IMU frames' rate (Hz).
IMU_RATE = 100.0
#: The sensors' mounting: pitch offset (deg) and gyro bias (x, y, z; deg/s).
MOUNTING = {"shank": (8.0, (0.5, -0.3, 1.2)), "foot": (-5.0, (-0.4, 0.2, -0.8))}
#: The channels of the IMUs of :data:`MOUNTING`.
IMU_CHANNELS = [c for seg in MOUNTING for c in imu_inputs(seg)]


def walk_frames(strides: int = 20, subject: int = 3, rate_hz: float = 100.0) -> list[SensorFrame]:
    """A level walk at 1.0 m/s of cohort subject ``subject`` as the frames a device sends."""
    sensors, _, _ = sensor_trial([(1.0, 0.0, strides)], subject=subject, rate_hz=rate_hz)
    return frames_from_table(sensors)


@functools.cache
def replay_csv() -> bytes:
    """A replay CSV of 8 strides at 1.0 m/s (the columns ``gaitscope replay`` and the uploads read)."""
    sensors, _, _ = sensor_trial([(1.0, 0.0, 8)])
    return replay_columns(sensors).to_csv(index=False, float_format="%.5f").encode()


def imu_standing(t0: float, seconds: float, seed: int = 0) -> list[dict[str, Any]]:
    """IMU frames from ``t0`` (s) of a subject standing still, upright, with the sensors mounted as
    :data:`MOUNTING` (their noise drawn with ``seed``)."""
    rng = np.random.default_rng(seed)
    frames = []
    for k in range(round(seconds * IMU_RATE)):
        frame: dict[str, Any] = {"type": "frame", "t": t0 + k / IMU_RATE}
        for seg, (offset, bias) in MOUNTING.items():
            a = math.radians(offset)
            gyro = np.array(bias) + rng.normal(0.0, 0.2, 3)
            accel = np.array([G0 * math.sin(a), G0 * math.cos(a), 0.0]) + rng.normal(0.0, 0.02, 3)
            frame.update(zip(imu_inputs(seg), [*gyro.tolist(), *accel.tolist()], strict=True))
        frames.append(frame)
    return frames


def imu_walking(t0: float) -> list[dict[str, Any]]:
    """IMU frames from ``t0`` (s) of 4 strides of walking (the sensors as simulated, not :data:`MOUNTING`)."""
    sensors, _, _ = sensor_trial([(1.0, 0.0, 4)], rate_hz=IMU_RATE)
    out = []
    for frame in frames_from_table(sensors):
        values = frame.model_dump(include=set(IMU_CHANNELS))
        out.append({"type": "frame", "t": t0 + frame.t, **values})
    return out
