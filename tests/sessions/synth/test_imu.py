"""The simulated IMU: its noise, biases, scale errors, misalignment and ADC match the declared figures."""

from __future__ import annotations

import numpy as np
import pytest

from gaitscope.sessions.synth.imu import G0, ImuErrors, ImuSpec, draw_errors, imu_readings, rotation

SPEC = ImuSpec()
RATE_HZ = 200.0
GYRO_LSB = 1 / SPEC.gyro_lsb_per_dps
ACCEL_LSB = G0 / SPEC.accel_lsb_per_g


def perfect() -> ImuErrors:
    zero = np.zeros(3)
    return ImuErrors(np.eye(3), zero, zero, zero, zero)


def at_rest(n: int, spec: ImuSpec = SPEC, errors: ImuErrors | None = None, seed: int = 0) -> tuple[np.ndarray, ...]:
    zero = np.zeros(n)
    return imu_readings(zero, zero, np.zeros((n, 3)), RATE_HZ, spec, errors or perfect(), np.random.default_rng(seed))


def test_the_datasheet_figures() -> None:
    assert (SPEC.gyro_noise_density_dps, SPEC.accel_noise_density_ug) == (0.01, 300.0)  # MPU-9250 tables 1, 2
    assert (SPEC.gyro_bias_dps, SPEC.accel_bias_mg, SPEC.scale_tolerance) == (5.0, (60.0, 60.0, 80.0), 0.03)
    gyro_sd, accel_sd = SPEC.noise_sd(RATE_HZ)
    assert gyro_sd == pytest.approx(0.01 * np.sqrt(100.0)) and accel_sd == pytest.approx(300e-6 * G0 * 10.0)
    assert SPEC.noise_sd(92.0)[0] == pytest.approx(0.0678, abs=1e-4)  # ~ the 0.1 deg/s-rms of a 92 Hz filter


def test_white_noise_at_rest_has_the_declared_sd_and_is_white() -> None:
    gyro, accel = at_rest(60_000)
    gyro_sd, accel_sd = SPEC.noise_sd(RATE_HZ)
    for x, sd, lsb in ((gyro, gyro_sd, GYRO_LSB), (accel - [0, G0, 0], accel_sd, ACCEL_LSB)):
        expected = np.sqrt(sd**2 + lsb**2 / 12)  # white noise plus the ADC's quantisation
        np.testing.assert_allclose(x.std(axis=0), expected, rtol=0.02)
        np.testing.assert_allclose(x.mean(axis=0), 0.0, atol=4 * expected / np.sqrt(len(x)))
        lag1 = [np.corrcoef(x[1:, i], x[:-1, i])[0, 1] for i in range(3)]
        assert np.abs(lag1).max() < 0.02
    np.testing.assert_allclose(gyro / GYRO_LSB, np.round(gyro / GYRO_LSB), atol=1e-6)  # on the ADC grid
    np.testing.assert_allclose(accel / ACCEL_LSB, np.round(accel / ACCEL_LSB), atol=1e-6)


def test_drawn_errors_spread_as_declared() -> None:
    rng = np.random.default_rng(1)
    draws = [draw_errors(SPEC, rng) for _ in range(4000)]
    gyro_bias = np.array([e.gyro_bias for e in draws])
    accel_bias = np.array([e.accel_bias for e in draws]) / (G0 * 1e-3)  # mg
    scale = np.array([np.r_[e.gyro_scale, e.accel_scale] for e in draws])
    assert np.abs(gyro_bias).max() <= 5.0 and np.abs(gyro_bias).max() > 4.9  # uniform within the tolerance
    np.testing.assert_allclose(gyro_bias.std(axis=0), 5.0 / np.sqrt(3), rtol=0.05)
    assert (np.abs(accel_bias) <= [60.0, 60.0, 80.0]).all()
    np.testing.assert_allclose(accel_bias.std(axis=0), np.array([60.0, 60.0, 80.0]) / np.sqrt(3), rtol=0.05)
    assert np.abs(scale).max() <= 0.03
    r = np.array([e.misalignment.T for e in draws])  # sensor axes in the segment frame: Rz Ry Rx
    angles = np.degrees(
        [np.arctan2(r[:, 2, 1], r[:, 2, 2]), -np.arcsin(r[:, 2, 0]), np.arctan2(r[:, 1, 0], r[:, 0, 0])]
    )
    np.testing.assert_allclose(angles.std(axis=1), SPEC.misalignment_sd_deg, rtol=0.06)
    for e in draws[:10]:
        np.testing.assert_allclose(e.misalignment @ e.misalignment.T, np.eye(3), atol=1e-12)


def test_biases_scale_and_misalignment_show_in_the_readings() -> None:
    quiet = ImuSpec(gyro_noise_density_dps=0.0, accel_noise_density_ug=0.0)
    errors = ImuErrors(rotation(np.array([0.0, 0.0, 5.0])).T, np.array([1.0, -2.0, 3.0]), np.array([0.1, 0.2, -0.3]),
                       np.zeros(3), np.array([0.0, 0.02, 0.0]))  # fmt: skip
    gyro, accel = at_rest(3, quiet, errors)
    np.testing.assert_allclose(gyro, [[1.0, -2.0, 3.0]] * 3, atol=GYRO_LSB / 2)
    tilt = np.radians(5.0)  # a sensor turned 5 deg about z (toes up) sees part of gravity on +x
    expected = [G0 * np.sin(tilt) + 0.1, 1.02 * G0 * np.cos(tilt) + 0.2, -0.3]
    np.testing.assert_allclose(accel[0], expected, atol=ACCEL_LSB / 2)


def test_sagittal_motion_gravity_and_full_scale() -> None:
    quiet = ImuSpec(gyro_noise_density_dps=0.0, accel_noise_density_ug=0.0)
    angle = np.array([30.0, 0.0, 0.0])
    rate = np.array([100.0, 5000.0, -5000.0])
    accel_world = np.array([[0.0, 0.0, 0.0], [2.0, -1.0, 0.5], [0.0, 300.0, 0.0]])
    gyro, accel = imu_readings(angle, rate, accel_world, RATE_HZ, quiet, perfect(), np.random.default_rng(0))
    np.testing.assert_allclose(gyro[:, 2], [100.0, 2000.0, -2000.0], atol=GYRO_LSB / 2)  # clipped at +/-2000
    np.testing.assert_allclose(gyro[:, :2], 0.0)
    a = np.radians(30.0)  # toes 30 deg up: gravity's reaction has a forward (+x) part
    np.testing.assert_allclose(accel[0], [G0 * np.sin(a), G0 * np.cos(a), 0.0], atol=ACCEL_LSB / 2)
    np.testing.assert_allclose(accel[1], [2.0, G0 - 1.0, 0.5], atol=ACCEL_LSB / 2)
    assert accel[2, 1] == pytest.approx(16 * G0, abs=ACCEL_LSB)  # clipped at 16 g
