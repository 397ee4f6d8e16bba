"""A body-worn 6-axis IMU: what it reads from a segment's sagittal motion, with a datasheet's errors.

The sensor's axes nominally align with its segment's (ISB, as in :data:`gaitscope.sessions.schema.CHANNELS`): x
anterior, y along the segment toward proximal, z to the subject's right, so the segment's sagittal
angle is a rotation about z. In the sagittal model the segment turns about z only; the mounting
misalignment makes that rotation, and gravity, show on the other axes too.

Reading = full-scale clip, quantised to the ADC step, of ``(1 + scale) * (M @ true) + bias + white noise``
per axis, with ``M`` the mounting misalignment. Every figure of :class:`ImuSpec` is the InvenSense
MPU-9250's (product specification PS-MPU-9250A-01 rev. 1.0, tables 1 and 2; the exoskeleton IMU of
seed 000's hardware), except the misalignment, from Picerno et al. 2008; sources and choices in
``docs/cohort.md`` ("Schema version 2").
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

import numpy as np

__all__ = ["G0", "ImuErrors", "ImuSpec", "draw_errors", "imu_readings", "rotation"]

#: Standard gravity (m/s^2): the datasheet's g.
G0: Final = 9.80665


@dataclass(frozen=True)
class ImuSpec:
    """Error figures of one IMU model; defaults are the MPU-9250's, at its largest full scales.

    Attributes:
        gyro_noise_density_dps: rate noise spectral density, deg/s/sqrt(Hz) (0.01).
        accel_noise_density_ug: noise power spectral density, micro-g/sqrt(Hz) (300).
        gyro_bias_dps: initial zero-rate-output tolerance at 25 C, +/- deg/s (5); each axis's bias is
            drawn uniformly within it, once per recording.
        accel_bias_mg: zero-g initial calibration tolerance x, y, z, +/- mg (60, 60, 80); drawn as the gyro's.
        scale_tolerance: sensitivity (scale factor) tolerance, +/- fraction (0.03); drawn as the biases.
        gyro_full_scale_dps, gyro_lsb_per_dps: +/-2000 deg/s at 16.4 LSB/(deg/s).
        accel_full_scale_g, accel_lsb_per_g: +/-16 g at 2048 LSB/g.
        misalignment_sd_deg: sd of the mounting misalignment about x, y, z (deg): Picerno et al. 2008's
            largest inter-examiner variability, 2.9 deg for flexion-extension (about z, and taken for
            x, which the abstract does not give) and 7.3 deg for internal-external rotation (about y).
    """

    gyro_noise_density_dps: float = 0.01
    accel_noise_density_ug: float = 300.0
    gyro_bias_dps: float = 5.0
    accel_bias_mg: tuple[float, float, float] = (60.0, 60.0, 80.0)
    scale_tolerance: float = 0.03
    gyro_full_scale_dps: float = 2000.0
    gyro_lsb_per_dps: float = 16.4
    accel_full_scale_g: float = 16.0
    accel_lsb_per_g: float = 2048.0
    misalignment_sd_deg: tuple[float, float, float] = (2.9, 7.3, 2.9)

    def noise_sd(self, rate_hz: float) -> tuple[float, float]:
        """White-noise sd per sample of gyro (deg/s) and accelerometer (m/s^2) sampled at ``rate_hz``:
        the noise density times the square root of the Nyquist bandwidth."""
        root = np.sqrt(rate_hz / 2.0)
        return float(self.gyro_noise_density_dps * root), float(self.accel_noise_density_ug * 1e-6 * G0 * root)


@dataclass(frozen=True)
class ImuErrors:
    """One mounted sensor's constant errors (one recording).

    Attributes:
        misalignment: (3, 3) rotation taking segment-frame vectors to sensor-frame ones.
        gyro_bias: (3,) deg/s.  accel_bias: (3,) m/s^2.
        gyro_scale, accel_scale: (3,) fractional sensitivity errors.
    """

    misalignment: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray
    gyro_scale: np.ndarray
    accel_scale: np.ndarray


def rotation(angles_deg: np.ndarray) -> np.ndarray:
    """The rotation ``Rz Ry Rx`` of small angles about x, y, z (deg), (3, 3)."""
    ax, ay, az = np.radians(angles_deg)
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def draw_errors(spec: ImuSpec, rng: np.random.Generator) -> ImuErrors:
    """A mounted sensor's errors: misalignment, then gyro bias, accelerometer bias, gyro and accelerometer
    scale (always drawn in this order, so one seed gives one sensor)."""
    tilt = rng.standard_normal(3) * np.asarray(spec.misalignment_sd_deg)
    gyro_bias = rng.uniform(-1.0, 1.0, 3) * spec.gyro_bias_dps
    accel_bias = rng.uniform(-1.0, 1.0, 3) * np.asarray(spec.accel_bias_mg) * 1e-3 * G0
    gyro_scale = rng.uniform(-1.0, 1.0, 3) * spec.scale_tolerance
    accel_scale = rng.uniform(-1.0, 1.0, 3) * spec.scale_tolerance
    return ImuErrors(rotation(tilt).T, gyro_bias, accel_bias, gyro_scale, accel_scale)


def imu_readings(
    angle_deg: np.ndarray,
    rate_dps: np.ndarray,
    accel_world: np.ndarray,
    rate_hz: float,
    spec: ImuSpec,
    errors: ImuErrors,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """Gyro (deg/s) and accelerometer (m/s^2) readings, each (n, 3), of a sensor on a segment.

    Args:
        angle_deg: (n,) the segment's sagittal angle (the sensor frame's rotation about z from the
            world's x forward, y up, z right frame).
        rate_dps: (n,) its angular velocity.
        accel_world: (n, 3) linear acceleration of the mounting point, world frame (forward, up, right),
            gravity not included.
        rate_hz: sample rate, for the white noise's sd (:meth:`ImuSpec.noise_sd`).
        rng: draws the white noise: gyro (n, 3), then accelerometer (n, 3).
    """
    n = angle_deg.shape[0]
    a = np.radians(angle_deg)
    c, s = np.cos(a), np.sin(a)
    force = accel_world + np.array([0.0, G0, 0.0])  # specific force: what an accelerometer senses
    seg_force = np.stack([c * force[:, 0] + s * force[:, 1], -s * force[:, 0] + c * force[:, 1], force[:, 2]], axis=1)
    seg_rate = np.stack([np.zeros(n), np.zeros(n), rate_dps], axis=1)
    gyro_sd, accel_sd = spec.noise_sd(rate_hz)
    gyro = (1 + errors.gyro_scale) * (seg_rate @ errors.misalignment.T) + errors.gyro_bias
    gyro = gyro + gyro_sd * rng.standard_normal((n, 3))
    accel = (1 + errors.accel_scale) * (seg_force @ errors.misalignment.T) + errors.accel_bias
    accel = accel + accel_sd * rng.standard_normal((n, 3))
    return (
        _adc(gyro, spec.gyro_full_scale_dps, 1.0 / spec.gyro_lsb_per_dps),
        _adc(accel, spec.accel_full_scale_g * G0, G0 / spec.accel_lsb_per_g),
    )


def _adc(x: np.ndarray, full_scale: float, step: float) -> np.ndarray:
    """Clipped at full scale and quantised to the ADC step."""
    return np.round(np.clip(x, -full_scale, full_scale) / step) * step
