"""Mounting calibration of body-worn IMUs from a standing period: pitch offset and gyro bias per sensor.

The subject stands still in a known posture (by default upright: thigh and shank vertical, foot flat,
every sagittal angle 0) for a few seconds. Each sensor's accelerometer then reads gravity alone, so its
inclination ``atan2(a_x, a_y)`` minus the posture's segment angle is the mounting's pitch offset, and its
gyro reads its bias (Ferrari et al. 2010, Gait Posture 31:540-542, calibrate in a static posture; the
ISB's anatomical calibration the same way). A sensor that was not still (its gyro moved by more than
``max_gyro_dps`` from its mean, or its accelerometer's sd above ``max_accel_sd``, or the norm far from
g) is refused with the reason, as is a period too short; the front end (:mod:`gaitscope.estimators.imu_frontend`)
takes the accepted offsets through ``retune(pitch_offset_deg=..., gyro_bias_{x,y,z}_dps=...)``.

Pure: arrays in, a frozen dataclass out (plain floats and strings, ready for a JSON API).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Final

import numpy as np
from numpy.typing import ArrayLike

from gaitscope.estimators.imu_frontend import G0

__all__ = ["MIN_STILL_S", "Calibration", "SensorCalibration", "calibrate_standing"]

#: Shortest standing period accepted (s).
MIN_STILL_S: Final = 2.0


@dataclass(frozen=True)
class SensorCalibration:
    """One sensor's calibration: what the front end applies, or why not.

    Attributes:
        segment: the IMU's segment (``foot``, ``shank_contra``, ...).
        ok: accepted (the subject was still); when False the offsets are 0 and ``reason`` says why.
        reason: ``""`` when accepted.
        pitch_offset_deg: sensor inclination minus the posture's segment angle (deg).
        gyro_bias_dps: mean gyro reading (x, y, z; deg/s).
        gyro_motion_dps: largest deviation of the gyro from its mean (deg/s), the stillness measure.
        accel_sd: largest per-axis accelerometer sd (m/s^2).
    """

    segment: str
    ok: bool
    reason: str
    pitch_offset_deg: float
    gyro_bias_dps: tuple[float, float, float]
    gyro_motion_dps: float
    accel_sd: float

    def retune_params(self) -> dict[str, float]:
        """The front end's ``retune`` parameters (empty when refused)."""
        if not self.ok:
            return {}
        bx, by, bz = self.gyro_bias_dps
        return {"pitch_offset_deg": self.pitch_offset_deg, "gyro_bias_x_dps": bx, "gyro_bias_y_dps": by,
                "gyro_bias_z_dps": bz}  # fmt: skip


@dataclass(frozen=True)
class Calibration:
    """Every sensor's calibration; ``ok`` when all were accepted, else ``reason`` names the refusals."""

    sensors: tuple[SensorCalibration, ...]
    duration_s: float

    @property
    def ok(self) -> bool:
        return all(s.ok for s in self.sensors)

    @property
    def reason(self) -> str:
        return "; ".join(f"{s.segment}: {s.reason}" for s in self.sensors if not s.ok)


def calibrate_standing(
    imus: Mapping[str, tuple[ArrayLike, ArrayLike]],
    rate_hz: float,
    posture_deg: Mapping[str, float] | None = None,
    *,
    max_gyro_dps: float = 10.0,
    max_accel_sd: float = 0.3,
    max_norm_error: float = 1.0,
) -> Calibration:
    """Each sensor's mounting offset from a standing period.

    Args:
        imus: by segment, ``(gyro, accel)``, each ``(n, 3)`` (deg/s, m/s^2; the front end's axes).
        rate_hz: sample rate (for the duration).
        posture_deg: the segments' true sagittal angles while standing (default 0: upright, foot flat).
        max_gyro_dps: largest deviation of any gyro axis from its mean (deg/s) for a still sensor.
        max_accel_sd: largest per-axis accelerometer sd (m/s^2) for a still sensor.
        max_norm_error: largest ``| mean |a| - g |`` (m/s^2): else not gravity alone (or a faulty sensor).

    Raises:
        ValueError: arrays of the wrong shape or a non-positive rate.
    """
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate_hz must be positive, got {rate_hz}")
    posture = posture_deg or {}
    out = []
    duration = 0.0
    for segment, (gyro_in, accel_in) in imus.items():
        gyro, accel = np.asarray(gyro_in, dtype=np.float64), np.asarray(accel_in, dtype=np.float64)
        if gyro.ndim != 2 or gyro.shape[1] != 3 or accel.shape != gyro.shape:
            raise ValueError(f"{segment}: gyro and accelerometer must both be (n, 3), got {gyro.shape}, {accel.shape}")
        duration = max(duration, gyro.shape[0] / rate_hz)
        out.append(_one(segment, gyro, accel, rate_hz, posture.get(segment, 0.0), max_gyro_dps, max_accel_sd,
                        max_norm_error))  # fmt: skip
    return Calibration(tuple(out), duration)


def _one(
    segment: str,
    gyro: np.ndarray,
    accel: np.ndarray,
    rate_hz: float,
    posture: float,
    max_gyro: float,
    max_accel_sd: float,
    max_norm_error: float,
) -> SensorCalibration:
    n = gyro.shape[0]
    finite = np.isfinite(gyro).all(axis=1) & np.isfinite(accel).all(axis=1)
    gyro, accel = gyro[finite], accel[finite]
    if gyro.shape[0] / rate_hz < MIN_STILL_S:
        s = f"only {gyro.shape[0] / rate_hz:.1f} s of valid readings ({n} samples); stand still for {MIN_STILL_S:g} s"
        return SensorCalibration(segment, False, s, 0.0, (0.0, 0.0, 0.0), math.nan, math.nan)
    bias = gyro.mean(axis=0)
    motion = float(np.abs(gyro - bias).max())
    accel_sd = float(accel.std(axis=0).max())
    mean = accel.mean(axis=0)
    norm = float(np.linalg.norm(mean))
    reason = ""
    if motion > max_gyro:
        reason = f"not still: the gyro moved {motion:.1f} deg/s from its mean (limit {max_gyro:g})"
    elif accel_sd > max_accel_sd:
        reason = f"not still: accelerometer sd {accel_sd:.2f} m/s^2 (limit {max_accel_sd:g})"
    elif abs(norm - G0) > max_norm_error:
        reason = f"the accelerometer reads {norm:.2f} m/s^2, not gravity ({G0:.2f}): a faulty or mis-scaled sensor"
    if reason:
        return SensorCalibration(segment, False, reason, 0.0, (0.0, 0.0, 0.0), motion, accel_sd)
    offset = math.degrees(math.atan2(float(mean[0]), float(mean[1]))) - posture
    b = (float(bias[0]), float(bias[1]), float(bias[2]))
    return SensorCalibration(segment, True, "", offset, b, motion, accel_sd)
